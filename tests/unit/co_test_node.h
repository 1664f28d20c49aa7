/* A CANopen node for the unit tests, written from CiA 301: an object dictionary of small entries (1..4
   bytes) behind an expedited SDO server on frames in memory, with the PDO rules a node enforces (mapping
   and count written only while the PDO is not valid and the count is 0, a mapped object must exist and be
   mappable, a mapping of more than 64 bits refused when its count is written). Every write is logged and
   may be acted on by the test (on_write); each answer takes a millisecond of the node's clock.
   Header-only: one per test executable that needs a node. */
#ifndef CO_TEST_NODE_H
#define CO_TEST_NODE_H

#include <stdint.h>
#include <string.h>

#include "msid_daq/msid_co.h"

#define TN_MAX_ENTRIES 96
#define TN_MAX_LOG 64

enum { TN_RW = 0, TN_RO = 1, TN_WO = 2 };

typedef struct tn_entry {
    uint16_t index;
    uint8_t sub, size, access, mappable;
    uint32_t value;
} tn_entry;

typedef struct tn_write {
    uint16_t index;
    uint8_t sub;
    uint32_t value;
} tn_write;

typedef struct test_node {
    uint8_t id;
    tn_entry od[TN_MAX_ENTRIES];
    int n;
    tn_write log[TN_MAX_LOG];
    int n_log;
    int silent;          /* answers nothing */
    /* called after each write the node took (a test's drive behaviour), NULL: none */
    void (*on_write)(struct test_node *t, uint16_t index, uint8_t sub, uint32_t value);
    void *user;
    msid_can_frame reply;
    int has_reply;
    uint64_t now;
} test_node;

static inline tn_entry *tn_find(test_node *t, uint16_t index, uint8_t sub)
{
    for (int i = 0; i < t->n; i++)
        if (t->od[i].index == index && t->od[i].sub == sub) return &t->od[i];
    return NULL;
}

static inline void tn_add(test_node *t, uint16_t index, uint8_t sub, uint8_t size, uint8_t access, uint8_t mappable,
                          uint32_t value)
{
    tn_entry *e = &t->od[t->n++];
    e->index = index, e->sub = sub, e->size = size, e->access = access, e->mappable = mappable, e->value = value;
}

static inline int tn_index_exists(test_node *t, uint16_t index)
{
    for (int i = 0; i < t->n; i++)
        if (t->od[i].index == index) return 1;
    return 0;
}

/* a PDO's communication and mapping records: COB-ID, transmission type, (TPDO) inhibit time; 8 entries */
static inline void tn_add_pdo(test_node *t, int tx, unsigned num, uint32_t cob, int with_inhibit)
{
    const uint16_t comm = (uint16_t)((tx ? 0x1800u : 0x1400u) + num - 1u);
    tn_add(t, comm, 1, 4, TN_RW, 0, cob);
    tn_add(t, comm, 2, 1, TN_RW, 0, 255);
    if (tx && with_inhibit) tn_add(t, comm, 3, 2, TN_RW, 0, 0);
    tn_add(t, (uint16_t)(comm + 0x200u), 0, 1, TN_RW, 0, 0);
    for (uint8_t k = 1; k <= 8; k++) tn_add(t, (uint16_t)(comm + 0x200u), k, 4, TN_RW, 0, 0);
}

static inline uint32_t tn_value(test_node *t, uint16_t index, uint8_t sub)
{
    tn_entry *e = tn_find(t, index, sub);
    return e ? e->value : 0xDEADBEEFu;
}

/* The CiA 301 PDO rules on a write to a mapping or communication record; 0 or an abort code. */
static inline uint32_t tn_pdo_rules(test_node *t, uint16_t index, uint8_t sub, uint32_t value)
{
    const int is_map = (index >= 0x1600u && index <= 0x17FFu) || (index >= 0x1A00u && index <= 0x1BFFu);
    const int is_comm = (index >= 0x1400u && index <= 0x15FFu) || (index >= 0x1800u && index <= 0x19FFu);
    if (!is_map && !is_comm) return 0;
    const uint16_t comm = is_map ? (uint16_t)(index - 0x200u) : index;
    const uint32_t cob = tn_value(t, comm, 1);
    const int valid = !(cob & 0x80000000u);
    if (is_comm && sub == 1 && valid && (value & 0x80000000u) == 0 && (value & 0x7FFu) != (cob & 0x7FFu))
        return 0x06090030u; /* a valid PDO's identifier changed */
    if (is_comm && sub == 3 && valid) return 0x06090030u; /* inhibit time only while not valid */
    if (!is_map) return 0;
    if (valid) return 0x08000022u;
    const uint32_t count = tn_value(t, index, 0);
    if (sub >= 1) {
        if (count) return 0x08000022u;
        tn_entry *m = tn_find(t, (uint16_t)(value >> 16), (uint8_t)(value >> 8));
        if (!m) return tn_index_exists(t, (uint16_t)(value >> 16)) ? 0x06090011u : 0x06020000u;
        if (!m->mappable || (value & 0xFFu) != 8u * m->size) return 0x06040041u;
        return 0;
    }
    if (value > 8) return 0x06090031u;
    unsigned bits = 0;
    for (uint8_t k = 1; k <= value; k++) bits += tn_value(t, index, k) & 0xFFu;
    return bits > 64 ? 0x06040042u : 0;
}

static inline void tn_answer(test_node *t, uint8_t cmd, const uint8_t *req, uint32_t data)
{
    memset(&t->reply, 0, sizeof t->reply);
    t->reply.id = MSID_CO_COB_SDO_TX + t->id;
    t->reply.len = 8;
    t->reply.data[0] = cmd;
    memcpy(&t->reply.data[1], &req[1], 3);
    for (int i = 0; i < 4; i++) t->reply.data[4 + i] = (uint8_t)(data >> (8 * i));
    t->has_reply = 1;
}

static inline void tn_serve(test_node *t, const msid_can_frame *f)
{
    const uint8_t *r = f->data;
    if (t->silent || f->id != MSID_CO_COB_SDO_RX + t->id || (r[0] >> 5) == 4) return;
    const uint16_t index = (uint16_t)(r[1] | r[2] << 8);
    const uint8_t sub = r[3];
    tn_entry *e = tn_find(t, index, sub);
    if (!e) return tn_answer(t, 0x80, r, tn_index_exists(t, index) ? 0x06090011u : 0x06020000u);
    if ((r[0] >> 5) == 2) {
        if (e->access == TN_WO) return tn_answer(t, 0x80, r, 0x06010001u);
        return tn_answer(t, (uint8_t)(0x43u | (4u - e->size) << 2), r, e->value);
    }
    if ((r[0] >> 5) != 1 || !(r[0] & 2u)) return tn_answer(t, 0x80, r, 0x05040001u);
    if (e->access == TN_RO) return tn_answer(t, 0x80, r, 0x06010002u);
    const unsigned n = (r[0] & 1u) ? 4u - ((r[0] >> 2) & 3u) : 4u;
    if (n != e->size) return tn_answer(t, 0x80, r, n > e->size ? 0x06070012u : 0x06070013u);
    uint32_t v = 0;
    for (unsigned i = 0; i < n; i++) v |= (uint32_t)r[4 + i] << (8 * i);
    const uint32_t refused = tn_pdo_rules(t, index, sub, v);
    if (refused) return tn_answer(t, 0x80, r, refused);
    e->value = v;
    if (t->n_log < TN_MAX_LOG) t->log[t->n_log++] = (tn_write){index, sub, v};
    if (t->on_write) t->on_write(t, index, sub, v);
    tn_answer(t, 0x60, r, 0);
}

static inline int tn_send(void *ctx, const msid_can_frame *f)
{
    tn_serve((test_node *)ctx, f);
    return 0;
}

static inline int tn_recv(void *ctx, msid_can_frame *f, int timeout_ms)
{
    test_node *t = ctx;
    if (!t->has_reply) {
        t->now += (uint64_t)timeout_ms;
        return -MSID_DAQ_E_TIMEOUT;
    }
    *f = t->reply;
    t->has_reply = 0;
    t->now += 1;  /* a round trip takes a millisecond: a test's waits end */
    return 1;
}

static inline uint64_t tn_now(void *ctx) { return ((test_node *)ctx)->now; }

static inline msid_co_io tn_io(test_node *t)
{
    const msid_co_io io = {t, tn_send, tn_recv, tn_now, NULL};
    return io;
}

#endif
