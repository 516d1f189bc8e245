/*
 * The blind test's truth variants (truth.json): for each candidate effect a
 * DIFFERENT functional form, so that the diagnosis, which fits the candidate
 * (host_sim/plant/effects_candidates.c), never fits the truth exactly. They
 * generate the blind test's "real" logs and are not part of the product:
 * only libleveler_truth.so (this folder) links them.
 *   thermal         gas-wall and wall-ambient time constants (wall temperature state)
 *   area            A_nom(y) times a piecewise-linear table over 5 heights
 *   friction        LuGre (bristle state z)
 *   valve_dynamics  first-order opening fractions, Cd falling with pressure ratio
 *   line_delay      a lumped tube volume with a linear (laminar) conductance, the pipe split in two
 *   leak            laminar capillary leak, m = K (P2^2 - Pa^2)
 *   sensor_lag      two cascaded lags on pressure, gain error, offsets
 */
#include "effects.h"

#include <math.h>

static double sgn(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

/* ---- thermal: the wall has a temperature of its own ---- */
static void thermal_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    if (!(q[0] > 0.0))
        return;
    double tw = x[PLANT_NX + PLANT_FX_XE_TW], t2 = x[PLANT_NX + PLANT_FX_XE_T2];
    plant_fx_thermal_balance(f, x, dx, fl, q[0], tw);
    /* wall: heated by the gas (capacity ratio q2), cooled by the room (tau q1) */
    dx[PLANT_NX + PLANT_FX_XE_TW] = (t2 - tw) / (q[0] * q[2]) + (f->pl.p.temperature_k - tw) / q[1];
}
const plant_fx_ops truth_thermal_ops = {.stage = PLANT_FX_STAGE_GAS, .uses = PLANT_FX_USES_GAS_T | PLANT_FX_USES_WALL_T,
                                        .rhs = thermal_rhs};

/* ---- area: piecewise linear over knots y_ref + (-2..2) * 20 mm, flat outside ---- */
static void area_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double u = (x[PLANT_X_Y] - f->y_ref_m) / 0.020 + 2.0, s;
    if (u <= 0.0) {
        s = 1.0 + q[0];
    } else if (u >= 4.0) {
        s = 1.0 + q[4];
    } else {
        int k = (int)u;
        double w = u - k;
        s = 1.0 + (1.0 - w) * q[k] + w * q[k + 1];
    }
    plant_fx_scale_area(f, x, dx, s);
}
const plant_fx_ops truth_area_ops = {.stage = PLANT_FX_STAGE_GEOMETRY, .rhs = area_rhs};

/* ---- friction: LuGre ---- */

/* Stribeck curve g(v) = Fc + Fs exp(-(v/vs)^2), never below 1 mN. */
static double lugre_g(const double *q, double v)
{
    return fmax(q[0] + q[1] * exp(-(v / q[2]) * (v / q[2])), 1e-3);
}

/* dz/dt = v - s0 |v| z / g(v), F = s0 z + s1 dz/dt (opposes motion). The
 * bristle state is stiff at speed (s0 |v| / g up to thousands per second), so
 * it is held within an RK4 step and advanced exactly after it. */
static void friction_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    const double vel = x[PLANT_X_VEL];
    double g = lugre_g(q, vel);
    double z = x[PLANT_NX + PLANT_FX_XE_Z];
    double dz = vel - q[3] * fabs(vel) * z / g;
    double ff = -(q[3] * z + q[4] * dz);
    dx[PLANT_X_VEL] += ff / f->pl.mass_kg;
}

/* Exact bristle update over h at the step's mean velocity v:
 * z -> z_ss + (z - z_ss) exp(-s0 |v| h / g), z_ss = g sign(v) / s0. Unconditionally stable. */
static void friction_after_step(plant_fx *f, const double *q, double *x, double vel0, double h)
{
    double v = 0.5 * (vel0 + x[PLANT_X_VEL]), z = f->xe[PLANT_FX_XE_Z];
    if (v != 0.0) {
        double g = lugre_g(q, v);
        double z_ss = g * sgn(v) / q[3];
        z = z_ss + (z - z_ss) * exp(-q[3] * fabs(v) * h / g);
    }
    x[PLANT_NX + PLANT_FX_XE_Z] = z;
}
const plant_fx_ops truth_friction_ops = {.stage = PLANT_FX_STAGE_FORCE, .uses = PLANT_FX_USES_Z, .rhs = friction_rhs,
                                         .after_step = friction_after_step};

/* ---- valve_dynamics: opening fractions u follow the command with first-order
 * lags; Cd falls linearly with (1 - Pd/Pu) (slope q2); outflows scaled by q3 ---- */
static void valve_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    const plant_params *p = &pl->p;
    const double *xu = x + PLANT_NX + PLANT_FX_XE_VALVE;
    const double p1 = x[PLANT_X_P_PIPE], p2 = x[PLANT_X_P_SPRING], pa = p->ambient_pa;
    for (int i = 0; i < 2; i++) {
        double target = f->cmd[i] ? 1.0 : 0.0;
        dx[PLANT_NX + PLANT_FX_XE_VALVE + i] = (target - xu[i]) / (target > xu[i] ? q[0] : q[1]);
    }
    double us = fmin(1.0, fmax(0.0, xu[0])), uv = fmin(1.0, fmax(0.0, xu[1]));
    double a = pl->spring_valve_area_m2, av = p->vent_valve_cd * pl->vent_valve_area_m2;
    double cd_scale = 1.0 - q[2] * (1.0 - fmin(p1, p2) / fmax(p1, p2));
    double m_s = us * cd_scale *
                 plant_fx_two_way(pl, p->spring_valve_cd_in * a, p->spring_valve_cd_out * a * q[3], p1, p2);
    double cdv = 1.0 - q[2] * (1.0 - fmin(pa, p1) / fmax(pa, p1));
    double m_v = uv * cdv * plant_fx_two_way(pl, av * q[3], av, p1, pa);
    plant_fx_replace_flows(pl, x, dx, fl, fl->compressor, m_s, m_v);
}
const plant_fx_ops truth_valve_dynamics_ops = {.stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_VALVE_X,
                                               .rhs = valve_rhs};

/* ---- line_delay: compressor -> tube volume q0 -> laminar conductance q1 -> junction;
 * a share q2 of the pipe's own volume sits on the tube's side (the pipe split in two) ---- */
static void line_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[PLANT_FX_XE_AUX] = f->pl.p.init_p_pipe_pa; /* tube pressure */
}

static void line_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    double m_line = q[1] * (x[PLANT_NX + PLANT_FX_XE_AUX] - x[PLANT_X_P_PIPE]);
    double v1 = pl->p.pipe_volume_m3;
    dx[PLANT_NX + PLANT_FX_XE_AUX] = pl->zn * pl->rt * (fl->compressor - m_line) / (q[0] + q[2] * v1);
    plant_fx_replace_flows(pl, x, dx, fl, m_line, fl->spring_valve, fl->vent_valve);
    dx[PLANT_X_P_PIPE] /= 1.0 - q[2];
}
const plant_fx_ops truth_line_delay_ops = {.stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX, .init = line_init,
                                           .rhs = line_rhs};

/* ---- leak: laminar capillary ---- */
static void leak_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    const plant *pl = &f->pl;
    double p2 = x[PLANT_X_P_SPRING], pa = pl->p.ambient_pa;
    double m_leak = p2 > pa ? q[0] * (p2 * p2 - pa * pa) : 0.0;
    dx[PLANT_X_P_SPRING] -= pl->zn * pl->rt * m_leak / x[PLANT_X_V2];
}
const plant_fx_ops truth_leak_ops = {.stage = PLANT_FX_STAGE_FLOW, .rhs = leak_rhs};

/* ---- sensor_lag: two cascaded lags on pressure, gain error, offsets ---- */
static void sensor_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    if (first)
        return;
    f->sens[0][0] = plant_fx_lag(f->sens[0][0], raw[0], q[2], dt_s);
    for (int c = 1; c < 4; c++) {
        f->sens[c][0] = plant_fx_lag(f->sens[c][0], raw[c], q[0], dt_s);
        f->sens[c][1] = plant_fx_lag(f->sens[c][1], f->sens[c][0], q[1], dt_s);
    }
}

static void sensor_sensed(const plant_fx *f, const double *q, double out[4])
{
    const double pa = f->pl.p.ambient_pa;
    out[0] = f->sens[0][0] + q[5];
    for (int c = 1; c < 4; c++)
        out[c] = pa + (f->sens[c][1] - pa) * (1.0 + q[4]);
    out[1] += q[3];
}
const plant_fx_ops truth_sensor_lag_ops = {.stage = PLANT_FX_STAGE_SENSOR, .uses = PLANT_FX_USES_SENS,
                                           .after_tick = sensor_after_tick, .sensed = sensor_sensed};
