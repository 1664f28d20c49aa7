#include "bla.hpp"

#include "stats.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace msidstat {

BlaLine bla_total(const std::vector<MatC> &G)
{
    const size_t R = G.size();
    if (R < 2) throw std::invalid_argument("the robust BLA needs at least 2 realisations");
    const Eigen::Index ny = G[0].rows(), nu = G[0].cols(), g = ny * nu;
    BlaLine b;
    b.G = MatC::Zero(ny, nu);
    for (size_t r = 0; r < R; ++r) b.G += G[r];
    const double Rd = (double)R;
    b.G /= Rd;
    b.cov = MatC::Zero(g, g);
    const MatC gm = Eigen::Map<const MatC>(b.G.data(), g, 1);
    for (size_t r = 0; r < R; ++r) {
        const MatC d = Eigen::Map<const MatC>(G[r].data(), g, 1) - gm;
        b.cov += d * d.adjoint();
    }
    b.cov /= Rd * (Rd - 1.0);
    b.dof = Rd - 1.0;
    return b;
}

BlaLine bla_line(const std::vector<MatC> &G, const std::vector<MatC> &cov, const std::vector<double> &dof)
{
    const size_t R = G.size();
    if (R < 2 || cov.size() != R || dof.size() != R) throw std::invalid_argument("the robust BLA needs at least 2 realisations");
    const Eigen::Index g = G[0].rows() * G[0].cols();
    BlaLine b = bla_total(G);
    b.cov_noise = MatC::Zero(g, g);
    for (size_t r = 0; r < R; ++r) {
        b.cov_noise += cov[r];
        b.dof_noise += dof[r];
    }
    const double Rd = (double)R;
    b.cov_noise /= Rd * Rd;
    b.var_nl = (b.cov - b.cov_noise).diagonal().real();
    b.var_s = Rd * b.var_nl;
    b.p_value.resize(g);
    for (Eigen::Index i = 0; i < g; ++i) {
        const double vn = b.cov_noise(i, i).real();
        b.p_value(i) = vn > 0 ? f_sf(2.0 * b.dof, 2.0 * b.dof_noise, b.cov(i, i).real() / vn) : NAN;
    }
    return b;
}

double fisher_combined(const std::vector<double> &p, int *n, int *significant)
{
    double x = 0;
    int k = 0, sig = 0;
    for (double v : p) {
        if (!std::isfinite(v)) continue;
        x -= 2.0 * std::log(std::max(v, 1e-300));
        ++k;
        sig += v < 0.01;
    }
    if (n) *n = k;
    if (significant) *significant = sig;
    return k ? chi2_sf(2.0 * k, x) : 1.0;
}

BlaSummary bla_summary(const std::vector<BlaLine> &lines)
{
    BlaSummary s;
    double nl = 0, nn = 0;
    std::vector<double> p;
    for (const auto &l : lines) {
        for (Eigen::Index i = 0; i < l.p_value.size(); ++i) p.push_back(l.p_value(i));
        nl += l.var_nl.sum();
        nn += l.cov_noise.diagonal().real().sum();
    }
    s.p_value = fisher_combined(p, &s.entries, &s.significant);
    s.detected = s.p_value < BLA_DETECT_ALPHA;
    s.nl_to_noise_db = nl > 0 && nn > 0 ? 10.0 * std::log10(nl / nn) : NAN;
    return s;
}

}  // namespace msidstat
