// The periodic FRF job's result as arrays: what an msid-frf/1 file holds, without a document tree.
// FrfJob::finish() fills it from the core's arrays; write_frf_text() streams the file's text from it
// (the bytes msidfrf::dump() gives of the document frf_document() builds), and the Python extension
// turns its arrays into NumPy arrays.
#pragma once
#include "frf_file.hpp"

#include <complex>
#include <string>
#include <vector>

namespace msidjob {

using Json = msidfrf::Json;

struct FrfResult {
    using cd = std::complex<double>;
    msidfrf::Header header;                  // format .. output_units (nu, ny, m: the dimensions below)
    uint64_t periods_used = 0, periods_rejected = 0;   // over every experiment
    std::string dft_path;                    // "stream" or "fft"
    std::vector<cd> noise_cov;               // ny x ny, row-major: the noise covariance of the samples
    std::vector<msidfrf::Experiment> experiments;   // m of them, in order
    // The excited lines, L of them; every array is line after line, each line's matrix row-major.
    std::vector<msidfrf::Position> pos;      // bin, frequency
    std::vector<cd> G;                       // L x ny x nu
    std::vector<cd> cov, cov_ki;             // L x g x g, g = ny nu (vec stacks columns); cov_ki: known input
    std::vector<double> dof, dof_ki;         // L: complex degrees of freedom of cov and cov_ki
    std::vector<cd> noise;                   // L x ny x ny: the output noise covariance per line
    std::vector<double> snr;                 // L x ny, dB (non-finite: null in the file)
    std::vector<double> cond, input_snr;     // L: the input matrix's condition number; input SNR in dB
    // The detection lines (not excited), Ld of them.
    std::vector<uint32_t> detect_bins;
    std::vector<cd> detect_mean;             // Ld x m x ny: the output's period mean per experiment
    std::vector<double> detect_var, detect_p;   // Ld x ny: noise variance and p value per output
    // The members written after the lines, in order: nonlinear_distortion, lines_auto, and a session's
    // acquisition block and completeness. They are small (a few dozen values) and differ by device
    // and source, so they stay a document of their own.
    Json tail = Json::object();

    size_t n_lines() const { return pos.size(); }
    size_t g() const { return (size_t)header.nu * header.ny; }
};

// The msid-frf/1 document of `r` (a tree: for callers that edit or compare documents).
Json frf_document(const FrfResult &r);
// That document without its lines (some dozen members: the header, the counts, the experiments,
// the detection lines and the tail), its members in the document's order.
Json frf_meta(const FrfResult &r);

// Appends the text of frf_document(r) as msidfrf::dump(doc, 1, out) writes it, and a newline, the
// lines written straight from the arrays (two threads for 64 lines or more, the same bytes).
// Throws msidfrf::NonFinite where dump() would (a NaN or Inf in a number that is not nullable).
void write_frf_text(const FrfResult &r, std::string &out);

// write_frf_text() to `path`, atomically (msidutil::write_file_atomic); a non-finite number is an
// Error naming its place in the document, as msidfmt::write_json_file() says it.
void write_frf_file(const std::string &path, const FrfResult &r, bool durable = true);

}  // namespace msidjob
