// The format dispatch: an experiment file of any supported format to a Record, chosen by its
// extension, and several files read by two threads.
#include "records_detail.hpp"

#include <cctype>
#include <cstring>
#include <exception>
#include <sys/stat.h>
#include <system_error>
#include <thread>

namespace msidrec {

static bool ends_with(const std::string &s, const char *suf)
{
    const size_t n = std::strlen(suf);
    if (s.size() < n) return false;
    for (size_t i = 0; i < n; ++i)
        if (std::tolower((unsigned char)s[s.size() - n + i]) != suf[i]) return false;
    return true;
}

static Record read_one(const std::string &path, const ColumnMap &cols, bool zero_copy, bool split,
                       bool defer_finite = false)
{
    if (ends_with(path, ".npy")) return read_record_npy(path, cols, zero_copy, defer_finite);
    if (ends_with(path, ".npz")) return read_record_npz(path, cols);
    if (ends_with(path, ".mat")) return read_record_mat(path, cols);
    return read_record_csv(path, cols, split);
}

bool is_csv_path(const std::string &path)
{
    return !ends_with(path, ".npy") && !ends_with(path, ".npz") && !ends_with(path, ".mat");
}

Record read_experiment(const std::string &path, const ColumnMap &cols, bool zero_copy)
{
    return read_one(path, cols, zero_copy, true);
}

std::vector<Record> read_experiments(const std::vector<std::string> &paths, const ColumnMap &cols, bool zero_copy,
                                     bool defer_finite)
{
    // .mat goes through libmatio (and HDF5, not thread-safe), .npz through zlib: serial, as is a
    // pipe (which might be given twice). Regular CSV and .npy files: one thread per file.
    bool par = paths.size() >= 2 && std::thread::hardware_concurrency() >= 2;
    for (const auto &p : paths) {
        struct stat st;
        par = par && !ends_with(p, ".npz") && !ends_with(p, ".mat") && ::stat(p.c_str(), &st) == 0 &&
              S_ISREG(st.st_mode);
    }
    std::vector<Record> recs(paths.size());
    if (!par) {
        for (size_t i = 0; i < paths.size(); ++i) recs[i] = read_one(paths[i], cols, zero_copy, true, defer_finite);
        return recs;
    }
    // Thread t reads files t, t + 2, ...; a thread stops at its first bad file. The first bad
    // file in the list is reported: every file before it was read (by one thread or the other).
    std::vector<std::exception_ptr> err(paths.size());
    auto work = [&](size_t t) {
        for (size_t i = t; i < paths.size(); i += 2) {
            try {
                recs[i] = read_one(paths[i], cols, zero_copy, false, defer_finite);
            } catch (...) {
                err[i] = std::current_exception();
                return;
            }
        }
    };
    std::thread th;
    try {
        th = std::thread(work, (size_t)1);
    } catch (const std::system_error &) {   // no thread to be had: one after the other
        for (size_t i = 0; i < paths.size(); ++i) recs[i] = read_one(paths[i], cols, zero_copy, true, defer_finite);
        return recs;
    }
    work(0);
    th.join();
    for (const auto &x : err)
        if (x) std::rethrow_exception(x);
    return recs;
}

}  // namespace msidrec
