#include "fit_sim.hpp"

#include <cmath>
#include <cstring>

namespace fitsim {

std::function<void(const tsim_design &, uint32_t, size_t, double *)> dt_plant(const SSModel &m)
{
    return [m](const tsim_design &t, uint32_t e, size_t nsamp, double *rows) {
        const uint32_t nu = t.d.n_inputs, ny = (uint32_t)m.C.rows(), P = t.d.period, C = nu + ny;
        msid_gen g;
        msid_gen_cfg gc = {&t.d, &t.tw, e, 0};
        void *mem = tsim_alloc(msid_gen_mem_size(&gc));
        msid_gen_init(&g, &gc, mem, msid_gen_mem_size(&gc));
        // warm-up of whole periods until the transient is below 1e-16
        double rho = 0;
        if (m.A.rows()) {
            Eigen::EigenSolver<MatR> es(m.A, false);
            for (Eigen::Index k = 0; k < m.A.rows(); ++k) rho = std::max(rho, std::abs(es.eigenvalues()(k)));
        }
        const uint64_t warm = rho > 0 ? (uint64_t)std::ceil(-37.0 / std::log(std::min(rho, 0.9999))) : 0;
        const uint64_t wp = (warm + P - 1) / P * P;
        VecR x = VecR::Zero(m.A.rows()), u(nu);
        for (uint64_t k = 0; k < wp; ++k) {
            msid_gen_next(&g, u.data());
            x = m.A * x + m.B * u;
        }
        for (size_t k = 0; k < nsamp; ++k) {
            msid_gen_next(&g, u.data());
            const VecR y = m.C * x + m.D * u;
            x = m.A * x + m.B * u;
            for (uint32_t j = 0; j < nu; ++j) rows[k * C + j] = u(j);
            for (uint32_t i = 0; i < ny; ++i) rows[k * C + nu + i] = y(i);
        }
        tsim_free(mem);
    };
}


std::function<void(const tsim_design &, uint32_t, size_t, double *)> ct_plant(const SSModel &m)
{
    return [m](const tsim_design &t, uint32_t e, size_t nsamp, double *rows) {
        const msid_design &d = t.d;
        const uint32_t nu = d.n_inputs, ny = (uint32_t)m.C.rows(), P = d.period, C = nu + ny, L = d.n_lines;
        const double h = d.sample_time;
        // y(nh) = sum_l Re{ G(j w_l) c_l e^{j w_l n h} } with the CT phasor c_l = A e^{j phi}
        // (the design's DT coefficient, conjugated back for folded lines)
        std::vector<MatC> G(L);
        for (uint32_t l = 0; l < L; ++l) G[l] = ss_eval(m, cd(0.0, d.omega[l]));
        for (size_t k = 0; k < nsamp; ++k) {
            VecC yc = VecC::Zero(ny);
            for (uint32_t j = 0; j < nu; ++j) rows[k * C + j] = 0;
            for (uint32_t l = 0; l < L; ++l) {
                const cd ph = std::polar(1.0, d.omega[l] * h * (double)k);
                for (uint32_t j = 0; j < nu; ++j) {
                    msid_cplx c = msid_design_coef(&d, e, j, l);
                    cd cc(c.re, c.im);
                    if (d.folded[l]) cc = std::conj(cc);
                    if (d.bins[l] == 0) { rows[k * C + j] += c.re; yc += G[l].col(j) * c.re; continue; }
                    rows[k * C + j] += (cc * ph).real();
                    yc += G[l].col(j) * (cc * ph);
                }
            }
            for (uint32_t i = 0; i < ny; ++i) rows[k * C + nu + i] = yc(i).real();
        }
    };
}

SSModel structure(const std::vector<double> &fn, const std::vector<double> &zeta, const MatR &phi, const MatR &psi)
{
    const Eigen::Index K = (Eigen::Index)fn.size(), ny = phi.rows(), nu = psi.rows();
    SSModel m;
    m.domain = Domain::CT;
    m.A = MatR::Zero(2 * K, 2 * K);
    m.B = MatR::Zero(2 * K, nu);
    m.C = MatR::Zero(ny, 2 * K);
    m.D = MatR::Zero(ny, nu);
    for (Eigen::Index k = 0; k < K; ++k) {
        const double w = 2 * M_PI * fn[(size_t)k], z = zeta[(size_t)k];
        m.A(2 * k, 2 * k + 1) = 1.0;
        m.A(2 * k + 1, 2 * k) = -w * w;
        m.A(2 * k + 1, 2 * k + 1) = -2 * z * w;
        m.B.row(2 * k + 1) = psi.col(k).transpose();
        m.C.col(2 * k) = -w * w * phi.col(k);
        m.C.col(2 * k + 1) = -2 * z * w * phi.col(k);
        m.D += phi.col(k) * psi.col(k).transpose();
    }
    return m;
}

Runner::Runner(const Bench &b) : b_(b)
{
    if (tsim_design_make(&t_, &b_.design) != MSID_OK) throw FitError("test design failed");
    const uint32_t P = t_.d.period, nu = t_.d.n_inputs, C = nu + b_.ny, m = t_.d.n_experiments;
    clean_.resize(m);
    for (uint32_t e = 0; e < m; ++e) {
        clean_[e].assign((size_t)b_.K * P * C, 0.0);
        b_.clean(t_, e, (size_t)b_.K * P, clean_[e].data());
    }
    rows_.resize((size_t)b_.K * P * C);
    msid_meas_cfg mc{};
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = b_.ny; mc.n_experiments = m;
    mc.n_lines = t_.d.n_lines; mc.bins = t_.d.bins; mc.twiddle = &t_.tw; mc.path = MSID_DFT_STREAM;
    nm_ = msid_meas_mem_size(&mc);
    mm_ = tsim_alloc(nm_);
    msid_frf_cfg fc{P, nu, b_.ny, m, t_.d.n_lines, 0, t_.d.is_ct ? t_.d.folded : nullptr};
    nf_ = msid_frf_mem_size(&fc);
    fm_ = tsim_alloc(nf_);
}

Runner::~Runner()
{
    tsim_free(mm_);
    tsim_free(fm_);
    tsim_design_free(&t_);
}

FrfData Runner::run(msid_rng &rng)
{
    const uint32_t P = t_.d.period, nu = t_.d.n_inputs, ny = b_.ny, C = nu + ny, m = t_.d.n_experiments, L = t_.d.n_lines;
    msid_meas_cfg mc{};
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m;
    mc.n_lines = L; mc.bins = t_.d.bins; mc.twiddle = &t_.tw; mc.path = MSID_DFT_STREAM;
    msid_meas ms;
    msid_meas_init(&ms, &mc, mm_, nm_);
    for (uint32_t e = 0; e < m; ++e) {
        for (size_t k = 0; k < (size_t)b_.K * P; ++k) {
            for (uint32_t j = 0; j < nu; ++j)
                rows_[k * C + j] = clean_[e][k * C + j] + (b_.sigma_u > 0 ? b_.sigma_u * msid_rng_normal(&rng) : 0.0);
            for (uint32_t i = 0; i < ny; ++i) rows_[k * C + nu + i] = clean_[e][k * C + nu + i] + b_.sigma_y * msid_rng_normal(&rng);
        }
        msid_meas_begin(&ms, e);
        msid_meas_push(&ms, rows_.data(), (size_t)b_.K * P);
        msid_meas_end(&ms, nullptr);
    }
    msid_frf_cfg fc{P, nu, ny, m, L, 0, t_.d.is_ct ? t_.d.folded : nullptr};
    msid_frf f;
    msid_frf_init(&f, &fc, fm_, nf_);
    const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
    for (uint32_t e = 0; e < m; ++e) ps[e] = msid_meas_stats(&ms, e);
    if (msid_frf_compute(&f, ps) != MSID_OK) throw FitError("test FRF failed");
    FrfData out;
    out.path = "<sim>";
    out.P = P; out.nu = nu; out.ny = ny; out.m = m;
    out.domain = t_.d.is_ct ? Domain::CT : Domain::DT;
    out.h = t_.d.is_ct ? t_.d.sample_time : 0.0;
    const size_t g = (size_t)nu * ny;
    auto cm = [](const msid_cplx *a, size_t r, size_t c) {
        MatC M(r, c);
        for (size_t i = 0; i < r; ++i)
            for (size_t j = 0; j < c; ++j) M(i, j) = cd(a[i * c + j].re, a[i * c + j].im);
        return M;
    };
    out.noise_time = cm(msid_frf_noise_cov_time(&f), ny, ny);
    for (uint32_t l = 0; l < L; ++l) {
        Line ln;
        ln.bin = t_.d.bins[l];
        ln.freq = (double)ln.bin / P;
        ln.omega = t_.d.is_ct ? t_.d.omega[l] : 2 * M_PI * ln.freq;
        ln.real = ln.bin == 0;
        ln.G = cm(msid_frf_G(&f, l), ny, nu);
        ln.cov = cm(msid_frf_cov(&f, l), g, g);
        ln.dof = msid_frf_dof(&f, l);
        ln.cov_ki = cm(msid_frf_cov_known_input(&f, l), g, g);
        ln.dof_ki = msid_frf_dof_known_input(&f, l);
        ln.noise = cm(msid_frf_noise_cov(&f, l), ny, ny);
        out.lines.push_back(ln);
    }
    return out;
}

CtBench::CtBench(const SSModel &pl, uint32_t P, uint32_t L, uint32_t K, double snr_db, uint64_t seed, uint32_t first)
{
    const double h = 0.01;
    om.resize(L);
    amp.assign(L, 1.0 / std::sqrt((double)L));
    double py = 0;
    for (uint32_t l = 0; l < L; ++l) {
        om[l] = (l + first) * 2 * M_PI / (P * h);
        py += 0.5 * std::norm(ss_eval(pl, cd(0, om[l]))(0, 0)) * amp[l] * amp[l];
    }
    b.design.period = P; b.design.n_lines = L; b.design.omega = om.data(); b.design.sample_time = h;
    b.design.amplitudes = amp.data(); b.design.n_inputs = 1; b.design.n_experiments = 1; b.design.seed = seed;
    b.ny = 1; b.K = K; b.sigma_y = std::sqrt(py) * std::pow(10.0, -snr_db / 20.0); b.clean = ct_plant(pl);
}

}  // namespace fitsim
