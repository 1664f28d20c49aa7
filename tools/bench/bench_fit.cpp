// msid bench fit: subspace, lmfd and ml on random stable DT systems (SISO and 2x2) with their
// accuracy against the truth and the NumPy peer of the weighted subspace algorithm on the same
// files; then the simulated structures (bench_structures.cpp), the whole `msid fit` process, and
// without --only the multiple-experiment ML (bench_multi.cpp) and cISSIM (bench_cissim.cpp).
#include "bench_fit_parts.hpp"

#include "frf_file.hpp"
#include "lmfd_fit.hpp"
#include "model_io.hpp"
#include "msid_host_util.hpp"
#include "msid_json_file.hpp"
#include "subspace.hpp"

#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace msidbench {

using namespace msidfit;
using msidfmt::Json;
using msidfmt::read_json_file;
using msidfmt::write_json_file;
using msidutil::fmt;

namespace {

struct FitCfg {
    const char *name;
    int n, nu, ny, L;
};

const FitCfg CONFIGS[] = {{"SISO n=4, 1000 lines", 4, 1, 1, 1000}, {"2x2 n=8, 500 lines", 8, 2, 2, 500}};

// A random stable DT system: n/2 lightly damped modes, random B, C, D.
SSModel random_system(msid_rng &r, int n, int nu, int ny)
{
    SSModel m;
    m.domain = Domain::DT;
    m.A = MatR::Zero(n, n);
    for (int k = 0; k < n / 2; ++k) {
        const double rad = 0.5 + 0.45 * msid_rng_uniform(&r), th = 0.1 + 2.7 * msid_rng_uniform(&r);
        m.A(2 * k, 2 * k) = m.A(2 * k + 1, 2 * k + 1) = rad * std::cos(th);
        m.A(2 * k, 2 * k + 1) = -rad * std::sin(th);
        m.A(2 * k + 1, 2 * k) = rad * std::sin(th);
    }
    m.B = MatR(n, nu);
    m.C = MatR(ny, n);
    m.D = MatR(ny, nu);
    for (int i = 0; i < m.B.size(); ++i) m.B.data()[i] = msid_rng_normal(&r);
    for (int i = 0; i < m.C.size(); ++i) m.C.data()[i] = msid_rng_normal(&r);
    for (int i = 0; i < m.D.size(); ++i) m.D.data()[i] = 0.5 * msid_rng_normal(&r);
    return m;
}

// FRF at L lines (bins 1..L of P = 2L+2) with M noisy repetitions per line:
// G + mean of M complex Gaussian noises (covariance s^2 I), sample covariance / M.
Json frf_doc(msid_rng &r, const SSModel &m, int L, double snr_db, int M)
{
    const int ny = (int)m.C.rows(), nu = (int)m.B.cols(), g = ny * nu, P = 2 * L + 2;
    std::vector<MatC> G(L);
    double pw = 0;
    for (int l = 0; l < L; ++l) {
        G[l] = ss_eval(m, std::polar(1.0, 2 * M_PI * (l + 1) / P));
        pw += G[l].squaredNorm() / (g * L);
    }
    const double s2 = pw * std::pow(10.0, -snr_db / 10.0);
    msidfrf::Header hd;
    hd.period = (uint32_t)P;
    hd.nu = (uint32_t)nu;
    hd.ny = (uint32_t)ny;
    hd.m = (uint32_t)nu;
    Json doc = msidfrf::header(hd);
    doc["periods_used"] = M;
    doc["periods_rejected"] = 0;
    doc["noise_cov"] = msidfrf::cmat(MatC(MatC::Identity(ny, ny) * (s2 / P)));
    doc["experiments"] = Json::array();
    Json lines = Json::array();
    for (int l = 0; l < L; ++l) {
        std::vector<VecC> x(M, VecC(g));
        VecC mean = VecC::Zero(g);
        for (int k = 0; k < M; ++k) {
            for (int a = 0; a < g; ++a)
                x[k](a) = Eigen::Map<const VecC>(G[l].data(), g)(a) +
                          std::sqrt(s2 / 2) * cd(msid_rng_normal(&r), msid_rng_normal(&r));
            mean += x[k] / (double)M;
        }
        MatC S = MatC::Zero(g, g);
        for (int k = 0; k < M; ++k) S += (x[k] - mean) * (x[k] - mean).adjoint();
        S /= (double)(M - 1) * M;
        msidfrf::Position pos;
        pos.bin = (uint32_t)(l + 1);
        pos.period = (uint32_t)P;
        msidfrf::LineStats st;
        st.G = Eigen::Map<const MatC>(mean.data(), ny, nu);
        st.cov = S;
        st.dof = M - 1;   // cov_known_input: the same
        lines.push_back(msidfrf::line(msidfrf::position(pos), st));
    }
    doc["lines"] = lines;
    return doc;
}

// The mean of the finite values (NAN if none), and the upper median.
double mean_finite(const std::vector<double> &v)
{
    double s = 0;
    int n = 0;
    for (double x : v)
        if (std::isfinite(x)) { s += x; ++n; }
    return n ? s / n : NAN;
}
double upper_median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// One configuration's random systems and their FRF files.
struct Systems {
    std::vector<SSModel> truth;
    std::vector<std::string> files;
};

Systems write_systems(const FitCfg &c, int NS, const std::string &dir)
{
    msid_rng r;
    msid_rng_seed(&r, 1000 + (uint64_t)c.n);
    Systems s;
    for (int k = 0; k < NS; ++k) {
        s.truth.push_back(random_system(r, c.n, c.nu, c.ny));
        s.files.push_back(dir + "/" + std::to_string(c.n) + "-" + std::to_string(k) + ".json");
        write_json_file(s.files.back(), frf_doc(r, s.truth.back(), c.L, 40.0, 10));
    }
    return s;
}

// The fits as `msid fit` runs them on one configuration: subspace (refined on the covariances
// pooled over 2H+1 lines, the pooling inside the timed fit), the lmfd closed form, and ml (--param
// lmfd, the DT MIMO default) on the pooled weights from the subspace start.
struct Fits {
    SubspaceOptions so;
    LmfdSpec ls;
    MlOptions mo;

    explicit Fits(const FitCfg &c)
    {
        so.order = c.n;
        so.stable_auto = true;
        so.refine_iter = 30;
        ls.nD = c.n / c.ny;
        ls.nN = ls.nD;
    }
    static std::vector<WeightedLine> pooled(std::vector<WeightedLine> w)
    {
        smooth_weights(w, ML_WEIGHT_SMOOTH);
        return w;
    }
    SubspaceResult subspace_pooled(const std::vector<WeightedLine> &w, const std::vector<WeightedLine> &wp,
                                   const FrfData &f) const
    {
        SubspaceOptions sp = so;
        sp.refine_w = &wp;
        return fit_subspace(f, Domain::DT, w, true, sp);
    }
    SubspaceResult subspace(const std::vector<WeightedLine> &w, const FrfData &f) const
    {
        return subspace_pooled(w, pooled(w), f);
    }
    MlResult ml(const std::vector<WeightedLine> &w, const FrfData &f) const
    {
        const auto wp = pooled(w);
        const SubspaceResult sr = subspace_pooled(w, wp, f);
        std::vector<MatC> target;
        for (const auto &l : w) target.push_back(ss_eval(sr.model, l.x));
        return lmfd_ml(wp, Domain::DT, 0, ls, lmfd_sk(wp, Domain::DT, 0, ls, 30, &target), mo, false);
    }
    // The closed form is the fully/under-constrained case on as many lines as the LMFD has unknowns / 2.
    int closed_form_lines(const FitCfg &c) const
    {
        const int qrow = ls.nD * c.ny + (ls.nN + 1) * c.nu;
        return qrow / (2 * c.nu);
    }
};

// The NumPy peer of the weighted subspace algorithm on the same files.
struct PeerFits {
    double t = -1, e_mean = NAN, e_med = NAN;
    std::string note;
};

// A matrix as the peer writes it (rows of numbers).
MatR json_matrix(const Json &v)
{
    MatR M((Eigen::Index)v.size(), v.empty() ? 0 : (Eigen::Index)v[0].size());
    for (size_t i = 0; i < v.size(); ++i)
        for (size_t j = 0; j < v[i].size(); ++j) M((Eigen::Index)i, (Eigen::Index)j) = v[i][j].get<double>();
    return M;
}

PeerFits run_peer(const FitCfg &c, const Systems &s, const std::string &dir)
{
    PeerFits p;
    std::string cmd = "python3 '" + peers_dir() + "/msid_peers/bench_fit_peer.py' " + std::to_string(c.n) + " '" + dir + "/peer.json'";
    for (auto &fl : s.files) cmd += " '" + fl + "'";
    std::string outp;
    if (capture(cmd + " 2>&1", outp) != 0) {
        p.note = "peer failed: " + outp.substr(0, 200);
        return p;
    }
    const Json pj = read_json_file(dir + "/peer.json");
    std::vector<double> ep, tp;
    for (size_t k = 0; k < pj["models"].size(); ++k) {
        const Json &mj = pj["models"][k];
        SSModel pm;
        pm.domain = Domain::DT;
        pm.A = json_matrix(mj["A"]); pm.B = json_matrix(mj["B"]); pm.C = json_matrix(mj["C"]); pm.D = json_matrix(mj["D"]);
        try { ep.push_back(ss_distance(pm, s.truth[k]).h2); } catch (const FitError &) { ep.push_back(NAN); }
        tp.push_back(pj["sec_per_fit"][k].get<double>());
    }
    p.t = upper_median(tp);
    p.e_mean = mean_finite(ep);
    p.e_med = upper_median(ep);
    p.note = "numpy " + pj["numpy"].get<std::string>();
    return p;
}

// One configuration: times, accuracy over the systems, the peer, and its rows of the report.
FitBenchRow bench_config(Writer &w, const FitCfg &c, const FitBenchRequest &rq, const std::string &dir)
{
    const Systems s = write_systems(c, rq.systems, dir);
    const FrfData f0 = read_frf(s.files[0]);
    const auto w0 = weigh(f0, Domain::DT, Weight::Cov);
    const Fits fits(c);
    volatile double sink = 0;
    FitBenchRow row;
    row.config = c.name;
    row.subspace_s = best_time([&] { sink = sink + fits.subspace(w0, f0).cost; }, rq.min_seconds);
    const int Lfc = fits.closed_form_lines(c);
    std::vector<WeightedLine> wfc(w0.begin(), w0.begin() + Lfc);
    row.lmfd_s = best_time([&] { sink = sink + lmfd_closed_form(wfc, Domain::DT, 0, fits.ls).model.Nm[0](0, 0); },
                           rq.min_seconds);
    row.ml_s = best_time([&] { sink = sink + fits.ml(w0, f0).cost; }, rq.min_seconds);
    // accuracy over the systems
    std::vector<double> e_sub, e_ml;
    for (int k = 0; k < rq.systems; ++k) {
        const FrfData f = read_frf(s.files[k]);
        const auto wk = weigh(f, Domain::DT, Weight::Cov);
        e_sub.push_back(ss_distance(fits.subspace(wk, f).model, s.truth[k]).h2);
        try {
            e_ml.push_back(ss_distance(lmfd_to_ss(fits.ml(wk, f).model), s.truth[k]).h2);
        } catch (const FitError &) {
            e_ml.push_back(NAN);
        }
    }
    row.subspace_h2_mean = mean_finite(e_sub);
    row.ml_h2_mean = mean_finite(e_ml);
    const PeerFits p = rq.peer ? run_peer(c, s, dir) : PeerFits{};
    row.peer_s = p.t;
    w.print("%s\n", c.name);
    const SubspaceResult s0 = fits.subspace(w0, f0);
    w.print("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g (%d systems)%s\n", "subspace",
            row.subspace_s * 1e3, row.subspace_h2_mean, upper_median(e_sub), rq.systems,
            p.t > 0 ? fmt("   %.1fx faster than the peer", p.t / row.subspace_s).c_str() : "");
    w.print("  %-10s   (system 1: r = %d, %d refinement steps, cost %.6g -> %.6g)\n", "", s0.r, s0.refine_steps,
            s0.cost_unrefined, s0.cost);
    w.print("  %-10s %10.3f ms   (closed form, %d lines: fully/under-constrained)\n", "lmfd", row.lmfd_s * 1e3, Lfc);
    w.print("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g (subspace start + SK + LM)\n", "ml",
            row.ml_s * 1e3, row.ml_h2_mean, upper_median(e_ml));
    if (p.t > 0)
        w.print("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g  (%s, median time per fit)\n", "peer",
                p.t * 1e3, p.e_mean, p.e_med, p.note.c_str());
    else if (rq.peer)
        w.print("  peer unavailable: %s\n", p.note.c_str());
    w.print("\n");
    return row;
}

// The whole `msid fit --method subspace` process against a plain NumPy weighted subspace (fixed r = 12) process.
void bench_process(Writer &w, FitBenchResult &res, const std::string &msid_exe, const std::string &dir)
{
    msid_rng r;
    msid_rng_seed(&r, 606);
    const SSModel m = random_system(r, 6, 2, 2);
    const std::string frf = dir + "/proc.json";
    write_json_file(frf, frf_doc(r, m, 202, 40.0, 10));
    char self[PATH_MAX];
    if (!realpath(msid_exe.c_str(), self)) return;
    const std::string msid_cmd = std::string("'") + self + "' fit --method subspace --order 6 '" + frf + "' -o '" + dir + "/proc-model.json'";
    const std::string peer_cmd = "python3 '" + peers_dir() + "/msid_peers/bench_fit_peer.py' 6 '" + dir + "/proc-peer.json' '" + frf + "' --r 12";
    const double t_msid = process_time(msid_cmd, 15), t_peer = process_time(peer_cmd, 5);
    res.process_msid_s = t_msid;
    res.process_peer_s = t_peer;
    w.print("whole process: 2x2, order 6, 202 lines (wall time, median)\n");
    w.print("  msid fit --method subspace   %8.1f ms\n", t_msid * 1e3);
    if (t_peer > 0)
        w.print("  NumPy subspace, r = 12       %8.1f ms   (python3 start-up, import, fit)   msid %.1fx faster\n\n",
                t_peer * 1e3, t_peer / t_msid);
    else
        w.print("  NumPy peer failed\n\n");
}

void check_request(const FitBenchRequest &rq)
{
    if (rq.only > 4) throw msidutil::UsageError("--only takes 1 (SISO), 2 (2x2), 3 (structures) or 4 (whole process)");
    if (rq.systems < 1) throw msidutil::UsageError("--systems must be at least 1");
    if (rq.runs > 1000) throw msidutil::UsageError("--runs must be at most 1000 (each run is 5 vector fits of seconds each)");
}

}  // namespace

FitBenchResult bench_fit(const FitBenchRequest &rq, const Sink &sink)
{
    check_request(rq);
    FitBenchResult res;
    Writer w(sink, res.report);
    const std::string dir = temp_dir("msid-bench-fit");
    w.print("msid bench fit  (msid %s, Eigen %d.%d.%d)\nmachine: %s\n", MSID_VERSION, EIGEN_WORLD_VERSION,
            EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION, machine().c_str());
    w.print("data: random stable DT systems, 40 dB SNR, line covariance from 10 repetitions; times: best of runs >= %.2g s\n\n",
            rq.min_seconds);
    for (const FitCfg &c : CONFIGS) {
        if (rq.only && (rq.only > 2 || &c != &CONFIGS[rq.only - 1])) continue;
        res.rows.push_back(bench_config(w, c, rq, dir));
    }
    if ((!rq.only || rq.only == 3) && rq.peer) fit_structures(w, dir, rq.min_seconds, rq.runs);
    if (!rq.only || rq.only == 4) bench_process(w, res, rq.msid_exe, dir);
    if (!rq.only) {   // the multiple-experiment ML on case M1, 50 runs per N
        MultiBenchRequest mq;
        mq.runs = 50;
        mq.peer = rq.peer;
        w.print("\n");
        fit_multi(w, mq);
    }
    remove_dir(w, dir, "msid bench: note: could not remove ");
    if (!rq.only) {   // discrete-cISSIM on its own simulated records
        CissimBenchRequest cq;
        cq.quick = true;
        cq.systems = rq.systems;
        w.print("\n");
        fit_cissim(w, cq);
    }
    return res;
}

}  // namespace msidbench
