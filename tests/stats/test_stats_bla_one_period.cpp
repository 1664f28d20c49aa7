// The best linear approximation from R random-phase realisations of ONE period each
// (msid frf --realisations R on the nonlinear-benchmark layout), through the FRF job
// (estimate_frf: records -> core -> total_only in tools/frfjob/frf_bla.cpp), Monte Carlo
// with fixed seeds:
//  - SISO Wiener system: G(z) = (0.5 + 0.3 z^-1) / (1 - 0.6 z^-1), then y = x + a x^3, plus
//    white output noise; a random-phase multisine of 60 lines with equal amplitudes. The true
//    BLA is analytic (below). For R = 4, 10 and 20, 200 runs each: the 95% regions of the file
//    (|G - G_BLA|^2 / v <= F(2, 2 dof) quantile, dof = R - 1) cover the true BLA about 95% of
//    the run x line trials, and the reported variance matches the spread of G over the runs.
//  - negative controls on the same runs: the covariance without its 1/R (the spread of one
//    realisation's FRF) over-covers, the asymptotic chi-square region (dof infinite) and dof = R
//    under-cover at R = 4: the test can fail.
//  - 2x2 (two experiments per realisation, the DFT pattern [1 1; 1 -1] of fresh random-phase
//    multisines, a cubic on each output), R = 10: the same coverage and variance per entry, the true
//    BLA from 5000 noise-free realisations computed here with an independent per-realisation
//    solve Y U^-1.
#include "msid_frf_job.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <random>
#include <string>
#include <vector>
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
}

using namespace msidjob;
using cd = std::complex<double>;

namespace {

const uint32_t P = 256;
const uint32_t L = 60;           // lines 1..60: x^3 reaches bin 180 < P - 60, no alias at a line
const double A = std::sqrt(2.0 / L);   // cosine amplitude per line: input RMS 1
const double NOISE = 0.2;        // output noise standard deviation: the noise is about 1/7 of the total

std::vector<uint32_t> bins()
{
    std::vector<uint32_t> b;
    for (uint32_t k = 1; k <= L; ++k) b.push_back(k);
    return b;
}

cd plant(double w) { const cd z = std::polar(1.0, -w); return (0.5 + 0.3 * z) / (1.0 - 0.6 * z); }

// The periodic steady state of a signal with complex amplitudes X[k] at bin k + 1 (cosines:
// x[t] = sum_k |X_k| cos(w_k t + arg X_k)).
std::vector<double> synth(const std::vector<cd> &X)
{
    std::vector<double> x(P, 0.0);
    for (uint32_t k = 0; k < L; ++k)
        for (uint32_t t = 0; t < P; ++t) x[t] += std::real(X[k] * std::polar(1.0, 2 * M_PI * (k + 1) * (double)t / P));
    return x;
}

double cubic(double x, double a) { return x + a * x * x * x; }

Record record(const std::string &name, uint32_t nu, uint32_t ny, const std::vector<std::vector<double>> &cols)
{
    Record r;
    r.path = name;
    r.nu = nu;
    r.ny = ny;
    r.n_rows = P;
    r.rows.resize((size_t)P * (nu + ny));
    for (uint32_t t = 0; t < P; ++t)
        for (uint32_t c = 0; c < nu + ny; ++c) r.rows[(size_t)t * (nu + ny) + c] = cols[c][t];
    for (uint32_t j = 0; j < nu; ++j) r.columns.push_back("u" + std::to_string(j + 1));
    for (uint32_t i = 0; i < ny; ++i) r.columns.push_back("y" + std::to_string(i + 1));
    return r;
}

cd jc(const Json &m, size_t i, size_t j) { return {m["re"][i][j].get<double>(), m["im"][i][j].get<double>()}; }

FrfOutcome bla(const std::vector<Record> &recs, uint32_t R)
{
    FrfRequest rq;
    rq.period = P;
    rq.bins = bins();
    FrfPlan plan;
    plan.bla = true;
    plan.realisations = R;
    return estimate_frf(rq, recs, plan);
}

// Coverage counters of one setting: trials, covered with the file's law, and with the controls.
struct Tally {
    long n = 0, cov = 0, no_div_r = 0, chi2 = 0, dof_r = 0;
    double var_reported = 0, var_spread = 0;   // summed over lines (entries)
    void add(cd G, cd Gt, double v, double dof, double R)
    {
        const double t = std::norm(G - Gt) / v;
        auto q = [](double n) { return n * std::expm1(-std::log(0.05) / n); };   // F(2, 2n) 95% quantile
        ++n;
        cov += t <= q(dof);
        no_div_r += t / R <= q(dof);
        chi2 += t <= -std::log(0.05);
        dof_r += t <= q(dof + 1);
    }
    double c(long k) const { return (double)k / (double)n; }
};

void siso_coverage(void **)
{
    const double a = 0.08;
    std::vector<cd> Gl(L), Gbla(L);
    double sx2 = 0;
    for (uint32_t k = 0; k < L; ++k) {
        Gl[k] = plant(2 * M_PI * (k + 1) / P);
        sx2 += A * A * std::norm(Gl[k]) / 2;
    }
    // x = sum_k (X_k e^{j w_k t} + cc) with X_k = A G_k e^{j phi_k} / 2 and independent uniform phases:
    // the part of (x^3)_k coherent with U_k comes from the index triples {k, l, -l}: 6 X_k |X_l|^2
    // for l != k and 3 X_k |X_k|^2, so G_BLA,k = G_k (1 + 3 a (sigma_x^2 - |X_k|^2)).
    for (uint32_t k = 0; k < L; ++k) Gbla[k] = Gl[k] * (1.0 + 3 * a * (sx2 - A * A * std::norm(Gl[k]) / 4));
    const int RUNS = 200;
    for (uint32_t R : {4u, 10u, 20u}) {
        Tally T;
        std::vector<std::vector<cd>> Gruns;
        std::vector<double> vsum(L, 0.0);
        std::mt19937_64 g(7000 + R);
        std::uniform_real_distribution<double> ph(0, 2 * M_PI);
        std::normal_distribution<double> nz(0, NOISE);
        double nl_over_noise = 0;
        for (int run = 0; run < RUNS; ++run) {
            std::vector<Record> recs;
            for (uint32_t r = 0; r < R; ++r) {
                std::vector<cd> U(L), X(L);
                for (uint32_t k = 0; k < L; ++k) {
                    U[k] = std::polar(A, ph(g));
                    X[k] = Gl[k] * U[k];
                }
                const std::vector<double> u = synth(U), x = synth(X);
                std::vector<double> y(P);
                for (uint32_t t = 0; t < P; ++t) y[t] = cubic(x[t], a) + nz(g);
                recs.push_back(record("sim:run" + std::to_string(run) + "r" + std::to_string(r), 1, 1, {u, y}));
            }
            const FrfOutcome o = bla(recs, R);
            const Json &lines = o.doc["lines"];
            assert_int_equal(lines.size(), L);
            assert_false(o.doc.contains("noise_cov"));
            assert_false(lines[0].contains("cov_known_input") || lines[0].contains("noise_cov"));
            std::vector<cd> G(L);
            for (uint32_t k = 0; k < L; ++k) {
                const Json &e = lines[k];
                assert_true(e["dof"].get<double>() == R - 1.0);
                G[k] = jc(e["G"], 0, 0);
                const double v = e["cov"]["re"][0][0].get<double>();
                vsum[k] += v;
                T.add(G[k], Gbla[k], v, R - 1.0, R);
                // the noise part of v: NOISE^2 P / |U_k|^2 / R with |U_k| = A P / 2
                nl_over_noise += v / (NOISE * NOISE * P / (A * A * P * P / 4) / R) / (RUNS * L);
            }
            Gruns.push_back(G);
        }
        for (uint32_t k = 0; k < L; ++k) {
            double s = 0;
            for (const auto &G : Gruns) s += std::norm(G[k] - Gbla[k]);
            T.var_spread += s / RUNS;
            T.var_reported += vsum[k] / RUNS;
        }
        const double ratio = T.var_reported / T.var_spread;
        std::printf("SISO R = %2u, %d runs x %u lines (total / noise variance %.1f): coverage %.4f (95%%), reported / "
                    "empirical variance %.3f; controls: cov x R %.4f, chi-square %.4f, dof = R %.4f\n",
                    R, RUNS, L, nl_over_noise, T.c(T.cov), ratio, T.c(T.no_div_r), T.c(T.chi2), T.c(T.dof_r));
        // 12000 trials: binomial sd 0.002; lines of a run share the realisations, so 3x that margin
        assert_true(std::fabs(T.c(T.cov) - 0.95) <= 0.01);
        assert_true(std::fabs(ratio - 1.0) <= 0.06);
        assert_true(nl_over_noise > 3.0);   // the distortion dominates: the total is tested, not the noise
        assert_true(T.c(T.no_div_r) > 0.985);
        if (R == 4) {
            assert_true(T.c(T.chi2) < 0.90);
            assert_true(T.c(T.dof_r) < 0.945);
        }
    }
}

void mimo_2x2_coverage(void **)
{
    const double a = 0.05;
    const uint32_t R = 10;
    std::vector<cd> G[2][2];
    for (uint32_t k = 0; k < L; ++k) {
        const double w = 2 * M_PI * (k + 1) / P;
        const cd z = std::polar(1.0, -w);
        G[0][0].push_back(plant(w));
        G[0][1].push_back(0.4 * z / (1.0 - 0.5 * z));
        G[1][0].push_back(0.3 / (1.0 + 0.4 * z));
        G[1][1].push_back((0.6 - 0.2 * z) / (1.0 - 0.3 * z));
    }
    // one realisation: experiments e = 0, 1 with inputs (s1, s2) and (s1, -s2); outputs, and the
    // realisation's FRF per line by Y U^-1 from the exact DFT of the samples (independent of msid)
    std::uniform_real_distribution<double> ph(0, 2 * M_PI);
    auto realisation = [&](std::mt19937_64 &g, double noise, std::vector<std::vector<std::vector<double>>> &cols,
                           std::vector<Eigen::Matrix2cd> *Gr) {
        std::normal_distribution<double> nz(0, 1.0);
        std::vector<cd> S1(L), S2(L);
        for (uint32_t k = 0; k < L; ++k) {
            S1[k] = std::polar(A, ph(g));
            S2[k] = std::polar(A, ph(g));
        }
        cols.clear();
        std::vector<Eigen::Matrix2cd> Yd(L), Ud(L);
        for (int e = 0; e < 2; ++e) {
            const double sg = e ? -1.0 : 1.0;
            std::vector<cd> U2(L), X1(L), X2(L);
            for (uint32_t k = 0; k < L; ++k) {
                U2[k] = sg * S2[k];
                X1[k] = G[0][0][k] * S1[k] + G[0][1][k] * U2[k];
                X2[k] = G[1][0][k] * S1[k] + G[1][1][k] * U2[k];
            }
            std::vector<double> u1 = synth(S1), u2 = synth(U2), x1 = synth(X1), x2 = synth(X2), y1(P), y2(P);
            for (uint32_t t = 0; t < P; ++t) {
                y1[t] = cubic(x1[t], a) + (noise > 0 ? noise * nz(g) : 0.0);
                y2[t] = cubic(x2[t], a) + (noise > 0 ? noise * nz(g) : 0.0);
            }
            if (Gr) {
                for (uint32_t k = 0; k < L; ++k) {
                    cd d[4] = {0, 0, 0, 0};
                    for (uint32_t t = 0; t < P; ++t) {
                        const cd wt = std::polar(1.0, -2 * M_PI * (k + 1) * (double)t / P);
                        d[0] += u1[t] * wt;
                        d[1] += u2[t] * wt;
                        d[2] += y1[t] * wt;
                        d[3] += y2[t] * wt;
                    }
                    Ud[k](0, e) = d[0];
                    Ud[k](1, e) = d[1];
                    Yd[k](0, e) = d[2];
                    Yd[k](1, e) = d[3];
                }
            }
            cols.push_back({u1, u2, y1, y2});
        }
        if (Gr)
            for (uint32_t k = 0; k < L; ++k) (*Gr)[k] = Yd[k] * Ud[k].inverse();
    };
    // the true BLA of this design: the mean of 5000 noise-free realisations' FRFs (its own error is
    // sqrt(R / 5000) = 0.045 of the standard deviation of the R-realisation BLA)
    std::vector<Eigen::Matrix2cd> Gt(L, Eigen::Matrix2cd::Zero()), Gr(L);
    {
        std::mt19937_64 g(9100);
        std::vector<std::vector<std::vector<double>>> cols;
        const int NB = 5000;
        for (int r = 0; r < NB; ++r) {
            realisation(g, 0.0, cols, &Gr);
            for (uint32_t k = 0; k < L; ++k) Gt[k] += Gr[k] / (double)NB;
        }
    }
    Tally T;
    const int RUNS = 100;
    std::mt19937_64 g(9200);
    std::vector<double> vrep(4 * L, 0.0), spread(4 * L, 0.0);
    for (int run = 0; run < RUNS; ++run) {
        std::vector<Record> recs;
        std::vector<std::vector<std::vector<double>>> cols;
        for (uint32_t r = 0; r < R; ++r) {
            realisation(g, NOISE, cols, nullptr);
            for (int e = 0; e < 2; ++e)
                recs.push_back(record("sim:r" + std::to_string(r) + "e" + std::to_string(e), 2, 2, cols[e]));
        }
        const FrfOutcome o = bla(recs, R);
        const Json &lines = o.doc["lines"];
        for (uint32_t k = 0; k < L; ++k) {
            const Json &e = lines[k];
            assert_true(e["dof"].get<double>() == R - 1.0);
            for (int j = 0; j < 2; ++j)
                for (int i = 0; i < 2; ++i) {
                    const int v = i + 2 * j;   // vec index
                    const double var = e["cov"]["re"][v][v].get<double>();
                    const cd Gh = jc(e["G"], i, j);
                    T.add(Gh, Gt[k](i, j), var, R - 1.0, R);
                    vrep[4 * k + v] += var / RUNS;
                    spread[4 * k + v] += std::norm(Gh - Gt[k](i, j)) / RUNS;
                }
        }
    }
    for (size_t q = 0; q < vrep.size(); ++q) {
        T.var_reported += vrep[q];
        T.var_spread += spread[q];
    }
    const double ratio = T.var_reported / T.var_spread;
    std::printf("2x2 R = %u, %d runs x %u lines x 4 entries: coverage %.4f (95%%), reported / empirical variance %.3f; "
                "controls: cov x R %.4f, chi-square %.4f, dof = R %.4f\n",
                R, RUNS, L, T.c(T.cov), ratio, T.c(T.no_div_r), T.c(T.chi2), T.c(T.dof_r));
    assert_true(std::fabs(T.c(T.cov) - 0.95) <= 0.01);
    assert_true(std::fabs(ratio - 1.0) <= 0.06);
    assert_true(T.c(T.no_div_r) > 0.985);
}

}  // namespace

int main()
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(siso_coverage),
        cmocka_unit_test(mimo_2x2_coverage),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
