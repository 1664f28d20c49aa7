#include "frf_data.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {

cd line_point(const Line &l, Domain d)
{
    if (d == Domain::DT) return std::polar(1.0, 2.0 * M_PI * l.freq);
    return cd(0.0, l.omega);
}

static std::string where(const std::string &file, const std::string &what) { return "'" + file + "': " + what; }

std::vector<WeightedLine> weigh(const FrfData &f, Domain d, Weight w, double noise_var)
{
    if (f.domain == Domain::CT && d == Domain::DT)
        throw FitError("'" + f.path + "' holds a continuous-time FRF (lines may alias); fit a ct model (--domain ct)");
    const size_t g = f.g();
    std::vector<WeightedLine> out;
    for (const Line &l : f.lines) {
        WeightedLine wl;
        wl.x = line_point(l, d);
        wl.real = l.real;
        wl.G = l.G;
        MatC C;
        if (w == Weight::None) {
            C = MatC::Identity(g, g);
            wl.dof = 1e9;
        } else if (noise_var > 0.0) {
            if (l.cov_ki.size() == 0 || l.noise.size() == 0)
                throw FitError("'" + f.path + "': --noise-var needs cov_known_input and noise_cov at every line");
            const double sp = l.noise(0, 0).real();
            if (!(sp > 0)) throw FitError(where(f.path, "zero noise_cov at line bin " + std::to_string(l.bin)));
            MatC Om(f.nu, f.nu);
            for (uint32_t a = 0; a < f.nu; ++a)
                for (uint32_t b = 0; b < f.nu; ++b) Om(a, b) = l.cov_ki(f.ny * a, f.ny * b) / sp;
            MatC S = MatC::Identity(f.ny, f.ny) * (noise_var * f.P);
            C = MatC(g, g);
            for (uint32_t a = 0; a < f.nu; ++a)
                for (uint32_t b = 0; b < f.nu; ++b) C.block(f.ny * a, f.ny * b, f.ny, f.ny) = Om(a, b) * S;
            wl.dof = 1e9;   // known noise
        } else {
            const MatC &src = w == Weight::KnownInput ? l.cov_ki : l.cov;
            if (src.size() == 0)
                throw FitError("'" + f.path + "' has no " + (w == Weight::KnownInput ? "cov_known_input" : "cov") +
                               " at line bin " + std::to_string(l.bin) + ": this method needs the FRF covariance");
            C = src;
            wl.dof = w == Weight::KnownInput ? l.dof_ki : l.dof;
            // The nonparametric covariance with several inputs is sum_e (w_e^T conj w_e) (x) S_e with
            // rank-one design factors: its inverse splits over the experiments, so its inverse moments
            // are those of one experiment's Wishart (K_e - 1 = dof/m dof for balanced designs), not of
            // the pooled dof. With one input the factors are scalars and the pooled dof applies.
            if (w == Weight::Cov && f.nu > 1 && f.m > 1 && f.method != "lpm" && f.method != "etfe" && f.realisations < 2)
                wl.dof = l.dof / f.m;
            // A robust-BLA file's cov is a plain sample covariance of the g = ny nu vector (R - 1 dof):
            // its inverse moment is n/(n - g); dof/nu gives that mean in the laws written for p = ny.
            if (w == Weight::Cov && f.nu > 1 && f.realisations >= 2) wl.dof = l.dof / f.nu;
        }
        // Hermitian part; real lines: real covariance
        MatC H = 0.5 * (C + C.adjoint());
        if (l.real) H = H.real().cast<cd>();
        // a zero variance is a dead (or noise-free) channel, not a "singular" covariance: name the entry
        if (w != Weight::None)
            for (Eigen::Index a = 0; a < H.rows(); ++a)
                if (H(a, a).real() == 0.0 && H.diagonal().real().maxCoeff() > 0)
                    throw FitError(where(f.path, "G[" + std::to_string(a % f.ny + 1) + "," + std::to_string(a / f.ny + 1) +
                                                     "] (output " + std::to_string(a % f.ny + 1) + ", input " +
                                                     std::to_string(a / f.ny + 1) + ") has zero variance at line bin " +
                                                     std::to_string(l.bin) +
                                                     ": a dead or noise-free channel cannot be weighted by its inverse "
                                                     "covariance (leave the channel out, or --weight none)"));
        Eigen::LLT<MatC> llt(H);
        const double scale = H.diagonal().real().cwiseAbs().maxCoeff();
        if (llt.info() != Eigen::Success || !(scale > 0) || !std::isfinite(scale)) {
            // a sample covariance of ny outputs from M periods has rank <= M - 1: name that cause
            if (w != Weight::None && noise_var <= 0.0 && wl.dof < (double)f.ny && scale > 0 && std::isfinite(scale))
                throw FitError("'" + f.path + "': the covariance rests on " + std::to_string(std::lround(wl.dof + 1)) +
                               " periods per experiment, too few for " + std::to_string(f.ny) +
                               " outputs (singular at line bin " + std::to_string(l.bin) +
                               "): weighting by the inverse sample covariance needs M >= 4 (Pintelon 2002, Theorem 2) "
                               "and M > " + std::to_string(f.ny) + " for " + std::to_string(f.ny) +
                               " outputs; measure more periods or use --weight none");
            throw FitError("'" + f.path + "': singular weights at line bin " + std::to_string(l.bin) +
                           " (covariance not positive definite)");
        }
        MatC Lm = llt.matrixL();
        // condition of the correlation matrix diag(H)^-1/2 H diag(H)^-1/2 (its Cholesky diagonal is
        // L_ii / sqrt(H_ii)): outputs in units 1e12 apart (nm and km) are not a singular covariance
        double dmin = 1e300, dmax = 0;
        for (Eigen::Index i = 0; i < Lm.rows(); ++i) {
            const double di = Lm(i, i).real() / std::sqrt(H(i, i).real());
            dmin = std::min(dmin, di);
            dmax = std::max(dmax, di);
        }
        if (!(dmin > 1e-8 * dmax))
            throw FitError("'" + f.path + "': singular weights at line bin " + std::to_string(l.bin) +
                           " (covariance condition number above 1e16)");
        wl.Linv = Lm.triangularView<Eigen::Lower>().solve(MatC::Identity(g, g));
        // the whitened value must be representable: |G| / sd near 1e154 or more (a corrupt entry such
        // as 1e308) overflowed the cost to inf or NaN, and a NaN cost validated as "consistent, p = 1"
        if (w != Weight::None) {
            const VecC z = wl.Linv * Eigen::Map<const VecC>(l.G.data(), l.G.size());
            if (!std::isfinite(z.squaredNorm()))
                throw FitError(where(f.path, "G at line bin " + std::to_string(l.bin) +
                                                 " is beyond 1e150 of its standard deviation: the weighted cost "
                                                 "overflows (a corrupt value?)"));
        } else if (!std::isfinite(l.G.squaredNorm())) {
            throw FitError(where(f.path, "G at line bin " + std::to_string(l.bin) +
                                             " overflows when squared (|G| beyond 1e154: a corrupt value?)"));
        }
        wl.cov = H;
        out.push_back(std::move(wl));
    }
    return out;
}

}  // namespace msidfit
