// msid-model/1: the blocks every fitting method writes its model document from (model_io.hpp).
#include "modal_io.hpp"
#include "model_io.hpp"
#include "stats.hpp"

extern "C" {
#include "msid/msid.h"   // MSID_VERSION
}

#include <algorithm>
#include <cmath>

namespace msidfit {

Json rmat_json(const MatR &M)
{
    Json a = Json::array();
    for (Eigen::Index r = 0; r < M.rows(); ++r) {
        Json row = Json::array();
        for (Eigen::Index c = 0; c < M.cols(); ++c) row.push_back(M(r, c));
        a.push_back(row);
    }
    return a;
}

Json cmat_json(const MatC &M) { return Json{{"re", rmat_json(M.real())}, {"im", rmat_json(M.imag())}}; }

Json model_head(const Json &source, Domain d, double h, const std::string &method, const Json &experiments)
{
    Json doc;
    doc["format"] = "msid-model/1";
    doc["generator"] = std::string("msid ") + MSID_VERSION;
    doc["source"] = source;
    if (!experiments.is_null()) doc["experiments"] = experiments;
    doc["domain"] = d == Domain::CT ? "ct" : "dt";
    if (h > 0) doc["sample_time"] = h;
    doc["method"] = method;
    return doc;
}

void model_put_ss(Json &doc, const SSModel &ss, int order, size_t nu, size_t ny, const Json &settings)
{
    doc["order"] = order;
    doc["n_inputs"] = nu;
    doc["n_outputs"] = ny;
    doc["settings"] = settings;
    doc["A"] = rmat_json(ss.A);
    doc["B"] = rmat_json(ss.B);
    doc["C"] = rmat_json(ss.C);
    doc["D"] = rmat_json(ss.D);
    doc["stable"] = ss_stable(ss);
}

void model_put_signals(Json &doc, const std::vector<std::string> &input_names,
                       const std::vector<std::string> &output_names, const std::vector<std::string> &input_units,
                       const std::vector<std::string> &output_units)
{
    if (!input_names.empty()) doc["input_names"] = input_names;
    if (!output_names.empty()) doc["output_names"] = output_names;
    if (!input_units.empty()) doc["input_units"] = input_units;
    if (!output_units.empty()) doc["output_units"] = output_units;
}

Json model_stability(const SSModel &ss, bool enforced, const VecC &poles)
{
    Json j;
    j["stable"] = ss_stable(ss);
    j["enforced"] = enforced;
    const char *key = ss.domain == Domain::CT ? "max_real_pole" : "max_abs_pole";
    if (poles.size() == 0) {
        j[key] = nullptr;
        return j;
    }
    double worst = ss.domain == Domain::CT ? -1e300 : 0.0;
    for (Eigen::Index k = 0; k < poles.size(); ++k)
        worst = ss.domain == Domain::CT ? std::max(worst, poles(k).real()) : std::max(worst, std::abs(poles(k)));
    j[key] = worst;
    return j;
}

Json model_params(const std::vector<std::string> &names, const VecR &theta, const MatR &cov, int rank,
                  const double *cov_factor)
{
    Json p;
    p["names"] = names;
    p["values"] = std::vector<double>(theta.data(), theta.data() + theta.size());
    p["cov"] = rmat_json(cov);
    if (cov_factor) p["cov_factor"] = *cov_factor;
    p["cov_rank"] = rank;
    return p;
}

Json model_lmfd(const LmfdModel &m)
{
    Json l;
    l["nD"] = m.nD;
    l["nN"] = m.nN;
    l["variable"] = m.domain == Domain::CT ? "s" : "z^-1";
    Json D = Json::array(), N = Json::array();
    for (const auto &x : m.Dm) D.push_back(rmat_json(x));
    for (const auto &x : m.Nm) N.push_back(rmat_json(x));
    l["D"] = D;
    l["N"] = N;
    return l;
}

Json model_cost(double V, double dof, double nmin, double ny)
{
    const CostLaw law = cost_law(dof, nmin, ny);
    Json c;
    c["value"] = V;
    c["expected"] = law.mean;
    c["dof"] = dof;
    const double pv = cost_pvalue(law, V);
    if (std::isfinite(pv)) c["p_value"] = pv; else c["p_value"] = nullptr;
    return c;
}

Json model_frf_line(uint32_t bin, double freq, double omega, const MatC &G, const MatC *cov)
{
    Json e;
    e["bin"] = bin;
    e["freq"] = freq;
    e["omega"] = omega;
    e["G"] = cmat_json(G);
    if (cov) e["cov"] = cmat_json(*cov); else e["cov"] = nullptr;
    return e;
}

void model_put_modes(Json &doc, std::string *text)
{
    try {
        const ModalReport r = modal_report(doc);
        doc["modes"] = modal_json(r);
        if (text && !r.modes.empty()) *text = modal_text(r);
    } catch (const std::exception &e) {
        doc["modes"] = Json{{"error", std::string("no modal parameters: ") + e.what()}};
    }
}

}  // namespace msidfit
