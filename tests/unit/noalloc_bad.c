/* Deliberately violates the core's rules: allocates and prints. Built only
 * to prove that the noalloc checker detects such references. */
#include <stdio.h>
#include <stdlib.h>

int msid_noalloc_bad(int n)
{
    int *p = (int *)malloc(sizeof(int) * (size_t)(n > 0 ? n : 1));
    if (!p) return -1;
    p[0] = n;
    printf("%d %p\n", n, (void *)p);
    const int v = p[0];
    free(p);
    return v;
}
