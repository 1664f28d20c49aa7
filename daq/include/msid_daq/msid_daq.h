/**
 * @file msid_daq.h
 * @brief Status codes shared by every transport of the host acquisition
 *        (daq/): SocketCAN, candump replay, Modbus TCP and RTU.
 *
 * Backend functions return 0 (or a count) on success and -msid_daq_status on
 * failure; ::msid_daq_strerror names a status.
 */
#ifndef MSID_DAQ_H
#define MSID_DAQ_H

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
    MSID_DAQ_E_FORMAT,      /**< malformed log line */
    MSID_DAQ_E_ARG,         /**< bad argument */
    MSID_DAQ_E_BUSY,        /**< send queue stayed full */
    MSID_DAQ_E_CRC,         /**< Modbus RTU: reply with a bad CRC */
    MSID_DAQ_E_EXCEPTION,   /**< Modbus: the device answered with an exception response */
    MSID_DAQ_E_BADDATA,     /**< Modbus: a reply that does not match the request */
    MSID_DAQ_E_CONNECT,     /**< Modbus: cannot connect (TCP) or open the serial port (RTU) */
    MSID_DAQ_E_COUNT_
} msid_daq_status;

/** @brief Message of a transport status. */
const char *msid_daq_strerror(msid_daq_status s);

#ifdef __cplusplus
}
#endif
#endif
