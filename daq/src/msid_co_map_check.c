/* The checks a CANopen run passes before anything is written to the node (msid_co_map.h): the bus budget of
   its SYNC cycle and every entry it uses against the node's EDS/DCF. */
#include "msid_daq/msid_co_map.h"

#include <math.h>
#include <stdio.h>

#include "msid_daq/msid_co_402.h"
#include "msid_daq/msid_co_bus.h"

int msid_co_map_check_bus(const msid_co_map *m, uint32_t bitrate, double rate_hz, double *max_rate, char *err,
                          size_t len)
{
    uint8_t bytes[1 + MSID_DEV_CO_TPDOS];
    unsigned n = 0;
    bytes[n++] = m->rpdo_len;
    for (uint32_t k = 0; k < m->n_tpdo && k < MSID_DEV_CO_TPDOS; ++k) bytes[n++] = m->tpdo_len[k];
    return msid_co_bus_check(bitrate, rate_hz, 0, bytes, n, MSID_CO_MAP_BUS_SHARE, max_rate, err, len);
}

/* the CiA 301 type a channel's `type` reads its object as */
static uint16_t co_type_of(uint32_t type)
{
    switch (type) {
    case MSID_DEV_INT16: return 0x0003;
    case MSID_DEV_UINT16: return 0x0006;
    case MSID_DEV_INT32: return 0x0004;
    case MSID_DEV_UINT32: return 0x0007;
    case MSID_DEV_FLOAT32: return 0x0008;
    default: return 0;
    }
}

static int readonly(const msid_co_od_entry *e) { return e->access == MSID_CO_RO || e->access == MSID_CO_CONST; }

/* One channel's object: in the file, of its type, PDO-mappable, writable (drive) or readable (measure). */
static int check_channel(const msid_co_map *m, const msid_co_eds *eds, const msid_dev_chan *c, int drive, char *err,
                         size_t len)
{
    const msid_co_od_entry *e = msid_co_eds_find(eds, c->co_index, c->co_sub);
    char at[MSID_DEV_PATH_CAP + 256];
    snprintf(at, sizeof at, "%s line %u: %s channel '%s' (object = \"0x%04X:%02X\")", m->d->source, (unsigned)c->line,
             drive ? "drive" : "measure", c->name, (unsigned)c->co_index, (unsigned)c->co_sub);
    if (!e) {
        snprintf(err, len, "%s: 0x%04X:%02X is not in %s", at, (unsigned)c->co_index, (unsigned)c->co_sub,
                 eds->source);
        return -MSID_DAQ_E_ARG;
    }
    const char *problem = NULL;
    if (drive && readonly(e)) problem = "is read only: a drive channel is a target msid writes";
    else if (!drive && e->access == MSID_CO_WO) problem = "is write only: the node cannot send it";
    else if (!e->pdo_mappable)
        problem = drive ? "is not PDO-mappable: a target goes in RPDO1" : "is not PDO-mappable: a measured value goes in a TPDO";
    if (problem) {
        snprintf(err, len, "%s: 0x%04X:%02X (%s) %s (%s line %u)", at, (unsigned)c->co_index, (unsigned)c->co_sub,
                 e->name, problem, eds->source, (unsigned)e->line);
        return -MSID_DAQ_E_ARG;
    }
    if (e->type != co_type_of(c->type)) {
        snprintf(err, len, "%s: 0x%04X:%02X (%s) is %s in %s line %u, but type = \"%s\" reads it as %s", at,
                 (unsigned)c->co_index, (unsigned)c->co_sub, e->name, msid_co_type_name(e->type), eds->source,
                 (unsigned)e->line, msid_dev_type_name(c->type), msid_co_type_name(co_type_of(c->type)));
        return -MSID_DAQ_E_ARG;
    }
    return 0;
}

/* An entry msid reads or writes by SDO of `bytes` bytes: in the file (unless optional), not write only for a
   read, not read only for a write, of that size. 1: absent and optional. */
static int check_use(const msid_co_eds *eds, uint16_t index, uint8_t sub, unsigned bytes, int write, int optional,
                     const char *what, char *err, size_t len)
{
    const msid_co_od_entry *e = msid_co_eds_find(eds, index, sub);
    if (!e) {
        if (optional) return 1;
        snprintf(err, len, "0x%04X:%02X (%s, which msid %s) is not in %s", (unsigned)index, (unsigned)sub, what,
                 write ? "writes" : "reads", eds->source);
        return -MSID_DAQ_E_ARG;
    }
    const char *problem = NULL;
    if (write && readonly(e)) problem = "is read only";
    else if (!write && e->access == MSID_CO_WO) problem = "is write only";
    if (problem) {
        snprintf(err, len, "0x%04X:%02X (%s, which msid %s) %s in %s line %u", (unsigned)index, (unsigned)sub, what,
                 write ? "writes" : "reads", problem, eds->source, (unsigned)e->line);
        return -MSID_DAQ_E_ARG;
    }
    const unsigned bits = msid_co_type_bits(e->type);
    if (bits != 8u * bytes) {
        snprintf(err, len, "0x%04X:%02X (%s) is %s in %s line %u: msid %s it as %u byte(s)", (unsigned)index,
                 (unsigned)sub, what, msid_co_type_name(e->type), eds->source, (unsigned)e->line,
                 write ? "writes" : "reads", bytes);
        return -MSID_DAQ_E_ARG;
    }
    return 0;
}

/* The parameters msid writes to configure one PDO (msid_co_pdo_configure's sequence). */
static int check_pdo_params(const msid_co_eds *eds, const msid_co_pdo_cfg *c, char *err, size_t len)
{
    const uint16_t comm = msid_co_pdo_comm_index(c->tx, c->num), map = (uint16_t)(comm + 0x200u);
    char what[64];
    const char *kind = c->tx ? "TPDO" : "RPDO";
    int rc;
    snprintf(what, sizeof what, "%s%u COB-ID", kind, (unsigned)c->num);
    if ((rc = check_use(eds, comm, 1, 4, 1, 0, what, err, len)) < 0) return rc;
    snprintf(what, sizeof what, "%s%u transmission type", kind, (unsigned)c->num);
    if ((rc = check_use(eds, comm, 2, 1, 1, 0, what, err, len)) < 0) return rc;
    if (c->tx) {
        /* a node without an inhibit time takes msid's 0 unwritten */
        snprintf(what, sizeof what, "%s%u inhibit time", kind, (unsigned)c->num);
        if ((rc = check_use(eds, comm, 3, 2, 1, 1, what, err, len)) < 0) return rc;
    }
    snprintf(what, sizeof what, "%s%u number of mapped objects", kind, (unsigned)c->num);
    if ((rc = check_use(eds, map, 0, 1, 1, 0, what, err, len)) < 0) return rc;
    for (unsigned i = 0; i < c->n; ++i) {
        snprintf(what, sizeof what, "%s%u mapped object %u", kind, (unsigned)c->num, i + 1);
        if ((rc = check_use(eds, map, (uint8_t)(i + 1), 4, 1, 0, what, err, len)) < 0) return rc;
    }
    return msid_co_eds_check_pdo(eds, c, err, len);
}

int msid_co_map_check_eds(const msid_co_map *m, const msid_co_eds *eds, char *err, size_t len)
{
    if (!m || !m->d || !eds || !eds->e) {
        snprintf(err, len, "EDS check: no mapping or no dictionary");
        return -MSID_DAQ_E_ARG;
    }
    const msid_devdesc *d = m->d;
    int rc;
    for (uint32_t i = 0; i < d->n_drive; ++i)
        if ((rc = check_channel(m, eds, &d->drive[i], 1, err, len)) < 0) return rc;
    for (uint32_t i = 0; i < d->n_measure; ++i)
        if ((rc = check_channel(m, eds, &d->measure[i], 0, err, len)) < 0) return rc;
    msid_co_pdo_cfg rp, tp[MSID_DEV_CO_TPDOS];
    msid_co_map_pdos(m, &rp, tp);
    if ((rc = check_pdo_params(eds, &rp, err, len)) < 0) return rc;
    for (uint32_t k = 0; k < m->n_tpdo; ++k)
        if ((rc = check_pdo_params(eds, &tp[k], err, len)) < 0) return rc;
    int torque = 0;
    for (uint32_t i = 0; i < d->n_drive + d->n_measure; ++i)
        torque |= (i < d->n_drive ? d->drive[i] : d->measure[i - d->n_drive]).co_quantity == MSID_DEV_CO_TORQUE;
    static const struct {
        uint16_t index;
        unsigned bytes;
        int write;
        const char *what;
    } USES[] = {
        {MSID_CO402_STATUSWORD, 2, 0, "statusword"},      {MSID_CO402_CONTROLWORD, 2, 1, "controlword"},
        {MSID_CO402_MODE, 1, 1, "modes of operation"},    {MSID_CO402_MODE_DISPLAY, 1, 0, "modes of operation display"},
        {0x1006, 4, 1, "communication cycle period"},     {0x1017, 2, 1, "producer heartbeat time"},
        {0x6076, 4, 0, "motor rated torque"},
    };
    for (size_t k = 0; k < sizeof USES / sizeof USES[0]; ++k) {
        if (USES[k].index == 0x1017 && !d->heartbeat_ms) continue;
        if (USES[k].index == 0x6076 && !(torque && isnan(d->rated_torque))) continue;
        if ((rc = check_use(eds, USES[k].index, 0, USES[k].bytes, USES[k].write, 0, USES[k].what, err, len)) < 0)
            return rc;
    }
    err[0] = '\0';
    return 0;
}
