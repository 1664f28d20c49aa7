/* Wrapper functions over the described-device backend table (msid_devio.h). */
#include "msid_daq/msid_devio.h"

int msid_devio_exchange(const msid_devio *d, const double *drive, double *measure, msid_devio_times *t)
{
    return d->be->exchange(d->ctx, drive, measure, t);
}

int msid_devio_write(const msid_devio *d, const double *drive, msid_devio_times *t)
{
    return d->be->write(d->ctx, drive, t);
}

int msid_devio_read(const msid_devio *d, double *measure, msid_devio_times *t)
{
    return d->be->read(d->ctx, measure, t);
}

int msid_devio_recover(const msid_devio *d) { return d->be->recover ? d->be->recover(d->ctx) : 0; }

const char *msid_devio_error(const msid_devio *d) { return d->be->error(d->ctx); }

const char *msid_devio_describe(const msid_devio *d) { return d->be->describe ? d->be->describe(d->ctx) : d->be->name; }
