// msid._msid.fit and .validate: an FRF document held by Python through the fit job
// (msidfitjob::fit_frf, validate_frf), as `msid fit` and `msid validate` run them on files: the same
// request and the same FRF give the same model.
#include "ext.hpp"
#include "ext_call.hpp"

#include "msid_fit_job.hpp"
#include "msid_host_util.hpp"

namespace msidpy {

using msidfitjob::FitRequest;
using msidutil::UsageError;

// A document's text: a file's as read (named by its path, with the command line's message when it is
// not JSON), or compute.py's json.dumps of an object in memory (every double's shortest round trip:
// the numbers arrive with their bits).
static Json parse_doc(const std::string &text, const std::string &name) { return msidfrf::parse_json(text, name); }

// What compute.py makes a Model of: the document, the notes, whether the iterations converged.
static py::dict outcome(const msidfitjob::FitOutcome &o)
{
    py::dict out;
    out["model"] = json_to_py(o.model);
    out["notes"] = o.notes;
    out["converged"] = o.converged;
    out["not_converged"] = o.not_converged;
    return out;
}

// The keywords of msid.fit (compute.py checked their types) as the options of `msid fit`.
static FitRequest fit_request(const py::dict &o)
{
    auto has = [&](const char *k) { return o.contains(k) && !o[k].is_none(); };
    auto str = [&](const char *k) { return has(k) ? o[k].cast<std::string>() : std::string(); };
    auto u32 = [&](const char *k) { return std::optional<uint32_t>(o[k].cast<uint32_t>()); };
    auto f64 = [&](const char *k) { return std::optional<double>(o[k].cast<double>()); };
    FitRequest rq;
    rq.method = str("method");
    choose<int>("method", rq.method, {{"subspace", 0}, {"lmfd", 0}, {"ml", 0}});
    rq.order = str("order");
    if (has("nd")) rq.nd = u32("nd");
    if (has("nn")) rq.nn = u32("nn");
    rq.domain = str("domain");
    if (has("weight")) rq.weight = str("weight");
    if (has("noise_var")) rq.noise_var = f64("noise_var");
    if (has("r")) rq.r = u32("r");
    rq.stable = has("stable") && o["stable"].cast<bool>();
    rq.allow_unstable = has("allow_unstable") && o["allow_unstable"].cast<bool>();
    rq.no_d = has("no_d") && o["no_d"].cast<bool>();
    if (has("pins")) rq.pins = o["pins"].cast<std::vector<std::string>>();
    rq.start = str("start");
    if (has("max_iter")) rq.max_iter = u32("max_iter");
    if (has("delta")) rq.delta = f64("delta");
    if (has("beta")) rq.beta = f64("beta");
    rq.feedthrough = str("feedthrough");
    rq.param = str("param");
    rq.refine = str("refine");
    if (has("weight_smooth")) rq.weight_smooth = u32("weight_smooth");
    return rq;
}

static py::dict fit(const std::string &frf_text, const std::string &name, const py::dict &opts)
{
    const FitRequest rq = fit_request(opts);
    const msidfitjob::FitOutcome o = without_gil({false, true, "msid.fit"}, [&] {
        const msidfrf::FrfData f = msidfrf::parse_frf(parse_doc(frf_text, name), name);
        return msidfitjob::fit_frf(f, rq);
    });
    return outcome(o);
}

static py::dict validate(const std::string &model_text, const std::string &model_name, const std::string &frf_text,
                         const std::string &frf_name, const py::dict &opts)
{
    msidfitjob::ValidateRequest rq;
    if (opts.contains("weight") && !opts["weight"].is_none())
        rq.weight = choose<msidfit::Weight>("weight", opts["weight"].cast<std::string>(),
                                            {{"cov", msidfit::Weight::Cov},
                                             {"known-input", msidfit::Weight::KnownInput},
                                             {"none", msidfit::Weight::None}});
    if (opts.contains("lpm_lines")) rq.lpm_lines = opts["lpm_lines"].cast<std::string>();
    const msidfitjob::ValidateOutcome v = without_gil({false, true, "msid.validate"}, [&] {
        const msidfit::ModelFile mf = msidfit::parse_model(parse_doc(model_text, model_name), model_name);
        const Json frf_doc = parse_doc(frf_text, frf_name);
        return msidfitjob::validate_frf(mf, msidfrf::parse_frf(frf_doc, frf_name), frf_doc, rq);
    });
    py::dict out;
    out["report"] = json_to_py(v.report);
    out["text"] = v.text;
    if (v.has_verdict) out["consistent"] = v.consistent;
    else out["consistent"] = py::none();
    return out;
}

// --method cissim: the options of `msid fit --method cissim`.
static msidfitjob::CissimRequest cissim_request(const py::dict &o)
{
    auto has = [&](const char *k) { return o.contains(k) && !o[k].is_none(); };
    msidfitjob::CissimRequest rq;
    if (!has("period") || !has("lines")) throw UsageError("cissim needs period and lines (or design)");
    rq.period = o["period"].cast<uint32_t>();
    rq.lines = o["lines"].cast<std::vector<uint32_t>>();
    if (has("order")) rq.order = o["order"].cast<uint32_t>();
    if (has("max_order")) rq.max_order = o["max_order"].cast<uint32_t>();
    if (has("block_rows")) rq.block_rows = o["block_rows"].cast<uint32_t>();
    if (has("lags")) rq.lags = o["lags"].cast<uint32_t>();
    if (has("skip_periods")) rq.skip_periods = o["skip_periods"].cast<uint32_t>();
    for (auto f : {std::make_pair("reduced", &rq.reduced), std::make_pair("no_d", &rq.no_d),
                   std::make_pair("no_covariance", &rq.no_covariance), std::make_pair("unweighted", &rq.unweighted),
                   std::make_pair("allow_unstable", &rq.allow_unstable)})
        *f.second = has(f.first) && o[f.first].cast<bool>();
    if (has("isp")) rq.isp = o["isp"].cast<std::string>();
    if (has("refine")) rq.refine = o["refine"].cast<std::string>();
    return rq;
}

// --method multi: the options of `msid fit --method multi`.
static msidfitjob::MultiRequest multi_request(const py::dict &o)
{
    auto has = [&](const char *k) { return o.contains(k) && !o[k].is_none(); };
    msidfitjob::MultiRequest rq;
    if (has("order")) rq.order = o["order"].cast<std::string>();
    if (has("order_rule")) rq.order_rule = o["order_rule"].cast<std::string>();
    if (has("noise_ar")) rq.noise_ar = o["noise_ar"].cast<std::vector<double>>();
    if (has("noise_ar_order")) rq.noise_ar_order = o["noise_ar_order"].cast<uint32_t>();
    if (has("input_noise_ratio")) rq.input_noise_ratio = o["input_noise_ratio"].cast<double>();
    if (has("fs")) rq.fs = o["fs"].cast<double>();
    if (has("feedthrough")) rq.feedthrough = o["feedthrough"].cast<std::string>();
    if (has("start")) rq.start = o["start"].cast<std::string>();
    if (has("max_iter")) rq.max_iter = o["max_iter"].cast<uint32_t>();
    if (has("columns")) rq.columns = o["columns"].cast<std::string>();
    return rq;
}

// The fits of time records: cissim (periodic records) and multi (records of any lengths; noise-only
// records for the AR noise model). The records are read in place and scanned for NaN/Inf first, as
// msid's readers scan files.
static py::dict fit_records(const std::string &method, const py::tuple &recs, const py::tuple &noise, const py::dict &opts)
{
    auto unpack = [](const py::tuple &t, bool free) {
        return records_of(t[0].cast<py::list>(), t[1].cast<py::list>(), t[2].cast<py::list>(),
                          t[3].cast<std::vector<uint32_t>>(), free);
    };
    msidfitjob::FitOutcome o;
    if (method == "cissim") {
        const msidfitjob::CissimRequest rq = cissim_request(opts);
        msidfitjob::check_cissim(rq);
        const std::vector<msidrec::Record> r = unpack(recs, false);
        // cissim plans its DFTs with FFTW: the planner lock
        o = without_gil({true, true, "msid.fit"}, [&] {
            for (const auto &x : r) msidrec::check_finite(x, 0, x.n_rows);
            return msidfitjob::fit_cissim(r, rq);
        });
    } else if (method == "multi") {
        const msidfitjob::MultiRequest rq = multi_request(opts);
        msidfitjob::check_multi(rq, py::len(noise[0]) > 0);
        const std::vector<msidrec::Record> r = unpack(recs, true), n = unpack(noise, true);
        o = without_gil({false, true, "msid.fit"}, [&] {
            for (const auto *set : {&r, &n})
                for (const auto &x : *set) msidrec::check_finite(x, 0, x.n_rows);
            return msidfitjob::fit_multi(r, n, rq);
        });
    } else {
        throw std::logic_error("internal error: record fit '" + method + "'");
    }
    return outcome(o);
}

// msid modes: the report and the text of a model document.
static py::dict modes(const std::string &model_text, const std::string &name)
{
    const msidfitjob::ModesOutcome o = without_gil(
        {false, true, "msid.modes"}, [&] { return msidfitjob::modes_of(parse_doc(model_text, name), name); });
    py::dict out;
    out["report"] = json_to_py(o.report);
    out["text"] = o.text;
    return out;
}

// msid validate MODEL --experiment ...: a multi model on records (read in place, scanned for NaN/Inf).
static py::dict validate_records(const std::string &model_text, const std::string &name, const py::tuple &recs, int lags,
                                 bool own)
{
    const std::vector<msidrec::Record> r = records_of(recs[0].cast<py::list>(), recs[1].cast<py::list>(),
                                                      recs[2].cast<py::list>(), recs[3].cast<std::vector<uint32_t>>(), true);
    const msidfitjob::ValidateOutcome v = without_gil({false, true, "msid.validate"}, [&] {
        const Json doc = parse_doc(model_text, name);
        msidfitjob::check_multi_model(doc, name);
        for (const auto &x : r) msidrec::check_finite(x, 0, x.n_rows);
        return msidfitjob::validate_records(doc, name, r, lags, own);
    });
    py::dict out;
    out["report"] = json_to_py(v.report);
    out["text"] = v.text;
    out["consistent"] = v.consistent;
    return out;
}

void register_fit(py::module_ &m)
{
    m.def("modes", &modes, py::arg("model_json"), py::arg("name"), "msid modes of an msid-model/1 document (use Model.modes).");
    m.def("validate_records", &validate_records, py::arg("model_json"), py::arg("name"), py::arg("records"),
          py::arg("lags"), py::arg("own"), "msid validate --experiment of a multi model on records (use msid.validate).");
    m.def("fit_records", &fit_records, py::arg("method"), py::arg("records"), py::arg("noise_records"), py::arg("opts"),
          "msid fit --method cissim|multi on C-contiguous float64 records (use msid.fit).");
    m.def("fit", &fit, py::arg("frf_json"), py::arg("name"), py::arg("opts"),
          "msid fit --method subspace|lmfd|ml on an msid-frf/1 document (use msid.fit).");
    m.def("validate", &validate, py::arg("model_json"), py::arg("model_name"), py::arg("frf_json"),
          py::arg("frf_name"), py::arg("opts"), "msid validate on an msid-model/1 and an msid-frf/1 document (use Model.validate).");
}

}  // namespace msidpy
