// The plant through the reference (msidacq::plant_through_reference, tools/acquire/reference_plant.cpp: what
// `msid measure --map` makes of the closed-loop preset's FRF from the reference r to the signals z) against
// theory and a computation written out here, not against itself:
//  - exact: for a discrete closed loop (plant G1 fed back through a PI controller C, a second output G2 that is
//    measured but not fed back), G_ur = C S, G_yr = G C S with S = 1 / (1 + G1 C); the plant returned equals G1
//    (SISO, z = [u, y]) and [G1; G2] (one input, two outputs, z = [y1, u, y2]: u not first) at every line to a
//    few rounding errors, and cov, cov_known_input and noise_cov equal the first-order propagation written
//    out per entry here (dG_a = (dG_{y_a r} - G_a dG_ur) / G_ur; the output error y_a - G_a u for noise_cov);
//    names, units, snr, input_snr, dof and the `reference` block follow the signals. A plant of two inputs
//    (two references) is refused: the function takes one reference.
//  - Monte Carlo (fixed seeds): G_zr perturbed by complex Gaussian noise of the line's covariance `cov` (what
//    the input document carries: the covariance of vec(G_zr), here the loop's fed-back sensor noise, rank one,
//    plus an independent part), at high SNR (noise 1e-3 of G_ur): the empirical covariance of the G returned
//    matches the returned covariance to within its sampling error at alpha 1e-3, and the 95% regions (the
//    covariance known exactly: chi-square, |e|^2 / v <= -ln 0.05 per entry, e^H V^-1 e <= 4.7439 for the pair)
//    cover within binomial bounds (alpha 1e-3). Negative control: the covariance without the G_ur term
//    (cov(G_yr) / |G_ur|^2, what dividing by an exact G_ur would give) fails both checks at every line where
//    that term moves a variance by more than 25% (two lines or more of each case).
//  - bad input: a line whose G_ur is 0, or so small that the plant or its covariance overflow, is refused
//    with a message naming its bin; nothing non-finite is returned.
#include "msid_mapped.hpp"

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

using msidacq::Json;
using cd = std::complex<double>;
using Mat = std::vector<std::vector<cd>>;   // row-major, written out: the test does its own algebra

namespace {

const uint32_t P = 64;
const std::vector<uint32_t> BINS = {1, 3, 5, 9, 15};

// The loop at bin k: plant G1 (fed back), G2 (measured only), PI controller C.
struct Loop {
    cd G1, G2, C, S;
};
Loop loop_at(uint32_t k)
{
    const cd z = std::polar(1.0, 2 * M_PI * k / P), zi = 1.0 / z;
    Loop l;
    l.G1 = 0.4 * zi / (1.0 - 0.7 * zi);
    l.G2 = (0.2 + 0.1 * zi) / (1.0 - 0.5 * zi);
    l.C = 0.8 + 0.3 * z / (z - 1.0);
    l.S = 1.0 / (1.0 + l.G1 * l.C);
    return l;
}

Json jm(const Mat &M)
{
    Json re = Json::array(), im = Json::array();
    for (const auto &row : M) {
        Json r = Json::array(), i = Json::array();
        for (cd x : row) {
            r.push_back(x.real());
            i.push_back(x.imag());
        }
        re.push_back(r);
        im.push_back(i);
    }
    return {{"re", re}, {"im", im}};
}
cd at(const Json &m, size_t i, size_t j) { return {m["re"][i][j].get<double>(), m["im"][i][j].get<double>()}; }
Mat col(const std::vector<cd> &v)
{
    Mat M;
    for (cd x : v) M.push_back({x});
    return M;
}

// A Hermitian positive definite n x n matrix: s^2 (v v^H + w B B^H) with B of a fixed seed, v the loop's
// fed-back noise direction.
Mat noise_cov(const std::vector<cd> &v, double s, double w, uint64_t seed)
{
    const size_t n = v.size();
    std::mt19937_64 g(seed);
    std::normal_distribution<double> N(0, 1);
    Mat B(n, std::vector<cd>(n)), C(n, std::vector<cd>(n));
    for (auto &r : B)
        for (cd &x : r) x = cd(N(g), N(g));
    for (size_t i = 0; i < n; ++i)
        for (size_t j = 0; j < n; ++j) {
            cd bb = 0;
            for (size_t q = 0; q < n; ++q) bb += B[i][q] * std::conj(B[j][q]);
            C[i][j] = s * s * (v[i] * std::conj(v[j]) + w * bb / (double)n);
        }
    return C;
}

// One line of the reference document: G_zr (n x 1) and its covariances, as the periodic FRF writes them.
struct RefLine {
    uint32_t bin;
    std::vector<cd> g;   // G_zr
    Mat cov;             // Cov vec(G_zr)
    Mat noise;           // the per-line noise covariance of one period's DFT of z
};

Json ref_doc(const std::vector<RefLine> &L, const std::vector<std::string> &names, const std::vector<std::string> &units)
{
    const size_t n = names.size();
    Json d = {{"format", "msid-frf/1"}, {"period_samples", P}, {"n_inputs", 1}, {"n_outputs", n},
              {"n_experiments", 1}, {"domain", "dt"}, {"input_names", {"Velocity target"}}, {"input_units", {"rad/s"}},
              {"output_names", names}, {"output_units", units}};
    Mat tn(n, std::vector<cd>(n, 0.0));
    Json lines = Json::array();
    for (const RefLine &l : L) {
        Json snr = Json::array();
        for (size_t i = 0; i < n; ++i) snr.push_back(40.0 + (double)i);
        lines.push_back({{"bin", l.bin}, {"freq", (double)l.bin / P}, {"G", jm(col(l.g))}, {"cov", jm(l.cov)},
                         {"dof", 7.0}, {"cov_known_input", jm(l.cov)}, {"dof_known_input", 7.0},
                         {"noise_cov", jm(l.noise)}, {"snr", snr}, {"cond", 1.0}, {"input_snr", nullptr}});
        for (size_t i = 0; i < n; ++i)
            for (size_t j = 0; j < n; ++j) tn[i][j] += l.noise[i][j] / (double)(P * L.size());
    }
    d["noise_cov"] = jm(tn);
    d["lines"] = lines;
    d["detection_lines"] = Json::array({{{"bin", 2}}});
    d["nonlinear_distortion"] = Json::object();
    return d;
}

// The first-order covariance of the plant [G_a] = [g_{y_a} / g_u] from Cov(g) = V, written out:
// Cov(G_a, G_b) = (V_ab - conj(G_b) V_au - G_a V_ub + G_a conj(G_b) V_uu) / |g_u|^2 (scale = 1 / |g_u|^2),
// and with scale 1 the same for the output error y_a - G_a u.
Mat propagate(const std::vector<cd> &g, const Mat &V, uint32_t u, bool divide)
{
    std::vector<uint32_t> y;
    for (uint32_t i = 0; i < g.size(); ++i)
        if (i != u) y.push_back(i);
    const double s = divide ? 1.0 / std::norm(g[u]) : 1.0;
    Mat R(y.size(), std::vector<cd>(y.size()));
    for (size_t a = 0; a < y.size(); ++a)
        for (size_t b = 0; b < y.size(); ++b) {
            const cd Ga = g[y[a]] / g[u], Gb = g[y[b]] / g[u];
            R[a][b] = s * (V[y[a]][y[b]] - std::conj(Gb) * V[y[a]][u] - Ga * V[u][y[b]] + Ga * std::conj(Gb) * V[u][u]);
        }
    return R;
}

// The reference lines of the loop: z = [u, y1] (SISO) or [y1, u, y2]; cov for the period means of K periods.
std::vector<RefLine> loop_lines(bool simo, double rel_noise)
{
    std::vector<RefLine> L;
    for (uint32_t k : BINS) {
        const Loop l = loop_at(k);
        const cd cs = l.C * l.S;
        // the fed-back sensor noise n on y1 moves z by [-C S, S] n (y2 not at all)
        std::vector<cd> g, v;
        if (!simo) {
            g = {cs, l.G1 * cs};
            v = {-cs, l.S};
        } else {
            g = {l.G1 * cs, cs, l.G2 * cs};
            v = {l.S, -cs, 0.0};
        }
        const double s = rel_noise * std::abs(cs);
        RefLine r{k, g, noise_cov(v, s, 1.0, 100 + k), {}};
        r.noise = noise_cov(v, s * 3.0, 1.0, 200 + k);   // one period's: K = 9 periods
        L.push_back(r);
    }
    return L;
}

double ulps(cd a, cd b) { return std::abs(a - b) / (std::abs(b) * 2.220446049250313e-16); }

void expect_cov(const Json &m, const Mat &R, double rel)
{
    for (size_t a = 0; a < R.size(); ++a)
        for (size_t b = 0; b < R.size(); ++b) {
            const double sc = std::sqrt(R[a][a].real() * R[b][b].real());
            if (std::abs(at(m, a, b) - R[a][b]) > rel * sc) {
                std::printf("  entry (%zu, %zu): %.17g%+.17gj, expected %.17g%+.17gj\n", a, b, at(m, a, b).real(),
                            at(m, a, b).imag(), R[a][b].real(), R[a][b].imag());
                fail();
            }
        }
}

void exact_siso(void **)
{
    const std::vector<RefLine> L = loop_lines(false, 1e-2);
    const Json ref = ref_doc(L, {"Torque demand", "Velocity actual"}, {"N m", "rad/s"});
    const Json d = msidacq::plant_through_reference(ref, 0);
    assert_int_equal(d["n_inputs"].get<int>(), 1);
    assert_int_equal(d["n_outputs"].get<int>(), 1);
    assert_true(d["input_names"] == Json::array({"Torque demand"}));
    assert_true(d["input_units"] == Json::array({"N m"}));
    assert_true(d["output_names"] == Json::array({"Velocity actual"}));
    assert_true(d["output_units"] == Json::array({"rad/s"}));
    assert_false(d.contains("detection_lines") || d.contains("nonlinear_distortion"));
    assert_true(d["reference"]["signal"] == "Velocity target" && d["reference"]["input"] == "Torque demand");
    assert_int_equal(d["lines"].size(), BINS.size());
    double worst = 0;
    for (size_t q = 0; q < L.size(); ++q) {
        const Json &e = d["lines"][q];
        const Loop l = loop_at(BINS[q]);
        assert_int_equal(e["bin"].get<uint32_t>(), BINS[q]);
        const double ul = ulps(at(e["G"], 0, 0), l.G1);
        worst = std::max(worst, ul);
        assert_true(ul <= 8);   // G1 C S / C S: three roundings
        expect_cov(e["cov"], propagate(L[q].g, L[q].cov, 0, true), 1e-13);
        expect_cov(e["cov_known_input"], propagate(L[q].g, L[q].cov, 0, true), 1e-13);
        expect_cov(e["noise_cov"], propagate(L[q].g, L[q].noise, 0, false), 1e-13);
        assert_true(e["dof"].get<double>() == 7.0 && e["dof_known_input"].get<double>() == 7.0);
        assert_true(e["snr"] == Json::array({41.0}));
        const double isnr = 10 * std::log10(std::norm(L[q].g[0]) / L[q].cov[0][0].real());
        assert_true(std::fabs(e["input_snr"].get<double>() - isnr) <= 1e-12);
    }
    assert_true(std::fabs(at(d["noise_cov"], 0, 0).real() - at(ref["noise_cov"], 1, 1).real()) == 0);
    std::printf("SISO: G = G1 at %zu lines to %.1f ulp\n", L.size(), worst);
}

void exact_simo(void **)
{
    const std::vector<RefLine> L = loop_lines(true, 1e-2);
    const Json ref = ref_doc(L, {"Velocity actual", "Torque demand", "Position actual"}, {"rad/s", "N m", "rad"});
    const Json d = msidacq::plant_through_reference(ref, 1);
    assert_int_equal(d["n_outputs"].get<int>(), 2);
    assert_true(d["input_names"] == Json::array({"Torque demand"}));
    assert_true(d["output_names"] == Json::array({"Velocity actual", "Position actual"}));
    assert_true(d["output_units"] == Json::array({"rad/s", "rad"}));
    double worst = 0;
    for (size_t q = 0; q < L.size(); ++q) {
        const Json &e = d["lines"][q];
        const Loop l = loop_at(BINS[q]);
        worst = std::max({worst, ulps(at(e["G"], 0, 0), l.G1), ulps(at(e["G"], 1, 0), l.G2)});
        assert_true(ulps(at(e["G"], 0, 0), l.G1) <= 8 && ulps(at(e["G"], 1, 0), l.G2) <= 8);
        expect_cov(e["cov"], propagate(L[q].g, L[q].cov, 1, true), 1e-13);
        expect_cov(e["noise_cov"], propagate(L[q].g, L[q].noise, 1, false), 1e-13);
        assert_true(e["snr"] == Json::array({40.0, 42.0}));
    }
    std::printf("one input, two outputs: G = [G1; G2] at %zu lines to %.1f ulp\n", L.size(), worst);
    // two references (a 2x2 plant) are not what the function takes: refused, not misread
    Json two = ref;
    two["n_inputs"] = 2;
    bool refused = false;
    try {
        msidacq::plant_through_reference(two, 1);
    } catch (const msidacq::Error &e) {
        refused = std::string(e.what()).find("one reference") != std::string::npos;
    }
    assert_true(refused);
}

// Exact binomial bounds [lo, hi] of the count of N trials of probability p, each tail alpha / 2.
void binomial_bounds(long N, double p, double alpha, long &lo, long &hi)
{
    std::vector<double> pmf(N + 1);
    for (long k = 0; k <= N; ++k)
        pmf[k] = std::exp(std::lgamma(N + 1.0) - std::lgamma(k + 1.0) - std::lgamma(N - k + 1.0) + k * std::log(p) +
                          (N - k) * std::log1p(-p));
    double c = 0;
    for (lo = 0; c + pmf[lo] <= alpha / 2; ++lo) c += pmf[lo];
    c = 0;
    for (hi = N; c + pmf[hi] <= alpha / 2; --hi) c += pmf[hi];
}

// Per line: the empirical covariance of the returned G against a covariance V (n x n), within the
// sampling error of N draws: |S_ab - V_ab| <= 3.3 sqrt(V_aa V_bb / N) (alpha 1e-3 for the real diagonal,
// below it for the complex off-diagonal entries).
bool cov_matches(const std::vector<std::vector<cd>> &E, const Mat &V)
{
    const size_t n = V.size(), N = E.size();
    for (size_t a = 0; a < n; ++a)
        for (size_t b = 0; b < n; ++b) {
            cd s = 0;
            for (const auto &e : E) s += e[a] * std::conj(e[b]);
            s /= (double)N;
            if (std::abs(s - V[a][b]) > 3.3 * std::sqrt(V[a][a].real() * V[b][b].real() / (double)N)) return false;
        }
    return true;
}

// e^H V^-1 e for n = 1, 2
double quad(const std::vector<cd> &e, const Mat &V)
{
    if (V.size() == 1) return std::norm(e[0]) / V[0][0].real();
    const cd det = V[0][0] * V[1][1] - V[0][1] * V[1][0];
    const cd q = (std::conj(e[0]) * (V[1][1] * e[0] - V[0][1] * e[1]) + std::conj(e[1]) * (V[0][0] * e[1] - V[1][0] * e[0])) / det;
    return q.real();
}

void monte_carlo(bool simo)
{
    const long N = 20000;
    const uint32_t u = simo ? 1 : 0;
    const std::vector<RefLine> L = loop_lines(simo, 1e-3);
    const std::vector<std::string> names = simo ? std::vector<std::string>{"y1", "u", "y2"} : std::vector<std::string>{"u", "y1"};
    Json ref = ref_doc(L, names, std::vector<std::string>(names.size(), ""));
    const size_t n = names.size(), ny = n - 1;
    // Cholesky factors of the line covariances: z = g + Lc w, w ~ CN(0, I)
    std::vector<Mat> Lc;
    for (const RefLine &l : L) {
        Mat C(n, std::vector<cd>(n, 0.0));
        for (size_t j = 0; j < n; ++j) {
            cd s = l.cov[j][j];
            for (size_t q = 0; q < j; ++q) s -= C[j][q] * std::conj(C[j][q]);
            C[j][j] = std::sqrt(s.real());
            for (size_t i = j + 1; i < n; ++i) {
                cd t = l.cov[i][j];
                for (size_t q = 0; q < j; ++q) t -= C[i][q] * std::conj(C[j][q]);
                C[i][j] = t / C[j][j].real();
            }
        }
        Lc.push_back(C);
    }
    std::vector<std::vector<std::vector<cd>>> err(L.size());   // [line][trial][output]
    std::vector<long> in(L.size(), 0), in_wrong(L.size(), 0), in_entry(L.size(), 0);
    std::vector<Mat> wrong;   // Cov(G_yr) / |G_ur|^2: the G_ur term left out
    for (const RefLine &l : L) {
        Mat W(ny, std::vector<cd>(ny));
        std::vector<uint32_t> y;
        for (uint32_t i = 0; i < n; ++i)
            if (i != u) y.push_back(i);
        for (size_t a = 0; a < ny; ++a)
            for (size_t b = 0; b < ny; ++b) W[a][b] = l.cov[y[a]][y[b]] / std::norm(l.g[u]);
        wrong.push_back(W);
    }
    const double q1 = -std::log(0.05), q2 = 4.743864518;   // chi-square(2) / 2, chi-square(4) / 2 at 95%
    assert_true(std::fabs((1 + q2) * std::exp(-q2) - 0.05) < 1e-9);
    std::mt19937_64 g(simo ? 4242 : 4141);
    std::normal_distribution<double> N01(0, std::sqrt(0.5));
    for (long t = 0; t < N; ++t) {
        for (size_t q = 0; q < L.size(); ++q) {
            std::vector<cd> w(n), z = L[q].g;
            for (cd &x : w) x = cd(N01(g), N01(g));
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j <= i; ++j) z[i] += Lc[q][i][j] * w[j];
            ref["lines"][q]["G"] = jm(col(z));
        }
        const Json d = msidacq::plant_through_reference(ref, u);
        for (size_t q = 0; q < L.size(); ++q) {
            const Json &e = d["lines"][q];
            const Loop l = loop_at(BINS[q]);
            const std::vector<cd> G0 = simo ? std::vector<cd>{l.G1, l.G2} : std::vector<cd>{l.G1};
            std::vector<cd> ev(ny);
            Mat V(ny, std::vector<cd>(ny));
            for (size_t a = 0; a < ny; ++a) {
                ev[a] = at(e["G"], a, 0) - G0[a];
                for (size_t b = 0; b < ny; ++b) V[a][b] = at(e["cov"], a, b);
            }
            err[q].push_back(ev);
            in[q] += quad(ev, V) <= (simo ? q2 : q1);
            in_wrong[q] += quad(ev, wrong[q]) <= (simo ? q2 : q1);
            in_entry[q] += std::norm(ev[ny - 1]) / V[ny - 1][ny - 1].real() <= q1;
        }
    }
    long lo, hi;
    binomial_bounds(N, 0.95, 1e-3, lo, hi);
    std::printf("%s, %ld draws per line, binomial bounds [%ld, %ld]:\n", simo ? "one input, two outputs" : "SISO", N, lo, hi);
    int controls = 0;
    for (size_t q = 0; q < L.size(); ++q) {
        const Mat R = propagate(L[q].g, L[q].cov, u, true);
        const bool ok = cov_matches(err[q], R), ok_wrong = cov_matches(err[q], wrong[q]);
        const double v_emp = [&] {
            double s = 0;
            for (const auto &e : err[q]) s += std::norm(e[0]);
            return s / (double)N;
        }();
        std::printf("  bin %2u: var(G_1) empirical / returned %.4f (without the G_ur term %.4f); coverage %.4f "
                    "(last entry %.4f), without the G_ur term %.4f\n",
                    BINS[q], v_emp / R[0][0].real(), v_emp / wrong[q][0][0].real(), (double)in[q] / N,
                    (double)in_entry[q] / N, (double)in_wrong[q] / N);
        assert_true(ok);
        assert_true(in[q] >= lo && in[q] <= hi);
        assert_true(in_entry[q] >= lo && in_entry[q] <= hi);
        // the negative control: where the G_ur term moves a variance by more than 25% (by the formulas, not
        // the draws; at the higher lines |S| is near 1 and G small, so it hardly matters there), the same
        // draws reject the covariance without it
        double moved = 0;
        for (size_t a = 0; a < ny; ++a) moved = std::max(moved, std::fabs(wrong[q][a][a].real() / R[a][a].real() - 1));
        if (moved > 0.25) {
            ++controls;
            assert_false(ok_wrong);
            assert_false(in_wrong[q] >= lo && in_wrong[q] <= hi);
        }
    }
    assert_true(controls >= 2);
}

void monte_carlo_siso(void **) { monte_carlo(false); }
void monte_carlo_simo(void **) { monte_carlo(true); }

// The message of plant_through_reference on ref, "" if it returned; what it returned must be finite.
std::string refusal(const Json &ref, uint32_t u)
{
    try {
        const Json d = msidacq::plant_through_reference(ref, u);
        for (const Json &e : d["lines"])
            for (const char *k : {"G", "cov", "noise_cov"})
                for (const char *p : {"re", "im"})
                    for (const Json &r : e[k][p])
                        for (const Json &x : r) assert_true(x.is_number() && std::isfinite(x.get<double>()));
        return "";
    } catch (const msidacq::Error &e) {
        return e.what();
    }
}

void bad_input(void **)
{
    const std::vector<RefLine> L = loop_lines(false, 1e-2);
    const Json ref = ref_doc(L, {"Torque demand", "Velocity actual"}, {"N m", "rad/s"});
    assert_string_equal(refusal(ref, 0).c_str(), "");
    // G_ur at bin 5 (the third line): 0, tiny (the covariance overflows), subnormal (1 / G_ur overflows)
    for (double gu : {0.0, 1e-200, 4e-320, -1e-170}) {
        Json r = ref;
        r["lines"][2]["G"]["re"][0][0] = gu;
        r["lines"][2]["G"]["im"][0][0] = 0.0;
        const std::string m = refusal(r, 0);
        std::printf("G_ur = %g at bin 5: %s\n", gu, m.c_str());
        assert_true(m.rfind("bin 5: ", 0) == 0);
        assert_true(m.find("G_ur") != std::string::npos);
    }
    // a small G_ur whose plant is still finite is the line's input_snr (far below 10 dB), not a refusal
    Json r = ref;
    r["lines"][2]["G"]["re"][0][0] = 1e-6;
    r["lines"][2]["G"]["im"][0][0] = 0.0;
    assert_string_equal(refusal(r, 0).c_str(), "");
    assert_true(msidacq::plant_through_reference(r, 0)["lines"][2]["input_snr"].get<double>() < -10);
    // the input among the signals, and two or more of them
    assert_true(refusal(ref, 2).find("one reference") != std::string::npos);
}

}  // namespace

int main()
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(exact_siso),
        cmocka_unit_test(exact_simo),
        cmocka_unit_test(monte_carlo_siso),
        cmocka_unit_test(monte_carlo_simo),
        cmocka_unit_test(bad_input),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
