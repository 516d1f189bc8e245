/*
 * Run-log columns from the firmware (leveler_app_status after a tick), for
 * every program that runs the firmware (leveler-sim, leveler-rig).
 */
#ifndef LEVELER_RUNLOG_FIRMWARE_H
#define LEVELER_RUNLOG_FIRMWARE_H

#include "runlog.h"

/* mode, control_state, latched_fault_bits, sensors_valid. */
void runlog_row_firmware_state(runlog_row *row);
/* height_m and the pressures as the firmware read them (its calibrated
 * readings of the ADC counts: quantisation and noise included); P3 empty
 * without an accumulator. */
void runlog_row_firmware_readings(runlog_row *row, int has_acc);

/* A fault code's name (leveler_fault_code; registers.json last_fault_code). */
const char *runlog_fault_name(int code);

#endif
