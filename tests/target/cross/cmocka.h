/* cmocka-compatible shim for the target builds only (cmocka is not built for
 * arm-none-eabi). It implements the subset tests/unit uses, with the same
 * meaning: cmocka_unit_test, cmocka_run_group_tests (group setup/teardown),
 * assert_true/false/int_equal/int_not_equal/non_null/null/memory_equal/
 * string_equal, fail, fail_msg, skip, print_message, print_error.
 * A failed assertion prints file:line and longjmps out of the test; the
 * group's return value is the number of failed tests (as in cmocka), which
 * main() returns and the board's startup passes to exit() over semihosting.
 * Host builds keep using the real cmocka (tests/CMakeLists.txt). */
#ifndef MSID_CMOCKA_SHIM_H
#define MSID_CMOCKA_SHIM_H

#include <setjmp.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

/* CM_SHIM_SKIP (a compile definition, e.g. "test_a,test_b") names tests this
 * build reports as skipped without running them; the build says why. */
#ifndef CM_SHIM_SKIP
#define CM_SHIM_SKIP ""
#endif

typedef void (*CMUnitTestFunction)(void **state);
typedef int (*CMFixtureFunction)(void **state);

struct CMUnitTest {
    const char *name;
    CMUnitTestFunction test_func;
    CMFixtureFunction setup_func;
    CMFixtureFunction teardown_func;
    void *initial_state;
};

#define cmocka_unit_test(f) { #f, f, NULL, NULL, NULL }
#define cmocka_unit_test_setup_teardown(f, s, t) { #f, f, s, t, NULL }

static jmp_buf cm_shim_jmp;   /* longjmp value: 1 failed, 2 skipped */

#define print_message(...) printf(__VA_ARGS__)
#define print_error(...) printf(__VA_ARGS__)

static void cm_shim_fail(const char *file, int line, const char *what)
{
    printf("%s:%d: %s\n", file, line, what);
    longjmp(cm_shim_jmp, 1);
}

#define fail() cm_shim_fail(__FILE__, __LINE__, "fail()")
#define fail_msg(...) do { printf(__VA_ARGS__); printf("\n"); fail(); } while (0)
#define skip() longjmp(cm_shim_jmp, 2)
#define assert_true(c) do { if (!(c)) cm_shim_fail(__FILE__, __LINE__, "assert_true(" #c ")"); } while (0)
#define assert_false(c) do { if (c) cm_shim_fail(__FILE__, __LINE__, "assert_false(" #c ")"); } while (0)
#define assert_non_null(p) assert_true((p) != NULL)
#define assert_null(p) assert_true((p) == NULL)
#define assert_int_equal(a, b) do { const uintmax_t cm_a_ = (uintmax_t)(a), cm_b_ = (uintmax_t)(b); \
        if (cm_a_ != cm_b_) { printf("%lld != %lld\n", (long long)cm_a_, (long long)cm_b_); \
            cm_shim_fail(__FILE__, __LINE__, "assert_int_equal(" #a ", " #b ")"); } } while (0)
#define assert_int_not_equal(a, b) assert_true((uintmax_t)(a) != (uintmax_t)(b))
#define assert_memory_equal(a, b, n) assert_true(memcmp((a), (b), (n)) == 0)
#define assert_string_equal(a, b) assert_true(strcmp((a), (b)) == 0)

static int cm_shim_run(const char *group, const struct CMUnitTest *t, size_t n,
                       CMFixtureFunction gsetup, CMFixtureFunction gteardown)
{
    void *gstate = NULL;
    int failed = 0;
    printf("[==========] %s: running %u test(s).\n", group, (unsigned)n);
    if (gsetup && gsetup(&gstate) != 0) { printf("[  ERROR   ] group setup failed\n"); return (int)n; }
    for (size_t i = 0; i < n; ++i) {
        void *state = t[i].initial_state ? t[i].initial_state : gstate;
        printf("[ RUN      ] %s\n", t[i].name);
        const size_t nl = strlen(t[i].name);
        const char *hit = strstr(CM_SHIM_SKIP, t[i].name);
        if (hit && (hit == CM_SHIM_SKIP || hit[-1] == ',') && (hit[nl] == ',' || hit[nl] == 0)) {
            printf("[  SKIPPED ] %s (not run on this target, see tests/target/cross/CMakeLists.txt)\n", t[i].name);
            continue;
        }
        const clock_t t0 = clock();   /* semihosting SYS_CLOCK: the emulator's time, informative */
        if (t[i].setup_func && t[i].setup_func(&state) != 0) {
            printf("[  FAILED  ] %s (setup)\n", t[i].name);
            failed++;
            continue;
        }
        const int r = setjmp(cm_shim_jmp);
        if (r == 0) t[i].test_func(&state);
        if (t[i].teardown_func) t[i].teardown_func(&state);
        if (r == 1) { printf("[  FAILED  ] %s\n", t[i].name); failed++; }
        else if (r == 2) printf("[  SKIPPED ] %s\n", t[i].name);
        else printf("[       OK ] %s (%ld ms)\n", t[i].name, (long)((clock() - t0) * 1000 / CLOCKS_PER_SEC));
    }
    if (gteardown) gteardown(&gstate);
    printf("[==========] %s: %u test(s) run, %d failed.\n", group, (unsigned)n, failed);
    return failed;
}

#define cmocka_run_group_tests(tests, gs, gt) \
    cm_shim_run(#tests, (tests), sizeof(tests) / sizeof((tests)[0]), (gs), (gt))

#endif
