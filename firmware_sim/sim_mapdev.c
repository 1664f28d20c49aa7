/* msid-devsim's described device (sim_mapdev.h): the plant stepped on the device's own cycle, the values it
 * publishes, its counter. */
#include "sim_mapdev.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sim_device.h"

int sim_mapdev_init(sim_mapdev *s, const msid_devdesc *d, const sim_plant_def *pd, const sim_mapdev_opts *o, char *err,
                    size_t cap)
{
    memset(s, 0, sizeof *s);
    if (pd->ct) {
        snprintf(err, cap, "a described device steps a discrete-time plant on its cycle: give a DT plant file");
        return -1;
    }
    const uint32_t ny = msid_devdesc_count(d, MSID_DEV_ROLE_OUTPUT);
    if (pd->nu != d->n_drive || pd->ny != ny) {
        snprintf(err, cap, "the plant has %u input(s) and %u output(s), the description %u drive and %u output "
                 "channel(s)", pd->nu, pd->ny, d->n_drive, ny);
        return -1;
    }
    if (!(o->cycle_hz > 0 && o->cycle_hz <= 1e6) || !(fabs(o->ppm) < 1e5)) {
        snprintf(err, cap, "--cycle-hz must be in (0, 1e6] and --clock-ppm below 1e5 in magnitude");
        return -1;
    }
    s->desc = d;
    s->pd = *pd;
    s->o = *o;
    msid_rng_seed(&s->rng, o->seed);
    for (uint32_t i = 0; i < d->n_drive; ++i) s->setpoint[i] = d->drive[i].safe;
    for (uint32_t j = 0, k = 0; j < d->n_measure; ++j)
        if (d->measure[j].role == MSID_DEV_ROLE_OUTPUT) s->out_of[j] = k++;
    for (uint32_t k = 0; k < d->n_drive; ++k) {
        const int q = msid_devdesc_readback(d, k);
        if (q >= 0) s->out_of[q] = k;   /* an input channel publishes the input of the drive channel it reads back */
    }
    s->t0 = sim_now_s();
    return 0;
}

/* One cycle: publish y = C x + D u and the read-back input, then step the plant. */
static void cycle(sim_mapdev *s)
{
    const sim_plant_def *p = &s->pd;
    const msid_devdesc *d = s->desc;
    double u[MSID_MAX_INPUTS], y[MSID_MAX_OUTPUTS], xn[SIM_MAX_STATES];
    for (uint32_t i = 0; i < p->nu; ++i) u[i] = s->setpoint[i];
    for (uint32_t j = 0; j < p->ny; ++j) {
        double v = 0;
        for (uint32_t k = 0; k < p->n; ++k) v += p->C[j * p->n + k] * s->x[k];
        for (uint32_t i = 0; i < p->nu; ++i) v += p->D[j * p->nu + i] * u[i];
        y[j] = v;
    }
    for (uint32_t q = 0; q < d->n_measure; ++q) {
        const msid_dev_chan *c = &d->measure[q];
        switch (c->role) {
        case MSID_DEV_ROLE_OUTPUT: s->value[q] = y[s->out_of[q]] + s->o.sigma_y * msid_rng_normal(&s->rng); break;
        case MSID_DEV_ROLE_INPUT: s->value[q] = u[s->out_of[q]] + s->o.sigma_u * msid_rng_normal(&s->rng); break;
        case MSID_DEV_ROLE_COUNTER: s->value[q] = (double)s->cycles; break;
        default: s->value[q] = u[0]; break;   /* reference: the setpoint of the first drive channel */
        }
    }
    for (uint32_t k = 0; k < p->n; ++k) {
        double v = 0;
        for (uint32_t l = 0; l < p->n; ++l) v += p->A[k * p->n + l] * s->x[l];
        for (uint32_t i = 0; i < p->nu; ++i) v += p->B[k * p->nu + i] * u[i];
        xn[k] = v;
    }
    memcpy(s->x, xn, sizeof(double) * p->n);
    s->cycles++;
}

void sim_mapdev_advance(sim_mapdev *s, double now_s)
{
    const double dev_t = (now_s - s->t0) * (1.0 + 1e-6 * s->o.ppm);
    const double due = floor(dev_t * s->o.cycle_hz) + 1;   /* cycles 0..due-1 have started by now */
    if (due <= (double)s->cycles) return;
    uint64_t n = (uint64_t)due - s->cycles;
    /* a device that was idle for long: only the last cycles matter to what it publishes next, but the plant's
       state must follow its input; the cycles run in full up to a bound, then the plant is reset to rest */
    if (n > 10000000u) {
        memset(s->x, 0, sizeof s->x);
        s->cycles = (uint64_t)due - 1;
        n = 1;
    }
    while (n--) cycle(s);
}
