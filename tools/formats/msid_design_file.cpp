#include "msid_design_file.hpp"
#include "msid_fftw_planner.hpp"

#include "msid/msid_fft_fftw.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace msidfmt {


static std::string line_name(const DesignParams &p, int32_t l)
{
    if (l < 0) return "?";
    if (!p.omega.empty()) return fmt("%d (omega = %.10g rad/s)", l + 1, p.omega[(size_t)l]);
    return fmt("%u", p.bins[(size_t)l]);
}

std::unique_ptr<Design> build_design(const DesignParams &p)
{
    auto D = std::make_unique<Design>();
    D->params = p;
    const bool ct = !p.omega.empty();
    const size_t L = ct ? p.omega.size() : p.bins.size();
    if (p.period < MSID_MIN_PERIOD || p.period > MSID_MAX_PERIOD)
        throw Error(fmt("period %u is outside [%u, %u] samples", p.period, MSID_MIN_PERIOD, MSID_MAX_PERIOD));
    if (L == 0) throw Error("no lines given");
    if (ct && !(p.sample_time > 0.0 && std::isfinite(p.sample_time)))
        throw Error("a continuous-time design needs a finite, positive " MSID_OPT("sample_time"));
    if (!p.amplitudes.empty() && p.amplitudes.size() != L && p.amplitudes.size() != (size_t)p.n_inputs * L)
        throw Error(fmt("%zu amplitudes for %zu lines: give 1, %zu or %zu values", p.amplitudes.size(), L, L,
                        (size_t)p.n_inputs * L));
    if (p.n_inputs == 0 || p.n_inputs > MSID_MAX_INPUTS)
        throw Error(fmt("%u inputs: must be 1..%u", p.n_inputs, MSID_MAX_INPUTS));
    if (p.n_experiments < p.n_inputs)
        throw Error(fmt("%u experiments for %u inputs: need at least as many experiments as inputs", p.n_experiments,
                        p.n_inputs));
    if (p.n_experiments > MSID_MAX_EXPERIMENTS)
        throw Error(fmt("%u experiments: at most %u are supported", p.n_experiments, MSID_MAX_EXPERIMENTS));

    size_t n = msid_twiddle_mem_size(p.period);
    D->mem_tw = Mem(n);
    check(msid_twiddle_init(&D->tw, p.period, D->mem_tw.p, n), "twiddle table");

    msid_design_cfg c{};
    c.period = p.period;
    c.n_lines = (uint32_t)L;
    c.bins = ct ? nullptr : p.bins.data();
    c.omega = ct ? p.omega.data() : nullptr;
    c.sample_time = p.sample_time;
    c.amplitudes = p.amplitudes.empty() ? nullptr : p.amplitudes.data();
    c.amp_per_input = p.amplitudes.size() == (size_t)p.n_inputs * L && p.n_inputs > 1 ? 1 : 0;
    c.phase_mode = p.phase_mode;
    c.phases = p.phases.empty() ? nullptr : p.phases.data();
    c.seed = p.seed;
    c.n_inputs = p.n_inputs;
    c.n_experiments = p.n_experiments;
    c.pattern = p.pattern;
    c.twiddle = &D->tw;
    // Crest factors by two real DFTs per input (O(m nu P log P)), not direct synthesis (O(m nu P L): 26 s
    // for P = 2^20 with 1000 lines). The plan lives only for the init.
    struct Plan {
        msid_fft_fftw f{};
        bool on = false;
        ~Plan() { if (on) msid_fft_fftw_destroy(&f); }   // after fftw_planner_ready() below
    } plan;
    msidutil::fftw_planner_ready();
    check(msid_fft_fftw_create(&plan.f, p.period, MSID_FFTW_ESTIMATE), "FFTW plan");
    plan.on = true;
    c.crest = MSID_CREST_FFT;
    c.fft = &plan.f.be;
    if (p.phase_mode == MSID_PHASE_USER && p.phases.size() != (size_t)p.n_inputs * L)
        throw Error(fmt("%zu phases for %u inputs x %zu lines", p.phases.size(), p.n_inputs, L));
    n = msid_design_mem_size(&c);
    if (n == 0) throw Error(fmt("design dimensions out of range (%zu lines, period %u)", L, p.period));
    D->mem_d = Mem(n);
    msid_status st = msid_design_init(&D->d, &c, D->mem_d.p, n);
    if (st != MSID_OK) {
        const msid_design_diag_t g = msid_design_diag(&D->d);
        switch (st) {
        case MSID_E_LINE_RANGE:
            throw Error(fmt("line %s is at or beyond Nyquist: bins must be below P/2 = %g", line_name(p, g.line_a).c_str(),
                            p.period / 2.0));
        case MSID_E_LINE_DUP:
            if (g.line_a < 0) throw Error(fmt("%zu lines cannot fit below Nyquist of a %u-sample period", L, p.period));
            throw Error(fmt("line %s is given twice (positions %d and %d)", line_name(p, g.line_b).c_str(),
                            g.line_a + 1, g.line_b + 1));
        case MSID_E_AMPLITUDE:
            throw Error(fmt("amplitude of line %s is not finite and in [%g, %g] (the range whose squares double "
                            "precision holds)",
                            line_name(p, g.line_a).c_str(), MSID_MIN_AMPLITUDE, MSID_MAX_AMPLITUDE));
        case MSID_E_PHASE:
            throw Error(fmt("phase of line %s is not finite", line_name(p, g.line_a).c_str()));
        case MSID_E_CT_NOT_PERIODIC: {
            const double w = p.omega[(size_t)g.line_a];
            throw Error(fmt("line %s does not complete a whole number of cycles in P*h = %.10g s (%.9g cycles): "
                            "choose the period and sample time so that omega*P*h/(2 pi) is an integer",
                            line_name(p, g.line_a).c_str(), p.period * p.sample_time,
                            w * p.period * p.sample_time / (2 * M_PI)));
        }
        case MSID_E_ALIAS_COLLISION:
            throw Error(fmt("lines %s and %s both fold onto bin %lld at h = %.10g s: this violates Assumption 2 "
                            "(lines must stay distinct after sampling); change h or the lines",
                            line_name(p, g.line_a).c_str(), line_name(p, g.line_b).c_str(), (long long)g.bin,
                            p.sample_time));
        case MSID_E_ALIAS_EDGE:
            throw Error(fmt("line %s folds onto %s (bin %lld) at h = %.10g s: this violates Assumption 2; "
                            "change h or the line",
                            line_name(p, g.line_a).c_str(), g.bin == 0 ? "DC" : "Nyquist", (long long)g.bin,
                            p.sample_time));
        case MSID_E_ARG:
            if (g.line_a >= 0)
                throw Error(fmt("line %s: frequencies must be finite and >= 0", line_name(p, g.line_a).c_str()));
            check(st, "design");
            break;
        case MSID_E_SINGULAR:
            throw Error(fmt("the %u x %u input matrix is singular at line %s", p.n_inputs, p.n_experiments,
                            line_name(p, g.line_a).c_str()));
        case MSID_E_PATTERN:
            throw Error(fmt("the Hadamard pattern needs a power-of-2 number of experiments (got %u); use " MSID_OPT("pattern") " dft",
                            p.n_experiments));
        default:
            check(st, "design");
        }
    }
    return D;
}

static const char *phase_name(msid_phase_mode m)
{
    return m == MSID_PHASE_RANDOM ? "random" : m == MSID_PHASE_SCHROEDER ? "schroeder" : "user";
}

Json design_to_json(const Design &D)
{
    const msid_design &d = D.d;
    const uint32_t L = d.n_lines, nu = d.n_inputs, m = d.n_experiments;
    Json j;
    j["format"] = "msid-design/1";
    j["generator"] = std::string("msid ") + MSID_VERSION;
    j["period_samples"] = d.period;
    j["n_inputs"] = nu;
    j["n_experiments"] = m;
    j["domain"] = d.is_ct ? "ct" : "dt";
    if (d.is_ct) j["sample_time"] = d.sample_time;
    j["phase_mode"] = phase_name(D.params.phase_mode);
    j["seed"] = D.params.seed;
    j["pattern"] = d.pattern == MSID_PATTERN_HADAMARD ? "hadamard" : "dft";
    if (D.params.periods) j["periods"] = D.params.periods;
    Json lines = Json::array();
    for (uint32_t l = 0; l < L; ++l) {
        Json e;
        e["bin"] = d.bins[l];
        e["freq"] = (double)d.bins[l] / d.period;
        if (d.is_ct) {
            e["omega"] = d.omega[l];
            e["folded"] = d.folded[l] != 0;
        }
        Json a = Json::array(), ph = Json::array();
        for (uint32_t i = 0; i < nu; ++i) {
            a.push_back(d.amp[(size_t)i * L + l]);
            ph.push_back(d.phase[(size_t)i * L + l]);
        }
        e["amplitude"] = a;
        e["phase_turns"] = ph;
        e["cond"] = d.cond[l];
        lines.push_back(e);
    }
    j["lines"] = lines;
    Json cf = Json::array();
    for (uint32_t e = 0; e < m; ++e) {
        Json row = Json::array();
        for (uint32_t i = 0; i < nu; ++i) row.push_back(msid_design_crest_factor(&d, e, i));
        cf.push_back(row);
    }
    j["crest_factor"] = cf;
    j["cond_max"] = d.cond_max;
    return j;
}

std::unique_ptr<Design> read_design_file(const std::string &path)
{
    const Json j = read_json_file(path);
    const Json &fmtv = jget(j, "format", path);
    if (!fmtv.is_string() || fmtv.get<std::string>() != "msid-design/1")
        throw Error("'" + path + "': format is " + fmtv.dump() + ", expected \"msid-design/1\"");
    DesignParams p;
    p.period = juint32(j, "period_samples", path);
    p.n_inputs = juint32(j, "n_inputs", path);
    p.n_experiments = juint32(j, "n_experiments", path);
    const Json &dom = jget(j, "domain", path);
    if (dom != "dt" && dom != "ct") throw Error("'" + path + "': 'domain' must be \"dt\" or \"ct\"");
    const bool ct = dom == "ct";
    if (ct) p.sample_time = jnum(jget(j, "sample_time", path), "'sample_time'", path);
    const Json &pat = jget(j, "pattern", path);
    if (pat == "dft") p.pattern = MSID_PATTERN_DFT;
    else if (pat == "hadamard") p.pattern = MSID_PATTERN_HADAMARD;
    else throw Error("'" + path + "': 'pattern' must be \"dft\" or \"hadamard\"");
    p.seed = juint(j, "seed", path);
    if (j.contains("periods")) p.periods = juint32(j, "periods", path);
    const Json &lines = jget(j, "lines", path);
    if (!lines.is_array() || lines.empty()) throw Error("'" + path + "': 'lines' must be a non-empty array");
    const size_t L = lines.size(), nu = p.n_inputs;
    if (nu == 0 || nu > MSID_MAX_INPUTS) throw Error("'" + path + "': 'n_inputs' out of range");
    p.amplitudes.assign(nu * L, 0.0);
    p.phases.assign(nu * L, 0.0);
    p.phase_mode = MSID_PHASE_USER;
    p.amp_per_input = true;
    for (size_t l = 0; l < L; ++l) {
        const Json &e = lines[l];
        const std::string where = fmt("lines[%zu]", l);
        if (ct) p.omega.push_back(jnum(jget(e, "omega", path), where + ".omega", path));
        else p.bins.push_back(juint32(e, "bin", path));
        const Json &a = jget(e, "amplitude", path), &ph = jget(e, "phase_turns", path);
        if (!a.is_array() || a.size() != nu || !ph.is_array() || ph.size() != nu)
            throw Error("'" + path + "': " + where + ".amplitude and .phase_turns need " + std::to_string(nu) + " values");
        for (size_t i = 0; i < nu; ++i) {
            p.amplitudes[i * L + l] = jnum(a[i], where + ".amplitude", path);
            p.phases[i * L + l] = jnum(ph[i], where + ".phase_turns", path);
        }
    }
    std::unique_ptr<Design> D;
    try {
        D = build_design(p);
    } catch (const msidutil::Error &e) {
        throw Error("'" + path + "': " + e.what());
    }
    // The file's bins must be the ones the design maps to (catches edited files).
    for (size_t l = 0; l < L; ++l) {
        if (ct && lines[l].contains("bin") && juint(lines[l], "bin", path) != D->d.bins[l])
            throw Error(fmt("'%s': lines[%zu].bin is %llu but omega maps to bin %u", path.c_str(), l,
                            (unsigned long long)juint(lines[l], "bin", path), D->d.bins[l]));
    }
    // Keep the original phase mode name for reporting.
    const Json &pm = jget(j, "phase_mode", path);
    if (pm == "random") D->params.phase_mode = MSID_PHASE_RANDOM;
    else if (pm == "schroeder") D->params.phase_mode = MSID_PHASE_SCHROEDER;
    return D;
}

}  // namespace msidfmt
