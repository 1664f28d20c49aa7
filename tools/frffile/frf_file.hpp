// msid-frf/1 (docs/schemas/msid-frf-1.schema.json): the one module that writes
// the format and the one that reads it. Every estimator of the CLI (the periodic
// job, the direct time-domain LS FRF, the LPM, the ETFE, the robust BLA, the
// benchmarks) builds its document from the parts below, and every consumer
// (msid fit/validate/modes, the benchmarks, the fuzzers) reads it with read_frf().
// Units: frequencies in cycles/sample (`freq`), rad/s (`omega`, CT) and Hz (`freq_hz`);
// matrices as {"re": [[...]], "im": [[...]]} row by row; vec stacks columns.
#pragma once
#include <Eigen/Dense>
#include <complex>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace msidfrf {

using Json = nlohmann::ordered_json;
using cd = std::complex<double>;
using MatC = Eigen::MatrixXcd;

// One clear message naming the file and the offending entry (msidfit::FitError is this type).
struct Error : std::runtime_error {
    explicit Error(const std::string &m) : std::runtime_error(m) {}
};
// A file that cannot be opened or read (missing, a directory, no permission): the Python
// extension's OSError; the command line treats it as any Error.
struct IoError : Error {
    explicit IoError(const std::string &m) : Error(m) {}
};

enum class Domain { DT, CT };

// One FRF line as read.
struct Line {
    uint32_t bin = 0;
    double freq = 0.0;        // cycles per sample
    double omega = 0.0;       // rad/s (CT) or rad/sample (DT without sample time)
    bool real = false;        // DC (or Nyquist): real-valued
    MatC G;                   // ny x nu
    MatC cov;                 // (ny nu)^2, vec stacks columns
    double dof = 0.0;         // complex dof of cov
    MatC cov_ki;              // known-input covariance
    double dof_ki = 0.0;
    MatC noise;               // per-line noise covariance (ny x ny), may be empty
};

// An msid-frf/1 file as read.
struct FrfData {
    std::string path;
    uint32_t P = 0, nu = 0, ny = 0, m = 0;
    Domain domain = Domain::DT;
    double h = 0.0;           // sample time (0: unknown)
    uint32_t realisations = 1;  // robust BLA file (msid frf --realisations): cov is a plain sample covariance
    MatC noise_time;          // ny x ny
    // "periodic" (default), "direct", "lpm" or "etfe": lpm and etfe pool one noise
    // covariance per line (cov = M^T kron C_v, one Wishart with `dof`), so their dof is
    // not split over the experiments like the periodic nonparametric covariance's
    std::string method = "periodic";
    // LPM files: lpm.window W as written (lines share 2W of their 2W+1 bins); 0 when absent or not an
    // unsigned integer (validation_stat.hpp refuses such an LPM file)
    uint64_t lpm_window = 0;
    // the signals' names and units (msid-frf/1 input_names .. output_units), empty when the file has none
    std::vector<std::string> input_names, output_names, input_units, output_units;
    std::vector<Line> lines;
    size_t g() const { return (size_t)nu * ny; }
};

// ---------------- reading ----------------

// Parse `path` as JSON; throws IoError ("cannot open ...") or Error ("... is not valid JSON: ...").
Json read_json(const std::string &path);
// Parse a file's text already in memory; `name` is the file in messages (as read_json names it).
Json parse_json(const std::string &text, const std::string &name);

// Read and validate an msid-frf/1 file (format, shapes, finiteness, dof >= 1). Throws
// Error naming the file and the offending entry.
FrfData read_frf(const std::string &path);

// The same checks on a document already in memory (the Python extension's FRFs); `name` stands for
// the file in messages and in FrfData::path.
FrfData parse_frf(const Json &doc, const std::string &name);

// A rows x cols {"re", "im"} matrix of a document (finite numbers of that shape); `file`
// and `what` name it in the message.
MatC parse_cmat(const Json &v, size_t rows, size_t cols, const std::string &file, const std::string &what);

// ---------------- writing ----------------

// The value of the document field `vec_convention`.
extern const char *const VEC_CONVENTION;

// Fields format, generator, period_samples, n_inputs, n_outputs, n_experiments, domain,
// sample_time (CT, or DT with fs), fs_hz (fs > 0).
struct Header {
    uint32_t period = 0, nu = 0, ny = 0, m = 0;
    bool ct = false;
    double sample_time = 0.0;   // s (CT)
    double fs = 0.0;            // Hz, 0: not given
    // The signals' names (nu and ny of them, or empty: u1.., y1.. are meant) and units (the same
    // counts, "" where unknown, or empty: none known); written only when not empty.
    std::vector<std::string> input_names, output_names, input_units, output_units;
};
Json header(const Header &h);

// Position fields of a line: bin, freq = bin / period, and for CT omega (rad/s), folded,
// freq_hz = omega / 2 pi; for DT with fs freq_hz = freq fs; real for DC.
struct Position {
    uint32_t bin = 0, period = 0;
    bool ct = false;
    double omega = 0.0;
    bool folded = false;
    double fs = 0.0;
};
Json position(const Position &p);

// {"re": [[...]], "im": [[...]]} of a rows x cols complex matrix stored row-major
// (msid_cplx and std::complex<double> arrays alike) or of an Eigen matrix.
Json cmat(const cd *a, size_t rows, size_t cols);
Json cmat(const MatC &M);
// The matrix of a row-major rows x cols array (the C core's and tools/est's layout).
MatC from_row_major(const cd *a, size_t rows, size_t cols);

// A finite number, or null (NaN, infinite).
Json finite_or_null(double v);

// The statistics of one excited line, written after its position fields in this order:
// G, cov, dof, cov_known_input, dof_known_input, pcov, noise_cov, snr, cond, input_snr.
struct LineStats {
    MatC G;                   // ny x nu
    MatC cov;                 // g x g, g = ny nu
    double dof = 0.0;
    MatC cov_ki;              // empty: the same as cov
    double dof_ki = 0.0;
    MatC pcov;                // pseudo-covariance (direct estimator); empty: not written
    MatC noise;               // ny x ny; empty: not written
    std::vector<double> snr;  // dB per output (non-finite: null)
    std::optional<double> cond, input_snr;   // written when set (non-finite: null)
};
Json line(Json position, const LineStats &s);

// Where one experiment came from and what its periods did. Optional blocks are written
// only by the estimators that test them.
struct Experiment {
    std::string source;
    uint64_t samples = 0, periods_total = 0, periods_skipped = 0, periods_used = 0;
    uint64_t periods_gap = 0, periods_nonfinite = 0;
    std::optional<bool> transient_tested;
    uint64_t periods_untested = 0;   // used after the test's history filled (written when > 0)
    std::vector<uint32_t> transient_flagged, transient_dropped;   // period numbers from 1
    bool drift_block = false;   // write drift_tested, drift, drift_p_value
    bool drift_tested = false, drift = false;
    double drift_p_value = 0.0;
    uint64_t leftover_samples = 0;
};
Json experiment(const Experiment &e);

// A non-excited detection line: bin, freq, freq_hz (fs > 0), Y_mean (m x ny), noise_var
// and p_value per output.
Json detection_line(uint32_t bin, uint32_t period, double fs, const MatC &Y_mean, const std::vector<double> &noise_var,
                    const std::vector<double> &p_value);

}  // namespace msidfrf
