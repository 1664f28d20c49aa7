// msid._msid: what the extension's files share. The public API is Python (tools/python/msid/
// compute.py); this module takes arrays and options already put in order there and runs the host
// libraries on them, with the GIL released while they work.
#pragma once
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <initializer_list>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "msid_design_file.hpp"
#include "msid_frf_job.hpp"
#include "msid_records.hpp"

namespace msidpy {

namespace py = pybind11;
using msidfmt::Design;
using msidfmt::Json;
using msidjob::FrfRequest;

// A design held by Python (msid.Design wraps it): FrfRequest::design points into it.
struct PyDesign {
    std::unique_ptr<Design> d;
};

// An msid document as Python objects (dict, list, float, int, str, bool, None), keys in order.
py::object json_to_py(const Json &j);

// An msid-frf/1 document (one the FRF job wrote) as what msid.FRF holds: NumPy arrays for the per-line
// values every line has (bin, freq, freq_hz, omega, real, G, cov, dof, cov_known_input, dof_known_input:
// L x ny x nu and L x g x g complex, L-vectors), "meta" (every top-level key but lines) and
// "line_extra" (per line, the other keys). The numbers keep their bits.
py::dict frf_to_py(const Json &doc);
// The same dict of an estimator's outcome: the periodic job's typed result straight from its arrays
// (no document in between), the other estimators' documents as above.
py::dict frf_to_py(const msidjob::FrfOutcome &o);
// Free an FRF document: one of many lines on a thread of its own, so that the call that made it returns
// (or raises KeyboardInterrupt) without waiting seconds for its memory to be freed.
void release_document(Json &&doc);
// release_document() of `doc` when the scope ends, however it ends (a KeyboardInterrupt in frf_to_py).
struct DocumentRelease {
    Json &doc;
    ~DocumentRelease() { release_document(std::move(doc)); }
};

// The options every estimating call shares (a dict put in order by compute.py: skip_periods,
// fs, detect_lines, transient, alpha, dft) into the request; a bad value is a UsageError.
void request_options(const py::dict &opts, FrfRequest &rq, const Design *D);

// A keyword's value among named choices (e.g. transient: flag, drop, off); else a UsageError listing them.
template <class E>
E choose(const std::string &what, const std::string &v, std::initializer_list<std::pair<const char *, E>> choices)
{
    std::string names;
    for (const auto &c : choices) {
        if (v == c.first) return c.second;
        names += (names.empty() ? "'" : ", '") + std::string(c.first) + "'";
    }
    throw msidutil::UsageError(what + " must be one of " + names + ", not '" + v + "'");
}

// A samples array that compute.py made C-contiguous float64 with rows x columns: its data, or an
// internal error (the Python layer converts; this is the check that it did).
const double *samples_of(const py::array &a, size_t &rows, size_t &cols);

// The arrays compute.py put in order (C-contiguous float64, columns u1.., y1..) as records read in
// place (Record::view), kept alive by the caller's list; nu[k] = 0 only where inputs are optional
// (free responses of msid fit --method multi).
std::vector<msidrec::Record> records_of(const py::list &arrays, const py::list &names, const py::list &columns,
                                        const std::vector<uint32_t> &nu, bool inputs_optional);

void register_frf(py::module_ &m);
void register_measurement(py::module_ &m);
void register_design(py::module_ &m);
void register_fit(py::module_ &m);
void register_measure(py::module_ &m);
void register_import(py::module_ &m);

}  // namespace msidpy
