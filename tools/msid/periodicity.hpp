// Is the input periodic, with which period, at which bins? The checks behind
// `msid frf --period auto`, `--lines auto`, and the diagnostics that name a
// non-periodic input or a wrong --period (docs/statistics.md, "Input
// periodicity").
#pragma once
#include "csv_io.hpp"

#include <string>
#include <vector>

namespace msidcli {

// A record is called not periodic with period P when more than this fraction
// of its input power changes from period to period.
constexpr double NONPERIODIC_FRACTION = 0.5;
// Family-wise false-alarm probability of --lines auto (all bins of a record).
constexpr double LINES_AUTO_ALPHA = 0.01;

// Fraction of the inputs' (AC) power that is not periodic with period P, over
// periods first .. first+count-1 (count >= 2) of r:
//   eta = sum_p sum_n |u_p[n] - ubar[n]|^2 / sum_p sum_n |u_p[n] - mean(u)|^2,
// pooled over the input channels (Parseval: the same sum over DFT bins, so it
// is the share of the input spectrum that differs between periods).
double nonperiodic_fraction(const Record &r, uint32_t P, size_t first, size_t count);

// Before the periodic FRF: throws one Error when an experiment's input is not
// periodic with period P (pointing at --method lpm) or repeats with another
// period (naming it, with the leakage and the phase drift that period P
// causes). `bins` (may be empty) are the excited lines, for the leakage figure.
void check_periodic_inputs(uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins,
                           const std::vector<Record> &recs);

// --period auto: the period of the inputs of the first record (autocorrelation,
// refined by nonperiodic_fraction). Throws Error saying so when the input does
// not repeat (at least twice). `report` describes what was found.
uint32_t find_period(const std::vector<Record> &recs, std::string &report);

// --lines auto: bins 1 .. ceil(P/2)-1 where an input carries a periodic
// component: per record and input channel, F = K |mean U|^2 / s^2 over the K
// periods after `skip` (F(2, 2(K-1)) without excitation) beyond its
// Bonferroni level LINES_AUTO_ALPHA / (bins x channels x records), and above
// a round-off floor 1e-20 x the strongest bin. `report` describes the test.
std::vector<uint32_t> find_lines(const std::vector<Record> &recs, uint32_t P, uint32_t skip, std::string &report);

// "1,3,5:2:11,20:25": a bin list in the --lines syntax.
std::string format_bins(const std::vector<uint32_t> &bins);

}  // namespace msidcli
