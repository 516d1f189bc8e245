/*
 * The engine: the C plant, its effect models and the unchanged firmware in
 * the loop behind one handle, for every Python caller (scripts/leveler/engine.py,
 * the one binding: the diagnosis, the blind test, the PIL harness, the config
 * loader). docs/architecture.md draws this boundary.
 *
 *   engine_open       a config read once (the built-in one for NULL); its
 *                     resolved form as JSON, its effects, its motor balance
 *   engine_run        a request: a replayed log or the firmware in the loop,
 *                     effects from a catalogue, one or many parameter sets;
 *                     results in the caller's buffers
 *   engine_step_*     one 10 ms tick at a time for the PIL harness, the
 *                     emulated image as the controller
 *   engine_schedule_* the simulator's schedule rules, without a plant
 *
 * A handle holds all of its state (no statics), but the firmware in the loop
 * is one per process, as on a board: closed-loop runs and the stepping API
 * are not reentrant across threads. Messages go to err (err_len bytes):
 * "file:line: field: ..." for a config, the request's field otherwise.
 */
#ifndef LEVELER_ENGINE_H
#define LEVELER_ENGINE_H

#include <stdint.h>

#include "effects.h"

/* The ABI of this header; engine.py refuses a library with another. */
#define ENGINE_ABI 7
int engine_abi_version(void);
/* The simulator's tick, s (SIM_TICK_S: the firmware's LEVELER_TICK_MS). */
double engine_tick_s(void);

typedef struct engine engine;

/* engine_open's flags. */
enum {
    /* the config's [effect.NAME] sections at their models' nominal values:
     * the nominal plant step for step, for what is estimated on it */
    ENGINE_EFFECTS_NOMINAL = 1,
};

/* config_path NULL: the built-in thesis 900 lb config. NULL with err. */
engine *engine_open(const char *config_path, int flags, char *err, int err_len);
void engine_close(engine *e);

/* The resolved config as JSON (plant_config_write_json) into buf (NUL-
 * terminated; buf NULL: only the length). The length without the NUL, or -1. */
int engine_config_json(const engine *e, char *buf, int buf_len, char *err, int err_len);
/* The config's own effects: ids[PLANT_FX_MAX_MODELS] (0 = none) and params
 * (PLANT_FX_MAX_PARAMS per id, SI). */
void engine_config_effects(const engine *e, int32_t *ids, double *params);
/* Motor speed rad/s in balance at pipe pressure p1_pa with the compressor on
 * a fraction duty of the time (plant_motor_steady_speed). */
double engine_motor_speed(const engine *e, double p1_pa, double duty);
/* The config's controller algorithm (1..3). */
int engine_algorithm(const engine *e);

/* ---- a run ---- */

/* The effect tables a request may name: the candidates (effects.json), and in
 * the blind test's build of the engine its truth families. */
enum { ENGINE_CANDIDATES = 0, ENGINE_TRUTH = 1, ENGINE_TRUTH2 = 2 };

typedef struct {
    int n;                   /* samples */
    const double *t_s;       /* n times, increasing; closed loop: the 10 ms tick grid */
    const double *load_n;    /* n loads, each over the interval from t_s[i] */
    /* n x 4 (compressor, spring_valve, vent_valve, acc_valve) to replay, or
     * NULL: the firmware in the loop */
    const int32_t *commands;
    /* replay only, may be NULL: where finite, the compressor runs while the
     * plant's P1 is below it instead of as logged (a log whose compressor
     * chatters faster than it samples: the replay regulates as the rig did) */
    const double *p1_track;
    /* replay only, may be NULL: where finite, the spring valve and the vent are
     * open while the plant's P2 is above it and shut below it instead of as
     * logged (a log whose discharge chatters faster than it samples) */
    const double *p2_track;
    /* closed loop only: register writes (mode, manual requests) made through
     * the firmware's register map at write_t_s[i] (increasing), write_values
     * n_writes x SIM_SCHEDULE_REG_COUNT (engine_schedule_column), -1 = none */
    int n_writes;
    const double *write_t_s;
    const int32_t *write_values;
    /* height m, P2, P1, P3 Pa, motor speed rad/s at t_s[0]; NaN = the
     * config's (P3 only with an accumulator). Given (even all NaN), the
     * platform starts at rest and, closed loop, the firmware decides from the
     * first tick; NULL = the config's initial state whole, its velocity and
     * [initial] actuators included (leveler-sim) */
    const double *init;
    int catalogue;           /* ENGINE_CANDIDATES, or a truth family in the blind test's build */
    const int32_t *fx_kinds; /* PLANT_FX_MAX_MODELS ids of that table (0 = none), or NULL */
    int n_sets;              /* parameter sets, one run each (at least 1) */
    /* n_sets x PLANT_FX_MAX_MODELS x PLANT_FX_MAX_PARAMS values (SI) */
    const double *fx_params;
} engine_request;

typedef struct {
    double *sensed;   /* n_sets x n x 4: height, P2, P1, P3 as the transducers report them at t_s[i] */
    int32_t *actuators; /* n_sets x n x 4: the actuators in force from t_s[i]; may be NULL */
} engine_result;

/* 0, or -1 with err (a set's failure names the set). */
int engine_run(engine *e, const engine_request *rq, engine_result *res, char *err, int err_len);

/* ---- one tick at a time (the PIL harness) ---- */

/* The plant at the config's initial state at t = 0 with its scenario's loads
 * and seeded noise. Returns the config's algorithm, or -1 with err. */
int engine_step_open(engine *e, char *err, int err_len);
/* The scenario's end time, s. */
double engine_step_end_s(const engine *e);
/* The four transducers as 12-bit ADC counts now (height, P2, P1, P3). noisy:
 * one draw of the config's seeded noise, as leveler-sim draws one per tick. */
void engine_step_counts(engine *e, int noisy, uint16_t counts[4]);
/* Decides the tick starting now: the image's outputs (compressor, spring,
 * vent, acc; the config's [initial] ones at the first tick) and the scheduled
 * load become the plant's inputs; applied = what the plant got. */
void engine_step_decide(engine *e, const int32_t outputs[4], int32_t applied[4]);
/* t, height m, P2, P1, P3 Pa (NaN without accumulator), load N of the tick decided last. */
void engine_step_state(const engine *e, double out[6]);
/* One 10 ms tick of RK4 under the inputs decided last. */
void engine_step_advance(engine *e);
/* The holding registers after commissioning for this config (algorithm 0 =
 * the config's), as runs a master writes with FC 16: runs[2k] = first
 * address, runs[2k+1] = count; values[address]. The number of runs, or -1. */
int engine_commission_registers(engine *e, int algorithm, uint16_t *runs, int max_runs, uint16_t *values,
                                int max_values, char *err, int err_len);

/* ---- schedules, without a plant ---- */

/* Name of schedule column 2 + j (a register's name), NULL past the last. */
const char *engine_schedule_column(int j);
/* The actuator (hal_output) column 2 + j asks for in manual mode, -1 for none. */
int engine_schedule_column_output(int j);
/* A schedule file by the simulator's one parser: up to cap rows into t_s,
 * load_n, values (cap x SIM_SCHEDULE_REG_COUNT, -1 = no write). The row
 * count, or -1 with "file:line: field: ..." in err. */
int engine_schedule_read(const char *path, int cap, double *t_s, double *load_n, int32_t *values, char *err,
                         int err_len);
/* A schedule's rows applied at the times t_s[i] by the simulator's rules:
 * load_out[i] over the tick from t_s[i]; regs_out (n x SIM_SCHEDULE_REG_COUNT)
 * what each schedule register holds after that tick's writes (the firmware's
 * register map read back). Resets the firmware. 0, or -1 with err. */
int engine_schedule_apply(int rows, const double *row_t_s, const double *row_load_n, const int32_t *values, int n,
                          const double *t_s, double *load_out, int32_t *regs_out, char *err, int err_len);
/* The load over each tick from t_s[i] of a scenario (base, +step from
 * step_on to step_off, end), by the simulator's one rule. */
void engine_scenario_loads(double base_load_n, double step_load_n, double step_on_s, double step_off_s,
                           double end_s, int n, const double *t_s, double *load_n);

/* ---- the effect tables (engine_catalogues.c; the blind test's build links its own) ---- */

typedef struct {
    const plant_fx_model *table;
    int count;
} engine_catalogue;
/* Table which (ENGINE_CANDIDATES ...) into out; -1 when this build has none. */
int engine_catalogue_find(int which, engine_catalogue *out);

#endif /* LEVELER_ENGINE_H */
