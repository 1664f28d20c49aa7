/**
 * @file msid_gen.h
 * @brief Sample generator for one experiment of a ::msid_design.
 *
 * Produces u(n) for all nu inputs, sample by sample or in blocks, with exact
 * integer twiddle indices: the output is bit-identical whatever the block
 * sizes, between the table and on-the-fly modes, and on every IEEE-754
 * platform (see msid_dmath.h). The sequence is periodic with period P.
 */
#ifndef MSID_GEN_H
#define MSID_GEN_H

#include "msid_design.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Generator configuration. */
typedef struct msid_gen_cfg {
    const msid_design *design;   /**< design (must outlive the generator) */
    const msid_twiddle *twiddle; /**< table of the design's period (must outlive the generator) */
    uint32_t experiment;         /**< e in [0, m) */
    int waveform_table;          /**< 1: precompute one period (P*nu doubles, O(1) per sample);
                                      0: O(L*nu) per sample, L*4 bytes of state */
} msid_gen_cfg;

/** Generator instance (caller-owned). */
typedef struct msid_gen {
    const msid_design *design;
    const msid_twiddle *twiddle;
    uint32_t experiment;
    uint32_t pos;          /**< sample index within the period, [0, P) */
    uint64_t count;        /**< samples produced since init or seek */
    double *wave;          /**< [P*nu] one period (table mode) or NULL */
    uint32_t *idx;         /**< [L] running twiddle index (on-the-fly mode) */
} msid_gen;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_gen_mem_size(const msid_gen_cfg *cfg);

/**
 * @brief Initialise at sample 0. Table mode costs O(P*L*nu) once.
 * @return MSID_OK, MSID_E_NULL, MSID_E_ARG (experiment out of range), MSID_E_PERIOD
 *         (twiddle period differs), MSID_E_MEM_ALIGN or MSID_E_MEM_SIZE.
 */
msid_status msid_gen_init(msid_gen *g, const msid_gen_cfg *cfg, void *mem, size_t len);

/**
 * @brief Write the next sample of every input to u[0..nu-1] and advance.
 */
void msid_gen_next(msid_gen *g, double *u);

/**
 * @brief Write n samples, row-major: u[k*stride + i] for input i of sample k.
 * @param stride doubles between consecutive samples, >= nu (lets callers fill
 *        the input columns of a wider row buffer)
 */
void msid_gen_block(msid_gen *g, double *u, size_t n, size_t stride);

/** @brief Jump to absolute sample index `sample` (period phase = sample mod P). */
void msid_gen_seek(msid_gen *g, uint64_t sample);

#ifdef __cplusplus
}
#endif
#endif
