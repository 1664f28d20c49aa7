// Design -> msid-can/1 parameter set (msid_param_upload.hpp).
#include "msid_param_upload.hpp"

#include <cmath>
#include <cstring>

namespace msidacq {

using msidutil::Error;
using msidutil::fmt;
using msidutil::Mem;

bool same_coef(const msid_design &a, const msid_design &b)
{
    if (a.period != b.period || a.n_lines != b.n_lines || a.n_inputs != b.n_inputs || a.n_experiments != b.n_experiments)
        return false;
    const size_t n = (size_t)a.n_experiments * a.n_inputs * a.n_lines;
    return std::memcmp(a.coef, b.coef, n * sizeof(msid_cplx)) == 0 &&
           std::memcmp(a.bins, b.bins, a.n_lines * sizeof(uint32_t)) == 0;
}

std::unique_ptr<DevDesign> device_design(const msid_params &c)
{
    auto D = std::make_unique<DevDesign>();
    if (c.period < MSID_MIN_PERIOD || c.period > MSID_MAX_PERIOD) { D->st = MSID_E_PERIOD; return D; }
    D->mtw = Mem(msid_twiddle_mem_size(c.period));
    if ((D->st = msid_twiddle_init(&D->tw, c.period, D->mtw.p, D->mtw.n)) != MSID_OK) return D;
    msid_design_cfg dc;
    msid_params_design_cfg(&c, &dc, &D->tw);
    const size_t n = msid_design_mem_size(&dc);
    if (!n) { D->st = MSID_E_DIMS; return D; }
    D->md = Mem(n);
    D->st = msid_design_init(&D->d, &dc, D->md.p, D->md.n);
    return D;
}


std::unique_ptr<msid_params> config_from_design(const Design &D, const StreamFmt &s)
{
    const msid_design &d = D.d;
    auto c = std::make_unique<msid_params>();
    std::memset(c.get(), 0, sizeof *c);
    const uint32_t L = d.n_lines, nu = d.n_inputs;
    if (L > MSID_PARAMS_MAX_LINES)
        throw Error(fmt("the design has %u lines: an msid-can/1 device takes at most %u", L, MSID_PARAMS_MAX_LINES));
    c->period = d.period;
    c->n_lines = L;
    c->n_inputs = nu;
    c->n_experiments = d.n_experiments;
    c->pattern = (uint32_t)d.pattern;
    if (d.is_ct) {
        c->is_ct = 1;
        std::memcpy(c->omega, d.omega, L * sizeof(double));
        c->sample_time = d.sample_time;
    } else {
        std::memcpy(c->bins, d.bins, L * sizeof(uint32_t));
    }
    bool ones = true;
    for (size_t k = 0; k < (size_t)nu * L; ++k) ones = ones && d.amp[k] == 1.0;
    c->have_amp = !ones;
    if (!ones) std::memcpy(c->amp, d.amp, (size_t)nu * L * sizeof(double));
    c->encoding = s.encoding;
    c->scale = s.scale;
    c->fd = s.fd;
    c->rate_hz = s.rate;
    c->periods = s.periods;
    // Compact form first (seed + phase mode); explicit phases when that does not rebuild the same design.
    c->phase_mode = (uint32_t)D.params.phase_mode;
    c->seed = D.params.seed;
    c->have_phase = 0;
    if (c->phase_mode != MSID_PHASE_USER) {
        auto dd = device_design(*c);
        if (dd->st == MSID_OK && same_coef(dd->d, d)) return c;
    }
    c->phase_mode = MSID_PHASE_USER;
    c->have_phase = 1;
    std::memcpy(c->phase, d.phase, (size_t)nu * L * sizeof(double));
    auto dd = device_design(*c);
    if (dd->st != MSID_OK || !same_coef(dd->d, d))
        throw Error("the design cannot be uploaded exactly (the device would rebuild a different excitation)");
    return c;
}

}  // namespace msidacq
