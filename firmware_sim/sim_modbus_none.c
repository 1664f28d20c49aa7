/* The Modbus front end of msid-devsim when the build has no libmodbus (-DMSID_WITH_MODBUS=OFF, or
 * AUTO without it): one message naming the option (docs/install.md). */
#include "sim_mbmap.h"
#include "sim_modbus.h"

#include <stdio.h>

int sim_modbus_main(sim_device *d)
{
    (void)d;
    fprintf(stderr, "msid-devsim: error: built without Modbus: install libmodbus-dev and configure with "
                    "-DMSID_WITH_MODBUS=ON\n");
    return 2;
}

int sim_mbmap_main(sim_device *d, const msid_devdesc *desc, const sim_mapdev_opts *mo)
{
    (void)d;
    (void)desc;
    (void)mo;
    fprintf(stderr, "msid-devsim: error: built without Modbus: install libmodbus-dev and configure with "
                    "-DMSID_WITH_MODBUS=ON\n");
    return 2;
}
