/*
 * The candidate effects the diagnosis fits, one set of functions per effect
 * (effects.h; names, parameters and ranges in effects.json). Parameters in
 * order, SI; "nominal" values give the nominal plant:
 *   thermal         tau_thermal_s (0: fixed polytropic n)
 *   area            A = A_nom (1 + a0 + a1 d + a2 d^2), d = y - y_ref held within +-50 mm:
 *                   a1 rel/m, a2 rel/m^2, a0 relative
 *   friction        Coulomb N, Stribeck N, Stribeck velocity m/s
 *   valve_dynamics  open delay s, close delay s, ISO 6358 b (0 = eq. 8)
 *   line_delay      transport delay s, junction volume change m^3, tube volume behind a laminar
 *                   resistance m^3, that resistance as the tube's time constant s
 *   leak            orifice area m^2 (Cd 1), spring -> ambient
 *   sensor_lag      pressure lag s, height lag s, P2 offset Pa, height offset m
 */
#include "effects.h"

#include <math.h>

static double sgn(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

/* ---- thermal: one gas-to-wall time constant, wall at ambient ---- */
static void thermal_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    if (q[0] > 0.0) /* 0: the fixed polytropic exponent */
        plant_fx_thermal_balance(f, x, dx, fl, q[0], f->pl.p.temperature_k);
}
const plant_fx_ops fx_thermal_ops = {.stage = PLANT_FX_STAGE_GAS, .uses = PLANT_FX_USES_GAS_T, .rhs = thermal_rhs};

/* ---- area: a quadratic in height, flat past +-50 mm (the rolling lobe) ---- */
static void area_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    (void)fl;
    double d = fmax(-0.05, fmin(0.05, x[PLANT_X_Y] - f->y_ref_m));
    plant_fx_scale_area(f, x, dx, 1.0 + q[2] + q[0] * d + q[1] * d * d);
}
const plant_fx_ops fx_area_ops = {.stage = PLANT_FX_STAGE_GEOMETRY, .rhs = area_rhs};

/* ---- friction: Coulomb + Stribeck; below 0.1 mm/s the guide sticks up to Fc + Fs ---- */
static void friction_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    (void)fl;
    const plant *pl = &f->pl;
    const double vel = x[PLANT_X_VEL];
    double f_other = dx[PLANT_X_VEL] * pl->mass_kg;
    double fs = q[0] + q[1];
    if (!(fs > 0.0))
        return; /* off */
    double ff;
    if (fabs(vel) < 1e-4)
        ff = -fmax(-fs, fmin(fs, f_other)) - 2.0e5 * vel;
    else
        ff = -sgn(vel) * (q[0] + q[1] * exp(-(vel / q[2]) * (vel / q[2])));
    dx[PLANT_X_VEL] += ff / pl->mass_kg;
}
const plant_fx_ops fx_friction_ops = {.stage = PLANT_FX_STAGE_FORCE, .rhs = friction_rhs};

/* ---- valve_dynamics: pure opening/closing delays, ISO 6358 flow ---- */

/* The commanded valve state after its opening/closing delay. */
static bool delayed_valve(plant_fx *f, const double *q, int i, bool cmd)
{
    double open_d = q[0], close_d = q[1], t = f->pl.t_s;
    if (cmd != f->cmd[i]) {
        f->cmd[i] = cmd;
        f->pending_s[i] = cmd != f->eff[i] ? t + (cmd ? open_d : close_d) : -1.0;
    }
    if (f->pending_s[i] >= 0.0 && t >= f->pending_s[i] - 1e-9) {
        f->eff[i] = f->cmd[i];
        f->pending_s[i] = -1.0;
    }
    return f->eff[i];
}

static void valve_inputs(plant_fx *f, const double *q, plant_inputs *eff)
{
    eff->spring_valve = delayed_valve(f, q, 0, eff->spring_valve);
    eff->vent_valve = delayed_valve(f, q, 1, eff->vent_valve);
}

static void valve_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    const plant *pl = &f->pl;
    const plant_params *p = &pl->p;
    double m_s = fl->spring_valve, m_v = fl->vent_valve;
    /* The discharge coefficients stay the config's: rescaling one is
     * calibration (calibrate.py), not a valve effect. */
    if (q[2] > 0.0) {
        double a = pl->spring_valve_area_m2, av = p->vent_valve_cd * pl->vent_valve_area_m2;
        m_s = pl->in.spring_valve ? plant_fx_two_way(pl, p->spring_valve_cd_in * a, p->spring_valve_cd_out * a,
                                                     x[PLANT_X_P1], x[PLANT_X_P2], q[2])
                                  : 0.0;
        m_v = pl->in.vent_valve ? plant_fx_two_way(pl, av, av, x[PLANT_X_P1], p->ambient_pa, q[2]) : 0.0;
    }
    plant_fx_replace_flows(pl, x, dx, fl, fl->compressor, m_s, m_v);
}
const plant_fx_ops fx_valve_dynamics_ops = {.stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_VALVE_MEM,
                                            .inputs = valve_inputs, .rhs = valve_rhs};

/* ---- line_delay: the compressor's flow reaches the junction after the
 * transport delay q0, through a tube of volume q2 behind a laminar resistance
 * (its filling time constant q3); q1 changes the junction's volume (negative:
 * part of the pipe sits behind the resistance, a pipe split in two) ---- */
static void line_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[PLANT_FX_XE_AUX] = f->pl.p.init_p_pipe_pa;
}

/* The junction keeps at least a fifth of the pipe's volume. */
static double line_junction_m3(const plant_fx *f, const double *q)
{
    double v1 = f->pl.p.pipe_volume_m3;
    return fmax(v1 + q[1], 0.2 * v1);
}

static void line_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    const plant *pl = &f->pl;
    double m_c = q[0] > 0.0 ? f->mc_delayed : fl->compressor;
    if (q[2] > 0.0) {
        double tau = fmax(q[3], 1e-3);
        double m_line = q[2] / (pl->zn * pl->rt * tau) * (x[PLANT_NX + PLANT_FX_XE_AUX] - x[PLANT_X_P1]);
        dx[PLANT_NX + PLANT_FX_XE_AUX] = pl->zn * pl->rt * (m_c - m_line) / q[2];
        m_c = m_line;
    }
    plant_fx_replace_flows(pl, x, dx, fl, m_c, fl->spring_valve, fl->vent_valve);
    dx[PLANT_X_P1] *= pl->p.pipe_volume_m3 / line_junction_m3(f, q);
}

/* Substeps that keep RK4 stable on the tube: its fastest mode decays at
 * (1 + Vt/Vj)/tau, kept below 1.5 per substep. */
static int line_substeps(const plant_fx *f, const double *q, double dt_s, int substeps)
{
    if (!(q[2] > 0.0))
        return substeps;
    double rate = (1.0 + q[2] / line_junction_m3(f, q)) / fmax(q[3], 1e-3);
    int need = (int)ceil(dt_s * rate / 1.5);
    return need > substeps ? (need < 400 ? need : 400) : substeps;
}

/* The compressor flow of this tick, read back delay/dt ticks later. */
static void line_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    (void)raw;
    (void)first;
    double dx[PLANT_NX];
    plant_flows fl;
    plant_derivatives(&f->pl, f->pl.x, dx, &fl);
    int d = (int)lround(q[0] / dt_s);
    if (d > PLANT_FX_DELAY_TICKS - 1)
        d = PLANT_FX_DELAY_TICKS - 1;
    f->mc_head = (f->mc_head + 1) % PLANT_FX_DELAY_TICKS;
    f->mc_buf[f->mc_head] = fl.compressor;
    f->mc_delayed = f->mc_buf[(f->mc_head - d + PLANT_FX_DELAY_TICKS) % PLANT_FX_DELAY_TICKS];
}
const plant_fx_ops fx_line_delay_ops = {.stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX | PLANT_FX_USES_DELAY,
                                        .init = line_init, .rhs = line_rhs, .after_tick = line_after_tick,
                                        .substeps = line_substeps};

/* ---- leak: an orifice (eq. 8/9) spring -> ambient ---- */
static void leak_rhs(const plant_fx *f, const double *q, const double *x, double *dx, const plant_flows *fl)
{
    (void)fl;
    const plant *pl = &f->pl;
    double m_leak = plant_orifice_flow(pl, q[0], x[PLANT_X_P2], pl->p.ambient_pa);
    dx[PLANT_X_P2] -= pl->zn * pl->rt * m_leak / x[PLANT_X_V2];
}
const plant_fx_ops fx_leak_ops = {.stage = PLANT_FX_STAGE_FLOW, .rhs = leak_rhs};

/* ---- sensor_lag: first-order lags, offsets ---- */
static void sensor_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    if (first)
        return;
    f->sens[0][0] = plant_fx_lag(f->sens[0][0], raw[0], q[1], dt_s);
    for (int c = 1; c < 4; c++)
        f->sens[c][0] = plant_fx_lag(f->sens[c][0], raw[c], q[0], dt_s);
}

static void sensor_sensed(const plant_fx *f, const double *q, double out[4])
{
    for (int c = 0; c < 4; c++)
        out[c] = f->sens[c][0];
    out[1] += q[2];
    out[0] += q[3];
}
const plant_fx_ops fx_sensor_lag_ops = {.stage = PLANT_FX_STAGE_SENSOR, .uses = PLANT_FX_USES_SENS,
                                        .after_tick = sensor_after_tick, .sensed = sensor_sensed};
