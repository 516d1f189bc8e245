/* HAL for the libmodbus-over-pty test: serial bytes over the master side of a
 * pseudo-terminal, ADC counts from a fixed table, outputs recorded, time from
 * CLOCK_MONOTONIC. The slave thread is the only caller of the hal_* functions;
 * the test thread reads the recorded outputs through the atomic accessors. */
#ifndef LEVELER_TEST_HAL_PTY_H
#define LEVELER_TEST_HAL_PTY_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/hal.h"

/* Counts the HAL returns for each channel (mid-scale of the default calibration). */
extern const uint16_t hal_pty_adc_counts[HAL_ADC_COUNT];

/* Serial goes over this (non-blocking) file descriptor from now on. */
void hal_pty_attach(int master_fd);

/* Last value given to hal_output_set() for an output (false before any). */
bool hal_pty_output(hal_output output);

#endif
