/*
 * Safety supervisor: overrides whatever the controller (or a manual request)
 * asks for. Rules, in order of strength:
 *  1. safe state (compressor off, every valve closed) while: mode is off, any
 *     sensor is not valid (power-up, or faulty), or a fault of code 3..7
 *     (stall/leak, sensors) or 8 (chatter) is latched. Those faults hold the safe state
 *     until cleared by command (coil clear_faults) AND the condition is gone.
 *  2. overpressure (any of P1/P2/P3 above overpressure_limit_pa): compressor off
 *     until all are below the limit minus LEVELER_OVERPRESSURE_HYST_PA. Above
 *     overpressure_vent_pa the vent opens, with the valve of the over-pressured
 *     volume (spring valve for P2, accumulator valve for P3). Fault 1 is latched
 *     as a record; the cut-off itself ends with the pressure.
 *  3. compressor run time: after compressor_max_run_s of continuous running it
 *     is forced off for compressor_cooldown_s. Fault 2 latched as a record.
 *  4. stall / leak: while filling the spring (compressor on, spring valve open), neither P1 nor P2 rising by
 *     stall_min_rise_pa nor the height by stall_min_rise_um within
 *     stall_window_s latches fault 3 (-> rule 1).
 *  5. chatter: more than chatter_max_per_min switchings of the driven outputs
 *     in the last minute (chatter.h; 0 = off) latches fault 8 (-> rule 1).
 * Every fault is latched with its code and counted (counters saturate);
 * latched bits re-latch at once while their condition is still present.
 */
#ifndef LEVELER_SUPERVISOR_H
#define LEVELER_SUPERVISOR_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/chatter.h"
#include "leveler/control.h"
#include "leveler/settings.h"
#include "leveler/status.h"

/* 1 psi: the compressor may restart once every pressure is this far below the cut-off. */
#define LEVELER_OVERPRESSURE_HYST_PA 6895

/* Latched faults that hold the safe state until cleared. */
#define LEVELER_FAULTS_HOLDING_SAFE                                                                        \
    ((uint16_t)(LEVELER_FAULT_BIT(LEVELER_FAULT_STALL) | LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_HEIGHT) |  \
                LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_SPRING) |                                         \
                LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE) | LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_ACC) | \
                LEVELER_FAULT_BIT(LEVELER_FAULT_CHATTER)))

typedef struct {
    int32_t height_um;
    int32_t p_spring_pa;
    int32_t p_pipe_pa;
    int32_t p_acc_pa;
    bool sensors_valid;         /* every channel in channels_used valid */
    uint16_t sensor_fault_bits; /* bit n = channel n faulty (used channels only) */
    uint16_t channels_used;     /* leveler_control_channels_used(): the rest are not trusted */
} leveler_measurements;

typedef struct {
    uint16_t active_bits;  /* conditions present this tick */
    uint16_t latched_bits;
    uint16_t last_fault_code;
    uint16_t fault_count[LEVELER_FAULT_COUNTERS];
    bool overpressure_cut;
    bool outputs_safe;     /* the last step held the safe state */
    uint32_t compressor_run_ms;
    uint32_t cooldown_left_ms;
    bool stall_armed;
    uint32_t stall_start_ms;
    int32_t stall_ref_p_pipe_pa;
    int32_t stall_ref_p_spring_pa;
    int32_t stall_ref_height_um;
    leveler_chatter chatter;
} leveler_supervisor;

void leveler_supervisor_init(leveler_supervisor *sv);

/* Clear the latched faults (command). Conditions still present re-latch on the next step. */
void leveler_supervisor_clear(leveler_supervisor *sv);

/*
 * One tick: request (controller or manual) -> outputs actually driven.
 * dt_ms is the time since the previous step (timers), now_ms the tick time.
 */
void leveler_supervisor_step(leveler_supervisor *sv, const leveler_settings *set, uint16_t mode,
                             const leveler_measurements *m, const leveler_outputs *request, uint32_t now_ms,
                             uint32_t dt_ms, leveler_outputs *out);

#endif /* LEVELER_SUPERVISOR_H */
