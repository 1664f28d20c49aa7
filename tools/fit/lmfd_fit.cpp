#include "lmfd_fit.hpp"
#include "msid_cancel.hpp"
#include "text_scan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>

namespace msidfit {

Pin parse_pin(const std::string &s)
{
    // ^\s*([DN])(\d+)(?:\[(\d+),(\d+)\])?\s*=\s*([-+0-9.eE]+)\s*$, every part read before any is converted
    size_t i = 0;
    scan_spaces(s, i);
    const char mat = i < s.size() ? s[i] : '\0';
    bool ok = (mat == 'D' || mat == 'N') && scan_char(s, i, mat);
    const std::string index = ok ? scan_digits(s, i) : std::string();
    std::string row, col, value;
    ok = ok && !index.empty();
    bool entry = false;
    if (ok && scan_char(s, i, '[')) {
        entry = true;
        row = scan_digits(s, i);
        ok = !row.empty() && scan_char(s, i, ',');
        if (ok) col = scan_digits(s, i);
        ok = ok && !col.empty() && scan_char(s, i, ']');
    }
    if (ok) {
        scan_spaces(s, i);
        ok = scan_char(s, i, '=');
    }
    if (ok) {
        scan_spaces(s, i);
        value = scan_set(s, i, "-+0123456789.eE");
        scan_spaces(s, i);
        ok = !value.empty() && i == s.size();
    }
    if (!ok) throw FitError("--pin '" + s + "': expected e.g. N0=0 or D1[1,2]=0.5 (entries 1-based)");
    // an index of more digits than an int holds (std::stoi would throw out_of_range) is no coefficient
    if (index.size() > 9 || row.size() > 9 || col.size() > 9)
        throw FitError("--pin '" + s + "': index out of range (entries 1-based)");
    Pin p;
    p.mat = mat;
    p.index = std::stoi(index);
    if (entry) { p.row = std::stoi(row) - 1; p.col = std::stoi(col) - 1; }
    try { p.value = std::stod(value); } catch (...) { throw FitError("--pin '" + s + "': bad value"); }
    if (!std::isfinite(p.value)) throw FitError("--pin '" + s + "': value not finite");
    return p;
}

static size_t q_of(const LmfdSpec &s, size_t ny, size_t nu) { return (size_t)s.nD * ny + (size_t)(s.nN + 1) * nu; }

std::vector<std::string> lmfd_param_names(const LmfdSpec &s, size_t ny, size_t nu)
{
    std::vector<std::string> n;
    for (size_t k = 0; k < ny; ++k) {
        for (int i = 1; i <= s.nD; ++i)
            for (size_t a = 0; a < ny; ++a) n.push_back("D" + std::to_string(i) + "[" + std::to_string(k + 1) + "," + std::to_string(a + 1) + "]");
        for (int j = 0; j <= s.nN; ++j)
            for (size_t b = 0; b < nu; ++b) n.push_back("N" + std::to_string(j) + "[" + std::to_string(k + 1) + "," + std::to_string(b + 1) + "]");
    }
    return n;
}

VecR lmfd_pack(const LmfdModel &m)
{
    const size_t ny = m.ny(), nu = m.nu(), q = (size_t)m.nD * ny + (size_t)(m.nN + 1) * nu;
    VecR th(q * ny);
    for (size_t k = 0; k < ny; ++k) {
        size_t t = k * q;
        for (int i = 1; i <= m.nD; ++i)
            for (size_t a = 0; a < ny; ++a) th(t++) = m.Dm[(size_t)i - 1](k, a);
        for (int j = 0; j <= m.nN; ++j)
            for (size_t b = 0; b < nu; ++b) th(t++) = m.Nm[(size_t)j](k, b);
    }
    return th;
}

LmfdModel lmfd_unpack(const VecR &th, const LmfdSpec &s, size_t ny, size_t nu, Domain d, double h)
{
    LmfdModel m;
    m.domain = d;
    m.h = h;
    m.nD = s.nD;
    m.nN = s.nN;
    m.Dm.assign((size_t)s.nD, MatR::Zero(ny, ny));
    m.Nm.assign((size_t)s.nN + 1, MatR::Zero(ny, nu));
    const size_t q = q_of(s, ny, nu);
    for (size_t k = 0; k < ny; ++k) {
        size_t t = k * q;
        for (int i = 1; i <= s.nD; ++i)
            for (size_t a = 0; a < ny; ++a) m.Dm[(size_t)i - 1](k, a) = th(t++);
        for (int j = 0; j <= s.nN; ++j)
            for (size_t b = 0; b < nu; ++b) m.Nm[(size_t)j](k, b) = th(t++);
    }
    return m;
}

// ---- internal scaled coordinates: p~ = p / ws (CT), p~ = 1/z (DT, ws = 1) ----

struct Prob {
    size_t ny, nu, q;
    Domain d;
    double h, ws;
    LmfdSpec s;
    std::vector<cd> pt;     // p~ per line
    VecR S;                 // unscaled = S .* scaled (length q, same for every row)
};

static Prob make_prob(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s)
{
    if (w.empty()) throw FitError("no lines");
    if (s.nD < 0 || s.nN < 0) throw FitError("LMFD degrees must be non-negative");
    Prob P;
    P.ny = (size_t)w[0].G.rows();
    P.nu = (size_t)w[0].G.cols();
    P.q = q_of(s, P.ny, P.nu);
    P.d = d;
    P.h = h;
    P.s = s;
    P.ws = 1.0;
    if (d == Domain::CT) {
        double lo = 1e300, hi = 0;
        for (const auto &l : w) {
            const double om = std::abs(l.x.imag());
            if (om > 0) { lo = std::min(lo, om); hi = std::max(hi, om); }
        }
        P.ws = s.wscale > 0 ? s.wscale : (hi > 0 ? std::sqrt(lo * hi) : 1.0);
    }
    for (const auto &l : w) P.pt.push_back(lmfd_var(d, l.x) / P.ws);
    P.S.resize((Eigen::Index)P.q);
    size_t t = 0;
    for (int i = 1; i <= s.nD; ++i)
        for (size_t a = 0; a < P.ny; ++a) P.S((Eigen::Index)t++) = std::pow(P.ws, -i);
    for (int j = 0; j <= s.nN; ++j)
        for (size_t b = 0; b < P.nu; ++b) P.S((Eigen::Index)t++) = std::pow(P.ws, -j);
    return P;
}

// Full-vector scale (all rows).
static VecR full_scale(const Prob &P)
{
    VecR S((Eigen::Index)(P.q * P.ny));
    for (size_t k = 0; k < P.ny; ++k) S.segment((Eigen::Index)(k * P.q), (Eigen::Index)P.q) = P.S;
    return S;
}

// G(p~) of scaled parameters th (full vector), and D^{-1}.
static void eval_scaled(const Prob &P, const VecR &th, cd pt, MatC &G, MatC &Dinv)
{
    const Eigen::Index ny = (Eigen::Index)P.ny, nu = (Eigen::Index)P.nu;
    MatC D = MatC::Identity(ny, ny), N = MatC::Zero(ny, nu);
    for (size_t k = 0; k < P.ny; ++k) {
        size_t t = k * P.q;
        cd pk = pt;
        for (int i = 1; i <= P.s.nD; ++i, pk *= pt)
            for (Eigen::Index a = 0; a < ny; ++a) D((Eigen::Index)k, a) += pk * th((Eigen::Index)t++);
        pk = 1.0;
        for (int j = 0; j <= P.s.nN; ++j, pk *= pt)
            for (Eigen::Index b = 0; b < nu; ++b) N((Eigen::Index)k, b) += pk * th((Eigen::Index)t++);
    }
    Eigen::PartialPivLU<MatC> lu(D);
    Dinv = lu.inverse();
    G = Dinv * N;
}

static MatC vec(const MatC &M) { return Eigen::Map<const MatC>(M.data(), M.size(), 1); }

// Complex Jacobian dvec(G)/dth (g x ny q) at one line, scaled parameters.
static MatC jac_line(const Prob &P, const MatC &G, const MatC &Dinv, cd pt)
{
    const Eigen::Index ny = (Eigen::Index)P.ny, nu = (Eigen::Index)P.nu, g = ny * nu;
    MatC J = MatC::Zero(g, (Eigen::Index)(P.ny * P.q));
    for (Eigen::Index k = 0; k < ny; ++k) {
        Eigen::Index t = k * (Eigen::Index)P.q;
        cd pk = pt;
        for (int i = 1; i <= P.s.nD; ++i, pk *= pt)
            for (Eigen::Index a = 0; a < ny; ++a, ++t) {
                // dG = -p^i Dinv[:,k] G[a,:]
                for (Eigen::Index b = 0; b < nu; ++b) J.block(b * ny, t, ny, 1) = -pk * Dinv.col(k) * G(a, b);
            }
        pk = 1.0;
        for (int j = 0; j <= P.s.nN; ++j, pk *= pt)
            for (Eigen::Index b = 0; b < nu; ++b, ++t) J.block(b * ny, t, ny, 1) = pk * Dinv.col(k);
    }
    return J;
}

double weighted_cost_lmfd(const LmfdModel &m, const std::vector<WeightedLine> &w)
{
    double V = 0;
    for (const auto &l : w) {
        const MatC e = l.Linv * vec(l.G - lmfd_eval(m, l.x));
        V += (l.real ? 0.5 : 1.0) * e.squaredNorm();
    }
    return V;
}

// Pinned indices (full vector) and values (unscaled).
static std::vector<std::pair<size_t, double>> pinned(const Prob &P)
{
    std::vector<std::pair<size_t, double>> out;
    for (const Pin &p : P.s.pins) {
        const bool isD = p.mat == 'D';
        if (isD && (p.index < 1 || p.index > P.s.nD))
            throw FitError("--pin D" + std::to_string(p.index) + ": the denominator has coefficients D1..D" + std::to_string(P.s.nD));
        if (!isD && (p.index < 0 || p.index > P.s.nN))
            throw FitError("--pin N" + std::to_string(p.index) + ": the numerator has coefficients N0..N" + std::to_string(P.s.nN));
        const size_t cols = isD ? P.ny : P.nu;
        if (p.row >= (int)P.ny || p.col >= (int)cols)
            throw FitError(std::string("--pin ") + p.mat + std::to_string(p.index) + ": entry out of range");
        const size_t base = isD ? (size_t)(p.index - 1) * P.ny : (size_t)P.s.nD * P.ny + (size_t)p.index * P.nu;
        for (size_t k = 0; k < P.ny; ++k)
            for (size_t c = 0; c < cols; ++c) {
                if (p.row >= 0 && ((size_t)p.row != k || (size_t)p.col != c)) continue;
                out.emplace_back(k * P.q + base + c, p.value);
            }
    }
    return out;
}

ClosedForm lmfd_closed_form(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s)
{
    const Prob P = make_prob(w, d, h, s);
    const Eigen::Index ny = (Eigen::Index)P.ny, nu = (Eigen::Index)P.nu, q = (Eigen::Index)P.q;
    Eigen::Index eq = 0;
    for (const auto &l : w) eq += (l.real ? 1 : 2) * nu;
    if (eq > q)
        throw FitError("the LMFD with nD = " + std::to_string(s.nD) + ", nN = " + std::to_string(s.nN) + " is over-constrained: " +
                       std::to_string(eq) + " real interpolation equations per output row for " + std::to_string(q) +
                       " unknowns; use --method ml (or more coefficients)");
    // A theta_k = b_k (scaled), theta_k^T Phi_l = -G_l[k,:]  (Theorem 6, eq. 50-53)
    MatR A(eq, q);
    MatR Bk(eq, ny);
    Eigen::Index r = 0;
    for (size_t li = 0; li < w.size(); ++li) {
        const auto &l = w[li];
        const cd pt = P.pt[li];
        MatC Phi = MatC::Zero(q, nu);
        Eigen::Index t = 0;
        cd pk = pt;
        for (int i = 1; i <= s.nD; ++i, pk *= pt, t += ny) Phi.block(t, 0, ny, nu) = pk * l.G;
        pk = 1.0;
        for (int j = 0; j <= s.nN; ++j, pk *= pt, t += nu) Phi.block(t, 0, nu, nu) = -pk * MatC::Identity(nu, nu);
        for (Eigen::Index c = 0; c < nu; ++c) {
            A.row(r) = Phi.col(c).real().transpose();
            Bk.row(r) = -l.G.col(c).real().transpose();
            ++r;
            if (!l.real) {
                A.row(r) = Phi.col(c).imag().transpose();
                Bk.row(r) = -l.G.col(c).imag().transpose();
                ++r;
            }
        }
    }
    // the one long step of a high order (an SVD of eq x q: tens of seconds at order 1000), abandoned on a stop
    const Eigen::JacobiSVD<MatR> svd = msidutil::abandonable<Eigen::JacobiSVD<MatR>>(
        [A] { return Eigen::JacobiSVD<MatR>(A, Eigen::ComputeFullU | Eigen::ComputeFullV); }, msidutil::Step::solves,
        "the lmfd fit");
    const VecR sv = svd.singularValues();
    const double tol = 1e-10 * (sv.size() ? sv(0) : 1.0);
    Eigen::Index rank = 0;
    while (rank < sv.size() && sv(rank) > tol) ++rank;
    if (rank < eq)
        throw FitError("the interpolation equations are rank deficient (rank " + std::to_string(rank) + " of " +
                       std::to_string(eq) + "): no LMFD of these degrees interpolates the FRF");
    const MatR Vn = svd.matrixV().rightCols(q - rank);       // kernel (scaled coordinates)
    const MatR Ainv = svd.matrixV().leftCols(rank) * sv.head(rank).cwiseInverse().asDiagonal() *
                      svd.matrixU().leftCols(rank).transpose();
    const auto pins = pinned(P);
    VecR th((Eigen::Index)(P.ny * P.q));
    for (Eigen::Index k = 0; k < ny; ++k) {
        const VecR t0 = Ainv * Bk.col(k);
        // unscaled family: S (t0 + Vn L); pins then minimum norm of the unscaled row
        std::vector<std::pair<Eigen::Index, double>> rp;
        for (const auto &p : pins)
            if ((Eigen::Index)(p.first / P.q) == k) rp.emplace_back((Eigen::Index)(p.first % P.q), p.second);
        const MatR SK = P.S.asDiagonal() * Vn;
        const VecR St0 = P.S.cwiseProduct(t0);
        VecR L = VecR::Zero(Vn.cols());
        MatR Nfree = MatR::Identity(Vn.cols(), Vn.cols());
        if (!rp.empty()) {
            MatR Kp((Eigen::Index)rp.size(), Vn.cols());
            VecR rhs((Eigen::Index)rp.size());
            for (size_t i = 0; i < rp.size(); ++i) {
                Kp.row((Eigen::Index)i) = SK.row(rp[i].first);
                rhs((Eigen::Index)i) = rp[i].second - St0(rp[i].first);
            }
            Eigen::CompleteOrthogonalDecomposition<MatR> cod(Kp);
            L = cod.solve(rhs);
            if ((Kp * L - rhs).norm() > 1e-9 * (1.0 + rhs.norm()))
                throw FitError("the pinned coefficients cannot all hold: the interpolation conditions fix them to other values");
            Eigen::FullPivLU<MatR> lu(Kp);
            Nfree = lu.kernel();
            if (lu.rank() == Kp.cols()) Nfree = MatR(Vn.cols(), 0);
        }
        if (Nfree.cols() > 0) {
            // minimise |S t0 + SK (L + Nfree z)|
            const MatR M = SK * Nfree;
            const VecR z = M.completeOrthogonalDecomposition().solve(-(St0 + SK * L));
            L += Nfree * z;
        }
        th.segment(k * q, q) = t0 + Vn * L;
    }
    ClosedForm cf;
    cf.model = lmfd_unpack(full_scale(P).cwiseProduct(th), s, P.ny, P.nu, d, h);
    cf.kernel = P.S.asDiagonal() * Vn;
    for (Eigen::Index c = 0; c < cf.kernel.cols(); ++c) cf.kernel.col(c).normalize();
    cf.equations = (int)eq;
    cf.unknowns = (int)q;
    cf.unique = Vn.cols() == 0;
    return cf;
}

// Whitened real residual and Jacobian over free parameters (scaled).
static void residual(const Prob &P, const std::vector<WeightedLine> &w, const VecR &th, const std::vector<Eigen::Index> &free,
                     VecR &r, MatR *J)
{
    const Eigen::Index g = (Eigen::Index)(P.ny * P.nu);
    Eigen::Index rows = 0;
    for (const auto &l : w) rows += l.real ? g : 2 * g;
    r.resize(rows);
    if (J) J->resize(rows, (Eigen::Index)free.size());
    Eigen::Index r0 = 0;
    for (size_t li = 0; li < w.size(); ++li) {
        const auto &l = w[li];
        MatC G, Dinv;
        eval_scaled(P, th, P.pt[li], G, Dinv);
        const MatC e = l.Linv * vec(l.G - G);
        const double sc = l.real ? std::sqrt(0.5) : 1.0;
        r.segment(r0, g) = sc * e.real();
        if (!l.real) r.segment(r0 + g, g) = e.imag();
        if (J) {
            const MatC Jl = -(l.Linv * jac_line(P, G, Dinv, P.pt[li]));
            for (size_t f = 0; f < free.size(); ++f) {
                J->block(r0, (Eigen::Index)f, g, 1) = sc * Jl.col(free[f]).real();
                if (!l.real) J->block(r0 + g, (Eigen::Index)f, g, 1) = Jl.col(free[f]).imag();
            }
        }
        r0 += l.real ? g : 2 * g;
    }
}

LmfdModel lmfd_sk(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, int iters,
                  const std::vector<MatC> *Gt)
{
    const Prob P = make_prob(w, d, h, s);
    const Eigen::Index ny = (Eigen::Index)P.ny, nu = (Eigen::Index)P.nu, g = ny * nu, nth = (Eigen::Index)(P.ny * P.q);
    const auto pins = pinned(P);
    const VecR Sf = full_scale(P);
    std::vector<char> isfree((size_t)nth, 1);
    VecR fixed = VecR::Zero(nth);
    for (const auto &p : pins) { isfree[p.first] = 0; fixed((Eigen::Index)p.first) = p.second / Sf((Eigen::Index)p.first); }
    std::vector<Eigen::Index> free;
    for (Eigen::Index t = 0; t < nth; ++t) if (isfree[(size_t)t]) free.push_back(t);
    VecR th = fixed;
    Eigen::Index rows = 0;
    for (const auto &l : w) rows += l.real ? g : 2 * g;
    for (int it = 0; it <= iters; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the lmfd fit");
        // minimise sum |Linv vec(Dprev^{-1} (D G - N))|^2, linear in theta
        MatR X(rows, (Eigen::Index)free.size());
        VecR y(rows);
        Eigen::Index r0 = 0;
        for (size_t li = 0; li < w.size(); ++li) {
            const auto &l = w[li];
            const MatC &Gd = Gt ? (*Gt)[li] : l.G;
            MatC Gm, Dinv;
            eval_scaled(P, it == 0 ? fixed : th, P.pt[li], Gm, Dinv);
            if (it == 0) Dinv = MatC::Identity(ny, ny);
            // D(p)G - N(p) = G + sum th_t * Phi_t ; residual of Dprev^{-1}(...)
            MatC M0 = Dinv * Gd;
            MatC Jl = MatC::Zero(g, nth);
            const cd pt = P.pt[li];
            for (Eigen::Index k = 0; k < ny; ++k) {
                Eigen::Index t = k * (Eigen::Index)P.q;
                cd pk = pt;
                for (int i = 1; i <= s.nD; ++i, pk *= pt)
                    for (Eigen::Index a = 0; a < ny; ++a, ++t)
                        for (Eigen::Index b = 0; b < nu; ++b) Jl.block(b * ny, t, ny, 1) = pk * Dinv.col(k) * Gd(a, b);
                pk = 1.0;
                for (int j = 0; j <= s.nN; ++j, pk *= pt)
                    for (Eigen::Index b = 0; b < nu; ++b, ++t) Jl.block(b * ny, t, ny, 1) = -pk * Dinv.col(k);
            }
            // pinned contributions move to the constant term
            MatC c0 = vec(M0);
            for (const auto &p : pins) c0 += Jl.col((Eigen::Index)p.first) * fixed((Eigen::Index)p.first);
            const MatC Wc = l.Linv * c0;
            const MatC WJ = l.Linv * Jl;
            const double sc = l.real ? std::sqrt(0.5) : 1.0;
            for (size_t f = 0; f < free.size(); ++f) X.block(r0, (Eigen::Index)f, g, 1) = sc * WJ.col(free[f]).real();
            y.segment(r0, g) = -sc * Wc.real();
            if (!l.real) {
                for (size_t f = 0; f < free.size(); ++f) X.block(r0 + g, (Eigen::Index)f, g, 1) = WJ.col(free[f]).imag();
                y.segment(r0 + g, g) = -Wc.imag();
            }
            r0 += l.real ? g : 2 * g;
        }
        // unit columns before the pivoting solve: a D_i(a, b) column scales with output a's units, an
        // N_j column does not; with outputs 1e10 apart the pivot threshold dropped columns and the
        // start (hence ml) depended on the units
        VecR cs(X.cols());
        for (Eigen::Index c = 0; c < X.cols(); ++c) {
            const double nc = X.col(c).norm();
            cs(c) = nc > 0 ? 1.0 / nc : 1.0;
        }
        const VecR sol = cs.asDiagonal() * (X * cs.asDiagonal()).colPivHouseholderQr().solve(y);
        VecR nth_v = fixed;
        for (size_t f = 0; f < free.size(); ++f) nth_v(free[f]) = sol((Eigen::Index)f);
        const double change = (nth_v - th).norm() / (1.0 + th.norm());
        th = nth_v;
        if (it > 0 && change < 1e-12) break;
    }
    return lmfd_unpack(Sf.cwiseProduct(th), s, P.ny, P.nu, d, h);
}

// Free (not pinned) parameter indices; pinned entries of th (scaled) set to their values.
static std::vector<Eigen::Index> free_params(const Prob &P, VecR *th)
{
    const Eigen::Index nth = (Eigen::Index)(P.ny * P.q);
    const VecR Sf = full_scale(P);
    std::vector<char> isfree((size_t)nth, 1);
    for (const auto &p : pinned(P)) {
        isfree[p.first] = 0;
        if (th) (*th)((Eigen::Index)p.first) = p.second / Sf((Eigen::Index)p.first);
    }
    std::vector<Eigen::Index> free;
    for (Eigen::Index t = 0; t < nth; ++t) if (isfree[(size_t)t]) free.push_back(t);
    return free;
}

static Eigen::Index n_residuals(const Prob &P, const std::vector<WeightedLine> &w)
{
    const Eigen::Index g = (Eigen::Index)(P.ny * P.nu);
    Eigen::Index n = 0;
    for (const auto &l : w) n += l.real ? g : 2 * g;
    return n;
}

MatR fisher_cov(const MatR &J, int &rank)
{
    MatR JtJ = MatR::Zero(J.cols(), J.cols());
    JtJ.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
    JtJ = JtJ.selfadjointView<Eigen::Lower>();
    const VecR sd = JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt();
    // a MatR argument: the one compute<MatrixXd> instance of eigen_inst_eigen.cpp, not one per expression type
    Eigen::SelfAdjointEigenSolver<MatR> es(MatR(sd.cwiseInverse().asDiagonal() * JtJ * sd.cwiseInverse().asDiagonal()));
    const VecR ev = es.eigenvalues();
    const double tol = 1e-12 * std::max(ev.maxCoeff(), 1e-300) * (double)ev.size();
    VecR inv(ev.size());
    rank = 0;
    for (Eigen::Index k = 0; k < ev.size(); ++k) {
        inv(k) = ev(k) > tol ? 1.0 / ev(k) : 0.0;
        rank += ev(k) > tol;
    }
    return 0.5 * sd.cwiseInverse().asDiagonal() * es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose() *
           sd.cwiseInverse().asDiagonal();
}

// Smallest non-zero singular value of J (Theorem 5, eq. 46) and the rank of J. The columns of J
// are the unscaled LMFD coefficients, graded by ws^-i: J^T J squares a condition of 1e10 or more
// and its smallest eigenvalue came out negative (sigma = 0, an infinite theta bound). Here J = B C
// with C the column norms; the SVD of the equilibrated B keeps its accuracy, and
// sigma_min(J) = 1 / |J^+| = 1 / sigma_max(C^-1 V_r S_r^-1) over the rank r of B.
double sigma_min_graded(const MatR &J, int &rank)
{
    rank = 0;
    if (J.cols() == 0 || J.rows() == 0) return 0.0;
    const VecR c = J.colwise().norm().transpose();
    VecR ci(c.size());
    for (Eigen::Index k = 0; k < c.size(); ++k) ci(k) = c(k) > 0 ? 1.0 / c(k) : 0.0;
    const Eigen::JacobiSVD<MatR> svd(J * ci.asDiagonal(), Eigen::ComputeThinV);
    const VecR sv = svd.singularValues();
    const double tol = 1e-13 * std::max(sv(0), 1e-300) * std::sqrt((double)J.cols());
    while (rank < sv.size() && sv(rank) > tol) ++rank;
    if (rank == 0) return 0.0;
    const MatR P = ci.asDiagonal() * svd.matrixV().leftCols(rank) * sv.head(rank).cwiseInverse().asDiagonal();
    const double pn = Eigen::JacobiSVD<MatR>(P).singularValues()(0);
    return pn > 0 ? 1.0 / pn : 0.0;
}

// Sample-ML correction: weights estimated with n complex dof (p outputs) inflate the
// variance by about n/(n - p - 1) (exact for p = 1: Pintelon & Schoukens SML, (M-2)/(M-3)
// relative to the CRB with the (n-1)/n bias of the inverse sample covariance).
double sample_ml_factor(const std::vector<WeightedLine> &w, size_t ny, bool known_noise)
{
    double nmin = 1e300;
    for (const auto &l : w) nmin = std::min(nmin, l.dof);
    if (known_noise || nmin >= 1e8) return 1.0;
    const double p = (double)ny;
    return nmin > p + 1.0 ? nmin / (nmin - p - 1.0) : std::numeric_limits<double>::infinity();
}

// Covariance, model FRF with covariance, and Theorem 5 quantities at scaled parameters th.
static MlResult evaluate_at(const Prob &P, const std::vector<WeightedLine> &w, const VecR &th,
                            const std::vector<Eigen::Index> &free, const MlOptions &o, bool known_noise, Eigen::Index nres)
{
    MlResult res;
    VecR r;
    MatR J;
    residual(P, w, th, free, r, &J);
    const double V = r.squaredNorm();
    const Eigen::Index g = (Eigen::Index)(P.ny * P.nu);
    const VecR Sf = full_scale(P);
    const LmfdSpec &s = P.s;
    const Domain d = P.d;
    const double h = P.h;
    res.model = lmfd_unpack(Sf.cwiseProduct(th), s, P.ny, P.nu, d, h);
    // Fisher information: r has components of variance 1/2, so Cov = (J^T J)^{-1} / 2 (scaled coordinates);
    // J^T J and its eigendecomposition are one dense step (rows x parameters^2): abandonable, on J shared
    struct Cov {
        MatR cov;
        int rank = 0;
    };
    const auto Jp = std::make_shared<const MatR>(std::move(J));
    const Cov fc = msidutil::abandonable<Cov>(std::function<Cov()>([Jp] {
                                                  Cov c;
                                                  c.cov = fisher_cov(*Jp, c.rank);
                                                  return c;
                                              }),
                                              msidutil::Step::solves, "the ml fit");
    res.cov_rank = fc.rank;
    MatR covs = fc.cov;
    res.grad_norm = (Jp->transpose() * r).cwiseQuotient(Jp->colwise().norm().transpose().cwiseMax(1e-300)).norm();
    res.cov_factor = sample_ml_factor(w, P.ny, known_noise);
    covs *= res.cov_factor;
    VecR Sfree((Eigen::Index)free.size());
    for (size_t f = 0; f < free.size(); ++f) Sfree((Eigen::Index)f) = Sf(free[f]);
    res.cov = Sfree.asDiagonal() * covs * Sfree.asDiagonal();
    res.theta.resize((Eigen::Index)free.size());
    const VecR thu = Sf.cwiseProduct(th);
    const auto allnames = lmfd_param_names(s, P.ny, P.nu);
    for (size_t f = 0; f < free.size(); ++f) {
        res.theta((Eigen::Index)f) = thu(free[f]);
        res.names.push_back(allnames[(size_t)free[f]]);
    }
    res.cost = V;         // eq. (40) in likelihood units: residual components have variance 1/2
    res.dof = (double)(nres - (Eigen::Index)free.size());
    double nmin = 1e300;
    for (const auto &l : w) nmin = std::min(nmin, l.dof);
    const double nw = nmin < 1e8 ? nmin : 0.0;
    const double mu = nw > (double)P.ny ? nw / (nw - (double)P.ny) : 1.0;
    res.cost_expected = 0.5 * res.dof * (known_noise ? 1.0 : mu);
    // model FRF and its covariance at the lines; Theorem 5 quantities
    Eigen::Index nc = 0, nr = 0;
    MatR Jg((Eigen::Index)0, (Eigen::Index)free.size());
    std::vector<MatR> blocks;
    for (size_t li = 0; li < w.size(); ++li) {
        // the model's FRF covariance at a line: parameters^2 per entry, seconds over thousands of lines
        msidutil::checkpoint(msidutil::Step::lines, 1, "the ml fit");
        MatC G, Dinv;
        eval_scaled(P, th, P.pt[li], G, Dinv);
        const MatC Jl = jac_line(P, G, Dinv, P.pt[li]);
        MatC Jf(g, (Eigen::Index)free.size());
        for (size_t f = 0; f < free.size(); ++f) Jf.col((Eigen::Index)f) = Jl.col(free[f]) / Sf(free[f]);
        res.G.push_back(G);
        res.Gcov.push_back(Jf * res.cov.cast<cd>() * Jf.adjoint());
        Eigen::SelfAdjointEigenSolver<MatC> es(w[li].cov);
        res.lambda_max_cov = std::max(res.lambda_max_cov, es.eigenvalues().maxCoeff());
        // |d calG|_F^2 = |dG(0)|^2 + 2 sum |dG(jw)|^2 over the +- pairs
        const double sc = w[li].real ? 1.0 : std::sqrt(2.0);
        blocks.push_back(sc * Jf.real());
        if (!w[li].real) blocks.push_back(sc * Jf.imag());
        (w[li].real ? nr : nc)++;
    }
    Eigen::Index rows = 0;
    for (auto &b : blocks) rows += b.rows();
    Jg.resize(rows, (Eigen::Index)free.size());
    rows = 0;
    for (auto &b : blocks) { Jg.block(rows, 0, b.rows(), b.cols()) = b; rows += b.rows(); }
    // the SVD of the stacked line Jacobians (2 lines x entries by parameters): one dense step, abandonable
    struct Sigma {
        double sigma = 0;
        int rank = 0;
    };
    const auto Jgp = std::make_shared<const MatR>(std::move(Jg));
    const Sigma sg = msidutil::abandonable<Sigma>(std::function<Sigma()>([Jgp] {
                                                      Sigma x;
                                                      x.sigma = sigma_min_graded(*Jgp, x.rank);
                                                      return x;
                                                  }),
                                                  msidutil::Step::solves, "the ml fit");
    res.sigma_min_J = sg.sigma;
    res.sigma_rank = sg.rank;
    // (45): 2 sqrt(lambda_max(Cov)) (sqrt(2 log(2/delta)) + sqrt(nu ny (2M+1)))
    const double B = std::sqrt((double)g * (double)(2 * nc + nr));
    res.frf_bound = 2.0 * std::sqrt(res.lambda_max_cov) * (std::sqrt(2.0 * std::log(2.0 / o.delta)) + B);
    res.theta_bound = res.frf_bound / (o.beta * res.sigma_min_J);
    return res;
}

MlResult lmfd_ml(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, const LmfdModel &start,
                 const MlOptions &o, bool known_noise)
{
    const Prob P = make_prob(w, d, h, s);
    VecR th = lmfd_pack(start).cwiseQuotient(full_scale(P));
    const std::vector<Eigen::Index> free = free_params(P, &th);
    const Eigen::Index nres = n_residuals(P, w);
    if ((Eigen::Index)free.size() >= nres)
        throw FitError("the model has " + std::to_string(free.size()) + " free parameters for " + std::to_string(nres) +
                       " real data: not over-constrained; use --method lmfd");
    // stable models (msid fit's default): a trial step to an unstable model is refused like one that
    // raises the cost, so a stable start stays stable
    const VecR Sf = full_scale(P);
    auto stable_at = [&](const VecR &t) {
        try {
            return ss_stable(lmfd_to_ss(lmfd_unpack(t.cwiseProduct(Sf), s, P.ny, P.nu, d, h)));
        } catch (const FitError &) {
            return false;
        }
    };
    const bool constrain = o.stable && stable_at(th);
    VecR r;
    MatR J;
    residual(P, w, th, free, r, &J);
    double V = r.squaredNorm();
    const double V0 = V;
    double lambda = 1e-3;
    int it = 0;
    bool conv = false;
    for (; it < o.max_iter; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the ml fit");
        const VecR grad = J.transpose() * r;
        const VecR dg = J.colwise().squaredNorm().transpose().cwiseMax(1e-300);
        bool stepped = false;
        for (int tries = 0; tries < 30; ++tries) {
            // a try is a QR of the augmented Jacobian (lines x parameters^2): up to 30 in one iteration
            if (tries) msidutil::checkpoint(msidutil::Step::solves, 0, "the ml fit");
            // (J^T J + lambda diag) delta = -J^T r, via the augmented least squares in the columns
            // scaled to unit norm (J^ = J diag(dg)^-1/2: the same step, but the pivoting threshold no
            // longer depends on the units of the outputs, which scale the D_i columns)
            const VecR ds = dg.cwiseSqrt().cwiseInverse();
            MatR Aug(J.rows() + J.cols(), J.cols());
            Aug << J * ds.asDiagonal(), std::sqrt(lambda) * MatR::Identity(J.cols(), J.cols());
            VecR rhs = VecR::Zero(Aug.rows());
            rhs.head(r.size()) = -r;
            const VecR delta = ds.asDiagonal() * Aug.colPivHouseholderQr().solve(rhs);
            VecR th2 = th;
            for (size_t f = 0; f < free.size(); ++f) th2(free[f]) += delta((Eigen::Index)f);
            if (constrain && !stable_at(th2)) { lambda *= 4.0; continue; }
            VecR r2;
            residual(P, w, th2, free, r2, nullptr);
            const double V2 = r2.squaredNorm();
            if (std::isfinite(V2) && V2 <= V) {
                const double rel = (V - V2) / std::max(V, 1e-300);
                const double step = delta.norm() / (1.0 + th.norm());
                th = th2;
                V = V2;
                lambda = std::max(lambda / 3.0, 1e-12);
                residual(P, w, th, free, r, &J);
                stepped = true;
                if (rel < o.tol && step < 1e-7) conv = true;
                break;
            }
            lambda *= 4.0;
        }
        if (conv) break;
        if (!stepped) {
            // no decrease possible: converged if the gradient is negligible, else the best iterate so far
            const double gn = grad.norm() / (1.0 + V);
            conv = gn < 1e-6;
            break;
        }
    }
    MlResult res = evaluate_at(P, w, th, free, o, known_noise, nres);
    res.iterations = std::min(it + 1, o.max_iter);
    res.converged = conv;
    res.stable_constrained = constrain;
    res.cost_start = V0;
    return res;
}

MlResult lmfd_evaluate(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, const LmfdModel &m,
                        const MlOptions &o, bool known_noise)
{
    const Prob P = make_prob(w, d, h, s);
    const std::vector<Eigen::Index> free = free_params(P, nullptr);
    const Eigen::Index nres = n_residuals(P, w);
    const VecR Sf = full_scale(P);
    return evaluate_at(P, w, lmfd_pack(m).cwiseQuotient(Sf), free, o, known_noise, nres);
}

}  // namespace msidfit
