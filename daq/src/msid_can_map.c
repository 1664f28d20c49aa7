/* A CAN description resolved against its DBC, and the signal codec through it (msid_can_map.h): which message
 * and signal each channel is, the checks that refuse what cannot work, packing drive values into the command
 * payloads and decoding status payloads. The backend that moves the frames is msid_can_map_io.c. */
#include "msid_daq/msid_can_map.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "can_map_internal.h"

int msid_can_map_fail(msid_can_map *m, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(m->err, sizeof m->err, fmt, ap);
    va_end(ap);
    return rc;
}
#define fail msid_can_map_fail

/* ---- what a signal is, in words ------------------------------------------------------------------ */

static void signal_words(const msid_dbc_signal *s, char *out, size_t cap)
{
    if (s->type == MSID_DBC_FLOAT32 || s->type == MSID_DBC_FLOAT64)
        snprintf(out, cap, "a float%u signal", s->type == MSID_DBC_FLOAT32 ? 32u : 64u);
    else
        snprintf(out, cap, "a %u-bit %s integer signal", s->length, s->is_signed ? "signed" : "unsigned");
}

/* Whether a description's `type` names the DBC signal's own type. */
static int type_matches(uint32_t type, const msid_dbc_signal *s)
{
    const int integer = s->type == MSID_DBC_INT;
    switch (type) {
    case MSID_DEV_INT16: return integer && s->length == 16 && s->is_signed;
    case MSID_DEV_UINT16: return integer && s->length == 16 && !s->is_signed;
    case MSID_DEV_INT32: return integer && s->length == 32 && s->is_signed;
    case MSID_DEV_UINT32: return integer && s->length == 32 && !s->is_signed;
    case MSID_DEV_FLOAT32: return s->type == MSID_DBC_FLOAT32;
    case MSID_DEV_FLOAT64: return s->type == MSID_DBC_FLOAT64;
    default: return 1;
    }
}

/* "a, b, c and 4 more": the signals of a message, for a signal name the message does not have. */
static void list_signals(const msid_dbc *dbc, const msid_dbc_message *msg, char *out, size_t cap)
{
    size_t len = 0;
    out[0] = 0;
    for (uint32_t k = 0; k < msg->n_signals && len < cap; ++k) {
        if (k == 6) {
            snprintf(out + len, cap - len, " and %u more", msg->n_signals - 6);
            return;
        }
        len += (size_t)snprintf(out + len, cap - len, "%s%s", k ? ", " : "", dbc->signals[msg->first_signal + k].name);
    }
}

/* ---- resolving ----------------------------------------------------------------------------------- */

/* The message and signal of channel c, and the type check. */
static int resolve_signal(msid_can_map *m, const msid_dev_chan *c, const msid_dbc_message **mo,
                          const msid_dbc_signal **so)
{
    const msid_devdesc *d = m->desc;
    const msid_dbc_message *msg = msid_dbc_message_by_name(m->dbc, c->message);
    if (!msg)
        return fail(m, -MSID_DAQ_E_ARG, "%s line %u: channel '%s': the DBC %s has no message '%s'", d->source, c->line,
                    c->name, d->dbc, c->message);
    const msid_dbc_signal *s = msid_dbc_signal_by_name(m->dbc, msg, c->signal);
    if (!s) {
        char names[240];
        list_signals(m->dbc, msg, names, sizeof names);
        return fail(m, -MSID_DAQ_E_ARG, "%s line %u: channel '%s': message '%s' of %s has no signal '%s' (its signals: %s)",
                    d->source, c->line, c->name, c->message, d->dbc, c->signal, names[0] ? names : "none");
    }
    if (c->type && !type_matches(c->type, s)) {
        char what[64];
        signal_words(s, what, sizeof what);
        return fail(m, -MSID_DAQ_E_ARG, "%s line %u: channel '%s': type = \"%s\", but %s.%s is %s in %s", d->source,
                    c->line, c->name, msid_dev_type_name(c->type), c->message, c->signal, what, d->dbc);
    }
    *mo = msg;
    *so = s;
    return 0;
}

/* Index of message msg in the list, appended when new. */
static uint32_t msg_slot(msid_can_map_msg *list, uint32_t *n, const msid_dbc_message *msg)
{
    for (uint32_t k = 0; k < *n; ++k)
        if (list[k].m == msg) return k;
    memset(&list[*n], 0, sizeof list[*n]);
    list[*n].m = msg;
    return (*n)++;
}

/* A drive value that its signal cannot carry: its bits or the DBC's range. */
static int check_fits(msid_can_map *m, uint32_t i, const char *what, double v)
{
    if (isnan(v)) return 0;
    const msid_dev_chan *c = &m->desc->drive[i];
    const msid_dbc_signal *s = m->dsig[i];
    uint8_t scratch[MSID_DBC_MAX_DLC] = {0};
    const double phys = (v - c->offset) / c->scale;
    if (msid_dbc_encode(s, phys, scratch, sizeof scratch) == 0) return 0;
    char kind[64], range[96] = "";
    signal_words(s, kind, sizeof kind);
    if (s->min < s->max) snprintf(range, sizeof range, ", the DBC's range [%g, %g]", s->min, s->max);
    return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channel '%s': %s %g does not fit %s.%s (%s, factor %g, offset "
                "%g%s)", m->desc->source, c->line, c->name, what, v, c->message, c->signal, kind, s->factor, s->offset,
                range);
}

/* The node that sends the status messages, when the DBC names one ("" when it does not, or names several). */
static const char *device_node(const msid_can_map *m)
{
    const char *node = "";
    for (uint32_t k = 0; k < m->n_st; ++k) {
        const char *snd = m->st[k].m->sender;
        if (!snd[0] || !strcmp(snd, "Vector__XXX")) continue;
        if (!node[0]) node = snd;
        else if (strcmp(node, snd)) return "";
    }
    return node;
}

static int resolve_measure(msid_can_map *m)
{
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const msid_dev_chan *c = &d->measure[i];
        const msid_dbc_message *msg;
        int rc = resolve_signal(m, c, &msg, &m->msig[i]);
        if (rc) return rc;
        if (c->role == MSID_DEV_ROLE_COUNTER && m->msig[i]->type != MSID_DBC_INT)
            return fail(m, -MSID_DAQ_E_ARG, "%s line %u: counter channel '%s': %s.%s is a float signal; a counter is an "
                        "integer signal", d->source, c->line, c->name, c->message, c->signal);
        m->st_of[i] = msg_slot(m->st, &m->n_st, msg);
        m->value[i] = NAN;
    }
    return 0;
}

static int resolve_drive(msid_can_map *m)
{
    const msid_devdesc *d = m->desc;
    const char *node = device_node(m);
    for (uint32_t i = 0; i < d->n_drive; ++i) {
        const msid_dev_chan *c = &d->drive[i];
        const msid_dbc_message *msg;
        int rc = resolve_signal(m, c, &msg, &m->dsig[i]);
        if (rc) return rc;
        const msid_dbc_signal *s = m->dsig[i];
        for (uint32_t j = 0; j < d->n_measure; ++j)
            if (m->st[m->st_of[j]].m == msg)
                return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channel '%s' is in message '%s', which the device "
                            "sends (measure channel '%s' reads it): msid writes only messages it sends", d->source,
                            c->line, c->name, c->message, d->measure[j].name);
        if (node[0] && !strcmp(msg->sender, node))
            return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channel '%s': message '%s' is sent by node %s in %s, the "
                        "node that sends the status messages: it is read-only to msid", d->source, c->line, c->name,
                        c->message, node, d->dbc);
        if (s->mux == MSID_DBC_SWITCH)
            return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channel '%s': %s.%s is the message's multiplexer switch, "
                        "not a value to excite", d->source, c->line, c->name, c->message, c->signal);
        for (uint32_t j = 0; j < i; ++j)
            if (m->dsig[j] == s)
                return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channels '%s' and '%s' both write %s.%s", d->source,
                            c->line, d->drive[j].name, c->name, c->message, c->signal);
        const uint32_t before = m->n_cmd;
        const uint32_t k = msg_slot(m->cmd, &m->n_cmd, msg);
        if (m->n_cmd > before) m->cmd_mux[k] = -1;   /* a message new to the list */
        m->cmd_of[i] = k;
        if (s->mux == MSID_DBC_MUXED) {
            if (m->cmd_mux[k] >= 0 && (uint32_t)m->cmd_mux[k] != s->mux_value)
                return fail(m, -MSID_DAQ_E_ARG, "%s line %u: drive channel '%s': %s.%s is multiplexed under %u, another "
                            "drive channel of '%s' under %d: one frame carries one multiplexer value", d->source,
                            c->line, c->name, c->message, c->signal, s->mux_value, c->message, m->cmd_mux[k]);
            m->cmd_mux[k] = (int32_t)s->mux_value;
        }
        if ((rc = check_fits(m, i, "the safe value", c->safe)) || (rc = check_fits(m, i, "min", c->min)) ||
            (rc = check_fits(m, i, "max", c->max)) || (rc = check_fits(m, i, "the operating point", c->op)))
            return rc;
    }
    /* a multiplexed command message's switch */
    for (uint32_t k = 0; k < m->n_cmd; ++k) {
        const msid_dbc_message *msg = m->cmd[k].m;
        if (m->cmd_mux[k] < 0 || msg->mux_signal < 0) continue;
        const int rc = msid_dbc_set_raw(&m->dbc->signals[msg->mux_signal], (uint64_t)m->cmd_mux[k], m->cmd[k].data,
                                        msg->dlc);
        if (rc < 0)
            return fail(m, -MSID_DAQ_E_ARG, "%s: message '%s': multiplexer value %d does not fit its switch",
                        d->source, msg->name, m->cmd_mux[k]);
    }
    return 0;
}

int msid_can_map_init(msid_can_map *m, const msid_devdesc *d, const msid_dbc *dbc, msid_can_transport *tr)
{
    memset(m, 0, sizeof *m);
    if (!d || !dbc || d->transport != MSID_DEV_CAN) return fail(m, -MSID_DAQ_E_ARG, "not a CAN description");
    m->desc = d;
    m->dbc = dbc;
    m->tr = tr;
    m->wait_ns = 1000000;
    m->read_wait_ns = 1000000000;
    m->send_timeout_ms = 1;
    int rc;
    if ((rc = resolve_measure(m)) || (rc = resolve_drive(m))) return rc;
    msid_can_map_attach(m);
    return 0;
}

/* ---- the codec ----------------------------------------------------------------------------------- */

int msid_can_map_pack(msid_can_map *m, const double *drive)
{
    const msid_devdesc *d = m->desc;
    /* every value checked first: a value that does not fit leaves every payload as it was */
    for (uint32_t i = 0; i < d->n_drive; ++i) {
        const msid_dev_chan *c = &d->drive[i];
        uint8_t scratch[MSID_DBC_MAX_DLC] = {0};
        if (msid_dbc_encode(m->dsig[i], (drive[i] - c->offset) / c->scale, scratch, sizeof scratch) != 0)
            return fail(m, -MSID_DAQ_E_RANGE, "'%s': %.9g does not fit %s.%s", c->name, drive[i], c->message,
                        c->signal);
    }
    for (uint32_t i = 0; i < d->n_drive; ++i) {
        const msid_dev_chan *c = &d->drive[i];
        msid_can_map_msg *k = &m->cmd[m->cmd_of[i]];
        (void)msid_dbc_encode(m->dsig[i], (drive[i] - c->offset) / c->scale, k->data, k->m->dlc);
    }
    return 0;
}

uint32_t msid_can_map_decode(const msid_can_map *m, uint32_t s, const uint8_t *data, size_t len, double *measure,
                             uint8_t *got)
{
    const msid_devdesc *d = m->desc;
    uint32_t n = 0;
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        if (m->st_of[i] != s) continue;
        const msid_dbc_signal *sg = m->msig[i];
        if (msid_dbc_present(m->dbc, sg, data, len) != 1) continue;
        double v;
        if (d->measure[i].role == MSID_DEV_ROLE_COUNTER) {
            uint64_t raw;
            if (msid_dbc_get_raw(sg, data, len, &raw) != 0) continue;
            v = (double)raw;
        } else {
            if (msid_dbc_decode(sg, data, len, &v) != 0) continue;
            v = v * d->measure[i].scale + d->measure[i].offset;
        }
        measure[i] = v;
        if (got) got[i] = 1;
        ++n;
    }
    return n;
}

int msid_can_map_status_index(const msid_can_map *m, uint32_t id)
{
    for (uint32_t k = 0; k < m->n_st; ++k)
        if (m->st[k].m->id == id) return (int)k;
    return -1;
}

int msid_can_map_take(msid_can_map *m, const msid_can_frame *f, int64_t now_ns)
{
    if (f->id & MSID_CAN_ERR_FLAG) {
        m->cnt.bus_errors++;
        return 0;
    }
    const int s = (f->id & MSID_CAN_RTR_FLAG) ? -1 : msid_can_map_status_index(m, f->id);
    if (s < 0) {
        m->cnt.other_frames++;
        return 0;
    }
    msid_can_map_msg *st = &m->st[s];
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_measure; ++i)
        if (m->st_of[i] == (uint32_t)s && msid_dbc_signal_bytes(m->msig[i]) > f->len) {
            m->cnt.short_frames++;
            return 1;
        }
    m->cnt.status_frames++;
    st->frames++;
    for (uint32_t i = 0; i < d->n_measure; ++i)
        if (m->st_of[i] == (uint32_t)s && m->fresh[i]) {
            m->cnt.superseded++;   /* a newer frame of the message in the same tick: the newest is the sample */
            break;
        }
    memcpy(st->data, f->data, f->len);
    st->last_ns = now_ns;
    uint8_t got[MSID_DEV_MAX_MEASURE] = {0};
    (void)msid_can_map_decode(m, (uint32_t)s, f->data, f->len, m->value, got);
    for (uint32_t i = 0; i < d->n_measure; ++i) m->fresh[i] |= got[i];
    if (now_ns > m->newest_ns) m->newest_ns = now_ns;
    return 1;
}

double msid_can_map_modulus(const msid_can_map *m, uint32_t i)
{
    const uint32_t len = m->msig[i]->length;
    return len >= 53 ? 9007199254740992.0 : ldexp(1.0, (int)len);
}
