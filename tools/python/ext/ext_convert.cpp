// The extension's conversions: msid documents to Python objects, the shared estimating options,
// and the check on the arrays the Python layer hands over.
#include "ext.hpp"

#include "ext_call.hpp"
#include "msid_host_util.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <system_error>
#include <thread>

namespace msidpy {

static py::object to_py(const Json &j);

// The collector paused while a document becomes Python objects: tens of thousands of new
// containers, none in a cycle, would start many collections (each walking the interpreter's objects)
// that can free nothing.
namespace {
#if PY_VERSION_HEX >= 0x030A0000
struct GcPause {
    bool was = PyGC_Disable() != 0;
    ~GcPause()
    {
        if (was) PyGC_Enable();
    }
};
#else
struct GcPause {   // Python < 3.10: the gc module's switches
    py::module_ gc = py::module_::import("gc");
    bool was = gc.attr("isenabled")().cast<bool>();
    GcPause() { gc.attr("disable")(); }
    ~GcPause()
    {
        if (!was) return;
        try {   // a destructor must not throw (the interpreter would abort); gc.enable() does not fail
            gc.attr("enable")();
        } catch (const py::error_already_set &) {
        }
    }
};
#endif
}  // namespace

py::object json_to_py(const Json &j)
{
    GcPause pause;
    return to_py(j);
}

static py::object to_py(const Json &j)
{
    switch (j.type()) {
    case Json::value_t::object: {
        py::dict d;
        for (auto it = j.begin(); it != j.end(); ++it) d[py::str(it.key())] = to_py(it.value());
        return std::move(d);
    }
    case Json::value_t::array: {
        py::list l(j.size());
        size_t k = 0;
        for (const auto &x : j) l[k++] = to_py(x);
        return std::move(l);
    }
    case Json::value_t::string: return py::str(j.get_ref<const std::string &>());
    case Json::value_t::boolean: return py::bool_(j.get<bool>());
    case Json::value_t::number_integer: return py::int_(j.get<int64_t>());
    case Json::value_t::number_unsigned: return py::int_(j.get<uint64_t>());
    case Json::value_t::number_float: return py::float_(j.get<double>());
    default: return py::none();
    }
}

void request_options(const py::dict &opts, FrfRequest &rq, const Design *D)
{
    using msidutil::UsageError;
    auto has = [&](const char *k) { return opts.contains(k) && !opts[k].is_none(); };
    if (has("skip_periods")) rq.skip = opts["skip_periods"].cast<uint32_t>();
    msidjob::GivenOptions given;
    for (const auto &kv : opts)
        if (!kv.second.is_none()) given.names.push_back(kv.first.cast<std::string>());
    if (has("fs")) rq.fs = opts["fs"].cast<double>();
    if (has("detect_lines")) rq.detect = opts["detect_lines"].cast<std::vector<uint32_t>>();
    if (has("transient"))
        rq.transient = choose<msid_transient_mode>(
            "transient", opts["transient"].cast<std::string>(),
            {{"flag", MSID_TRANSIENT_FLAG}, {"drop", MSID_TRANSIENT_DROP}, {"off", MSID_TRANSIENT_OFF}});
    if (has("alpha")) rq.alpha = opts["alpha"].cast<double>();
    if (has("dft"))
        rq.path = choose<msid_dft_path>("dft", opts["dft"].cast<std::string>(),
                                        {{"auto", MSID_DFT_AUTO}, {"stream", MSID_DFT_STREAM}, {"fft", MSID_DFT_FFT}});
    msidjob::check_options(rq, given, D);   // the job's rules, in neutral words
}

const double *samples_of(const py::array &a, size_t &rows, size_t &cols)
{
    static const double none = 0.0;
    if (a.ndim() == 2 && a.size() == 0 && a.dtype().is(py::dtype::of<double>())) {
        // an empty matrix (a callback's block of 0 frames): NumPy calls any strides of it contiguous
        rows = (size_t)a.shape(0);
        cols = (size_t)a.shape(1);
        return &none;
    }
    const bool dense = a.ndim() == 2 && a.dtype().is(py::dtype::of<double>()) &&
                       (a.shape(1) <= 1 || a.strides(1) == (py::ssize_t)sizeof(double)) &&
                       (a.shape(0) <= 1 || a.strides(0) == a.shape(1) * (py::ssize_t)sizeof(double)) &&
                       reinterpret_cast<uintptr_t>(a.data()) % alignof(double) == 0;
    if (!dense) throw std::logic_error("internal error: msid._msid takes C-contiguous float64 matrices (msid/compute.py)");
    rows = (size_t)a.shape(0);
    cols = (size_t)a.shape(1);
    return static_cast<const double *>(a.data());
}

std::vector<msidrec::Record> records_of(const py::list &arrays, const py::list &names, const py::list &columns,
                                        const std::vector<uint32_t> &nu, bool inputs_optional)
{
    std::vector<msidrec::Record> recs(arrays.size());
    for (size_t k = 0; k < recs.size(); ++k) {
        msidrec::Record &r = recs[k];
        size_t rows = 0, cols = 0;
        r.view = samples_of(arrays[k].cast<py::array>(), rows, cols);
        r.path = names[k].cast<std::string>();
        r.columns = columns[k].cast<std::vector<std::string>>();
        if ((nu.at(k) == 0 && !inputs_optional) || nu[k] >= cols || r.columns.size() != cols)
            throw std::logic_error("internal error: columns of " + r.path);
        r.nu = nu[k];
        r.ny = (uint32_t)(cols - nu[k]);
        r.n_rows = rows;
    }
    return recs;
}

// ---- an msid-frf/1 document as the arrays of msid.FRF ----

namespace {

// A document of a million lines takes seconds to convert, with the GIL held: every CHUNK lines of each
// pass over them count as progress and Ctrl-C is asked (PyErr_CheckSignals: the signal handler's
// exception is raised), about a millisecond of work apart.
constexpr size_t CHUNK = 1024;

void ask_for_signals(size_t l)
{
    if (l % CHUNK != CHUNK - 1) return;
    count_progress(msidutil::Step::document, CHUNK);
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

// While the collector is paused (GcPause), the young generations collected every CHUNK lines: the new
// objects are scanned once either way, but in pieces between the questions for a signal, not by one
// collection of millions of objects (seconds, no signal seen) at the first allocation after the pause.
class YoungCollector {
public:
    YoungCollector() : collect_(py::module_::import("gc").attr("collect")) {}
    void at(size_t l)
    {
        ask_for_signals(l);
        if (l % CHUNK == CHUNK - 1) collect_(1);
    }

private:
    py::object collect_;
};

// Every line of the document holds `key` (msid.FRF keeps an array only then, as frf_from_doc does).
bool all_lines_have(const Json &lines, const char *key)
{
    for (size_t l = 0; l < lines.size(); ++l) {
        ask_for_signals(l);
        if (!lines[l].contains(key)) return false;
    }
    return true;
}

// lines[*][key], each an r x c {"re", "im"} matrix, as an L x r x c complex array.
py::array_t<std::complex<double>> stack_cmats(const Json &lines, const char *key, size_t r, size_t c)
{
    py::array_t<std::complex<double>> a({lines.size(), r, c});
    auto v = a.mutable_unchecked<3>();
    for (size_t l = 0; l < lines.size(); ++l) {
        ask_for_signals(l);
        const Json &m = lines[l][key];
        const Json &re = m.at("re"), &im = m.at("im");
        if (re.size() != r || im.size() != r) throw std::logic_error(std::string("internal error: the shape of ") + key);
        for (size_t i = 0; i < r; ++i) {
            if (re[i].size() != c || im[i].size() != c) throw std::logic_error(std::string("internal error: the shape of ") + key);
            for (size_t j = 0; j < c; ++j)
                v((py::ssize_t)l, (py::ssize_t)i, (py::ssize_t)j) = {re[i][j].get<double>(), im[i][j].get<double>()};
        }
    }
    return a;
}

template <class T>
py::array_t<T> column(const Json &lines, const char *key)
{
    py::array_t<T> a((py::ssize_t)lines.size());
    auto v = a.template mutable_unchecked<1>();
    for (size_t l = 0; l < lines.size(); ++l) {
        ask_for_signals(l);
        v((py::ssize_t)l) = lines[l][key].get<T>();
    }
    return a;
}

}  // namespace

void release_document(Json &&doc)
{
    // Freeing a document of a million lines takes seconds, with the GIL held and no signal seen:
    // beyond this many lines it is freed on a thread of its own (it owns nothing but its memory).
    constexpr size_t LARGE = 65536;
    const auto lines = doc.is_object() ? doc.find("lines") : doc.end();
    if (lines == doc.end() || !lines->is_array() || lines->size() < LARGE) {
        Json().swap(doc);
        return;
    }
    auto owned = std::make_unique<Json>(std::move(doc));
    try {
        std::thread([d = owned.get()] { delete d; }).detach();
        owned.release();
    } catch (const std::system_error &) {   // no thread to be had: freed here
    }
}

py::dict frf_to_py(const Json &doc)
{
    const Json &lines = doc.at("lines");
    const size_t ny = doc.at("n_outputs").get<size_t>(), nu = doc.at("n_inputs").get<size_t>(), g = ny * nu;
    static const char *const ARRAYS[] = {"bin", "freq", "freq_hz", "omega", "real", "G", "cov", "dof",
                                         "cov_known_input", "dof_known_input"};
    py::dict out;
    for (const char *k : ARRAYS) {
        if (!all_lines_have(lines, k)) continue;
        const std::string key(k);
        if (key == "G") out[k] = stack_cmats(lines, k, ny, nu);
        else if (key == "cov" || key == "cov_known_input") out[k] = stack_cmats(lines, k, g, g);
        else if (key == "bin") out[k] = column<int64_t>(lines, k);
        else if (key == "real") out[k] = column<bool>(lines, k);
        else out[k] = column<double>(lines, k);
    }
    if (!out.contains("real")) {   // a line without "real" is not a DC line
        py::array_t<bool> re((py::ssize_t)lines.size());
        auto v = re.mutable_unchecked<1>();
        for (size_t l = 0; l < lines.size(); ++l) {
            ask_for_signals(l);
            v((py::ssize_t)l) = lines[l].value("real", false);
        }
        out["real"] = re;
    }
    GcPause pause;
    YoungCollector young;
    py::dict meta;
    for (auto it = doc.begin(); it != doc.end(); ++it)
        if (it.key() != "lines") meta[py::str(it.key())] = to_py(it.value());
    py::list extra(lines.size());
    for (size_t l = 0; l < lines.size(); ++l) {
        young.at(l);
        py::dict e;
        for (auto it = lines[l].begin(); it != lines[l].end(); ++it)
            if (std::find(std::begin(ARRAYS), std::end(ARRAYS), it.key()) == std::end(ARRAYS))
                e[py::str(it.key())] = to_py(it.value());
        extra[l] = std::move(e);
    }
    out["meta"] = std::move(meta);
    out["line_extra"] = std::move(extra);
    return out;
}

py::dict frf_to_py(const msidjob::FrfOutcome &o)
{
    if (!o.doc.is_null()) return frf_to_py(o.doc);
    const msidjob::FrfResult &r = o.frf;
    const size_t L = r.n_lines(), ny = r.header.ny, nu = r.header.nu, g = ny * nu;
    auto stack = [&](const std::vector<std::complex<double>> &v, size_t rows, size_t cols) {
        py::array_t<std::complex<double>> a({L, rows, cols});
        std::copy(v.begin(), v.end(), a.mutable_data());
        return a;
    };
    auto vec = [](const std::vector<double> &v) {
        py::array_t<double> a((py::ssize_t)v.size());
        std::copy(v.begin(), v.end(), a.mutable_data());
        return a;
    };
    py::array_t<int64_t> bin((py::ssize_t)L);
    py::array_t<double> freq((py::ssize_t)L), freq_hz((py::ssize_t)L), omega((py::ssize_t)L);
    py::array_t<bool> real((py::ssize_t)L);
    const bool ct = r.header.ct, has_hz = ct || r.header.fs > 0;
    for (size_t l = 0; l < L; ++l) {   // the values msidfrf::position() writes
        const msidfrf::Position &p = r.pos[l];
        bin.mutable_data()[l] = p.bin;
        freq.mutable_data()[l] = (double)p.bin / p.period;
        omega.mutable_data()[l] = p.omega;
        freq_hz.mutable_data()[l] = ct ? p.omega / (2 * M_PI) : (double)p.bin / p.period * p.fs;
        real.mutable_data()[l] = p.bin == 0;
    }
    py::dict out;
    out["bin"] = bin;
    out["freq"] = freq;
    if (L && has_hz) out["freq_hz"] = freq_hz;
    if (L && ct) out["omega"] = omega;
    if (L && r.pos[0].bin == 0 && L == 1) out["real"] = real;   // as a document whose every line says "real"
    out["G"] = stack(r.G, ny, nu);
    out["cov"] = stack(r.cov, g, g);
    out["dof"] = vec(r.dof);
    out["cov_known_input"] = stack(r.cov_ki, g, g);
    out["dof_known_input"] = vec(r.dof_ki);
    if (!out.contains("real")) out["real"] = real;
    py::dict meta;
    const Json m = msidjob::frf_meta(r);
    for (auto it = m.begin(); it != m.end(); ++it) meta[py::str(it.key())] = to_py(it.value());
    // per line the members not held in arrays, as a document's line holds them
    auto number_or_none = [](double v) -> py::object { return std::isfinite(v) ? py::object(py::float_(v)) : py::none(); };
    py::list extra(L);
    py::str k_noise("noise_cov"), k_snr("snr"), k_cond("cond"), k_isnr("input_snr"), k_re("re"), k_im("im");
    for (size_t l = 0; l < L; ++l) {
        ask_for_signals(l);
        const std::complex<double> *nc = &r.noise[l * ny * ny];
        py::list re(ny), im(ny);
        for (size_t i = 0; i < ny; ++i) {
            py::list a(ny), b(ny);
            for (size_t j = 0; j < ny; ++j) {
                a[j] = py::float_(nc[i * ny + j].real());
                b[j] = py::float_(nc[i * ny + j].imag());
            }
            re[i] = std::move(a);
            im[i] = std::move(b);
        }
        py::dict n;
        n[k_re] = std::move(re);
        n[k_im] = std::move(im);
        py::list snr(ny);
        for (size_t i = 0; i < ny; ++i) snr[i] = number_or_none(r.snr[l * ny + i]);
        py::dict e;
        e[k_noise] = std::move(n);
        e[k_snr] = std::move(snr);
        e[k_cond] = py::float_(r.cond[l]);
        e[k_isnr] = number_or_none(r.input_snr[l]);
        extra[l] = std::move(e);
    }
    out["meta"] = std::move(meta);
    out["line_extra"] = std::move(extra);
    return out;
}

}  // namespace msidpy
