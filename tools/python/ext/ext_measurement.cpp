// msid._msid.Measurement: the FRF job fed block by block (msidjob::FrfJob), for samples that
// arrive from a device callback. The core's line DFT and period statistics give the same bits
// whatever the block sizes, so the result equals msid.frf on the whole records.
#include "ext.hpp"
#include "ext_call.hpp"

#include "frf_distortion.hpp"
#include "msid_host_util.hpp"

#include <cmath>
#include <mutex>

namespace msidpy {

using msidjob::FrfJob;
using msidjob::FrfOutcome;
using msidutil::check;
using msidutil::fmt;
using msidutil::UsageError;

class Measurement {
public:
    Measurement(py::object design, const py::dict &opts, uint32_t max_periods)
        : design_(std::move(design)), D_(design_.cast<const PyDesign &>().d.get()), max_periods_(max_periods)
    {
        request_from_design(rq_, *D_);
        request_options(opts, rq_, D_);
        m_ = D_->d.n_experiments;
        nu_ = D_->d.n_inputs;
        rows_.assign(m_, 0);
        refused_.assign(m_, 0);
        closed_.assign(m_, 0);
        if (rq_.transient != MSID_TRANSIENT_OFF && max_periods_ < 3)
            throw UsageError("max_periods must be at least 3 (the transient test compares periods), or transient='off'");
    }

    // The job frees its FFTW plans under the planner lock: now when it is free or this thread's (a
    // progress callable of msid.measure), else by the thread that holds it. With the GIL held (also at
    // the interpreter's exit), so this never waits.
    ~Measurement()
    {
        FrfJob *j = job_.release();
        if (j) job_lock().release_later([j] { delete j; });
    }
    Measurement(const Measurement &) = delete;
    Measurement &operator=(const Measurement &) = delete;

    // Rows [u1..u_nu, y1..y_ny] of experiment e, any number (none: nothing happens). Pushed in blocks
    // of at most 256 KiB, a checkpoint after each: Ctrl-C keeps the blocks before it (progress counts
    // them) and raises KeyboardInterrupt.
    void push(const py::array &a, uint32_t e)
    {
        size_t n = 0, C = 0;
        const double *x = samples_of(a, n, C);
        without_gil({false, true, "Measurement.push"}, [&] {
            std::lock_guard<std::mutex> lock(mu_);
            if (done_) throw UsageError("this measurement is finished (frf() was called): start a new one");
            if (e >= m_) throw UsageError(fmt("experiment %u: the design has %u (counted from 0)", e, m_));
            start(C);
            if (C != (size_t)nu_ + ny_)
                throw msidjob::Error(fmt("experiment %u: a block of %zu columns, but the samples have %u (u1..u%u, "
                                         "y1..y%u)", e, C, nu_ + ny_, nu_, ny_));
            if (n == 0) return;
            open(e);
            scan_finite(x, n, e);
            const size_t blk = std::max<size_t>(1, ((size_t)256 << 10) / (8 * C));
            for (size_t k = 0; k < n; k += blk) {
                const size_t b = std::min(blk, n - k);
                msid_status st = msid_meas_push(job_->meas(), x + k * C, b);
                if (st == MSID_E_CAPACITY)
                    throw UsageError(fmt("experiment %u: more than max_periods = %u periods: the transient test keeps "
                                         "every period; give a larger max_periods, or transient='off'", e, max_periods_));
                check(st, fmt("experiment %u", e));
                rows_[e] += b;
                msidutil::checkpoint(msidutil::Step::rows, b, "Measurement.push");
            }
        });
    }

    std::vector<uint64_t> progress()
    {
        // never wait for the lock with the GIL held (a push holding it may ask Python for Ctrl-C)
        return without_gil({false, false, "Measurement.progress"}, [&] {
            std::lock_guard<std::mutex> lock(mu_);
            std::vector<uint64_t> p(m_);
            for (uint32_t e = 0; e < m_; ++e) p[e] = rows_[e] / rq_.period;
            return p;
        });
    }

    py::dict frf()
    {
        const FrfOutcome o = without_gil({false, true, "Measurement.frf"}, [&] {
            std::lock_guard<std::mutex> lock(mu_);
            if (done_) throw UsageError("this measurement is finished (frf() was called): start a new one");
            if (!job_) throw msidjob::Error("no samples were pushed");
            done_ = true;
            for (uint32_t e = 0; e < m_; ++e)   // what the refused blocks took away, before the core's counts
                if (rows_[e] / rq_.period < 2 && refused_[e])
                    throw msidjob::Error(fmt("experiment %u: only %llu usable period(s) were taken (at least 2 are "
                                             "needed): %llu rows came in blocks refused for NaN or Inf",
                                             e, (unsigned long long)(rows_[e] / rq_.period),
                                             (unsigned long long)refused_[e]));
            if (open_ >= 0) check(msid_meas_end(job_->meas(), nullptr), fmt("experiment %d", open_));
            std::vector<msidjob::ExpSource> src;
            std::vector<std::string> notes;
            for (uint32_t e = 0; e < m_; ++e) {
                const uint64_t P = rq_.period;
                src.push_back({name(e), rows_[e], rows_[e] / P, rows_[e] % P});
                if (rows_[e] % P)
                    notes.push_back(fmt("'%s': %llu samples after the last whole period are not used", name(e).c_str(),
                                        (unsigned long long)(rows_[e] % P)));
            }
            FrfOutcome r = job_->finish(src, notes);
            msidjob::add_detection_distortion(r);
            return r;
        });
        py::dict out;
        out["frf"] = frf_to_py(o);
        out["notes"] = o.notes;
        return out;
    }

    uint32_t n_outputs() const { return ny_; }

private:
    py::object design_;   // keeps D_ alive
    const Design *D_;
    FrfRequest rq_;
    uint32_t max_periods_;
    uint32_t m_ = 0, nu_ = 0, ny_ = 0;
    std::unique_ptr<FrfJob> job_;
    int open_ = -1;
    std::vector<uint8_t> closed_;
    std::vector<uint64_t> rows_;
    std::vector<uint64_t> refused_;   // rows of blocks refused for NaN/Inf, per experiment
    bool done_ = false;
    std::mutex mu_;

    static std::string name(uint32_t e) { return "experiment " + std::to_string(e); }

    // The job, at the first block (it tells the number of outputs).
    void start(size_t C)
    {
        if (job_) return;
        if (C <= nu_)
            throw msidjob::Error(fmt("a block of %zu columns: the design's %u inputs leave no output column", C, nu_));
        ny_ = (uint32_t)(C - nu_);
        const uint32_t hist = rq_.transient == MSID_TRANSIENT_OFF ? 0 : max_periods_;
        const JobGuard planner("Measurement.push");
        job_ = std::make_unique<FrfJob>(rq_, nu_, ny_, m_, hist, hist, 1);
    }

    // Experiments are measured one after another: another one closes the open one for good.
    void open(uint32_t e)
    {
        if ((int)e == open_) return;
        if (closed_[e])
            throw UsageError(fmt("experiment %u was closed when another one began: push each experiment's samples "
                                 "in one run, one experiment after another", e));
        if (open_ >= 0) {
            check(msid_meas_end(job_->meas(), nullptr), fmt("experiment %d", open_));
            closed_[(size_t)open_] = 1;
        }
        check(msid_meas_begin(job_->meas(), e), fmt("experiment %u", e));
        open_ = (int)e;
    }

    // The records' rule: no NaN/Inf, no magnitude beyond the samples' range (the message msid.frf
    // gives, rows counted in the experiment).
    void scan_finite(const double *x, size_t n, uint32_t e)
    {
        const size_t C = (size_t)nu_ + ny_;
        for (size_t i = 0; i < n * C; ++i)
            if (!msidrec::sample_ok(x[i])) {
                refused_[e] += n;
                throw msidjob::Error(fmt("'%s' row %llu, column %zu: %s: the block of %zu rows is not taken (the next "
                                         "block follows the rows taken before it)",
                                         name(e).c_str(), (unsigned long long)(rows_[e] + i / C + 1), i % C + 1,
                                         msidrec::sample_fault(x[i]).c_str(), n));
            }
    }
};

void register_measurement(py::module_ &m)
{
    py::class_<Measurement>(m, "Measurement", "The FRF job fed block by block (use msid.Measurement).")
        .def(py::init<py::object, const py::dict &, uint32_t>(), py::arg("design"), py::arg("opts"),
             py::arg("max_periods"))
        .def("push", &Measurement::push, py::arg("block"), py::arg("experiment"))
        .def("progress", &Measurement::progress)
        .def("frf", &Measurement::frf)
        .def_property_readonly("n_outputs", &Measurement::n_outputs);
}

}  // namespace msidpy
