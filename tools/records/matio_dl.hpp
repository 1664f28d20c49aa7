// libmatio loaded on first use (dlopen): it pulls in HDF5 and a few dozen
// libraries, which would otherwise cost every `msid` start ~10 ms.
#pragma once
#include <matio.h>
#include <string>

namespace msidrec {

struct Matio {
    decltype(&Mat_Open) Open;
    decltype(&Mat_Close) Close;
    decltype(&Mat_VarReadNextInfo) VarReadNextInfo;
    decltype(&Mat_VarRead) VarRead;
    decltype(&Mat_VarFree) VarFree;
    decltype(&Mat_LogInitFunc) LogInitFunc;
    decltype(&Mat_CreateVer) CreateVer;
    decltype(&Mat_VarCreate) VarCreate;
    decltype(&Mat_VarWrite) VarWrite;
    void *lib;   // the dlopen handle (dlsym on it also finds the HDF5 libmatio links)
};

// The loaded library; throws Error if libmatio cannot be loaded.
const Matio &matio();

// libmatio's log handler (Mat_LogInitFunc): its last message, for the one error of a file it cannot open.
extern std::string g_mat_msg;
void mat_log(int level, char *msg);

}  // namespace msidrec
