/*
 * Firmware in the loop: the plant (leveler_plant), the HAL over it
 * (hal_sim.c) and the unchanged firmware (leveler_firmware), stepped by the
 * one tick loop (stepper.h).
 *
 * Each 10 ms tick: the load schedule sets the load, the plant integrates
 * 10 ms with RK4 (config [solver] substeps_per_tick fixed sub-steps) under the
 * outputs the firmware set last, the sensors turn the state into ADC counts,
 * then leveler_app_tick() runs. The first tick (0 to 10 ms) runs under the
 * config's [initial] actuators and the firmware's first tick is at 10 ms, as
 * Appendix B's controller first acts after its first step. The simulator owns
 * time: hal_now_ms() is simulated milliseconds. Runs are deterministic.
 *
 * The firmware is one set of globals, so one simulation runs at a time per
 * process (sim_run is not reentrant).
 */
#ifndef LEVELER_SIMLOOP_H
#define LEVELER_SIMLOOP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "plant.h"
#include "runlog.h"
#include "stepper.h"

typedef struct {
    const plant_config *config;
    int algorithm;               /* 0 = the config's; 1, 2 or 3 overrides */
    const sim_load_step *steps;  /* NULL = the config's scenario */
    size_t step_count;
    double end_s;                /* 0 = the schedule's end; later = hold the last load */
    runlog *log;                 /* optional: one row per tick */
    runlog_row *rows;            /* optional caller buffer: one row per tick, t = 0 first */
    size_t rows_cap;
    void (*progress)(double t_s, double end_s, void *user); /* optional, about every simulated 5 % */
    void *progress_user;
    bool commission;             /* write the coil `commission` (1) before the firmware's first tick:
                                  * the commissioning routine runs first (leveler/commissioning.h) */
} sim_options;

/* What happened in a run that a user must be told (leveler-sim's summary). */
#define SIM_FAULT_CODES 16
typedef struct {
    uint16_t latched_bits;               /* every fault the supervisor latched (LEVELER_FAULT_BIT) */
    double fault_t_s[SIM_FAULT_CODES];   /* when fault code c + 1 first latched; NAN = never */
    double safe_s;                       /* time the outputs were held safe by a latched fault */
    double safe_from_s;                  /* the first tick they were; NAN = never */
    int end_stop;                        /* first end stop reached: -1 bottom, +1 top, 0 none */
    double end_stop_t_s;
    double load_out_t_s;                 /* first tick with a load outside [spring] load_min..load_max; NAN = none */
    double load_out_n;
} sim_events;

typedef struct {
    size_t ticks;         /* 10 ms ticks simulated (t = 0 included; the firmware runs from the second) */
    size_t rows;          /* rows stored in the buffer */
    double end_s;
    plant final_plant;    /* plant at the end */
    sim_events events;
} sim_result;

/* Run a whole scenario. 0 on success; -1 with a message in err (refused
 * setting, log write error). */
int sim_run(const sim_options *opt, sim_result *res, char *err, size_t err_len);

/* hal_sim.c: the firmware as the stepper's commands hook. sim_firmware_start
 * resets the HAL and the firmware and commissions it (commission.h); 0 or -1
 * with the refusal in err. sim_firmware_commands hands the tick's counts and
 * time (k * 10 ms) to the HAL, runs leveler_app_tick() and reads the outputs. */
int sim_firmware_start(const plant_config *cfg, int algorithm, char *err, size_t err_len);
void sim_firmware_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT]);
/* The coil `commission` written 1 through the register map, as a SCADA would; 0 or -1 with the refusal. */
int sim_firmware_commission(char *err, size_t err_len);

/* A schedule's register writes (mode, manual requests; stepper.h), made the
 * way a SCADA makes them: through the firmware's register map
 * (leveler_regs_write, validated all-or-nothing), before the firmware's tick
 * each row is due at (sim_schedule_due, the loads' rule).
 * Within a row the manual requests go first, then the mode. Pass it as
 * sim_firmware_commands' user (NULL: no writes). A refused write stops the
 * writes and leaves the reason in failed / err; the caller checks after each
 * tick. */
typedef struct {
    const sim_load_step *steps;
    size_t count;
    size_t next;   /* first row not yet written */
    int failed;
    char err[200];
} sim_schedule_writer;

/* The writer's rows due at t_s (the rule above), each in
 * sim_schedule_write_order; sim_firmware_commands calls it before each tick. */
void sim_schedule_write_due(sim_schedule_writer *w, double t_s);

#endif /* LEVELER_SIMLOOP_H */
