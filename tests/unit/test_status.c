/* msid_strerror: one distinct, non-empty message per status; a fixed text otherwise. */
#include "unit_util.h"

static const char *UNKNOWN = "unknown msid status";

static void test_codes_are_dense_and_ordered(void **state)
{
    (void)state;
    /* MSID_OK is zero and every error is positive (header contract). */
    assert_int_equal(MSID_OK, 0);
    assert_true((int)MSID_E_NULL > 0);
    assert_true((int)MSID_E_RANGE == (int)MSID_E_COUNT_ - 1);
}

static void test_every_code_has_distinct_message(void **state)
{
    (void)state;
    for (int s = 0; s < (int)MSID_E_COUNT_; ++s) {
        const char *m = msid_strerror((msid_status)s);
        UT_CHECK(m != NULL, "status %d", s);
        UT_CHECK(m[0] != '\0', "status %d has an empty message", s);
        UT_CHECK(strcmp(m, UNKNOWN) != 0, "status %d falls through to the unknown text", s);
        for (int t = 0; t < s; ++t)
            UT_CHECK(strcmp(m, msid_strerror((msid_status)t)) != 0,
                     "statuses %d and %d share the message \"%s\"", t, s, m);
    }
}

static void test_unknown_values(void **state)
{
    (void)state;
    const int bad[] = {(int)MSID_E_COUNT_, (int)MSID_E_COUNT_ + 1, 1000, -1, -1000};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        const char *m = msid_strerror((msid_status)bad[k]);
        UT_CHECK(m != NULL && strcmp(m, UNKNOWN) == 0, "value %d gave \"%s\"", bad[k], m ? m : "(null)");
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_codes_are_dense_and_ordered),
        cmocka_unit_test(test_every_code_has_distinct_message),
        cmocka_unit_test(test_unknown_values),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
