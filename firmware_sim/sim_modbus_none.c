/* The Modbus front end of msid-devsim when the build has no libmodbus (-DMSID_WITH_MODBUS=OFF, or
 * AUTO without it): one message naming the option (docs/install.md). */
#include "sim_modbus.h"

#include <stdio.h>

int sim_modbus_main(sim_device *d)
{
    (void)d;
    fprintf(stderr, "msid-devsim: error: built without Modbus: install libmodbus-dev and configure with "
                    "-DMSID_WITH_MODBUS=ON\n");
    return 2;
}
