/*
 * Fake HAL for unit tests (link-time substitute for hal.h).
 * Settable ADC counts per channel (with an optional per-read script), read
 * failures, settable time, recorded outputs, serial byte queues.
 */
#ifndef LEVELER_FAKE_HAL_H
#define LEVELER_FAKE_HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "leveler/hal.h"

#define FAKE_HAL_SERIAL_CAP 1024u
#define FAKE_HAL_ADC_SCRIPT_CAP 64u

/* Everything back to power-up: counts 2048, reads succeed, time 0, outputs off, queues empty. */
void fake_hal_reset(void);

/* Every read of the channel returns counts (after any scripted values). */
void fake_hal_set_adc(hal_adc_channel channel, uint16_t counts);
/* The next n reads of the channel return values[0..n-1] in order, then the set counts again. */
void fake_hal_script_adc(hal_adc_channel channel, const uint16_t *values, size_t n);
/* Reads of the channel fail (return false) while set. */
void fake_hal_set_adc_fail(hal_adc_channel channel, bool fail);
/* How many times the channel was read. */
uint32_t fake_hal_adc_reads(hal_adc_channel channel);

void fake_hal_set_time_ms(uint32_t now_ms);
void fake_hal_advance_ms(uint32_t dt_ms);

/* Last value driven on the output, and how many times it was set. */
bool fake_hal_output(hal_output output);
uint32_t fake_hal_output_writes(hal_output output);

/* Serial: bytes the firmware will read, and bytes it wrote. */
void fake_hal_serial_push_rx(const uint8_t *bytes, size_t n);
size_t fake_hal_serial_take_tx(uint8_t *out, size_t cap);
/* Limit how many bytes one hal_serial_write() accepts (default: unlimited). */
void fake_hal_serial_set_tx_limit(size_t max_per_call);

#endif /* LEVELER_FAKE_HAL_H */
