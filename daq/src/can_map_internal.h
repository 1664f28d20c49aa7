/* Shared by the CAN map's resolver (msid_can_map.c) and its tick-loop backend (msid_can_map_io.c). */
#ifndef MSID_CAN_MAP_INTERNAL_H
#define MSID_CAN_MAP_INTERNAL_H

#include "msid_daq/msid_can_map.h"

/* Set m->err (printf style) and return rc. */
int msid_can_map_fail(msid_can_map *m, int rc, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Fill m->io with the backend table. */
void msid_can_map_attach(msid_can_map *m);

#endif
