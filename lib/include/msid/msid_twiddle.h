/**
 * @file msid_twiddle.h
 * @brief Exact-index twiddle table W^n = exp(-j*2*pi*n/P), n = 0..P-1.
 *
 * Shared, read-only, by the generator (::msid_gen) and the line DFT
 * (::msid_linedft) so one period needs one table. Entries come from
 * ::msid_cis_turns and are bit-identical on every platform. Users index it by
 * (k*n) mod P computed in integers, so a run of any length has no phase drift.
 */
#ifndef MSID_TWIDDLE_H
#define MSID_TWIDDLE_H

#include "msid_types.h"
#include "msid_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Twiddle table instance (caller-owned). */
typedef struct msid_twiddle {
    uint32_t period;        /**< P, samples per period */
    const msid_cplx *w;     /**< w[n] = (cos(2 pi n/P), -sin(2 pi n/P)), P entries */
} msid_twiddle;

/**
 * @brief Bytes of working memory for a table of period P.
 * @param period P in [MSID_MIN_PERIOD, MSID_MAX_PERIOD]
 * @return 16*P rounded up to MSID_MEM_ALIGN, or 0 if P is out of range.
 */
size_t msid_twiddle_mem_size(uint32_t period);

/**
 * @brief Fill the table in `mem`.
 * @param tw   instance to initialise
 * @param period P in [MSID_MIN_PERIOD, MSID_MAX_PERIOD]
 * @param mem  working memory, MSID_MEM_ALIGN-aligned
 * @param len  bytes available at `mem`, >= msid_twiddle_mem_size(P)
 * @return MSID_OK, MSID_E_NULL, MSID_E_PERIOD, MSID_E_MEM_ALIGN or MSID_E_MEM_SIZE
 */
msid_status msid_twiddle_init(msid_twiddle *tw, uint32_t period, void *mem, size_t len);

#ifdef __cplusplus
}
#endif
#endif
