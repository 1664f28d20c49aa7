/* libFuzzer: the DBC reader (msid_dbc_mem_size, msid_dbc_init) on any text, then the codec on every
 * signal of what it accepts: decode of a payload from the input, encode of that value back (where it is
 * accepted, decoding the result gives the value again, as the codec rounds), raw get/set round trips,
 * and the lookups. mem_size and init must agree: a text that sizes must place in exactly that memory. */
#include "fuzz_util.h"
#include "msid_daq/msid_dbc.h"

#include <math.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 64) return 0;
    const uint8_t *payload = data;   /* the first 64 bytes: a payload; the rest: the DBC text */
    const char *text = (const char *)data + 64;
    const size_t len = size - 64;
    const size_t need = msid_dbc_mem_size(text, len);
    msid_dbc d;
    if (need == 0) {
        if (msid_dbc_init(&d, text, len, NULL, 0) != -MSID_DAQ_E_FORMAT || !d.err[0]) abort();
        return 0;
    }
    void *mem = fz_alloc(need);
    if (!mem) return 0;
    const int rc = msid_dbc_init(&d, text, len, mem, need);
    if (rc != 0 && (rc != -MSID_DAQ_E_FORMAT || !d.err[0] || d.err_line == 0)) abort();
    for (uint32_t i = 0; rc == 0 && i < d.n_messages; ++i) {
        const msid_dbc_message *m = &d.messages[i];
        if (msid_dbc_message_by_id(&d, m->id) != m || msid_dbc_message_by_name(&d, m->name) != m) abort();
        for (uint32_t k = 0; k < m->n_signals; ++k) {
            const msid_dbc_signal *s = &d.signals[m->first_signal + k];
            if (msid_dbc_signal_bytes(s) > m->dlc) abort();
            uint64_t raw, back;
            uint8_t p[64];
            memcpy(p, payload, 64);
            if (msid_dbc_get_raw(s, p, m->dlc, &raw) || msid_dbc_set_raw(s, raw, p, m->dlc) || memcmp(p, payload, 64))
                abort();   /* writing the raw read leaves the payload as it was */
            double v, w;
            if (msid_dbc_decode(s, p, m->dlc, &v)) abort();
            (void)msid_dbc_present(&d, s, p, m->dlc);
            if (msid_dbc_encode(s, v, p, m->dlc) == 0 && s->type == MSID_DBC_INT) {
                if (msid_dbc_decode(s, p, m->dlc, &w)) abort();
                /* the raw encoded is the nearest integer of (v - offset) / factor: decoding it again
                   gives v up to the rounding of the two conversions */
                if (isfinite(v) && isfinite(w) && fabs(w - v) > 1e-9 * fabs(v) + fabs(s->factor) && fabs(v) < 1e300)
                    abort();
            }
            if (msid_dbc_get_raw(s, p, m->dlc, &back)) abort();
        }
    }
    free(mem);
    return 0;
}
