/* Shared helpers of the firmware unit tests. */
#ifndef LEVELER_TEST_SUPPORT_H
#define LEVELER_TEST_SUPPORT_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "fake_hal.h"
#include "leveler/app.h"
#include "leveler/settings.h"

/* Counts that the default calibration of the channel maps nearest to value (um or Pa). */
uint16_t counts_for(hal_adc_channel channel, double value);

/* Set the four sensors (default calibration) to these values. */
void set_sensors(double height_um, double p_spring_pa, double p_pipe_pa, double p_acc_pa);

/* Advance the fake clock one tick and run the app n times. */
void run_ticks(unsigned n);

/* Fresh fake HAL + app_init, sensors at a mid-band nominal state, run until valid. */
void boot_valid(void);

/* Write one uint16 / int32 holding register through the register map; returns the status. */
int write_hr_u16(uint16_t addr, uint16_t value, uint16_t *reason);
int write_hr_i32(uint16_t addr, int32_t value, uint16_t *reason);
int32_t read_hr_i32(uint16_t addr);
uint16_t read_ir_u16(uint16_t addr);
int write_coil(uint16_t addr, uint16_t value);

#define MID_BAND_UM 398780.0 /* 15.7 in */
#define P_NOMINAL_PA 613633.0 /* 89 psia */

#endif
