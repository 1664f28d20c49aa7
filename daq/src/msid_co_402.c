/* CiA 402 power state machine: statusword decoding (CiA 402 table 30), the controlword of each step up or
   out, and both applied over SDO; modes of operation. */
#include "msid_daq/msid_co_402.h"

#include <stdio.h>

msid_co402_state msid_co402_decode(uint16_t sw)
{
    /* the states whose pattern leaves bit 5 (quick stop) free are matched on 0x4F, the others on 0x6F */
    switch (sw & 0x4Fu) {
    case 0x00u: return MSID_CO402_NOT_READY;
    case 0x40u: return MSID_CO402_SWITCH_ON_DISABLED;
    case 0x0Fu: return MSID_CO402_FAULT_REACTION;
    case 0x08u: return MSID_CO402_FAULT;
    default: break;
    }
    switch (sw & 0x6Fu) {
    case 0x21u: return MSID_CO402_READY;
    case 0x23u: return MSID_CO402_SWITCHED_ON;
    case 0x27u: return MSID_CO402_OPERATION_ENABLED;
    case 0x07u: return MSID_CO402_QUICK_STOP_ACTIVE;
    default: return MSID_CO402_FAULT;  /* a pattern of no state: the drive is treated as faulty */
    }
}

const char *msid_co402_state_name(msid_co402_state s)
{
    switch (s) {
    case MSID_CO402_NOT_READY: return "not ready to switch on";
    case MSID_CO402_SWITCH_ON_DISABLED: return "switch on disabled";
    case MSID_CO402_READY: return "ready to switch on";
    case MSID_CO402_SWITCHED_ON: return "switched on";
    case MSID_CO402_OPERATION_ENABLED: return "operation enabled";
    case MSID_CO402_QUICK_STOP_ACTIVE: return "quick stop active";
    case MSID_CO402_FAULT_REACTION: return "fault reaction active";
    case MSID_CO402_FAULT: return "fault";
    }
    return "unknown state";
}

const char *msid_co402_mode_name(int mode)
{
    switch (mode) {
    case MSID_CO402_MODE_PP: return "profile position (PP)";
    case MSID_CO402_MODE_PV: return "profile velocity (PV)";
    case MSID_CO402_MODE_PT: return "profile torque (PT)";
    case MSID_CO402_MODE_HM: return "homing (HM)";
    case MSID_CO402_MODE_IP: return "interpolated position (IP)";
    case MSID_CO402_MODE_CSP: return "cyclic synchronous position (CSP)";
    case MSID_CO402_MODE_CSV: return "cyclic synchronous velocity (CSV)";
    case MSID_CO402_MODE_CST: return "cyclic synchronous torque (CST)";
    default: return "unknown mode";
    }
}

static msid_co402_action write_cw(uint16_t *cw, uint16_t value)
{
    *cw = value;
    return MSID_CO402_WRITE;
}

static msid_co402_action step_up(msid_co402_state from, uint16_t last_cw, int reset_faults, uint16_t *cw)
{
    switch (from) {
    case MSID_CO402_OPERATION_ENABLED: return MSID_CO402_THERE;
    case MSID_CO402_SWITCH_ON_DISABLED: return write_cw(cw, MSID_CO402_CW_SHUTDOWN);           /* 2 */
    case MSID_CO402_READY: return write_cw(cw, MSID_CO402_CW_SWITCH_ON);                       /* 3 */
    case MSID_CO402_SWITCHED_ON: return write_cw(cw, MSID_CO402_CW_ENABLE_OPERATION);          /* 4 */
    case MSID_CO402_QUICK_STOP_ACTIVE: return write_cw(cw, MSID_CO402_CW_DISABLE_VOLTAGE);     /* 12, then up */
    case MSID_CO402_FAULT:
        if (!reset_faults) return MSID_CO402_STUCK;
        /* transition 15 takes a rising edge of bit 7 */
        return write_cw(cw, (last_cw & MSID_CO402_CW_FAULT_RESET) ? MSID_CO402_CW_DISABLE_VOLTAGE : MSID_CO402_CW_FAULT_RESET);
    case MSID_CO402_NOT_READY:
    case MSID_CO402_FAULT_REACTION: return MSID_CO402_WAIT;
    }
    return MSID_CO402_STUCK;
}

static msid_co402_action step_out(msid_co402_state from, uint16_t *cw)
{
    switch (from) {
    case MSID_CO402_SWITCH_ON_DISABLED:
    case MSID_CO402_FAULT: return MSID_CO402_THERE;
    case MSID_CO402_OPERATION_ENABLED: return write_cw(cw, MSID_CO402_CW_QUICK_STOP);  /* 11: brake on the ramp */
    case MSID_CO402_QUICK_STOP_ACTIVE:                                                 /* 12 */
    case MSID_CO402_READY:                                                             /* 7 */
    case MSID_CO402_SWITCHED_ON: return write_cw(cw, MSID_CO402_CW_DISABLE_VOLTAGE);   /* 10 */
    case MSID_CO402_NOT_READY:
    case MSID_CO402_FAULT_REACTION: return MSID_CO402_WAIT;
    }
    return MSID_CO402_STUCK;
}

msid_co402_action msid_co402_step(msid_co402_state from, int up, uint16_t last_cw, int reset_faults, uint16_t *cw)
{
    return up ? step_up(from, last_cw, reset_faults, cw) : step_out(from, cw);
}

static int read_state(msid_co_sdo *s, msid_co402_state *st)
{
    uint32_t sw;
    const int rc = msid_co_sdo_read_uint(s, MSID_CO402_STATUSWORD, 0, 2, &sw);
    if (!rc) *st = msid_co402_decode((uint16_t)sw);
    return rc;
}

int msid_co402_goto(msid_co_sdo *s, int up, int reset_faults, int timeout_ms, msid_co402_state *final)
{
    if (!s || timeout_ms <= 0) return -MSID_DAQ_E_ARG;
    const uint64_t deadline = msid_co_now_ms(&s->io) + (uint64_t)timeout_ms;
    uint16_t cw = 0, last = 0;
    msid_co402_state st = MSID_CO402_NOT_READY;
    int writes = 0, rc;
    for (;;) {
        if ((rc = read_state(s, &st))) return rc;
        if (final) *final = st;
        const msid_co402_action a = msid_co402_step(st, up, last, reset_faults, &cw);
        if (a == MSID_CO402_THERE) return 0;
        if (a == MSID_CO402_STUCK) {
            snprintf(s->err, sizeof s->err, "node %u is in fault (statusword 0x6041): not reset", (unsigned)s->node);
            return -MSID_DAQ_E_DEVICE;
        }
        if (writes >= 16 || msid_co_now_ms(&s->io) >= deadline) {
            snprintf(s->err, sizeof s->err, "node %u stays in \"%s\" on the way %s \"operation enabled\" (%d controlword writes, %d ms)",
                     (unsigned)s->node, msid_co402_state_name(st), up ? "to" : "out of", writes, timeout_ms);
            return -MSID_DAQ_E_DEVICE;
        }
        if (a == MSID_CO402_WRITE) {
            if ((rc = msid_co_sdo_write_uint(s, MSID_CO402_CONTROLWORD, 0, 2, cw))) return rc;
            last = cw;
            writes++;
        }
    }
}

int msid_co402_set_mode(msid_co_sdo *s, msid_co402_mode mode, int timeout_ms)
{
    if (!s || timeout_ms <= 0) return -MSID_DAQ_E_ARG;
    int rc = msid_co_sdo_write_uint(s, MSID_CO402_MODE, 0, 1, (uint32_t)mode);
    if (rc) return rc;
    const uint64_t deadline = msid_co_now_ms(&s->io) + (uint64_t)timeout_ms;
    uint32_t shown;
    do {
        if ((rc = msid_co_sdo_read_uint(s, MSID_CO402_MODE_DISPLAY, 0, 1, &shown))) return rc;
        if ((int8_t)shown == (int)mode) return 0;
    } while (msid_co_now_ms(&s->io) < deadline);
    snprintf(s->err, sizeof s->err, "node %u displays mode %d (%s) in 0x6061 after %s was written to 0x6060",
             (unsigned)s->node, (int)(int8_t)shown, msid_co402_mode_name((int8_t)shown), msid_co402_mode_name((int)mode));
    return -MSID_DAQ_E_DEVICE;
}
