/* Status messages. */
#include "msid/msid_status.h"

const char *msid_strerror(msid_status s)
{
    switch (s) {
    case MSID_OK: return "ok";
    case MSID_E_NULL: return "a required pointer argument is NULL";
    case MSID_E_MEM_SIZE: return "working memory is shorter than the object's _mem_size()";
    case MSID_E_MEM_ALIGN: return "working memory is not aligned to MSID_MEM_ALIGN bytes";
    case MSID_E_PERIOD: return "period is outside the supported range";
    case MSID_E_NO_LINES: return "no frequency lines given";
    case MSID_E_LINE_RANGE: return "a line is at or beyond Nyquist (bin >= P/2)";
    case MSID_E_LINE_DUP: return "the same line is given twice";
    case MSID_E_DIMS: return "number of inputs, outputs, channels or experiments out of range";
    case MSID_E_EXPERIMENTS: return "fewer experiments than inputs (need m >= nu)";
    case MSID_E_AMPLITUDE: return "an amplitude is not finite, or outside [1e-150, 1e150]";
    case MSID_E_PHASE: return "a phase is not finite";
    case MSID_E_PATTERN: return "unknown MIMO pattern, or Hadamard pattern with a number of experiments that is not a power of 2";
    case MSID_E_SAMPLE_TIME: return "sample time is not finite and positive";
    case MSID_E_CT_NOT_PERIODIC: return "period*sample_time does not span a whole number of periods of a continuous-time line";
    case MSID_E_ALIAS_COLLISION: return "two continuous-time lines fold onto the same discrete-time bin (violates Assumption 2)";
    case MSID_E_ALIAS_EDGE: return "a non-zero continuous-time line folds onto DC or Nyquist (violates Assumption 2)";
    case MSID_E_ARG: return "an argument is out of range";
    case MSID_E_STATE: return "call out of order for the object's state";
    case MSID_E_CAPACITY: return "more periods than the configured history holds (raise max_periods)";
    case MSID_E_FEW_PERIODS: return "fewer than 2 usable periods in an experiment: no covariance possible";
    case MSID_E_SINGULAR: return "the input matrix is singular at a line";
    case MSID_E_BACKEND: return "the FFT backend failed or does not match the period";
    case MSID_E_NOT_FINITE: return "a value that must be finite is NaN or infinite";
    case MSID_E_RANGE: return "the data's magnitudes are beyond what double precision can process at a line (|U| or |Y| "
                              "near 1e150 or 1e-150): rescale the records, e.g. change their units";
    case MSID_E_COUNT_:
    case MSID_STATUS_FORCE_INT_: break;
    }
    return "unknown msid status";
}
