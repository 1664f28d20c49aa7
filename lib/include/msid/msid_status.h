/**
 * @file msid_status.h
 * @brief Status codes returned by every msid function, and their messages.
 */
#ifndef MSID_STATUS_H
#define MSID_STATUS_H

#ifdef __cplusplus
extern "C" {
#endif

/** Status of an msid call. ::MSID_OK is zero; every error is positive. */
typedef enum msid_status {
    MSID_OK = 0,               /**< success */
    MSID_E_NULL,               /**< a required pointer argument is NULL */
    MSID_E_MEM_SIZE,           /**< working memory shorter than `_mem_size()` */
    MSID_E_MEM_ALIGN,          /**< working memory not aligned to MSID_MEM_ALIGN */
    MSID_E_PERIOD,             /**< period outside [MSID_MIN_PERIOD, MSID_MAX_PERIOD] */
    MSID_E_NO_LINES,           /**< no lines given */
    MSID_E_LINE_RANGE,         /**< a line is at or beyond Nyquist (bin >= P/2) */
    MSID_E_LINE_DUP,           /**< the same line is given twice */
    MSID_E_DIMS,               /**< inputs/outputs/channels/experiments out of range */
    MSID_E_EXPERIMENTS,        /**< fewer experiments than inputs (m < nu) */
    MSID_E_AMPLITUDE,          /**< an amplitude is not finite, or outside [MSID_MIN_AMPLITUDE, MSID_MAX_AMPLITUDE] */
    MSID_E_PHASE,              /**< a user phase is not finite */
    MSID_E_PATTERN,            /**< unknown MIMO pattern, or Hadamard with m not a power of 2 */
    MSID_E_SAMPLE_TIME,        /**< sample time not finite and positive */
    MSID_E_CT_NOT_PERIODIC,    /**< P*h does not span a whole number of periods of a line */
    MSID_E_ALIAS_COLLISION,    /**< two continuous-time lines fold onto the same bin (Assumption 2) */
    MSID_E_ALIAS_EDGE,         /**< a non-zero line folds onto DC or Nyquist (Assumption 2) */
    MSID_E_ARG,                /**< an argument is out of range */
    MSID_E_STATE,              /**< call out of order for the object's state */
    MSID_E_CAPACITY,           /**< more periods than the configured history holds */
    MSID_E_FEW_PERIODS,        /**< fewer than 2 usable periods in an experiment */
    MSID_E_SINGULAR,           /**< the input matrix is singular at a line */
    MSID_E_BACKEND,            /**< the FFT backend failed or does not match the period */
    MSID_E_NOT_FINITE,         /**< a value that must be finite is NaN or infinite */
    MSID_E_RANGE,              /**< magnitudes beyond what double precision can process (e.g. data scaled by 1e150) */
    MSID_E_COUNT_,             /**< number of codes (not a status) */
    /** Not a status: keeps the enum int-sized where the ABI packs enums (arm-none-eabi's
     *  -fshort-enums default), so any int converts to msid_status without truncation. */
    MSID_STATUS_FORCE_INT_ = 0x7fffffff
} msid_status;

/**
 * @brief Human-readable message for a status.
 * @param s any value; unknown values give "unknown msid status".
 * @return a static, NUL-terminated string; never NULL.
 */
const char *msid_strerror(msid_status s);

#ifdef __cplusplus
}
#endif
#endif
