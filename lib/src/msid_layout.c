/* The memory layout helper of the core objects (see msid__layout in
 * msid_internal.h): one routine per object walks its chunks with msid__lay,
 * without memory for _mem_size, on the caller's block for _init. */
#include "msid_internal.h"

void *msid__lay(msid__layout *y, size_t n, size_t sz)
{
    void *p = y->base ? (void *)(y->base + y->size) : (void *)0;
    y->size = msid__add(y->size, msid__chunk(n, sz));
    return p;
}
