/* libFuzzer: the candump .log line parser (msid_candump_parse), and format -> parse round trips of what
 * it accepts (a parsed frame, written again, must parse to the same frame). */
#include "fuzz_util.h"
#include "msid_daq/msid_candump.h"

#include <stdio.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char line[1100];
    if (size >= sizeof line) size = sizeof line - 1;
    memcpy(line, data, size);
    line[size] = 0;
    msid_can_frame f, g;
    char ifn[32], ifn2[32], buf[256];
    if (msid_candump_parse(line, &f, ifn, sizeof ifn) != 0) return 0;
    if (msid_candump_format(buf, sizeof buf, &f, ifn) < 0) return 0;
    if (msid_candump_parse(buf, &g, ifn2, sizeof ifn2) != 0) abort();   /* what we write we must read */
    if (g.id != f.id || g.len != f.len || g.flags != f.flags || strcmp(ifn, ifn2) ||
        (!(f.id & MSID_CAN_RTR_FLAG) && memcmp(g.data, f.data, f.len)))
        abort();
    return 0;
}
