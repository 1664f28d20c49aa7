// Is the input periodic, with which period, at which bins? The checks behind
// `msid frf --period auto`, `--lines auto`, and the diagnostics that name a
// non-periodic input or a wrong --period (docs/statistics.md, "Input
// periodicity").
#pragma once
#include "msid_frf_job.hpp"

#include <memory>
#include <string>
#include <vector>

extern "C" {
#include "msid/msid_pstats.h"
}

namespace msidjob {

// A record is called not periodic with period P when more than this fraction
// of its input power changes from period to period.
constexpr double NONPERIODIC_FRACTION = 0.5;
// Family-wise false-alarm probability of --lines auto (all bins of a record).
constexpr double LINES_AUTO_ALPHA = 0.01;

// A noisy periodic input is still periodic: its period mean is stable within
// its standard error. Per (bin, input channel) F = K |mean U|^2 / s^2 over K
// periods is F(2, 2(K-1)) when the bin holds no periodic component (Gaussian
// noise of any colour, bins taken one by one); a bin "shows" a periodic
// component at level PERIODIC_BIN_ALPHA, and the input is called periodic when
// more bins show one than chance explains: P(Binomial(tested, PERIODIC_BIN_ALPHA)
// >= shown) < PERIODIC_EVIDENCE, or one bin's tail is below PERIODIC_EVIDENCE /
// tested (Bonferroni; a few strong lines among many bins) (docs/statistics.md,
// "Input periodicity").
constexpr double PERIODIC_BIN_ALPHA = 0.01;
constexpr double PERIODIC_EVIDENCE = 1e-6;

struct PeriodicEvidence {
    size_t tested = 0;     // (bin, input channel) pairs with power
    size_t shown = 0;      // of those, with a significant period mean
    double p_value = 1.0;  // P(Binomial(tested, PERIODIC_BIN_ALPHA) >= shown)
    double eta = 0.0;      // share of the power at those bins that changes from period to period
    double min_p = 1.0;    // smallest per-bin tail: one strong line is evidence too (Bonferroni)
    bool periodic() const
    {
        return tested > 0 && (p_value < PERIODIC_EVIDENCE || min_p * (double)tested < PERIODIC_EVIDENCE);
    }
};

// P(X >= k) for X ~ Binomial(n, a).
double binomial_tail(size_t n, size_t k, double a);

// The evidence over periods first .. first+count-1 (count >= 2) of r at `bins`
// (empty: every bin 1 .. ceil(P/2)-1).
PeriodicEvidence periodic_evidence(const Record &r, uint32_t P, size_t first, size_t count,
                                   const std::vector<uint32_t> &bins);

// The same check where only the core's period statistics exist (the FRF job of
// every host path: files, msid measure, msid modbus|can measure): `ps[e]` of
// experiment e, nu inputs first among its channels, `bins` its lines. Throws one
// Error naming the source when an experiment's input is not periodic with period P
// at its lines (most of its power there changes from period to period and no
// more lines show a stable period mean than chance explains); with a period
// history a coherent phase rotation from period to period is named as a wrong
// period or a sample-clock mismatch.
void check_periodic_lines(const msid_pstats *const *ps, uint32_t m, uint32_t nu, uint32_t P,
                          const std::vector<uint32_t> &bins, const std::vector<std::string> &sources);

// Fraction of the inputs' (AC) power that is not periodic with period P, over
// periods first .. first+count-1 (count >= 2) of r:
//   eta = sum_p sum_n |u_p[n] - ubar[n]|^2 / sum_p sum_n |u_p[n] - mean(u)|^2,
// pooled over the input channels (Parseval: the same sum over DFT bins, so it
// is the share of the input spectrum that differs between periods).
double nonperiodic_fraction(const Record &r, uint32_t P, size_t first, size_t count);

// Before the periodic FRF: throws one Error when an experiment's input is not
// periodic with period P (most of its power changes from period to period and
// periodic_evidence() finds no stable period mean: pointing at --method lpm) or repeats with another
// period (naming it, with the leakage and the phase drift that period P
// causes). `bins` (may be empty) are the excited lines, for the leakage figure.
void check_periodic_inputs(uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins,
                           const std::vector<Record> &recs);

// check_periodic_inputs() reads at most the first input_check_rows(P, skip) rows of a record,
// unless input_check_needs_whole() of those rows (an input that is not periodic with P, nor with
// a neighbour, whose period the whole record is searched for; lines that show no input power,
// named from the whole record's). The FRF job's streaming
// path (estimate_frf_files) runs the check on that prefix and reads the whole record otherwise.
size_t input_check_rows(uint32_t P, uint32_t skip);
bool input_check_needs_whole(uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins, const Record &prefix);

// --period auto: the period of the inputs of the first record's first
// PERIOD_SEARCH_ROWS rows (autocorrelation, refined by nonperiodic_fraction).
// Throws Error saying so when the input does not repeat (at least twice).
// `report` describes what was found. `signal` names the inputs in the report and messages:
// "reference" when recs hold the excitation's reference columns as inputs (reference_records).
uint32_t find_period(const std::vector<Record> &recs, std::string &report, const char *signal = "input");

// --period auto searches the first PERIOD_SEARCH_ROWS rows of the first record (whole when shorter):
// periods up to half of it (2^20 samples) with two repetitions; a longer period is given (--period).
// A record streamed from its file and one read whole give the same period. The search holds those
// rows (8 bytes per column and row) and an FFT of 2^22 points (its buffer and FFTW's twiddle factors,
// about 60 MB), whatever the record's length.
constexpr size_t PERIOD_SEARCH_ROWS = (size_t)1 << 21;

// --lines auto's statistic for one record, fed one period at a time: per input channel and bin
// 1 .. ceil(P/2)-1 the running mean of the period spectra and their scatter (Welford's update, in period
// order), so a record streamed from its file and one read whole give the same bits. Memory: 24 bytes
// per bin and input, and an FFT of length P.
class LineScan {
public:
    // P >= 3 (check_lines_period); `source` names the record in messages
    LineScan(uint32_t P, uint32_t nu, std::string source);
    ~LineScan();
    LineScan(LineScan &&) noexcept;
    LineScan &operator=(LineScan &&) noexcept;
    // one period: P rows of C >= nu columns (row-major), the inputs first
    void push(const double *rows, size_t C);
    size_t periods() const;
    const std::string &source() const;

private:
    friend std::vector<uint32_t> lines_from_scans(const std::vector<LineScan> &, uint32_t, uint32_t, std::string &,
                                                  std::vector<double> *);
    struct Impl;
    std::unique_ptr<Impl> p_;
};

// Throws the --lines auto message for a period without bins between DC and Nyquist (P < 3).
void check_lines_period(uint32_t P);

// --lines auto from every record's scan (each over its periods after the `skip` skipped): the test
// find_lines() describes. Throws naming the first record with fewer than 2 periods scanned.
std::vector<uint32_t> lines_from_scans(const std::vector<LineScan> &scans, uint32_t P, uint32_t skip,
                                       std::string &report, std::vector<double> *p_min = nullptr);

// --lines auto: bins 1 .. ceil(P/2)-1 where an input carries a periodic
// component: per record and input channel, F = K |mean U|^2 / s^2 over the K
// periods after `skip` (F(2, 2(K-1)) without excitation) beyond its
// Bonferroni level LINES_AUTO_ALPHA / (bins x channels x records), and above
// a round-off floor 1e-20 x the strongest bin. `report` describes the test.
std::vector<uint32_t> find_lines(const std::vector<Record> &recs, uint32_t P, uint32_t skip, std::string &report,
                                 std::vector<double> *p_min = nullptr);

// The bins --lines auto could not decide: where the excitation's grid (the found bins' common step
// from the first to the last found bin) has bins the test did not take although some input shows
// power there at UNDECIDED_ALPHA (its smallest p-value over inputs and records, p_min[k - 1]): a
// force that drops at a resonance or near the mains, too weak over the periods at hand for the
// family-wise level. A grid bin with no such evidence (a detection line) is not named.
constexpr double UNDECIDED_ALPHA = 0.05;
struct UndecidedLines {
    uint32_t step = 0, first = 0, last = 0;   // the grid: first, first + step, ..., last
    std::vector<uint32_t> bins;               // grid bins left out with p_min < UNDECIDED_ALPHA
    size_t silent = 0;                        // grid bins left out without it
};
UndecidedLines undecided_lines(const std::vector<uint32_t> &found, const std::vector<double> &p_min);

// "1,3,5:2:11,20:25": a bin list in the --lines syntax.
std::string format_bins(const std::vector<uint32_t> &bins);

}  // namespace msidjob
