/*
 * leveler-rig's side of the HAL (hal_rig.c implements firmware/include/leveler/hal.h).
 * hal_output_set() only records the wanted state (safe at any time, no I/O);
 * the main loop applies it through the output backend after each tick.
 * hal_now_ms() is the rig's one time source: CLOCK_MONOTONIC since start, or
 * in lockstep the module's clock as read in the last scan.
 */
#ifndef LEVELER_RIG_HAL_H
#define LEVELER_RIG_HAL_H

#include <stdbool.h>
#include "leveler/hal.h"
#include "rig_config.h"
#include "sensor_module.h"

void rig_hal_bind(rig_sensors *sensors, rig_clock clock);
void rig_hal_wanted_outputs(bool out[HAL_OUT_COUNT]);
/* hal_now_ms()'s clock in seconds at full resolution, for the run log: a late
 * tick and the on-time one after it can fall in the same millisecond, and the
 * log's time column must still increase. */
double rig_hal_now_s(void);

#endif
