// An idfrd-shaped MATLAB v5 or v7.3 .mat, as MATLAB's System Identification Toolbox saves the fields of an
// idfrd and as `msid export --mat` writes them: ResponseData (ny x nu x L complex; MATLAB drops trailing
// singleton dimensions), Frequency (L values), Ts (0: continuous time), FrequencyUnit (rad/s,
// rad/TimeUnit, Hz, kHz, MHz, GHz, cycles/TimeUnit, rpm), optional CovarianceData (ny x nu x L x 2 x 2,
// the covariance of [Re Im] of each element: its trace is the complex variance), dof (msid's export),
// InputName, OutputName, InputUnit, OutputUnit (cell arrays of char). Read by tools/records'
// read_mat_values: v5 by msid's own reader, v7.3 through libmatio after its HDF5 objects are bounded;
// every size checked against the file before it sizes anything.
#include "frf_import.hpp"

#include "msid_mat_values.hpp"
#include "msid_records.hpp"

#include <cmath>
#include <map>

namespace msidfrfimport {

namespace {

const msidrec::MatValue *find(const std::vector<msidrec::MatValue> &v, const std::string &name)
{
    for (const auto &x : v)
        if (x.name == name) return &x;
    return nullptr;
}

const msidrec::MatValue &need_numeric(const std::string &path, const std::vector<msidrec::MatValue> &v,
                                      const std::string &name)
{
    const msidrec::MatValue *x = find(v, name);
    if (!x) throw Error("'" + path + "' has no variable '" + name + "' (an idfrd-shaped .mat: ResponseData, Frequency, Ts)");
    if (x->kind != msidrec::MatValue::Numeric) throw Error("'" + path + "' variable '" + name + "' is not numeric");
    return *x;
}

// rad/s per unit of the Frequency variable (rad/TimeUnit, cycles/TimeUnit: per the time unit, which
// msid takes as seconds); 0 for a unit it does not know.
double rad_s_per(const std::string &unit)
{
    static const std::map<std::string, double> u = {
        {"rad/s", 1.0}, {"rad/TimeUnit", 1.0}, {"Hz", 2 * M_PI}, {"kHz", 2e3 * M_PI}, {"MHz", 2e6 * M_PI},
        {"GHz", 2e9 * M_PI}, {"cycles/TimeUnit", 2 * M_PI}, {"rpm", 2 * M_PI / 60}};
    const auto it = u.find(unit);
    return it == u.end() ? 0.0 : it->second;
}

std::vector<std::string> cells(const std::string &path, const std::vector<msidrec::MatValue> &v, const char *name,
                               uint32_t n)
{
    const msidrec::MatValue *x = find(v, name);
    if (!x) return {};
    if (x->kind == msidrec::MatValue::Char && n == 1) return {x->text};
    if (x->kind != msidrec::MatValue::Cells || x->cells.size() != n)
        throw Error("'" + path + "' variable '" + name + "' must be a cell array of " + std::to_string(n) + " char rows");
    return x->cells;
}

}  // namespace

Imported read_idfrd_mat(const std::string &path)
{
    const std::vector<msidrec::MatValue> v = msidrec::read_mat_values(
        path, {"ResponseData", "Frequency", "Ts", "FrequencyUnit", "CovarianceData", "dof", "InputName", "OutputName",
               "InputUnit", "OutputUnit"});
    const msidrec::MatValue &R = need_numeric(path, v, "ResponseData");
    const msidrec::MatValue &F = need_numeric(path, v, "Frequency");
    const msidrec::MatValue &T = need_numeric(path, v, "Ts");
    // sizes: ny x nu x L, trailing singleton dimensions dropped (L = 1: ny x nu)
    if (R.dims.size() < 2 || R.dims.size() > 3 || (R.dims.size() == 3 && R.dims[2] == 0))
        throw Error("'" + path + "': ResponseData must be ny x nu x L");
    const uint64_t ny = R.dims[0], nu = R.dims[1], L = R.dims.size() == 3 ? R.dims[2] : 1;
    if (ny == 0 || nu == 0 || ny > 16 || nu > 16)
        throw Error("'" + path + "': ResponseData is " + std::to_string(ny) + " x " + std::to_string(nu) +
                    " x L; msid takes 1..16 outputs and inputs");
    if (F.re.size() != L)
        throw Error("'" + path + "': Frequency has " + std::to_string(F.re.size()) + " values, ResponseData " +
                    std::to_string(L) + " lines");
    if (T.re.size() != 1 || !std::isfinite(T.re[0]) || T.re[0] < 0)
        throw Error("'" + path + "': Ts must be one non-negative number (0: continuous time)");
    const msidrec::MatValue *U = find(v, "FrequencyUnit");
    const std::string unit = U && U->kind == msidrec::MatValue::Char ? U->text : "rad/TimeUnit";
    const double scale = rad_s_per(unit);
    if (scale == 0) throw Error("'" + path + "': FrequencyUnit '" + unit + "' is not one msid reads (rad/s, Hz, ...)");
    Imported im;
    im.path = path;
    im.format = "mat";
    im.ny = (uint32_t)ny;
    im.nu = (uint32_t)nu;
    im.ct = T.re[0] == 0;
    im.sample_time = T.re[0];
    const bool cplx = !R.im.empty();
    for (uint64_t k = 0; k < L; ++k) {
        im.omega.push_back(F.re[k] * scale);
        MatC G((Eigen::Index)ny, (Eigen::Index)nu);
        for (uint64_t j = 0; j < nu; ++j)
            for (uint64_t i = 0; i < ny; ++i) {
                const size_t at = (size_t)(i + ny * (j + nu * k));   // column-major
                G((Eigen::Index)i, (Eigen::Index)j) = cd(R.re[at], cplx ? R.im[at] : 0.0);
            }
        im.G.push_back(G);
    }
    const msidrec::MatValue *C = find(v, "CovarianceData");
    if (C && C->kind == msidrec::MatValue::Numeric && !C->re.empty()) {
        const size_t g = (size_t)(ny * nu);
        if (C->re.size() != g * L * 4)
            throw Error("'" + path + "': CovarianceData must be ny x nu x L x 2 x 2 (" + std::to_string(g * L * 4) +
                        " values), it has " + std::to_string(C->re.size()));
        const msidrec::MatValue *D = find(v, "dof");
        if (D && (D->kind != msidrec::MatValue::Numeric || D->re.size() != L))
            throw Error("'" + path + "': dof must hold one number per line");
        for (uint64_t k = 0; k < L; ++k) {
            MatC Cv = MatC::Zero((Eigen::Index)g, (Eigen::Index)g);
            for (uint64_t j = 0; j < nu; ++j)
                for (uint64_t i = 0; i < ny; ++i) {
                    // the complex variance E|e|^2: the trace of the [Re Im] covariance
                    auto at = [&](uint64_t r, uint64_t c) { return C->re[(size_t)(i + ny * (j + nu * (k + L * (r + 2 * c))))]; };
                    Cv((Eigen::Index)(i + ny * j), (Eigen::Index)(i + ny * j)) = at(0, 0) + at(1, 1);
                }
            im.cov.push_back(Cv);
            // no dof in an idfrd: the covariance is taken as known (the chi-square law)
            im.dof.push_back(D ? D->re[(size_t)k] : 1e9);
        }
    }
    im.input_names = cells(path, v, "InputName", im.nu);
    im.output_names = cells(path, v, "OutputName", im.ny);
    im.input_units = cells(path, v, "InputUnit", im.nu);
    im.output_units = cells(path, v, "OutputUnit", im.ny);
    im.info["frequency_unit"] = unit;
    im.info["Ts"] = T.re[0];
    return im;
}

}  // namespace msidfrfimport
