#include "frf_data.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include "json_util.hpp"
#include <sstream>

namespace msidfit {

Json read_json(const std::string &path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw FitError("cannot open '" + path + "': " + std::strerror(errno));
    std::stringstream ss;
    ss << in.rdbuf();
    try {
        return Json::parse(ss.str());
    } catch (const Json::parse_error &e) {
        throw FitError("'" + path + "' is not valid JSON: " + e.what());
    }
}

cd line_point(const Line &l, Domain d)
{
    if (d == Domain::DT) return std::polar(1.0, 2.0 * M_PI * l.freq);
    return cd(0.0, l.omega);
}

static std::string where(const std::string &file, const std::string &what) { return "'" + file + "': " + what; }

static const Json &need(const Json &o, const char *key, const std::string &file, const std::string &ctx = "")
{
    if (!o.is_object()) throw FitError(where(file, (ctx.empty() ? "" : ctx + ": ") + "expected an object"));
    auto it = o.find(key);
    if (it == o.end()) throw FitError(where(file, "missing '" + (ctx.empty() ? "" : ctx + ".") + key + "'"));
    return *it;
}

static double num(const Json &v, const std::string &file, const std::string &what)
{
    if (!v.is_number()) throw FitError(where(file, what + " must be a number"));
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw FitError(where(file, what + " is not finite"));
    return x;
}

static uint32_t uint(const Json &v, const std::string &file, const std::string &what)
{
    if (!v.is_number_integer() || v.get<int64_t>() < 0 || v.get<int64_t>() > 0xFFFFFFFFll)
        throw FitError(where(file, what + " must be a non-negative 32-bit integer"));
    return (uint32_t)v.get<int64_t>();
}

static MatC cmat(const Json &v, size_t rows, size_t cols, const std::string &file, const std::string &what)
{
    if (!v.is_object() || !v.contains("re") || !v.contains("im"))
        throw FitError(where(file, what + " must be {\"re\": [[...]], \"im\": [[...]]}"));
    const Json &re = v["re"], &im = v["im"];
    if (!re.is_array() || !im.is_array() || re.size() != rows || im.size() != rows)
        throw FitError(where(file, what + " must have " + std::to_string(rows) + " rows"));
    MatC M(rows, cols);
    for (size_t r = 0; r < rows; ++r) {
        if (!re[r].is_array() || !im[r].is_array() || re[r].size() != cols || im[r].size() != cols)
            throw FitError(where(file, what + " must have " + std::to_string(cols) + " columns"));
        for (size_t c = 0; c < cols; ++c)
            M(r, c) = cd(num(re[r][c], file, what), num(im[r][c], file, what));
    }
    return M;
}

FrfData read_frf(const std::string &path)
{
    const Json j = read_json(path);
    const Json &fm = need(j, "format", path);
    if (!fm.is_string() || fm.get<std::string>() != "msid-frf/1")
        throw FitError(where(path, "format is " + fm.dump() + ", expected \"msid-frf/1\""));
    FrfData f;
    f.path = path;
    f.P = uint(need(j, "period_samples", path), path, "'period_samples'");
    f.nu = uint(need(j, "n_inputs", path), path, "'n_inputs'");
    f.ny = uint(need(j, "n_outputs", path), path, "'n_outputs'");
    f.m = uint(need(j, "n_experiments", path), path, "'n_experiments'");
    if (f.nu == 0 || f.ny == 0 || f.nu > 16 || f.ny > 16) throw FitError(where(path, "n_inputs/n_outputs out of range"));
    if (f.m == 0 || f.m > 64) throw FitError(where(path, "'n_experiments' must be 1..64"));
    const Json &dom = need(j, "domain", path);
    if (dom == "ct") f.domain = Domain::CT;
    else if (dom == "dt") f.domain = Domain::DT;
    else throw FitError(where(path, "'domain' must be \"dt\" or \"ct\""));
    if (j.contains("sample_time")) {
        f.h = num(j["sample_time"], path, "'sample_time'");
        if (!(f.h > 0)) throw FitError(where(path, "'sample_time' must be positive"));
    }
    if (f.domain == Domain::CT && f.h <= 0) throw FitError(where(path, "a continuous-time file needs 'sample_time'"));
    if (j.contains("method") && j["method"].is_string()) f.method = j["method"].get<std::string>();
    if (j.contains("nonlinear_distortion") && j["nonlinear_distortion"].is_object() &&
        j["nonlinear_distortion"].contains("realisations") && j["nonlinear_distortion"]["realisations"].is_number_integer())
        f.realisations = (uint32_t)std::max<int64_t>(1, j["nonlinear_distortion"]["realisations"].get<int64_t>());
    const size_t g = f.g();
    f.noise_time = cmat(need(j, "noise_cov", path), f.ny, f.ny, path, "'noise_cov'");
    const Json &lines = need(j, "lines", path);
    if (!lines.is_array() || lines.empty()) throw FitError(where(path, "'lines' must be a non-empty array"));
    for (size_t k = 0; k < lines.size(); ++k) {
        const Json &e = lines[k];
        const std::string ctx = "lines[" + std::to_string(k) + "]";
        Line l;
        l.bin = uint(need(e, "bin", path, ctx), path, ctx + ".bin");
        l.freq = num(need(e, "freq", path, ctx), path, ctx + ".freq");
        if (e.contains("omega")) l.omega = num(e["omega"], path, ctx + ".omega");
        else if (f.h > 0) l.omega = 2.0 * M_PI * l.freq / f.h;
        else l.omega = 2.0 * M_PI * l.freq;
        l.real = e.contains("real") && e["real"].is_boolean() && e["real"].get<bool>();
        l.G = cmat(need(e, "G", path, ctx), f.ny, f.nu, path, ctx + ".G");
        if (e.contains("cov")) {
            l.cov = cmat(e["cov"], g, g, path, ctx + ".cov");
            l.dof = num(need(e, "dof", path, ctx), path, ctx + ".dof");
            if (!(l.dof >= 1)) throw FitError(where(path, ctx + ".dof must be at least 1"));
        }
        if (e.contains("cov_known_input")) {
            l.cov_ki = cmat(e["cov_known_input"], g, g, path, ctx + ".cov_known_input");
            l.dof_ki = e.contains("dof_known_input") ? num(e["dof_known_input"], path, ctx + ".dof_known_input") : l.dof;
            if (!(l.dof_ki >= 1)) throw FitError(where(path, ctx + ".dof_known_input must be at least 1"));
        }
        if (e.contains("noise_cov")) l.noise = cmat(e["noise_cov"], f.ny, f.ny, path, ctx + ".noise_cov");
        f.lines.push_back(std::move(l));
    }
    return f;
}

std::vector<WeightedLine> weigh(const FrfData &f, Domain d, Weight w, double noise_var)
{
    if (f.domain == Domain::CT && d == Domain::DT)
        throw FitError("'" + f.path + "' holds a continuous-time FRF (lines may alias); fit a ct model (--domain ct)");
    const size_t g = f.g();
    std::vector<WeightedLine> out;
    for (const Line &l : f.lines) {
        WeightedLine wl;
        wl.x = line_point(l, d);
        wl.real = l.real;
        wl.G = l.G;
        MatC C;
        if (w == Weight::None) {
            C = MatC::Identity(g, g);
            wl.dof = 1e9;
        } else if (noise_var > 0.0) {
            if (l.cov_ki.size() == 0 || l.noise.size() == 0)
                throw FitError("'" + f.path + "': --noise-var needs cov_known_input and noise_cov at every line");
            const double sp = l.noise(0, 0).real();
            if (!(sp > 0)) throw FitError(where(f.path, "zero noise_cov at line bin " + std::to_string(l.bin)));
            MatC Om(f.nu, f.nu);
            for (uint32_t a = 0; a < f.nu; ++a)
                for (uint32_t b = 0; b < f.nu; ++b) Om(a, b) = l.cov_ki(f.ny * a, f.ny * b) / sp;
            MatC S = MatC::Identity(f.ny, f.ny) * (noise_var * f.P);
            C = MatC(g, g);
            for (uint32_t a = 0; a < f.nu; ++a)
                for (uint32_t b = 0; b < f.nu; ++b) C.block(f.ny * a, f.ny * b, f.ny, f.ny) = Om(a, b) * S;
            wl.dof = 1e9;   // known noise
        } else {
            const MatC &src = w == Weight::KnownInput ? l.cov_ki : l.cov;
            if (src.size() == 0)
                throw FitError("'" + f.path + "' has no " + (w == Weight::KnownInput ? "cov_known_input" : "cov") +
                               " at line bin " + std::to_string(l.bin) + ": this method needs the FRF covariance");
            C = src;
            wl.dof = w == Weight::KnownInput ? l.dof_ki : l.dof;
            // The nonparametric covariance with several inputs is sum_e (w_e^T conj w_e) (x) S_e with
            // rank-one design factors: its inverse splits over the experiments, so its inverse moments
            // are those of one experiment's Wishart (K_e - 1 = dof/m dof for balanced designs), not of
            // the pooled dof. With one input the factors are scalars and the pooled dof applies.
            if (w == Weight::Cov && f.nu > 1 && f.m > 1 && f.method != "lpm" && f.method != "etfe" && f.realisations < 2)
                wl.dof = l.dof / f.m;
            // A robust-BLA file's cov is a plain sample covariance of the g = ny nu vector (R - 1 dof):
            // its inverse moment is n/(n - g); dof/nu gives that mean in the laws written for p = ny.
            if (w == Weight::Cov && f.nu > 1 && f.realisations >= 2) wl.dof = l.dof / f.nu;
        }
        // Hermitian part; real lines: real covariance
        MatC H = 0.5 * (C + C.adjoint());
        if (l.real) H = H.real().cast<cd>();
        Eigen::LLT<MatC> llt(H);
        const double scale = H.diagonal().real().cwiseAbs().maxCoeff();
        if (llt.info() != Eigen::Success || !(scale > 0) || !std::isfinite(scale)) {
            // a sample covariance of ny outputs from M periods has rank <= M - 1: name that cause
            if (w != Weight::None && noise_var <= 0.0 && wl.dof < (double)f.ny && scale > 0 && std::isfinite(scale))
                throw FitError("'" + f.path + "': the covariance rests on " + std::to_string(std::lround(wl.dof + 1)) +
                               " periods per experiment, too few for " + std::to_string(f.ny) +
                               " outputs (singular at line bin " + std::to_string(l.bin) +
                               "): weighting by the inverse sample covariance needs M >= 4 (Pintelon 2002, Theorem 2) "
                               "and M > " + std::to_string(f.ny) + " for " + std::to_string(f.ny) +
                               " outputs; measure more periods or use --weight none");
            throw FitError("'" + f.path + "': singular weights at line bin " + std::to_string(l.bin) +
                           " (covariance not positive definite)");
        }
        MatC Lm = llt.matrixL();
        const double dmin = Lm.diagonal().real().minCoeff(), dmax = Lm.diagonal().real().maxCoeff();
        if (!(dmin > 1e-8 * dmax))
            throw FitError("'" + f.path + "': singular weights at line bin " + std::to_string(l.bin) +
                           " (covariance condition number above 1e16)");
        wl.Linv = Lm.triangularView<Eigen::Lower>().solve(MatC::Identity(g, g));
        wl.cov = H;
        out.push_back(std::move(wl));
    }
    return out;
}

}  // namespace msidfit
