/* A node's object dictionary (msid_co_eds.h): lookup, data type sizes and names, and the checks made before
   a write or a PDO mapping. The file is read by msid_co_eds_file.cpp. */
#include "msid_daq/msid_co_eds.h"

#include <stdio.h>

const msid_co_od_entry *msid_co_eds_find(const msid_co_eds *eds, uint16_t index, uint8_t sub)
{
    if (!eds || !eds->e) return NULL;
    const uint32_t key = (uint32_t)index << 8 | sub;
    uint32_t lo = 0, hi = eds->n;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        const uint32_t k = (uint32_t)eds->e[mid].index << 8 | eds->e[mid].sub;
        if (k == key) return &eds->e[mid];
        if (k < key) lo = mid + 1;
        else hi = mid;
    }
    return NULL;
}

typedef struct type_info {
    uint16_t type;
    unsigned bits;
    const char *name;
} type_info;

/* CiA 301 table 44's basic types */
static const type_info TYPES[] = {
    {0x0001, 1, "BOOLEAN"},       {0x0002, 8, "INTEGER8"},     {0x0003, 16, "INTEGER16"},  {0x0004, 32, "INTEGER32"},
    {0x0005, 8, "UNSIGNED8"},     {0x0006, 16, "UNSIGNED16"},  {0x0007, 32, "UNSIGNED32"}, {0x0008, 32, "REAL32"},
    {0x0009, 0, "VISIBLE_STRING"}, {0x000A, 0, "OCTET_STRING"}, {0x000B, 0, "UNICODE_STRING"},
    {0x000C, 48, "TIME_OF_DAY"},  {0x000D, 48, "TIME_DIFFERENCE"}, {0x000F, 0, "DOMAIN"},
    {0x0010, 24, "INTEGER24"},    {0x0011, 64, "REAL64"},      {0x0012, 40, "INTEGER40"},  {0x0013, 48, "INTEGER48"},
    {0x0014, 56, "INTEGER56"},    {0x0015, 64, "INTEGER64"},   {0x0016, 24, "UNSIGNED24"}, {0x0018, 40, "UNSIGNED40"},
    {0x0019, 48, "UNSIGNED48"},   {0x001A, 56, "UNSIGNED56"},  {0x001B, 64, "UNSIGNED64"},
};

static const type_info *type_of(uint16_t type)
{
    for (size_t i = 0; i < sizeof TYPES / sizeof TYPES[0]; i++)
        if (TYPES[i].type == type) return &TYPES[i];
    return NULL;
}

unsigned msid_co_type_bits(uint16_t type)
{
    const type_info *t = type_of(type);
    return t ? t->bits : 0;
}

const char *msid_co_type_name(uint16_t type)
{
    const type_info *t = type_of(type);
    return t ? t->name : "unknown type";
}

static int readonly(const msid_co_od_entry *e) { return e->access == MSID_CO_RO || e->access == MSID_CO_CONST; }

/* the entry, or a message naming it missing */
static const msid_co_od_entry *known(const msid_co_eds *eds, uint16_t index, uint8_t sub, const char *what, char *err,
                                     size_t len)
{
    const msid_co_od_entry *e = msid_co_eds_find(eds, index, sub);
    if (!e)
        snprintf(err, len, "%s0x%04X:%02X is not in %s", what, (unsigned)index, (unsigned)sub, eds->source);
    return e;
}

int msid_co_eds_check_write(const msid_co_eds *eds, uint16_t index, uint8_t sub, size_t bytes, char *err, size_t len)
{
    const msid_co_od_entry *e = known(eds, index, sub, "", err, len);
    if (!e) return -MSID_DAQ_E_ARG;
    if (readonly(e)) {
        snprintf(err, len, "0x%04X:%02X (%s) is read only in %s line %u", (unsigned)index, (unsigned)sub, e->name,
                 eds->source, (unsigned)e->line);
        return -MSID_DAQ_E_ARG;
    }
    const unsigned bits = msid_co_type_bits(e->type);
    if (bits >= 8 && bytes * 8 != bits) {
        snprintf(err, len, "0x%04X:%02X (%s) is %s (%u bytes) in %s, not %zu bytes", (unsigned)index, (unsigned)sub,
                 e->name, msid_co_type_name(e->type), bits / 8, eds->source, bytes);
        return -MSID_DAQ_E_ARG;
    }
    return 0;
}

int msid_co_eds_check_pdo(const msid_co_eds *eds, const msid_co_pdo_cfg *c, char *err, size_t len)
{
    char what[32];
    for (unsigned i = 0; i < c->n && i < MSID_CO_PDO_MAX_ENTRIES; i++) {
        const msid_co_pdo_entry *m = &c->e[i];
        snprintf(what, sizeof what, "%s%u maps ", c->tx ? "TPDO" : "RPDO", (unsigned)c->num);
        const msid_co_od_entry *e = known(eds, m->index, m->sub, what, err, len);
        if (!e) return -MSID_DAQ_E_ARG;
        const char *problem = NULL;
        if (!e->pdo_mappable) problem = "is not PDO-mappable";
        else if (!c->tx && readonly(e)) problem = "is read only: it cannot be a target msid writes";
        else if (c->tx && e->access == MSID_CO_WO) problem = "is write only: the node cannot send it";
        if (problem) {
            snprintf(err, len, "%s0x%04X:%02X (%s), which %s (%s line %u)", what, (unsigned)m->index, (unsigned)m->sub,
                     e->name, problem, eds->source, (unsigned)e->line);
            return -MSID_DAQ_E_ARG;
        }
        const unsigned bits = msid_co_type_bits(e->type);
        if (bits && bits != m->bits) {
            snprintf(err, len, "%s0x%04X:%02X (%s) with %u bits: it is %s, %u bits (%s line %u)", what, (unsigned)m->index,
                     (unsigned)m->sub, e->name, (unsigned)m->bits, msid_co_type_name(e->type), bits, eds->source,
                     (unsigned)e->line);
            return -MSID_DAQ_E_ARG;
        }
    }
    return 0;
}
