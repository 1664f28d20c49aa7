#include "model_io.hpp"
#include "json_util.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

namespace msidfit {

static MatR rmat(const Json &v, Eigen::Index rows, Eigen::Index cols, const std::string &file, const std::string &what)
{
    if (!v.is_array() || (Eigen::Index)v.size() != rows)
        throw FitError("'" + file + "': " + what + " must have " + std::to_string(rows) + " rows");
    MatR M(rows, cols);
    for (Eigen::Index r = 0; r < rows; ++r) {
        if (!v[(size_t)r].is_array() || (Eigen::Index)v[(size_t)r].size() != cols)
            throw FitError("'" + file + "': " + what + " must have " + std::to_string(cols) + " columns");
        for (Eigen::Index c = 0; c < cols; ++c) {
            const Json &x = v[(size_t)r][(size_t)c];
            if (!x.is_number() || !std::isfinite(x.get<double>()))
                throw FitError("'" + file + "': " + what + " holds a non-finite or non-numeric entry");
            M(r, c) = x.get<double>();
        }
    }
    return M;
}

static int64_t ival(const Json &o, const char *k, const std::string &file)
{
    if (!o.contains(k) || !o[k].is_number_integer() || o[k].get<int64_t>() < 0)
        throw FitError("'" + file + "': '" + k + "' must be a non-negative integer");
    return o[k].get<int64_t>();
}

ModelFile read_model(const std::string &path)
{
    return parse_model(read_json(path), path);
}

ModelFile parse_model(const Json &j, const std::string &path)
{
    if (!j.is_object() || !j.contains("format") || j["format"] != "msid-model/1")
        throw FitError("'" + path + "': format is " + (j.is_object() && j.contains("format") ? j["format"].dump() : "missing") +
                       ", expected \"msid-model/1\"");
    ModelFile m;
    m.path = path;
    if (!j.contains("domain") || (j["domain"] != "dt" && j["domain"] != "ct"))
        throw FitError("'" + path + "': 'domain' must be \"dt\" or \"ct\"");
    m.domain = j["domain"] == "ct" ? Domain::CT : Domain::DT;
    if (j.contains("sample_time") && j["sample_time"].is_number()) m.h = j["sample_time"].get<double>();
    const int64_t n = ival(j, "order", path), nu = ival(j, "n_inputs", path), ny = ival(j, "n_outputs", path);
    // n_inputs 0: a free-response model (msid fit --method multi on ring-downs): B and D have no columns
    if (nu < 0 || ny < 1 || nu > 16 || ny > 16 || n > 400) throw FitError("'" + path + "': dimensions out of range");
    m.ss.domain = m.domain;
    m.ss.h = m.h;
    for (const char *k : {"A", "B", "C", "D"})
        if (!j.contains(k)) throw FitError("'" + path + "': missing '" + k + "'");
    m.ss.A = rmat(j["A"], n, n, path, "A");
    m.ss.B = rmat(j["B"], n, nu, path, "B");
    m.ss.C = rmat(j["C"], ny, n, path, "C");
    m.ss.D = rmat(j["D"], ny, nu, path, "D");
    m.method = j.contains("method") && j["method"].is_string() ? j["method"].get<std::string>() : "";
    if (j.contains("settings") && j["settings"].contains("weight") && j["settings"]["weight"].is_string())
        m.weight = j["settings"]["weight"].get<std::string>();
    if (j.contains("n_params") && j["n_params"].is_number_integer()) m.n_params = j["n_params"].get<int>();
    if (j.contains("lmfd") && j["lmfd"].is_object()) {
        const Json &l = j["lmfd"];
        LmfdModel L;
        L.domain = m.domain;
        L.h = m.h;
        const int64_t nD = ival(l, "nD", path), nN = ival(l, "nN", path);
        if (nD > 400 || nN > 400) throw FitError("'" + path + "': lmfd.nD and lmfd.nN must be at most 400");
        L.nD = (int)nD;   // range-checked before the cast (a crafted 2^32 - 1 was a crash)
        L.nN = (int)nN;
        if (!l.contains("D") || !l["D"].is_array() || (int)l["D"].size() != L.nD || !l.contains("N") ||
            !l["N"].is_array() || (int)l["N"].size() != L.nN + 1)
            throw FitError("'" + path + "': lmfd.D needs nD and lmfd.N nN+1 matrices");
        for (int i = 0; i < L.nD; ++i) L.Dm.push_back(rmat(l["D"][(size_t)i], ny, ny, path, "lmfd.D"));
        for (int i = 0; i <= L.nN; ++i) L.Nm.push_back(rmat(l["N"][(size_t)i], ny, nu, path, "lmfd.N"));
        m.lmfd = L;
    }
    if (j.contains("pole_residue") && j["pole_residue"].is_object() && j["pole_residue"].contains("poles")) {
        const Json &pl = j["pole_residue"]["poles"];
        if (!pl.is_array() || (int64_t)pl.size() > n) throw FitError("'" + path + "': pole_residue.poles must be a list of at most 'order' poles");
        for (const Json &p : pl) {
            const std::string at = "'" + path + "': pole_residue.poles[" + std::to_string(m.poles.size()) + "]";
            if (!p.is_object() || !p.contains("re") || !p.contains("im") || !p["re"].is_number() || !p["im"].is_number())
                throw FitError(at + " needs numbers 're' and 'im'");
            const cd z(p["re"].get<double>(), p["im"].get<double>());
            if (!std::isfinite(z.real()) || !std::isfinite(z.imag())) throw FitError(at + " is not finite");
            if (z.imag() < 0) throw FitError(at + " has Im < 0: list each complex pair once, by its Im > 0 member");
            m.poles.push_back(z);
        }
    }
    return m;
}

}  // namespace msidfit
