// msid._msid.measure: one measurement of a device (msidacq::measure_device, the session `msid measure`
// runs) with the GIL released. The acquisition asks its Control after every poll: that is where a
// Python progress callable is called and where Ctrl-C is seen, both with the GIL taken back.
#include "ext.hpp"
#include "ext_call.hpp"

#include "msid_acquire.hpp"
#include "msid_mapped.hpp"
#include "msid_ondevice.hpp"

#include <chrono>
#include <functional>
#include <cxxabi.h>
#include <csignal>
#include <cmath>

namespace msidpy {

using msidutil::fmt;
using msidutil::UsageError;

// What msid.measure's caller sees while the device runs. Every call comes from the measuring thread
// without the GIL; a call into Python takes it for that call only.
class PyControl : public msidacq::Control {
public:
    explicit PyControl(py::object progress) : progress_(std::move(progress)) {}

    void update(const msidacq::ProgressState &s) override
    {
        const double t = now();
        const bool event = s.exp != last_.exp || s.periods != last_.periods || s.rejected != last_.rejected ||
                           s.lost != last_.lost || s.link_errors != last_.link_errors;
        // Python at most every 20 ms between events: a poll can come every few hundred microseconds
        if (!event && t - last_call_ < 0.02) return;
        last_call_ = t;
        last_ = s;
        // The interpreter is exiting: stop without Python (a daemon thread that took the GIL now
        // could be ended inside the acquisition, leaving the device mid-run).
        if (Call::shutting_down()) {
            stop_ = SIGINT;
            return;
        }
        py::gil_scoped_acquire gil;
        if (stop_) return;
        if (PyErr_CheckSignals() != 0) { caught(); return; }   // Ctrl-C (the main thread only sees signals)
        if (progress_.is_none()) return;
        try {
            progress_(state_dict(s));
        } catch (py::error_already_set &e) {
            e.restore();
            caught();
        }
    }

    int stop() override { return stop_; }

    // KeyboardInterrupt stopped the run (its complete periods are kept).
    bool interrupted() const { return interrupted_; }
    // Another exception of the progress callable stopped the run: raised again once the run ended.
    void raise_pending()
    {
        if (!pending_) return;
        PyErr_Restore(pending_type_, pending_value_, pending_tb_);
        pending_ = false;
        throw py::error_already_set();
    }

private:
    py::object progress_;
    msidacq::ProgressState last_{};
    double last_call_ = -1;
    int stop_ = 0;
    bool interrupted_ = false, pending_ = false;
    PyObject *pending_type_ = nullptr, *pending_value_ = nullptr, *pending_tb_ = nullptr;

    static double now()
    {
        return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    }

    // The Python error just raised ends the run: KeyboardInterrupt as Ctrl-C does in `msid measure`
    // (SIGINT), any other one to be raised again after the acquisition is closed.
    void caught()
    {
        stop_ = SIGINT;
        if (PyErr_ExceptionMatches(PyExc_KeyboardInterrupt)) {
            interrupted_ = true;
            PyErr_Clear();
            return;
        }
        PyErr_Fetch(&pending_type_, &pending_value_, &pending_tb_);
        pending_ = true;
    }

    static py::dict state_dict(const msidacq::ProgressState &s)
    {
        py::dict d;
        d["experiment"] = s.exp;               // 1-based, as the command line shows it
        d["experiments"] = s.n_exp;
        d["periods"] = s.periods;
        d["periods_target"] = s.periods_target;
        d["periods_total"] = s.periods_total;
        d["rejected"] = s.rejected;
        d["samples_lost"] = s.lost;
        d["link_errors"] = s.link_errors;
        d["snr_db"] = std::isnan(s.snr_db) ? py::object(py::none()) : py::object(py::float_(s.snr_db));
        d["eta_s"] = std::isnan(s.eta_s) ? py::object(py::none()) : py::object(py::float_(s.eta_s));
        return d;
    }
};

// Whether this thread runs a measurement (its progress callable may call msid, but not measure again).
static thread_local bool t_measuring = false;
struct Measuring {
    Measuring() { t_measuring = true; }
    ~Measuring() { t_measuring = false; }
};

// One device session without the GIL, the way every msid.measure runs: the acquisition stops on the Control
// (Ctrl-C keeps the complete periods), never at a checkpoint; only the wait for the planner lock (another
// thread's job) is interrupted. A stop before every experiment had 2 periods is a plain KeyboardInterrupt, and
// an exception of the progress callable is the one raised.
static void run_session(PyControl &ctl, const char *name, const std::function<void()> &session)
{
    bool stopped_empty = false;
    std::string why;
    std::exception_ptr failed;
    without_gil({true, false, name}, [&] {
        const Measuring here;
        try {
            session();
        } catch (const msidutil::Error &e) {
            if (!(ctl.stop() && e.code > 128)) {
                failed = std::current_exception();
                return;
            }
            stopped_empty = true;
            why = e.what();
        } catch (abi::__forced_unwind &) {
            throw;   // this thread is being ended
        } catch (...) {
            failed = std::current_exception();
        }
    });
    ctl.raise_pending();
    if (failed) std::rethrow_exception(failed);
    if (stopped_empty) {
        PyErr_SetString(PyExc_KeyboardInterrupt, why.c_str());
        throw py::error_already_set();
    }
}

// measure(device, design, opts, periods, rate, scale, timeout, progress) -> {"frf", "notes", "complete",
// "summary", "interrupted"}. opts: the estimating options (request_options).
static py::dict measure(const std::string &device, py::object design, const py::dict &opts, uint32_t periods,
                        uint32_t rate, double scale, double timeout, py::object progress, bool on_device,
                        bool stream_check)
{
    if (t_measuring)
        throw std::runtime_error("msid.measure cannot run inside the progress callable of another msid.measure "
                                 "(one device run per thread at a time); measure after it returns, or from another thread");
    const msidacq::DeviceUri dev = msidacq::parse_device_uri(device);
    msidacq::MeasurePlan plan;
    // the design stays Python's: `design` holds it for the whole call
    plan.D = std::shared_ptr<const Design>(design.cast<const PyDesign &>().d.get(), [](const Design *) {});
    request_from_design(plan.rq, *plan.D);
    request_options(opts, plan.rq, plan.D.get());
    plan.sf.periods = periods;
    plan.sf.rate = rate;
    plan.sf.scale = (float)scale;
    plan.sf.fd = dev.fd ? 1 : 0;
    plan.timeout = timeout;
    msidacq::check_plan(plan, "periods", "skip_periods");
    if (on_device) msidacq::check_ondevice_request(plan.rq);
    PyControl ctl(std::move(progress));
    msidacq::MeasureResult R;
    msidacq::OnDeviceResult OD;
    run_session(ctl, "msid.measure", [&] {
        if (!on_device) {
            R = msidacq::measure_device(dev, [&](uint32_t, msidacq::MeasurePlan &P) { P = std::move(plan); }, ctl);
        } else {
            OD = msidacq::measure_device_ondevice(dev, plan, stream_check ? "the host's estimate (msid.measure)" : "",
                                                  ctl);
            if (OD.checked && !OD.host.complete) {
                R = std::move(OD.host);   // stopped in the stream check's host session: its complete periods
            } else {
                if (!OD.mismatch.empty()) throw msidacq::Error(OD.mismatch);
                R.o.doc = std::move(OD.doc);
                R.summary = OD.summary;
            }
        }
    });
    py::dict out;
    out["frf"] = frf_to_py(R.o);
    out["notes"] = R.o.notes;
    out["complete"] = R.complete;
    out["summary"] = R.summary;
    out["interrupted"] = ctl.interrupted();
    if (on_device && OD.checked && R.complete) out["host"] = frf_to_py(OD.host.o);
    return out;
}

// measure_mapped(device, design, opts, periods, rate, timeout, progress, map, realtime): a described device
// (msid-device/1) with host-timed excitation (msidacq::measure_mapped, what `msid measure --map` runs); as
// measure's dict, and "reference" (the msid-frf/1 document of the reference path, a dict) for the closed-loop
// preset: msid.measure converts it as read_frf converts reference.json.
static py::dict measure_mapped(const std::string &device, py::object design, const py::dict &opts, uint32_t periods,
                               double rate, double timeout, py::object progress, const std::string &map_path,
                               bool realtime)
{
    const msidacq::DeviceUri dev = msidacq::parse_device_uri(device);
    const msid_devdesc desc = msidacq::load_description(map_path);
    std::shared_ptr<const Design> D(design.cast<const PyDesign &>().d.get(), [](const Design *) {});
    msidacq::MappedOptions mo;
    mo.rate_hz = rate;
    mo.realtime = realtime;
    mo.timeout = timeout;
    mo.desc_path = map_path;
    msidacq::MeasurePlan plan;
    plan.D = D;
    request_from_design(plan.rq, *plan.D);
    request_options(opts, plan.rq, plan.D.get());
    plan.sf.periods = periods;
    plan.timeout = timeout;
    msidacq::check_plan(plan, "periods", "skip_periods");
    if (t_measuring)
        throw std::runtime_error("msid.measure cannot run inside the progress callable of another msid.measure "
                                 "(one device run per thread at a time); measure after it returns, or from another thread");
    PyControl ctl(std::move(progress));
    msidacq::MeasureResult R;
    run_session(ctl, "msid.measure", [&] {
        R = msidacq::measure_mapped(dev, desc, mo, [&](uint32_t, msidacq::MeasurePlan &P) { P = std::move(plan); }, ctl);
    });
    py::dict out;
    out["frf"] = frf_to_py(R.o);
    out["notes"] = R.o.notes;
    out["complete"] = R.complete;
    out["summary"] = R.summary;
    out["interrupted"] = ctl.interrupted();
    // the closed-loop preset: the FRF from the reference to every signal (reference.json of the command line)
    if (!R.reference.is_null()) out["reference"] = json_to_py(R.reference);
    return out;
}

void register_measure(py::module_ &m)
{
    m.def("measure_mapped", &measure_mapped, py::arg("device"), py::arg("design"), py::arg("opts"), py::arg("periods"),
          py::arg("rate"), py::arg("timeout"), py::arg("progress"), py::arg("map"), py::arg("realtime") = true,
          "One measurement of a described device (use msid.measure(..., map=...)).");
    m.def("measure", &measure, py::arg("device"), py::arg("design"), py::arg("opts"), py::arg("periods"),
          py::arg("rate"), py::arg("scale"), py::arg("timeout"), py::arg("progress"), py::arg("on_device") = false,
          py::arg("stream_check") = false,
          "One measurement of a device (use msid.measure).");
}

}  // namespace msidpy
