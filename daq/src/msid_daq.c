/* Status messages shared by every daq transport. */
#include "msid_daq/msid_daq.h"

const char *msid_daq_strerror(msid_daq_status s)
{
    switch (s) {
    case MSID_DAQ_OK: return "ok";
    case MSID_DAQ_E_TIMEOUT: return "timed out";
    case MSID_DAQ_E_EOF: return "end of log";
    case MSID_DAQ_E_NOSUPPORT: return "no SocketCAN in this kernel";
    case MSID_DAQ_E_NODEV: return "no such CAN interface";
    case MSID_DAQ_E_PERM: return "operation not permitted";
    case MSID_DAQ_E_DOWN: return "CAN interface is down";
    case MSID_DAQ_E_NOFD: return "the interface does not carry CAN FD";
    case MSID_DAQ_E_IO: return "I/O error";
    case MSID_DAQ_E_FORMAT: return "malformed candump log line";
    case MSID_DAQ_E_ARG: return "bad argument";
    case MSID_DAQ_E_BUSY: return "send queue full";
    case MSID_DAQ_E_CRC: return "reply with a bad CRC";
    case MSID_DAQ_E_EXCEPTION: return "exception response";
    case MSID_DAQ_E_BADDATA: return "reply does not match the request";
    case MSID_DAQ_E_CONNECT: return "cannot connect";
    default: return "unknown daq status";
    }
}
