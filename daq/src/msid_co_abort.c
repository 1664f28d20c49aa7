/* SDO abort codes and their names, as CiA 301 (v4.2, table 22) words them. */
#include "msid_daq/msid_co_sdo.h"

#include <stddef.h>

typedef struct abort_name {
    uint32_t code;
    const char *name;
} abort_name;

/* sorted by code (binary search) */
static const abort_name NAMES[] = {
    {0x05030000u, "toggle bit not alternated"},
    {0x05040000u, "SDO protocol timed out"},
    {0x05040001u, "client/server command specifier not valid or unknown"},
    {0x05040002u, "invalid block size (block mode only)"},
    {0x05040003u, "invalid sequence number (block mode only)"},
    {0x05040004u, "CRC error (block mode only)"},
    {0x05040005u, "out of memory"},
    {0x06010000u, "unsupported access to an object"},
    {0x06010001u, "attempt to read a write only object"},
    {0x06010002u, "attempt to write a read only object"},
    {0x06020000u, "object does not exist in the object dictionary"},
    {0x06040041u, "object cannot be mapped to the PDO"},
    {0x06040042u, "the number and length of the objects to be mapped would exceed PDO length"},
    {0x06040043u, "general parameter incompatibility reason"},
    {0x06040047u, "general internal incompatibility in the device"},
    {0x06060000u, "access failed due to a hardware error"},
    {0x06070010u, "data type does not match, length of service parameter does not match"},
    {0x06070012u, "data type does not match, length of service parameter too high"},
    {0x06070013u, "data type does not match, length of service parameter too low"},
    {0x06090011u, "sub-index does not exist"},
    {0x06090030u, "invalid value for parameter (download only)"},
    {0x06090031u, "value of parameter written too high (download only)"},
    {0x06090032u, "value of parameter written too low (download only)"},
    {0x06090036u, "maximum value is less than minimum value"},
    {0x060A0023u, "resource not available: SDO connection"},
    {0x08000000u, "general error"},
    {0x08000020u, "data cannot be transferred or stored to the application"},
    {0x08000021u, "data cannot be transferred or stored to the application because of local control"},
    {0x08000022u, "data cannot be transferred or stored to the application because of the present device state"},
    {0x08000023u, "object dictionary dynamic generation fails or no object dictionary is present"},
    {0x08000024u, "no data available"},
};

const char *msid_co_abort_name(uint32_t code)
{
    size_t lo = 0, hi = sizeof NAMES / sizeof NAMES[0];
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (NAMES[mid].code == code) return NAMES[mid].name;
        if (NAMES[mid].code < code) lo = mid + 1;
        else hi = mid;
    }
    return "unknown abort code";
}
