// The registry of temporary files being written (msid_partial_file.hpp).
#include "msid_partial_file.hpp"

#include <atomic>
#include <cstring>
#include <unistd.h>

namespace msidutil {

namespace {
constexpr int SLOTS = 32;
constexpr size_t PATH_MAX_BYTES = 4096;
enum : int { FREE = 0, FILLING = 1, HELD = 2 };
struct Slot {
    std::atomic<int> state{FREE};   // lock-free: read by a signal handler
    char path[PATH_MAX_BYTES];
};
Slot g_slots[SLOTS];
static_assert(std::atomic<int>::is_always_lock_free, "the handler reads the slots' states");
}  // namespace

PartialFile::PartialFile(const std::string &tmp_path)
{
    if (tmp_path.size() >= PATH_MAX_BYTES) return;
    for (int i = 0; i < SLOTS; ++i) {
        int expected = FREE;
        if (!g_slots[i].state.compare_exchange_strong(expected, FILLING)) continue;
        std::memcpy(g_slots[i].path, tmp_path.c_str(), tmp_path.size() + 1);
        g_slots[i].state.store(HELD);
        slot_ = i;
        return;
    }
}

PartialFile::~PartialFile()
{
    if (slot_ >= 0) g_slots[slot_].state.store(FREE);
}

void remove_partial_files() noexcept
{
    for (int i = 0; i < SLOTS; ++i)
        if (g_slots[i].state.load() == HELD) ::unlink(g_slots[i].path);   // renamed already: ENOENT, nothing
}

}  // namespace msidutil
