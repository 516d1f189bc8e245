/*
 * The firmware's commissioning routine (leveler/commissioning.h) run on a
 * config's plant: the config's base load held, the coil `commission` written
 * before the first tick, the run long enough for the routine's 60 s. What it
 * learnt, read back from the firmware's settings, beside what the plant really
 * has (its hysteresis lines at the controller's target height for that load).
 * leveler-sim --commission prints it; the commissioning test checks it.
 */
#ifndef LEVELER_SIM_COMMISSIONING_RUN_H
#define LEVELER_SIM_COMMISSIONING_RUN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "runlog.h"
#include "simloop.h"

#define SIM_COMMISSIONING_END_S 62.0 /* the routine's 60 s and a little: what it left behind */

typedef struct {
    uint16_t result;           /* registers.json commission_result */
    double took_s;             /* commission_ms */
    int32_t up_pa, down_pa;    /* the lines it learnt (Pa abs, at the target height) */
    int32_t gap_pa;            /* the settings after it */
    int32_t k_up_pa_per_mm, k_down_pa_per_mm;
    uint16_t coast_up_ms, coast_down_ms;
    uint16_t moves;            /* algorithm 3's moves during the run */
    double target_m;           /* the controller's target height */
    double true_up_pa, true_down_pa; /* the plant's lines at target_m for the base load, Pa abs */
    double final_height_m;     /* at the end of the run (true) */
    bool in_band;              /* final height inside the band */
    uint16_t latched_faults;
} sim_commissioning;

/* Run it (algorithm 3 whatever the config says; log optional). 0 or -1 with err. */
int sim_commissioning_run(const plant_config *cfg, double end_s, runlog *log, sim_commissioning *out, char *err,
                          size_t err_len);

/* What the routine ends on, by name (registers.json's enum). */
const char *sim_commissioning_result_name(uint16_t result);

#endif /* LEVELER_SIM_COMMISSIONING_RUN_H */
