/* CiA 402 power state machine and the cyclic synchronous modes of the simulated drive. */
#include "sim_co402.h"

#include <math.h>

sim_co402_gains sim_co402_gains_for(double ts)
{
    /* total inertia J = 3e-4 kg m^2: kp = J wc, the integral corner at wc / 4, the position loop at wc / 4.
     * wc = 2 pi 20 Hz where the SYNC is fast enough (kp T / J <= 0.2), else wc = 0.2 / T: the discrete loop
     * (tau[k] = kp e[k] + I[k], I[k] = I[k-1] + ki T e[k], x[k+1] = A x[k] + B tau[k], A, B of sim_twomass at
     * T) then keeps its poles where a 1 kHz SYNC has them. Its poles (beside the position's z = 1, which the
     * velocity loop does not see), by the eigenvalues of that 5-state map for the default mechanics:
     *   1 kHz: 0.528 +- 0.667j (the shaft's mode), 0.914, 0.952;
     *   100 Hz: -0.632 +- 0.549j (the shaft's mode, aliased; |z| 0.837), 0.851, 0.933;
     *   50 Hz: 0.037 +- 0.748j (the shaft's mode, aliased; |z| 0.749), 0.841, 0.938;
 *   25 Hz: -0.538 +- 0.051j (the shaft's mode, aliased), 0.822, 0.945;
     *   20 Hz: 0.359 +- 0.298j, 0.814, 0.947.
     * The loop's own poles are real (well damped; its slowest, 0.93..0.95, settles in about 16 SYNCs at any
     * rate), and the shaft's mode keeps about the damping it has open loop. Not at 300 Hz: the shaft's mode
     * aliases next to Nyquist there and the loop pushes it out of the unit circle (z = -1.06). */
    const double two_pi = 2.0 * 3.14159265358979323846, J = 3e-4;
    double wc = two_pi * 20.0;
    if (ts > 0 && wc * ts > 0.2) wc = 0.2 / ts;
    const sim_co402_gains g = {J * wc, J * wc * wc / 4.0, wc / 4.0, 3000.0};
    return g;
}

sim_co402_gains sim_co402_default_gains(void) { return sim_co402_gains_for(1e-3); }

void sim_co402_init(sim_co402 *d, const sim_co402_gains *g)
{
    d->state = MSID_CO402_SWITCH_ON_DISABLED;
    d->controlword = 0;
    d->g = *g;
    d->integ = 0;
}

void sim_co402_controlword(sim_co402 *d, uint16_t cw)
{
    const int reset_edge = (cw & 0x80u) && !(d->controlword & 0x80u);
    d->controlword = cw;
    const int disable_voltage = (cw & 0x02u) == 0;
    const int quick_stop = (cw & 0x06u) == 0x02u;
    const int shutdown = (cw & 0x87u) == 0x06u;
    const int switch_on = (cw & 0x8Fu) == 0x07u;
    const int enable = (cw & 0x8Fu) == 0x0Fu;
    switch (d->state) {
    case MSID_CO402_FAULT:
        if (reset_edge) d->state = MSID_CO402_SWITCH_ON_DISABLED;
        return;
    case MSID_CO402_FAULT_REACTION:
    case MSID_CO402_NOT_READY:
        return;
    case MSID_CO402_SWITCH_ON_DISABLED:
        if (shutdown) d->state = MSID_CO402_READY;
        return;
    case MSID_CO402_READY:
        if (disable_voltage || quick_stop) d->state = MSID_CO402_SWITCH_ON_DISABLED;
        else if (switch_on) d->state = MSID_CO402_SWITCHED_ON;
        else if (enable) d->state = MSID_CO402_OPERATION_ENABLED;  /* transitions 3 and 4 in one */
        break;
    case MSID_CO402_SWITCHED_ON:
        if (disable_voltage || quick_stop) d->state = MSID_CO402_SWITCH_ON_DISABLED;
        else if (shutdown) d->state = MSID_CO402_READY;
        else if (enable) d->state = MSID_CO402_OPERATION_ENABLED;
        break;
    case MSID_CO402_OPERATION_ENABLED:
        if (disable_voltage) d->state = MSID_CO402_SWITCH_ON_DISABLED;
        else if (quick_stop) d->state = MSID_CO402_QUICK_STOP_ACTIVE;
        else if (shutdown) d->state = MSID_CO402_READY;
        else if (switch_on) d->state = MSID_CO402_SWITCHED_ON;
        break;
    case MSID_CO402_QUICK_STOP_ACTIVE:
        /* quick stop option code 6: stay here until the voltage is disabled, or enabled again (16) */
        if (disable_voltage) d->state = MSID_CO402_SWITCH_ON_DISABLED;
        else if (enable) d->state = MSID_CO402_OPERATION_ENABLED;
        break;
    }
    if (d->state != MSID_CO402_OPERATION_ENABLED && d->state != MSID_CO402_QUICK_STOP_ACTIVE) d->integ = 0;
}

void sim_co402_fault(sim_co402 *d)
{
    d->state = MSID_CO402_FAULT;
    d->integ = 0;
}

uint16_t sim_co402_statusword(const sim_co402 *d)
{
    static const uint16_t bits[] = {
        [MSID_CO402_NOT_READY] = 0x0000, [MSID_CO402_SWITCH_ON_DISABLED] = 0x0040, [MSID_CO402_READY] = 0x0021,
        [MSID_CO402_SWITCHED_ON] = 0x0023, [MSID_CO402_OPERATION_ENABLED] = 0x0027,
        [MSID_CO402_QUICK_STOP_ACTIVE] = 0x0007, [MSID_CO402_FAULT_REACTION] = 0x000F, [MSID_CO402_FAULT] = 0x0008,
    };
    return (uint16_t)(bits[d->state] | 0x0210u);
}

int32_t sim_co402_pos_to_bus(double theta)
{
    const double u = theta / SIM_CO402_POS_UNIT;
    if (!(fabs(u) < 9e18)) return 0;
    return (int32_t)(uint32_t)(uint64_t)llround(u);
}

int32_t sim_co402_vel_to_bus(double omega)
{
    const double u = omega / SIM_CO402_VEL_UNIT;
    return u >= 2147483647.0 ? INT32_MAX : u <= -2147483648.0 ? INT32_MIN : (int32_t)lround(u);
}

static double velocity_loop(sim_co402 *d, double w_ref, const sim_co402_io *io, double rated)
{
    const double lim = d->g.max_pm * 1e-3 * rated;
    const double e = w_ref - io->omega;
    double integ = d->integ + d->g.ki * e * io->ts;
    if (integ > lim) integ = lim;
    if (integ < -lim) integ = -lim;
    d->integ = integ;
    return d->g.kp * e + integ;
}

double sim_co402_demand(sim_co402 *d, const sim_co402_io *io, int16_t *demand_pm)
{
    const double rated = (io->rated_mnm ? io->rated_mnm : 1u) * 1e-3;
    double tau = 0;
    if (d->state == MSID_CO402_OPERATION_ENABLED) {
        if (io->mode == MSID_CO402_MODE_CST) tau = io->target_torque * 1e-3 * rated;
        else if (io->mode == MSID_CO402_MODE_CSV) tau = velocity_loop(d, io->target_vel * SIM_CO402_VEL_UNIT, io, rated);
        else if (io->mode == MSID_CO402_MODE_CSP) {
            /* position error on the INTEGER32 circle of the bus, so a wrapped target is the near one */
            const int32_t err = (int32_t)((uint32_t)io->target_pos - (uint32_t)sim_co402_pos_to_bus(io->theta));
            tau = velocity_loop(d, d->g.kpp * err * SIM_CO402_POS_UNIT, io, rated);
        }
        if (io->mode == MSID_CO402_MODE_CST || io->mode == MSID_CO402_MODE_CSV || io->mode == MSID_CO402_MODE_CSP)
            tau += io->torque_offset * 1e-3 * rated;   /* a feed-forward beside the loop, as CiA 402 has it */
    } else if (d->state == MSID_CO402_QUICK_STOP_ACTIVE)
        tau = velocity_loop(d, 0.0, io, rated);
    double pm = tau / rated * 1e3;
    const double lim = d->g.max_pm < 32767.0 ? d->g.max_pm : 32767.0;
    if (pm > lim) pm = lim;
    if (pm < -lim) pm = -lim;
    *demand_pm = (int16_t)lround(pm);
    return *demand_pm * 1e-3 * rated;
}
