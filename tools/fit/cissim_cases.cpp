// Reference cases Y1, Y2 of discrete-cISSIM and the core FRF peer (cissim_cases.hpp).
#include "cissim_cases.hpp"

extern "C" {
#include "msid/msid.h"
}

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>

namespace msidfit {

SSModel y1_system(msid_rng &r, double rmin, double rmax)
{
    SSModel m;
    m.domain = Domain::DT;
    m.A = MatR::Zero(4, 4);
    for (int k = 0; k < 2; ++k) {
        const double rad = rmin + (rmax - rmin) * msid_rng_uniform(&r);
        const double th = (0.05 + 0.3 * msid_rng_uniform(&r)) * M_PI;
        m.A(2 * k, 2 * k) = m.A(2 * k + 1, 2 * k + 1) = rad * std::cos(th);
        m.A(2 * k, 2 * k + 1) = -rad * std::sin(th);
        m.A(2 * k + 1, 2 * k) = rad * std::sin(th);
    }
    m.B = MatR(4, 1);
    m.C = MatR(1, 4);
    m.D = MatR(1, 1);
    for (int i = 0; i < 4; ++i) m.B(i, 0) = msid_rng_normal(&r);
    for (int i = 0; i < 4; ++i) m.C(0, i) = msid_rng_normal(&r);
    m.D(0, 0) = 0.5 * msid_rng_normal(&r);
    return m;
}

CissimRecord periodic_record(const SSModel &m, const std::vector<double> &u, uint32_t T, uint32_t K, double snr_db,
                             msid_rng &r)
{
    CissimRecord rec;
    rec.period = T;
    rec.nu = (uint32_t)m.B.cols();
    rec.ny = (uint32_t)m.C.rows();
    const uint32_t nu = rec.nu, C = nu + rec.ny;
    rec.n_rows = (size_t)T * K;
    rec.rows.assign(rec.n_rows * C, 0.0);
    VecR x = VecR::Zero(m.A.rows()), uk(nu);
    double py = 0;
    for (size_t k = 0; k < rec.n_rows; ++k) {
        for (uint32_t j = 0; j < nu; ++j) uk(j) = u[(k % T) * nu + j];
        const VecR y = m.C * x + m.D * uk;
        x = m.A * x + m.B * uk;
        for (uint32_t j = 0; j < nu; ++j) rec.rows[k * C + j] = uk(j);
        for (uint32_t i = 0; i < rec.ny; ++i) rec.rows[k * C + nu + i] = y(i), py += y(i) * y(i);
    }
    const double s = std::sqrt(py / (double)(rec.n_rows * rec.ny) * std::pow(10.0, -snr_db / 10.0));
    for (size_t k = 0; k < rec.n_rows; ++k)
        for (uint32_t i = 0; i < rec.ny; ++i) rec.rows[k * C + nu + i] += s * msid_rng_normal(&r);
    return rec;
}

CissimRecord y1_record(const SSModel &m, uint32_t T, uint32_t K, double snr_db, msid_rng &r)
{
    std::vector<double> u(T);
    for (uint32_t n = 0; n < T; ++n) u[n] = std::sin(0.2 * M_PI * (double)n * n / T);   // omega(n) = 0.4 pi n / T
    return periodic_record(m, u, T, K, snr_db, r);
}

std::vector<uint32_t> y1_reduced_bins(uint32_t T, uint32_t q)
{
    const double top = 0.2 * T;   // 0.4 pi rad/sample
    std::vector<uint32_t> b;
    for (uint32_t i = 0; i < q; ++i) {
        const uint32_t v = (uint32_t)std::lround(1.0 + (top - 2.0) * (i + 0.5) / q);
        if (b.empty() || v > b.back()) b.push_back(v);
    }
    return b;
}

std::vector<CissimProcessCase> cissim_process_cases()
{
    std::vector<CissimProcessCase> out(2);
    {
        CissimProcessCase &c = out[0];
        c.name = "2x2";
        msid_rng r;
        msid_rng_seed(&r, 2828);
        SSModel &m = c.truth;
        m.domain = Domain::DT;
        m.A = MatR::Zero(4, 4);
        const double rad[2] = {0.9, 0.8}, ang[2] = {0.2 * M_PI, 0.6 * M_PI};
        for (int k = 0; k < 2; ++k) {
            m.A(2 * k, 2 * k) = m.A(2 * k + 1, 2 * k + 1) = rad[k] * std::cos(ang[k]);
            m.A(2 * k, 2 * k + 1) = -rad[k] * std::sin(ang[k]);
            m.A(2 * k + 1, 2 * k) = rad[k] * std::sin(ang[k]);
        }
        m.B = MatR(4, 2);
        m.C = MatR(2, 4);
        for (Eigen::Index i = 0; i < m.B.size(); ++i) m.B(i) = msid_rng_normal(&r);
        for (Eigen::Index i = 0; i < m.C.size(); ++i) m.C(i) = msid_rng_normal(&r);
        m.D = MatR::Zero(2, 2);
        const uint32_t T = 2000;
        for (uint32_t b = 3; b <= 900; b += 3) c.lines.push_back(b);
        std::vector<double> u((size_t)T * 2, 0.0);
        const double a = std::sqrt(2.0 / (double)c.lines.size());   // unit rms per input
        for (uint32_t j = 0; j < 2; ++j)
            for (uint32_t b : c.lines) {
                const double ph = 2.0 * M_PI * msid_rng_uniform(&r);
                for (uint32_t n = 0; n < T; ++n)
                    u[(size_t)n * 2 + j] += a * std::cos(2.0 * M_PI * (double)((uint64_t)b * n % T) / T + ph);
            }
        c.rec = periodic_record(m, u, T, 30, 30.0, r);
    }
    {
        CissimProcessCase &c = out[1];
        c.name = "sparse";
        msid_rng r;
        msid_rng_seed(&r, 4242);
        c.truth = y1_system(r, 0.97, 0.995);
        c.rec = y1_record(c.truth, 3000, 24, 20.0, r);
        c.lines = y1_reduced_bins(3000, 50);
    }
    return out;
}

SSModel y2_system()
{
    SSModel m;
    m.domain = Domain::DT;
    m.A = MatR::Zero(2, 2);
    m.A(0, 0) = 0.8;
    m.A(1, 1) = 0.2;
    m.B = MatR::Ones(2, 1);
    m.C = MatR(2, 2);
    m.C << 1, 0, 1, 1;
    m.D = MatR::Zero(2, 1);
    return m;
}

void y2_sigmas(MatR &Sww, MatR &Svv, MatR &Stt)
{
    Sww = MatR::Zero(2, 2);
    Svv = MatR::Zero(2, 2);
    Stt = MatR::Zero(1, 1);
    Sww(0, 0) = 2.30e-3;
    Sww(1, 1) = 0.16e-3;
    Svv(0, 0) = 2.30e-3;
    Svv(1, 1) = 3.64e-3;
    Stt(0, 0) = 0.11e-3;
}

CissimRecord y2_record(uint32_t T, uint32_t K, msid_rng &r)
{
    const SSModel m = y2_system();
    MatR Sww, Svv, Stt;
    y2_sigmas(Sww, Svv, Stt);
    CissimRecord rec;
    rec.period = T;
    rec.nu = 1;
    rec.ny = 2;
    rec.n_rows = (size_t)T * K;
    rec.rows.assign(rec.n_rows * 3, 0.0);
    std::vector<double> u(T);
    for (auto &v : u) v = msid_rng_normal(&r);
    VecR x = VecR::Zero(2);
    for (size_t k = 0; k < rec.n_rows; ++k) {
        const double uk = u[k % T];
        rec.rows[k * 3] = uk + std::sqrt(Stt(0, 0)) * msid_rng_normal(&r);
        for (int i = 0; i < 2; ++i) {
            double y = m.C.row(i).dot(x);
            rec.rows[k * 3 + 1 + i] = y + std::sqrt(Svv(i, i)) * msid_rng_normal(&r);
        }
        VecR w(2);
        w << std::sqrt(Sww(0, 0)) * msid_rng_normal(&r), std::sqrt(Sww(1, 1)) * msid_rng_normal(&r);
        x = m.A * x + m.B * uk + w;
    }
    return rec;
}

std::vector<MatR> model_correlations(const SSModel &m, const MatR &Sww, const MatR &Svv, int lags)
{
    // (23): Xi = A Xi A^T + Sigma_ww by fixed-point iteration (A Schur)
    MatR Xi = Sww, term = Sww;
    for (int k = 0; k < 5000; ++k) {
        term = m.A * term * m.A.transpose();
        Xi += term;
        if (term.norm() < 1e-18 * Xi.norm()) break;
    }
    std::vector<MatR> out;
    out.push_back(m.C * Xi * m.C.transpose() + Svv);   // (24), l = 0
    MatR CA = m.C;
    for (int l = 1; l <= lags; ++l) {
        CA = CA * m.A;
        out.push_back(CA * Xi * m.C.transpose());
    }
    return out;
}

CovErrors y2_errors(const SSModel &est, const NoiseCov &nc, int r)
{
    const SSModel tr = y2_system();
    MatR Sww, Svv, Stt;
    y2_sigmas(Sww, Svv, Stt);
    CovErrors e;
    e.v = (nc.Sigma_vv - Svv).norm() / Svv.norm();
    e.tau = (nc.Sigma_tt - Stt).norm() / Stt.norm();
    // similarity compensation: modes of A-hat in the order of the truth (0.8, 0.2), each state scaled
    // so that the column of C-hat matches the true C column (the basis of the true model)
    Eigen::EigenSolver<MatR> es(est.A);
    MatR V = es.eigenvectors().real();
    VecR lam = es.eigenvalues().real();
    std::vector<int> idx = {0, 1};
    std::sort(idx.begin(), idx.end(), [&](int a, int b) { return lam(a) > lam(b); });
    MatR Vs(2, 2);
    for (int k = 0; k < 2; ++k) Vs.col(k) = V.col(idx[(size_t)k]);
    const MatR Cm = est.C * Vs;   // C in the modal basis x = Vs x'
    MatR Tm = Vs;
    for (int k = 0; k < 2; ++k) {
        const double s = Cm.col(k).dot(tr.C.col(k)) / Cm.col(k).squaredNorm();   // x' = s x_true
        Tm.col(k) *= s;
    }
    // x_hat = Tm x_true  =>  Sigma_ww(true basis) = Tm^-1 Sigma_ww_hat Tm^-T
    const MatR Ti = Tm.inverse();
    const MatR Sw = Ti * nc.Sigma_ww * Ti.transpose();
    e.w = (Sw - Sww).norm() / Sww.norm();
    const auto Xt = model_correlations(tr, Sww, Svv, r);
    const auto Xe = model_correlations(est, nc.Sigma_ww, nc.Sigma_vv, r);
    for (int j = 0; j <= r; ++j) e.r += (Xe[(size_t)j] - Xt[(size_t)j]).norm() / Xt[(size_t)j].norm();
    return e;
}

CovErrors y2_run(uint32_t T, uint32_t K, uint64_t seed, double *seconds)
{
    msid_rng r;
    msid_rng_seed(&r, seed);
    const CissimRecord rec = y2_record(T, K + 1, r);
    std::vector<uint32_t> full;
    for (uint32_t b = 0; 2 * b < T; ++b) full.push_back(b);
    CissimOptions o;
    o.order = 2;
    const auto t0 = std::chrono::steady_clock::now();
    const SSModel m = cissim_fit({cissim_isp(rec.rows.data(), rec.n_rows, 1, 2, T, full, 1)}, o).model;
    const int M = std::max(5, std::min(50, (int)std::lround(std::cbrt((double)K * T))));
    const NoiseCov nc = cissim_noise_cov(m, cissim_correlations(rec.rows.data(), rec.n_rows, 1, 2, T, 1, M));
    if (seconds) *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return y2_errors(m, nc);
}

namespace {
struct Aligned {
    void *p = nullptr;
    explicit Aligned(size_t n) { p = std::aligned_alloc(MSID_MEM_ALIGN, (n + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN + MSID_MEM_ALIGN); }
    ~Aligned() { std::free(p); }
};
}  // namespace

FrfData core_frf(const CissimRecord &rec, const std::vector<uint32_t> &bins, uint32_t skip)
{
    if (rec.nu != 1) throw FitError("core_frf: one experiment needs one input");
    const uint32_t P = rec.period, L = (uint32_t)bins.size();
    Aligned twm(msid_twiddle_mem_size(P));
    msid_twiddle tw;
    if (msid_twiddle_init(&tw, P, twm.p, msid_twiddle_mem_size(P)) != MSID_OK) throw FitError("core_frf: twiddle");
    msid_meas_cfg mc{};
    mc.period = P;
    mc.n_inputs = 1;
    mc.n_outputs = rec.ny;
    mc.n_experiments = 1;
    mc.n_lines = L;
    mc.bins = bins.data();
    mc.twiddle = &tw;
    mc.path = MSID_DFT_STREAM;
    mc.skip_periods = skip;
    const size_t nm = msid_meas_mem_size(&mc);
    Aligned mm(nm);
    msid_meas ms;
    if (msid_meas_init(&ms, &mc, mm.p, nm) != MSID_OK) throw FitError("core_frf: meas init");
    msid_meas_begin(&ms, 0);
    msid_meas_push(&ms, rec.rows.data(), rec.n_rows);
    msid_meas_end(&ms, nullptr);
    msid_frf_cfg fc{P, 1, rec.ny, 1, L, 0, nullptr};
    const size_t nf = msid_frf_mem_size(&fc);
    Aligned fm(nf);
    msid_frf f;
    if (msid_frf_init(&f, &fc, fm.p, nf) != MSID_OK) throw FitError("core_frf: frf init");
    const msid_pstats *ps[1] = {msid_meas_stats(&ms, 0)};
    if (msid_frf_compute(&f, ps) != MSID_OK) throw FitError("core_frf: FRF failed");
    FrfData out;
    out.path = "<core>";
    out.P = P;
    out.nu = 1;
    out.ny = rec.ny;
    out.m = 1;
    auto cm = [](const msid_cplx *a, size_t r, size_t c) {
        MatC M(r, c);
        for (size_t i = 0; i < r; ++i)
            for (size_t j = 0; j < c; ++j) M(i, j) = cd(a[i * c + j].re, a[i * c + j].im);
        return M;
    };
    const size_t g = rec.ny;
    out.noise_time = cm(msid_frf_noise_cov_time(&f), rec.ny, rec.ny);
    for (uint32_t l = 0; l < L; ++l) {
        Line ln;
        ln.bin = bins[l];
        ln.freq = (double)ln.bin / P;
        ln.omega = 2 * M_PI * ln.freq;
        ln.real = ln.bin == 0;
        ln.G = cm(msid_frf_G(&f, l), rec.ny, 1);
        ln.cov = cm(msid_frf_cov(&f, l), g, g);
        ln.dof = msid_frf_dof(&f, l);
        ln.cov_ki = cm(msid_frf_cov_known_input(&f, l), g, g);
        ln.dof_ki = msid_frf_dof_known_input(&f, l);
        ln.noise = cm(msid_frf_noise_cov(&f, l), rec.ny, rec.ny);
        out.lines.push_back(ln);
    }
    return out;
}

}  // namespace msidfit
