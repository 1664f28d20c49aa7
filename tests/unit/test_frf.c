/* MIMO FRF: recovery of a simulated plant's FRF (noiseless, SISO / 2x2 with
 * m = 2, 3), singular inputs, too few periods, folded CT lines, DC lines,
 * covariance / dof closed forms, and the detection-line F test. */
#include "unit_util.h"
#include "unit_plants.h"
#ifdef MSID_HAVE_FFTW
#include "msid/msid_fft_fftw.h"
#endif

typedef struct {
    msid_meas ms;
    void *mem_ms;
    msid_frf frf;
    void *mem_frf;
    const msid_pstats *stats[MSID_MAX_EXPERIMENTS];
} pipeline;

typedef struct {
    uint32_t K[MSID_MAX_EXPERIMENTS];   /* periods per experiment */
    uint32_t n_detect;
    const uint32_t *detect_bins;
    const uint8_t *folded;
    msid_dft_path path;
    const msid_fft_backend *fft;
    /* optional: add amp*cos(2 pi bin n / P + phase) to output 0 */
    double inj_amp;
    uint32_t inj_bin;
    int same_rows;                      /* 1: every experiment gets experiment 0's rows */
    double scale_u, scale_y;            /* 0 or a factor on the inputs / outputs (range tests) */
} run_opts;

static void pipe_free(pipeline *pp)
{
    tsim_free(pp->mem_ms);
    tsim_free(pp->mem_frf);
    pp->mem_ms = pp->mem_frf = NULL;
}

/* Simulate every experiment on the bench, measure and solve. Returns the frf status. */
static msid_status pipe_run(pipeline *pp, const tsim_design *t, tsim_bench *b, const run_opts *o, msid_rng *rng)
{
    const msid_design *d = &t->d;
    const uint32_t P = d->period, nu = d->n_inputs, ny = b->plant.ny, m = d->n_experiments, C = nu + ny;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m;
    mc.n_lines = d->n_lines; mc.bins = d->bins;
    mc.n_detect = o->n_detect; mc.detect_bins = o->detect_bins;
    mc.twiddle = &t->tw; mc.path = o->path ? o->path : MSID_DFT_STREAM; mc.fft = o->fft;
    const size_t nms = msid_meas_mem_size(&mc);
    pp->mem_ms = tsim_alloc(nms);
    UT_STATUS(msid_meas_init(&pp->ms, &mc, pp->mem_ms, nms), MSID_OK);
    double *rows0 = NULL;
    for (uint32_t e = 0; e < m; ++e) {
        const uint32_t K = o->K[e];
        double *rows = (double *)malloc(sizeof(double) * ((size_t)K * P * C + 1));
        if (o->same_rows && e > 0) memcpy(rows, rows0, sizeof(double) * K * P * C);
        else tsim_run(b, t, e, K, rng, rows);
        if (o->inj_amp != 0.0)
            for (size_t n = 0; n < (size_t)K * P; ++n)
                rows[n * C + nu] += o->inj_amp * cos(UT_TWO_PI * (double)((o->inj_bin * n) % P) / P + 0.3);
        if (o->scale_u != 0.0 || o->scale_y != 0.0)
            for (size_t k = 0; k < (size_t)K * P * C; ++k) rows[k] *= (k % C < nu ? o->scale_u : o->scale_y);
        UT_STATUS(msid_meas_begin(&pp->ms, e), MSID_OK);
        UT_STATUS(msid_meas_push(&pp->ms, rows, (size_t)K * P), MSID_OK);
        UT_STATUS(msid_meas_end(&pp->ms, NULL), MSID_OK);
        if (e == 0) rows0 = rows; else free(rows);
        pp->stats[e] = msid_meas_stats(&pp->ms, e);
    }
    free(rows0);
    msid_frf_cfg fc = {P, nu, ny, m, d->n_lines, o->n_detect, o->folded};
    const size_t nf = msid_frf_mem_size(&fc);
    pp->mem_frf = tsim_alloc(nf);
    UT_STATUS(msid_frf_init(&pp->frf, &fc, pp->mem_frf, nf), MSID_OK);
    return msid_frf_compute(&pp->frf, pp->stats);
}

static msid_design_cfg dt_cfg(uint32_t P, uint32_t L, const uint32_t *bins, uint32_t nu, uint32_t m)
{
    msid_design_cfg c = ut_design_cfg(P, L, bins, nu, m);
    c.phase_mode = MSID_PHASE_SCHROEDER;
    c.pattern = MSID_PATTERN_DFT;
    return c;
}

/* The setup most tests share: a design, a bench (plant + warm-up) and a seeded rng. */
typedef struct {
    tsim_design t;
    tsim_bench b;
    msid_rng r;
} scene;

static void scene_make(scene *s, msid_design_cfg c, msid_plant_cfg pc, uint32_t warmup, uint64_t seed)
{
    UT_STATUS(tsim_design_make(&s->t, &c), MSID_OK);
    UT_STATUS(tsim_bench_make(&s->b, &pc, warmup), MSID_OK);
    msid_rng_seed(&s->r, seed);
}

static void scene_free(scene *s)
{
    tsim_bench_free(&s->b);
    tsim_design_free(&s->t);
}

/* pipe_run on the scene's design, bench and rng. */
static msid_status scene_run(scene *s, pipeline *pp, const run_opts *o)
{
    return pipe_run(pp, &s->t, &s->b, o, &s->r);
}

static run_opts opts_k(uint32_t m, uint32_t K)
{
    run_opts o;
    memset(&o, 0, sizeof o);
    for (uint32_t e = 0; e < m; ++e) o.K[e] = K;
    return o;
}

/* max_ij |Ghat_ij - G_ij| <= tol * max_ij |G_ij| at every line, G from the plant at frequency f_l. */
static void check_G(const msid_frf *f, msid_plant *plant, const double *freq, double tol, const char *what)
{
    const uint32_t g = f->n_inputs * f->n_outputs;
    for (uint32_t l = 0; l < f->n_lines; ++l) {
        msid_cplx G[MSID_MAX_INPUTS * MSID_MAX_OUTPUTS];
        UT_STATUS(msid_plant_frf(plant, freq[l], G), MSID_OK);
        const msid_cplx *Gh = msid_frf_G(f, l);
        double gmax = 0.0, emax = 0.0;
        for (uint32_t k = 0; k < g; ++k) {
            gmax = fmax(gmax, ut_cabs(G[k]));
            emax = fmax(emax, ut_cdist(G[k], Gh[k]));
        }
        UT_CHECK(emax <= tol * gmax && msid_frf_line_status(f, l) == MSID_LINE_OK, "%s line %u (f=%.4f): err %.3g of %.3g",
                 what, l, freq[l], emax, gmax);
    }
}

static void bin_freqs(const msid_design *d, double *f)
{
    for (uint32_t l = 0; l < d->n_lines; ++l) f[l] = (double)d->bins[l] / d->period;
}

/* ---------- noiseless recovery ---------- */

static void test_noiseless_siso(void **state)
{
    (void)state;
    const uint32_t bins[] = {1, 3, 5, 8, 13, 20, 31};
    scene s;
    scene_make(&s, dt_cfg(64, 7, bins, 1, 1), up_siso(), 400, 1u);
    pipeline pp;
    run_opts o = opts_k(1, 3);
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    double f[7];
    bin_freqs(&s.t.d, f);
    check_G(&pp.frf, &s.b.plant, f, 1e-9, "SISO");
    for (uint32_t l = 0; l < 7; ++l)
        UT_CHECK(msid_frf_dof_known_input(&pp.frf, l) == 2.0 && fabs(msid_frf_cond(&pp.frf, l) - 1.0) < 1e-12, "line %u", l);
    UT_CHECK(pp.frf.K_total == 3 && pp.frf.bad_line == -1 && pp.frf.bad_experiment == -1, "%u", pp.frf.K_total);
    pipe_free(&pp);
    /* without warm-up the transient spoils the estimate: the check can fail */
    const msid_plant_cfg pc = up_siso();
    tsim_bench b0;
    UT_STATUS(tsim_bench_make(&b0, &pc, 0), MSID_OK);
    UT_STATUS(pipe_run(&pp, &s.t, &b0, &o, &s.r), MSID_OK);
    double worst = 0.0;
    for (uint32_t l = 0; l < 7; ++l) {
        msid_cplx G;
        msid_plant_frf(&b0.plant, f[l], &G);
        worst = fmax(worst, ut_cdist(G, msid_frf_G(&pp.frf, l)[0]) / ut_cabs(G));
    }
    UT_CHECK(worst > 1e-6, "transient not visible: %.3g", worst);
    pipe_free(&pp);
    tsim_bench_free(&b0);
    scene_free(&s);
}

static void test_noiseless_mimo(void **state)
{
    (void)state;
    const uint32_t bins[] = {1, 2, 5, 9, 17, 33, 50, 63};
    for (uint32_t m = 2; m <= 3; ++m) {
        scene s;
        scene_make(&s, dt_cfg(128, 8, bins, 2, m), up_mimo(), 500, 2u);
        pipeline pp;
        run_opts o = opts_k(m, 3);
        UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
        double f[8];
        bin_freqs(&s.t.d, f);
        check_G(&pp.frf, &s.b.plant, f, 1e-9, m == 2 ? "2x2 m=2" : "2x2 m=3");
        for (uint32_t l = 0; l < 8; ++l) {
            UT_CHECK(fabs(msid_frf_cond(&pp.frf, l) - 1.0) < 1e-9, "cond %.17g", msid_frf_cond(&pp.frf, l));
            UT_CHECK(msid_frf_dof_known_input(&pp.frf, l) == 2.0 * m, "dof_ki %g", msid_frf_dof_known_input(&pp.frf, l));
        }
        pipe_free(&pp);
        scene_free(&s);
    }
}

/* ---------- singular inputs, too few periods ---------- */

static void test_singular_identical_experiments(void **state)
{
    (void)state;
    const uint32_t bins[] = {2, 3, 7};
    scene s;
    scene_make(&s, dt_cfg(32, 3, bins, 2, 2), up_mimo(), 200, 3u);
    pipeline pp;
    run_opts o = opts_k(2, 3);
    o.same_rows = 1;   /* experiment 1 repeats experiment 0: Ubar has rank 1 at every line */
    UT_STATUS(scene_run(&s, &pp, &o), MSID_E_SINGULAR);
    UT_CHECK(pp.frf.bad_line == 0, "bad_line %d", (int)pp.frf.bad_line);
    for (uint32_t l = 0; l < 3; ++l) {
        UT_CHECK(msid_frf_line_status(&pp.frf, l) == MSID_LINE_SINGULAR && isnan(msid_frf_G(&pp.frf, l)[0].re) &&
                 isnan(msid_frf_dof(&pp.frf, l)) && !(msid_frf_cond(&pp.frf, l) < 1e12), "line %u", l);
    }
    pipe_free(&pp);
    scene_free(&s);
}

/* Statistics built directly: line 1's inputs are the same in every experiment. */
static void test_singular_one_line(void **state)
{
    (void)state;
    const uint32_t nu = 2, ny = 2, m = 3, L = 3, q = 4, K = 4;
    msid_rng r;
    msid_rng_seed(&r, 77u);
    msid_cplx G[3][4], U[3][3][2];
    for (uint32_t l = 0; l < L; ++l) {
        for (int k = 0; k < 4; ++k) G[l][k] = ut_c(msid_rng_normal(&r), msid_rng_normal(&r));
        for (uint32_t e = 0; e < m; ++e)
            for (uint32_t j = 0; j < nu; ++j)
                U[l][e][j] = (l == 1 && e > 0) ? U[1][0][j] : ut_c(msid_rng_normal(&r), msid_rng_normal(&r));
    }
    msid_pstats ps[3];
    void *mem[3];
    const msid_pstats *st[3];
    msid_pstats_cfg pc = {L, q, 0, 0, MSID_TRANSIENT_OFF, 0.0, 0};
    for (uint32_t e = 0; e < m; ++e) {
        mem[e] = tsim_alloc(msid_pstats_mem_size(&pc));
        UT_STATUS(msid_pstats_init(&ps[e], &pc, mem[e], msid_pstats_mem_size(&pc)), MSID_OK);
        for (uint32_t p = 0; p < K; ++p) {
            msid_cplx z[3 * 4];
            for (uint32_t l = 0; l < L; ++l) {
                for (uint32_t j = 0; j < nu; ++j) z[l * q + j] = U[l][e][j];
                for (uint32_t i = 0; i < ny; ++i) {
                    msid_cplx y = ut_c(0, 0);
                    for (uint32_t j = 0; j < nu; ++j) {
                        const msid_cplx gu = ut_cmul(G[l][i * nu + j], U[l][e][j]);
                        y.re += gu.re; y.im += gu.im;
                    }
                    z[l * q + nu + i] = y;
                }
            }
            UT_STATUS(msid_pstats_add(&ps[e], z, 0), MSID_OK);
        }
        st[e] = &ps[e];
    }
    msid_frf f;
    msid_frf_cfg fc = {32, nu, ny, m, L, 0, NULL};
    void *fm = tsim_alloc(msid_frf_mem_size(&fc));
    UT_STATUS(msid_frf_init(&f, &fc, fm, msid_frf_mem_size(&fc)), MSID_OK);
    UT_STATUS(msid_frf_compute(&f, st), MSID_E_SINGULAR);
    UT_CHECK(f.bad_line == 1, "bad_line %d", (int)f.bad_line);
    for (uint32_t l = 0; l < L; ++l) {
        if (l == 1) {
            UT_CHECK(msid_frf_line_status(&f, l) == MSID_LINE_SINGULAR, "line %u", l);
            continue;
        }
        UT_CHECK(msid_frf_line_status(&f, l) == MSID_LINE_OK, "line %u", l);
        const msid_cplx *Gh = msid_frf_G(&f, l);
        for (int k = 0; k < 4; ++k)
            UT_CHECK(ut_cdist(Gh[k], G[l][k]) <= 1e-12 * ut_cabs(G[l][k]) + 1e-13, "line %u entry %d", l, k);
        /* exact data: zero covariance */
        for (int k = 0; k < 16; ++k) UT_CHECK(ut_cabs(msid_frf_cov_known_input(&f, l)[k]) <= 1e-20, "cov %d", k);
    }
    /* FEW_PERIODS: experiment 2 with a single period */
    msid_pstats_reset(&ps[2]);
    msid_cplx z1[12];
    memset(z1, 0, sizeof z1);
    msid_pstats_add(&ps[2], z1, 0);
    UT_STATUS(msid_frf_compute(&f, st), MSID_E_FEW_PERIODS);
    UT_CHECK(f.bad_experiment == 2, "bad_experiment %d", (int)f.bad_experiment);
    msid_pstats_reset(&ps[2]);
    UT_STATUS(msid_frf_compute(&f, st), MSID_E_FEW_PERIODS);
    UT_CHECK(f.bad_experiment == 2, "bad_experiment %d", (int)f.bad_experiment);
    /* mismatched statistics */
    msid_frf f2;
    msid_frf_cfg fc2 = {32, nu, ny, m, L + 1, 0, NULL};
    void *fm2 = tsim_alloc(msid_frf_mem_size(&fc2));
    UT_STATUS(msid_frf_init(&f2, &fc2, fm2, msid_frf_mem_size(&fc2)), MSID_OK);
    UT_STATUS(msid_frf_compute(&f2, st), MSID_E_DIMS);
    UT_STATUS(msid_frf_compute(&f2, NULL), MSID_E_NULL);
    for (uint32_t e = 0; e < m; ++e) tsim_free(mem[e]);
    tsim_free(fm);
    tsim_free(fm2);
}

static void test_few_periods_pipeline(void **state)
{
    (void)state;
    const uint32_t bins[] = {2, 3, 7};
    scene s;
    scene_make(&s, dt_cfg(32, 3, bins, 2, 2), up_mimo(), 100, 4u);
    s.b.sigma_y[0] = s.b.sigma_y[1] = 0.1;
    pipeline pp;
    run_opts o = opts_k(2, 3);
    o.K[1] = 1;
    UT_STATUS(scene_run(&s, &pp, &o), MSID_E_FEW_PERIODS);
    UT_CHECK(pp.frf.bad_experiment == 1, "%d", (int)pp.frf.bad_experiment);
    pipe_free(&pp);
    scene_free(&s);
}

/* ---------- folded CT lines and DC lines ---------- */

static void test_folded_lines_conjugate(void **state)
{
    (void)state;
    /* P = 16, h = 0.01: 3, 21, 30, 44 cycles -> bins 3, 5, 2 (folded), 4 (folded) */
    const uint32_t P = 16;
    const double h = 0.01, kc[] = {3, 21, 30, 44};
    double omega[4], fct[4];
    for (int l = 0; l < 4; ++l) {
        omega[l] = UT_TWO_PI * kc[l] / (P * h);
        fct[l] = omega[l] * h / UT_TWO_PI;   /* CT frequency in cycles/sample (aliases >= 1/2) */
    }
    const msid_plant_cfg pcs[2] = {up_siso(), up_mimo()};
    for (int mi = 0; mi < 2; ++mi) {
        const uint32_t nu = mi ? 2 : 1;
        msid_design_cfg c = dt_cfg(P, 4, NULL, nu, nu);
        c.bins = NULL;
        c.omega = omega;
        c.sample_time = h;
        scene s;
        scene_make(&s, c, pcs[mi], 300, 10u);
        UT_CHECK(s.t.d.folded[2] == 1 && s.t.d.folded[3] == 1 && s.t.d.folded[0] == 0 && s.t.d.folded[1] == 0, "%d", 0);
        /* noiseless: G at the CT frequency, i.e. conj(G(b/P)) on folded lines */
        pipeline pp;
        run_opts o = opts_k(nu, 3);
        o.folded = s.t.d.folded;
        UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
        check_G(&pp.frf, &s.b.plant, fct, 1e-9, "folded CT");
        pipe_free(&pp);
        /* noisy: with and without the folded flags, the folded lines are exact conjugates */
        s.b.sigma_y[0] = s.b.sigma_y[1] = 0.05;
        s.b.sigma_u[0] = s.b.sigma_u[1] = 0.02;
        pipeline pa, pb;
        msid_rng_seed(&s.r, 11u);
        o.K[0] = o.K[1] = 6;
        UT_STATUS(scene_run(&s, &pa, &o), MSID_OK);
        msid_rng_seed(&s.r, 11u);
        run_opts o2 = o;
        o2.folded = NULL;
        UT_STATUS(scene_run(&s, &pb, &o2), MSID_OK);
        const uint32_t g = nu * nu;
        for (uint32_t l = 0; l < 4; ++l) {
            const int fl = s.t.d.folded[l];
            const msid_cplx *Ga = msid_frf_G(&pa.frf, l), *Gb = msid_frf_G(&pb.frf, l);
            const msid_cplx *Ca = msid_frf_cov(&pa.frf, l), *Cb = msid_frf_cov(&pb.frf, l);
            const msid_cplx *Ka = msid_frf_cov_known_input(&pa.frf, l), *Kb = msid_frf_cov_known_input(&pb.frf, l);
            for (uint32_t k = 0; k < g; ++k)
                UT_CHECK(Ga[k].re == Gb[k].re && Ga[k].im == (fl ? -Gb[k].im : Gb[k].im), "line %u G %u", l, k);
            for (uint32_t k = 0; k < g * g; ++k)
                UT_CHECK(Ca[k].re == Cb[k].re && Ca[k].im == (fl ? -Cb[k].im : Cb[k].im) &&
                         Ka[k].re == Kb[k].re && Ka[k].im == (fl ? -Kb[k].im : Kb[k].im), "line %u cov %u", l, k);
            UT_CHECK(msid_frf_dof(&pa.frf, l) == msid_frf_dof(&pb.frf, l), "line %u", l);
        }
        pipe_free(&pa);
        pipe_free(&pb);
        scene_free(&s);
    }
}

static void check_dc_real(const msid_frf *f, const char *what)
{
    const uint32_t g = f->n_inputs * f->n_outputs;
    const msid_cplx *G = msid_frf_G(f, 0);
    for (uint32_t k = 0; k < g; ++k) UT_CHECK(G[k].im == 0.0 && isfinite(G[k].re), "%s: DC G[%u] = (%.17g, %.3g)", what, k, G[k].re, G[k].im);
}

static void test_dc_line_real(void **state)
{
    (void)state;
    const uint32_t bins[] = {0, 3, 7};
    /* SISO noiseless: value; noisy: still exactly real */
    scene s;
    scene_make(&s, dt_cfg(32, 3, bins, 1, 1), up_siso(), 300, 12u);
    pipeline pp;
    run_opts o = opts_k(1, 3);
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    double f[3];
    bin_freqs(&s.t.d, f);
    check_G(&pp.frf, &s.b.plant, f, 1e-9, "DC SISO");
    check_dc_real(&pp.frf, "SISO noiseless");
    pipe_free(&pp);
    s.b.sigma_y[0] = 0.3;
    s.b.sigma_u[0] = 0.1;
    o.K[0] = 5;
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    check_dc_real(&pp.frf, "SISO noisy");
    pipe_free(&pp);
#ifdef MSID_HAVE_FFTW
    msid_fft_fftw fw;
    UT_STATUS(msid_fft_fftw_create(&fw, 32, MSID_FFTW_ESTIMATE), MSID_OK);
    o.path = MSID_DFT_FFT;
    o.fft = &fw.be;
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    check_dc_real(&pp.frf, "SISO noisy FFTW");
    pipe_free(&pp);
    msid_fft_fftw_destroy(&fw);   /* the plan leaked (LeakSanitizer) */
    o.path = MSID_DFT_STREAM;
    o.fft = NULL;
#endif
    scene_free(&s);
    /* 2x2, Hadamard pattern (real at DC), noisy; a new design and bench, the rng runs on */
    msid_design_cfg c = dt_cfg(32, 3, bins, 2, 2);
    c.pattern = MSID_PATTERN_HADAMARD;
    const msid_plant_cfg pm = up_mimo();
    UT_STATUS(tsim_design_make(&s.t, &c), MSID_OK);
    UT_STATUS(tsim_bench_make(&s.b, &pm, 300), MSID_OK);
    s.b.sigma_y[0] = s.b.sigma_y[1] = 0.2;
    o = opts_k(2, 4);
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    check_dc_real(&pp.frf, "2x2 Hadamard");
    msid_cplx G0[4];
    msid_plant_frf(&s.b.plant, 0.0, G0);
    for (int k = 0; k < 4; ++k)
        UT_CHECK(fabs(msid_frf_G(&pp.frf, 0)[k].re - G0[k].re) < 0.1, "DC G[%d] %.4f vs %.4f", k, msid_frf_G(&pp.frf, 0)[k].re, G0[k].re);
    pipe_free(&pp);
    scene_free(&s);
}

/* ---------- covariance and dof closed forms ---------- */

static void test_covariance_siso_closed_form(void **state)
{
    (void)state;
    const uint32_t bins[] = {1, 4, 9, 15};
    scene s;
    scene_make(&s, dt_cfg(32, 4, bins, 1, 1), up_siso(), 200, 13u);
    s.b.sigma_y[0] = 0.2;
    s.b.sigma_u[0] = 0.05;
    pipeline pp;
    const uint32_t K = 7;
    run_opts o = opts_k(1, K);
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    const msid_pstats *st = pp.stats[0];
    for (uint32_t l = 0; l < 4; ++l) {
        const msid_cplx *z = msid_pstats_mean(st, l), *M = msid_pstats_scatter(st, l);
        /* G = ybar / ubar */
        const long double ur = z[0].re, ui = z[0].im, yr = z[1].re, yi = z[1].im, u2 = ur * ur + ui * ui;
        const long double gr = (yr * ur + yi * ui) / u2, gi = (yi * ur - yr * ui) / u2;
        const msid_cplx *G = msid_frf_G(&pp.frf, l);
        UT_CHECK(fabsl(G[0].re - gr) <= 1e-12L * sqrtl(gr * gr + gi * gi) && fabsl(G[0].im - gi) <= 1e-12L * sqrtl(gr * gr + gi * gi),
                 "line %u G", l);
        /* known input: (Syy / (K-1)) / (K |ubar|^2) */
        const long double cki = (M[3].re / (K - 1)) / (K * u2);
        const double got_ki = msid_frf_cov_known_input(&pp.frf, l)[0].re;
        UT_CHECK(fabsl(got_ki - cki) <= 1e-12L * cki, "line %u cov_ki %.17g vs %.17Lg", l, got_ki, cki);
        /* nonparametric: [-G 1] M [-G 1]^H / ((K-1) K |ubar|^2) */
        const long double v = (gr * gr + gi * gi) * M[0].re + M[3].re - 2.0L * (gr * M[1].re - gi * M[1].im);  /* -2 Re(G M_uy) */
        const long double cnp = v / ((K - 1) * (long double)K * u2);
        const double got = msid_frf_cov(&pp.frf, l)[0].re;
        UT_CHECK(fabsl(got - cnp) <= 1e-10L * cnp && msid_frf_cov(&pp.frf, l)[0].im == 0.0, "line %u cov %.17g vs %.17Lg", l, got, cnp);
        UT_CHECK(msid_frf_dof(&pp.frf, l) == (double)(K - 1) && msid_frf_dof_known_input(&pp.frf, l) == (double)(K - 1), "dof %g", msid_frf_dof(&pp.frf, l));
        /* pooled noise: Syy/(K-1); SNR of the mean: |ybar|^2 / (noise/K) */
        const double nz = msid_frf_noise_cov(&pp.frf, l)[0].re;
        UT_CHECK(fabs(nz - M[3].re / (K - 1)) <= 1e-14 * nz, "line %u noise", l);
        const double snr = 10.0 * log10((double)(yr * yr + yi * yi) / (nz / K));
        UT_CHECK(fabs(msid_frf_snr_db(&pp.frf, l)[0] - snr) <= 1e-9, "line %u snr %.6f vs %.6f", l, msid_frf_snr_db(&pp.frf, l)[0], snr);
    }
    pipe_free(&pp);
    scene_free(&s);
}

static void test_dof_unbalanced_mimo(void **state)
{
    (void)state;
    const uint32_t bins[] = {2, 5, 11};
    scene s;
    scene_make(&s, dt_cfg(32, 3, bins, 2, 2), up_mimo(), 200, 14u);
    s.b.sigma_y[0] = s.b.sigma_y[1] = 0.1;
    pipeline pp;
    run_opts o = opts_k(2, 4);
    o.K[1] = 7;
    UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
    for (uint32_t l = 0; l < 3; ++l) {
        /* W = Ubar^{-1} (m = nu): c_e = |row e of W|^2 / K_e */
        const msid_cplx *z0 = msid_pstats_mean(pp.stats[0], l), *z1 = msid_pstats_mean(pp.stats[1], l);
        /* Ubar = [[z0[0], z1[0]], [z0[1], z1[1]]] (column e = experiment e) */
        const msid_cplx a = z0[0], bb = z1[0], cc = z0[1], dd = z1[1];
        const msid_cplx det = ut_c(a.re * dd.re - a.im * dd.im - (bb.re * cc.re - bb.im * cc.im),
                                   a.re * dd.im + a.im * dd.re - (bb.re * cc.im + bb.im * cc.re));
        const double dn = det.re * det.re + det.im * det.im;
        /* rows of Ubar^{-1}: [d, -b]/det and [-c, a]/det */
        const double w0 = (ut_cabs(dd) * ut_cabs(dd) + ut_cabs(bb) * ut_cabs(bb)) / dn;
        const double w1 = (ut_cabs(cc) * ut_cabs(cc) + ut_cabs(a) * ut_cabs(a)) / dn;
        const double c0 = w0 / 4.0, c1 = w1 / 7.0;
        const double want = (c0 + c1) * (c0 + c1) / (c0 * c0 / 3.0 + c1 * c1 / 6.0);
        UT_CHECK(fabs(msid_frf_dof(&pp.frf, l) - want) <= 1e-9 * want, "line %u dof %.12g want %.12g", l, msid_frf_dof(&pp.frf, l), want);
        UT_CHECK(msid_frf_dof_known_input(&pp.frf, l) == 9.0, "dof_ki %g", msid_frf_dof_known_input(&pp.frf, l));
        UT_CHECK(msid_frf_dof(&pp.frf, l) < 9.0 && msid_frf_dof(&pp.frf, l) > 3.0, "dof %g", msid_frf_dof(&pp.frf, l));
    }
    pipe_free(&pp);
    scene_free(&s);
}

/* Regression: data scaled far from 1 never gives NaN/Inf results or a misleading
 * "singular" status. Inputs and outputs both scaled by 1e78 (and 1e-78): the dof is scale-free and
 * equals the unscaled one; outputs near 1e155 overflow the covariances and inputs of 1e160 or 1e-200
 * overflow/underflow |U|^2: each is MSID_E_RANGE with the line named. */
static void test_range_of_magnitudes(void **state)
{
    (void)state;
    const uint32_t bins[] = {2, 5, 11};
    scene s;
    pipeline pp;
    double dof0[3];
    const double su[] = {1.0, 1e78, 1e-78, 1.0, 1e160, 1e-200};
    const double sy[] = {1.0, 1e78, 1e-78, 1e155, 1.0, 1.0};
    for (int k = 0; k < 6; ++k) {
        scene_make(&s, dt_cfg(32, 3, bins, 2, 2), up_mimo(), 200, 14u);   /* same seed: same data each time */
        s.b.sigma_y[0] = s.b.sigma_y[1] = 0.1;
        run_opts o = opts_k(2, 4);
        o.K[1] = 7;
        o.scale_u = su[k];
        o.scale_y = sy[k];
        const msid_status st = scene_run(&s, &pp, &o);
        if (k < 3) {
            UT_STATUS(st, MSID_OK);
            for (uint32_t l = 0; l < 3; ++l) {
                const double dof = msid_frf_dof(&pp.frf, l);
                if (k == 0) dof0[l] = dof;
                UT_CHECK(isfinite(dof) && fabs(dof - dof0[l]) <= 1e-12 * dof0[l], "scale %g line %u dof %.17g vs %.17g",
                         su[k], l, dof, dof0[l]);
                UT_CHECK(isfinite(msid_frf_cov(&pp.frf, l)[0].re), "scale %g line %u cov", su[k], l);
            }
        } else {
            UT_CHECK(st == MSID_E_RANGE && pp.frf.bad_line >= 0, "u x %g, y x %g: status %s", su[k], sy[k], msid_strerror(st));
        }
        pipe_free(&pp);
        scene_free(&s);
    }
}

/* ---------- detection lines ---------- */

static void test_detection_lines(void **state)
{
    (void)state;
    /* complex bins only: DC and Nyquist are refused as detection lines (real-valued,
     * the F(2m, 2n) test would not hold there) */
    const uint32_t bins[] = {2, 5}, det[] = {9, 13, 15};
    scene s;
    scene_make(&s, dt_cfg(32, 2, bins, 1, 1), up_siso(), 200, 15u);
    s.b.sigma_y[0] = 1.0;
    const int N = 200;
    const uint32_t K = 6;
    double sum[3] = {0, 0, 0};
    int below[3] = {0, 0, 0};
    for (int run = 0; run < N; ++run) {
        pipeline pp;
        run_opts o = opts_k(1, K);
        o.n_detect = 3;
        o.detect_bins = det;
        UT_STATUS(scene_run(&s, &pp, &o), MSID_OK);
        for (uint32_t d = 0; d < 3; ++d) {
            const double p = msid_frf_detect_pvalue(&pp.frf, d)[0];
            /* independent: F = K |ybar|^2 / pooled variance ~ F(2, 2(K-1)) under H0 */
            const msid_cplx ym = msid_frf_detect_mean(&pp.frf, d)[0];
            const double var = msid_frf_detect_var(&pp.frf, d)[0];
            const double want_var = msid_pstats_scatter(pp.stats[0], 2 + d)[3].re / (K - 1);
            const double F = K * (ym.re * ym.re + ym.im * ym.im) / var;
            const double want = tsim_ftail(1, K - 1, F);
            UT_CHECK(fabs(var - want_var) <= 1e-14 * want_var && fabs(p - want) <= 1e-9 * want + 1e-15, "run %d det %u p %.17g want %.17g", run, d, p, want);
            UT_CHECK(p >= 0.0 && p <= 1.0, "p %g", p);
            sum[d] += p;
            below[d] += p < 0.1;
        }
        pipe_free(&pp);
    }
    for (int d = 0; d < 3; ++d)
        print_message("detection bin %u: mean p %.3f, P(p < 0.1) = %.3f over %d runs\n", det[d], sum[d] / N, below[d] / (double)N, N);
    for (int d = 0; d < 2; ++d) {
        const double mean = sum[d] / N;
        UT_CHECK(mean > 0.01 && mean < 0.99, "mean p %.3f", mean);
        UT_CHECK(fabs(mean - 0.5) < 5.0 * sqrt(1.0 / 12.0 / N), "det %d: mean p %.3f not uniform-like", d, mean);
        UT_CHECK(fabs(below[d] / (double)N - 0.1) < 5.0 * sqrt(0.09 / N), "det %d: P(p<0.1) = %.3f", d, below[d] / (double)N);
    }
    /* a sinusoid at detection bin 9 */
    for (uint32_t m = 1; m <= 2; ++m) {
        tsim_design t2;
        msid_design_cfg c2 = dt_cfg(32, 2, bins, 1, m);
        UT_STATUS(tsim_design_make(&t2, &c2), MSID_OK);
        pipeline pp;
        run_opts o = opts_k(m, K);
        o.n_detect = 3;
        o.detect_bins = det;
        o.inj_amp = 3.0;
        o.inj_bin = 9;
        UT_STATUS(pipe_run(&pp, &t2, &s.b, &o, &s.r), MSID_OK);
        const double p9 = msid_frf_detect_pvalue(&pp.frf, 0)[0], p13 = msid_frf_detect_pvalue(&pp.frf, 1)[0];
        UT_CHECK(p9 < 1e-6 && p13 > 1e-6, "m=%u p(bin 9) %.3g p(bin 13) %.3g", m, p9, p13);
        const msid_cplx *dm = msid_frf_detect_mean(&pp.frf, 0);
        for (uint32_t e = 0; e < m; ++e)
            UT_CHECK(fabs(ut_cabs(dm[e]) - 48.0) < 10.0, "m=%u e=%u |mean| %.3f (A P/2 = 48)", m, e, ut_cabs(dm[e]));
        pipe_free(&pp);
        tsim_design_free(&t2);
    }
    scene_free(&s);
}

static void test_init_errors(void **state)
{
    (void)state;
    msid_frf f;
    msid_frf_cfg c = {32, 2, 2, 3, 4, 1, NULL};
    const size_t need = msid_frf_mem_size(&c);
    UT_CHECK(need > 0, "%zu", need);
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    UT_STATUS(msid_frf_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_frf_init(&f, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_frf_init(&f, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_frf_init(&f, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_frf_init(&f, &c, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_frf_init(&f, &c, mem + 64, need), MSID_OK);
    msid_frf_cfg e = c;
    e.n_lines = 0;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_NO_LINES);
    UT_CHECK(msid_frf_mem_size(&e) == 0 && msid_frf_mem_size(NULL) == 0, "%d", 0);
    e = c; e.period = 1;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_PERIOD);
    e = c; e.n_inputs = 0;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_outputs = MSID_MAX_OUTPUTS + 1u;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_experiments = MSID_MAX_EXPERIMENTS + 1u;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_experiments = 1;
    UT_STATUS(msid_frf_init(&f, &e, mem, need), MSID_E_EXPERIMENTS);
    tsim_free(mem);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_noiseless_siso),
        cmocka_unit_test(test_noiseless_mimo),
        cmocka_unit_test(test_singular_identical_experiments),
        cmocka_unit_test(test_singular_one_line),
        cmocka_unit_test(test_few_periods_pipeline),
        cmocka_unit_test(test_folded_lines_conjugate),
        cmocka_unit_test(test_dc_line_real),
        cmocka_unit_test(test_covariance_siso_closed_form),
        cmocka_unit_test(test_dof_unbalanced_mimo),
        cmocka_unit_test(test_range_of_magnitudes),
        cmocka_unit_test(test_detection_lines),
        cmocka_unit_test(test_init_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
