// Order selection (`msid fit --order auto | a:b | a:step:b`), modal parameters
// in every model file, and `msid modes model.json`. See docs/fitting.md.
#include "cli_util.hpp"
#include "validation_stat.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "frf_data.hpp"
#include "modal_io.hpp"
#include "order_select.hpp"
#include "stats.hpp"

#include <algorithm>
#include <map>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <unistd.h>
#include <fcntl.h>

namespace msidcli {

using namespace msidfit;

bool fit_order_is_scan(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i) {
        std::string a = argv[i], v;
        if (a == "--order" && i + 1 < argc) v = argv[i + 1];
        else if (a.rfind("--order=", 0) == 0) v = a.substr(8);
        else continue;
        return v == "auto" || v.find(':') != std::string::npos;
    }
    return false;
}

void add_modes(Json &doc, bool print)
{
    try {
        const ModalReport r = modal_report(doc);
        doc["modes"] = modal_json(r);
        if (print && !r.modes.empty()) std::fputs(modal_text(r).c_str(), stdout);
    } catch (const std::exception &e) {
        doc["modes"] = Json{{"error", std::string("no modal parameters: ") + e.what()}};
    }
}

// Run `msid fit` with stdout silenced, marked as a fit of the order scan (its not-converged warning,
// which would name the temporary file, is left to the scan); returns its exit status (throws its Error).
static int fit_quiet(std::vector<std::string> args)
{
    std::vector<char *> av;
    for (auto &s : args) av.push_back(&s[0]);
    av.push_back(nullptr);
    std::fflush(stdout);
    const int saved = dup(STDOUT_FILENO), null = open("/dev/null", O_WRONLY);
    dup2(null, STDOUT_FILENO);
    close(null);
    struct Restore {
        int fd;
        ~Restore() { std::fflush(stdout); dup2(fd, STDOUT_FILENO); close(fd); fit_in_order_scan(false); }
    } restore{saved};
    fit_in_order_scan(true);
    return cmd_fit((int)args.size(), av.data());
}

int cmd_fit_scan(int argc, char **argv)
{
    // the options of `msid fit`, with --order and -o/--output taken out
    std::vector<std::string> base;
    std::string range, out, frf, method;
    for (int i = 0; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&](const char *key, std::string &dst) {
            const std::string k = std::string("--") + key;
            if (a == k && i + 1 < argc) { dst = argv[++i]; return true; }
            if (a.rfind(k + "=", 0) == 0) { dst = a.substr(k.size() + 1); return true; }
            return false;
        };
        if (i >= 2 && value("order", range)) continue;
        if (i >= 2 && (a == "-o" && i + 1 < argc)) { out = argv[++i]; continue; }
        if (i >= 2 && value("output", out)) continue;
        if (i >= 2) {
            std::string m;
            const int at = i;
            if (value("method", m)) { method = m; base.push_back("--method"); base.push_back(m); continue; }
            i = at;
        }
        base.push_back(a);
    }
    if (out.empty()) throw UsageError("missing -o <model.json>");
    if (method == "lmfd") throw UsageError("--order auto/a:b needs --method subspace or ml (lmfd interpolates at every order)");
    for (size_t i = 2; i < base.size(); ++i) {
        const std::string v = base[i] == "--start" && i + 1 < base.size() ? base[i + 1]
                              : base[i].rfind("--start=", 0) == 0 ? base[i].substr(8) : "";
        if (!v.empty() && v != "subspace" && v != "sk")
            throw UsageError("--start " + v + " starts one order (the model's): give one --order or leave it out, not " +
                             range);
    }
    // the FRF: the one positional argument (the first argument of base after "msid fit" that names a readable file)
    FrfData f;
    bool found = false;
    for (size_t i = 2; i < base.size() && !found; ++i) {
        if (base[i].rfind("-", 0) == 0) continue;
        try {
            f = read_frf(base[i]);
            found = true;
        } catch (const FitError &) {
        }
    }
    if (!found) throw UsageError("give exactly one readable msid-frf/1 file");
    double neq = 0;
    for (const auto &l : f.lines) neq += (l.real ? 1.0 : 2.0) * (double)f.g();
    const int step = method == "subspace" ? 1 : (int)f.ny;
    // auto's largest order: the largest the method fits on these lines (subspace: the block-row limit;
    // ml in the pole-residue form: fewer parameters n (1 + g) + g than real equations), at least the
    // former neq / (2 (nu + ny)), at most 40. The former bound alone stopped at order 2 on 5 SISO
    // lines, where the 4th-order plant fits (p = 0.9), and the elbow rule chose order 2 at p = 0.
    const double g = (double)f.g(), eq_lines = neq / g;
    int method_cap = 0;
    if (method == "subspace") method_cap = (int)std::floor(eq_lines * f.nu / (double)(f.nu + f.ny)) - 2;
    const bool poles = std::find(base.begin(), base.end(), "lmfd") == base.end() &&
                       !(f.domain == Domain::DT && f.nu > 1 && std::find(base.begin(), base.end(), "ct") == base.end());
    if (method == "ml" && poles) method_cap = (int)std::floor((neq - g - 1.0) / (1.0 + g));
    const int cap = std::min(40, std::max((int)std::floor(neq / (2.0 * (f.nu + f.ny))), method_cap));
    bool is_auto = false;
    std::vector<int> orders;
    try {
        orders = parse_order_range(range, step, cap, &is_auto);
    } catch (const FitError &e) {
        throw UsageError(e.what());
    }
    const size_t stride = lpm_line_stride(f);   // as msid validate: every (2W+1)-th line of an LPM file
    // The stabilisation diagram compares residue matrices by a relative Frobenius norm, which the
    // entries in the largest units dominate: with outputs in 1e-9 and 1e3 the count of stable poles
    // changed (11/12 against 8/12 at the same model). The residues are compared in units where every
    // output's and input's |G| has mean square 1 (a two-way fit of log mean_l |G_l(i, j)|^2, as the
    // subspace normalisation): C and B of the compared model are scaled, nothing written changes.
    Eigen::VectorXd so = Eigen::VectorXd::Ones(f.ny), si = Eigen::VectorXd::Ones(f.nu);
    {
        Eigen::MatrixXd lm = Eigen::MatrixXd::Zero(f.ny, f.nu);
        for (const auto &l : f.lines) lm += l.G.cwiseAbs2();
        bool ok = true;
        for (Eigen::Index i = 0; i < lm.size(); ++i) {
            ok = ok && lm(i) > 0 && std::isfinite(lm(i));
            if (ok) lm(i) = std::log(lm(i) / (double)f.lines.size());
        }
        if (ok) {
            const double grand = lm.mean();
            for (Eigen::Index i = 0; i < (Eigen::Index)f.ny; ++i) so(i) = std::exp(0.5 * lm.row(i).mean());
            for (Eigen::Index j = 0; j < (Eigen::Index)f.nu; ++j) si(j) = std::exp(0.5 * (lm.col(j).mean() - grand));
        }
    }
    std::vector<Json> docs;
    const std::string tmp = out + ".order-scan.tmp";
    std::string usage;   // a usage error of the fit (e.g. --start sk with --param poles) holds at every order
    auto fit_at = [&](int n) {
        if (!usage.empty()) throw FitError(usage);
        std::vector<std::string> args = base;
        args.push_back("--order");
        args.push_back(std::to_string(n));
        args.push_back("-o");
        args.push_back(tmp);
        OrderFit r;
        std::remove(tmp.c_str());
        int rc = 0;
        try {
            rc = fit_quiet(args);
        } catch (const UsageError &e) {
            std::remove(tmp.c_str());
            usage = e.what();
            throw FitError(usage);
        } catch (const Error &e) {
            std::remove(tmp.c_str());
            throw FitError(e.what());
        }
        Json d = read_json(tmp);
        std::remove(tmp.c_str());
        r.ok = true;
        r.converged = rc == 0 && d.value("converged", true);
        // the statistic of msid validate: for an LPM file the cost over every (2W+1)-th line (independent),
        // which `msid fit` writes as cost.independent_lines (validation_stat.hpp); every line otherwise
        const Json &c = stride > 1 ? d["cost"].value("independent_lines", Json()) : d["cost"];
        if (c.is_null()) {   // too few independent lines for this many parameters: no p-value
            r.cost = d["cost"]["value"].get<double>();
            r.expected = d["cost"]["expected"].get<double>();
            r.dof = d["cost"]["dof"].get<double>();
            r.p_value = NAN;
        } else {
            r.cost = c["value"].get<double>();
            r.expected = c["expected"].get<double>();
            r.dof = c["dof"].get<double>();
            r.p_value = c["p_value"].is_number() ? c["p_value"].get<double>() : NAN;
        }
        const Eigen::Index k = d["order"].get<Eigen::Index>(), nu = f.nu, ny = f.ny;
        r.model.domain = d["domain"] == "ct" ? Domain::CT : Domain::DT;
        auto jm = [](const Json &v, Eigen::Index rr, Eigen::Index cc) {
            MatR M(rr, cc);
            for (Eigen::Index i = 0; i < rr; ++i)
                for (Eigen::Index j = 0; j < cc; ++j) M(i, j) = v.at((size_t)i).at((size_t)j).get<double>();
            return M;
        };
        r.model.A = jm(d["A"], k, k);
        r.model.B = jm(d["B"], k, nu) * si.cwiseInverse().asDiagonal();   // unit-free residues (above)
        r.model.C = so.cwiseInverse().asDiagonal() * jm(d["C"], ny, k);
        r.model.D = jm(d["D"], ny, nu);
        if (d.contains("modes") && d["modes"].contains("modes"))
            for (const Json &m : d["modes"]["modes"])
                if (m.contains("identified")) r.not_identified = std::max(r.not_identified, 0) + !m["identified"].get<bool>();
        d["__order"] = n;
        docs.push_back(std::move(d));
        return r;
    };
    OrderSelection sel = select_order(orders, fit_at, f.h, 0.05, StabTol{}, is_auto);
    if (!usage.empty()) throw UsageError(usage);   // one message, exit 2, not one failed row per order
    sel.line_stride = stride;
    if (stride > 1)
        std::printf("LPM file: cost and p-value over every %zu-th line (2W+1 bins apart: independent), as msid validate\n",
                    stride);
    // Every order failed for the same reason (the data's, e.g. too few periods for the weighting): that one
    // message, not one table row per order and the same again below.
    const bool same_failure = !sel.rows.empty() && std::all_of(sel.rows.begin(), sel.rows.end(), [&](const auto &r) {
        return !r.fit.ok && r.fit.error == sel.rows.front().fit.error;
    });
    if (same_failure) throw Error(sel.rows.front().fit.error);
    // "stabilised": poles that repeat from the order below (the diagram's sense, not the model's stability)
    std::printf("order  cost          expected      p-value     stabilised    not identified\n");
    std::map<std::string, int> failed_first;   // error -> the first order that printed it
    for (const auto &r : sel.rows) {
        if (!r.fit.ok) {
            const auto seen = failed_first.emplace(r.fit.error, r.order);
            if (seen.second) std::printf("%-6d failed: %s\n", r.order, r.fit.error.c_str());
            else std::printf("%-6d failed: as order %d\n", r.order, seen.first->second);
            continue;
        }
        const std::string sp = std::to_string(r.n_stable) + "/" + std::to_string(r.poles.size());
        std::printf("%-6d %-13.6g %-13.6g %-11.3g %-13s %-14s%s%s\n", r.order, r.fit.cost, r.fit.expected, r.fit.p_value,
                    sp.c_str(), r.fit.not_identified >= 0 ? std::to_string(r.fit.not_identified).c_str() : "-",
                    r.fit.converged ? "" : "  (not converged)", r.order == sel.chosen ? "  <- chosen" : "");
    }
    if (sel.chosen < 0) throw Error("no order in '" + range + "' gave a model: " + sel.rows.back().fit.error);
    Json doc;
    for (auto &d : docs)
        if (d["__order"] == sel.chosen) doc = std::move(d);
    doc.erase("__order");
    doc["order_selection"] = order_selection_json(sel);
    const bool conv = doc.value("converged", true);
    write_json_file(out, doc);
    std::printf("chosen order %d (%s rule); wrote %s\n", sel.chosen, sel.rule.c_str(), out.c_str());
    ModalReport mr = modal_report(doc);
    if (!mr.modes.empty()) std::fputs(modal_text(mr).c_str(), stdout);
    if (!conv) {   // as a fit at a fixed order: the best iterate is written, exit status 3
        std::fprintf(stderr, "msid fit: warning: the chosen order %d did not converge (cost %.6g, gradient norm %.3g): "
                             "wrote its best iterate to %s marked \"converged\": false (exit status 3)\n",
                     sel.chosen, doc["cost"].value("fit_cost_smoothed_weights", doc["cost"]["value"].get<double>()),
                     doc.value("gradient_norm", 0.0), out.c_str());
        return 3;
    }
    return 0;
}

int cmd_modes(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid modes model.json [-o modes.json]\n"
        "Natural frequencies, damping ratios and residues of every pole pair of an msid-model/1 file,\n"
        "with standard deviations from its parameter covariance (delta method; ml and unique lmfd\n"
        "models). DT poles are mapped to CT by ln(z)/h.\n";
    Args a(argc, argv, 2, HELP, {"output"}, {});
    if (a.positional().size() != 1) throw UsageError("give one msid-model/1 file");
    try {
        const Json j = read_json(a.positional()[0]);
        if (!j.is_object() || j.value("format", "") != "msid-model/1")
            throw FitError("'" + a.positional()[0] + "': not an msid-model/1 file");
        if (j.value("method", "") == "multi")   // poles shared by records, no FRF residues (cmd_fit_multi.cpp)
            return cmd_modes_multi(j, a.positional()[0], a.has("output") ? a.get("output") : std::string());
        const ModalReport r = modal_report(j);
        std::fputs(modal_text(r).c_str(), stdout);
        if (a.has("output")) {
            Json o = modal_json(r);
            o["format"] = "msid-modes/1";
            o["model"] = a.positional()[0];
            write_json_file(a.get("output"), o);
        }
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    } catch (const Json::exception &e) {
        throw Error("'" + a.positional()[0] + "': malformed model file (" + e.what() + ")");
    }
}

}  // namespace msidcli
