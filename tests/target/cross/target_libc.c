/* What the unit-test helpers (tests/common) need from POSIX and newlib lacks:
 * posix_memalign, here on newlib's memalign. Target test builds only. */
#include <errno.h>
#include <malloc.h>
#include <stddef.h>

int posix_memalign(void **p, size_t align, size_t n);
int posix_memalign(void **p, size_t align, size_t n)
{
    void *q = memalign(align, n);
    if (!q) return ENOMEM;
    *p = q;
    return 0;
}
