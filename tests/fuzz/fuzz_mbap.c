/* libFuzzer: the Modbus TCP reply reader of our own (daq/src/msid_mbap.c) against a hostile byte stream.
 * The input is everything a device sends on the connection (after a unit id and a first transaction id),
 * written into one end of a socket pair that is then shut down, so every wait ends at once (data or end
 * of stream: no timeout is ever waited for). The client issues requests until one fails. It must never
 * read out of bounds, return a reply longer than a Modbus PDU, or consume more frames than the bytes
 * hold (every frame, skipped, malformed or taken, is at least 7 + 1 bytes, a malformed one 7). Seeds in
 * corpus/fuzz_mbap: a device answering twice, stale and foreign frames before the match, a malformed
 * length and protocol id, a frame cut short, an exception reply. */
#define _DEFAULT_SOURCE
#include "fuzz_util.h"
#include "msid_daq/msid_daq.h"
#include "msid_daq/msid_mbap.h"

#include <sys/socket.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 3 || size > 16384) return 0;
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) return 0;
    msid_mbap c;
    memset(&c, 0, sizeof c);
    c.fd = sv[0];
    c.unit = data[0];
    c.tid = (uint16_t)(data[1] << 8 | data[2]);
    c.response_timeout_ms = 1000;
    c.byte_timeout_ms = 1000;
    size_t off = 3;
    while (off < size) {
        const ssize_t w = write(sv[1], data + off, size - off);
        if (w <= 0) break;
        off += (size_t)w;
    }
    shutdown(sv[1], SHUT_WR);
    const uint8_t req[5] = {4, 0, 0, 0, 1};
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    uint64_t taken = 0;
    for (int k = 0; k < 4096; ++k) {
        size_t n = 0;
        const int rc = msid_mbap_request(&c, req, sizeof req, rsp, &n);
        if (rc < 0) {
            if (rc != -MSID_DAQ_E_IO && rc != -MSID_DAQ_E_PROTOCOL && rc != -MSID_DAQ_E_TIMEOUT) abort();
            if (!c.err[0]) abort();   /* every failure says why */
            break;
        }
        if (n < 1 || n > MSID_MBAP_MAX_PDU) abort();
        taken++;
    }
    if (8 * (c.skipped + taken) + 7 * c.malformed > size - 3) abort();
    close(sv[0]);
    close(sv[1]);
    return 0;
}
