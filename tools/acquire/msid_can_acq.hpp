// The CAN decoder feeding an FRF job (inside msid_acquire; also the candump replay of `msid can
// replay`): the msid-can/1 sample frames of one device into msid_meas, with an optional candump log
// of every frame, the `acquisition` block and the notes on what was lost. docs/can-protocol.md.
#pragma once
#include "msid_acquire.hpp"

extern "C" {
#include "msid_daq/msid_can_decoder.h"
#include "msid_daq/msid_can_transport.h"
}

#include <cstdio>
#include <memory>

#include "msid_partial_file.hpp"

namespace msidacq {

// The decoder and its FRF job. The log is written to PATH.tmp.PID and renamed at close_log().
struct CanAcq {
    std::unique_ptr<msidjob::FrfJob> job;
    msidutil::Mem mdec;
    msid_can_decoder dec{};
    FILE *log = nullptr;
    std::string log_path, log_tmp, iface;
    std::unique_ptr<msidutil::PartialFile> log_partial;   // the temporary, for a signal that ends the process
    ~CanAcq();
    // Start the candump log (Error when it cannot be created).
    void open_log(const std::string &path);
    // One frame into the log (Error when it cannot be written); frames without a time get the clock's.
    void log_frame(const msid_can_frame &f);
    // Flush, fsync and rename the log into place (Error when that fails; the temporary is removed).
    void close_log();
    // The FRF job (history: periods kept per experiment for the transient test) and the decoder for
    // the device's stream format `c` at identifier `base`, reorder window `window` frames.
    void init(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, uint32_t periods, uint32_t base,
              const msid_params &c, uint32_t window, uint32_t history);
    // One received frame into the decoder (Error when the measurement is full or the core refuses).
    void feed(const msid_can_frame &f);
};

// "classic/int16", "fd/float32": the frame format of a parameter set.
std::string can_format_name(const msid_params &c);
// The `acquisition` block of the FRF document.
Json can_acquisition_json(const CanAcq &a, const msid_can_link_stats &ls, const std::string &transport, uint32_t base,
                          const msid_params &cfg, uint32_t crc);
// The experiments' sources ("can:IFACE experiment i") with their sample and period counts.
std::vector<msidjob::ExpSource> can_sources(const CanAcq &a, uint32_t m);
// Notes on what was lost or ignored (gaps, kernel drops, restarts, error frames...).
std::vector<std::string> can_loss_notes(const msid_can_decoder &d, const msid_can_link_stats &ls);

}  // namespace msidacq
