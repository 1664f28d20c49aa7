#include "poleres.hpp"
#include "poleres_problem.hpp"
#include "msid_cancel.hpp"
#include "lmfd_fit.hpp"
#include "stab_bound.hpp"
#include "stats.hpp"
#include "subspace.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>

namespace msidfit {

using namespace prfit;

namespace {

struct LmOut {
    Layout L;                     // the final layout (the continuation below may turn two real poles into a pair)
    VecR th;
    double V = 0, gnorm = 0;
    bool conv = false;
    int iters = 0;
    std::vector<char> at_bound;   // per pole: on the stability bound at the end (held there)
};

// Continuation through a double real pole. Two real poles a1, a2 and the pair a +- j d (a = (a1 + a2)/2,
// d = |a1 - a2|/2) span the same functions to second order in d: 1/(x - a), 1/(x - a)^2 and +d^2 (real)
// or -d^2 (pair) times 1/(x - a)^3, one smooth coordinate u = +-d^2 through the double pole, which a
// parametrisation by poles of a fixed kind cuts in two. Data that want a pair where a start put two
// real poles (or the reverse) drive them to the double pole, their residues growing with opposite
// signs, along a valley the step creeps down for hundreds of iterations without crossing. So when two
// real poles come within MERGE_REL of each other (or a pair's |Im| within MERGE_REL of its |Re|), the
// other kind at the same a and d is tried, its residues re-solved, and kept when its cost is lower.
constexpr double MERGE_REL = 0.2;

// The pole list (scaled) with poles i and j (two real poles) made one pair, or pole i (a pair, j = size)
// made two real poles; sorted as pole_list sorts.
std::vector<cd> other_kind(const std::vector<cd> &p, size_t i, size_t j, Domain d, bool stable)
{
    std::vector<cd> q;
    for (size_t k = 0; k < p.size(); ++k)
        if (k != i && k != j) q.push_back(p[k]);
    if (j < p.size()) {
        const double a = 0.5 * (p[i].real() + p[j].real()), dd = 0.5 * std::abs(p[i].real() - p[j].real());
        const cd z(a, std::max(dd, 1e-12 * std::abs(a)));
        q.push_back(stable ? stab_project(z, d) : z);
    } else {
        for (const double sg : {-1.0, 1.0}) {
            const cd z(p[i].real() + sg * p[i].imag(), 0.0);
            q.push_back(stable ? stab_project(z, d) : z);
        }
    }
    std::sort(q.begin(), q.end(), [](const cd &x, const cd &y) {
        return std::abs(x) != std::abs(y) ? std::abs(x) < std::abs(y) : x.real() < y.real();
    });
    return q;
}

// The kind-change candidates: (i, j) for two real poles within MERGE_REL of each other, (i, size) for a
// pair with |Im| <= MERGE_REL |Re|.
std::vector<std::pair<size_t, size_t>> kind_candidates(const std::vector<cd> &p, const Layout &L)
{
    std::vector<std::pair<size_t, size_t>> c;
    for (size_t i = 0; i < p.size(); ++i) {
        if (L.pair[i]) {
            if (std::abs(p[i].imag()) <= MERGE_REL * std::abs(p[i].real())) c.push_back({i, p.size()});
            continue;
        }
        for (size_t j = i + 1; j < p.size(); ++j)
            if (!L.pair[j] &&
                std::abs(p[i].real() - p[j].real()) <= MERGE_REL * std::max(std::abs(p[i].real()), std::abs(p[j].real())))
                c.push_back({i, j});
    }
    return c;
}

// One try of the continuation at th: the first candidate whose other kind lowers the cost replaces L, th,
// r, J and V. `tried` holds the candidates already refused (their centre, their separation): one is tried
// again only once its separation has halved.
void try_other_kind(const Prob &P, Layout &L, VecR &th, Normal &N, bool stable, std::vector<std::pair<cd, double>> &tried)
{
    std::vector<cd> p;
    for (size_t k = 0; k < L.pair.size(); ++k) p.push_back(pole_of(L, th, k));
    for (const auto &c : kind_candidates(p, L)) {
        const bool merge = c.second < p.size();
        const double sep = merge ? std::abs(p[c.first].real() - p[c.second].real()) : std::abs(p[c.first].imag());
        const cd centre = merge ? 0.5 * (p[c.first] + p[c.second]) : cd(p[c.first].real(), 0.0);
        bool seen = false;
        for (const auto &t : tried) seen = seen || (std::abs(t.first - centre) <= 0.05 * std::abs(centre) && sep > 0.5 * t.second);
        if (seen) continue;
        tried.push_back({centre, sep});
        const std::vector<cd> q = other_kind(p, c.first, c.second, P.d, stable);
        const Layout Lq = make_layout(q, P.g, L.D);
        VecR thq = VecR::Zero(Lq.n);
        for (size_t k = 0; k < q.size(); ++k) {
            thq(Lq.po[k]) = q[k].real();
            if (Lq.pair[k]) thq(Lq.po[k] + 1) = q[k].imag();
        }
        msidutil::checkpoint(msidutil::Step::solves, 0, "the ml fit");   // one solve over every line per candidate
        Normal Nq;
        solve_linear(P, Lq, thq, Nq);
        if (std::isfinite(Nq.V) && Nq.V < N.V) {
            L = Lq;
            th = thq;
            N = std::move(Nq);
            return;
        }
    }
}

LmOut lm(const Prob &P, Layout L, VecR th, int max_iter, double tol, bool stable, int *refl)
{
    LmOut o;
    Normal N, N2;
    canonical(L, th, P.d, stable, P.g, refl);
    solve_linear(P, L, th, N);
    double lambda = 1e-3;
    std::vector<char> act(L.pair.size(), 0);
    std::vector<std::pair<cd, double>> tried;
    int it = 0;
    for (; it < max_iter; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the ml fit");
        try_other_kind(P, L, th, N, stable, tried);
        const double V = N.V;
        act.assign(L.pair.size(), 0);
        if (stable) act = active_set(L, th, N.grad, P.d);
        o.gnorm = free_gnorm(L, th, N.JtJ, N.grad, act, P.d);
        if (o.gnorm <= 1e-9 * std::sqrt(std::max(V, 1e-300))) { o.conv = true; break; }
        bool stepped = false;
        for (int tries = 0; tries < 40 && !stepped; ++tries) {
            // a try is a cost over every line: up to 40 of them in one iteration
            if (tries) msidutil::checkpoint(msidutil::Step::solves, 0, "the ml fit");
            VecR th2 = th + constrained_step(L, th, N.JtJ, N.grad, lambda, act, P.d);
            canonical(L, th2, P.d, stable, P.g, nullptr);
            const double V2 = cost_at(P, L, th2);
            if (std::isfinite(V2) && V2 < V) {
                solve_linear(P, L, th2, N2);
                const double rel = (V - N2.V) / std::max(V, 1e-300);
                th = th2;
                std::swap(N, N2);
                lambda = std::max(lambda / 5.0, 1e-12);
                stepped = true;
                if (rel < tol) o.conv = true;
            } else {
                lambda *= 4.0;
            }
        }
        if (o.conv) { ++it; break; }
        if (!stepped) {
            // no descent possible from here: a (numerical) stationary point if the gradient is small
            o.conv = o.gnorm <= 1e-5 * std::sqrt(std::max(V, 1.0));
            break;
        }
    }
    o.V = N.V;
    // at the end every pole on the bound is held there, whichever way the gradient points: its damping is
    // the value the projection gave it, not one the data determine
    o.at_bound.assign(L.pair.size(), 0);
    if (stable)
        for (size_t k = 0; k < L.pair.size(); ++k) o.at_bound[k] = stab_held_at_end(pole_of(L, th, k), P.d);
    o.gnorm = free_gnorm(L, th, N.JtJ, N.grad, o.at_bound, P.d);
    o.L = L;
    o.th = th;
    o.iters = it;
    return o;
}

VecR theta_from_poles(const Layout &L, const std::vector<cd> &poles, double ws)
{
    VecR th = VecR::Zero(L.n);
    for (size_t k = 0; k < poles.size(); ++k) {
        th(L.po[k]) = poles[k].real() / ws;
        if (L.pair[k]) th(L.po[k] + 1) = poles[k].imag() / ws;
    }
    return th;
}

}  // namespace

std::vector<cd> vector_fit_poles(const std::vector<WeightedLine> &w, Domain d, int order, bool feedthrough, int iters,
                                 double wscale, bool relaxed)
{
    const Prob P = make_prob(w, d, wscale);
    const Eigen::Index F = (Eigen::Index)w.size(), g = P.g;
    // starting poles (Gustavsen & Semlyen 1999 §4): pairs spread over the band, Re = -Im/100
    std::vector<cd> poles;
    double lo = 1e300, hi = 0;
    for (const cd &x : P.xt) {
        const double a = d == Domain::CT ? std::abs(x.imag()) : std::abs(std::arg(x));
        if (a > 0) { lo = std::min(lo, a); hi = std::max(hi, a); }
    }
    if (!(hi > 0)) throw FitError("vector fitting needs lines above DC");
    const int npair = order / 2;
    for (int k = 0; k < npair; ++k) {
        const double f = npair > 1 ? (double)k / (npair - 1) : 0.5;
        if (d == Domain::CT) {
            const double om = relaxed ? lo + (hi - lo) * f : lo * std::pow(hi / lo, f);
            poles.push_back(cd(-om / 100.0, om));
        } else {
            const double th = lo + (hi - lo) * f;
            poles.push_back(std::polar(0.97, th));
        }
    }
    if (order % 2) poles.push_back(cd(d == Domain::CT ? -lo : 0.5, 0.0));
    // weights: 1/sqrt of the diagonal of each line covariance (real lines: sqrt(1/2))
    MatR wt(F, g);
    for (Eigen::Index l = 0; l < F; ++l)
        for (Eigen::Index ij = 0; ij < g; ++ij)
            wt(l, ij) = (w[(size_t)l].real ? std::sqrt(0.5) : 1.0) / std::sqrt(std::max(w[(size_t)l].cov(ij, ij).real(), 1e-300));
    const Eigen::Index nd = feedthrough ? 1 : 0;
    for (int it = 0; it < iters; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the ml fit");
        std::vector<char> pair;
        for (const cd &p : poles) pair.push_back(p.imag() > 0);
        const Eigen::Index N = (Eigen::Index)std::count(pair.begin(), pair.end(), 1) * 2 +
                               (Eigen::Index)std::count(pair.begin(), pair.end(), 0);
        // each response's 2F real rows must determine its 2N + nd (+1 relaxed) unknowns before the
        // sigma rows are taken from its QR: with fewer lines than that (several outputs can fit an
        // order that one response's lines cannot) the poles stay where they are
        if (2 * F < 2 * N + nd + (relaxed ? 1 : 0)) break;
        MatC Phi(F, N);
        for (Eigen::Index l = 0; l < F; ++l) {
            Eigen::Index c = 0;
            for (size_t k = 0; k < poles.size(); ++k) {
                const cd q = 1.0 / (P.xt[(size_t)l] - poles[k]);
                if (pair[k]) {
                    const cd q2 = 1.0 / (P.xt[(size_t)l] - std::conj(poles[k]));
                    Phi(l, c++) = q + q2;
                    Phi(l, c++) = cd(0, 1) * (q - q2);
                } else {
                    Phi(l, c++) = q;
                }
            }
        }
        // fast VF: per response QR, keep the rows that only involve the sigma coefficients.
        // Relaxed (Gustavsen 2006): sigma = sum c~ Phi + d~ with d~ free, every response's rows
        // homogeneous, and one more row Re sum_l sigma(x_l) = F (weighted by |w G| / F) against the
        // trivial solution; the new poles are the zeros of sigma, eig(A - b c~^T / d~).
        const Eigen::Index ns = N + (relaxed ? 1 : 0);   // sigma's unknowns
        MatR S(g * ns + (relaxed ? 1 : 0), ns);
        VecR sb = VecR::Zero(S.rows());
        double wg2 = 0.0;   // |w G|^2 over lines and responses (the extra row's weight)
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            MatR A(2 * F, 2 * N + nd + (relaxed ? 1 : 0));
            VecR b(2 * F);
            for (Eigen::Index l = 0; l < F; ++l) {
                const double ww = wt(l, ij);
                const cd Gv = w[(size_t)l].G.data()[ij];
                for (Eigen::Index c = 0; c < N; ++c) {
                    const cd a = ww * Phi(l, c), s = -ww * Gv * Phi(l, c);
                    A(2 * l, c) = a.real(); A(2 * l + 1, c) = a.imag();
                    A(2 * l, N + nd + c) = s.real(); A(2 * l + 1, N + nd + c) = s.imag();
                }
                if (nd) { A(2 * l, N) = ww; A(2 * l + 1, N) = 0.0; }
                if (relaxed) {   // -G d~
                    A(2 * l, 2 * N + nd) = -ww * Gv.real();
                    A(2 * l + 1, 2 * N + nd) = -ww * Gv.imag();
                    wg2 += std::norm(ww * Gv);
                }
                b(2 * l) = relaxed ? 0.0 : ww * Gv.real();
                b(2 * l + 1) = relaxed ? 0.0 : ww * Gv.imag();
            }
            const Eigen::Index nc = A.cols();
            Eigen::HouseholderQR<MatR> qr(A);
            const MatR Rf = qr.matrixQR().topRows(nc).triangularView<Eigen::Upper>();
            S.block(ij * ns, 0, ns, ns) = Rf.block(N + nd, N + nd, ns, ns);
            if (!relaxed) sb.segment(ij * N, N) = (qr.householderQ().transpose() * b).head(nc).segment(N + nd, N);
        }
        if (relaxed) {
            const double we = std::sqrt(wg2) / (double)F;
            for (Eigen::Index c = 0; c < N; ++c) S(g * ns, c) = we * Phi.col(c).real().sum();
            S(g * ns, N) = we * (double)F;
            sb(g * ns) = we * (double)F;
        }
        VecR ct = S.colPivHouseholderQr().solve(sb);
        if (!ct.allFinite()) break;
        if (relaxed) {   // c~ / d~ (a d~ near zero: no relocation from this step)
            const double dt = ct(N);
            if (!(std::abs(dt) > 1e-8)) break;
            ct = (ct.head(N) / dt).eval();
        }
        // zeros of sigma = eig(A - b c~^T)
        MatR A = MatR::Zero(N, N);
        VecR bb = VecR::Zero(N);
        Eigen::Index c = 0;
        for (size_t k = 0; k < poles.size(); ++k) {
            if (pair[k]) {
                A(c, c) = A(c + 1, c + 1) = poles[k].real();
                A(c, c + 1) = poles[k].imag();
                A(c + 1, c) = -poles[k].imag();
                bb(c) = 2.0;
                c += 2;
            } else {
                A(c, c) = poles[k].real();
                bb(c) = 1.0;
                ++c;
            }
        }
        Eigen::EigenSolver<MatR> es(A - bb * ct.transpose(), false);
        std::vector<cd> np = pole_list(es.eigenvalues());
        for (cd &p : np) p = reflect(p, d, nullptr);
        if (np.empty()) break;
        // converged: the same pole list to 1e-10 relative (pole_list's order: by |p|, then Re p)
        bool same = np.size() == poles.size();
        for (size_t k = 0; same && k < np.size(); ++k) same = std::abs(np[k] - poles[k]) <= 1e-10 * std::abs(poles[k]);
        poles = np;
        if (same) break;
    }
    for (cd &p : poles) p *= P.ws;
    return poles;
}

// Covariance, model FRF and its covariance at scaled theta. `act`: the poles held on the stability
// bound, whose normal component is no estimate (fixed by the constraint, not by the data): the
// Fisher information is that of the other directions, and the normal gets no variance.
static void finish(const Prob &P, const Layout &L, const VecR &th, const std::vector<char> &act, bool known_noise,
                   PrResult &res)
{
    const Eigen::Index g = P.g;
    const std::vector<WeightedLine> &w = *P.w;
    VecR r;
    MatR J;
    resid(P, L, th, r, &J);
    res.cost = r.squaredNorm();
    // scaled -> unscaled: poles and residues times ws, D unchanged
    VecR S = VecR::Ones(L.n);
    S.head(L.dof).setConstant(P.ws);
    PoleResidueModel &m = res.model;
    m.domain = P.d;
    m.feedthrough = L.D;
    m.poles.clear();
    m.R.clear();
    for (size_t k = 0; k < L.pair.size(); ++k) {
        m.poles.push_back(pole_of(L, th, k) * P.ws);
        MatC R(P.ny, P.nu);
        for (Eigen::Index ij = 0; ij < g; ++ij) R.data()[ij] = res_of(L, th, k, ij, g) * P.ws;
        m.R.push_back(R);
    }
    m.D = MatR::Zero(P.ny, P.nu);
    if (L.D) m.D = Eigen::Map<const MatR>(th.data() + L.dof, P.ny, P.nu);
    res.theta = S.cwiseProduct(th);
    res.names.clear();
    auto ent = [&](Eigen::Index ij) { return "[" + std::to_string(ij % P.ny + 1) + "," + std::to_string(ij / P.ny + 1) + "]"; };
    for (size_t k = 0; k < L.pair.size(); ++k) {
        const std::string p = "p" + std::to_string(k + 1);
        if (L.pair[k]) { res.names.push_back(p + ".re"); res.names.push_back(p + ".im"); }
        else res.names.push_back(p);
    }
    for (size_t k = 0; k < L.pair.size(); ++k)
        for (int part = 0; part < (L.pair[k] ? 2 : 1); ++part)
            for (Eigen::Index ij = 0; ij < g; ++ij)
                res.names.push_back("R" + std::to_string(k + 1) + ent(ij) + (L.pair[k] ? (part ? ".im" : ".re") : ""));
    if (L.D)
        for (Eigen::Index ij = 0; ij < g; ++ij) res.names.push_back("D" + ent(ij));
    res.at_bound = act;
    // Fisher information 2 J^T J (residual components have variance 1/2): pseudo-inverse with its rank.
    // J^T J and its eigendecomposition are one dense step of rows x parameters^2 (seconds at high orders
    // on many lines): abandonable, on its own copy of the layout and the Jacobian it moves
    struct HeldCov {
        MatR cov;
        int rank = 0;
    };
    const auto Jp = std::make_shared<const MatR>(std::move(J));
    const Domain dom = P.d;
    const HeldCov hc = msidutil::abandonable<HeldCov>(
        std::function<HeldCov()>([L, th, act, dom, Jp] {
            HeldCov h;
            h.cov = held_fisher_cov(L, th, act, dom, *Jp, h.rank);
            return h;
        }),
        msidutil::Step::solves, "the ml fit");
    res.cov_rank = hc.rank;
    MatR covs = hc.cov;
    res.cov_factor = sample_ml_factor(w, (size_t)P.ny, known_noise);
    covs *= res.cov_factor;
    res.cov = S.asDiagonal() * covs * S.asDiagonal();
    res.G.clear();
    res.Gcov.clear();
    VecC gm;
    MatC dG, dGp;
    const MatC cc = covs.cast<cd>(), I = MatC::Identity(g, g);
    for (size_t li = 0; li < w.size(); ++li) {
        // the model's FRF covariance at a line: parameters^2 per entry, seconds over thousands of lines
        msidutil::checkpoint(msidutil::Step::lines, 1, "the ml fit");
        line_terms(P, L, th, li, I, gm, &dG, dGp);   // with Linv = I: -d vec(G) / d theta
        res.G.push_back(Eigen::Map<const MatC>(gm.data(), P.ny, P.nu));
        res.Gcov.push_back(dG * cc * dG.adjoint());
    }
}

PrResult pr_ml(const std::vector<WeightedLine> &w, Domain d, double h, const PrOptions &o)
{
    if (w.empty()) throw FitError("no lines");
    if (o.order < 1) throw FitError("the order must be positive");
    const Prob P = make_prob(w, d, o.wscale);
    const Eigen::Index g = P.g;
    const bool tryD = o.feedthrough != Feedthrough::No;
    {
        const Eigen::Index npar = o.order + (Eigen::Index)o.order * g + (tryD ? g : 0);
        if (npar >= P.rows) {
            const Eigen::Index nmax = (P.rows - 1 - (tryD ? g : 0)) / (1 + g);
            throw FitError("order " + std::to_string(o.order) + " needs " + std::to_string(npar) + " parameters for " +
                           std::to_string(P.rows) + " real data: the largest order these lines support is " +
                           std::to_string(std::max<Eigen::Index>(nmax, 0)));
        }
    }
    PrResult res;
    int refl = 0;
    // starts: vector fitting, then the subspace models (several block-row counts)
    struct Cand { std::string name; std::vector<cd> poles; };
    std::vector<Cand> cands;
    // given poles (a model to refine) replace the other starts
    for (const auto &ps : o.pole_starts) cands.push_back({ps.first, ps.second});
    if (cands.empty()) {
        cands.push_back({"vector-fitting", vector_fit_poles(w, d, o.order, tryD, o.vf_iter, o.wscale, false)});
        if (o.rvf_iter > 0)
            cands.push_back({"vector-fitting-relaxed", vector_fit_poles(w, d, o.order, tryD, o.rvf_iter, o.wscale, true)});
        for (size_t k = 0; k < o.subspace_starts.size(); ++k) {
            std::vector<cd> p = ss_poles(o.subspace_starts[k]);
            const bool refined = o.refined_subspace_start && k + 1 == o.subspace_starts.size();
            if (!p.empty()) cands.push_back({refined ? "subspace-refined" : "subspace#" + std::to_string(k + 1), p});
        }
    }
    LmOut best;
    best.V = std::numeric_limits<double>::infinity();
    for (const Cand &c : cands) {
        // a start's cost at its poles (a solve over every line) comes before its first iteration's checkpoint
        msidutil::checkpoint(msidutil::Step::solves, 1, "the ml fit");
        const Layout L = make_layout(c.poles, g, tryD);
        if (L.n >= P.rows) continue;
        int rc = 0;
        const LmOut r = lm(P, L, theta_from_poles(L, c.poles, P.ws), std::min(o.start_iter, o.max_iter), o.tol, o.stable, &rc);
        res.starts.push_back({c.name, r.V});
        if (r.V < best.V) { best = r; res.best_start = c.name; refl = rc; }
    }
    if (!std::isfinite(best.V)) throw FitError("no start gave a finite cost (order " + std::to_string(o.order) + ")");
    // the best start continues; --max-iter bounds its iterations in total (start + refinement)
    LmOut fin = best;
    if (!best.conv) {
        fin = lm(P, best.L, best.th, std::max(0, o.max_iter - best.iters), o.tol, o.stable, &refl);
        fin.iters += best.iters;
    }
    Layout finL = fin.L;
    if (o.feedthrough == Feedthrough::Auto) {
        // likelihood-ratio test of D = 0: 2 (V0 - V1) ~ chi2_g (eq. 40 residual components have variance 1/2)
        std::vector<cd> poles;
        for (size_t k = 0; k < fin.L.pair.size(); ++k) poles.push_back(pole_of(fin.L, fin.th, k) * P.ws);
        const Layout L0 = make_layout(poles, g, false);
        VecR th0 = fin.th.head(L0.n);
        // The D = 0 fit gets start_iter iterations from the poles of the D fit: its cost is an upper
        // bound of the D = 0 optimum, so the test errs towards keeping D (never a bias, one more
        // parameter per entry); when D = 0 is accepted it continues to convergence.
        LmOut f0 = lm(P, L0, th0, o.start_iter, o.tol, o.stable, nullptr);
        res.feedthrough_lr_p = chi2_sf((double)g, std::max(0.0, 2.0 * (f0.V - fin.V)));
        if (res.feedthrough_lr_p >= o.auto_alpha) {
            const int done = f0.iters;
            f0 = lm(P, L0, f0.th, o.max_iter, o.tol, o.stable, nullptr);
            f0.iters += done;
            res.feedthrough_lr_p = chi2_sf((double)g, std::max(0.0, 2.0 * (f0.V - fin.V)));
            fin = f0;
            finL = f0.L;
        }
    }
    res.converged = fin.conv;
    res.iterations = fin.iters;
    res.grad_norm = fin.gnorm;
    res.reflected = refl;
    finish(P, finL, fin.th, fin.at_bound, o.known_noise, res);
    res.model.h = h;
    return res;
}

PrResult pr_ml_fit(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted, PrOptions o)
{
    if (!o.pole_starts.empty()) return pr_ml(w, d, f.h, o);   // a model to refine: its poles are the start
    try {
        SubspaceOptions so;
        so.order = o.order;
        so.estimate_D = o.feedthrough != Feedthrough::No;
        so.refine_iter = 30;        // msid fit --method subspace's model: refined ...
        so.stable_auto = o.stable;  // ... and stable by default
        const std::vector<WeightedLine> &ws = o.subspace_scan_w ? *o.subspace_scan_w : w;
        if (&ws != &w) so.refine_w = &w;   // refined on the weights ml minimises
        const SubspaceResult sr = fit_subspace(f, d, ws, weighted, so);
        o.subspace_starts.insert(o.subspace_starts.end(), sr.candidates.begin(), sr.candidates.end());
        o.subspace_starts.push_back(sr.model);
        o.refined_subspace_start = true;
    } catch (const FitError &) {
        // subspace cannot start this order (too few lines for its block rows): vector fitting still does
    }
    return pr_ml(w, d, f.h, o);
}

}  // namespace msidfit
