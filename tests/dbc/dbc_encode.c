/* The encoding side of daq's DBC codec for tests/dbc/test_dbc_peer.py (msid's command line decodes,
 * `msid can decode`; nothing a user types encodes, so this test program does). Reads a DBC file, then
 * one request per stdin line:
 *     MESSAGE HEX SIGNAL VALUE [SIGNAL VALUE ...]
 * HEX is the starting payload (its length is the payload's), each VALUE a C99 number (the test writes
 * Python's float.hex(): exact). Each signal is encoded in turn with msid_dbc_encode; the answer line is
 *     HEX FLAGS
 * the payload after, and one flag per signal: '.' encoded, 'R' refused (-MSID_DAQ_E_RANGE), 'S' payload
 * too short, '?' no such signal. A line naming no message of the file answers "? ". Exit 1 on a DBC the
 * reader refuses (its message on stderr). `dbc_encode FILE.dbc --list` prints the tables the reader
 * built instead, for the test to hold against cantools':
 *     M ID DLC CYCLE_MS NAME                        (ID in hex, with 'x' before an extended one)
 *     S NAME START LENGTH ORDER SIGNED TYPE MUX MUXVALUE FACTOR OFFSET MIN MAX UNIT   (numbers as %a) */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "msid_daq/msid_dbc.h"

static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int main(int argc, char **argv)
{
    if (argc != 2 && !(argc == 3 && !strcmp(argv[2], "--list"))) {
        fprintf(stderr, "usage: dbc_encode FILE.dbc [--list] < requests\n");
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    if (!f) {
        perror(argv[1]);
        return 1;
    }
    static char text[1 << 24];
    const size_t len = fread(text, 1, sizeof text, f);
    fclose(f);
    const size_t need = msid_dbc_mem_size(text, len);
    msid_dbc d;
    void *mem = need ? aligned_alloc(8, (need + 7) / 8 * 8) : NULL;
    if (msid_dbc_init(&d, text, len, mem, need)) {
        fprintf(stderr, "%s: %s\n", argv[1], d.err);
        return 1;
    }
    if (argc == 3) {
        for (uint32_t i = 0; i < d.n_messages; ++i) {
            const msid_dbc_message *m = &d.messages[i];
            printf("M %s%X %u %u %s\n", (m->id & MSID_CAN_EFF_FLAG) ? "x" : "", (unsigned)(m->id & 0x1FFFFFFFu),
                   (unsigned)m->dlc, (unsigned)m->cycle_ms, m->name);
            for (uint32_t k = 0; k < m->n_signals; ++k) {
                const msid_dbc_signal *g = &d.signals[m->first_signal + k];
                printf("S %s %u %u %u %u %u %u %u %a %a %a %a %s\n", g->name, (unsigned)g->start, (unsigned)g->length,
                       g->order, g->is_signed, g->type, g->mux, (unsigned)g->mux_value, g->factor, g->offset, g->min,
                       g->max, g->unit);
            }
        }
        free(mem);
        return 0;
    }
    static char line[1 << 20];
    while (fgets(line, sizeof line, stdin)) {
        char *save = NULL;
        const char *msg = strtok_r(line, " \n", &save), *hex = strtok_r(NULL, " \n", &save);
        const msid_dbc_message *m = msg ? msid_dbc_message_by_name(&d, msg) : NULL;
        if (!m || !hex) {
            printf("? \n");
            continue;
        }
        uint8_t data[64];
        size_t n = 0;
        for (; hex[2 * n] && hex[2 * n + 1] && n < sizeof data; ++n)
            data[n] = (uint8_t)(hexval(hex[2 * n]) << 4 | hexval(hex[2 * n + 1]));
        char flags[4096];
        size_t nf = 0;
        const char *sig;
        while ((sig = strtok_r(NULL, " \n", &save)) != NULL && nf + 1 < sizeof flags) {
            const char *val = strtok_r(NULL, " \n", &save);
            const msid_dbc_signal *s = msid_dbc_signal_by_name(&d, m, sig);
            if (!s || !val) {
                flags[nf++] = '?';
                continue;
            }
            const int rc = msid_dbc_encode(s, strtod(val, NULL), data, n);
            flags[nf++] = rc == 0 ? '.' : rc == -MSID_DAQ_E_RANGE ? 'R' : 'S';
        }
        flags[nf] = 0;
        for (size_t k = 0; k < n; ++k) printf("%02X", data[k]);
        printf(" %s\n", flags);
    }
    free(mem);
    return 0;
}
