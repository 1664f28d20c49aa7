// msid_formats: excitation designs built from parameters, and the msid-design/1 JSON file.
#pragma once
#include <memory>
#include <vector>

#include "msid_host_util.hpp"
#include "msid_json_file.hpp"
#include <nlohmann/json.hpp>


namespace msidfmt {

using msidutil::check;
using msidutil::Mem;

struct DesignParams {
    uint32_t period = 0;
    std::vector<uint32_t> bins;        // DT design
    std::vector<double> omega;         // CT design (rad/s), with sample_time
    double sample_time = 0.0;
    std::vector<double> amplitudes;    // empty, L, or nu*L (amp_per_input)
    bool amp_per_input = false;
    msid_phase_mode phase_mode = MSID_PHASE_RANDOM;
    std::vector<double> phases;        // nu*L turns (user)
    uint64_t seed = 1;
    uint32_t n_inputs = 1, n_experiments = 1;
    msid_pattern pattern = MSID_PATTERN_DFT;
    uint32_t periods = 0;              // recommended number of periods (0: unspecified)
};

// A built design with its twiddle table (owned memory).
struct Design {
    DesignParams params;
    Mem mem_tw, mem_d;
    msid_twiddle tw{};
    msid_design d{};
    bool is_ct() const { return d.is_ct != 0; }
};

// Build and validate; errors name the offending lines.
std::unique_ptr<Design> build_design(const DesignParams &p);

Json design_to_json(const Design &d);
std::unique_ptr<Design> read_design_file(const std::string &path);

}  // namespace msidfmt
