/*
 * The engine of unmodelled effects (effects.h): a plant plus extra states,
 * stepped by the plant's one RK4 step, with up to two effect models' corrections;
 * and the building blocks the candidate and truth models share.
 */
#include "effects.h"

#include <math.h>
#include <string.h>

const plant_fx_model *plant_fx_find(const plant_fx_model *table, int count, int id)
{
    for (int i = 0; i < count; i++)
        if (table[i].id == id)
            return &table[i];
    return NULL;
}

int plant_fx_init(plant_fx *f, const plant_params *p, const plant_fx_model *model, const double *params)
{
    return plant_fx_init_models(f, p, 1, &model, params);
}

/* Checks the models and places them in stage order; the number placed, or an error. */
static int place_models(plant_fx *f, int n, const plant_fx_model *const *models, const double *params)
{
    static const double nominal[PLANT_FX_MAX_PARAMS];
    unsigned used = 0;
    for (int i = 0; i < n; i++) {
        const plant_fx_model *m = models[i];
        const double *q = params ? params + i * PLANT_FX_MAX_PARAMS : nominal;
        if (!m)
            continue;
        if (f->nmodels == PLANT_FX_MAX_MODELS || (used & m->ops->uses) != 0)
            return PLANT_FX_PAIR_REFUSED;
        for (int j = 0; j < f->nmodels; j++)
            if (f->model[j]->id == m->id)
                return PLANT_FX_PAIR_REFUSED;
        for (int k = 0; k < m->nparams; k++)
            if (!(q[k] >= m->lo[k] && q[k] <= m->hi[k]))
                return -1;
        used |= m->ops->uses;
        int at = f->nmodels++; /* insertion by stage, stable */
        while (at > 0 && f->model[at - 1]->ops->stage > m->ops->stage) {
            f->model[at] = f->model[at - 1];
            memcpy(f->q[at], f->q[at - 1], sizeof f->q[at]);
            at--;
        }
        f->model[at] = m;
        memcpy(f->q[at], q, sizeof f->q[at]);
    }
    return 0;
}

int plant_fx_init_models(plant_fx *f, const plant_params *p, int n, const plant_fx_model *const *models,
                         const double *params)
{
    memset(f, 0, sizeof *f);
    plant_init(&f->pl, p);
    int rc = place_models(f, n, models, params);
    if (rc != 0)
        return rc;
    f->y_ref_m = p->init_height_m;
    f->xe[PLANT_FX_XE_T2] = f->xe[PLANT_FX_XE_T1] = f->xe[PLANT_FX_XE_TW] = p->temperature_k;
    f->pending_s[0] = f->pending_s[1] = -1.0;
    f->open_frac[0] = f->open_frac[1] = 1.0; /* open when open, unless a valve model says less */
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->init)
            f->model[i]->ops->init(f, f->q[i]);
    return 0;
}

void plant_fx_set_inputs(plant_fx *f, const plant_inputs *in)
{
    plant_inputs eff = *in;
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->inputs)
            f->model[i]->ops->inputs(f, f->q[i], &eff);
    f->cmd[0] = in->spring_valve; /* the commanded states (valve models) */
    f->cmd[1] = in->vent_valve;
    plant_set_inputs(&f->pl, &eff);
}

static void fx_rhs(const void *ctx, const double *x, double *dx)
{
    const plant_fx *f = ctx;
    plant_flows fl;
    plant_derivatives(&f->pl, x, dx, &fl);
    for (int i = 0; i < PLANT_FX_NX; i++)
        dx[PLANT_NX + i] = 0.0;
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->rhs)
            f->model[i]->ops->rhs(f, f->q[i], x, dx, &fl);
}

/* The plant's RK4 step (plant_rk4_step) over the plant and the extra states. */
static void rk4_step(plant_fx *f, double h)
{
    enum { N = PLANT_NX + PLANT_FX_NX };
    plant *pl = &f->pl;
    double vel = pl->x[PLANT_X_VEL];
    double x[N];
    memcpy(x, pl->x, sizeof pl->x);
    memcpy(x + PLANT_NX, f->xe, sizeof f->xe);
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->before_step)
            f->model[i]->ops->before_step(f, f->q[i], x, h);
    plant_rk4_step(pl, x, N, fx_rhs, f, h);
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->after_step)
            f->model[i]->ops->after_step(f, f->q[i], x, vel, h);
    memcpy(pl->x, x, sizeof pl->x);
    memcpy(f->xe, x + PLANT_NX, sizeof f->xe);
}

void plant_fx_advance(plant_fx *f, double dt_s, int substeps)
{
    f->tick_s = dt_s; /* the valve models place a switch inside the next tick by it */
    if (f->nmodels == 0) {
        plant_advance(&f->pl, dt_s, substeps);
    } else {
        int n = substeps; /* the most any model needs */
        for (int i = 0; i < f->nmodels; i++)
            if (f->model[i]->ops->substeps) {
                int need = f->model[i]->ops->substeps(f, f->q[i], dt_s, substeps);
                n = need > n ? need : n;
            }
        if (n < 1)
            n = 1;
        f->substeps = n;
        for (int i = 0; i < n; i++) {
            f->substep = i;
            rk4_step(f, dt_s / n);
        }
    }
    /* the transducer filters start from the first tick's values; they filter
     * what the transducers see where they sit (the models before the sensors') */
    double raw[4];
    plant_sensed(&f->pl, raw);
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->sensed && f->model[i]->ops->stage < PLANT_FX_STAGE_SENSOR)
            f->model[i]->ops->sensed(f, f->q[i], raw);
    bool first = !f->sens_ready;
    if (first) {
        for (int c = 0; c < 4; c++)
            f->sens[c][0] = f->sens[c][1] = raw[c];
        f->sens_ready = true;
    }
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->after_tick)
            f->model[i]->ops->after_tick(f, f->q[i], raw, dt_s, first);
}

void plant_fx_sensed(const plant_fx *f, double out[4])
{
    plant_sensed(&f->pl, out);
    for (int i = 0; i < f->nmodels; i++)
        if (f->model[i]->ops->sensed && f->sens_ready)
            f->model[i]->ops->sensed(f, f->q[i], out);
}

/* ---- building blocks ---- */

double plant_fx_two_way(const plant *pl, double cda_fwd, double cda_back, double pa, double pb)
{
    return pa > pb ? plant_orifice_flow(pl, cda_fwd, pa, pb) : -plant_orifice_flow(pl, cda_back, pb, pa);
}

void plant_fx_replace_flows(const plant *pl, const double *x, double *dx, plant_flows *fl, double m_c,
                            double m_s, double m_v)
{
    const double zn = pl->zn, rt = pl->rt, v1 = pl->p.pipe_volume_m3, v2 = x[PLANT_X_V2];
    dx[PLANT_X_P_PIPE] += zn * rt * ((m_c - fl->compressor) - (m_s - fl->spring_valve) - (m_v - fl->vent_valve)) / v1;
    dx[PLANT_X_P_SPRING] += zn * rt * (m_s - fl->spring_valve) / v2;
    fl->compressor = m_c;
    fl->spring_valve = m_s;
    fl->vent_valve = m_v;
}

void plant_fx_thermal_balance(const plant_fx *f, const double *x, double *dx, const plant_flows *fl, double tau,
                              double tw)
{
    plant_fx_thermal_balance_in(f, x, dx, fl, tau, tw, f->pl.p.temperature_k);
}

void plant_fx_thermal_balance_in(const plant_fx *f, const double *x, double *dx, const plant_flows *fl, double tau,
                                 double tw, double t_in)
{
    /* Energy balance of the gas in spring and pipe (ideal gas, U = P V/(k-1)):
     *   dP/dt = Z k (R T_src m - P dV/dt)/V + P (Tw - T)/(T tau)
     *   dT/dt = T (dP/P + dV/V) - m R T^2/(P V)
     * in place of the fixed exponent n. Inflow from the compressor at t_in. */
    const plant_params *p = &f->pl.p;
    const double *xe = x + PLANT_NX;
    double *dxe = dx + PLANT_NX;
    const double p1 = x[PLANT_X_P_PIPE], p2 = x[PLANT_X_P_SPRING], v2 = x[PLANT_X_V2], v1 = p->pipe_volume_m3;
    double k = p->heat_ratio_k, z = p->compressibility, r = p->gas_constant_j_per_kg_k;
    double t2 = xe[PLANT_FX_XE_T2], t1 = xe[PLANT_FX_XE_T1];
    double m_s = fl->spring_valve, m_v = fl->vent_valve, m_c = fl->compressor, m_a = fl->acc_valve;
    double dv2 = dx[PLANT_X_V2];
    double t_s_src = m_s > 0.0 ? t1 : t2; /* gas crossing the spring valve */
    double d_p2 = z * k * (r * t_s_src * m_s - p2 * dv2) / v2 + p2 * (tw - t2) / (t2 * tau);
    double d_t2 = t2 * (d_p2 / p2 + dv2 / v2) - m_s * r * t2 * t2 / (p2 * v2);
    /* the accumulator's flow (its gas stays polytropic) counted at the pipe's temperature */
    double d_p1 = z * k * r * (t_in * m_c - t_s_src * m_s - t1 * (m_v + m_a)) / v1 +
                  p1 * (p->temperature_k - t1) / (t1 * tau);
    double d_t1 = t1 * d_p1 / p1 - (m_c - m_s - m_v - m_a) * r * t1 * t1 / (p1 * v1);
    dx[PLANT_X_P_SPRING] = d_p2;
    dx[PLANT_X_P_PIPE] = d_p1;
    dxe[PLANT_FX_XE_T2] = d_t2;
    dxe[PLANT_FX_XE_T1] = d_t1;
}

void plant_fx_scale_area(const plant_fx *f, const double *x, double *dx, double s)
{
    const plant *pl = &f->pl;
    double dv2_nom = dx[PLANT_X_V2];
    double dv2 = dv2_nom * s;
    dx[PLANT_X_V2] = dv2;
    dx[PLANT_X_P_SPRING] -= pl->zn * x[PLANT_X_P_SPRING] * (dv2 - dv2_nom) / x[PLANT_X_V2];
    double f_press = dx[PLANT_X_VEL] * pl->mass_kg + pl->damping_n_s_per_m * x[PLANT_X_VEL];
    dx[PLANT_X_VEL] += f_press * (s - 1.0) / pl->mass_kg;
}

double plant_fx_lag(double state, double target, double tau, double dt)
{
    return tau > 1e-6 ? state + (target - state) * (1.0 - exp(-dt / tau)) : target;
}
