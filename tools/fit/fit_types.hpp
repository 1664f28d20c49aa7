// Common types of the msid host fitting library (C++17, Eigen).
#pragma once
#include "frf_file.hpp"
#include "stats.hpp"   // the FRF stage's distribution laws (tools/frfstat)

#include <Eigen/Dense>
#include "eigen_inst.hpp"   // the shared decompositions, instantiated once in msid_fit
#include <complex>
#include <stdexcept>
#include <string>
#include <vector>

namespace msidfit {

using msidfrf::cd;
using msidfrf::MatC;
using VecC = Eigen::VectorXcd;
using MatR = Eigen::MatrixXd;
using VecR = Eigen::VectorXd;

// The msid-frf/1 types (tools/frffile): a fit error is the file module's error type, so
// one catch handles both.
using FitError = msidfrf::Error;
using msidfrf::Domain;
using msidfrf::FrfData;
using msidfrf::Line;

// The distribution laws of the FRF stage (tools/frfstat), by their names in the fits.
using msidstat::beta_inc;
using msidstat::binom_sf;
using msidstat::chi2_sf;
using msidstat::cost_law;
using msidstat::cost_pvalue;
using msidstat::CostLaw;
using msidstat::f_sf;
using msidstat::gamma_q;

// Frequency variable of a line for a model of the given domain:
// DT: z = exp(j*2*pi*freq); CT: s = j*omega (omega in rad/s).
cd line_point(const Line &l, Domain d);

}  // namespace msidfit
