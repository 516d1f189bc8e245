/*
 * engine_run (engine.h): one run per parameter set of a request, either
 * replaying logged actuator commands open loop or with the unchanged firmware
 * in the loop (hal_sim.c), on the simulator's one stepper (stepper.h).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "engine_internal.h"
#include "engine_writes.h"
#include "simloop.h"

/* Hooks: replayed commands, the run's own loads (the plant: sim_fx_plant). */
typedef struct {
    const int32_t *commands;
    const double *p1_track;
    const double *p2_track;
    const plant_fx *f;
} replay_ctx;

static void replay_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT])
{
    const replay_ctx *r = user;
    const int32_t *c = r->commands + 4 * s->k;
    memset(out, 0, HAL_OUT_COUNT * sizeof out[0]);
    out[HAL_OUT_COMPRESSOR] = c[0] != 0;
    if (r->p1_track && isfinite(r->p1_track[s->k]))
        out[HAL_OUT_COMPRESSOR] = r->f->pl.x[PLANT_X_P_PIPE] < r->p1_track[s->k];
    out[HAL_OUT_SPRING_VALVE] = c[1] != 0;
    out[HAL_OUT_VENT_VALVE] = c[2] != 0;
    out[HAL_OUT_ACC_VALVE] = c[3] != 0;
    if (r->p2_track && isfinite(r->p2_track[s->k]))
        out[HAL_OUT_SPRING_VALVE] = out[HAL_OUT_VENT_VALVE] = r->f->pl.x[PLANT_X_P_SPRING] > r->p2_track[s->k];
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

static int check_request(const engine_request *rq, char *err, int err_len)
{
    bool closed = rq->commands == NULL;
    if (rq->n < 1 || rq->n_sets < 1) {
        snprintf(err, (size_t)err_len, "request: %d samples, %d parameter sets (at least 1 each)", rq->n,
                 rq->n_sets);
        return -1;
    }
    for (int i = 1; i < rq->n; i++) {
        double dt = rq->t_s[i] - rq->t_s[i - 1];
        if (!(dt > 0.0)) {
            snprintf(err, (size_t)err_len, "t_s[%d]: time not increasing", i);
            return -1;
        }
        if (closed && fabs(dt - SIM_TICK_S) > 1e-6) {
            snprintf(err, (size_t)err_len, "t_s[%d]: closed loop needs the 10 ms tick grid", i);
            return -1;
        }
    }
    if (!closed && rq->n_writes > 0) {
        snprintf(err, (size_t)err_len, "request: register writes need the firmware in the loop (commands NULL)");
        return -1;
    }
    return 0;
}

/* The models of fx_kinds (0: none) in the request's table; -1 with a message. */
static int find_models(const engine_request *rq, const plant_fx_model *models[PLANT_FX_MAX_MODELS], char *err,
                       int err_len)
{
    engine_catalogue c;
    if (engine_catalogue_find(rq->catalogue, &c) != 0) {
        snprintf(err, (size_t)err_len, "request: effect table %d is not in this build of the engine", rq->catalogue);
        return -1;
    }
    for (int i = 0; i < PLANT_FX_MAX_MODELS; i++) {
        int kind = rq->fx_kinds ? rq->fx_kinds[i] : 0;
        models[i] = plant_fx_find(c.table, c.count, kind);
        if (kind != 0 && !models[i]) {
            snprintf(err, (size_t)err_len, "effect %d: unknown", kind);
            return -1;
        }
        if (models[i] && !rq->fx_params) {
            snprintf(err, (size_t)err_len, "effect %s: no parameters (fx_params NULL)", models[i]->name);
            return -1;
        }
    }
    return 0;
}

static void open_failed(int rc, const plant_fx_model *const m[PLANT_FX_MAX_MODELS], char *err, int err_len)
{
    const char *a = m[0] ? m[0]->name : "", *sep = m[0] && m[1] ? "/" : "", *b = m[1] ? m[1]->name : "";
    if (rc == PLANT_FX_PAIR_REFUSED)
        snprintf(err, (size_t)err_len,
                 "effects %s%s%s and the config's: cannot run together (one effect twice, more than %d, "
                 "or a shared state)", a, sep, b, PLANT_FX_MAX_MODELS);
    else
        snprintf(err, (size_t)err_len, "effect %s%s%s: a parameter is outside its range", a, sep, b);
}

/* The plant of one set, at the request's initial state. */
static int open_plant(engine *e, const engine_request *rq, const plant_fx_model *const models[PLANT_FX_MAX_MODELS],
                      const double *params, char *err, int err_len)
{
    plant_params p = initial_params(&e->cfg, rq->init, rq->load_n[0]);
    int rc = sim_plant_open(&e->run_fx, &e->cfg, &p, PLANT_FX_MAX_MODELS, models, params);
    if (rc != 0) {
        open_failed(rc, models, err, err_len);
        return -1;
    }
    if (rq->init && isfinite(rq->init[3]) && p.acc_type != PLANT_ACC_NONE)
        e->run_fx.pl.x[PLANT_X_P_ACC] = rq->init[3]; /* the accumulator's volume follows from P3 */
    return 0;
}

/* The stepper's loop: decide, record, advance. */
static int step_all(sim_stepper *st, const sim_schedule_writer *writer, int n, double *out, int32_t *act, char *err,
                    int err_len)
{
    for (int i = 0; i < n; i++) {
        sim_stepper_decide(st);
        if (writer->failed) {
            snprintf(err, (size_t)err_len, "%s", writer->err);
            return -1;
        }
        memcpy(&out[4 * i], st->sensed, sizeof st->sensed);
        if (act) {
            act[4 * i] = st->in.compressor;
            act[4 * i + 1] = st->in.spring_valve;
            act[4 * i + 2] = st->in.vent_valve;
            act[4 * i + 3] = st->in.acc_valve;
        }
        if (i + 1 < n)
            sim_stepper_advance(st);
    }
    return 0;
}

/*
 * One set. From the config's own initial state (a rig already running, as
 * leveler-sim starts): the first tick under its [initial] actuators, the
 * firmware's first decision at its end. From a given state (init: a log's
 * first state, at rest) the firmware decides from the first tick. The
 * firmware reads the config's sensor noise, seeded (a rig's chatter).
 */
static int run_set(engine *e, const engine_request *rq, const plant_fx_model *const models[PLANT_FX_MAX_MODELS],
                   const double *params, const sim_schedule_writer *rows, double *out, int32_t *act, char *err,
                   int err_len)
{
    bool closed = rq->commands == NULL;
    if (open_plant(e, rq, models, params, err, err_len) != 0)
        return -1;
    if (closed && sim_firmware_start(&e->cfg, e->cfg.algorithm, err, (size_t)err_len) != 0)
        return -1;
    plant_rng rng;
    plant_rng_seed(&rng, e->cfg.sensors.noise_seed);
    replay_ctx replay = {rq->commands, rq->p1_track, rq->p2_track, &e->run_fx};
    sim_schedule_writer writer = *rows;
    sim_stepper st = {.cfg = &e->cfg, .plant = &e->run_fx, .ops = &sim_fx_plant,
                      .commands = closed ? sim_firmware_commands : replay_commands,
                      .commands_user = closed ? (void *)&writer : (void *)&replay, .load = logged_load,
                      .load_user = (void *)rq->load_n, .rng = &rng,
                      .initial_outputs = closed && !rq->init, .times_s = rq->t_s, .n_times = (size_t)rq->n};
    sim_stepper_start(&st);
    return step_all(&st, &writer, rq->n, out, act, err, err_len);
}

int engine_run(engine *e, const engine_request *rq, engine_result *res, char *err, int err_len)
{
    const plant_fx_model *models[PLANT_FX_MAX_MODELS];
    if (check_request(rq, err, err_len) != 0 || find_models(rq, models, err, err_len) != 0)
        return -1;
    sim_load_step *rows = NULL;
    if (engine_writes_take(rq->n_writes, rq->write_t_s, NULL, rq->write_values, &rows, err, err_len) != 0)
        return -1;
    const size_t per_set = (size_t)rq->n * 4, per_params = PLANT_FX_MAX_MODELS * PLANT_FX_MAX_PARAMS;
    int rc = 0;
    for (int k = 0; k < rq->n_sets && rc == 0; k++) {
        sim_schedule_writer w = {.steps = rows, .count = (size_t)rq->n_writes};
        const double *params = rq->fx_params ? rq->fx_params + (size_t)k * per_params : NULL;
        rc = run_set(e, rq, models, params, &w, res->sensed + (size_t)k * per_set,
                     res->actuators ? res->actuators + (size_t)k * per_set : NULL, err, err_len);
        if (rc != 0 && rq->n_sets > 1) {
            char why[256];
            snprintf(why, sizeof why, "%s", err);
            snprintf(err, (size_t)err_len, "parameter set %d: %s", k, why);
        }
    }
    free(rows);
    return rc;
}
