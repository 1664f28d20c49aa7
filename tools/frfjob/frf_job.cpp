#include "frf_job_detail.hpp"
#include "msid_frf_job.hpp"
#include "frf_file.hpp"   // msid-frf/1: the one writer (tools/frffile)
#include "periodicity.hpp"
#include "msid_cancel.hpp"
#include "msid_fftw_planner.hpp"
#include "msid_mapped_pages.hpp"

extern "C" {
#include "msid/msid_fft_fftw.h"
}
#include <algorithm>
#include <cmath>
#include <exception>
#include <system_error>
#include <thread>

namespace msidjob {


static_assert(sizeof(std::complex<double>) == sizeof(msid_cplx), "msid_cplx is {re, im}");

Json cmat_json(const msid_cplx *a, size_t rows, size_t cols)
{
    return msidfrf::cmat(reinterpret_cast<const std::complex<double> *>(a), rows, cols);
}

static msidfrf::Header header_of(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m)
{
    msidfrf::Header h;
    h.period = rq.period;
    h.nu = nu;
    h.ny = ny;
    h.m = m;
    h.ct = !rq.omega.empty();
    h.sample_time = rq.sample_time;
    h.fs = rq.fs;
    h.input_names = rq.input_names;
    h.output_names = rq.output_names;
    h.input_units = rq.input_units;
    h.output_units = rq.output_units;
    return h;
}

Json frf_header(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m) { return msidfrf::header(header_of(rq, nu, ny, m)); }

// The position fields of line l (msidfrf::position() gives their tree).
static msidfrf::Position line_pos(const FrfRequest &rq, size_t l)
{
    msidfrf::Position p;
    p.bin = rq.bins[l];
    p.period = rq.period;
    p.ct = !rq.omega.empty();
    if (p.ct) {
        p.omega = rq.omega[l];
        p.folded = rq.folded[l] != 0;
    }
    p.fs = rq.fs;
    return p;
}

Json line_position(const FrfRequest &rq, size_t l) { return msidfrf::position(line_pos(rq, l)); }

void request_from_design(FrfRequest &rq, const Design &D)
{
    request_from_core_design(rq, D.d);
    rq.design = &D;
}

void request_from_core_design(FrfRequest &rq, const msid_design &d)
{
    rq.period = d.period;
    rq.bins.assign(d.bins, d.bins + d.n_lines);
    if (d.is_ct) {
        rq.folded.assign(d.folded, d.folded + d.n_lines);
        rq.omega.assign(d.omega, d.omega + d.n_lines);
        rq.sample_time = d.sample_time;
    }
}

// RAII for the FFTW backend.
struct Fftw {
    msid_fft_fftw f{};
    bool on = false;
    ~Fftw()
    {
        if (!on) return;
        fftw_planner_ready();
        msid_fft_fftw_destroy(&f);
    }
};

void validate_lines(const FrfRequest &rq)
{
    if (rq.period < MSID_MIN_PERIOD || rq.period > MSID_MAX_PERIOD)
        throw Error(fmt("period %u is outside [%u, %u] samples", rq.period, MSID_MIN_PERIOD, MSID_MAX_PERIOD));
    if (rq.bins.empty()) throw Error("no lines given");
    std::vector<int32_t> seen(rq.period / 2 + 1, -1);
    for (size_t l = 0; l < rq.bins.size(); ++l) {
        const uint32_t b = rq.bins[l];
        if ((uint64_t)b * 2 >= rq.period)
            throw Error(fmt("line %u is at or beyond Nyquist: lines must be below P/2 = %g", b, rq.period / 2.0));
        if (seen[b] >= 0) throw Error(fmt("line %u is given twice", b));
        seen[b] = (int32_t)l;
    }
    for (uint32_t b : rq.detect) {
        if (b == 0 || (uint64_t)b * 2 >= rq.period)
            throw Error(fmt("detection line %u must lie strictly between DC and Nyquist (0 < bin < %g)", b,
                            rq.period / 2.0));
        if (seen[b] >= 0) throw Error(fmt("detection line %u is an excited line or given twice", b));
        seen[b] = 1 << 30;
    }
}

void check_records(const FrfRequest &rq, const std::vector<Record> &recs, bool count)
{
    if (recs.empty()) throw Error("no experiment files given (--experiment)");
    const uint32_t nu = recs[0].nu, ny = recs[0].ny, m = (uint32_t)recs.size();
    for (const auto &r : recs)
        if (r.nu != nu || r.ny != ny)
            throw Error(fmt("'%s' has %u inputs and %u outputs but '%s' has %u and %u", r.path.c_str(), r.nu, r.ny,
                            recs[0].path.c_str(), nu, ny));
    if (m > MSID_MAX_EXPERIMENTS) throw Error(fmt("%u experiments: at most %u are supported", m, MSID_MAX_EXPERIMENTS));
    if (count && m < nu)
        throw Error(fmt("%u inputs need at least %u experiments (one file each); got %u", nu, nu, m));
    if (rq.design) {
        if (rq.design->d.n_inputs != nu)
            throw Error(fmt("the design has %u inputs but the files have %u input columns", rq.design->d.n_inputs, nu));
        if (count && rq.design->d.n_experiments != m)
            throw Error(fmt("the design has %u experiments but %u experiment files are given",
                            rq.design->d.n_experiments, m));
    }
}

uint64_t record_periods(const Record &r, const FrfRequest &rq, uint32_t min_used)
{
    const uint32_t P = rq.period;
    const uint64_t K = r.n_rows / P;
    if (K < min_used + (uint64_t)rq.skip)
        throw Error(fmt("'%s' holds %llu whole period(s) of %u samples (%zu samples)%s: at least %s",
                        r.path.c_str(), (unsigned long long)K, P, r.n_rows,
                        rq.skip ? fmt(", %u skipped", rq.skip).c_str() : "",
                        min_used >= 2 ? K == 1u + rq.skip ? "2 usable periods are needed to estimate a covariance (random-"
                                                            "phase realisations of one period each: --realisations R)"
                                                          : "2 usable periods are needed to estimate a covariance"
                                      : "1 usable period is needed"));
    if (K > MAX_RECORD_PERIODS) throw Error(fmt("'%s' holds too many periods", r.path.c_str()));
    return K;
}

void on_lanes(uint32_t m, uint32_t lanes, const std::function<void(uint32_t lane, uint32_t e)> &one)
{
    std::vector<std::exception_ptr> err(m);
    auto lane_run = [&](uint32_t lane) {
        for (uint32_t e = lane; e < m; e += lanes) {
            try {
                one(lane, e);
            } catch (...) {
                err[e] = std::current_exception();
                return;   // this lane's later experiments are never reported
            }
        }
    };
    std::thread th;
    if (lanes == 2) {
        try {
            // the second lane asks the caller's cancellation token too
            th = std::thread([&lane_run, c = msidutil::current_cancel()] {
                const msidutil::CancelScope scope(c);
                lane_run(1u);
            });
        } catch (const std::system_error &) {   // no thread to be had: lane 1 after lane 0
        }
    }
    lane_run(0);
    if (th.joinable()) th.join();
    else if (lanes == 2) lane_run(1);
    for (const auto &x : err)
        if (x) std::rethrow_exception(x);
}

void measure_records(FrfJob &job, const FrfRequest &rq, const std::vector<Record> &recs)
{
    const uint32_t m = (uint32_t)recs.size(), P = rq.period;
    const size_t C = recs[0].nu + recs[0].ny;
    on_lanes(m, job.lanes(), [&](uint32_t lane, uint32_t e) {
        msid_meas &ms = *job.meas(lane);
        const Record &r = recs[e];
        check(msid_meas_begin(&ms, e), "experiment " + std::to_string(e + 1));
        const size_t nwhole = r.n_rows / P * P;
        // Blocks of 256 KiB (the results do not depend on the block size), a checkpoint after each
        // (a caller's token may end a long record early). A record read without its NaN/Inf scan
        // (read_experiments' defer_finite) is scanned block by block just before the block is pushed,
        // while it is in cache, the rows after the last whole period at the end: the reader's
        // message, no sample used unchecked.
        // On the streaming DFT path a row costs a rotation per line and channel: at most 2^20 of
        // those between checkpoints (milliseconds).
        size_t cap = std::max<size_t>(1, ((size_t)256 << 10) / (8 * C));
        if (job.streaming()) cap = std::min(cap, std::max<size_t>(64, ((size_t)1 << 20) / ((rq.bins.size() + rq.detect.size()) * C)));
        const size_t blk = std::min<size_t>(rq.block ? rq.block : nwhole, cap);
        for (size_t k = 0; k < nwhole; k += blk) {
            const size_t n = std::min(blk, nwhole - k);
            if (r.finite_unchecked) check_finite(r, k, n);
            check(msid_meas_push(&ms, r.data() + k * C, n), "'" + r.path + "'");
            // a record read in place from a mapped file: the pages pushed go back to the kernel
            if (r.view) msidrec::release_mapped(r.data() + k * C, n * C * sizeof(double));
            msidutil::checkpoint(msidutil::Step::rows, n, "the FRF job");
        }
        if (r.finite_unchecked) check_finite(r, nwhole, r.n_rows - nwhole);
        check(msid_meas_end(&ms, nullptr), "'" + r.path + "'");
    });
}

FrfOutcome run_frf(const FrfRequest &rq, const std::vector<Record> &recs)
{
    std::vector<std::string> notes;
    validate_lines(rq);
    check_records(rq, recs);
    const uint32_t nu = recs[0].nu, ny = recs[0].ny, m = (uint32_t)recs.size(), P = rq.period;
    uint32_t maxK = 0;
    for (const auto &r : recs) {
        const uint64_t K = record_periods(r, rq), left = r.n_rows % P;
        if (left)
            notes.push_back(fmt("'%s': %llu samples after the last whole period are not used", r.path.c_str(),
                                (unsigned long long)left));
        if (K > maxK) maxK = (uint32_t)K;
    }
    // The input diagnostics on the samples (non-periodic input, wrong period; docs/statistics.md
    // "Input periodicity"), for every caller of the periodic job on records.
    if (!rq.inputs_checked) check_periodic_inputs(P, rq.skip, rq.bins, recs);
    // Two experiments at once on two lanes (threads), each experiment's statistics the same bits as
    // measured alone; an error is that of the first failing experiment in file order, as serially.
    const uint32_t lanes = m >= 2 && std::thread::hardware_concurrency() >= 2 ? 2 : 1;
    FrfJob job(rq, nu, ny, m, maxK, maxK, lanes);
    measure_records(job, rq, recs);
    std::vector<ExpSource> src;
    for (const Record &r : recs) src.push_back({r.path, r.n_rows, r.n_rows / P, r.n_rows % P});
    return job.finish(src, notes);
}

struct FrfJob::Impl {
    FrfRequest rq;
    uint32_t nu, ny, m;
    Mem mtw, mm;
    uint32_t history = 0;   // the transient test's periods per experiment
    msid_twiddle tw{};
    std::string dft_path;
    struct Lane {
        Mem mm;
        Fftw fftw;
        msid_meas ms{};
    };
    std::vector<std::unique_ptr<Lane>> lane;
};

FrfJob::~FrfJob() = default;
msid_meas *FrfJob::meas(uint32_t lane) { return &p_->lane.at(lane)->ms; }
uint32_t FrfJob::lanes() const { return (uint32_t)p_->lane.size(); }
bool FrfJob::streaming() const { return p_->dft_path == "stream"; }

FrfJob::FrfJob(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, uint32_t maxK, uint32_t history,
               uint32_t lanes)
    : p_(std::make_unique<Impl>())
{
    if (lanes < 1 || lanes > 2) throw Error("internal error: 1 or 2 measurement lanes");
    if (nu > MSID_MAX_INPUTS || ny > MSID_MAX_OUTPUTS)
        throw Error(fmt("%u inputs and %u outputs: msid estimates at most %u inputs and %u outputs", nu, ny, MSID_MAX_INPUTS,
                        MSID_MAX_OUTPUTS));
    validate_lines(rq);
    Impl &I = *p_;
    I.rq = rq;
    I.nu = nu;
    I.ny = ny;
    I.m = m;
    const uint32_t P = rq.period;
    // Twiddle table (stream path only: P values of msid_cis_turns, ~0.1 ms at P = 4096) and FFTW
    // backend (dense path).
    const size_t L = rq.bins.size(), Ld = rq.detect.size();
    msid_dft_path path = rq.path;
    if (path == MSID_DFT_AUTO) path = msid_linedft_choose(P, (uint32_t)(L + Ld), nu + ny, 1);
    if (path != MSID_DFT_FFT) {
        I.mtw = Mem(msid_twiddle_mem_size(P));
        check(msid_twiddle_init(&I.tw, P, I.mtw.p, I.mtw.n), "twiddle table");
    }
    I.dft_path = path == MSID_DFT_FFT ? "fft" : "stream";

    msid_meas_cfg mc{};
    mc.period = P;
    mc.n_inputs = nu;
    mc.n_outputs = ny;
    mc.n_experiments = m;
    mc.n_lines = (uint32_t)L;
    mc.bins = rq.bins.data();
    mc.n_detect = (uint32_t)Ld;
    mc.detect_bins = Ld ? rq.detect.data() : nullptr;
    mc.twiddle = path != MSID_DFT_FFT ? &I.tw : nullptr;
    mc.path = path;
    mc.fft = nullptr;   // per lane
    mc.skip_periods = rq.skip;
    mc.transient = maxK >= (uint64_t)rq.skip + 3 ? rq.transient : MSID_TRANSIENT_OFF;
    // The history holds at most HISTORY_BYTES per experiment: a longer record's later periods are
    // used untested (beyond_history), so memory does not grow with the record.
    const uint32_t cap = (uint32_t)std::max(3.0, std::floor(HISTORY_BYTES / (16.0 * (double)(L + Ld) * (nu + ny))));
    if (history > cap) {
        history = cap;
        mc.beyond_history = 1;
    }
    I.history = history;
    mc.max_periods = mc.transient != MSID_TRANSIENT_OFF ? history : 0;
    mc.alpha = rq.alpha;
    if (path == MSID_DFT_FFT) fftw_planner_ready();   // msid frf's warm-up plan (msid_fftw_planner.hpp) has set the planner up
    for (uint32_t k = 0; k < lanes; ++k) {   // FFTW plans are made here, in one thread (its planner is not thread-safe)
        I.lane.push_back(std::make_unique<Impl::Lane>());
        Impl::Lane &ln = *I.lane.back();
        if (path == MSID_DFT_FFT) {
            check(msid_fft_fftw_create(&ln.fftw.f, P, MSID_FFTW_LINES), "FFTW plan");
            ln.fftw.on = true;
        }
        mc.fft = ln.fftw.on ? &ln.fftw.f.be : nullptr;
        const size_t nm = msid_meas_mem_size(&mc);
        if (nm == 0) throw Error("measurement dimensions out of range");
        ln.mm = Mem(nm);
        check(msid_meas_init(&ln.ms, &mc, ln.mm.p, ln.mm.n), "measurement setup");
    }
}

// --lines auto (FrfRequest::screen_lines): the lines whose neighbours leave the input too weak, the median
// of the input SNR (of the period mean) at the SCREEN_NEIGHBOURS lines on either side below
// MIN_INPUT_SNR_DB; none for a line without neighbours. The line's own data are left out of its test:
// lines kept because their own noise happened to look small are those whose covariance is too small too
// (their regions would under-cover); the neighbours' noise is independent of the line's, and the
// input's spectrum, shaped by the plant and a controller, changes little from one line to the next.
static std::vector<uint8_t> screened_weak_lines(const msid_frf &f, size_t L)
{
    std::vector<double> snr(L), nb;
    for (size_t l = 0; l < L; ++l) snr[l] = msid_frf_input_snr_db(&f, (uint32_t)l);
    std::vector<uint8_t> weak(L, 0);
    for (size_t l = 0; l < L; ++l) {
        nb.clear();
        for (size_t j = l >= SCREEN_NEIGHBOURS ? l - SCREEN_NEIGHBOURS : 0; j < L && j <= l + SCREEN_NEIGHBOURS; ++j)
            if (j != l) nb.push_back(snr[j]);
        if (nb.empty()) continue;
        std::sort(nb.begin(), nb.end());   // +-inf for an input without power or without noise; never NaN
        const size_t n = nb.size();
        const double med = n % 2 ? nb[n / 2] : 0.5 * (nb[n / 2 - 1] + nb[n / 2]);
        weak[l] = !(med >= MIN_INPUT_SNR_DB);
    }
    return weak;
}

// The lines the FRF cannot use: the core's (msid_frf_compute gave MSID_E_SINGULAR: `singular`) and, with
// --lines auto, those screened_weak_lines() names. The message names the first, as it always has for the
// core's; every one is listed for --lines auto (UnusableLines).
static UnusableLines unusable_lines(const msid_frf &f, const FrfRequest &rq, uint32_t nu, bool singular)
{
    const size_t L = rq.bins.size();
    const std::vector<uint8_t> screened = rq.screen_lines ? screened_weak_lines(f, L) : std::vector<uint8_t>(L, 0);
    std::string msg;
    if (singular) {
        const uint32_t l = (uint32_t)f.bad_line;
        if (msid_frf_line_status(&f, l) == MSID_LINE_UNEXCITED)
            msg = fmt("the inputs do not excite line %u (bin %u): its weakest input direction is %.1f dB below "
                      "the strongest line and %.1f dB above the input noise; drop the line or excite it",
                      l + 1, rq.bins[l], -msid_frf_input_rel_db(&f, l), msid_frf_input_snr_db(&f, l));
        else if (nu == 1)   // one input: a 1 x m input matrix is singular only where the input has no power
            msg = fmt("the input has no power at line %u (bin %u): drop the line or excite it (--lines auto "
                      "finds the excited bins)",
                      l + 1, rq.bins[l]);
        else
            msg = fmt("the input matrix is singular at line %u (bin %u, condition number %.3g): the experiments do "
                      "not excite the %u inputs independently there",
                      l + 1, rq.bins[l], msid_frf_cond(&f, l), nu);
    } else {
        for (size_t l = 0; l < L && msg.empty(); ++l)
            if (screened[l])
                msg = fmt("the inputs barely excite line %zu (bin %u) and its neighbours: the input SNR of the lines "
                          "around it is below %g dB",
                          l + 1, rq.bins[l], MIN_INPUT_SNR_DB);
    }
    UnusableLines u(msg);
    for (uint32_t k = 0; k < (uint32_t)L; ++k) {
        const int s = msid_frf_line_status(&f, k);
        // one input without power is the weak case too: no input direction to speak of
        if (s == MSID_LINE_UNEXCITED || (s != MSID_LINE_OK && nu == 1) || (s == MSID_LINE_OK && screened[k]))
            u.weak.push_back(k);
        else if (s != MSID_LINE_OK) u.dependent.push_back(k);
    }
    return u;
}

// The core's FRF as the typed result: every array copied out of the core's memory (freed with the job).
static FrfResult frf_result(const msid_frf &f, const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, uint64_t used,
                            uint64_t rejected, const std::string &dft_path, std::vector<msidfrf::Experiment> exps)
{
    const size_t L = rq.bins.size(), Ld = rq.detect.size(), g = (size_t)nu * ny;
    FrfResult r;
    r.header = header_of(rq, nu, ny, m);
    r.periods_used = used;
    r.periods_rejected = rejected;
    r.dft_path = dft_path;
    auto cplx = [](const msid_cplx *a) { return reinterpret_cast<const std::complex<double> *>(a); };
    auto put = [](std::vector<std::complex<double>> &v, const std::complex<double> *a, size_t n) { v.insert(v.end(), a, a + n); };
    put(r.noise_cov, cplx(msid_frf_noise_cov_time(&f)), (size_t)ny * ny);
    r.experiments = std::move(exps);
    r.pos.reserve(L);
    r.G.reserve(L * g);
    r.cov.reserve(L * g * g);
    r.cov_ki.reserve(L * g * g);
    r.noise.reserve(L * ny * ny);
    r.snr.reserve(L * ny);
    for (uint32_t l = 0; l < (uint32_t)L; ++l) {
        r.pos.push_back(line_pos(rq, l));
        put(r.G, cplx(msid_frf_G(&f, l)), g);
        put(r.cov, cplx(msid_frf_cov(&f, l)), g * g);
        r.dof.push_back(msid_frf_dof(&f, l));
        put(r.cov_ki, cplx(msid_frf_cov_known_input(&f, l)), g * g);
        r.dof_ki.push_back(msid_frf_dof_known_input(&f, l));
        put(r.noise, cplx(msid_frf_noise_cov(&f, l)), (size_t)ny * ny);
        r.snr.insert(r.snr.end(), msid_frf_snr_db(&f, l), msid_frf_snr_db(&f, l) + ny);
        r.cond.push_back(msid_frf_cond(&f, l));
        r.input_snr.push_back(msid_frf_input_snr_db(&f, l));
    }
    for (uint32_t d = 0; d < (uint32_t)Ld; ++d) {
        r.detect_bins.push_back(rq.detect[d]);
        put(r.detect_mean, cplx(msid_frf_detect_mean(&f, d)), (size_t)m * ny);
        r.detect_var.insert(r.detect_var.end(), msid_frf_detect_var(&f, d), msid_frf_detect_var(&f, d) + ny);
        r.detect_p.insert(r.detect_p.end(), msid_frf_detect_pvalue(&f, d), msid_frf_detect_pvalue(&f, d) + ny);
    }
    return r;
}

FrfOutcome FrfJob::finish(const std::vector<ExpSource> &src, std::vector<std::string> notes)
{
    Impl &I = *p_;
    const FrfRequest &rq = I.rq;
    const uint32_t nu = I.nu, ny = I.ny, m = I.m, P = rq.period;
    const size_t L = rq.bins.size(), Ld = rq.detect.size();
    FrfOutcome out;
    out.notes = std::move(notes);
    out.dft_path = I.dft_path;
    // Per-experiment accounting, and enough periods left?
    std::vector<msidfrf::Experiment> exps;
    uint64_t used = 0, rejected = 0;
    std::vector<const msid_pstats *> ps(m);
    for (uint32_t e = 0; e < m; ++e) {
        const ExpSource &r = src[e];
        ps[e] = msid_meas_stats(&I.lane[e % I.lane.size()]->ms, e);
        const msid_pstats_counts c = msid_pstats_get_counts(ps[e]);
        std::vector<uint32_t> flagged, dropped;
        const double dp = msid_pstats_drift_pvalue(ps[e]);
        std::string flagged_list;
        size_t n_listed = 0;
        bool leading = true;   // every period before this one flagged too: the record's start
        for (uint32_t k = 0; k < msid_pstats_history(ps[e]); ++k) {
            double pv;
            const int s = msid_pstats_period_state(ps[e], k, &pv);
            // period number in the record, counted from 1: the same in the notes and the file
            const uint32_t num = msid_pstats_period_number(ps[e], k) + 1;
            leading = leading && s >= 1;
            if (s >= 1) flagged.push_back(num);
            if (s == 2) dropped.push_back(num);
            if (s >= 1 && c.drift) {
                flagged_list += (flagged_list.empty() ? "" : ", ") + std::to_string(num);
                ++n_listed;
            } else if (s >= 1 && leading)
                out.notes.push_back(fmt("'%s': period %u departs from the others more than the noise explains "
                                        "(p = %.2g): likely a start-up transient%s",
                                        r.source.c_str(), num, pv,
                                        s == 2 ? "; dropped" : "; kept (use --skip-periods or --transient drop)"));
            else if (s >= 1)   // after periods that passed: not the start-up
                out.notes.push_back(fmt("'%s': period %u departs from the others more than the noise explains "
                                        "(p = %.2g), after periods that do not: a disturbance during the record "
                                        "(a knock, a load change, a sensor glitch), not a start-up transient%s",
                                        r.source.c_str(), num, pv,
                                        s == 2 ? "; dropped" : "; kept (use --transient drop)"));
        }
        if (c.drift)
            out.notes.push_back(fmt("'%s': the spectra drift through the whole record (a trend over the last %u of %u "
                                    "periods, p = %.2g): drift, not a start-up transient; no period dropped%s%s. The "
                                    "FRF is an average over the drift; check the plant and sensors (temperature, "
                                    "offsets, gain changes) or measure shorter records",
                                    r.source.c_str(), msid_pstats_history(ps[e]) - msid_pstats_history(ps[e]) / 2,
                                    msid_pstats_history(ps[e]), dp,
                                    flagged_list.empty() ? "" : n_listed == 1 ? "; period " : "; periods ",
                                    flagged_list.empty() ? ""
                                                         : (flagged_list + (n_listed == 1 ? " departs" : " depart") +
                                                            " most from the mean").c_str()));
        msidfrf::Experiment x;
        x.source = r.source;
        x.samples = r.samples;
        x.periods_total = r.periods_total;
        x.periods_skipped = c.skipped;
        x.periods_used = c.used;
        x.periods_gap = c.gap;
        x.periods_nonfinite = c.nonfinite;
        x.transient_tested = c.tested != 0;
        x.periods_untested = c.untested;
        // a transient test that could not run is said, never left for a pass: transient_tested false alone reads
        // like a clean record (it needs 3 periods, msid_pstats_detect; from 3 to 5 it runs and only the drift test,
        // which needs 6, does not: drift_tested false)
        if (rq.transient != MSID_TRANSIENT_OFF && !c.tested && c.used >= 2)
            out.notes.push_back(fmt("'%s': the start-up transient was not tested (nor drift): the transient test "
                                    "needs 3 periods, %u were used; the FRF holds whatever settling is in them "
                                    "(measure more periods, or skip the settling)",
                                    r.source.c_str(), c.used));
        if (c.untested)
            out.notes.push_back(fmt("'%s': the transient and drift tests covered the first %u of %u used periods (their "
                                    "history holds %.0f MiB per experiment); the last %u are in the FRF untested",
                                    r.source.c_str(), msid_pstats_history(ps[e]), c.used, HISTORY_BYTES / 1048576.0,
                                    c.untested));
        // a period whose spectrum overflowed (samples near 1e308) or held NaN/Inf is rejected: said, as
        // the gaps of a device are, not only counted
        if (c.nonfinite && c.used >= 2)
            out.notes.push_back(fmt("'%s': %u period(s) rejected: NaN or Inf in their samples or line spectra (samples "
                                    "beyond double precision's range, e.g. near 1e308, overflow the DFT)",
                                    r.source.c_str(), c.nonfinite));
        x.transient_flagged = flagged;
        x.transient_dropped = dropped;
        x.drift_block = true;
        x.drift_tested = c.drift_tested != 0;
        x.drift = c.drift != 0;
        x.drift_p_value = dp;
        x.leftover_samples = r.leftover;
        exps.push_back(std::move(x));
        used += c.used;
        rejected += c.gap + c.nonfinite + c.transient_dropped;
        if (c.used < 2) {   // which rule rejected them: the fix differs (the link, the data, the settling)
            std::string why;
            auto add = [&](uint32_t n, const char *what) {
                if (n) why += fmt("%s%u %s", why.empty() ? ": " : ", ", n, what);
            };
            add(c.gap, "with samples missing or out of order");
            add(c.nonfinite, "with NaN/Inf samples (a device sends those for values its sample encoding cannot "
                             "carry, e.g. beyond the int16 range at its scale: a larger scale or smaller amplitudes)");
            add(c.transient_dropped, "dropped by the transient test");
            throw Error(fmt("'%s': only %u usable period(s) after skipping %u and rejecting %u%s: at least 2 are needed",
                            r.source.c_str(), c.used, c.skipped, c.gap + c.nonfinite + c.transient_dropped, why.c_str()));
        }
    }

    // Every source (files, msid measure, msid modbus|can measure): is the input periodic at the
    // lines? Said before the FRF, whose singular-line message would hide the cause.
    {
        std::vector<std::string> names;
        for (const auto &r : src) names.push_back(r.source);
        check_periodic_lines(ps.data(), m, nu, P, rq.bins, names);
    }
    msid_frf_cfg fc{};
    fc.period = P;
    fc.n_inputs = nu;
    fc.n_outputs = ny;
    fc.n_experiments = m;
    fc.n_lines = (uint32_t)L;
    fc.n_detect = (uint32_t)Ld;
    fc.folded = rq.folded.empty() ? nullptr : rq.folded.data();
    const size_t nf = msid_frf_mem_size(&fc);
    if (nf == 0) throw Error("FRF dimensions out of range");
    Mem mf(nf);
    msid_frf f;
    check(msid_frf_init(&f, &fc, mf.p, mf.n), "FRF setup");
    msid_status st = msid_frf_compute(&f, ps.data());
    if (st == MSID_E_SINGULAR || (rq.screen_lines && st == MSID_OK)) {
        UnusableLines u = unusable_lines(f, rq, nu, st == MSID_E_SINGULAR);
        if (st == MSID_E_SINGULAR || !u.weak.empty() || !u.dependent.empty()) throw u;
    }
    if (st == MSID_E_FEW_PERIODS)
        throw Error(fmt("'%s': fewer than 2 usable periods", src[(size_t)f.bad_experiment].source.c_str()));
    check(st, "FRF");

    out.frf = frf_result(f, rq, nu, ny, m, used, rejected, out.dft_path, std::move(exps));
    return out;
}

Json &FrfOutcome::tree()
{
    if (doc.is_null()) {
        doc = frf_document(frf);
        frf = FrfResult();
    }
    return doc;
}

uint64_t FrfOutcome::periods_used() const
{
    return doc.is_null() ? frf.periods_used : doc.at("periods_used").get<uint64_t>();
}

uint64_t FrfOutcome::periods_rejected() const
{
    return doc.is_null() ? frf.periods_rejected : doc.at("periods_rejected").get<uint64_t>();
}

void write_outcome(const std::string &path, const FrfOutcome &o, bool durable)
{
    if (o.doc.is_null()) write_frf_file(path, o.frf, durable);
    else msidfmt::write_json_file(path, o.doc, durable);
}

}  // namespace msidjob
