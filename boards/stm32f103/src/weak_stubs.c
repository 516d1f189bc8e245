/*
 * Weak stand-ins for the Modbus RTU slave until firmware/ provides it: the
 * board then answers nothing. The ELF links leveler_firmware as a whole
 * archive, so the strong definitions, once they exist, always win.
 */
#include "leveler/modbus_rtu.h"

__attribute__((weak)) void leveler_modbus_rtu_init(void) {}
__attribute__((weak)) void leveler_modbus_rtu_poll(void) {}
