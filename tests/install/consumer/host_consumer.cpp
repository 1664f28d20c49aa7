// Out-of-tree consumer of the installed host libraries (msid::frfjob over msid::records): the FRF job on
// samples held in memory, no file and no command line. The plant is y[n] = b u[n] + a y[n-1] (b = 0.5,
// a = 0.6) driven by a 6-line multisine in steady state, plus a small deterministic disturbance: the
// estimate must equal G(e^{j w}) = b / (1 - a e^{-j w}) at every line within the disturbance's effect.
#include "msid_frf_job.hpp"
#ifdef MSID_CONSUMER_FIT
#include "msid_fit_job.hpp"
#endif

#include <cmath>
#include <complex>
#include <cstdio>

int main()
{
    const uint32_t P = 64, K = 6;
    const std::vector<uint32_t> bins = {1, 2, 3, 5, 8, 13};
    const double b = 0.5, a = 0.6, pi = std::acos(-1.0);
    msidrec::Record r;
    r.path = "memory";
    r.nu = 1;
    r.ny = 1;
    r.n_rows = (size_t)P * K;
    r.rows.resize(r.n_rows * 2);
    uint32_t lcg = 12345;
    for (size_t n = 0; n < r.n_rows; ++n) {
        double u = 0, y = 0;
        for (uint32_t k : bins) {
            const double w = 2 * pi * k / P, ph = 0.7 * k * k;   // Schroeder-like phases
            const std::complex<double> G = b / (1.0 - a * std::polar(1.0, -w));
            u += std::cos(w * (double)(n % P) + ph);
            y += std::abs(G) * std::cos(w * (double)(n % P) + ph + std::arg(G));
        }
        lcg = lcg * 1664525u + 1013904223u;
        r.rows[2 * n] = u;
        r.rows[2 * n + 1] = y + 1e-6 * ((double)(lcg >> 8) / (1u << 24) - 0.5);
    }
    msidjob::FrfRequest rq;
    rq.period = P;
    rq.bins = bins;
    msidjob::FrfPlan plan;
    try {
        msidjob::FrfOutcome o = msidjob::estimate_frf(rq, {r}, plan);
        const auto &lines = o.tree().at("lines");
        if (lines.size() != bins.size()) { std::fprintf(stderr, "host consumer: %zu lines\n", lines.size()); return 1; }
        for (size_t l = 0; l < bins.size(); ++l) {
            const double w = 2 * pi * bins[l] / P;
            const std::complex<double> G0 = b / (1.0 - a * std::polar(1.0, -w));
            const std::complex<double> G(lines[l]["G"]["re"][0][0].get<double>(), lines[l]["G"]["im"][0][0].get<double>());
            if (std::abs(G - G0) > 1e-4 * std::abs(G0)) {
                std::fprintf(stderr, "host consumer: line %u: G = %g%+gj, expected %g%+gj\n", bins[l], G.real(), G.imag(),
                             G0.real(), G0.imag());
                return 1;
            }
        }
#ifdef MSID_CONSUMER_FIT
        // msid::fitjob: a first-order model of that FRF (A is 1 x 1: its pole), at a
        msidfitjob::FitRequest fr;
        fr.method = "ml";
        fr.order = "1";
        const msidfitjob::FitOutcome fit = msidfitjob::fit_frf(msidfrf::parse_frf(o.doc, "memory"), fr);
        const auto &A = fit.model.at("A");
        if (A.size() != 1 || std::abs(A[0][0].get<double>() - a) > 1e-4) {
            std::fprintf(stderr, "host consumer: fitted A = %s, expected %g\n", A.dump().c_str(), a);
            return 1;
        }
#endif
    } catch (const std::exception &e) {   // msidutil::Error, and msidfrf::Error of the FRF reader
        std::fprintf(stderr, "host consumer: %s\n", e.what());
        return 1;
    }
    // the library's error type carries msid's message: a record of one period cannot give a covariance
    msidrec::Record one = r;
    one.n_rows = P;
    one.rows.resize(2 * P);
    try {
        (void)msidjob::estimate_frf(rq, {one}, plan);
        std::fprintf(stderr, "host consumer: one period was accepted\n");
        return 1;
    } catch (const msidjob::Error &e) {
        if (std::string(e.what()).find("at least 2 usable periods") == std::string::npos) {
            std::fprintf(stderr, "host consumer: unexpected message: %s\n", e.what());
            return 1;
        }
    }
    std::puts("host consumer: ok");
    return 0;
}
