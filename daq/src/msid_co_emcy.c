/* CANopen emergency messages: decoding and the names of CiA 301's error codes (table 21) and of the
   CiA 402 drive codes msid is most likely to meet. */
#include "msid_daq/msid_co_emcy.h"

#include <stdio.h>
#include <string.h>

typedef struct code_name {
    uint16_t code, mask;  /* a code matches when (code & mask) == this code */
    const char *name;
} code_name;

/* the most specific first: exact codes, then classes by high byte, then by high nibble */
static const code_name NAMES[] = {
    {0x2310u, 0xFFFFu, "continuous over current"},
    {0x3210u, 0xFFFFu, "DC link over-voltage"},
    {0x3220u, 0xFFFFu, "DC link under-voltage"},
    {0x4310u, 0xFFFFu, "excess temperature drive"},
    {0x7121u, 0xFFFFu, "motor blocked"},
    {0x8110u, 0xFFFFu, "CAN overrun (objects lost)"},
    {0x8120u, 0xFFFFu, "CAN in error passive mode"},
    {0x8130u, 0xFFFFu, "life guard error or heartbeat error"},
    {0x8140u, 0xFFFFu, "recovered from bus off"},
    {0x8150u, 0xFFFFu, "CAN-ID collision"},
    {0x8210u, 0xFFFFu, "PDO not processed due to length error"},
    {0x8220u, 0xFFFFu, "PDO length exceeded"},
    {0x8230u, 0xFFFFu, "DAM MPDO not processed, destination object not available"},
    {0x8240u, 0xFFFFu, "unexpected SYNC data length"},
    {0x8250u, 0xFFFFu, "RPDO timeout"},
    {0x8611u, 0xFFFFu, "following error"},
    {0x0000u, 0xFF00u, "error reset or no error"},
    {0x1000u, 0xFF00u, "generic error"},
    {0x2100u, 0xFF00u, "current, device input side"},
    {0x2200u, 0xFF00u, "current inside the device"},
    {0x2300u, 0xFF00u, "current, device output side"},
    {0x3100u, 0xFF00u, "mains voltage"},
    {0x3200u, 0xFF00u, "voltage inside the device"},
    {0x3300u, 0xFF00u, "output voltage"},
    {0x4100u, 0xFF00u, "ambient temperature"},
    {0x4200u, 0xFF00u, "device temperature"},
    {0x6100u, 0xFF00u, "internal software"},
    {0x6200u, 0xFF00u, "user software"},
    {0x6300u, 0xFF00u, "data set"},
    {0x8100u, 0xFF00u, "communication"},
    {0x8200u, 0xFF00u, "protocol error"},
    {0x9000u, 0xFF00u, "external error"},
    {0xF000u, 0xFF00u, "additional functions"},
    {0xFF00u, 0xFF00u, "device specific"},
    {0x2000u, 0xF000u, "current"},
    {0x3000u, 0xF000u, "voltage"},
    {0x4000u, 0xF000u, "temperature"},
    {0x5000u, 0xF000u, "device hardware"},
    {0x6000u, 0xF000u, "device software"},
    {0x7000u, 0xF000u, "additional modules"},
    {0x8000u, 0xF000u, "monitoring"},
};

const char *msid_co_emcy_name(uint16_t code)
{
    for (size_t i = 0; i < sizeof NAMES / sizeof NAMES[0]; i++)
        if ((code & NAMES[i].mask) == NAMES[i].code) return NAMES[i].name;
    return "unknown error code";
}

int msid_co_emcy_decode(const msid_can_frame *f, unsigned node, msid_co_emcy *e)
{
    if (!msid_co_node_valid(node) || (f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) ||
        f->id != MSID_CO_COB_EMCY + node)
        return 0;
    if (f->len != 8) return -MSID_DAQ_E_PROTOCOL;
    e->node = (uint8_t)node;
    e->code = (uint16_t)(f->data[0] | f->data[1] << 8);
    e->reg = f->data[2];
    memcpy(e->mfr, &f->data[3], 5);
    return 1;
}

/* the error register's bits, by name, "none" for 0 */
void msid_co_erreg_describe(uint8_t reg, char *buf, size_t n)
{
    static const char *const BITS[8] = {"generic", "current", "voltage", "temperature",
                                        "communication", "device profile", "bit 6", "manufacturer"};
    size_t at = 0;
    buf[0] = '\0';
    for (int b = 0; b < 8; b++) {
        if (!(reg & (1u << b))) continue;
        const int w = snprintf(buf + at, n - at, "%s%s", at ? ", " : "", BITS[b]);
        if (w < 0 || (size_t)w >= n - at) break;
        at += (size_t)w;
    }
    if (!at) snprintf(buf, n, "none");
}

int msid_co_emcy_describe(const msid_co_emcy *e, char *buf, size_t n)
{
    char bits[96];
    msid_co_erreg_describe(e->reg, bits, sizeof bits);
    return snprintf(buf, n,
                    "node %u EMCY 0x%04X (%s), error register 0x%02X (%s), manufacturer bytes %02X %02X %02X %02X %02X",
                    (unsigned)e->node, (unsigned)e->code, msid_co_emcy_name(e->code), (unsigned)e->reg, bits,
                    (unsigned)e->mfr[0], (unsigned)e->mfr[1], (unsigned)e->mfr[2], (unsigned)e->mfr[3],
                    (unsigned)e->mfr[4]);
}
