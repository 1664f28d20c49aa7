// The design as the msid-can/1 parameter set (CFG records, CRC-32), shared by the CAN upload
// (CFG frames) and the Modbus upload (parameter mailbox): the device rebuilds the design from these
// parameters with lib/, never from samples.
#pragma once
#include "msid_design_file.hpp"
#include "msid_host_util.hpp"

extern "C" {
#include "msid_daq/msid_params.h"
}

#include <memory>

namespace msidacq {

using msidfmt::Design;

// The design the device builds from `c` (exactly as firmware_sim does); st says why it could not.
struct DevDesign {
    msidutil::Mem mtw, md;
    msid_twiddle tw{};
    msid_design d{};
    msid_status st = MSID_OK;
};
std::unique_ptr<DevDesign> device_design(const msid_params &c);

// Stream options that travel with the design to the device.
struct StreamFmt {
    uint32_t encoding = MSID_CAN_ENC_S16;  // MSID_CAN_ENC_S16 or _F32 (Modbus: the link's encoding)
    uint32_t fd = 0;                       // CAN FD sample frames
    uint32_t rate = 0;                     // samples per second, whole Hz; 0: as fast as the link carries
    uint32_t periods = 8;                  // periods per experiment, 2..MSID_PARAMS_MAX_PERIODS
    float scale = 0.001f;                  // value of one int16 step
};

// Same lines and coefficients (what the device would generate).
bool same_coef(const msid_design &a, const msid_design &b);

// The parameter set of a design: the compact form (phase mode + seed) when the device rebuilds
// exactly the same coefficients from it, else explicit phases. Throws msidutil::Error when the
// design cannot travel (too many lines, or no parameter set rebuilds it exactly).
std::unique_ptr<msid_params> config_from_design(const Design &D, const StreamFmt &s);

}  // namespace msidacq
