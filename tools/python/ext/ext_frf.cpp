// msid._msid.frf: records held by NumPy through the FRF job (msidjob::estimate_frf), as `msid frf`
// runs it on files: the same request, the same steps, the same bits. The samples are read in place.
#include "ext.hpp"
#include "ext_call.hpp"

#include "msid_frf_est.hpp"
#include "msid_host_util.hpp"
#include "msid_reference.hpp"

#include <algorithm>

namespace msidpy {

using msidjob::FrfOutcome;
using msidjob::FrfPlan;
using msidrec::Record;
using msidutil::UsageError;

// The whole request of msid.frf's options (compute.py passes only those given, their types checked)
// and design (an msid.Design or None). Only their conversion: the rules between them are the job's
// (msidjob::check_plan), which names the keywords (the options' neutral names) in its messages.
static void request_of(const py::dict &opts, const py::object &design, FrfRequest &rq, FrfPlan &plan)
{
    auto has = [&](const char *k) { return opts.contains(k) && !opts[k].is_none(); };
    for (const auto &kv : opts)
        if (!kv.second.is_none()) plan.given.names.push_back(kv.first.cast<std::string>());
    const Design *D = design.is_none() ? nullptr : design.cast<const PyDesign &>().d.get();
    if (D) {
        plan.given.add("design");
        request_from_design(rq, *D);
    }
    plan.design = D;
    plan.auto_period = has("auto_period") && opts["auto_period"].cast<bool>();
    plan.auto_lines = has("auto_lines") && opts["auto_lines"].cast<bool>();
    if (has("period")) rq.period = opts["period"].cast<uint32_t>();
    if (has("lines")) rq.bins = opts["lines"].cast<std::vector<uint32_t>>();
    if (has("block")) rq.block = opts["block"].cast<size_t>();
    request_options(opts, rq, D);
    plan.direct = has("direct") && opts["direct"].cast<bool>();
    if (!plan.direct) plan.given.names.erase(std::remove(plan.given.names.begin(), plan.given.names.end(), "direct"),
                                             plan.given.names.end());
    plan.bla = has("realisations");
    plan.realisations = plan.bla ? opts["realisations"].cast<uint32_t>() : 1;
    msidjob::check_plan(rq, plan);
}

static py::dict frf(const py::list &arrays, const py::list &names, const py::list &columns,
                    const std::vector<uint32_t> &nu, const py::dict &opts, const py::object &design)
{
    FrfRequest rq;
    FrfPlan plan;
    request_of(opts, design, rq, plan);
    std::vector<Record> recs = records_of(arrays, names, columns, nu, false);
    std::vector<std::string> reports;
    plan.report = [&](const std::string &s) { reports.push_back(s); };
    // The arrays stay alive in the caller's list; nothing in the call touches a Python object.
    FrfOutcome o = without_gil({true, true, "msid.frf"}, [&] {
        // As `msid frf` reads its files: the plain periodic job scans each block for NaN/Inf just
        // before it uses it; every other path reads samples first, so they are scanned first.
        const bool plain = !plan.direct && !plan.bla && !plan.auto_period && !plan.auto_lines;
        for (Record &r : recs)
            if (plain) r.finite_unchecked = true;
            else msidrec::check_finite(r, 0, r.n_rows);
        return msidjob::estimate_frf(rq, recs, plan);
    });
    const DocumentRelease release{o.doc};
    py::dict out;
    out["frf"] = frf_to_py(o);
    out["notes"] = o.notes;
    out["reports"] = reports;
    return out;
}

// Experiment files (CSV, .npy, .npz, .mat) through the job `msid frf` runs on them
// (msidjob::estimate_frf_files): a CSV record streamed through the core where the plan allows it.
static py::dict frf_files(const std::vector<std::string> &paths, const std::string &columns, const py::dict &opts,
                          const py::object &design)
{
    FrfRequest rq;
    FrfPlan plan;
    request_of(opts, design, rq, plan);
    const msidrec::ColumnMap cols = columns.empty() ? msidrec::ColumnMap{} : msidrec::parse_column_map(columns);
    std::vector<std::string> reports;
    plan.report = [&](const std::string &s) { reports.push_back(s); };
    msidjob::FilesOutcome o =
        without_gil({true, true, "msid.frf"}, [&] { return msidjob::estimate_frf_files(rq, paths, cols, plan); });
    const DocumentRelease release{o.o.doc};
    py::dict out;
    out["frf"] = frf_to_py(o.o);
    out["notes"] = o.o.notes;
    out["reports"] = reports;
    out["streamed"] = o.streamed;
    return out;
}

// ---- method="lpm" | "etfe": arbitrary records (msidjob::estimate_frf_est) ----

// The plan of msid.frf's keywords (compute.py passes only those given): method, band (f1, f2, text),
// order, window, reference (file column names), period, delta, gstar, threads.
static msidjob::EstPlan est_plan_of(const py::dict &opts)
{
    auto has = [&](const char *k) { return opts.contains(k) && !opts[k].is_none(); };
    msidjob::EstPlan p;
    p.method = msidjob::est_method(opts["method"].cast<std::string>());
    if (has("band")) {
        const auto b = opts["band"].cast<py::tuple>();
        p.band = true;
        p.f1 = b[0].cast<double>();
        p.f2 = b[1].cast<double>();
        p.band_text = b[2].cast<std::string>();
    }
    if (has("order")) p.order = opts["order"].cast<uint32_t>();
    if (has("window")) p.window = opts["window"].cast<uint32_t>();
    if (has("period")) p.period = opts["period"].cast<uint32_t>();
    if (has("delta")) p.delta = opts["delta"].cast<double>();
    if (has("gstar")) p.gstar = opts["gstar"].cast<double>();
    if (has("threads")) {
        p.threads = opts["threads"].cast<uint32_t>();
        p.given.add("threads");
    }
    if (has("fs")) p.given.add("fs");
    if (has("reference")) p.reference = opts["reference"].cast<std::vector<std::string>>();
    return p;
}

static double fs_of(const py::dict &opts)
{
    return !opts.contains("fs") || opts["fs"].is_none() ? 0.0 : opts["fs"].cast<double>();
}

static py::dict est_result(const msidjob::FrfOutcome &o)
{
    py::dict out;
    out["frf"] = frf_to_py(o);
    out["notes"] = o.notes;
    out["reports"] = std::vector<std::string>{};
    return out;
}

// Arrays (as msid.frf's records) and, for the LPM on references, one n_rows x n_inputs array of
// reference samples per record (compute.py made them C-contiguous float64).
static py::dict frf_est(const py::list &arrays, const py::list &names, const py::list &columns,
                        const std::vector<uint32_t> &nu, const py::dict &opts, const py::list &refs)
{
    FrfRequest rq;
    rq.fs = fs_of(opts);
    msidjob::EstPlan plan = est_plan_of(opts);
    msidjob::check_est_plan(plan, rq.fs);
    std::vector<Record> recs = records_of(arrays, names, columns, nu, false);
    std::vector<Record> ref_recs(refs.size());
    for (size_t k = 0; k < ref_recs.size(); ++k) {
        Record &r = ref_recs[k];
        size_t rows = 0, cols = 0;
        r.view = samples_of(refs[k].cast<py::array>(), rows, cols);
        r.path = "reference[" + std::to_string(k) + "]";
        r.n_rows = rows;
        r.nu = (uint32_t)cols;
        for (size_t c = 0; c < cols; ++c) r.columns.push_back("r" + std::to_string(c + 1));
        if (k < recs.size() && (rows != recs[k].n_rows || cols != recs[k].nu))
            throw UsageError(msidutil::fmt("%s has %zu rows and %zu columns: need one column per input of %s, %zu x %u",
                                           r.path.c_str(), rows, cols, recs[k].path.c_str(), recs[k].n_rows,
                                           recs[k].nu));
        plan.reference_rows.push_back(r.view);
    }
    msidjob::FrfOutcome o = without_gil({true, true, "msid.frf"}, [&] {
        for (Record &r : recs) msidrec::check_finite(r, 0, r.n_rows);
        for (Record &r : ref_recs) msidrec::check_finite(r, 0, r.n_rows);
        return msidjob::estimate_frf_est(rq, recs, plan);
    });
    const DocumentRelease release{o.doc};
    return est_result(o);
}

// Experiment files, as `msid frf --method lpm|etfe --experiment ...` reads them.
static py::dict frf_est_files(const std::vector<std::string> &paths, const std::string &columns, const py::dict &opts)
{
    FrfRequest rq;
    rq.fs = fs_of(opts);
    const msidjob::EstPlan plan = est_plan_of(opts);
    msidjob::check_est_plan(plan, rq.fs);
    const msidrec::ColumnMap cols = columns.empty() ? msidrec::ColumnMap{} : msidrec::parse_column_map(columns);
    msidjob::check_reference_columns(plan.reference, cols);
    msidjob::FrfOutcome o = without_gil({true, true, "msid.frf"}, [&] {
        std::vector<Record> recs;
        for (const auto &p : paths) recs.push_back(msidrec::read_experiment(p, cols));
        return msidjob::estimate_frf_est(rq, recs, plan);
    });
    const DocumentRelease release{o.doc};
    return est_result(o);
}

void register_frf(py::module_ &m)
{
    m.def("frf_est", &frf_est, py::arg("arrays"), py::arg("names"), py::arg("columns"), py::arg("n_inputs"),
          py::arg("opts"), py::arg("reference"), "The LPM or ETFE on C-contiguous float64 records (use msid.frf).");
    m.def("frf_est_files", &frf_est_files, py::arg("paths"), py::arg("columns"), py::arg("opts"),
          "The LPM or ETFE on experiment files, as msid frf --method lpm|etfe (use msid.frf).");
    m.def("parse_reference", &msidrec::parse_reference, py::arg("spec"),
          "A --reference spec (r1=Cmd1,... or r1,...) as the reference column names in order r1..");
    m.def("frf_files", &frf_files, py::arg("paths"), py::arg("columns"), py::arg("opts"), py::arg("design"),
          "The FRF job on experiment files, as msid frf (use msid.frf with file paths).");
    m.def("frf", &frf, py::arg("arrays"), py::arg("names"), py::arg("columns"), py::arg("n_inputs"), py::arg("opts"),
          py::arg("design"), "The FRF job on C-contiguous float64 records (use msid.frf).");
    m.def(
        "resolve_columns",
        [](const std::string &where, const std::vector<std::string> &names, const std::string &spec, bool free) {
            msidrec::ColumnMap cm;
            if (!spec.empty()) cm = msidrec::parse_column_map(spec, free);
            cm.inputs_optional = free;
            uint32_t nu = 0, ny = 0;
            std::vector<size_t> src = msidrec::resolve_columns(where, names, cm, false, nu, ny);
            return py::make_tuple(src, nu, ny);
        },
        py::arg("where"), py::arg("names"), py::arg("spec"), py::arg("inputs_optional") = false,
        "Which of `names` feed u1.., y1.. (a --columns spec, or the u<k>/y<k> names): (indices, nu, ny).");
}

}  // namespace msidpy
