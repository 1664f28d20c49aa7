// `msid export`: an msid-frf/1 file as CSV (spreadsheets) or MATLAB .mat in the shape of idfrd
// (docs/python.md#msid-export). Reads with the fitting tools' reader (tools/fit/frf_data.cpp: shapes
// and finiteness checked); writes atomically (temporary file, then rename): a failed run leaves no file.
#include "cli_util.hpp"
#include "commands.hpp"
#include "frf_data.hpp"
#include "matio_dl.hpp"   // libmatio on first use (tools/records)

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

namespace msidcli {
using msidrec::matio;
using msidrec::Matio;

static const char *HELP =
    "usage: msid export frf.json (--csv out.csv | --mat out.mat) [--known-input]\n"
    "Frequencies, G and standard deviations of an msid-frf/1 file for spreadsheets and MATLAB.\n"
    "  --csv   one row per line: bin, freq (cycles/sample), freq_hz (when the rate is known), omega\n"
    "          (rad/s; rad/sample without a sample time), then per output i / input j the columns\n"
    "          G_yi_uj_re, G_yi_uj_im, G_yi_uj_sd (sd = sqrt of the complex variance E|Ghat - G|^2), and dof\n"
    "  --mat   MATLAB v5: ResponseData (ny x nu x L complex), Frequency (L x 1, rad/s or rad/sample),\n"
    "          Ts (sample time; 0 for a continuous-time file, 1 when unknown), CovarianceData\n"
    "          (ny x nu x L x 2 x 2: covariance of [Re Im], circular noise: v/2 on the diagonal; DC lines\n"
    "          v and 0), SD (ny x nu x L), dof (L x 1), Bin, FrequencyHz (when known), FrequencyUnit:\n"
    "          idfrd(ResponseData, Frequency, Ts, 'CovarianceData', CovarianceData, 'FrequencyUnit', FrequencyUnit)\n"
    "  --known-input   standard deviations from cov_known_input instead of cov\n";

namespace {

struct Exported {
    msidfit::FrfData f;
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
        if (!m_) throw Error("cannot create '" + path + "'");
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
    void close()
    {
        if (M_.Close(m_) != 0) { m_ = nullptr; throw Error("cannot write '" + path_ + "'"); }
        m_ = nullptr;
    }

private:
    void put(matvar_t *v, const char *name)
    {
        // VarCreate keeps a pointer to the data (no copy): it must live until VarWrite returns
        const int rc = v ? M_.VarWrite(m_, v, MAT_COMPRESSION_NONE) : -1;
        if (v) M_.VarFree(v);
        if (rc != 0) throw Error("cannot write variable " + std::string(name) + " to '" + path_ + "'");
    }
    const Matio &M_;
    std::string path_;
    mat_t *m_ = nullptr;
};

void write_mat(const Exported &e, const std::string &tmp)
{
    const auto &f = e.f;
    const size_t L = f.lines.size(), ny = f.ny, nu = f.nu;
    const size_t n3 = ny * nu * L;
    std::vector<double> re(n3), im(n3), sd(n3), cov(n3 * 4, 0.0), om(L), hz(L), dof(L), bin(L);
    for (size_t k = 0; k < L; ++k) {
        const auto &l = f.lines[k];
        om[k] = l.omega;
        hz[k] = f.domain == msidfit::Domain::CT ? l.omega / (2 * M_PI) : l.freq / f.h;
        dof[k] = e.dof(k);
        bin[k] = l.bin;
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
            }
    }
    MatWriter w(matio(), tmp);
    w.cplx("ResponseData", {ny, nu, L}, re, im);
    w.real("Frequency", {L, 1}, om);
    w.real("Ts", {1, 1}, {f.domain == msidfit::Domain::CT ? 0.0 : (f.h > 0 ? f.h : 1.0)});
    w.real("CovarianceData", {ny, nu, L, 2, 2}, cov);
    w.real("SD", {ny, nu, L}, sd);
    w.real("dof", {L, 1}, dof);
    w.real("Bin", {L, 1}, bin);
    if (f.h > 0) w.real("FrequencyHz", {L, 1}, hz);
    w.text("FrequencyUnit", f.h > 0 ? "rad/s" : "rad/TimeUnit");
    w.close();
}

}  // namespace

int cmd_export(int argc, char **argv)
{
    Args a(argc, argv, 2, HELP, {"csv", "mat"}, {"known-input"});
    if (a.positional().size() != 1) throw UsageError("give one FRF file (msid export frf.json --csv out.csv | --mat out.mat)");
    if (a.has("csv") == a.has("mat")) throw UsageError("give exactly one of --csv out.csv and --mat out.mat");
    Exported e;
    e.f = msidfit::read_frf(a.positional()[0]);
    e.known_input = a.has("known-input");
    for (size_t k = 0; k < e.f.lines.size(); ++k) {
        const auto &l = e.f.lines[k];
        if ((e.known_input ? l.cov_ki : l.cov).rows() == 0)
            throw Error(fmt("'%s': lines[%zu] has no %s: nothing to take the standard deviations from",
                            a.positional()[0].c_str(), k, e.known_input ? "cov_known_input" : "cov"));
    }
    if (a.has("csv")) {
        write_file_atomic(a.get("csv"), to_csv(e));
        std::printf("wrote %s: %zu lines, %ux%u\n", a.get("csv").c_str(), e.f.lines.size(), e.f.ny, e.f.nu);
        return 0;
    }
    const std::string out = a.get("mat"), tmp = out + fmt(".tmp.%d", (int)getpid());
    try {
        write_mat(e, tmp);
        if (std::rename(tmp.c_str(), out.c_str()) != 0)
            throw Error("cannot write '" + out + "': " + std::strerror(errno));
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
    std::printf("wrote %s: %zu lines, %ux%u (idfrd: ResponseData, Frequency, Ts, CovarianceData)\n", out.c_str(),
                e.f.lines.size(), e.f.ny, e.f.nu);
    return 0;
}

}  // namespace msidcli
