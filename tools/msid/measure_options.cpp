// The options every `measure` command shares (measure.hpp).
#include "measure.hpp"

#include <cmath>

namespace msidcli {

void parse_periods_and_estimate(const Args &a, const Design &D, StreamFmt &sf, FrfRequest &rq)
{
    sf.periods = a.u32("periods", (D.params.periods ? D.params.periods : 8));
    if (sf.periods < 2 || sf.periods > MSID_PARAMS_MAX_PERIODS)
        throw UsageError(fmt("--periods must be 2..%u", MSID_PARAMS_MAX_PERIODS));
    request_from_design(rq, D);
    parse_estimate_options(a, rq);
    if ((uint64_t)rq.skip + 2 > sf.periods)   // 64-bit: a huge --skip-periods must not wrap
        throw UsageError(fmt("--periods %u with --skip-periods %u leaves fewer than 2 periods", sf.periods, rq.skip));
}

void parse_measure_options(const Args &a, const Design &D, StreamFmt &sf, FrfRequest &rq)
{
    if (a.has("scale")) {
        const double s = parse_double(a.get("scale"), "--scale");
        if (!(s > 0 && s < 1e30)) throw UsageError("--scale must be positive");
        sf.scale = (float)s;
    }
    sf.periods = a.u32("periods", (D.params.periods ? D.params.periods : 8));
    if (sf.periods < 2 || sf.periods > MSID_PARAMS_MAX_PERIODS)
        throw UsageError(fmt("--periods must be 2..%u", MSID_PARAMS_MAX_PERIODS));
    if (a.has("rate")) {
        const double r = parse_double(a.get("rate"), "--rate");
        if (!(r >= 0 && r <= 4e9) || r != std::floor(r))
            throw UsageError("--rate must be a whole number of Hz (0: unpaced)");
        sf.rate = (uint32_t)r;
    }
    request_from_design(rq, D);
    parse_estimate_options(a, rq);
    if (sf.rate > 0 && !D.d.is_ct) rq.fs = sf.rate;
    if ((uint64_t)rq.skip + 2 > sf.periods)   // 64-bit: a huge --skip-periods must not wrap
        throw UsageError(fmt("--periods %u with --skip-periods %u leaves fewer than 2 periods", sf.periods, rq.skip));
}

}  // namespace msidcli
