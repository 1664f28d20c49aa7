// The estimating commands' shared options, into the FRF job's request.
#include "host_libs.hpp"

namespace msidcli {

void parse_estimate_options(const Args &a, FrfRequest &rq)
{
    rq.skip = a.u32("skip-periods", rq.skip);
    if (a.has("detect-lines")) rq.detect = parse_uint_list(a.get("detect-lines"), "--detect-lines");
    rq.transient = a.enum_<msid_transient_mode>(
        "transient", MSID_TRANSIENT_FLAG,
        {{"flag", MSID_TRANSIENT_FLAG}, {"drop", MSID_TRANSIENT_DROP}, {"off", MSID_TRANSIENT_OFF}});
    rq.alpha = a.f64("alpha", rq.alpha);
    msidjob::check_options(rq, {});   // --alpha's range: the job's rule
    // line DFT path, for commands that list --dft (a device estimates on the stream path)
    rq.path = a.enum_<msid_dft_path>("dft", rq.path,
                                     {{"auto", MSID_DFT_AUTO}, {"stream", MSID_DFT_STREAM}, {"fft", MSID_DFT_FFT}});
}

}  // namespace msidcli
