// msid fit --method cissim: discrete-cISSIM from periodic time records (You et al. 2023),
// with the noise covariances of section 4.3. docs/fitting.md, section "cissim".
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "cissim.hpp"
#include "model_io.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace msidcli {

using namespace msidfit;

static const char *CISSIM_HELP =
    "usage: msid fit --method cissim --period P --lines L1,L2,... --experiment e.csv [--experiment e2.csv ...]\n"
    "                [--order n] [--reduced] [--block-rows NBAR] [--max-order N] [--skip-periods K]\n"
    "                [--isp auto|direct|fft] [--no-d] [--lags M] [--no-covariance] [--columns u1=..,y1=..]\n"
    "                [--refine ml|none]\n"
    "                -o model.json\n"
    "\n"
    "Discrete-cISSIM (You, Huang, Zhang 2023) on periodic time records (the records of `msid frf`, whole\n"
    "periods of P samples; one experiment may excite all inputs): invariant-subspace regression (Alg. 1 by\n"
    "per-period sums and one product per line, or Alg. 3 by one FFT, chosen by the number of lines), A, C\n"
    "and the order by QR + SVD (Alg. 4), B and D by the Sylvester regression (Alg. 5).\n"
    "  --lines          the excited lines (bins below P/2; ranges a:b, a:step:b)\n"
    "  --reduced        use only --lines in the regression (reduced set); default: the full set of bins\n"
    "                   0 .. ceil(P/2) - 1\n"
    "  --order n        state order; without it the largest singular-value gap up to --max-order (10)\n"
    "  --block-rows     nbar of Alg. 4 (default 2n, or max-order + 1 when the order is estimated)\n"
    "  --skip-periods   leading periods of each record to ignore (default 1, as the paper: transient)\n"
    "  --lags M         correlation lags of the noise covariance (default max(ceil(n^2/ny^2) + 1, N^(1/3)), <= 50)\n"
    "  --unweighted     the published Alg. 4 (no whitening of R22 by the noise of the block rows; biased\n"
    "                   for a reduced set of lines in a band at finite N)\n"
    "  --allow-unstable keep poles of A outside the unit circle (default: reflected, Assumption 1)\n"
    "  --no-covariance  skip Sigma_ww, Sigma_vv, Sigma_tt (section 4.3, Alg. 6-7)\n"
    "  --refine ml      (default) refine the cissim model by weighted output error (maximum likelihood) on the\n"
    "                   same phasors, weights from the per-line sample covariance over the periods, and report\n"
    "                   the covariance of the model FRF at --lines (frf[].cov); needs >= 2 periods after the\n"
    "                   skipped ones and noise. --refine none: the paper's estimate alone (no FRF covariance)\n";

int cmd_fit_cissim(int argc, char **argv)
{
    Args a(argc, argv, 2, CISSIM_HELP,
           {"method", "period", "lines", "order", "block-rows", "max-order", "skip-periods", "isp", "lags", "columns",
            "output", "refine"},
           {"reduced", "no-d", "no-covariance", "unweighted", "allow-unstable"}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string out = a.require("output");
    const uint32_t P = parse_u32(a.require("period"), "--period");
    if (P < 4) throw UsageError("--period must be at least 4 samples");
    std::vector<uint32_t> lines = parse_uint_list(a.require("lines"), "--lines");
    if (lines.empty()) throw UsageError("--lines is empty");
    for (uint32_t b : lines)
        if (2 * (uint64_t)b >= P) throw UsageError(fmt("--lines: bin %u is not below P/2 = %u", b, P / 2));
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");
    CissimOptions o;
    if (a.has("order")) {
        o.order = (int)parse_u32(a.get("order"), "--order");
        if (o.order == 0) throw UsageError("--order must be positive");
    }
    if (a.has("max-order")) {
        o.max_order = (int)parse_u32(a.get("max-order"), "--max-order");
        if (o.max_order == 0) throw UsageError("--max-order must be positive");
    }
    if (a.has("block-rows")) o.block_rows = (int)parse_u32(a.get("block-rows"), "--block-rows");
    o.estimate_D = !a.has("no-d");
    o.weighted = !a.has("unweighted");
    o.stable = !a.has("allow-unstable");
    const uint32_t skip = a.u32("skip-periods", 1);
    const std::string im = a.get("isp", "auto");
    IspMethod method = IspMethod::Auto;
    if (im == "direct") method = IspMethod::Direct;
    else if (im == "fft") method = IspMethod::Fft;
    else if (im != "auto") throw UsageError("--isp must be auto, direct or fft (got '" + im + "')");
    const bool reduced = a.has("reduced");
    const std::string refine = a.get("refine", "ml");
    if (refine != "ml" && refine != "none") throw UsageError("--refine must be ml or none (got '" + refine + "')");
    const bool do_refine = refine == "ml";
    std::vector<uint32_t> bins = lines;
    if (!reduced) {
        bins.clear();
        for (uint32_t b = 0; 2 * b < P; ++b) bins.push_back(b);
    }
    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    std::vector<Record> recs;
    for (const auto &p : a.all("experiment")) recs.push_back(read_experiment(p, cols, true));
    const uint32_t nu = recs[0].nu, ny = recs[0].ny;
    for (const auto &r : recs) {
        if (r.nu != nu || r.ny != ny)
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' %u and %u: the experiments must share the channels",
                            r.path.c_str(), r.nu, r.ny, recs[0].path.c_str(), nu, ny));
        const size_t K = r.n_rows / P;
        if (K < (size_t)skip + 2)
            throw Error(fmt("'%s' holds %zu whole period(s) of %u samples: cissim needs at least %u (--skip-periods %u, "
                            "plus 2 to check that the input is periodic, Assumption 4)",
                            r.path.c_str(), K, P, skip + 2, skip));
        const double eta = nonperiodic_fraction(r, P, skip, K - skip);
        if (!(eta <= NONPERIODIC_FRACTION))
            throw Error(fmt("'%s': the input is not periodic with period %u: %.0f%% of its power changes from period to "
                            "period (You et al. Assumption 4 needs u(k + P) = u(k)); give the right --period "
                            "(`msid frf --period auto` finds it) or use `msid frf --method lpm`",
                            r.path.c_str(), P, 100.0 * eta));
        if (r.n_rows % P)
            std::fprintf(stderr, "msid fit: note: '%s': the last %zu sample(s) do not fill a period and are not used\n",
                         r.path.c_str(), r.n_rows % P);
    }
    try {
        std::vector<IspResult> isp;
        for (const auto &r : recs) isp.push_back(cissim_isp(r.data(), r.n_rows, nu, ny, P, bins, skip, method, do_refine));
        const CissimResult res = cissim_fit(isp, o);
        CissimMlResult ml;
        if (do_refine) {
            // the weighted output error uses the excited lines only (--lines), also for the full set
            std::vector<IspResult> at_lines = isp;
            std::vector<Eigen::Index> pick;
            for (uint32_t b : lines) pick.push_back((Eigen::Index)(std::find(bins.begin(), bins.end(), b) - bins.begin()));
            for (auto &r : at_lines) {
                IspResult s2 = r;
                s2.bins = lines;
                s2.U.resize(nu, (Eigen::Index)pick.size());
                s2.Y.resize(ny, (Eigen::Index)pick.size());
                s2.line_cov.clear();
                for (size_t l = 0; l < pick.size(); ++l) {
                    s2.U.col((Eigen::Index)l) = r.U.col(pick[l]);
                    s2.Y.col((Eigen::Index)l) = r.Y.col(pick[l]);
                    if (!r.line_cov.empty()) s2.line_cov.push_back(r.line_cov[(size_t)pick[l]]);
                }
                r = s2;
            }
            ml = cissim_refine(res.model, at_lines);
        }
        const SSModel &ss = do_refine ? ml.model : res.model;
        const int n = res.order;
        Json doc;
        doc["format"] = "msid-model/1";
        doc["generator"] = std::string("msid ") + MSID_VERSION;
        doc["source"] = recs[0].path;
        Json ex = Json::array();
        for (const auto &r : recs) ex.push_back(r.path);
        doc["experiments"] = ex;
        doc["domain"] = "dt";
        doc["method"] = "cissim";
        doc["order"] = n;
        doc["n_inputs"] = nu;
        doc["n_outputs"] = ny;
        Json st;
        st["weight"] = "none";
        st["period"] = P;
        st["lines"] = format_bins(lines);
        st["frequency_set"] = reduced ? "reduced" : "full";
        st["isp"] = isp[0].used_fft ? "fft (Alg. 3)" : "direct (Alg. 1)";
        st["block_rows"] = res.block_rows;
        st["order_estimated"] = res.order_estimated;
        st["skip_periods"] = skip;
        st["periods_used"] = Json::array();
        for (const auto &r : isp) st["periods_used"].push_back(r.periods);
        st["estimate_D"] = o.estimate_D;
        st["weighted"] = o.weighted;
        st["refine"] = refine;
        doc["settings"] = st;
        doc["A"] = rmat_json(ss.A);
        doc["B"] = rmat_json(ss.B);
        doc["C"] = rmat_json(ss.C);
        doc["D"] = rmat_json(ss.D);
        doc["stable"] = ss_stable(ss);
        {
            Json sj;
            sj["stable"] = ss_stable(ss);
            sj["enforced"] = o.stable;
            double worst = 0;
            Eigen::EigenSolver<MatR> es(ss.A, false);
            for (Eigen::Index k = 0; k < ss.A.rows(); ++k) worst = std::max(worst, std::abs(es.eigenvalues()(k)));
            sj["max_abs_pole"] = worst;
            doc["stability"] = sj;
        }
        const int nparams = n * (int)(nu + ny) + (o.estimate_D ? (int)(nu * ny) : 0);
        doc["n_params"] = nparams;
        Json cj;
        cj["singular_values"] = res.sv;
        cj["lines_per_experiment"] = res.lines;
        cj["real_columns"] = res.real_columns;
        cj["reflected_poles"] = res.reflected;
        if (do_refine && !std::isfinite(ml.cov_factor))
            std::fprintf(stderr, "msid fit: note: %llu period(s) after the skipped ones are too few for an uncertainty "
                                 "(the per-line weights need more than %u + 2): frf[].cov is null\n",
                         (unsigned long long)isp[0].periods, ny);
        if (do_refine)
            cj["refinement"] = Json{{"method", "weighted output error (ML) on the ISP phasors at --lines, Levenberg-Marquardt"},
                                    {"cost_start", ml.cost_start},
                                    {"cost", ml.cost},
                                    {"expected", 0.5 * ml.dof},
                                    {"dof", ml.dof},
                                    {"iterations", ml.iterations},
                                    {"converged", ml.converged},
                                    {"cov_factor", std::isfinite(ml.cov_factor) ? Json(ml.cov_factor) : Json(nullptr)},
                                    {"cov_rank", ml.cov_rank},
                                    {"cov_note", "FRF covariance from the Fisher information of the weighted output error "
                                                 "(weights: per-line sample covariance over the periods), sample-ML factor applied"}};
        // noise covariance (section 4.3) on the full set, from the first experiment's residuals
        NoiseCov nc;
        bool have_nc = false;
        if (!a.has("no-covariance")) {
            const Record &r0 = recs[0];
            const uint64_t N = (uint64_t)(r0.n_rows / P - skip) * P;
            int M = a.has("lags") ? (int)parse_u32(a.get("lags"), "--lags")
                                  : std::max<int>((int)std::ceil((double)n * n / ((double)ny * ny)) + 1,
                                                  std::min(50, (int)std::lround(std::cbrt((double)N))));
            const int Mmin = (int)std::ceil((double)n * n / ((double)ny * ny)) + 1;
            if (M < Mmin)
                throw UsageError(fmt("--lags %d is below ceil(n^2 / ny^2) + 1 = %d (Assumption 8)", M, Mmin));
            if ((uint64_t)M >= N / 2) throw UsageError(fmt("--lags %d needs M << N = %llu (Assumption 8)", M, (unsigned long long)N));
            const Correlations c = cissim_correlations(r0.data(), r0.n_rows, nu, ny, P, skip, M);
            nc = cissim_noise_cov(ss, c);
            have_nc = true;
            Json nj;
            nj["Sigma_ww"] = rmat_json(nc.Sigma_ww);
            nj["Sigma_vv"] = rmat_json(nc.Sigma_vv);
            nj["Sigma_tt"] = rmat_json(nc.Sigma_tt);
            nj["Xi_zz"] = rmat_json(nc.Xi_zz);
            Json xr = Json::array();
            for (const auto &X : c.Xi_rr) xr.push_back(rmat_json(X));
            nj["Xi_rr"] = xr;
            nj["lags"] = nc.lags;
            nj["samples"] = c.n;
            nj["source"] = r0.path;
            nj["strongly_detectable"] = nc.detectable;
            nj["nominal"] = !nc.detectable;
            nj["note"] = nc.note.empty() ? Json(nullptr) : Json(nc.note);
            nj["solver"] = Json{{"method", "ADMM on (35) with the PSD constraints of (36)"},
                                {"iterations", nc.iterations},
                                {"constraint_residual", nc.primal_residual},
                                {"relative_fit_residual", nc.fit_residual}};
            nj["basis"] = "the states of A, B, C above (Sigma_ww depends on the similarity transform)";
            doc["noise_covariance"] = nj;
            if (!nc.detectable) std::fprintf(stderr, "msid fit: note: %s\n", nc.note.c_str());
        }
        // model FRF at the excited lines and a white-noise cost of the phasor residuals:
        // var(P_r) = 4 Xi_rr^0 / (K T) per complex phasor (white approximation)
        Json fr = Json::array();
        double V = 0, neq = 0;
        for (size_t l = 0; l < lines.size(); ++l) {
            const cd z = std::polar(1.0, 2.0 * M_PI * lines[l] / P);
            const MatC G = ss_eval(ss, z);
            Json e;
            e["bin"] = lines[l];
            e["freq"] = (double)lines[l] / P;
            e["omega"] = 2.0 * M_PI * lines[l] / P;
            e["G"] = cmat_json(G);
            e["cov"] = nullptr;
            if (do_refine && std::isfinite(ml.cov_factor)) {
                // E[dg dg^H] = C_aa + C_bb + j (C_ba - C_ab) from the real [Re vec G; Im vec G] covariance
                const MatR &Cr = ml.Gcov[l];
                const Eigen::Index g = Cr.rows() / 2;
                MatC Cc(g, g);
                Cc.real() = Cr.topLeftCorner(g, g) + Cr.bottomRightCorner(g, g);
                Cc.imag() = Cr.bottomLeftCorner(g, g) - Cr.topRightCorner(g, g);
                e["cov"] = cmat_json(Cc);
            }
            fr.push_back(e);
        }
        Json cost;
        const std::vector<uint32_t> &cb = bins;
        MatR Xi0;
        if (have_nc) {
            const Record &r0 = recs[0];
            const Correlations c0 = cissim_correlations(r0.data(), r0.n_rows, nu, ny, P, skip, 1);
            Xi0 = c0.Xi_rr[0] * ((double)c0.periods / (double)(c0.periods - 1));
        }
        if (Xi0.size() && Eigen::FullPivLU<MatR>(Xi0).rank() == (Eigen::Index)ny) {
            const MatR Xinv = Xi0.inverse();
            for (const auto &r : isp) {
                const double scale = (double)r.periods * P / 4.0;
                for (size_t l = 0; l < cb.size(); ++l) {
                    if (std::find(lines.begin(), lines.end(), cb[l]) == lines.end()) continue;
                    const cd z = std::polar(1.0, 2.0 * M_PI * cb[l] / P);
                    const VecC e = r.Y.col((Eigen::Index)l) - ss_eval(ss, z) * r.U.col((Eigen::Index)l);
                    const bool dc = cb[l] == 0;
                    V += (dc ? 0.5 : 1.0) * scale * (e.adjoint() * Xinv.cast<cd>() * e)(0, 0).real();
                    neq += (dc ? 1.0 : 2.0) * ny;
                }
            }
            cost["value"] = V;
            cost["expected"] = 0.5 * (neq - nparams);
            cost["dof"] = neq - nparams;
        } else {
            cost["value"] = 0.0;
            cost["expected"] = 0.0;
            cost["dof"] = 0.0;
        }
        cost["p_value"] = nullptr;
        cost["weight"] = "none";
        cost["note"] = "phasor residuals at --lines weighted by the white-noise phasor covariance 4 Xi_rr^0 / (K T); "
                       "no p-value (the input noise and coloured output noise are not in this weight)";
        doc["cost"] = cost;
        doc["cissim"] = cj;
        doc["frf"] = fr;
        add_modes(doc, true);
        write_json_file(out, doc);
        std::printf("wrote %s: cissim fit (%s set, %zu line(s), ISP by %s), order %d%s, block rows %d%s%s\n", out.c_str(),
                    reduced ? "reduced" : "full", bins.size(), isp[0].used_fft ? "FFT" : "direct products", n,
                    res.order_estimated ? " (estimated)" : "", res.block_rows,
                    do_refine ? fmt(", ML refined (cost %.4g -> %.4g, expected %.4g)", ml.cost_start, ml.cost, 0.5 * ml.dof).c_str() : "",
                    ss_stable(ss) ? "" : ", UNSTABLE");
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

}  // namespace msidcli
