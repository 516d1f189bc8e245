/*
 * ctypes entry point of the sim-to-real diagnosis (scripts/leveler/diagnose/cplant.py):
 * one call simulates one whole run of the C plant with up to two effects switched on,
 * either replaying logged actuator commands open loop or with the unchanged
 * firmware in the loop (hal_sim.c), on the simulator's one stepper (stepper.h).
 *
 * Built as a shared library WITHOUT sanitizers (a sanitized .so cannot be
 * dlopen'ed from the venv python; host_sim/diagnose/CMakeLists.txt); the
 * sanitized test build checks the effects through tests/diagnose/test_effects.c.
 */
#define _POSIX_C_SOURCE 200809L /* open_memstream */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "diag.h"
#include "effects.h"
#include "leveler/app.h"
#include "leveler/regmap.h"
#include "plant.h"
#include "simloop.h"

/* Version of this ABI; cplant.py refuses a library with another. */
int diag_abi_version(void) { return 5; }

/* The simulator's tick, s (SIM_TICK_S: the firmware's LEVELER_TICK_MS). */
double diag_tick_s(void) { return SIM_TICK_S; }

/* Loads a config file; 0 or -1 with the loader's file:line message in err. */
int diag_config_check(const char *path, char *err, int err_len)
{
    static plant_config cfg;
    return plant_config_load(path, &cfg, err, (size_t)err_len);
}

/* The resolved config as JSON (plant_config_write_json; path NULL: the
 * built-in one) into buf (buf_len bytes, NUL-terminated; buf NULL: only the
 * length). Returns the length without the NUL, or -1 with err (the loader's
 * file:line message, or a buffer too small). Python's leveler.config reads it. */
int diag_config_json(const char *path, char *buf, int buf_len, char *err, int err_len)
{
    static plant_config cfg;
    if (path)
        if (plant_config_load(path, &cfg, err, (size_t)err_len) != 0)
            return -1;
    if (!path)
        plant_config_defaults(&cfg);
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f || plant_config_write_json(&cfg, f) != 0 || fclose(f) != 0) {
        snprintf(err, (size_t)err_len, "%s: cannot write the config as JSON", path ? path : "(built-in)");
        free(text);
        return -1;
    }
    int rc = (int)len;
    if (buf && (size_t)buf_len <= len) {
        snprintf(err, (size_t)err_len, "config JSON: %zu bytes, buffer %d", len + 1, buf_len);
        rc = -1;
    } else if (buf) {
        memcpy(buf, text, len + 1);
    }
    free(text);
    return rc;
}

/* The config's own effects ([effect.NAME] sections): ids[PLANT_FX_MAX_MODELS]
 * (0 = none) and params (PLANT_FX_MAX_PARAMS per id, SI). 0, or -1 with err. */
int diag_config_effects(const char *path, int32_t *ids, double *params, char *err, int err_len)
{
    static plant_config cfg;
    if (plant_config_load(path, &cfg, err, (size_t)err_len) != 0)
        return -1;
    for (int s = 0; s < PLANT_FX_MAX_MODELS; s++) {
        ids[s] = cfg.effect_id[s];
        memcpy(params + s * PLANT_FX_MAX_PARAMS, cfg.effect_params[s], sizeof cfg.effect_params[s]);
    }
    return 0;
}

/* Motor speed in balance at pipe pressure p1_pa with the compressor on a
 * fraction duty of the time (plant_motor_steady_speed); -1 if the config fails. */
double diag_motor_speed(const char *path, double p1_pa, double duty, char *err, int err_len)
{
    static plant_config cfg;
    if (plant_config_load(path, &cfg, err, (size_t)err_len) != 0)
        return -1.0;
    return plant_motor_steady_speed(&cfg.plant, p1_pa, duty);
}

/* Hooks: replayed commands, the run's own loads (the plant: sim_fx_plant). */
typedef struct {
    const int32_t *commands;
    const double *p1_track;
    const plant_fx *f;
} replay_ctx;

static void replay_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT])
{
    const replay_ctx *r = user;
    const int32_t *c = r->commands + 4 * s->k;
    memset(out, 0, HAL_OUT_COUNT * sizeof out[0]);
    out[HAL_OUT_COMPRESSOR] = c[0] != 0;
    if (r->p1_track && isfinite(r->p1_track[s->k]))
        out[HAL_OUT_COMPRESSOR] = r->f->pl.x[PLANT_X_P1] < r->p1_track[s->k];
    out[HAL_OUT_SPRING_VALVE] = c[1] != 0;
    out[HAL_OUT_VENT_VALVE] = c[2] != 0;
    out[HAL_OUT_ACC_VALVE] = c[3] != 0;
}

static double logged_load(sim_stepper *s, void *user, double t_s)
{
    (void)t_s;
    return ((const double *)user)[s->k];
}

/* The plant's initial state: the config's, or a given one at rest (init);
 * the spring then holds the volume the config implies at the given height
 * under the first load (the config's volume is at its own [initial] height). */
static plant_params initial_params(const plant_config *cfg, const double *init, double load0_n)
{
    plant_params p = cfg->plant;
    if (init) {
        if (isfinite(init[0])) {
            p.spring_volume0_m3 = plant_spring_volume_at(&cfg->plant, load0_n, init[0]);
            p.init_height_m = init[0];
        }
        if (isfinite(init[1]))
            p.init_p_spring_pa = init[1];
        if (isfinite(init[2]))
            p.init_p_pipe_pa = init[2];
        if (isfinite(init[4]))
            p.init_motor_speed_rad_per_s = init[4];
        p.init_velocity_m_per_s = 0.0;
    }
    return p;
}

static int check_time_base(int n, const double *t_s, bool closed, char *err, int err_len)
{
    for (int i = 1; i < n; i++) {
        double dt = t_s[i] - t_s[i - 1];
        if (!(dt > 0.0)) {
            snprintf(err, (size_t)err_len, "t_s[%d]: time not increasing", i);
            return -1;
        }
        if (closed && fabs(dt - SIM_TICK_S) > 1e-6) {
            snprintf(err, (size_t)err_len, "t_s[%d]: closed loop needs the 10 ms tick grid", i);
            return -1;
        }
    }
    return 0;
}

/* ---- a schedule's register writes in closed loop (mode, manual requests) ---- */

#define DIAG_MAX_WRITE_ROWS 1024
static sim_load_step write_rows[DIAG_MAX_WRITE_ROWS];
static size_t write_count;

/* n schedule rows at t_s[i] (strictly increasing) into write_rows: the load
 * load_n[i] (load_n may be NULL: writes only) and values[i *
 * SIM_SCHEDULE_REG_COUNT + j] for sim_schedule_regs[j] (diag_schedule_column),
 * -1 = no write. 0, or -1 with err. */
static int take_rows(int n, const double *t_s, const double *load_n, const int32_t *values, char *err, int err_len)
{
    write_count = 0;
    if (n < 0 || n > DIAG_MAX_WRITE_ROWS) {
        snprintf(err, (size_t)err_len, "schedule writes: %d rows (at most %d)", n, DIAG_MAX_WRITE_ROWS);
        return -1;
    }
    for (int i = 0; i < n; i++) {
        sim_load_step row = {.t_s = t_s[i], .load_n = load_n ? load_n[i] : 0.0};
        for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++) {
            int32_t v = values[i * SIM_SCHEDULE_REG_COUNT + j];
            if (v < -1 || v > sim_schedule_regs[j].max || (i > 0 && !(t_s[i] > t_s[i - 1]))) {
                snprintf(err, (size_t)err_len, "schedule writes row %d: %s = %d at %g s", i,
                         sim_schedule_regs[j].name, (int)v, t_s[i]);
                return -1;
            }
            if (v >= 0) {
                row.writes |= (uint8_t)(1u << j);
                row.value[j] = (uint16_t)v;
            }
        }
        write_rows[i] = row;
    }
    write_count = (size_t)n;
    return 0;
}

/* The writes of the next diag_run (closed loop; one run only, then cleared):
 * n rows as take_rows takes them. The firmware gets them through its register
 * map (simloop.h). 0, or -1 with err. */
int diag_set_schedule_writes(int n, const double *t_s, const int32_t *values, char *err, int err_len)
{
    return take_rows(n, t_s, NULL, values, err, err_len);
}

static sim_schedule_writer take_schedule_writes(void)
{
    sim_schedule_writer w = {.steps = write_rows, .count = write_count};
    write_count = 0;
    return w;
}

/*
 * A schedule's rows (as take_rows) applied at the times t_s[i] by the
 * simulator's own rules, without a plant: load_out[i] the load over the tick
 * from t_s[i] (sim_schedule_load_at); regs_out (n x SIM_SCHEDULE_REG_COUNT)
 * what each schedule register holds in the firmware's register map after
 * that tick's writes (sim_schedule_write_due from the firmware's power-up
 * settings, read back with leveler_regs_read): so the diagnosis asks, and
 * never re-implements, which mode and manual requests are in force when.
 * Resets the firmware (as a closed-loop run does) and drops writes set for
 * the next run (diag_set_schedule_writes). 0, or -1 with err.
 */
int diag_schedule_apply(int rows, const double *row_t_s, const double *row_load_n, const int32_t *values, int n,
                        const double *t_s, double *load_out, int32_t *regs_out, char *err, int err_len)
{
    if (rows < 1) {
        snprintf(err, (size_t)err_len, "schedule: no rows");
        return -1;
    }
    if (take_rows(rows, row_t_s, row_load_n, values, err, err_len) != 0)
        return -1;
    sim_schedule_cursor cursor = {write_rows, write_count, 0};
    sim_schedule_writer writer = take_schedule_writes();
    leveler_app_init();
    for (int i = 0; i < n; i++) {
        load_out[i] = sim_schedule_load_at(&cursor, t_s[i]);
        sim_schedule_write_due(&writer, t_s[i]);
        if (writer.failed) {
            snprintf(err, (size_t)err_len, "%s", writer.err);
            return -1;
        }
        for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++) {
            const sim_schedule_reg *r = &sim_schedule_regs[j];
            uint16_t v = 0;
            if (leveler_regs_read((leveler_table)r->table, r->address, 1, &v) != LEVELER_REG_OK) {
                snprintf(err, (size_t)err_len, "register %s: not readable", r->name);
                return -1;
            }
            regs_out[i * SIM_SCHEDULE_REG_COUNT + j] = v;
        }
    }
    return 0;
}

/* Name of schedule column 2 + j (sim_schedule_regs[j]: a register's name), NULL past the last. */
const char *diag_schedule_column(int j)
{
    return j >= 0 && j < SIM_SCHEDULE_REG_COUNT ? sim_schedule_regs[j].name : NULL;
}

/* The actuator schedule column 2 + j asks for in manual mode (hal_output: the
 * column of cmd_out), -1 for one that is no manual request or past the last. */
int diag_schedule_column_output(int j)
{
    return j >= 0 && j < SIM_SCHEDULE_REG_COUNT ? sim_schedule_regs[j].output : -1;
}

/* A schedule file read by the simulator's one parser (schedule.c): up to cap
 * rows into t_s, load_n and values (cap x SIM_SCHEDULE_REG_COUNT, -1 = no
 * write). The row count, or -1 with "file:line: field: ..." in err. */
int diag_schedule_read(const char *path, int cap, double *t_s, double *load_n, int32_t *values, char *err,
                       int err_len)
{
    sim_load_step *v = NULL;
    size_t n = 0;
    if (sim_schedule_load(path, &v, &n, err, (size_t)err_len) != 0)
        return -1;
    if (n > (size_t)cap) {
        snprintf(err, (size_t)err_len, "%s: %zu rows (at most %d)", path, n, cap);
        free(v);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        t_s[i] = v[i].t_s;
        load_n[i] = v[i].load_n;
        for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++)
            values[i * SIM_SCHEDULE_REG_COUNT + j] = (v[i].writes & (1u << j)) ? v[i].value[j] : -1;
    }
    free(v);
    return (int)n;
}

/*
 * Simulate one run.
 *   config_path      plant config (INI)
 *   n, t_s, load_n   the run's time base and load schedule (load for the interval from t_s[i])
 *   commands         n x 4 (compressor, spring_valve, vent_valve, acc_valve) to replay, or NULL for the
 *                    firmware in the loop (then t_s must be the 10 ms tick grid from 0; the
 *                    register writes set by diag_set_schedule_writes are made during it)
 *   p1_track         replay only, may be NULL: where finite, the compressor runs while the
 *                    plant's P1 is below it instead of as logged (a log whose compressor
 *                    chatters faster than it samples: the replay regulates as the rig did)
 *   fx_kinds, fx_params  PLANT_FX_MAX_MODELS effect ids (effects.json; 0 = none), for each
 *                    PLANT_FX_MAX_PARAMS doubles: up to two effects at once (effects.h)
 *   init             height m, P2, P1, P3 Pa, motor speed rad/s at t_s[0]; NaN = the
 *                    config's (P3 only with an accumulator). Given (even all
 *                    NaN), the platform starts at rest and, closed loop, the firmware
 *                    decides from the first tick; NULL = the config's initial state
 *                    whole, its velocity and [initial] actuators included (leveler-sim)
 *   out              n x 4: height, P2, P1, P3 as the transducers report them at t_s[i]
 *   cmd_out          n x 4: the actuator states in force from t_s[i] (may be NULL)
 * Returns 0, or -1 with a message in err.
 */
int diag_simulate(const char *config_path, int n, const double *t_s, const double *load_n,
                  const int32_t *commands, const double *p1_track, const int32_t *fx_kinds,
                  const double *fx_params, const double *init, double *out, int32_t *cmd_out, char *err, int err_len)
{
    return diag_run(plant_fx_catalogue, plant_fx_catalogue_count, config_path, n, t_s, load_n, commands, p1_track,
                    fx_kinds, fx_params, init, out, cmd_out, err, err_len);
}

/* The models of fx_kinds (0: none); -1 with a message for an unknown id. */
static int find_models(const plant_fx_model *table, int table_count, const int32_t *fx_kinds,
                       const plant_fx_model *models[PLANT_FX_MAX_MODELS], char *err, int err_len)
{
    for (int i = 0; i < PLANT_FX_MAX_MODELS; i++) {
        int kind = fx_kinds ? fx_kinds[i] : 0;
        models[i] = plant_fx_find(table, table_count, kind);
        if (kind != 0 && !models[i]) {
            snprintf(err, (size_t)err_len, "effect %d: unknown", kind);
            return -1;
        }
    }
    return 0;
}

int diag_run(const plant_fx_model *table, int table_count, const char *config_path, int n, const double *t_s,
             const double *load_n, const int32_t *commands, const double *p1_track, const int32_t *fx_kinds,
             const double *fx_params, const double *init, double *out, int32_t *cmd_out, char *err, int err_len)
{
    const plant_fx_model *models[PLANT_FX_MAX_MODELS];
    if (find_models(table, table_count, fx_kinds, models, err, err_len) != 0)
        return -1;
    static plant_config cfg;
    static plant_fx f;
    if (plant_config_load(config_path, &cfg, err, (size_t)err_len) != 0)
        return -1;
    if (n < 1) {
        snprintf(err, (size_t)err_len, "no samples");
        return -1;
    }
    bool closed = commands == NULL;
    if (check_time_base(n, t_s, closed, err, err_len) != 0)
        return -1;
    plant_params p = initial_params(&cfg, init, load_n[0]);
    int rc = sim_plant_open(&f, &cfg, &p, PLANT_FX_MAX_MODELS, models, fx_params);
    if (rc != 0) {
        if (rc == PLANT_FX_PAIR_REFUSED)
            snprintf(err, (size_t)err_len,
                     "effects %s%s%s and the config's: cannot run together (one effect twice, more than %d, "
                     "or a shared state)",
                     models[0] ? models[0]->name : "", models[0] && models[1] ? "/" : "",
                     models[1] ? models[1]->name : "", PLANT_FX_MAX_MODELS);
        else
            snprintf(err, (size_t)err_len, "effect %s%s%s: a parameter is outside its range",
                     models[0] ? models[0]->name : "", models[0] && models[1] ? "/" : "",
                     models[1] ? models[1]->name : "");
        return -1;
    }
    if (init && isfinite(init[3]) && p.acc_type != PLANT_ACC_NONE)
        f.pl.x[PLANT_X_P3] = init[3]; /* the accumulator's volume follows from P3 */
    if (closed && sim_firmware_start(&cfg, cfg.algorithm, err, (size_t)err_len) != 0)
        return -1;
    /* From the config's own initial state (a rig already running, as
     * leveler-sim starts): the first tick under its [initial] actuators, the
     * firmware's first decision at its end. From a given state (init: a log's
     * first state, at rest) the firmware decides from the first tick. The
     * firmware reads the config's sensor noise, seeded (a rig's chatter). */
    static plant_rng rng;
    plant_rng_seed(&rng, cfg.sensors.noise_seed);
    replay_ctx replay = {commands, p1_track, &f};
    sim_schedule_writer writer = take_schedule_writes();
    sim_stepper st = {.cfg = &cfg, .plant = &f, .ops = &sim_fx_plant,
                      .commands = closed ? sim_firmware_commands : replay_commands,
                      .commands_user = closed ? (void *)&writer : (void *)&replay, .load = logged_load,
                      .load_user = (void *)load_n, .rng = &rng,
                      .initial_outputs = closed && !init, .times_s = t_s, .n_times = (size_t)n};
    sim_stepper_start(&st);
    for (int i = 0; i < n; i++) {
        sim_stepper_decide(&st);
        if (writer.failed) {
            snprintf(err, (size_t)err_len, "%s", writer.err);
            return -1;
        }
        memcpy(&out[4 * i], st.sensed, sizeof st.sensed);
        if (cmd_out) {
            cmd_out[4 * i] = st.in.compressor;
            cmd_out[4 * i + 1] = st.in.spring_valve;
            cmd_out[4 * i + 2] = st.in.vent_valve;
            cmd_out[4 * i + 3] = st.in.acc_valve;
        }
        if (i + 1 < n)
            sim_stepper_advance(&st);
    }
    return 0;
}

/* The load over each tick starting at t_s[i] of a scenario (base, +step from
 * step_on to step_off, end), by the simulator's one rule (stepper.h): for
 * runs known only by their event figures (scripts/leveler/diagnose/features.py). */
void diag_scenario_loads(double base_load_n, double step_load_n, double step_on_s, double step_off_s,
                         double end_s, int n, const double *t_s, double *load_n)
{
    plant_config cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.base_load_n = base_load_n;
    cfg.step_load_n = step_load_n;
    cfg.step_on_s = step_on_s;
    cfg.step_off_s = step_off_s;
    cfg.end_s = end_s;
    sim_load_step steps[4];
    double end;
    sim_schedule_cursor c = {steps, sim_schedule_from_config(&cfg, steps, &end), 0};
    for (int i = 0; i < n; i++)
        load_n[i] = sim_schedule_load_at(&c, t_s[i]);
}
