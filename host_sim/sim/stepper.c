/* The tick loop of a simulated run (stepper.h). */
#include "stepper.h"

#include <math.h>
#include <string.h>

static void nominal_set_inputs(void *pl, const plant_inputs *in) { plant_set_inputs(pl, in); }
static void nominal_advance(void *pl, double dt_s, int substeps) { plant_advance(pl, dt_s, substeps); }
static void nominal_sensed(const void *pl, double out[4]) { plant_sensed(pl, out); }

const sim_plant_ops sim_nominal_plant = {nominal_set_inputs, nominal_advance, nominal_sensed};

static void fx_set_inputs(void *f, const plant_inputs *in) { plant_fx_set_inputs(f, in); }
static void fx_advance(void *f, double dt_s, int substeps) { plant_fx_advance(f, dt_s, substeps); }
static void fx_sensed(const void *f, double out[4]) { plant_fx_sensed(f, out); }

const sim_plant_ops sim_fx_plant = {fx_set_inputs, fx_advance, fx_sensed};

int sim_plant_open(plant_fx *f, const plant_config *cfg, const plant_params *p, int n_more,
                   const plant_fx_model *const *more, const double *more_params)
{
    const plant_fx_model *models[2 * PLANT_FX_MAX_MODELS];
    double params[2 * PLANT_FX_MAX_MODELS][PLANT_FX_MAX_PARAMS];
    plant_config_effect_models(cfg, models);
    memcpy(params, cfg->effect_params, sizeof cfg->effect_params);
    int n = PLANT_FX_MAX_MODELS;
    for (int i = 0; i < n_more && i < PLANT_FX_MAX_MODELS; i++, n++) {
        models[n] = more[i];
        memcpy(params[n], more_params + i * PLANT_FX_MAX_PARAMS, sizeof params[n]);
    }
    /* the config's effects first, then the requested ones, empty slots skipped */
    int used = 0;
    for (int i = 0; i < n; i++)
        if (models[i]) {
            models[used] = models[i];
            memmove(params[used], params[i], sizeof params[used]);
            used++;
        }
    if (used > PLANT_FX_MAX_MODELS)
        return PLANT_FX_PAIR_REFUSED;
    return plant_fx_init_models(f, p ? p : &cfg->plant, used, models, &params[0][0]);
}

void sim_initial_outputs(const plant_config *cfg, bool out[HAL_OUT_COUNT])
{
    memset(out, 0, HAL_OUT_COUNT * sizeof out[0]);
    out[HAL_OUT_COMPRESSOR] = cfg->init_compressor != 0;
    out[HAL_OUT_SPRING_VALVE] = cfg->init_spring_valve != 0;
    out[HAL_OUT_VENT_VALVE] = cfg->init_vent_valve != 0;
    out[HAL_OUT_ACC_VALVE] = cfg->init_acc_valve != 0;
}

double sim_schedule_load_at(sim_schedule_cursor *c, double t_s)
{
    while (c->i + 1 < c->count && sim_schedule_due(c->steps[c->i + 1].t_s, t_s))
        c->i++;
    return c->steps[c->i].load_n;
}

double sim_load_from_schedule(sim_stepper *s, void *user, double t_s)
{
    (void)s;
    return sim_schedule_load_at(user, t_s);
}

static double time_of(const sim_stepper *s, size_t k)
{
    return s->times_s ? s->times_s[k] : (double)k * SIM_TICK_S;
}

void sim_stepper_start(sim_stepper *s)
{
    s->k = 0;
    s->t_s_now = time_of(s, 0);
    memset(s->out, 0, sizeof s->out);
}

void sim_stepper_counts(sim_stepper *s, uint16_t counts[4])
{
    plant_counts(&s->cfg->sensors, s->sensed, s->rng, counts);
}

void sim_stepper_decide(sim_stepper *s)
{
    s->ops->sensed(s->plant, s->sensed);
    if (s->k == 0 && s->initial_outputs)
        sim_initial_outputs(s->cfg, s->out);
    else
        s->commands(s, s->commands_user, s->out);
    s->in.load_n = s->load(s, s->load_user, s->t_s_now);
    s->in.compressor = s->out[HAL_OUT_COMPRESSOR];
    s->in.spring_valve = s->out[HAL_OUT_SPRING_VALVE];
    s->in.vent_valve = s->out[HAL_OUT_VENT_VALVE];
    s->in.acc_valve = s->out[HAL_OUT_ACC_VALVE];
    s->ops->set_inputs(s->plant, &s->in);
}

int sim_stepper_advance(sim_stepper *s)
{
    double next = time_of(s, s->k + 1);
    /* on the tick grid the step is exactly 10 ms (not a difference of two times) */
    double dt = s->times_s ? next - s->t_s_now : SIM_TICK_S;
    if (!(dt > 0.0))
        return -1;
    /* [solver] substeps_per_tick RK4 steps per 10 ms, at least one */
    long sub = lround(dt / SIM_TICK_S * s->cfg->substeps_per_tick);
    s->ops->advance(s->plant, dt, sub < 1 ? 1 : (int)sub);
    s->k++;
    s->t_s_now = next;
    return 0;
}
