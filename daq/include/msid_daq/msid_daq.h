/**
 * @file msid_daq.h
 * @brief The one error space of the host acquisition (daq/): every daq
 *        object (transports, the Modbus client and poller, the CAN session)
 *        returns 0 (or a count) on success and a negative code on failure.
 *
 * A negative code is either -msid_daq_status (the link, the device or the
 * protocol failed) or, when the core (lib/) refused, the core's status carried
 * unchanged: ::msid_daq_core(st) == -(MSID_DAQ_CORE_BASE + st). A caller asks
 * ::msid_daq_core_status for the core's reason and ::msid_daq_message for the
 * text of any code; it never looks into an object for the reason. The objects
 * that keep a message buffer (`err`) add the details (addresses, counts,
 * device error names). The CAN frame decoder and ::msid_stream feed the core
 * directly and return msid_status, the core's own space.
 */
#ifndef MSID_DAQ_H
#define MSID_DAQ_H

#include "msid/msid_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Transport status codes (negative returns of the backend functions). */
typedef enum msid_daq_status {
    MSID_DAQ_OK = 0,
    MSID_DAQ_E_TIMEOUT,     /**< nothing arrived in time */
    MSID_DAQ_E_EOF,         /**< end of a replayed log */
    MSID_DAQ_E_NOSUPPORT,   /**< the kernel has no SocketCAN (AF_CAN) */
    MSID_DAQ_E_NODEV,       /**< no such interface */
    MSID_DAQ_E_PERM,        /**< operation not permitted */
    MSID_DAQ_E_DOWN,        /**< interface is down */
    MSID_DAQ_E_NOFD,        /**< CAN FD requested on a classic-only interface */
    MSID_DAQ_E_IO,          /**< other system error (see the backend's message) */
    MSID_DAQ_E_FORMAT,      /**< malformed log line or DBC file */
    MSID_DAQ_E_ARG,         /**< bad argument */
    MSID_DAQ_E_BUSY,        /**< send queue stayed full */
    MSID_DAQ_E_CRC,         /**< Modbus RTU: reply with a bad CRC */
    MSID_DAQ_E_EXCEPTION,   /**< Modbus: the device answered with an exception response */
    MSID_DAQ_E_BADDATA,     /**< Modbus: a reply that does not match the request */
    MSID_DAQ_E_CONNECT,     /**< Modbus: cannot connect (TCP) or open the serial port (RTU) */
    MSID_DAQ_E_DEVICE,      /**< the device reported an error or refused the configuration (the object's err names it) */
    MSID_DAQ_E_PROTOCOL,    /**< the device does not follow the protocol (version, CRC, counts; the object's err) */
    MSID_DAQ_E_HOOK,        /**< the caller's frame hook failed (e.g. a log that cannot be written) */
    MSID_DAQ_E_STOPPED,     /**< the caller's poll hook asked to stop (e.g. Ctrl-C): complete periods are kept */
    MSID_DAQ_E_RANGE,       /**< DBC: a value that does not fit its signal (bits or the DBC's range) */
    MSID_DAQ_E_SHORT,       /**< DBC: a payload that ends before the signal */
    MSID_DAQ_E_COUNT_
} msid_daq_status;

/** Core statuses are carried as -(MSID_DAQ_CORE_BASE + msid_status), beyond every msid_daq_status. */
#define MSID_DAQ_CORE_BASE 1000

/** @brief Message of a transport status. */
const char *msid_daq_strerror(msid_daq_status s);

/** @brief A core status in the daq error space: 0 for MSID_OK, else -(MSID_DAQ_CORE_BASE + st). */
int msid_daq_core(msid_status st);

/** @brief The core status a daq code carries (MSID_OK if the code is not a core refusal). */
msid_status msid_daq_core_status(int rc);

/** @brief Text of any daq code: msid_strerror of a carried core status, else ::msid_daq_strerror of -rc ("ok" for rc >= 0). */
const char *msid_daq_message(int rc);

#ifdef __cplusplus
}
#endif
#endif
