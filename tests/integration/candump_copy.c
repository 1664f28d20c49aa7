/* candump_copy IN OUT: read a candump .log with msid's replay reader (msid_candump_open/recv) and
 * write every frame again with msid's writer (msid_candump_format), as `msid can measure --log` does.
 * The tests (test_can_replay_sessions.py) use it to get logs written by msid without a CAN bus:
 * direction T/R kept, python-can reads the copy, the copy of python-can's log replays the same. */
#include <stdio.h>
#include "msid_daq/msid_candump.h"

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: candump_copy IN.log OUT.log\n");
        return 2;
    }
    msid_candump_reader r;
    if (msid_candump_open(&r, argv[1]) < 0) {
        fprintf(stderr, "candump_copy: %s\n", r.err);
        return 1;
    }
    FILE *out = fopen(argv[2], "w");
    if (!out) {
        fprintf(stderr, "candump_copy: cannot write '%s'\n", argv[2]);
        msid_can_close(&r.tr);
        return 1;
    }
    msid_can_frame f[64];
    char buf[256];
    int k, rc = 0;
    while ((k = msid_can_recv(&r.tr, f, 64, 0)) > 0)
        for (int i = 0; i < k; ++i) {
            const int n = msid_candump_format(buf, sizeof buf, &f[i], r.iface);
            if (n < 0 || fwrite(buf, 1, (size_t)n, out) != (size_t)n) rc = 1;
        }
    if (k != -MSID_DAQ_E_EOF) {
        fprintf(stderr, "candump_copy: %s\n", msid_can_error(&r.tr));
        rc = 1;
    }
    if (fclose(out) != 0) rc = 1;
    msid_can_close(&r.tr);
    return rc;
}
