#include "modal_io.hpp"
#include "poleres.hpp"

#include "model_io.hpp"
#include "text_scan.hpp"

#include <cmath>
#include <cstdio>

namespace msidfit {

static MatR jmat(const Json &v, Eigen::Index rows, Eigen::Index cols)
{
    MatR M(rows, cols);
    for (Eigen::Index r = 0; r < rows; ++r)
        for (Eigen::Index c = 0; c < cols; ++c) M(r, c) = v.at((size_t)r).at((size_t)c).get<double>();
    return M;
}

// Entry of an LMFD coefficient named like "D1[2,1]" or "N0[1,1]" (1-based).
struct Slot {
    char mat;
    int index, row, col;
};

static Slot slot_of(const std::string &name)
{
    // ^([DN])(\d+)\[(\d+),(\d+)\]$
    size_t i = 0;
    const char mat = name.empty() ? '\0' : name[0];
    std::string index, row, col;
    bool ok = (mat == 'D' || mat == 'N') && scan_char(name, i, mat);
    if (ok) index = scan_digits(name, i);
    ok = ok && !index.empty() && scan_char(name, i, '[');
    if (ok) row = scan_digits(name, i);
    ok = ok && !row.empty() && scan_char(name, i, ',');
    if (ok) col = scan_digits(name, i);
    ok = ok && !col.empty() && scan_char(name, i, ']') && i == name.size();
    // more digits than an int holds (std::stoi would throw out_of_range): no coefficient either
    ok = ok && index.size() <= 9 && row.size() <= 9 && col.size() <= 9;
    if (!ok) throw FitError("parameter name '" + name + "' is not an LMFD coefficient");
    return {mat, std::stoi(index), std::stoi(row) - 1, std::stoi(col) - 1};
}

// The fitted lines of a model file ("frf": bin, freq, omega per line) in the model's variable.
static std::vector<cd> fitted_points(const Json &j, Domain d)
{
    std::vector<cd> xs;
    if (!j.contains("frf") || !j["frf"].is_array()) return xs;
    for (const Json &l : j["frf"]) {
        if (!l.is_object() || !l.contains("freq") || !l.contains("omega")) return {};
        Line ln;
        ln.freq = l["freq"].get<double>();
        ln.omega = l["omega"].get<double>();
        xs.push_back(line_point(ln, d));
    }
    return xs;
}

// The modes whose pole the fit held on the stability bound (pole_residue.poles[k].at_bound): marked, and
// no standard deviation of the damping (the constraint fixed it; the delta method would report the
// spread of an estimate there is none of).
static void mark_at_bound(const Json &poles, std::vector<Mode> &modes)
{
    for (const Json &p : poles) {
        if (!p.is_object() || !p.value("at_bound", false) || modes.empty()) continue;
        const cd z(p.at("re").get<double>(), p.at("im").get<double>());
        Mode *best = nullptr;
        double d = 1e300;
        for (Mode &m : modes) {
            const double dm = std::abs(m.pole - z);
            if (dm < d) { d = dm; best = &m; }
        }
        best->at_bound = true;
        best->sd_zeta = NAN;
    }
}

ModalReport modal_report(const Json &j)
{
    ModalReport r;
    r.domain = j.at("domain") == "ct" ? Domain::CT : Domain::DT;
    r.h = j.contains("sample_time") && j["sample_time"].is_number() ? j["sample_time"].get<double>() : 0.0;
    const Eigen::Index n = j.at("order").get<Eigen::Index>(), nu = j.at("n_inputs").get<Eigen::Index>(),
                       ny = j.at("n_outputs").get<Eigen::Index>();
    SSModel ss;
    ss.domain = r.domain;
    ss.h = r.h;
    ss.A = jmat(j.at("A"), n, n);
    ss.B = jmat(j.at("B"), n, nu);
    ss.C = jmat(j.at("C"), ny, n);
    ss.D = jmat(j.at("D"), ny, nu);
    const bool lm = j.contains("lmfd") && j["lmfd"].is_object() && n > 0;
    const bool pars = j.contains("parameters") && j["parameters"].is_object() && j["parameters"].contains("cov");
    const bool prf = j.contains("pole_residue") && j["pole_residue"].is_object() && n > 0;
    if (prf && pars && nu == 1) {
        // ml in pole-residue form: the delta method through the same finite
        // differences, on the realisation of the parameters (p_k, R_k, D) as pr_to_ss builds it
        const Json &p = j["parameters"];
        std::vector<std::string> names;
        for (const auto &nm : p.at("names")) names.push_back(nm.get<std::string>());
        const Eigen::Index np = (Eigen::Index)names.size();
        VecR th(np);
        for (Eigen::Index i = 0; i < np; ++i) th(i) = p.at("values").at((size_t)i).get<double>();
        const MatR cov = jmat(p.at("cov"), np, np);
        std::vector<int> pair;   // per pole: 1 = complex pair (p.re, p.im), 0 = real
        bool hasD = false;
        for (const auto &nm : names) {
            if (nm[0] == 'p' && nm.find(".im") == std::string::npos) pair.push_back(nm.find(".re") != std::string::npos);
            if (nm[0] == 'D') hasD = true;
        }
        const Eigen::Index g = ny * nu;
        auto realise = [&, pair, hasD, g](const VecR &t) {
            PoleResidueModel m;
            m.domain = r.domain;
            m.h = r.h;
            Eigen::Index i = 0;
            for (int pk : pair) {
                m.poles.push_back(pk ? cd(t(i), t(i + 1)) : cd(t(i), 0.0));
                i += pk ? 2 : 1;
            }
            for (int pk : pair) {
                MatC R = MatC::Zero(ny, nu);
                for (int part = 0; part < (pk ? 2 : 1); ++part)
                    for (Eigen::Index ij = 0; ij < g; ++ij) R.data()[ij] += part ? cd(0.0, t(i++)) : cd(t(i++), 0.0);
                m.R.push_back(R);
            }
            m.feedthrough = hasD;
            m.D = hasD ? MatR(Eigen::Map<const MatR>(t.data() + i, ny, nu)) : MatR::Zero(ny, nu);
            return pr_to_ss(m);
        };
        r.modes = modes_with_sd(realise, th, cov, r.h, 1.0, fitted_points(j, r.domain));
        mark_at_bound(j["pole_residue"]["poles"], r.modes);
        r.have_sd = true;
        r.sd_source = "delta method from the parameter covariance (inverse Fisher information) of the pole-residue form";
        return r;
    }
    if (!lm || !pars) {
        r.modes = modes_of(ss, r.h);
        r.sd_source = n == 0 ? "none: the model has no poles"
                      : prf && pars ? "none: pole-residue models with several inputs (each pole repeated per input in the "
                                      "realisation); refit with --param lmfd for standard deviations"
                      : j.value("method", "") == "subspace"
                          ? "none: subspace gives no parameter covariance (refit with --method ml for standard deviations)"
                          : "none: the model file holds no parameter covariance";
        return r;
    }
    const Json &l = j["lmfd"];
    LmfdModel base;
    base.domain = r.domain;
    base.h = r.h;
    base.nD = l.at("nD").get<int>();
    base.nN = l.at("nN").get<int>();
    for (int i = 0; i < base.nD; ++i) base.Dm.push_back(jmat(l.at("D").at((size_t)i), ny, ny));
    for (int i = 0; i <= base.nN; ++i) base.Nm.push_back(jmat(l.at("N").at((size_t)i), ny, nu));
    const Json &p = j["parameters"];
    std::vector<Slot> slots;
    for (const auto &nm : p.at("names")) slots.push_back(slot_of(nm.get<std::string>()));
    const Eigen::Index np = (Eigen::Index)slots.size();
    VecR th(np);
    for (Eigen::Index i = 0; i < np; ++i) th(i) = p.at("values").at((size_t)i).get<double>();
    const MatR cov = jmat(p.at("cov"), np, np);
    double ws = 1.0;
    lmfd_realise_scaled(base, &ws);   // one frequency scale for every perturbation
    auto realise = [&](const VecR &t) {
        LmfdModel m = base;
        for (Eigen::Index i = 0; i < np; ++i) {
            const Slot &s = slots[(size_t)i];
            (s.mat == 'D' ? m.Dm[(size_t)s.index - 1] : m.Nm[(size_t)s.index])(s.row, s.col) = t(i);
        }
        if (r.domain == Domain::CT) {
            for (int i = 1; i <= m.nD; ++i) m.Dm[(size_t)i - 1] *= std::pow(ws, i);
            for (int i = 0; i <= m.nN; ++i) m.Nm[(size_t)i] *= std::pow(ws, i);
        }
        return lmfd_to_ss(m);
    };
    r.modes = modes_with_sd(realise, th, cov, r.h, ws, fitted_points(j, r.domain));
    r.have_sd = true;
    r.sd_source = "delta method from the parameter covariance (inverse Fisher information) of the LMFD";
    return r;
}

Json modal_json(const ModalReport &r)
{
    Json o;
    const bool hz = r.domain == Domain::CT || r.h > 0;
    o["frequency_unit"] = hz ? "Hz" : "cycles/sample";
    o["residue_variable"] = r.domain == Domain::CT ? "s" : "z";
    o["sd_source"] = r.sd_source;
    o["tolerance_note"] = "first-order (delta method) standard deviations; valid while they are small against the "
                          "distance between poles";
    Json a = Json::array();
    for (const Mode &m : r.modes) {
        Json e;
        e["pole"] = {m.pole.real(), m.pole.imag()};
        e["pole_ct"] = {m.pole_ct.real(), m.pole_ct.imag()};
        e["real_pole"] = m.real;
        e["fn"] = m.fn;
        e["wn"] = m.wn;
        e["zeta"] = m.zeta;
        e["residue"] = cmat_json(m.residue);
        e["at_bound"] = m.at_bound;
        if (r.have_sd) {
            e["sd_fn"] = m.sd_fn;
            e["sd_wn"] = m.sd_wn;
            e["sd_zeta"] = m.at_bound ? Json(nullptr) : Json(m.sd_zeta);
            e["sd_residue"] = {{"re", rmat_json(m.sd_residue_re)}, {"im", rmat_json(m.sd_residue_im)}};
            if (std::isfinite(m.contrib_p)) {
                e["contribution_test"] = {{"chi2", m.contrib_chi2}, {"dof", m.contrib_dof}, {"p_value", m.contrib_p}};
                if (m.contrib_with >= 0) e["contribution_test"]["with_mode"] = m.contrib_with + 1;
                e["identified"] = m.contrib_p < MODE_IDENTIFIED_P;
            }
        } else {
            e["sd_fn"] = nullptr;
            e["sd_wn"] = nullptr;
            e["sd_zeta"] = nullptr;
            e["sd_residue"] = nullptr;
        }
        a.push_back(e);
    }
    o["modes"] = a;
    return o;
}

static std::string fmt_with(int other)
{
    return ", with mode " + std::to_string(other + 1);
}

std::string modal_text(const ModalReport &r)
{
    const bool hz = r.domain == Domain::CT || r.h > 0;
    std::string s;
    char buf[256];
    std::snprintf(buf, sizeof buf, "%-4s %-14s %-12s %-12s %-12s %s\n", "mode", hz ? "fn [Hz]" : "fn [cyc/smp]", "sd(fn)",
                  "zeta [%]", "sd(zeta)[%]", "|residue| (largest entry)");
    s += buf;
    int k = 1, weak = 0, held = 0;
    for (const Mode &m : r.modes) {
        Eigen::Index i, jj;
        const double rmax = m.residue.cwiseAbs().maxCoeff(&i, &jj);
        std::string note = m.real ? "  (real pole)" : "";
        if (m.at_bound) {
            ++held;
            note += "  ON THE STABILITY BOUND";
        }
        if (m.contrib_p >= MODE_IDENTIFIED_P) {   // NaN (no test): no note
            ++weak;
            char t[96];
            std::snprintf(t, sizeof t, "  NOT identified (p = %.2g%s)", m.contrib_p,
                          m.contrib_with >= 0 ? fmt_with(m.contrib_with).c_str() : "");
            note += t;
        }
        if (r.have_sd && (m.real || m.at_bound))   // a real pole's damping ratio is +-1 by definition; at the bound the constraint's: no sd
            std::snprintf(buf, sizeof buf, "%-4d %-14.6g %-12.3g %-12.4g %-12s %.4g%s\n", k++, m.fn, m.sd_fn,
                          100 * m.zeta, "-", rmax, note.c_str());
        else if (r.have_sd)
            std::snprintf(buf, sizeof buf, "%-4d %-14.6g %-12.3g %-12.4g %-12.3g %.4g%s\n", k++, m.fn, m.sd_fn,
                          100 * m.zeta, 100 * m.sd_zeta, rmax, note.c_str());
        else
            std::snprintf(buf, sizeof buf, "%-4d %-14.6g %-12s %-12.4g %-12s %.4g%s\n", k++, m.fn, "-", 100 * m.zeta, "-",
                          rmax, m.real ? "  (real pole)" : "");
        s += buf;
    }
    s += "standard deviations: " + r.sd_source + "\n";
    if (held > 0)
        s += "ON THE STABILITY BOUND: the data push " + std::string(held == 1 ? "this pole" : "these poles") +
             " out of the stable region and the constrained fit holds " + (held == 1 ? "it" : "them") +
             " on its edge: the damping is the constraint's (no sd), not a damping the data give; model error "
             "(nonlinear distortion, an order above what the data identify) or an unstable plant (--allow-unstable)\n";
    if (weak > 0)
        s += "NOT identified: the mode's contribution to the FRF at the fitted lines is within the noise (Wald test, "
             "p >= " + std::string(weak == 1 ? "0.001): a pole pair spent on noise" : "0.001): pole pairs spent on noise") +
             "; the order is larger than the data support (--order auto picks the order the data identify)\n";
    return s;
}

}  // namespace msidfit
