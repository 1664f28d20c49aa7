/* CANopen NMT master commands, SYNC frames and the heartbeat consumer (CiA 301 7.2.8). */
#include "msid_daq/msid_co_nmt.h"

#include <string.h>

const char *msid_co_nmt_cmd_name(unsigned cmd)
{
    switch (cmd) {
    case MSID_CO_NMT_START: return "start";
    case MSID_CO_NMT_STOP: return "stop";
    case MSID_CO_NMT_PREOPERATIONAL: return "enter pre-operational";
    case MSID_CO_NMT_RESET_NODE: return "reset node";
    case MSID_CO_NMT_RESET_COMMUNICATION: return "reset communication";
    default: return "unknown command";
    }
}

const char *msid_co_state_name(unsigned state)
{
    if (state == MSID_CO_STATE_UNKNOWN) return "no heartbeat yet";
    switch (state & 0x7Fu) {
    case MSID_CO_STATE_BOOTUP: return "boot-up";
    case MSID_CO_STATE_STOPPED: return "stopped";
    case MSID_CO_STATE_OPERATIONAL: return "operational";
    case MSID_CO_STATE_PREOPERATIONAL: return "pre-operational";
    default: return "unknown state";
    }
}

int msid_co_nmt_send(const msid_co_io *io, msid_co_nmt_cmd cmd, unsigned node)
{
    if (!io || !io->send || node > MSID_CO_NODE_MAX || !strcmp(msid_co_nmt_cmd_name((unsigned)cmd), "unknown command"))
        return -MSID_DAQ_E_ARG;
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = MSID_CO_COB_NMT;
    f.len = 2;
    f.data[0] = (uint8_t)cmd;
    f.data[1] = (uint8_t)node;
    const int rc = io->send(io->ctx, &f);
    return rc < 0 ? rc : 0;
}

int msid_co_sync_frame(msid_can_frame *f, unsigned counter)
{
    if (!f || counter > 240u) return -MSID_DAQ_E_ARG;
    memset(f, 0, sizeof *f);
    f->id = MSID_CO_COB_SYNC;
    f->len = counter ? 1 : 0;
    f->data[0] = (uint8_t)counter;
    return 0;
}

uint32_t msid_co_hb_entry(unsigned node, unsigned time_ms)
{
    return (uint32_t)(node & 0xFFu) << 16 | (uint32_t)(time_ms & 0xFFFFu);
}

int msid_co_hb_init(msid_co_hb *hb, unsigned node, unsigned time_ms)
{
    if (!hb || !msid_co_node_valid(node) || time_ms == 0 || time_ms > 0xFFFFu) return -MSID_DAQ_E_ARG;
    memset(hb, 0, sizeof *hb);
    hb->node = (uint8_t)node;
    hb->time_ms = (uint16_t)time_ms;
    hb->state = MSID_CO_STATE_UNKNOWN;
    return 0;
}

int msid_co_hb_frame(msid_co_hb *hb, const msid_can_frame *f, uint64_t now_ms)
{
    if ((f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) || f->id != MSID_CO_COB_HEARTBEAT + hb->node)
        return 0;
    if (f->len != 1) {
        hb->malformed++;
        return -MSID_DAQ_E_PROTOCOL;
    }
    hb->state = (uint8_t)(f->data[0] & 0x7Fu);
    hb->last_ms = now_ms;
    hb->lost = 0;
    hb->heartbeats++;
    if (hb->state == MSID_CO_STATE_BOOTUP) hb->bootups++;
    return 1;
}

msid_co_hb_status msid_co_hb_check(msid_co_hb *hb, uint64_t now_ms)
{
    if (hb->heartbeats == 0) return MSID_CO_HB_WAITING;
    if (hb->lost) return MSID_CO_HB_LOST;
    if (now_ms > hb->last_ms && now_ms - hb->last_ms > hb->time_ms) {
        hb->lost = 1;
        hb->losses++;
        return MSID_CO_HB_LOST;
    }
    return MSID_CO_HB_ALIVE;
}
