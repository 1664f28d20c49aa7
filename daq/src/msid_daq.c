/* The daq error space: transport, device and protocol statuses, and core statuses carried unchanged. */
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
    case MSID_DAQ_E_FORMAT: return "malformed candump log line or DBC file";
    case MSID_DAQ_E_ARG: return "bad argument";
    case MSID_DAQ_E_BUSY: return "send queue full";
    case MSID_DAQ_E_CRC: return "reply with a bad CRC";
    case MSID_DAQ_E_EXCEPTION: return "exception response";
    case MSID_DAQ_E_BADDATA: return "reply does not match the request";
    case MSID_DAQ_E_CONNECT: return "cannot connect";
    case MSID_DAQ_E_DEVICE: return "the device reported an error";
    case MSID_DAQ_E_PROTOCOL: return "the device does not follow the protocol";
    case MSID_DAQ_E_HOOK: return "the frame hook failed";
    case MSID_DAQ_E_STOPPED: return "stopped at the caller's request";
    case MSID_DAQ_E_RANGE: return "value does not fit the signal";
    case MSID_DAQ_E_SHORT: return "payload shorter than the signal";
    default: return "unknown daq status";
    }
}

int msid_daq_core(msid_status st)
{
    return st == MSID_OK ? 0 : -(MSID_DAQ_CORE_BASE + (int)st);
}

msid_status msid_daq_core_status(int rc)
{
    return rc <= -MSID_DAQ_CORE_BASE ? (msid_status)(-rc - MSID_DAQ_CORE_BASE) : MSID_OK;
}

const char *msid_daq_message(int rc)
{
    if (rc >= 0) return msid_daq_strerror(MSID_DAQ_OK);
    if (rc <= -MSID_DAQ_CORE_BASE) return msid_strerror(msid_daq_core_status(rc));
    return msid_daq_strerror((msid_daq_status)-rc);
}
