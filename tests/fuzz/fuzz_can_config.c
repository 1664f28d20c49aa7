/* libFuzzer: the design upload (msid-can/1 parameter records, also carried by Modbus) as a device and
 * `msid can replay` read it: 8-byte records into msid_params_feed; a committed set is turned into a
 * design (crest factors off, as on a device) and its counts must be within what a design allows. */
#include "fuzz_util.h"
#include "msid/msid.h"
#include "msid_daq/msid_params.h"

static msid_params CFG;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    msid_params_reset(&CFG);
    for (size_t i = 0; i + 8 <= size; i += 8) {
        uint8_t rec[8];
        memcpy(rec, data + i, 8);
        /* a valid COMMIT needs the running CRC: let every 4th commit carry it */
        if (rec[0] == MSID_CAN_P_COMMIT && (rec[1] & 3) == 0 && CFG.open) msid_can_put_u32(rec + 4, CFG.run_crc);
        if (msid_params_feed(&CFG, rec, 8, MSID_CAN_PROTO_VERSION) != 1) continue;
        if (CFG.periods < 2 || CFG.periods > MSID_PARAMS_MAX_PERIODS || CFG.period < MSID_MIN_PERIOD ||
            CFG.period > MSID_MAX_PERIOD)
            abort();   /* a committed set must be within the design's ranges */
        if (CFG.period > (1u << 16)) continue;   /* keep one run fast; the ranges are checked above */
        const size_t nt = msid_twiddle_mem_size(CFG.period);
        void *mt = fz_alloc(nt);
        msid_twiddle tw;
        if (!mt || msid_twiddle_init(&tw, CFG.period, mt, nt) != MSID_OK) abort();
        msid_design_cfg dc;
        msid_params_design_cfg(&CFG, &dc, &tw);
        const size_t nd = msid_design_mem_size(&dc);
        void *md = nd ? fz_alloc(nd) : NULL;
        msid_design d;
        if (md) (void)msid_design_init(&d, &dc, md, nd);
        free(md);
        free(mt);
    }
    return 0;
}
