/*
 * What the firmware publishes (status) and the commands it accepts (coils).
 * The register map binds its items to these fields by name (registers.json "bind").
 */
#ifndef LEVELER_STATUS_H
#define LEVELER_STATUS_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/hal.h"
#include "leveler/version.h" /* generated from the top-level VERSION file */

#define LEVELER_FIRMWARE_VERSION LEVELER_VERSION_NUMBER /* major*10000 + minor*100 + patch */

/* Fault codes (registers.json last_fault_code); bit (code - 1) in the fault bit fields. */
typedef enum {
    LEVELER_FAULT_NONE = 0,
    LEVELER_FAULT_OVERPRESSURE = 1,
    LEVELER_FAULT_RUN_TIME = 2,
    LEVELER_FAULT_STALL = 3,
    LEVELER_FAULT_SENSOR_HEIGHT = 4, /* + channel: 5 P2, 6 P1, 7 P3 */
    LEVELER_FAULT_SENSOR_P_SPRING = 5,
    LEVELER_FAULT_SENSOR_P_PIPE = 6,
    LEVELER_FAULT_SENSOR_P_ACC = 7,
    LEVELER_FAULT_CHATTER = 8 /* outputs switching faster than settings.chatter_max_per_min */
} leveler_fault_code;

#define LEVELER_FAULT_BIT(code) ((uint16_t)(1u << ((unsigned)(code) - 1u)))

/* fault_count[] slots: overpressure, run time, stall, any sensor, chatter. */
#define LEVELER_FAULT_COUNTERS 5u

typedef enum {
    LEVELER_STATE_IN_BAND = 0,
    LEVELER_STATE_CHARGING = 1,
    LEVELER_STATE_DISCHARGING = 2,
    LEVELER_STATE_SAFE = 3
} leveler_control_state;

typedef struct {
    int32_t height_um;
    int32_t p_spring_pa; /* P2 */
    int32_t p_pipe_pa;   /* P1, the "system pressure" of the accumulator rules */
    int32_t p_acc_pa;    /* P3 */
    uint16_t sensor_fault_bits;
    uint16_t control_state; /* leveler_control_state */
    uint16_t active_fault_bits;
    uint16_t latched_fault_bits;
    uint16_t last_fault_code;
    uint16_t fault_count[LEVELER_FAULT_COUNTERS];
    uint16_t last_refusal_reason;
    uint32_t uptime_ms;
    uint32_t compressor_run_ms;
    uint32_t cooldown_left_ms;
    uint32_t tick_overruns;
    uint32_t tick_cycles_worst;
    uint16_t firmware_version;
    uint16_t raw_counts[HAL_ADC_COUNT];
    uint32_t log_rows_dropped; /* Linux rig: run-log rows not written */
    uint32_t sensor_scans_failed; /* Linux rig: module scans without a valid reply */
    uint32_t link_faults_auto_cleared; /* Linux rig: link-outage sensor faults cleared by [faults] auto-clear */
    uint16_t alg3_phase; /* leveler_alg3_phase */
    uint16_t alg3_moves;
    uint16_t commission_step; /* leveler_commission_phase, 0 = not running */
    bool compressor_on;
    bool spring_valve_open;
    bool vent_valve_open;
    bool acc_valve_open;
    bool outputs_safe;
    bool fault_latched;
    bool sensors_valid;
    bool clock_fault;
    bool watchdog_reset;
    bool log_fault;            /* Linux rig: the last run-log row could not be written */
} leveler_status;

typedef struct {
    bool clear_faults; /* acted on when written 1; always reads 0 */
    bool manual_compressor;
    bool manual_spring_valve;
    bool manual_vent_valve;
    bool manual_acc_valve;
    bool commission; /* written 1: run the commissioning routine; reads 1 while it runs; written 0: abort */
} leveler_command;

/* The status of the last tick and the commands in force. */
const leveler_status *leveler_app_status(void);
const leveler_command *leveler_app_command(void);

#endif /* LEVELER_STATUS_H */
