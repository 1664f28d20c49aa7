// Common types of the msid host fitting library (C++17, Eigen).
#pragma once
#include <Eigen/Dense>
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

namespace msidfit {

using cd = std::complex<double>;
using MatC = Eigen::MatrixXcd;
using VecC = Eigen::VectorXcd;
using MatR = Eigen::MatrixXd;
using VecR = Eigen::VectorXd;

// One clear message; the CLI prints it once and exits non-zero.
struct FitError : std::runtime_error {
    explicit FitError(const std::string &m) : std::runtime_error(m) {}
};

enum class Domain { DT, CT };

// One FRF line with its weighting.
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

// An msid-frf/1 file.
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
    std::vector<Line> lines;
    size_t g() const { return (size_t)nu * ny; }
};

// Frequency variable of a line for a model of the given domain:
// DT: z = exp(j*2*pi*freq); CT: s = j*omega (omega in rad/s).
cd line_point(const Line &l, Domain d);

}  // namespace msidfit
