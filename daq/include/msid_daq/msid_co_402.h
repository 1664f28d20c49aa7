/**
 * @file msid_co_402.h
 * @brief CiA 402 drive profile: the statusword 0x6041 decoded into the drive's state, the controlword
 *        0x6040 that takes it one step to "operation enabled" or back out of it, and the modes of
 *        operation 0x6060 / 0x6061.
 *
 * The way up is CiA 402's transitions 2, 3 and 4 (shutdown, switch on, enable
 * operation) from "switch on disabled", after a fault reset (transition 15, a
 * rising edge of controlword bit 7) when the caller allows one. The way out of
 * "operation enabled" is a quick stop (transition 11) and then disable voltage
 * (transition 12): the drive brakes on its quick-stop ramp and ends in "switch
 * on disabled" (or stays in "quick stop active" when its quick stop option code
 * says so, until disable voltage). ::msid_co402_step is the pure rule;
 * ::msid_co402_goto applies it over SDO, reading the statusword after each write.
 */
#ifndef MSID_CO_402_H
#define MSID_CO_402_H

#include <stdint.h>
#include "msid_co_sdo.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Object indices of the profile. */
#define MSID_CO402_CONTROLWORD 0x6040u
#define MSID_CO402_STATUSWORD 0x6041u
#define MSID_CO402_MODE 0x6060u          /**< modes of operation (int8, written) */
#define MSID_CO402_MODE_DISPLAY 0x6061u  /**< modes of operation display (int8, read) */

/** Controlword commands (CiA 402 table 5; bit 7 is fault reset on its rising edge). */
#define MSID_CO402_CW_SHUTDOWN 0x0006u
#define MSID_CO402_CW_SWITCH_ON 0x0007u
#define MSID_CO402_CW_ENABLE_OPERATION 0x000Fu
#define MSID_CO402_CW_DISABLE_VOLTAGE 0x0000u
#define MSID_CO402_CW_QUICK_STOP 0x0002u
#define MSID_CO402_CW_FAULT_RESET 0x0080u

/** States of the drive's power state machine. */
typedef enum msid_co402_state {
    MSID_CO402_NOT_READY = 0,      /**< not ready to switch on (passes by itself) */
    MSID_CO402_SWITCH_ON_DISABLED,
    MSID_CO402_READY,              /**< ready to switch on */
    MSID_CO402_SWITCHED_ON,
    MSID_CO402_OPERATION_ENABLED,
    MSID_CO402_QUICK_STOP_ACTIVE,
    MSID_CO402_FAULT_REACTION,     /**< fault reaction active (passes by itself, to fault) */
    MSID_CO402_FAULT
} msid_co402_state;

/** Modes of operation (0x6060 values). */
typedef enum msid_co402_mode {
    MSID_CO402_MODE_PP = 1,   /**< profile position */
    MSID_CO402_MODE_PV = 3,   /**< profile velocity */
    MSID_CO402_MODE_PT = 4,   /**< profile torque */
    MSID_CO402_MODE_HM = 6,   /**< homing */
    MSID_CO402_MODE_IP = 7,   /**< interpolated position */
    MSID_CO402_MODE_CSP = 8,  /**< cyclic synchronous position: target 0x607A each SYNC */
    MSID_CO402_MODE_CSV = 9,  /**< cyclic synchronous velocity: target 0x60FF each SYNC */
    MSID_CO402_MODE_CST = 10  /**< cyclic synchronous torque: target 0x6071 each SYNC */
} msid_co402_mode;

/** @brief The state a statusword reports (bits 0..3, 5 and 6; the others are ignored). */
msid_co402_state msid_co402_decode(uint16_t statusword);

/** @brief "switch on disabled", "operation enabled", ... (CiA 402's names). */
const char *msid_co402_state_name(msid_co402_state s);

/** @brief "cyclic synchronous torque (CST)", ...; "unknown mode" for a value CiA 402 does not define here. */
const char *msid_co402_mode_name(int mode);

/** What ::msid_co402_step asks of the caller. */
typedef enum msid_co402_action {
    MSID_CO402_THERE = 0,  /**< the drive is where it should be */
    MSID_CO402_WRITE = 1,  /**< write *cw to the controlword */
    MSID_CO402_WAIT = 2,   /**< a transient state: read the statusword again */
    MSID_CO402_STUCK = 3   /**< in fault and no fault reset allowed: the caller names the fault */
} msid_co402_action;

/**
 * @brief The next controlword on the way from state `from` to operation enabled (up != 0) or out of it
 *        (up == 0: to "switch on disabled"; "quick stop active" then goes on to it; "fault" counts as out).
 * @param last_cw the controlword written last (a fault reset needs bit 7 low before its rising edge)
 * @param reset_faults 1: a fault on the way up is reset
 */
msid_co402_action msid_co402_step(msid_co402_state from, int up, uint16_t last_cw, int reset_faults, uint16_t *cw);

/**
 * @brief Take the drive to operation enabled (up) or out of it over SDO, for at most timeout_ms
 *        (the io's clock), at most 16 controlword writes.
 * @param final receives the last state read (may be NULL)
 * @return 0; -MSID_DAQ_E_DEVICE for a drive in fault that was not to be reset or that stays in fault, or
 *         one that does not follow the transitions in time (s->err names the state it stays in); or the SDO's error
 */
int msid_co402_goto(msid_co_sdo *s, int up, int reset_faults, int timeout_ms, msid_co402_state *final);

/**
 * @brief Write the mode of operation and wait (at most timeout_ms) for 0x6061 to display it.
 * @return 0; -MSID_DAQ_E_DEVICE when the drive displays another mode (s->err names both); or the SDO's error
 */
int msid_co402_set_mode(msid_co_sdo *s, msid_co402_mode mode, int timeout_ms);

#ifdef __cplusplus
}
#endif
#endif
