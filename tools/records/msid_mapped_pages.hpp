// The pages of a mapped experiment file that a reader of its samples has gone past (FileBytes maps
// the whole file): given back to the kernel, so that a record read in place costs the memory of the
// block in use, not of the file. The samples stay readable: a page touched again is read from the
// file again (a private read-only mapping is never written).
#pragma once
#include <cstddef>

namespace msidrec {

// Release the whole pages inside [p, p + n) when they belong to a file that FileBytes has mapped;
// anything else (a file read from a pipe into memory, a caller's array) is left alone.
void release_mapped(const void *p, size_t n);

}  // namespace msidrec
