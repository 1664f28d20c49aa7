// The input diagnostics of the shared FRF job (tools/msid/pipeline.cpp,
// FrfJob::finish -> check_periodic_lines, periodicity.cpp), the one every host
// path runs (msid frf on files, msid measure, msid modbus|can measure): records
// are pushed into the real core (msid_meas) exactly as the acquisition paths do.
// Monte Carlo with fixed seeds:
//  - a periodic multisine with white input noise at 0 dB and -10 dB input SNR
//    (errors-in-variables, 64 periods) is periodic: no refusal in 40 records
//    each, and the FRF is written;
//  - negative control: a white-noise input (not periodic) is refused in 40 of
//    40 records, naming the source and pointing at --method lpm;
//  - a multisine of period P + 1 read with period P: refused, the phase turn per
//    period at the strongest line named (about -360 b / (P + 1) degrees).
#include "periodicity.hpp"
#include "msid_frf_job.hpp"

#include <cmath>
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

namespace {

const uint32_t P = 256;
const std::vector<uint32_t> BINS = {20, 25, 30, 35, 40, 45, 50, 55, 60};

// Periodic multisine of period Q on BINS (unit power per line set), K*P samples.
std::vector<double> multisine(uint32_t Q, size_t n, std::mt19937_64 &g)
{
    std::uniform_real_distribution<double> ph(0, 2 * M_PI);
    std::vector<double> u(n, 0.0);
    for (uint32_t b : BINS) {
        const double p = ph(g);
        for (size_t t = 0; t < n; ++t) u[t] += std::cos(2 * M_PI * (double)b * (double)(t % Q) / Q + p);
    }
    return u;
}

// y = 0.5 u[t] + 0.3 u[t-1] (periodic continuation for t = 0) + output noise; rows [u, y].
std::vector<double> rows_of(const std::vector<double> &u, uint32_t Q, std::mt19937_64 &g)
{
    std::normal_distribution<double> nz(0, 0.01);
    std::vector<double> x(2 * u.size());
    for (size_t t = 0; t < u.size(); ++t) {
        const double um1 = t ? u[t - 1] : u[Q - 1];
        x[2 * t] = u[t];
        x[2 * t + 1] = 0.5 * u[t] + 0.3 * um1 + nz(g);
    }
    return x;
}

// The FRF job as msid modbus|can measure drive it: push the samples, finish. "" or the error.
std::string job(const std::vector<double> &x, uint32_t K)
{
    FrfRequest rq;
    rq.period = P;
    rq.bins = BINS;
    FrfJob j(rq, 1, 1, 1, K, K);
    msid_meas *ms = j.meas();
    if (msid_meas_begin(ms, 0) != MSID_OK) return "begin";
    if (msid_meas_push(ms, x.data(), (size_t)K * P) != MSID_OK) return "push";
    if (msid_meas_end(ms, nullptr) != MSID_OK) return "end";
    try {
        const FrfOutcome o = j.finish({{"sim:experiment 1", (uint64_t)K * P, K, 0}});
        return o.frf.n_lines() == BINS.size() ? "" : "lines";
    } catch (const Error &e) {
        return e.what();
    }
}

double power(const std::vector<double> &u)
{
    double s = 0;
    for (double v : u) s += v * v;
    return s / (double)u.size();
}

void noisy_input_is_periodic(void **)
{
    const uint32_t K = 64;   // the core wants >= 10 dB input SNR of the period mean at every line
    for (double snr_db : {0.0, -10.0}) {
        int refused = 0;
        for (int seed = 0; seed < 40; ++seed) {
            std::mt19937_64 g(1000 + seed);
            std::vector<double> u = multisine(P, (size_t)K * P, g);
            const double s = std::sqrt(power(u) / std::pow(10.0, snr_db / 10));
            std::normal_distribution<double> nz(0, s);
            std::vector<double> x = rows_of(u, P, g);
            for (size_t t = 0; t < u.size(); ++t) x[2 * t] += nz(g);   // measured input: errors in variables
            const std::string r = job(x, K);
            refused += !r.empty();
            if (!r.empty()) std::printf("  refused at %g dB (seed %d): %s\n", snr_db, seed, r.c_str());
        }
        std::printf("periodic input at %g dB input SNR: refused in %d of 40 records\n", snr_db, refused);
        assert_int_equal(refused, 0);
    }
}

void noise_input_is_refused(void **)
{
    const uint32_t K = 16;
    int refused = 0;
    for (int seed = 0; seed < 40; ++seed) {
        std::mt19937_64 g(2000 + seed);
        std::normal_distribution<double> nz(0, 1);
        std::vector<double> u((size_t)K * P);
        for (auto &v : u) v = nz(g);
        const std::string r = job(rows_of(u, P, g), K);
        const bool ok = r.find("'sim:experiment 1': the input is not periodic with period 256") == 0 &&
                        r.find("--method lpm") != std::string::npos;
        refused += ok;
        if (!ok) std::printf("  seed %d: '%s'\n", seed, r.c_str());
    }
    std::printf("white-noise input (negative control): refused in %d of 40 records\n", refused);
    assert_int_equal(refused, 40);
}

void wrong_period_turns(void **)
{
    const uint32_t K = 24;
    std::mt19937_64 g(3000);
    const std::vector<double> u = multisine(P + 1, (size_t)K * P, g);
    const std::string r = job(rows_of(u, P + 1, g), K);
    std::printf("period %u read as %u: %s\n", P + 1, P, r.c_str());
    assert_true(r.find("the input is not periodic with period 256") != std::string::npos);
    unsigned b = 0;
    double deg = 0;
    const size_t at = r.find("the input phase at bin ");
    assert_true(at != std::string::npos);
    assert_int_equal(std::sscanf(r.c_str() + at, "the input phase at bin %u turns by %lf degrees", &b, &deg), 2);
    double expect = std::remainder(-360.0 * b / (P + 1), 360.0);
    assert_true(std::fabs(deg - expect) < 0.05 * std::fabs(expect) + 0.5);
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(noisy_input_is_periodic),
        cmocka_unit_test(noise_input_is_refused),
        cmocka_unit_test(wrong_period_turns),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
