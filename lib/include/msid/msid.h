/**
 * @file msid.h
 * @brief Umbrella header of the msid estimator core (libmsid).
 *
 * Data flow: ::msid_design -> ::msid_gen (excitation) -> device -> rows of
 * [u; y] -> ::msid_meas (::msid_linedft + ::msid_pstats per experiment) ->
 * ::msid_frf (Ghat, covariances, dof) -> msid-frf/1 file -> host fitting.
 */
#ifndef MSID_H
#define MSID_H

#include "msid_types.h"
#include "msid_status.h"
#include "msid_dmath.h"
#include "msid_rng.h"
#include "msid_twiddle.h"
#include "msid_design.h"
#include "msid_gen.h"
#include "msid_fft.h"
#include "msid_linedft.h"
#include "msid_pstats.h"
#include "msid_meas.h"
#include "msid_frf.h"
#include "msid_plant.h"
#include "msid_cissim.h"

/** Library version string. */
#define MSID_VERSION "0.1.0"

#endif
