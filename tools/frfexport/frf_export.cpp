// msid-frf/1 and msid-model/1 files for other tools (msid_frf_export.hpp).
#include "msid_frf_export.hpp"

#include "frf_data.hpp"
#include "matio_dl.hpp"   // libmatio on first use (tools/records)
#include "model_io.hpp"
#include "msid_json_file.hpp"
#include "msid_partial_file.hpp"
#include "stats.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

namespace msidexport {

using msidrec::matio;
using msidrec::Matio;
using msidutil::fmt;
using msidutil::Error;
using msidfmt::Json;
using msidfmt::read_json_file;

namespace {

struct Exported {
    msidfit::FrfData f;
    Json doc;   // the file's document: the signals' names and units
    bool known_input = false;
    // complex variance of element (i, j) of line k: cov[i + ny j][i + ny j]
    double var(size_t k, uint32_t i, uint32_t j) const
    {
        const auto &l = f.lines[k];
        const auto &c = known_input ? l.cov_ki : l.cov;
        const Eigen::Index a = (Eigen::Index)(i + f.ny * j);
        return c.rows() ? std::max(0.0, c(a, a).real()) : std::nan("");
    }
    double dof(size_t k) const { return known_input ? f.lines[k].dof_ki : f.lines[k].dof; }
};

std::string num(double v) { return std::isfinite(v) ? fmt("%.17g", v) : std::string(); }

std::string to_csv(const Exported &e)
{
    const auto &f = e.f;
    std::string s = "bin,freq";
    const bool hz = f.h > 0;
    if (hz) s += ",freq_hz";
    s += ",omega";
    for (uint32_t i = 0; i < f.ny; ++i)
        for (uint32_t j = 0; j < f.nu; ++j)
            s += fmt(",G_y%u_u%u_re,G_y%u_u%u_im,G_y%u_u%u_sd", i + 1, j + 1, i + 1, j + 1, i + 1, j + 1);
    s += ",dof\n";
    for (size_t k = 0; k < f.lines.size(); ++k) {
        const auto &l = f.lines[k];
        s += fmt("%u,", l.bin) + num(l.freq);
        if (hz) s += "," + num(f.domain == msidfit::Domain::CT ? l.omega / (2 * M_PI) : l.freq / f.h);
        s += "," + num(l.omega);
        for (uint32_t i = 0; i < f.ny; ++i)
            for (uint32_t j = 0; j < f.nu; ++j)
                s += "," + num(l.G(i, j).real()) + "," + num(l.G(i, j).imag()) + "," + num(std::sqrt(e.var(k, i, j)));
        s += "," + num(e.dof(k)) + "\n";
    }
    return s;
}

class MatWriter {
public:
    MatWriter(const Matio &M, const std::string &path) : M_(M), path_(path)
    {
        m_ = M.CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
        if (!m_) throw msidutil::IoError("cannot create '" + path + "'");
    }
    ~MatWriter() { if (m_) M_.Close(m_); }
    void real(const char *name, std::vector<size_t> dims, std::vector<double> data)
    {
        put(M_.VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, (int)dims.size(), dims.data(), data.data(), 0), name);
    }
    void cplx(const char *name, std::vector<size_t> dims, std::vector<double> re, std::vector<double> im)
    {
        mat_complex_split_t z{re.data(), im.data()};
        put(M_.VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, (int)dims.size(), dims.data(), &z, MAT_F_COMPLEX), name);
    }
    void text(const char *name, const std::string &s)
    {
        size_t dims[2] = {1, s.size()};
        std::string copy = s;
        put(M_.VarCreate(name, MAT_C_CHAR, MAT_T_UINT8, 2, dims, copy.data(), 0), name);
    }
    // A column cell array of char rows ({'u1'; 'u2'}: the InputName/OutputName of ss and idss).
    void cellstr(const char *name, const std::vector<std::string> &items)
    {
        std::vector<std::string> copies(items);
        std::vector<matvar_t *> cells;
        for (auto &c : copies) {
            size_t d[2] = {1, c.size()};
            matvar_t *v = M_.VarCreate(nullptr, MAT_C_CHAR, MAT_T_UINT8, 2, d, c.data(), 0);
            if (!v) {
                for (matvar_t *x : cells) M_.VarFree(x);
                throw msidutil::IoError("cannot write variable " + std::string(name) + " to '" + path_ + "'");
            }
            cells.push_back(v);
        }
        size_t dims[2] = {cells.size(), 1};
        // the cell takes the element variables (it copies the pointers): VarFree of the cell frees them
        matvar_t *cell = M_.VarCreate(name, MAT_C_CELL, MAT_T_CELL, 2, dims, cells.data(), 0);
        if (!cell)
            for (matvar_t *x : cells) M_.VarFree(x);
        put(cell, name);
    }
    void close()
    {
        if (M_.Close(m_) != 0) { m_ = nullptr; throw msidutil::IoError("cannot write '" + path_ + "'"); }
        m_ = nullptr;
    }

private:
    void put(matvar_t *v, const char *name)
    {
        // VarCreate keeps a pointer to the data (no copy): it must live until VarWrite returns
        const int rc = v ? M_.VarWrite(m_, v, MAT_COMPRESSION_NONE) : -1;
        if (v) M_.VarFree(v);
        if (rc != 0) throw msidutil::IoError("cannot write variable " + std::string(name) + " to '" + path_ + "'");
    }
    const Matio &M_;
    std::string path_;
    mat_t *m_ = nullptr;
};

// Variance factor of line k that makes showConfidence's Gaussian region at SD95 standard deviations
// (Mahalanobis radius sqrt(chi2_2 quantile) = sqrt(-2 log 0.05)) the exact 95% region of the file:
// |e|^2 / v ~ F(2, 2 dof) on complex lines (radius^2 = v dof (0.05^(-1/dof) - 1)), e^2 / v ~ F(1, dof) on DC
// lines (docs/statistics.md). It tends to 1 as the dof grow; no dof (infinite) is 1.
constexpr double CONF_ALPHA = 0.05;
double sd95() { return std::sqrt(-2.0 * std::log(CONF_ALPHA)); }

double f1_quantile(double n, double alpha)
{
    double lo = 0, hi = 1;
    while (msidfit::f_sf(1, n, hi) > alpha && hi < 1e300) hi *= 2;
    for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        (msidfit::f_sf(1, n, mid) > alpha ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

double confidence_scale95(double dof, bool dc)
{
    if (!(dof > 0) || !std::isfinite(dof)) return 1.0;
    const double s2 = sd95() * sd95();
    if (dc) return f1_quantile(dof, CONF_ALPHA) / s2;          // Re only, all of v: SD95^2 c v = v q1
    return 2.0 * dof * std::expm1(-std::log(CONF_ALPHA) / dof) / s2;   // v/2 per axis: SD95^2 c v/2 = v q2
}

// Names of the inputs or outputs: the file's `key` list when it has n non-empty strings, else
// <prefix>1 .. <prefix>n (the names msid prints).
std::vector<std::string> signal_names(const Json &doc, const char *key, size_t n, const char *prefix)
{
    std::vector<std::string> out;
    if (doc.contains(key) && doc[key].is_array() && doc[key].size() == n)
        for (const auto &x : doc[key])
            if (x.is_string() && !x.get<std::string>().empty()) out.push_back(x.get<std::string>());
    if (out.size() == n) return out;
    out.clear();
    for (size_t k = 0; k < n; ++k) out.push_back(fmt("%s%zu", prefix, k + 1));
    return out;
}

// Units of the inputs or outputs: the file's `key` list when it has n strings ("" where unknown),
// else n empty strings (idfrd's and ss's InputUnit/OutputUnit take empty units).
std::vector<std::string> signal_units(const Json &doc, const char *key, size_t n)
{
    std::vector<std::string> out;
    if (doc.contains(key) && doc[key].is_array() && doc[key].size() == n)
        for (const auto &x : doc[key])
            if (x.is_string()) out.push_back(x.get<std::string>());
    if (out.size() != n) out.assign(n, "");
    return out;
}

// InputName, OutputName, InputUnit, OutputUnit (cell arrays of char) as idfrd, ss and idss take them.
void write_signals(MatWriter &w, const Json &doc, size_t nu, size_t ny)
{
    w.cellstr("InputName", signal_names(doc, "input_names", nu, "u"));
    w.cellstr("OutputName", signal_names(doc, "output_names", ny, "y"));
    w.cellstr("InputUnit", signal_units(doc, "input_units", nu));
    w.cellstr("OutputUnit", signal_units(doc, "output_units", ny));
}

void write_mat(const Exported &e, const std::string &tmp)
{
    const auto &f = e.f;
    const size_t L = f.lines.size(), ny = f.ny, nu = f.nu;
    const size_t n3 = ny * nu * L;
    std::vector<double> re(n3), im(n3), sd(n3), cov(n3 * 4, 0.0), cov95(n3 * 4, 0.0), om(L), hz(L), dof(L), bin(L),
        scale(L);
    for (size_t k = 0; k < L; ++k) {
        const auto &l = f.lines[k];
        om[k] = l.omega;
        hz[k] = f.domain == msidfit::Domain::CT ? l.omega / (2 * M_PI) : l.freq / f.h;
        dof[k] = e.dof(k);
        bin[k] = l.bin;
        scale[k] = confidence_scale95(dof[k], l.real);
        for (size_t j = 0; j < nu; ++j)
            for (size_t i = 0; i < ny; ++i) {
                const size_t a = i + ny * (j + nu * k);   // column-major (MATLAB) index of (i, j, k)
                re[a] = l.G((Eigen::Index)i, (Eigen::Index)j).real();
                im[a] = l.G((Eigen::Index)i, (Eigen::Index)j).imag();
                const double v = e.var(k, (uint32_t)i, (uint32_t)j);
                sd[a] = std::sqrt(v);
                // CovarianceData(i, j, k, r, c): [Re Im] covariance; circular noise splits v evenly
                const double vr = l.real ? v : v / 2, vi = l.real ? 0.0 : v / 2;
                cov[a + n3 * (0 + 2 * 0)] = vr;
                cov[a + n3 * (1 + 2 * 1)] = vi;
                cov95[a + n3 * (0 + 2 * 0)] = vr * scale[k];
                cov95[a + n3 * (1 + 2 * 1)] = vi * scale[k];
            }
    }
    MatWriter w(matio(), tmp);
    w.cplx("ResponseData", {ny, nu, L}, re, im);
    w.real("Frequency", {L, 1}, om);
    w.real("Ts", {1, 1}, {f.domain == msidfit::Domain::CT ? 0.0 : (f.h > 0 ? f.h : 1.0)});
    // an FRF without covariance (another tool's, msid import) has no uncertainty to export
    bool any_cov = false;
    for (const auto &l : f.lines) any_cov = any_cov || (e.known_input ? l.cov_ki : l.cov).size() > 0;
    if (any_cov) {
        w.real("CovarianceData", {ny, nu, L, 2, 2}, cov);
        w.real("SD", {ny, nu, L}, sd);
        w.real("dof", {L, 1}, dof);
        w.real("ConfidenceScale95", {L, 1}, scale);
        w.real("CovarianceData95", {ny, nu, L, 2, 2}, cov95);
        w.real("SD95", {1, 1}, {sd95()});
    }
    w.real("Bin", {L, 1}, bin);
    // rad/s when the frequencies are in seconds: a DT file with a sample time, any CT file (one
    // without a sample time, from msid import, has its lines in rad/s)
    const bool seconds = f.h > 0 || f.domain == msidfit::Domain::CT;
    if (seconds) w.real("FrequencyHz", {L, 1}, hz);
    w.text("FrequencyUnit", seconds ? "rad/s" : "rad/TimeUnit");
    write_signals(w, e.doc, nu, ny);
    w.close();
}

// A file whose "format" is msid-model/1 (anything else goes to the FRF reader, which names the problem).
bool model_file(const std::string &path)
{
    try {
        const Json d = read_json_file(path);
        return d.is_object() && d.value("format", std::string()) == "msid-model/1";
    } catch (const std::exception &) {
        return false;
    }
}

// MATLAB column-major copy of a real matrix.
std::vector<double> col_major(const msidfit::MatR &M)
{
    std::vector<double> v((size_t)(M.rows() * M.cols()));
    for (Eigen::Index c = 0; c < M.cols(); ++c)
        for (Eigen::Index r = 0; r < M.rows(); ++r) v[(size_t)(r + M.rows() * c)] = M(r, c);
    return v;
}

void write_model_mat(const std::string &path, const std::string &tmp)
{
    const msidfit::ModelFile mf = msidfit::read_model(path);
    const Json doc = read_json_file(path);
    const auto &m = mf.ss;
    const size_t n = (size_t)m.A.rows(), nu = (size_t)m.D.cols(), ny = (size_t)m.D.rows();
    MatWriter w(matio(), tmp);
    w.real("A", {n, n}, col_major(m.A));
    w.real("B", {n, nu}, col_major(m.B));
    w.real("C", {ny, n}, col_major(m.C));
    w.real("D", {ny, nu}, col_major(m.D));
    w.real("Ts", {1, 1}, {mf.domain == msidfit::Domain::CT ? 0.0 : (mf.h > 0 ? mf.h : 1.0)});
    write_signals(w, doc, nu, ny);
    w.text("Domain", mf.domain == msidfit::Domain::CT ? "ct" : "dt");
    w.text("Method", mf.method);
    w.real("Order", {1, 1}, {(double)n});
    w.close();
}

// Write `out` through a temporary file: a failed run leaves no file.
template <class F> void write_atomically(const std::string &out, F write)
{
    const std::string tmp = out + fmt(".tmp.%d", (int)getpid());
    const msidutil::PartialFile partial(tmp);
    try {
        write(tmp);
        if (std::rename(tmp.c_str(), out.c_str()) != 0)
            throw msidutil::IoError("cannot write '" + out + "': " + std::strerror(errno));
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
}


// The FRF file read for export, with a covariance on every line for the standard deviations.
Exported exported(const std::string &path, bool known_input)
{
    Exported e;
    e.f = msidfit::read_frf(path);
    e.doc = msidfmt::read_json_file(path);
    e.known_input = known_input;
    for (size_t k = 0; k < e.f.lines.size(); ++k) {
        const auto &l = e.f.lines[k];
        if ((e.known_input ? l.cov_ki : l.cov).rows() == 0)
            throw Error(fmt("'%s': lines[%zu] has no %s: nothing to take the standard deviations from", path.c_str(), k,
                            e.known_input ? "cov_known_input" : "cov"));
    }
    return e;
}

}  // namespace

bool is_model_file(const std::string &path) { return model_file(path); }

ExportSummary export_frf_csv(const std::string &frf_path, const std::string &out, bool known_input)
{
    const Exported e = exported(frf_path, known_input);
    msidutil::write_file_atomic(out, to_csv(e));
    return {e.f.lines.size(), e.f.ny, e.f.nu};
}

ExportSummary export_frf_mat(const std::string &frf_path, const std::string &out, bool known_input)
{
    const Exported e = exported(frf_path, known_input);
    write_atomically(out, [&](const std::string &tmp) { write_mat(e, tmp); });
    return {e.f.lines.size(), e.f.ny, e.f.nu};
}

void export_model_mat(const std::string &model_path, const std::string &out)
{
    write_atomically(out, [&](const std::string &tmp) { write_model_mat(model_path, tmp); });
}

}  // namespace msidexport
