/* CANopen PDO configuration by SDO in CiA 301's order, the check that comes before any write, what the
   node held saved and written back, and the communication cycle period 0x1006. */
#include "msid_daq/msid_co_pdo.h"

#include <stdio.h>
#include <string.h>

#define SUB_COB_ID 1u
#define SUB_TRANS_TYPE 2u
#define SUB_INHIBIT 3u
#define ABORT_NO_SUBINDEX 0x06090011u

uint16_t msid_co_pdo_comm_index(unsigned tx, unsigned num)
{
    return (uint16_t)((tx ? 0x1800u : 0x1400u) + (num - 1u));
}

uint32_t msid_co_pdo_map_value(const msid_co_pdo_entry *e)
{
    return (uint32_t)e->index << 16 | (uint32_t)e->sub << 8 | e->bits;
}

unsigned msid_co_pdo_bits(const msid_co_pdo_cfg *c)
{
    unsigned bits = 0;
    for (unsigned i = 0; i < c->n && i < MSID_CO_PDO_MAX_ENTRIES; i++) bits += c->e[i].bits;
    return bits;
}

static const char *kind(unsigned tx) { return tx ? "TPDO" : "RPDO"; }

/* CiA 301's restricted COB-IDs (NMT, SYNC/EMCY's reserved part, TIME, SDO, NMT error control, LSS) */
static int cob_restricted(uint32_t id)
{
    return id <= 0x07Fu || (id >= 0x101u && id <= 0x180u) || (id >= 0x581u && id <= 0x5FFu) ||
           (id >= 0x601u && id <= 0x67Fu) || (id >= 0x6E0u && id <= 0x6FFu) || id >= 0x701u;
}

/* the predefined connection set's COB-ID of PDO num (1..4) of node, 0 beyond */
static uint32_t default_cob(unsigned tx, unsigned num, unsigned node)
{
    if (num < 1 || num > 4) return 0;
    return (tx ? 0x180u : 0x200u) + 0x100u * (num - 1u) + node;
}

static uint32_t cob_of(const msid_co_pdo_cfg *c, unsigned node)
{
    return c->cob_id ? (c->cob_id & 0x7FFu) : default_cob(c->tx, c->num, node);
}

static int check_entries(const msid_co_pdo_cfg *c, char *err, size_t len)
{
    if (c->n > MSID_CO_PDO_MAX_ENTRIES) {
        snprintf(err, len, "%s%u maps %u entries: at most %u fit in a PDO of 8 bytes", kind(c->tx), (unsigned)c->num,
                 (unsigned)c->n, MSID_CO_PDO_MAX_ENTRIES);
        return -MSID_DAQ_E_ARG;
    }
    for (unsigned i = 0; i < c->n; i++)
        if (c->e[i].bits == 0 || c->e[i].bits > 64) {
            snprintf(err, len, "%s%u entry %u (0x%04X:%02X) is %u bits long (1..64)", kind(c->tx), (unsigned)c->num,
                     i + 1, (unsigned)c->e[i].index, (unsigned)c->e[i].sub, (unsigned)c->e[i].bits);
            return -MSID_DAQ_E_ARG;
        }
    const unsigned bits = msid_co_pdo_bits(c);
    if (bits > 64) {
        snprintf(err, len, "%s%u maps %u bits (%u bytes): a PDO carries at most 8 bytes", kind(c->tx),
                 (unsigned)c->num, bits, (bits + 7) / 8);
        return -MSID_DAQ_E_ARG;
    }
    return 0;
}

static int check_transmission(const msid_co_pdo_cfg *c, char *err, size_t len)
{
    const unsigned t = c->trans_type;
    const int ok = t <= 240u || t == 254u || t == 255u || (c->tx && (t == 252u || t == 253u));
    if (!ok) {
        snprintf(err, len, "%s%u: transmission type %u is not one a%s takes (0..240, %s254, 255)", kind(c->tx),
                 (unsigned)c->num, t, c->tx ? " TPDO" : "n RPDO", c->tx ? "252, 253, " : "");
        return -MSID_DAQ_E_ARG;
    }
    return 0;
}

int msid_co_pdo_check(const msid_co_pdo_cfg *c, unsigned node, char *err, size_t len)
{
    if (!c) return -MSID_DAQ_E_ARG;
    if (!msid_co_node_valid(node)) {
        snprintf(err, len, "node id %u is out of range (1..127)", node);
        return -MSID_DAQ_E_ARG;
    }
    if (c->num < 1 || c->num > 512) {
        snprintf(err, len, "%s number %u is out of range (1..512)", kind(c->tx), (unsigned)c->num);
        return -MSID_DAQ_E_ARG;
    }
    const uint32_t cob = cob_of(c, node);
    if (!c->cob_id && !cob) {
        snprintf(err, len, "%s%u has no COB-ID of the predefined connection set (PDOs 1..4): give one", kind(c->tx),
                 (unsigned)c->num);
        return -MSID_DAQ_E_ARG;
    }
    if ((c->cob_id & ~(MSID_CO_PDO_COB_INVALID | MSID_CO_PDO_COB_NO_RTR)) > 0x7FFu || cob_restricted(cob)) {
        snprintf(err, len, "%s%u: COB-ID 0x%X is not an 11-bit identifier a PDO may use (CiA 301 restricts 0x000-0x07F, "
                 "0x101-0x180, 0x581-0x5FF, 0x601-0x67F, 0x6E0-0x6FF, 0x701-0x7FF)", kind(c->tx), (unsigned)c->num,
                 (unsigned)(c->cob_id ? c->cob_id & ~(MSID_CO_PDO_COB_INVALID | MSID_CO_PDO_COB_NO_RTR) : cob));
        return -MSID_DAQ_E_ARG;
    }
    int rc = check_entries(c, err, len);
    return rc ? rc : check_transmission(c, err, len);
}

/* ---- the node's side ---- */

/* prefix s->err with the PDO it was about */
static int pdo_failed(msid_co_sdo *s, unsigned tx, unsigned num, int rc)
{
    char prefix[40];
    const int w = snprintf(prefix, sizeof prefix, "%s%u of node %u: ", kind(tx), num, (unsigned)s->node);
    const size_t p = w > 0 && (size_t)w < sizeof prefix ? (size_t)w : 0, room = sizeof s->err - 1 - p;
    size_t n = strlen(s->err);
    if (n > room) n = room;
    memmove(s->err + p, s->err, n);
    memcpy(s->err, prefix, p);
    s->err[p + n] = '\0';
    return rc;
}

/* The write sequence of CiA 301: not valid, transmission type, inhibit time, count 0, entries, count, COB-ID
   (final_cob, which may itself be not valid). */
static int write_sequence(msid_co_sdo *s, const msid_co_pdo_cfg *c, uint32_t final_cob)
{
    const uint16_t comm = msid_co_pdo_comm_index(c->tx, c->num), map = (uint16_t)(comm + 0x200u);
    int rc = msid_co_sdo_write_uint(s, comm, SUB_COB_ID, 4, final_cob | MSID_CO_PDO_COB_INVALID);
    if (!rc) rc = msid_co_sdo_write_uint(s, comm, SUB_TRANS_TYPE, 1, c->trans_type);
    if (!rc && c->tx) {
        rc = msid_co_sdo_write_uint(s, comm, SUB_INHIBIT, 2, c->inhibit_100us);
        /* a node without an inhibit time takes none: only a time of 0 may go unwritten */
        if (rc == -MSID_DAQ_E_DEVICE && s->abort_code == ABORT_NO_SUBINDEX && c->inhibit_100us == 0) rc = 0;
    }
    if (!rc) rc = msid_co_sdo_write_uint(s, map, 0, 1, 0);
    for (unsigned i = 0; !rc && i < c->n; i++) rc = msid_co_sdo_write_uint(s, map, (uint8_t)(i + 1), 4, msid_co_pdo_map_value(&c->e[i]));
    if (!rc) rc = msid_co_sdo_write_uint(s, map, 0, 1, c->n);
    if (!rc && !(final_cob & MSID_CO_PDO_COB_INVALID)) rc = msid_co_sdo_write_uint(s, comm, SUB_COB_ID, 4, final_cob);
    return rc;
}

static int save_mapping(msid_co_sdo *s, uint16_t map, msid_co_pdo_cfg *saved)
{
    uint32_t v;
    int rc = msid_co_sdo_read_uint(s, map, 0, 1, &v);
    if (rc) return rc;
    if (v > MSID_CO_PDO_MAX_ENTRIES) {
        snprintf(s->err, sizeof s->err, "0x%04X:00 maps %u entries: msid keeps at most %u", (unsigned)map, (unsigned)v,
                 MSID_CO_PDO_MAX_ENTRIES);
        return -MSID_DAQ_E_PROTOCOL;
    }
    saved->n = (uint8_t)v;
    for (unsigned i = 0; i < saved->n; i++) {
        if ((rc = msid_co_sdo_read_uint(s, map, (uint8_t)(i + 1), 4, &v))) return rc;
        saved->e[i].index = (uint16_t)(v >> 16);
        saved->e[i].sub = (uint8_t)(v >> 8);
        saved->e[i].bits = (uint8_t)v;
    }
    return 0;
}

int msid_co_pdo_save(msid_co_sdo *s, unsigned tx, unsigned num, msid_co_pdo_cfg *saved)
{
    if (!s || !saved || num < 1 || num > 512) return -MSID_DAQ_E_ARG;
    memset(saved, 0, sizeof *saved);
    saved->tx = (uint8_t)(tx != 0);
    saved->num = (uint16_t)num;
    const uint16_t comm = msid_co_pdo_comm_index(tx, num);
    uint32_t v;
    int rc = msid_co_sdo_read_uint(s, comm, SUB_COB_ID, 4, &saved->cob_id);
    if (!rc) rc = msid_co_sdo_read_uint(s, comm, SUB_TRANS_TYPE, 1, &v);
    if (!rc) saved->trans_type = (uint8_t)v;
    if (!rc && tx) {
        rc = msid_co_sdo_read_uint(s, comm, SUB_INHIBIT, 2, &v);
        if (rc == -MSID_DAQ_E_DEVICE && s->abort_code == ABORT_NO_SUBINDEX) rc = 0, v = 0;
        saved->inhibit_100us = (uint16_t)v;
    }
    if (!rc) rc = save_mapping(s, (uint16_t)(comm + 0x200u), saved);
    if (!rc) s->err[0] = '\0';
    return rc ? pdo_failed(s, tx, num, rc) : 0;
}

int msid_co_pdo_configure(msid_co_sdo *s, const msid_co_pdo_cfg *c, const msid_co_pdo_cfg *saved)
{
    if (!s || !c) return -MSID_DAQ_E_ARG;
    int rc = msid_co_pdo_check(c, s->node, s->err, sizeof s->err);
    if (rc) return rc;
    uint32_t cob = cob_of(c, s->node) | (c->cob_id & MSID_CO_PDO_COB_NO_RTR);
    if (!c->cob_id && saved) cob |= saved->cob_id & MSID_CO_PDO_COB_NO_RTR;
    rc = write_sequence(s, c, cob);
    if (!rc) return 0;
    pdo_failed(s, c->tx, c->num, rc);
    if (saved) {
        /* the first failure is the one the user needs; the restore's own outcome is left out */
        char first[sizeof s->err];
        memcpy(first, s->err, sizeof first);
        const uint32_t code = s->abort_code;
        const uint8_t by_node = s->abort_by_node;
        (void)write_sequence(s, saved, saved->cob_id);
        memcpy(s->err, first, sizeof first);
        s->abort_code = code;
        s->abort_by_node = by_node;
    }
    return rc;
}

int msid_co_pdo_restore(msid_co_sdo *s, const msid_co_pdo_cfg *saved)
{
    if (!s || !saved) return -MSID_DAQ_E_ARG;
    const int rc = write_sequence(s, saved, saved->cob_id);
    return rc ? pdo_failed(s, saved->tx, saved->num, rc) : 0;
}

int msid_co_cycle_write(msid_co_sdo *s, uint32_t period_us)
{
    return msid_co_sdo_write_uint(s, 0x1006, 0, 4, period_us);
}

int msid_co_cycle_read(msid_co_sdo *s, uint32_t *period_us)
{
    return msid_co_sdo_read_uint(s, 0x1006, 0, 4, period_us);
}
