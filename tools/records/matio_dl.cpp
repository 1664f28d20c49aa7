#include "matio_dl.hpp"
#include "records_detail.hpp"

#include <dlfcn.h>

namespace msidrec {

std::string g_mat_msg;   // matio's last log message
void mat_log(int, char *msg) { g_mat_msg = msg ? msg : ""; }

const Matio &matio()
{
    static Matio m{};
    static bool loaded = false;
    if (loaded) return m;
    void *h = nullptr;
    for (const char *so : {"libmatio.so.11", "libmatio.so"})
        if ((h = dlopen(so, RTLD_NOW | RTLD_LOCAL))) break;
    if (!h) throw Error("reading or writing .mat files needs libmatio (Debian: libmatio11), which cannot be loaded");
    auto sym = [&](auto &fn, const char *name) {
        fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(dlsym(h, name));
        if (!fn) throw Error(std::string("libmatio has no ") + name);
    };
    sym(m.Open, "Mat_Open");
    sym(m.Close, "Mat_Close");
    sym(m.VarReadNextInfo, "Mat_VarReadNextInfo");
    sym(m.VarRead, "Mat_VarRead");
    sym(m.VarFree, "Mat_VarFree");
    sym(m.LogInitFunc, "Mat_LogInitFunc");
    sym(m.CreateVer, "Mat_CreateVer");
    sym(m.VarCreate, "Mat_VarCreate");
    sym(m.VarWrite, "Mat_VarWrite");
    m.lib = h;
    loaded = true;
    return m;
}

}  // namespace msidrec
