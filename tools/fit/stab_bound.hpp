// The stability bound of the constrained (stable) pole-residue fit: its geometry in the fit's own
// pole variable, shared by the optimiser (poleres.cpp: projection and active set) and by the
// model file's readers (which poles a fit left on it).
//
// CT: the pole variable is the scaled s~ = s / ws (ws the frequency scale of the fit, rad/s) and the
// feasible set is Re p~ <= -STAB_MARGIN. DT: the feasible set is |p| <= 1 - STAB_MARGIN. The margin
// keeps a pole on the bound strictly inside the stable region (ss_stable: Re < 0, |z| < 1), with
// a damping ratio of the order of 1e-9 at the band's centre: no damping the data could resolve.
#pragma once
#include "fit_types.hpp"

#include <cmath>

namespace msidfit {

constexpr double STAB_MARGIN = 1e-9;

// The largest stable value of the bounded coordinate: CT Re p~, DT |p|.
inline double stab_limit(Domain d)
{
    return d == Domain::CT ? -STAB_MARGIN : 1.0 - STAB_MARGIN;
}

// Nearest point of the feasible set (a projection, not a reflection: the part of a step that
// crosses the bound is cut off there).
inline cd stab_project(cd p, Domain d)
{
    if (d == Domain::CT) return p.real() > -STAB_MARGIN ? cd(-STAB_MARGIN, p.imag()) : p;
    const double r = std::abs(p), lim = stab_limit(d);
    return r > lim ? p * (lim / r) : p;
}

// On the bound, to a relative 1e-6 of the margin (the projection puts a pole exactly there).
inline bool stab_on_bound(cd p, Domain d)
{
    if (d == Domain::CT) return p.real() >= -STAB_MARGIN * (1.0 + 1e-6);
    return std::abs(p) >= stab_limit(d) - 1e-6 * STAB_MARGIN;
}

// Within one margin of the bound: where a fit ends, a pole this close has a damping no data resolve (the
// step may have moved it off the bound by a fraction of the margin when the cost is flat there).
inline bool stab_held_at_end(cd p, Domain d)
{
    if (d == Domain::CT) return p.real() >= -2.0 * STAB_MARGIN;
    return std::abs(p) >= stab_limit(d) - STAB_MARGIN;
}

// Outward unit normal of the bound at p in (Re p, Im p): CT (1, 0), DT radial.
inline cd stab_normal(cd p, Domain d)
{
    if (d == Domain::CT) return cd(1.0, 0.0);
    const double r = std::abs(p);
    return r > 0 ? p / r : cd(1.0, 0.0);
}

}  // namespace msidfit
