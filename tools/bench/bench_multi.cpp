// msid bench fit --only multi: the multiple-experiment ML (tools/fit/multi.hpp) on case M1 of
// shared/reference-cases.md (Markovsky & Pintelon §VII, K runs per N as in the paper), and its
// speed against the SciPy peer that estimates every record's initial conditions as parameters
// (tools/peers/msid_peers/bench_multi_peer.py) on the same records.
#include "bench_fit_parts.hpp"

#include "msid_host_util.hpp"
#include "msid_json_file.hpp"
#include "multi_sim.hpp"

#include <cmath>
#include <cstdlib>

namespace msidbench {

using namespace msidfit;
using msidfmt::Json;
using msidutil::fmt;

namespace {

double specnorm(const MatR &A) { return Eigen::JacobiSVD<MatR>(A).singularValues()(0); }

// What every part shares: the case, its true coefficients and the fit's options.
struct M1 {
    M1Case c;
    VecR a0 = c.alpha();
    MultiOptions o;
    int K;
    explicit M1(int runs) : K(runs)
    {
        o.order = 6;
        o.h = c.ts;
    }
};

// Slope of the least-squares line through (x, y) from index `from` on.
double fit_slope(const std::vector<double> &lx, const std::vector<double> &ly, size_t from)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t k = from; k < lx.size(); ++k) { sx += lx[k]; sy += ly[k]; sxx += lx[k] * lx[k]; sxy += lx[k] * ly[k]; }
    const double nn = (double)(lx.size() - from);
    return (nn * sxy - sx * sy) / (nn * sxx - sx * sx);
}

// 1: consistency, error against N (new initial conditions, lengths and noise every run).
void consistency(Writer &w, const M1 &m)
{
    const int K = m.K;
    w.print("1. M1 rms error e = sqrt(mean |alpha_hat - alpha|^2) over %d runs (alpha: DT characteristic coefficients)\n", K);
    w.print("   %4s %12s %14s %12s %10s %12s\n", "N", "ML (multi)", "sqrt(tr cov)", "Prony", "ML/sqrt-law", "ms per fit");
    const std::vector<int> Ns = {1, 2, 3, 5, 7, 10, 15, 20, 30, 40, 50};
    std::vector<double> lx, ly;
    double e_first = 0;
    int notconv = 0;
    for (int N : Ns) {
        msid_rng r;
        msid_rng_seed(&r, 5000 + (uint64_t)N);
        double e2 = 0, p2 = 0, t = 0, c2 = 0;
        for (int k = 0; k < K; ++k) {
            const MultiData d = m1_data(m.c, r, N);
            const auto y = multi_add_noise(d.clean, r, multi_noise_sd(d.clean, 100.0));
            const double t0 = wall_s();
            const MultiResult f = multi_fit(y, m.o);
            t += wall_s() - t0;
            notconv += !f.converged;
            e2 += (f.alpha - m.a0).squaredNorm() / K;
            c2 += f.cov.topLeftCorner(6, 6).trace() / K;
            p2 += (multi_start_prony(y, 6, 1) - m.a0).squaredNorm() / K;
        }
        const double e = std::sqrt(e2);
        if (N == Ns.front()) e_first = e;
        lx.push_back(std::log((double)N));
        ly.push_back(std::log(e));
        w.print("   %4d %12.4g %14.4g %12.4g %10.3f %12.3f\n", N, e, std::sqrt(c2), std::sqrt(p2),
                e / (e_first / std::sqrt((double)N)), t / K * 1e3);
    }
    w.print("   slope of log e on log N: %.3f for N = 1..50, %.3f for N = 5..50 (1/sqrt(N): -0.5);\n"
            "   fits not converged: %d of %zu. sqrt(tr cov): the rms error the fits' own covariances predict\n"
            "   (with random initial conditions a few records can leave a mode weakly excited: the bound\n"
            "   itself falls faster than 1/sqrt(N) at small N)\n\n",
            fit_slope(lx, ly, 0), fit_slope(lx, ly, 3), notconv, Ns.size() * (size_t)K);
}

// 2: efficiency, e' = ||C - V||_2 / ||C||_2 (paper Fig. 3) with fixed initial conditions.
void efficiency(Writer &w, const M1 &m)
{
    const int K = m.K;
    w.print("2. M1 covariance against the Cramer-Rao bound C (fixed records, %d noise realisations)\n", K);
    w.print("   %4s %10s %12s %14s\n", "N", "e' (emp.)", "MSE/CRB", "reported vs C");
    for (int N : {1, 2, 5, 10, 20, 50}) {
        msid_rng r;
        msid_rng_seed(&r, 7000 + (uint64_t)N);
        const MultiData d = m1_data(m.c, r, N);
        const double sd = multi_noise_sd(d.clean, 100.0);
        std::vector<MatR> u;
        for (const auto &x : d.clean) u.push_back(x.u);
        const MatR C = multi_crb(m.a0, {}, 1, u, d.x0, 1, sd * sd);
        const Eigen::LLT<MatR> L(C);
        std::vector<VecR> est;
        double w2 = 0, rep = 0;
        for (int k = 0; k < K; ++k) {
            const MultiResult f = multi_fit(multi_add_noise(d.clean, r, sd), m.o);
            est.push_back(f.alpha);
            w2 += L.matrixL().solve(f.alpha - m.a0).squaredNorm() / (6.0 * K);
            rep += specnorm(f.cov.topLeftCorner(6, 6) - C) / specnorm(C) / K;
        }
        VecR mean = VecR::Zero(6);
        for (const auto &e : est) mean += e / K;
        MatR V = MatR::Zero(6, 6);
        for (const auto &e : est) V += (e - mean) * (e - mean).transpose() / (K - 1);
        w.print("   %4d %10.3f %12.3f %14.3f\n", N, specnorm(C - V) / specnorm(C), w2, rep);
    }
    w.print("   e': relative spectral distance of the empirical covariance (sampling error ~ sqrt(2/K) = %.2f);\n"
            "   MSE/CRB: mean of |C^-1/2 (alpha_hat - alpha)|^2 / 6; reported vs C: mean relative distance of\n"
            "   the covariance each fit reports\n\n", std::sqrt(2.0 / K));
}

// 3: time per fit on one noisy M1 set per N, and the peer's on the same records.
struct Speed {
    std::vector<int> Ps = {1, 5, 10, 20, 50};
    std::vector<double> tm, tp, dev;   // msid's median time, the peer's, the peer's deviation
    std::vector<VecR> am;              // msid's estimates
    Json in;                           // the records and starts, as the peer reads them
};

Speed time_multi(const M1 &m)
{
    Speed s;
    s.tm.assign(s.Ps.size(), 0);
    s.tp.assign(s.Ps.size(), -1);
    s.dev.assign(s.Ps.size(), NAN);
    s.am.resize(s.Ps.size());
    s.in["order"] = 6;
    s.in["sets"] = Json::array();
    for (size_t q = 0; q < s.Ps.size(); ++q) {
        msid_rng r;
        msid_rng_seed(&r, 9000 + (uint64_t)s.Ps[q]);
        const MultiData d = m1_data(m.c, r, s.Ps[q]);
        const auto y = multi_add_noise(d.clean, r, multi_noise_sd(d.clean, 100.0));
        std::vector<double> ts;
        for (int rep = 0; rep < 5; ++rep) {
            const double t0 = wall_s();
            s.am[q] = multi_fit(y, m.o).alpha;
            ts.push_back(wall_s() - t0);
        }
        std::sort(ts.begin(), ts.end());
        s.tm[q] = ts[2];
        Json set;
        Json recs = Json::array();
        for (const auto &x : y) recs.push_back(std::vector<double>(x.y.data(), x.y.data() + x.y.rows()));
        set["records"] = recs;
        const VecR st = multi_start_kung(y, 6);
        set["start"] = std::vector<double>(st.data(), st.data() + st.size());
        s.in["sets"].push_back(set);
    }
    return s;
}

// The SciPy peer on the same records: its times and deviations into `s`; returns the note.
std::string run_peer(Writer &w, const M1 &m, Speed &s)
{
    const std::string dir = temp_dir("msid-bench-multi");
    msidfmt::write_json_file(dir + "/in.json", s.in);
    const std::string cmd = "python3 '" + peers_dir() + "/msid_peers/bench_multi_peer.py' '" + dir + "/in.json' '" + dir +
                            "/out.json' 2>&1";
    const int rc = std::system(cmd.c_str());
    std::string note;
    if (rc == 0) {
        const Json pj = msidfmt::read_json_file(dir + "/out.json");
        note = "SciPy " + pj["scipy"].get<std::string>() + ", NumPy " + pj["numpy"].get<std::string>();
        for (size_t q = 0; q < s.Ps.size(); ++q) {
            s.tp[q] = pj["results"][q]["seconds"].get<double>();
            VecR ap(6);
            for (int k = 0; k < 6; ++k) ap(k) = pj["results"][q]["alpha"][(size_t)k].get<double>();
            s.dev[q] = (ap - s.am[q]).norm() / (s.am[q] - m.a0).norm();
        }
    } else {
        note = "peer failed (exit " + std::to_string(rc) + ")";
    }
    remove_dir(w, dir, "msid bench: could not remove ");
    return note;
}

void speed(Writer &w, const M1 &m, bool peer)
{
    w.print("3. time per fit on the same records (one noisy M1 set per N)\n");
    Speed s = time_multi(m);
    const std::string note = peer ? run_peer(w, m, s) : "--no-peer";
    w.print("   %4s %14s %16s %10s %22s\n", "N", "multi (ms)", "SciPy LM (ms)", "speed-up", "|a_peer-a|/|a-a_true|");
    for (size_t q = 0; q < s.Ps.size(); ++q)
        w.print("   %4d %14.3f %16s %10s %22s\n", s.Ps[q], s.tm[q] * 1e3, s.tp[q] > 0 ? fmt("%.1f", s.tp[q] * 1e3).c_str() : "-",
                s.tp[q] > 0 ? fmt("%.1fx", s.tp[q] / s.tm[q]).c_str() : "-",
                std::isfinite(s.dev[q]) ? fmt("%.2g", s.dev[q]).c_str() : "-");
    w.print("   peer: %s, least_squares(method='lm') over the poles and every record's initial conditions,\n"
            "   started from the same Kung poles; multi: median of 5, starts included\n\n", note.c_str());
}

// 4: order selection (--order auto: orders 1..12, MDL with the initial conditions counted).
void order_selection(Writer &w, const M1 &m)
{
    const int KO = std::max(10, m.K / 4);
    std::vector<int> orders;
    for (int n2 = 1; n2 <= 12; ++n2) orders.push_back(n2);
    w.print("4. --order auto on M1 (orders 1..12, %d runs per N, SNR 100): fraction choosing 6\n", KO);
    w.print("   %4s %8s %8s %14s %16s\n", "N", "MDL", "AIC", "Hankel gap", "ms per auto fit");
    for (int N : {2, 5, 10}) {
        msid_rng r;
        msid_rng_seed(&r, 11000 + (uint64_t)N);
        int cm = 0, ca = 0, cg = 0;
        double t = 0;
        for (int k = 0; k < KO; ++k) {
            const MultiData d = m1_data(m.c, r, N);
            const auto y = multi_add_noise(d.clean, r, multi_noise_sd(d.clean, 100.0));
            const double t0 = wall_s();
            const MultiOrderSelection sel = multi_select_order(y, m.o, orders, "mdl");
            t += wall_s() - t0;
            cm += sel.chosen == 6;
            cg += sel.hankel_gap_order == 6;
            int best = -1;
            double ba = INFINITY;
            for (const auto &row : sel.rows)
                if (row.ok && row.aic < ba) { ba = row.aic; best = row.order; }
            ca += best == 6;
        }
        w.print("   %4d %8.3f %8.3f %14.3f %16.2f\n", N, (double)cm / KO, (double)ca / KO, (double)cg / KO, t / KO * 1e3);
    }
    w.print("\n");
}

// 5: coloured noise: AR(2) band-pass noise at the 130 Hz mode, weighted (AR given / estimated) against unweighted.
void coloured_noise(Writer &w, const M1 &m)
{
    const int KC = std::max(10, m.K / 2), N = 5;
    VecR car(2);
    car << -2 * 0.8 * std::cos(2 * M_PI * 0.13), 0.64;
    MultiOptions og = m.o, oe = m.o;
    og.noise_ar = car;
    oe.noise_ar_order = 2;
    msid_rng r;
    msid_rng_seed(&r, 12000);
    double e[3] = {0, 0, 0}, tt[3] = {0, 0, 0};
    int cov_in[3] = {0, 0, 0}, tot = 0;
    for (int k = 0; k < KC; ++k) {
        const MultiData d = m1_data(m.c, r, N);
        const auto y = multi_add_ar_noise(d.clean, r, car, multi_noise_sd(d.clean, 100.0));
        const MultiOptions *os[3] = {&m.o, &og, &oe};
        for (int j = 0; j < 3; ++j) {
            const double t0 = wall_s();
            const MultiResult f = multi_fit(y, *os[j]);
            tt[j] += wall_s() - t0;
            e[j] += (f.alpha - m.a0).squaredNorm() / KC;
            for (size_t q = 0; q < f.modes.size() && f.modes.size() == 3; ++q) {
                cov_in[j] += std::abs(f.modes[q].fn - m.c.fn[q]) < 1.96 * f.modes[q].sd_fn;
                cov_in[j] += std::abs(f.modes[q].zeta - m.c.zeta[q]) < 1.96 * f.modes[q].sd_zeta;
            }
        }
        tot += 6;
    }
    w.print("5. M1 N = %d with AR(2) noise (poles 0.8 e^{+-j 2pi 0.13}, SNR 100), %d runs\n", N, KC);
    w.print("   %-28s %12s %22s %12s\n", "estimator", "rms error", "95% coverage fn, zeta", "ms per fit");
    const char *names[3] = {"unweighted (white model)", "AR(2) given (--noise-ar)", "AR(2) estimated (2-stage)"};
    for (int j = 0; j < 3; ++j)
        w.print("   %-28s %12.4g %22.3f %12.2f\n", names[j], std::sqrt(e[j]), (double)cov_in[j] / tot, tt[j] / KC * 1e3);
}

}  // namespace

void fit_multi(Writer &w, const MultiBenchRequest &rq)
{
    if (rq.runs < 10) throw msidutil::UsageError("--runs must be at least 10");
    w.print("msid bench fit --only multi  (msid %s, Eigen %d.%d.%d)\nmachine: %s\n\n", MSID_VERSION, EIGEN_WORLD_VERSION,
            EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION, machine().c_str());
    const M1 m(rq.runs);
    consistency(w, m);
    efficiency(w, m);
    speed(w, m, rq.peer);
    order_selection(w, m);
    coloured_noise(w, m);
}

MultiBenchResult bench_fit_multi(const MultiBenchRequest &rq, const Sink &sink)
{
    return with_report<MultiBenchResult>(fit_multi, rq, sink);
}

}  // namespace msidbench
