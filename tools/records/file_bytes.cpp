// The bytes of a file as the readers take them: the whole file mapped read-only (FileBytes), a
// pipe read into memory, and the allocator of the sample matrices.
#include "msid_mapped_pages.hpp"
#include "records_detail.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <map>
#include <mutex>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace msidrec {

namespace {

// Every mapping FileBytes holds (start -> length): release_mapped() gives back only their pages.
std::mutex &maps_lock()
{
    static std::mutex m;
    return m;
}

std::map<uintptr_t, size_t> &maps()
{
    static auto *m = new std::map<uintptr_t, size_t>;   // never destroyed: a FileBytes may outlive statics
    return *m;
}

// A file up to this size is read in whole when it is mapped (MAP_POPULATE: no page faults later); a
// larger one is read as its pages are used, and a reader gives back those it has passed.
constexpr size_t POPULATE_MAX = (size_t)16 << 20;

}  // namespace

void release_mapped(const void *p, size_t n)
{
    const uintptr_t a = (uintptr_t)p, b = a + n;
    const uintptr_t pg = (uintptr_t)sysconf(_SC_PAGESIZE);
    std::lock_guard<std::mutex> lock(maps_lock());
    auto it = maps().upper_bound(a);
    if (it == maps().begin()) return;
    --it;
    if (b > it->first + it->second) return;   // not inside one mapping
    const uintptr_t lo = (a + pg - 1) / pg * pg, hi = b / pg * pg;   // the whole pages only
    if (hi > lo) madvise((void *)lo, hi - lo, MADV_DONTNEED);
}

void *alloc_big(size_t bytes)
{
    constexpr size_t H = (size_t)1 << 21;
    void *p;
    if (bytes >= H) {
        const size_t b = (bytes + H - 1) & ~(H - 1);
        p = std::aligned_alloc(H, b);
        if (p) madvise(p, b, MADV_HUGEPAGE);
    } else {
        p = std::malloc(bytes ? bytes : 1);
    }
    if (!p) throw std::bad_alloc();
    return p;
}

void read_chunks(const std::string &path, const std::function<void(const char *, size_t)> &take)
{
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw FileError("cannot open '" + path + "': " + std::strerror(errno));
    std::vector<char> buf((size_t)1 << 20);
    for (;;) {
        const ssize_t k = ::read(fd, buf.data(), buf.size());
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) {
            const int e = errno;
            ::close(fd);
            throw FileError("cannot read '" + path + "': " + std::strerror(e));
        }
        if (k == 0) break;
        try {
            take(buf.data(), (size_t)k);
        } catch (...) {
            ::close(fd);
            throw;
        }
    }
    ::close(fd);
}

// The whole file in one buffer, with a '\n' appended so every line ends in one.
std::string slurp(const std::string &path)
{
    std::string s;
    read_chunks(path, [&](const char *p, size_t n) { s.append(p, n); });
    s.push_back('\n');
    return s;
}

FileBytes::FileBytes(const std::string &path)
{
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw FileError("cannot open '" + path + "': " + std::strerror(errno));
    struct stat st;
    if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
        if constexpr (sizeof(size_t) < sizeof(uint64_t)) {   // a 32-bit target: the size must fit size_t
            if ((uint64_t)st.st_size > SIZE_MAX) {
                ::close(fd);
                throw FileError("cannot read '" + path + "' whole: " + std::to_string((uint64_t)st.st_size) +
                                " bytes are more than a 32-bit process can address");
            }
        }
        const size_t n = (size_t)st.st_size;
        void *m = mmap(nullptr, n, PROT_READ, MAP_PRIVATE | (n <= POPULATE_MAX ? MAP_POPULATE : 0), fd, 0);
        if (m != MAP_FAILED) {
            if (n > POPULATE_MAX) madvise(m, n, MADV_SEQUENTIAL);
            map_ = m;
            p_ = (const char *)m;
            n_ = n;
            ::close(fd);
            std::lock_guard<std::mutex> lock(maps_lock());
            maps()[(uintptr_t)m] = n;
            return;
        }
    }
    ::close(fd);
    own_ = slurp(path);
    own_.pop_back();   // slurp's newline
    p_ = own_.data();
    n_ = own_.size();
}

FileBytes::~FileBytes()
{
    if (!map_) return;
    {
        std::lock_guard<std::mutex> lock(maps_lock());
        maps().erase((uintptr_t)map_);
    }
    munmap(map_, n_);
}

}  // namespace msidrec
