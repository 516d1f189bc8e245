/*
 * The Modbus analog-input module leveler-rig reads its sensors from (RTU or
 * TCP, libmodbus). One scan per tick reads every enabled channel with one
 * request per register table; hal_adc_read() then hands out the counts.
 * A failed or timed-out read marks that scan's channels invalid.
 */
#ifndef LEVELER_RIG_SENSOR_MODULE_H
#define LEVELER_RIG_SENSOR_MODULE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "modbus_link.h"
#include "rig_config.h"

typedef struct rig_sensors rig_sensors;

/* Scans over link (not owned). A module that cannot be reached is not an
 * error: reads fail, the firmware's debounce acts, the link reconnects. */
rig_sensors *rig_sensors_open(const rig_config *cfg, rig_link *link, char *err, size_t err_len);
void rig_sensors_close(rig_sensors *s);

/* Read every enabled channel (and the module clock in lockstep). */
void rig_sensors_scan(rig_sensors *s);

/* Results of the last scan. false = no fresh reading. */
bool rig_sensors_counts(const rig_sensors *s, hal_adc_channel channel, uint16_t *counts);
bool rig_sensors_load_n(const rig_sensors *s, double *load_n);
bool rig_sensors_module_time_ms(const rig_sensors *s, uint32_t *time_ms);

/* Lockstep: ask the module to advance its clock (and plant) by step_ms. */
int rig_sensors_step(rig_sensors *s, uint16_t step_ms);

/* Raw register value -> engineering value along a channel's straight line.
 * ADC counts are rounded and saturated to 0..HAL_ADC_MAX_COUNTS. */
double rig_channel_convert(const rig_channel *ch, uint16_t raw);
uint16_t rig_channel_counts(const rig_channel *ch, uint16_t raw);

uint32_t rig_sensors_failed_scans(const rig_sensors *s);

#endif
