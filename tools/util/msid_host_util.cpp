#include "msid_host_util.hpp"
#include "msid_partial_file.hpp"

#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sys/mman.h>
#include <system_error>
#include <thread>
#include <unistd.h>

namespace msidutil {

void check(msid_status st, const std::string &context)
{
    if (st != MSID_OK) throw Error(context + ": " + msid_strerror(st));
}

void write_file_atomic(const std::string &path, const std::string &data, bool durable)
{
    write_file_atomic(path, std::vector<std::string_view>{data}, durable);
}

void write_file_atomic(const std::string &path, const std::vector<std::string_view> &pieces, bool durable)
{
    std::string tmp = path + ".tmp." + std::to_string(getpid());
    const PartialFile partial(tmp);   // removed by a signal that ends the process (the CLI's handler)
    // mode 0666 less the umask, as any program's new file (0644 under the default umask 022)
    int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (fd < 0) throw IoError("cannot write '" + path + "': " + std::strerror(errno));
    for (const std::string_view &data : pieces) {
        size_t off = 0;
        while (off < data.size()) {
            ssize_t k = ::write(fd, data.data() + off, data.size() - off);
            if (k < 0) {
                if (errno == EINTR) continue;
                int e = errno;
                ::close(fd);
                ::unlink(tmp.c_str());
                throw IoError("cannot write '" + path + "': " + std::strerror(e));
            }
            off += (size_t)k;
        }
    }
    if ((durable && ::fsync(fd) != 0) || ::close(fd) != 0) {
        int e = errno;
        ::unlink(tmp.c_str());
        throw IoError("cannot write '" + path + "': " + std::strerror(e));
    }
    // The file replaced, if any, is held open (O_PATH: no read access, no blocking on a FIFO) so that
    // rename() only unlinks it, and its blocks are freed when that descriptor is closed by a thread
    // of its own, beside the rest of the command, instead of inside rename() (where ext4 would free
    // them while the command waits). Nothing a reader sees changes: the path still switches from
    // the whole old file to the whole new one.
    const int old = ::open(path.c_str(), O_PATH | O_CLOEXEC);
    if (::rename(tmp.c_str(), path.c_str()) != 0) {
        int e = errno;
        if (old >= 0) ::close(old);
        ::unlink(tmp.c_str());
        throw IoError("cannot write '" + path + "': " + std::strerror(e));
    }
    if (old >= 0) {
        try {
            std::thread([old] { ::close(old); }).detach();
        } catch (const std::system_error &) {   // no thread: freed here, as without the hold
            ::close(old);
        }
    }
}

// A block of 256 KiB or more is mapped: the kernel's pages are zero already, and a page
// is only faulted in when the core touches it (the second FrfJob lane never touches the
// other lane's experiments), instead of all of it by memset.
static constexpr size_t MEM_MAP_MIN = (size_t)256 << 10;

static void mem_release(void *p, size_t n)
{
    if (!p) return;
    if (n >= MEM_MAP_MIN) munmap(p, n);
    else std::free(p);
}

Mem::Mem(size_t bytes)
{
    if (bytes == 0) bytes = MSID_MEM_ALIGN;
    size_t r = (bytes + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN;
    if (r >= MEM_MAP_MIN) {
        void *m = mmap(nullptr, r, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED) throw Error("out of memory (" + std::to_string(bytes) + " bytes)");
        p = m;   // page-aligned (>= MSID_MEM_ALIGN) and zero
        n = r;
        return;
    }
    p = std::aligned_alloc(MSID_MEM_ALIGN, r);
    if (!p) throw Error("out of memory (" + std::to_string(bytes) + " bytes)");
    std::memset(p, 0, r);
    n = r;
}
Mem &Mem::operator=(Mem &&o) noexcept
{
    if (this != &o) { mem_release(p, n); p = o.p; n = o.n; o.p = nullptr; o.n = 0; }
    return *this;
}
Mem::~Mem() { mem_release(p, n); }

std::string fmt(const char *f, ...)
{
    char buf[1024];
    va_list ap;
    va_start(ap, f);
    vsnprintf(buf, sizeof buf, f, ap);
    va_end(ap);
    return buf;
}

}  // namespace msidutil
