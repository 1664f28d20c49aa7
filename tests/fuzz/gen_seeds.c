/* Writes the structured seeds of tests/fuzz/corpus/ (run once; the files are in the repository):
 *   cc -I lib/include -I daq/include tests/fuzz/gen_seeds.c build/daq/libmsid_daq.a build/lib/libmsid.a -lm
 *   ./a.out tests/fuzz/corpus
 * Seeds: a valid design upload (fuzz_can_config), a clean experiment of frames in the harness's format
 * (fuzz_can_decoder), and a consistent device header with its ring (fuzz_mb_acq). */
#include "msid/msid.h"
#include "msid_daq/msid_params.h"
#include "msid_daq/msid_mb_proto.h"

#include <stdio.h>
#include <string.h>

static FILE *open_seed(const char *dir, const char *h, const char *name)
{
    char p[512];
    snprintf(p, sizeof p, "%s/%s/%s", dir, h, name);
    FILE *f = fopen(p, "wb");
    if (!f) { perror(p); return NULL; }
    return f;
}

static void put_frame(FILE *f, uint32_t id, uint8_t len, uint8_t flags, const uint8_t *d)
{
    uint8_t h[6] = {(uint8_t)id, (uint8_t)(id >> 8), (uint8_t)(id >> 16), (uint8_t)(id >> 24), len, flags};
    fwrite(h, 1, 6, f);
    fwrite(d, 1, len, f);
}

static msid_params CFG;

int main(int argc, char **argv)
{
    const char *dir = argc > 1 ? argv[1] : "corpus";
    /* 1. a design upload: 16-sample period, lines 1 and 3, 1 input, 1 experiment, 4 periods */
    memset(&CFG, 0, sizeof CFG);
    CFG.period = 16; CFG.n_lines = 2; CFG.n_inputs = 1; CFG.n_experiments = 1; CFG.bins[0] = 1; CFG.bins[1] = 3;
    CFG.phase_mode = MSID_PHASE_RANDOM; CFG.seed = 7; CFG.encoding = MSID_CAN_ENC_S16; CFG.scale = 0.001f;
    CFG.periods = 4;
    uint8_t rec[64][8];
    const size_t n = msid_params_frames(&CFG, rec, 64);
    FILE *f = open_seed(dir, "fuzz_can_config", "upload");
    if (!f) return 1;
    fwrite(rec, 8, n, f);
    fclose(f);
    /* 2. frames: P = 8 (first byte 0), nu = 1, ny = 1, m = 1, S16 classic, window 16, bounded, K = 2 */
    for (int variant = 0; variant < 2; ++variant) {
        f = open_seed(dir, "fuzz_can_decoder", variant ? "done-beyond" : "clean");
        if (!f) return 1;
        const uint8_t cfg[9] = {0, 0, 0, 0, 0, 0, 15, 1, 0};
        fwrite(cfg, 1, sizeof cfg, f);
        uint8_t d[64];
        msid_can_encode_state(d, MSID_CAN_STATE_RUNNING, 0, 0, 16);
        put_frame(f, 0x202, 8, 0, d);
        for (uint32_t s = 0; s < 16; ++s) {
            const double row[2] = {0.1 * s, -0.05 * s};
            msid_can_encode_sample(d, MSID_CAN_ENC_S16, 0, 0, s, 0,
                                   (s % 8 == 0 ? MSID_CAN_PSTART : 0u) | (s == 0 ? MSID_CAN_SEGSTART : 0u), row, 2, 0.001);
            put_frame(f, 0x200 + msid_can_chunk_id(MSID_CAN_ENC_S16, 0, 0), 8, 0, d);
        }
        msid_can_encode_state(d, MSID_CAN_STATE_DONE, 0, 0, variant ? 0xFFFFFFFFu : 16);
        put_frame(f, 0x202, 8, 0, d);
        memset(d, 0, 8);
        d[1] = 0x04;
        put_frame(f, 0x20000044u | 0x80000000u, 8, 0, d);   /* an error frame: controller + bus-off */
        fclose(f);
    }
    /* 3. Modbus: int16, ABCD, K = 2 (P = 16): the headers the poller reads and a ring of 32 samples */
    f = open_seed(dir, "fuzz_mb_acq", "clean");
    if (!f) return 1;
    const uint8_t sel[3] = {0, 0, 0};
    fwrite(sel, 1, 3, f);
    const uint32_t W = msid_mb_sample_regs(MSID_MB_ENC_S16, 2);
    for (int k = 0; k < 4; ++k) {   /* command: header, header; poll: header; ring read follows */
        msid_mb_header h;
        memset(&h, 0, sizeof h);
        h.magic = MSID_MB_MAGIC; h.version = MSID_MB_PROTO_VERSION; h.state = k < 2 ? MSID_MB_STATE_RUNNING : MSID_MB_STATE_DONE;
        h.nu = 1; h.ny = 1; h.sample_regs = W; h.ring_addr = MSID_MB_RING_ADDR; h.ring_samples = 100;
        h.write_index = k < 2 ? 0 : 32; h.total = 32; h.period = 16; h.periods = 2; h.cmd_done = 1;
        uint16_t r[MSID_MB_IR_HEADER];
        msid_mb_header_encode(r, &h);
        fwrite(r, 2, MSID_MB_IR_HEADER, f);
        if (k == 3) {
            uint16_t ring[32 * 3];
            for (uint32_t s = 0; s < 32; ++s) {
                ring[s * W] = (uint16_t)s;
                msid_mb_encode_value(ring + s * W + 1, 0.01 * s, MSID_MB_ENC_S16, 0, 0.001);
                msid_mb_encode_value(ring + s * W + 2, -0.02 * s, MSID_MB_ENC_S16, 0, 0.001);
            }
            fwrite(ring, 2, 32 * W, f);
        }
    }
    fclose(f);
    return 0;
}
