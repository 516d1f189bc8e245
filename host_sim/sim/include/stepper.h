/*
 * THE tick loop of a simulated run, shared by leveler-sim (simloop.c), the
 * plant server (host_sim/rig/plant_server.c), the diagnosis library
 * (the engine, host_sim/diagnose/engine_run.c) and anything else that steps the plant
 * against a controller.
 *
 * Each tick k at time t_k:
 *   decide   what the transducers report (ops->sensed), the actuators from the
 *            commands hook (firmware in the loop, replayed log, Modbus coils),
 *            except at k = 0 when the config's [initial] actuators are asked for;
 *            the load from the load hook; both become the plant's inputs;
 *   advance  the plant integrates to t_(k+1) under them (ops->advance, RK4 with
 *            [solver] substeps_per_tick per 10 ms).
 * The stepper owns neither the firmware nor a log: hooks bring them in, so the
 * plant server links it without the firmware.
 */
#ifndef LEVELER_SIM_STEPPER_H
#define LEVELER_SIM_STEPPER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "leveler/app.h"
#include "leveler/hal.h"
#include "effects.h"
#include "plant.h"

/* The firmware's tick (leveler/app.h) is the simulator's time step. */
#define SIM_TICK_S (LEVELER_TICK_MS / 1000.0)

/* ---- loads ---- */

/* The register-map entries a schedule row may write (optional columns of a
 * schedule file, named as firmware/regmap/registers.json names them): the
 * operating mode and the manual actuator requests. */
#define SIM_SCHEDULE_REG_COUNT 5
typedef struct {
    const char *name;  /* column name = register name */
    uint8_t table;     /* leveler_table (leveler/regmap.h) */
    uint16_t address;  /* 0-based protocol address */
    uint16_t max;      /* values 0..max */
    int8_t output;     /* the actuator (hal_output) a manual request asks for; -1: not a request */
} sim_schedule_reg;
/* mode, manual_compressor, manual_spring_valve, manual_vent_valve, manual_acc_valve */
extern const sim_schedule_reg sim_schedule_regs[SIM_SCHEDULE_REG_COUNT];
/* The order a row's writes are made in (indices into sim_schedule_regs): the
 * manual requests first, then the mode, so that switching to manual takes the
 * row's requests at once (the simulator's hal_sim.c and leveler-schedule-run). */
extern const uint8_t sim_schedule_write_order[SIM_SCHEDULE_REG_COUNT];

typedef struct {
    double t_s;    /* the load takes effect (and the writes are made) at this time */
    double load_n; /* absolute load */
    uint8_t writes; /* bit j set: sim_schedule_regs[j] is written value[j] at t_s (0 = a load step only) */
    uint16_t value[SIM_SCHEDULE_REG_COUNT];
    int line;      /* the schedule file's line (0: the config's scenario), for messages */
} sim_load_step;

/* The rows of a schedule whose loads lie outside the config's [spring]
 * load_min..load_max (the loads the model was fitted for): 0, or -1 with
 * "file:line: load_n: ..." for the first, and a hint when the loads look
 * like lbf typed as newtons. */
int sim_schedule_check_loads(const plant_config *cfg, const char *path, const sim_load_step *steps, size_t count,
                             char *err, size_t err_len);

/* The config's built-in scenario (base, +step at step_on, removed at step_off,
 * end): out needs room for 4 steps. Returns the count; *end_s = scenario end. */
size_t sim_schedule_from_config(const plant_config *cfg, sim_load_step out[4], double *end_s);

/* A schedule file (CSV t_s,load_n[,mode][,manual_compressor]...; an empty
 * register cell writes nothing; docs/config-format.md). On success *steps is
 * malloc'ed (free it) and the run ends at the last time. -1 with
 * "file:line: field: ..." in err on failure. */
int sim_schedule_load(const char *path, sim_load_step **steps, size_t *count, char *err, size_t err_len);

/* THE rule of a schedule row's time: a row at row_t_s is in force over the
 * tick starting at t_s when it is at or before t_s, with half a tick of slack
 * against rounding (the loads below, the register writes of simloop.h). */
static inline bool sim_schedule_due(double row_t_s, double t_s)
{
    return row_t_s <= t_s + 0.5 * SIM_TICK_S;
}

/* THE scenario-to-load rule: the load over the tick starting at t_s is the
 * last step due (sim_schedule_due). The cursor only moves forward; past the
 * last step the last load holds. */
typedef struct {
    const sim_load_step *steps;
    size_t count;
    size_t i;
} sim_schedule_cursor;
double sim_schedule_load_at(sim_schedule_cursor *c, double t_s);

/* ---- the plant behind the stepper ---- */

typedef struct {
    void (*set_inputs)(void *plant, const plant_inputs *in);
    void (*advance)(void *plant, double dt_s, int substeps);
    /* height m, P2, P1, P3 Pa abs as the transducers report them */
    void (*sensed)(const void *plant, double out[4]);
} sim_plant_ops;

extern const sim_plant_ops sim_nominal_plant; /* plant.h's plant */
extern const sim_plant_ops sim_fx_plant;      /* effects.h's plant_fx */

/* THE plant of a config: f from p (NULL: the config's own parameters) with
 * the config's [effect.NAME] sections switched on, then n_more requested
 * models (NULL entries skipped) with PLANT_FX_MAX_PARAMS values each in
 * more_params. Without effects it steps exactly as the nominal plant. Returns
 * plant_fx_init_models's code (0; -1 a value outside its range;
 * PLANT_FX_PAIR_REFUSED: more than PLANT_FX_MAX_MODELS, or ones that cannot
 * run together). */
int sim_plant_open(plant_fx *f, const plant_config *cfg, const plant_params *p, int n_more,
                   const plant_fx_model *const *more, const double *more_params);

/* ---- the stepper ---- */

typedef struct sim_stepper sim_stepper;

/* Sets out[HAL_OUT_COUNT] for tick k (s->k, s->t_s_now); may call sim_stepper_counts. */
typedef void (*sim_commands_fn)(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT]);
/* The load over tick k starting at t_s. */
typedef double (*sim_load_fn)(sim_stepper *s, void *user, double t_s);

struct sim_stepper {
    const plant_config *cfg;
    void *plant;
    const sim_plant_ops *ops;
    sim_commands_fn commands;
    void *commands_user;
    sim_load_fn load;
    void *load_user;
    plant_rng *rng;          /* sensor noise ([sensors] noise_counts); NULL = none */
    bool initial_outputs;    /* tick 0 runs under the config's [initial] actuators */
    const double *times_s;   /* optional time base t_k (n of them); NULL = k * 10 ms */
    size_t n_times;
    /* the tick in progress */
    size_t k;
    double t_s_now;
    double sensed[4];
    bool out[HAL_OUT_COUNT];
    plant_inputs in;
};

/* The actuators over a run's first tick, before the controller's first
 * decision: the config's [initial] section, indexed by hal_output. */
void sim_initial_outputs(const plant_config *cfg, bool out[HAL_OUT_COUNT]);

/* Tick 0 at t_0; the hooks and plant must be set. */
void sim_stepper_start(sim_stepper *s);
/* Decide tick k: sensed values, actuators, load -> the plant's inputs. */
void sim_stepper_decide(sim_stepper *s);
/* ADC counts of s->sensed (plant_counts with the stepper's noise). */
void sim_stepper_counts(sim_stepper *s, uint16_t counts[4]);
/* Integrate to the next tick (k + 1). -1 if the time base does not increase. */
int sim_stepper_advance(sim_stepper *s);

/* Ready-made load hook over a schedule cursor (user = sim_schedule_cursor *). */
double sim_load_from_schedule(sim_stepper *s, void *user, double t_s);

#endif /* LEVELER_SIM_STEPPER_H */
