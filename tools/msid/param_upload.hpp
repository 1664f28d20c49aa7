// The design as the msid-can/1 parameter set (CFG records, CRC-32), shared by the
// CAN upload (CFG frames) and the Modbus upload (parameter mailbox): the device
// rebuilds the design from these parameters with lib/, never from samples.
#pragma once
#include "host_libs.hpp"

extern "C" {
#include "msid_daq/msid_params.h"
}

namespace msidcli {

// The design the device builds from `c` (exactly as firmware_sim does).
struct DevDesign {
    Mem mtw, md;
    msid_twiddle tw{};
    msid_design d{};
    msid_status st = MSID_OK;
};
std::unique_ptr<DevDesign> device_design(const msid_params &c);

// Stream options that travel with the design.
struct StreamFmt {
    uint32_t encoding = MSID_CAN_ENC_S16, fd = 0, rate = 0, periods = 8;
    float scale = 0.001f;
};

// The options every `measure` command shares: --scale, --periods (2..100000,
// default the design's or 8) and --rate (whole Hz, 0: unpaced) into `sf`; the
// design's lines and --skip-periods/--detect-lines/--transient/--alpha into `rq`
// (a DT rate also sets rq.fs). --skip-periods must leave 2 periods. Throws UsageError.
void parse_measure_options(const Args &a, const Design &D, StreamFmt &sf, FrfRequest &rq);

// Same lines and coefficients (what the device would generate).
bool same_coef(const msid_design &a, const msid_design &b);

// The parameter set of a design: the compact form (phase mode + seed) when the device
// rebuilds exactly the same coefficients from it, else explicit phases. Throws Error.
std::unique_ptr<msid_params> config_from_design(const Design &D, const StreamFmt &s);

}  // namespace msidcli
