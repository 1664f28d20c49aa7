/* The simulated CANopen node's object dictionary: an EDS's entries with values in fixed memory. */
#include "sim_co_od.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define N_DOMAINS (sizeof(((sim_co_od *)0)->domains) / SIM_CO_OD_DOMAIN_MAX)

/* A DefaultValue as CiA 306 writes it: decimal, 0x hex, octal, with "$NODEID+" (or "+$NODEID") added. */
static int parse_value(const char *s, unsigned node, uint64_t *out)
{
    char buf[48];
    snprintf(buf, sizeof buf, "%s", s);
    uint64_t add = 0;
    char *p = strstr(buf, "$NODEID");
    if (!p) p = strstr(buf, "$nodeid");
    if (p) {
        add = node;
        memset(p, ' ', 7);
        for (char *q = buf; *q; ++q)
            if (*q == '+') { *q = ' '; break; }
    }
    char *b = buf;
    while (*b == ' ' || *b == '\t') ++b;
    char *e = b + strlen(b);
    while (e > b && (e[-1] == ' ' || e[-1] == '\t')) *--e = 0;
    if (!*b) { *out = add; return 0; }
    char *end;
    if (*b == '-') {
        const long long x = strtoll(b, &end, 0);
        if (*end) return -1;
        *out = (uint64_t)x + add;
    } else {
        const unsigned long long x = strtoull(b, &end, 0);
        if (*end) return -1;
        *out = (uint64_t)x + add;
    }
    return 0;
}

static int add_var(sim_co_od *od, uint16_t index, uint8_t sub, uint8_t access, uint16_t type, uint8_t mappable,
                   const char *value, unsigned node)
{
    if (od->n >= SIM_CO_OD_MAX) {
        snprintf(od->err, sizeof od->err, "the node holds at most %u entries", SIM_CO_OD_MAX);
        return -1;
    }
    sim_co_var *v = &od->v[od->n];
    memset(v, 0, sizeof *v);
    v->index = index, v->sub = sub, v->access = access, v->type = type, v->mappable = mappable;
    const unsigned bits = msid_co_type_bits(type);
    if (bits) {
        v->size = (uint8_t)((bits + 7u) / 8u);
        uint64_t x = 0;
        if (parse_value(value, node, &x) != 0) {
            snprintf(od->err, sizeof od->err, "entry 0x%04X:%02X: DefaultValue '%s' is not a number", index, sub, value);
            return -1;
        }
        for (unsigned k = 0; k < v->size; ++k) v->def[k] = v->val[k] = (uint8_t)(x >> (8u * k));
    } else {
        if (od->n_dom >= N_DOMAINS) {
            snprintf(od->err, sizeof od->err, "entry 0x%04X:%02X: the node holds at most %u domain or string entries",
                     index, sub, (unsigned)N_DOMAINS);
            return -1;
        }
        v->dom = (uint16_t)(od->n_dom++ * SIM_CO_OD_DOMAIN_MAX);
        const size_t l = strlen(value) < SIM_CO_OD_DOMAIN_MAX ? strlen(value) : SIM_CO_OD_DOMAIN_MAX;
        memcpy(&od->domains[v->dom], value, l);
        v->len = (uint16_t)l;
    }
    od->n++;
    return 0;
}

static int by_key(const void *a, const void *b)
{
    const sim_co_var *x = a, *y = b;
    const uint32_t kx = (uint32_t)x->index << 8 | x->sub, ky = (uint32_t)y->index << 8 | y->sub;
    return kx < ky ? -1 : kx > ky;
}

int sim_co_od_init(sim_co_od *od, const msid_co_eds *eds, unsigned node)
{
    memset(od, 0, sizeof *od);
    for (uint32_t i = 0; i < eds->n; ++i) {
        const msid_co_od_entry *e = &eds->e[i];
        if (add_var(od, e->index, e->sub, e->access, e->type, e->pdo_mappable, e->value, node) != 0) return -1;
    }
    /* the node sends EMCY: CiA 301's COB-ID EMCY when the EDS has none */
    if (!sim_co_od_has_index(od, 0x1014) && add_var(od, 0x1014, 0, MSID_CO_RO, 0x0007, 0, "$NODEID+0x80", node) != 0)
        return -1;
    qsort(od->v, od->n, sizeof od->v[0], by_key);
    return 0;
}

sim_co_var *sim_co_od_find(sim_co_od *od, uint16_t index, uint8_t sub)
{
    const uint32_t key = (uint32_t)index << 8 | sub;
    uint32_t lo = 0, hi = od->n;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        const uint32_t k = (uint32_t)od->v[mid].index << 8 | od->v[mid].sub;
        if (k == key) return &od->v[mid];
        if (k < key) lo = mid + 1;
        else hi = mid;
    }
    return NULL;
}

int sim_co_od_has_index(const sim_co_od *od, uint16_t index)
{
    for (uint32_t i = 0; i < od->n; ++i)
        if (od->v[i].index == index) return 1;
    return 0;
}

static uint32_t missing(sim_co_od *od, uint16_t index)
{
    return sim_co_od_has_index(od, index) ? SIM_CO_ABORT_NO_SUB : SIM_CO_ABORT_NO_OBJECT;
}

uint32_t sim_co_od_check_read(sim_co_od *od, uint16_t index, uint8_t sub)
{
    const sim_co_var *v = sim_co_od_find(od, index, sub);
    if (!v) return missing(od, index);
    return v->access == MSID_CO_WO ? SIM_CO_ABORT_WRITE_ONLY : 0;
}

uint32_t sim_co_od_check_write(sim_co_od *od, uint16_t index, uint8_t sub, size_t len)
{
    const sim_co_var *v = sim_co_od_find(od, index, sub);
    if (!v) return missing(od, index);
    if (v->access == MSID_CO_RO || v->access == MSID_CO_CONST) return SIM_CO_ABORT_READ_ONLY;
    if (v->size) return len > v->size ? SIM_CO_ABORT_TOO_HIGH : len < v->size ? SIM_CO_ABORT_TOO_LOW : 0;
    return len > SIM_CO_OD_DOMAIN_MAX ? SIM_CO_ABORT_TOO_HIGH : 0;
}

const uint8_t *sim_co_od_bytes(sim_co_od *od, const sim_co_var *v, size_t *len)
{
    if (v->size) { *len = v->size; return v->val; }
    *len = v->len;
    return &od->domains[v->dom];
}

void sim_co_od_store(sim_co_od *od, sim_co_var *v, const uint8_t *data, size_t len)
{
    if (v->size) { memcpy(v->val, data, v->size < len ? v->size : len); return; }
    if (len > SIM_CO_OD_DOMAIN_MAX) len = SIM_CO_OD_DOMAIN_MAX;
    if (len) memcpy(&od->domains[v->dom], data, len);
    v->len = (uint16_t)len;
}

uint64_t sim_co_od_get(sim_co_od *od, uint16_t index, uint8_t sub)
{
    const sim_co_var *v = sim_co_od_find(od, index, sub);
    uint64_t x = 0;
    if (!v) return 0;
    for (unsigned k = 0; k < v->size; ++k) x |= (uint64_t)v->val[k] << (8u * k);
    return x;
}

int64_t sim_co_od_get_signed(sim_co_od *od, uint16_t index, uint8_t sub)
{
    const sim_co_var *v = sim_co_od_find(od, index, sub);
    if (!v || !v->size) return 0;
    const uint64_t x = sim_co_od_get(od, index, sub);
    const unsigned sh = 64u - 8u * v->size;
    return sh ? (int64_t)(x << sh) >> sh : (int64_t)x;
}

void sim_co_od_set(sim_co_od *od, uint16_t index, uint8_t sub, uint64_t value)
{
    sim_co_var *v = sim_co_od_find(od, index, sub);
    if (!v) return;
    for (unsigned k = 0; k < v->size; ++k) v->val[k] = (uint8_t)(value >> (8u * k));
}

void sim_co_od_reset(sim_co_od *od, uint16_t lo, uint16_t hi)
{
    for (uint32_t i = 0; i < od->n; ++i)
        if (od->v[i].index >= lo && od->v[i].index <= hi) memcpy(od->v[i].val, od->v[i].def, sizeof od->v[i].val);
}
