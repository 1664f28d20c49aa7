/* An out-of-tree consumer of an installed msid (tests/install/run.sh, docs/install.md): links the core
 * (msid::core / -lmsid) and the acquisition library (msid::daq / -lmsid_daq with libmodbus), and calls
 * into both, libmodbus included (a connection refused by a closed local port). Exit 0 when all is as
 * expected, 1 with a message otherwise. */
#include <msid/msid.h>
#include <msid/msid_rng.h>
#include <msid_daq/msid_daq.h>
#include <msid_daq/msid_modbus.h>

#include <stdio.h>
#include <string.h>

int main(void)
{
    msid_rng r1, r2;
    msid_rng_seed(&r1, 42);
    msid_rng_seed(&r2, 42);
    const double a = msid_rng_normal(&r1), b = msid_rng_normal(&r2);
    if (a != b) { fprintf(stderr, "consumer: the generator is not reproducible\n"); return 1; }
    const char *s = msid_strerror(MSID_E_SINGULAR);
    if (!s || !*s) { fprintf(stderr, "consumer: msid_strerror gave nothing\n"); return 1; }
    msid_modbus m;
    msid_modbus_cfg c;
    memset(&c, 0, sizeof c);
    c.host = "127.0.0.1";
    c.port = 1;   /* nothing listens: connect fails */
    c.unit = 1;
    c.response_timeout_ms = 200;
    c.byte_timeout_ms = 50;
    const int rc = msid_modbus_open(&m, &c);
    if (rc != -MSID_DAQ_E_CONNECT && rc != -MSID_DAQ_E_NOSUPPORT) {
        fprintf(stderr, "consumer: msid_modbus_open returned %d (%s)\n", rc, m.err);
        return 1;
    }
    printf("msid %s: normal %.17g; \"%s\"; modbus: %s (%s)\n", MSID_VERSION, a, s,
           msid_daq_strerror((msid_daq_status)-rc), m.err);
    return 0;
}
