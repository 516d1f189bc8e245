/*
 * The candidate effects the diagnosis fits, one set of functions per effect
 * (effects.h; names, parameters and ranges in effects.json). Parameters in
 * order, SI; "nominal" values give the nominal plant:
 *   thermal         tau_thermal_s (0: fixed polytropic n); wall's share of the gas's heat
 *                   capacity (0: a wall held at ambient), wall-to-room s, warm delivery (relative)
 *   area            A = A_nom (1 + a0 + a1 d + a2 d^2 + a3 dp), d = y - y_ref held within +-50 mm,
 *                   dp = P2 - P2 at the start: a1 rel/m, a2 rel/m^2, a0 relative, a3 rel/Pa
 *   friction        Coulomb N, Stribeck N, Stribeck velocity m/s
 *   valve_dynamics  open delay s, close delay s, the opening's lag after the delay s (0: the
 *                   valve opens and shuts at once)
 *   line_delay      transport delay s, junction volume change m^3, tube volume behind a laminar
 *                   resistance m^3, that resistance as the tube's time constant s; hose volume
 *                   between spring valve and spring m^3, its fitting's Cd A relative to the
 *                   valve's, share of the hose's / tube's pressure the P2 / P1 transducers read
 *   leak            orifice area m^2 (Cd 1), spring -> ambient
 *   sensor_lag      pressure lag s, height lag s, P2 offset Pa, height offset m
 */
#include "effects.h"

#include <math.h>

static double sgn(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

/* ---- thermal: one gas-to-wall time constant q0, the wall at ambient; extended
 * by a wall that warms (its heat capacity: the gas's over the wall's, q1; its
 * own time constant to the room, q2) and a compressor that delivers warm air
 * (q3: its outlet above ambient, relative) ---- */
static void thermal_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    if (!(q[0] > 0.0)) /* 0: the fixed polytropic exponent */
        return;
    double ta = f->pl.p.temperature_k, tw = q[1] > 0.0 ? x[PLANT_NX + PLANT_FX_XE_TW] : ta;
    plant_fx_thermal_balance_in(f, x, dx, fl, q[0], tw, ta * (1.0 + q[3]));
    if (q[1] > 0.0)
        dx[PLANT_NX + PLANT_FX_XE_TW] =
            q[1] * (x[PLANT_NX + PLANT_FX_XE_T2] - tw) / q[0] + (q[2] > 0.0 ? (ta - tw) / q[2] : 0.0);
}
const plant_fx_ops fx_thermal_ops = {.stage = PLANT_FX_STAGE_GAS, .uses = PLANT_FX_USES_GAS_T | PLANT_FX_USES_WALL_T,
                                     .rhs = thermal_rhs};

/* ---- area: a quadratic in height, flat past +-50 mm (the rolling lobe), and
 * linear in the spring's pressure above the start's (q3: a bellows bulges with
 * its pressure, which moves the effective area of a rolling lobe) ---- */
static void area_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double d = fmax(-0.05, fmin(0.05, x[PLANT_X_Y] - f->y_ref_m));
    double dp = q[3] != 0.0 ? x[PLANT_X_P_SPRING] - f->pl.p.init_p_spring_pa : 0.0;
    plant_fx_scale_area(f, x, dx, 1.0 + q[2] + q[0] * d + q[1] * d * d + q[3] * dp);
}
const plant_fx_ops fx_area_ops = {.stage = PLANT_FX_STAGE_GEOMETRY, .rhs = area_rhs};

/* ---- friction: Coulomb + Stribeck; below 0.1 mm/s the guide sticks up to Fc + Fs ---- */
static void friction_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
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

/* ---- valve_dynamics: opening/closing delays, and an opening that follows the
 * delayed command as a first-order lag (q2). The flow law and the discharge
 * coefficients stay the config's: a rescaled Cd is calibration (calibrate.py),
 * and a steady flow law is not dynamics. ---- */

/* First-order lag over a span of len_s from the opening *o toward g (time
 * constant tau_s > 0): the mean opening over the span; *o becomes its end. */
static double lag_span(double *o, double g, double len_s, double tau_s)
{
    if (!(len_s > 0.0))
        return *o;
    double a = exp(-len_s / tau_s), o0 = *o;
    *o = g + (o0 - g) * a;
    return g + (o0 - g) * tau_s / len_s * (1.0 - a);
}

/* The lagged valve's mean opening over a tick of dt_s, the switch (from
 * eff_before to eff) switch_in_s into it; *o advances to the tick's end. A
 * fully shut or open valve is snapped there (exp never gets there itself). */
static double lagged_opening(double *o, bool before, bool now, double switch_in_s, double dt_s, double tau_s)
{
    double first = switch_in_s < 0.0 ? dt_s : fmin(dt_s, switch_in_s);
    double m1 = lag_span(o, before ? 1.0 : 0.0, first, tau_s);
    double m2 = lag_span(o, now ? 1.0 : 0.0, dt_s - first, tau_s);
    if (fabs(*o - (now ? 1.0 : 0.0)) < 1e-6)
        *o = now ? 1.0 : 0.0;
    return dt_s > 0.0 ? (m1 * first + m2 * (dt_s - first)) / dt_s : *o;
}

/* The valve's open share of the coming tick after its opening/closing delay.
 * A switch due inside the tick opens the valve for the share of the tick after
 * it (the flow scaled by that share): the plant is then a continuous function
 * of the delays, not a staircase of 10 ms steps a least-squares fit cannot
 * climb. Without a tick length yet (the first tick) the switch waits for the
 * tick boundary. With a lag, the share is the tick's mean opening. */
static double delayed_valve(plant_fx *f, const double *q, int i, bool cmd)
{
    double open_d = q[0], close_d = q[1], t = f->pl.t_s, dt = f->tick_s;
    if (cmd != f->cmd[i]) {
        f->cmd[i] = cmd;
        f->pending_s[i] = cmd != f->eff[i] ? t + (cmd ? open_d : close_d) : -1.0;
    }
    double frac = f->eff[i] ? 1.0 : 0.0;
    f->eff_before[i] = f->eff[i];
    f->switch_in_s[i] = -1.0;
    if (f->pending_s[i] >= 0.0 && t + dt > f->pending_s[i] - 1e-9) {
        double after = dt > 0.0 && f->pending_s[i] > t ? fmax(0.0, (t + dt - f->pending_s[i]) / dt) : 1.0;
        f->eff[i] = f->cmd[i];
        f->pending_s[i] = -1.0;
        f->switch_in_s[i] = (1.0 - after) * dt;
        frac = f->eff[i] ? after : 1.0 - after;
    }
    if (q[2] > 0.0) {
        double o = f->opening[i]; /* the tick's mean; after_tick advances the state */
        frac = lagged_opening(&o, f->eff_before[i], f->eff[i], f->switch_in_s[i], dt, q[2]);
    }
    return frac;
}

static void valve_inputs(plant_fx *f, const double *q, plant_inputs *eff)
{
    f->open_frac[0] = delayed_valve(f, q, 0, eff->spring_valve);
    f->open_frac[1] = delayed_valve(f, q, 1, eff->vent_valve);
    eff->spring_valve = f->open_frac[0] > 0.0;
    eff->vent_valve = f->open_frac[1] > 0.0;
}

/* The lagged openings move over the tick as it was (a log's ticks vary);
 * without a lag nothing reads them. */
static void valve_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    (void)raw;
    (void)first;
    if (!(q[2] > 0.0))
        return;
    for (int i = 0; i < 2; i++)
        (void)lagged_opening(&f->opening[i], f->eff_before[i], f->eff[i], f->switch_in_s[i], dt_s, q[2]);
}

static void valve_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)q;
    plant_fx_replace_flows(&f->pl, x, dx, fl, fl->compressor, fl->spring_valve * f->open_frac[0],
                           fl->vent_valve * f->open_frac[1]);
}
const plant_fx_ops fx_valve_dynamics_ops = {.stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_VALVE_MEM,
                                            .inputs = valve_inputs, .rhs = valve_rhs,
                                            .after_tick = valve_after_tick};

/* ---- line_delay: the compressor's flow reaches the junction after the
 * transport delay q0, through a tube of volume q2 behind a laminar resistance
 * (its filling time constant q3); q1 changes the junction's volume (negative:
 * part of the pipe sits behind the resistance, a pipe split in two). On the
 * spring's side, a hose of volume q4 between the spring valve and the spring,
 * entering it through a fitting (an orifice, q5 times the spring valve's Cd A);
 * the spring's transducer reads a share q6 of the hose's pressure (1: it sits
 * on the hose), the pipe's a share q7 of the tube's (1: at the compressor's
 * end). Both transducer places of each restriction are covered. ---- */
enum { LINE_TUBE = PLANT_FX_XE_AUX, LINE_HOSE = PLANT_FX_XE_AUX + 1 };

static void line_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[LINE_TUBE] = f->pl.p.init_p_pipe_pa;
    f->xe[LINE_HOSE] = f->pl.p.init_p_spring_pa;
}

/* The junction keeps at least a fifth of the pipe's volume. */
static double line_junction_m3(const plant_fx *f, const double *q)
{
    double v1 = f->pl.p.pipe_volume_m3;
    return fmax(v1 + q[1], 0.2 * v1);
}

/* A hose of any volume above none is at least a short 1/4 in one: smaller
 * ones are not seen at 100 Hz, and a fit's first finite-difference step from
 * none lands on a hose of that size, as it did before the implicit step. */
#define LINE_HOSE_MIN_M3 2e-5
static double line_hose_m3(const double *q) { return q[4] > 0.0 ? fmax(q[4], LINE_HOSE_MIN_M3) : 0.0; }
static bool line_has_hose(const double *q) { return q[4] > 0.0; }

static void line_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    double m_c = q[0] > 0.0 ? f->mc_delayed : fl->compressor;
    if (q[2] > 0.0) { /* the tube takes the compressor's air; line_after_step passes it on */
        dx[PLANT_NX + LINE_TUBE] = pl->zn * pl->rt * m_c / q[2];
        m_c = 0.0;
    }
    /* with a hose, the spring valve's flow goes pipe -> hose -> spring in line_hose_exchange */
    plant_fx_replace_flows(pl, x, dx, fl, m_c, line_has_hose(q) ? 0.0 : fl->spring_valve, fl->vent_valve);
    dx[PLANT_X_P_PIPE] *= pl->p.pipe_volume_m3 / line_junction_m3(f, q);
}

/* The tube's exchange with the junction through its laminar resistance, exact
 * over a span of h: the pressure difference D decays as exp(-(1 + Vt/Vj) h /
 * tau), and what leaves the tube (Vt dPt) enters the junction (Vj dP1). */
static void line_tube_exchange(const plant_fx *f, const double *q, double *x, double h)
{
    if (!(q[2] > 0.0))
        return;
    double vt = q[2], vj = line_junction_m3(f, q), tau = fmax(q[3], 1e-3);
    double moved = -(x[PLANT_NX + LINE_TUBE] - x[PLANT_X_P_PIPE]) * expm1(-(1.0 + vt / vj) * h / tau);
    x[PLANT_NX + LINE_TUBE] -= moved * vj / (vj + vt);
    x[PLANT_X_P_PIPE] += moved * vt / (vj + vt);
}

/* The spring valve's flow junction -> hose (a valve model's open share, else
 * whole): that of the plant's spring valve between p1 and ph. */
static double line_valve_flow(const plant_fx *f, double p1, double ph)
{
    const plant *pl = &f->pl;
    double a = pl->spring_valve_area_m2;
    return pl->in.spring_valve ? f->open_frac[0] * plant_fx_two_way(pl, pl->p.spring_valve_cd_in * a,
                                                                    pl->p.spring_valve_cd_out * a, p1, ph)
                               : 0.0;
}

/* The fitting's flow hose -> spring: an orifice q5 times the valve's Cd A into the spring. */
static double line_fitting_flow(const plant_fx *f, const double *q, double ph, double p2)
{
    double cda = q[5] * f->pl.p.spring_valve_cd_in * f->pl.spring_valve_area_m2;
    return plant_fx_two_way(&f->pl, cda, cda, ph, p2);
}

/* One implicit stage of the hose's exchange from the start state x: the
 * masses the valve and the fitting pass are e + a m(end of stage) (kg; e: the
 * explicit part of the stage). */
typedef struct {
    const plant_fx *f;
    const double *q, *x;
    double zrt, vj, a, e_v, e_f;
} line_hose_stage;

/* The stage's balance at a trial end pressure ph of the hose: the fitting's
 * flow at ph (the spring held: its volume dwarfs the hose's), the junction's
 * end pressure p1 that keeps the mass the hose and the spring took, the
 * valve's flow at p1 and ph. Returns ph minus where those masses take the
 * hose (Pa); it rises with ph (the valve's inflow falls, the fitting's outflow
 * grows). */
static double line_hose_balance(const line_hose_stage *s, double ph, double *p1, double *m_v, double *m_f)
{
    const double *x = s->x, ph0 = x[PLANT_NX + LINE_HOSE], vh = line_hose_m3(s->q);
    *m_f = line_fitting_flow(s->f, s->q, ph, x[PLANT_X_P_SPRING]);
    double mass_f = s->e_f + s->a * *m_f;
    *p1 = x[PLANT_X_P_PIPE] - (vh * (ph - ph0) + s->zrt * mass_f) / s->vj;
    *m_v = line_valve_flow(s->f, *p1, ph);
    return ph - ph0 - s->zrt * (s->e_v + s->a * *m_v - mass_f) / vh;
}

/* The balance is solved to LINE_HOSE_TOL_PA: with its slope >= 1 that puts
 * the hose's pressure within 0.1 Pa, under a millionth of it. Solving to 1e-3 Pa
 * made each of line_delay's simulations about 10 % dearer, for the same fit
 * and verdicts (docs/diagnosis.md, Speed). */
#define LINE_HOSE_TOL_PA 0.1

/* The root of the stage's balance, from a guess ph_guess and the balance's
 * slope there (<= 0: probed 1 Pa toward the root; the slope is >= 1): Newton
 * steps until the root is bracketed, then regula falsi with the Illinois
 * halving to a bracket of 1 Pa, the root taken where the last bracket's chord
 * crosses zero (unbiased). *slope returns the last bracket's slope. */
static double line_hose_solve(const line_hose_stage *s, double ph_guess, double *slope, double *p1, double *m_v,
                              double *m_f)
{
    double a = ph_guess, g_a = line_hose_balance(s, a, p1, m_v, m_f);
    if (fabs(g_a) < LINE_HOSE_TOL_PA)
        return a;
    double k = *slope;
    if (!(k >= 1.0)) {
        double d = g_a > 0.0 ? -1.0 : 1.0;
        k = fmax(1.0, (line_hose_balance(s, a + d, p1, m_v, m_f) - g_a) / d);
    }
    /* Newton steps (lengthened each time) until the sign changes */
    double b = a, g_b = g_a, step = -g_a / k;
    for (int it = 0; it < 40 && (g_b > 0.0) == (g_a > 0.0); it++, step *= 2.0) {
        a = b, g_a = g_b;
        b = a + step;
        g_b = line_hose_balance(s, b, p1, m_v, m_f);
    }
    double lo = fmin(a, b), hi = fmax(a, b), f_lo = a < b ? g_a : g_b, f_hi = a < b ? g_b : g_a;
    double g_lo = f_lo, g_hi = f_hi, ph = b, g = g_b;
    for (int it = 0, side = 0; it < 60 && hi - lo > 1.0 && fabs(g) > LINE_HOSE_TOL_PA; it++) {
        ph = lo - g_lo * (hi - lo) / (g_hi - g_lo);
        if (!(ph > lo && ph < hi))
            ph = 0.5 * (lo + hi);
        g = line_hose_balance(s, ph, p1, m_v, m_f);
        if (g > 0.0) {
            hi = ph, g_hi = f_hi = g;
            g_lo *= side > 0 ? 0.5 : 1.0;
            side = 1;
        } else {
            lo = ph, g_lo = f_lo = g;
            g_hi *= side < 0 ? 0.5 : 1.0;
            side = -1;
        }
    }
    *slope = hi > lo && f_hi > f_lo ? (f_hi - f_lo) / (hi - lo) : k;
    if (fabs(g) > LINE_HOSE_TOL_PA && f_hi > f_lo) {
        ph = lo - f_lo * (hi - lo) / (f_hi - f_lo);
        line_hose_balance(s, ph, p1, m_v, m_f);
    }
    return ph;
}

/* The hose's exchange over h by a two-stage L-stable SDIRK (second order,
 * stiffly accurate: gamma = 1 - 1/sqrt 2), implicit in the hose's and the
 * junction's pressures: a hose however small needs no RK4 substeps (explicit
 * RK4 needed 40 a tick for a 2e-5 m^3 hose behind a wide fitting, and still
 * left its pressure chattering 100 Pa about the spring's at rest). Near no
 * drop an orifice's flow has an infinite slope, so at a bracket of 1 Pa the
 * balance can be off by 100 Pa: the restriction nearer no drop passes what
 * the hose does not keep, so mass is kept exactly and a shut valve passes
 * nothing. */
static void line_hose_exchange(const plant_fx *f, const double *q, double *x, double h)
{
    /* a shut valve and a hose level with the spring: nothing moves */
    if (!line_has_hose(q) || (!f->pl.in.spring_valve && fabs(x[PLANT_NX + LINE_HOSE] - x[PLANT_X_P_SPRING]) < 1e-3))
        return;
    const double gamma = 1.0 - sqrt(0.5), ph0 = x[PLANT_NX + LINE_HOSE];
    line_hose_stage s = {f, q, x, f->pl.zn * f->pl.rt, line_junction_m3(f, q), gamma * h, 0.0, 0.0};
    double p1, m_v, m_f, slope = 0.0;
    double y1 = line_hose_solve(&s, ph0, &slope, &p1, &m_v, &m_f);
    s.e_v = (1.0 - gamma) * h * m_v;
    s.e_f = (1.0 - gamma) * h * m_f;
    double ph = line_hose_solve(&s, y1, &slope, &p1, &m_v, &m_f);
    double mass_v = s.e_v + s.a * m_v, mass_f = s.e_f + s.a * m_f, kept = (ph - ph0) * line_hose_m3(q) / s.zrt;
    if (fabs(p1 - ph) < fabs(ph - x[PLANT_X_P_SPRING]) && f->pl.in.spring_valve)
        mass_v = mass_f + kept;
    else
        mass_f = mass_v - kept;
    x[PLANT_X_P_PIPE] -= s.zrt * mass_v / s.vj;
    x[PLANT_X_P_SPRING] += s.zrt * mass_f / x[PLANT_X_V2];
    x[PLANT_NX + LINE_HOSE] = ph;
}

/* Strang splitting, second order: the exchanges half before and half after
 * the RK4 steps of the other flows. The tube's (exact for any tau: a fast
 * resistance needed up to 400 RK4 substeps a tick) around each substep; the
 * hose's around the tick's substeps together, half a tick before the first
 * and half after the last (a hose run 15 ms against 24 ms around each
 * substep; within 4.1 um of the same equations on 0.1 ms ticks: test_effects). */
static void line_before_step(plant_fx *f, const double *q, double *x, double h)
{
    line_tube_exchange(f, q, x, 0.5 * h);
    if (f->substep == 0)
        line_hose_exchange(f, q, x, 0.5 * f->tick_s);
}

static void line_after_step(plant_fx *f, const double *q, double *x, double vel0, double h)
{
    (void)vel0;
    if (f->substep + 1 == f->substeps)
        line_hose_exchange(f, q, x, 0.5 * f->tick_s);
    line_tube_exchange(f, q, x, 0.5 * h);
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

/* Where the transducers sit: on the hose rather than the spring, at the
 * compressor's end of the tube rather than at the valves. */
static void line_sensed(const plant_fx *f, const double *q, double out[4])
{
    if (line_has_hose(q))
        out[1] += q[6] * (f->xe[LINE_HOSE] - f->pl.x[PLANT_X_P_SPRING]);
    if (q[2] > 0.0)
        out[2] += q[7] * (f->xe[LINE_TUBE] - f->pl.x[PLANT_X_P_PIPE]);
}
const plant_fx_ops fx_line_delay_ops = {.stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX | PLANT_FX_USES_DELAY,
                                        .init = line_init, .rhs = line_rhs, .before_step = line_before_step,
                                        .after_step = line_after_step,
                                        .after_tick = line_after_tick,
                                        .sensed = line_sensed};

/* ---- leak: an orifice (eq. 8/9) spring -> ambient ---- */
static void leak_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    const plant *pl = &f->pl;
    double m_leak = plant_orifice_flow(pl, q[0], x[PLANT_X_P_SPRING], pl->p.ambient_pa);
    dx[PLANT_X_P_SPRING] -= pl->zn * pl->rt * m_leak / x[PLANT_X_V2];
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
