// msid demo: the main job end to end on a built-in simulated plant.
// design -> generate -> simulate a known 2x2 plant with coloured noise and a
// noisy input measurement -> CSV files -> the same FRF pipeline as `msid frf`
// -> the estimate beside the true FRF and its 95% region.
#include "commands.hpp"
#include "csv_io.hpp"
#include "frf_io.hpp"
#include "pipeline.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sys/stat.h>

namespace msidcli {

static const char *HELP =
    "usage: msid demo [--out DIR] [--seed S] [--periods K] [--quiet]\n"
    "\n"
    "Designs a 2-input multisine (2 experiments, DFT pattern), simulates a 4-state 2x2\n"
    "plant with coloured output noise and noisy input measurements, writes DIR/design.json,\n"
    "DIR/e1.csv, DIR/e2.csv, estimates DIR/frf.json with the same code as `msid frf`,\n"
    "and prints the estimate beside the true FRF with its 95% region. Default DIR: msid-demo.\n";

// The built-in plant: two lightly damped modes, coupled 2x2 (discrete time, fs = 1 kHz).
struct DemoPlant {
    double A[16], B[8], C[8], D[4];
    DemoPlant()
    {
        const double r1 = 0.97, t1 = 2 * M_PI * 0.02, r2 = 0.95, t2 = 2 * M_PI * 0.09;
        const double a[16] = {r1 * std::cos(t1), -r1 * std::sin(t1), 0, 0,
                              r1 * std::sin(t1), r1 * std::cos(t1),  0, 0,
                              0, 0, r2 * std::cos(t2), -r2 * std::sin(t2),
                              0, 0, r2 * std::sin(t2), r2 * std::cos(t2)};
        const double b[8] = {0.10, 0.02, 0.00, 0.05, 0.04, 0.10, 0.08, 0.00};
        const double c[8] = {1.0, 0.0, 0.6, 0.2, 0.3, 0.5, 0.0, 1.0};
        const double d[4] = {0.05, 0.0, 0.0, 0.02};
        std::memcpy(A, a, sizeof a); std::memcpy(B, b, sizeof b);
        std::memcpy(C, c, sizeof c); std::memcpy(D, d, sizeof d);
    }
};

int cmd_demo(int argc, char **argv)
{
    Args a(argc, argv, 2, HELP, {"out", "seed", "periods"}, {"quiet"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const std::string dir = a.get("out", "msid-demo");
    const uint64_t seed = a.u64("seed", 2026);
    const uint32_t K = a.u32("periods", 8);
    if (K < 3) throw UsageError("--periods must be at least 3 (one is skipped as transient)");
    const bool quiet = a.has("quiet");
    const double fs = 1000.0;
    const uint32_t P = 1024, nu = 2, ny = 2, m = 2;
    const double sigma_e = 0.02, ar = 0.7, sigma_u = 0.002;

    // 1. design: 14 roughly log-spaced lines between 2 Hz and 300 Hz
    DesignParams dp;
    dp.period = P;
    for (uint32_t b : {2u, 3u, 5u, 8u, 12u, 17u, 20u, 25u, 35u, 50u, 80u, 92u, 150u, 300u}) dp.bins.push_back(b);
    dp.n_inputs = nu;
    dp.n_experiments = m;
    dp.seed = seed;
    dp.periods = K;
    dp.amplitudes.assign(dp.bins.size(), 0.5);
    auto D = build_design(dp);
    const msid_design &d = D->d;

    // 2. simulate both experiments from rest (the first period holds the plant transient)
    DemoPlant pl;
    msid_plant_cfg pc{4, nu, ny, pl.A, pl.B, pl.C, pl.D};
    Mem pm(msid_plant_mem_size(&pc));
    msid_plant plant;
    check(msid_plant_init(&plant, &pc, pm.p, pm.n), "plant");
    const double na[1] = {ar}, nb[1] = {1.0}, nc[1] = {ar}, nd[1] = {1.0};
    msid_plant_cfg nc_cfg{1, 1, 1, na, nb, nc, nd};   // e / (1 - 0.7 q^-1)
    Mem nm0(msid_plant_mem_size(&nc_cfg)), nm1(msid_plant_mem_size(&nc_cfg));
    msid_plant nf[2];
    check(msid_plant_init(&nf[0], &nc_cfg, nm0.p, nm0.n), "noise filter");
    check(msid_plant_init(&nf[1], &nc_cfg, nm1.p, nm1.n), "noise filter");
    msid_rng rng;
    msid_rng_seed(&rng, seed ^ 0x5eedull);

    if (::mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST)
        throw Error("cannot create directory '" + dir + "': " + std::strerror(errno));
    const size_t n = (size_t)K * P, C = nu + ny;
    std::vector<std::string> header = {"u1", "u2", "y1", "y2"};
    std::vector<std::string> paths;
    for (uint32_t e = 0; e < m; ++e) {
        msid_gen_cfg gc{&d, &D->tw, e, 1};
        Mem gm(msid_gen_mem_size(&gc));
        msid_gen g;
        check(msid_gen_init(&g, &gc, gm.p, gm.n), "generator");
        msid_plant_set_state(&plant, nullptr);
        std::vector<double> rows(n * C);
        for (size_t k = 0; k < n; ++k) {
            double u[2], y[2];
            msid_gen_next(&g, u);
            msid_plant_step(&plant, u, y);
            for (uint32_t i = 0; i < nu; ++i) rows[k * C + i] = u[i] + sigma_u * msid_rng_normal(&rng);
            for (uint32_t i = 0; i < ny; ++i) {
                double ev = sigma_e * msid_rng_normal(&rng), v;
                msid_plant_step(&nf[i], &ev, &v);
                rows[k * C + nu + i] = y[i] + v;
            }
        }
        paths.push_back(dir + "/e" + std::to_string(e + 1) + ".csv");
        write_file_atomic(paths.back(), format_csv(header, rows.data(), n, C));
    }
    write_json_file(dir + "/design.json", design_to_json(*D));

    // 3. estimate from the files, exactly as `msid frf --design ... --skip-periods 1` does
    std::vector<Record> recs;
    for (auto &p : paths) recs.push_back(read_record_csv(p));
    FrfRequest rq;
    request_from_design(rq, *D);
    rq.fs = fs;
    rq.skip = 1;
    FrfOutcome o = run_frf(rq, recs);
    write_json_file(dir + "/frf.json", o.doc);

    // 4. compare with the truth
    const auto &lines = o.doc["lines"];
    const size_t L = lines.size();
    size_t inside = 0, total = 0;
    Json truth = Json::array();
    if (!quiet) {
        std::printf("msid demo: 2x2 plant (4 states, modes at %.0f Hz and %.0f Hz), coloured output noise\n"
                    "  (AR(1) pole %.1f, innovation std %.3g) and input measurement noise (std %.3g).\n"
                    "  %u experiments x %u periods of %u samples at %.0f Hz; first period skipped (transient).\n\n",
                    0.02 * fs, 0.09 * fs, ar, sigma_e, sigma_u, m, K, P, fs);
        std::printf("%6s %8s  %-3s %22s %22s %9s %9s %4s\n", "bin", "f [Hz]", "G", "estimate", "true", "|error|",
                    "r95", "in");
    }
    for (size_t l = 0; l < L; ++l) {
        const uint32_t b = lines[l]["bin"].get<uint32_t>();
        msid_cplx G0[4];
        check(msid_plant_frf(&plant, (double)b / P, G0), "true FRF");
        const double dof = lines[l]["dof"].get<double>();
        // |e|^2 / v ~ F(2, 2n): 95% radius sqrt(v * n (0.05^{-1/n} - 1))
        const double fq = dof * (std::pow(0.05, -1.0 / dof) - 1.0);
        Json tl;
        tl["bin"] = b;
        tl["G"] = cmat_json(G0, ny, nu);
        truth.push_back(tl);
        for (uint32_t i = 0; i < ny; ++i)
            for (uint32_t j = 0; j < nu; ++j) {
                const double gr = lines[l]["G"]["re"][i][j].get<double>(), gi = lines[l]["G"]["im"][i][j].get<double>();
                const size_t v = i + (size_t)ny * j;
                const double var = lines[l]["cov"]["re"][v][v].get<double>();
                const double err = std::hypot(gr - G0[i * nu + j].re, gi - G0[i * nu + j].im);
                const double r95 = std::sqrt(var * fq);
                const bool in = err <= r95;
                inside += in;
                ++total;
                if (!quiet)
                    std::printf("%6u %8.2f  %u%u  %+10.5f%+10.5fj  %+10.5f%+10.5fj %9.2e %9.2e %4s\n", b,
                                (double)b / P * fs, i + 1, j + 1, gr, gi, G0[i * nu + j].re, G0[i * nu + j].im, err, r95,
                                in ? "yes" : "NO");
            }
    }
    write_json_file(dir + "/truth.json", Json{{"format", "msid-demo-truth/1"}, {"lines", truth}});
    const double expct = 0.95 * total, sd = std::sqrt(total * 0.95 * 0.05);
    std::printf("\n%zu of %zu true FRF values lie inside their 95%% region (expected %.1f +- %.1f).\n", inside, total,
                expct, sd);
    for (const auto &nt : o.notes) std::printf("note: %s\n", nt.c_str());
    std::printf("files: %s/{design.json,e1.csv,e2.csv,frf.json,truth.json}\n"
                "reproduce the estimate: %s frf --design %s/design.json --experiment %s/e1.csv --experiment %s/e2.csv "
                "--skip-periods 1 --fs %.0f -o frf.json\n",
                dir.c_str(), argv[0], dir.c_str(), dir.c_str(), dir.c_str(), fs);
    // A demo that misses badly is a failure, not a success.
    if (inside + 4 * sd < expct) {
        std::fprintf(stderr, "msid demo: error: coverage far below 95%%\n");
        return 1;
    }
    return 0;
}

}  // namespace msidcli
