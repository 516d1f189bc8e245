/*
 * The blind test's SECOND truth family (truth2.json; README.md here): effect
 * forms written from the physics alone, apart from the diagnosis's candidate
 * models, so that the diagnosis can be measured on truths it was never tuned
 * on. Each form names the effect it belongs to (thermal, area, friction,
 * valve_dynamics, line_delay, leak, sensor_lag) or "unknown" (outside the
 * catalogue: the honest-about-the-unknown test).
 *
 * Every form plugs into the plant through effects.h's plant_fx_ops: it adds
 * corrections to plant_derivatives()' result and keeps its own states in the
 * extra slots. Forms run one at a time (no pairs), so each only declares the
 * slots it uses. Not part of the product: linked into libleveler_truth.so only.
 */
#include <math.h>
#include <string.h>

#include "effects.h"

#define T2_PI 3.14159265358979323846
#define T2_AUX PLANT_FX_XE_AUX     /* first free slot of a form */
#define T2_AUX2 (PLANT_FX_XE_AUX + 1)

static int need_steps(double dt_s, double rate_per_s, int given)
{
    /* explicit RK4 is stable to h * rate ~ 2.7: keep it at 1 */
    int n = (int)ceil(dt_s * rate_per_s);
    return n > given ? n : given;
}

/* Restriction in a pipe: turbulent (sqrt of the drop) above p_t, laminar
 * (linear) below it, so that two nearly equal nodes are not stiff. a -> b (+). */
#define T2_LAMINAR_PA 2000.0
static double restriction_flow(const plant *pl, double cda, double pa_, double pb)
{
    double rho = 0.5 * (pa_ + pb) * pl->inv_rt;
    double dp = pa_ - pb;
    return cda * sqrt(2.0 * rho) * dp / sqrt(fabs(dp) + T2_LAMINAR_PA);
}

/* d(flow)/d(dp) at zero drop over volume v: the node's own rate, 1/s. */
static double restriction_rate(const plant *pl, double cda, double p, double v)
{
    return pl->zn * pl->rt * cda * sqrt(2.0 * p * pl->inv_rt / T2_LAMINAR_PA) / v;
}

static double orifice_two_way(const plant *pl, double cda_fwd, double cda_back, double pa_, double pb)
{
    return pa_ >= pb ? plant_orifice_flow(pl, cda_fwd, pa_, pb) : -plant_orifice_flow(pl, cda_back, pb, pa_);
}

/* ======================= thermal ======================= */

/* Spring gas energy balance (adiabatic exponent k, not the fixed n), with heat
 * q_term = (k-1) Q / V2 from a wall; T_in the temperature of gas entering. */
static void spring_energy(const plant_fx *f, const double *x, double *dx, double m_s, double t_in,
                          double q_term)
{
    const plant_params *p = &f->pl.p;
    double p2 = x[PLANT_X_P_SPRING], v2 = x[PLANT_X_V2], t2 = x[PLANT_NX + PLANT_FX_XE_T2];
    double z = p->compressibility, k = p->heat_ratio_k, r = p->gas_constant_j_per_kg_k;
    double dv2 = dx[PLANT_X_V2];
    double t_src = m_s > 0.0 ? t_in : t2;
    double d_p2 = z * k * (r * t_src * m_s - p2 * dv2) / v2 + q_term;
    dx[PLANT_X_P_SPRING] = d_p2;
    dx[PLANT_NX + PLANT_FX_XE_T2] = t2 * (d_p2 / p2 + dv2 / v2 - z * r * t2 * m_s / (p2 * v2));
}

/* thermal_wall: q = tau_gas_s, wall_ratio, tau_wall_s. The wall has its own
 * heat capacity (wall_ratio times the gas's) and cools to ambient slowly. */
static void wall_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    double t2 = x[PLANT_NX + PLANT_FX_XE_T2], tw = x[PLANT_NX + PLANT_FX_XE_TW];
    double ta = f->pl.p.temperature_k;
    spring_energy(f, x, dx, fl->spring_valve, ta, x[PLANT_X_P_SPRING] * (tw - t2) / (t2 * q[0]));
    dx[PLANT_NX + PLANT_FX_XE_TW] = (t2 - tw) / (q[0] * q[1]) + (ta - tw) / q[2];
}

static int wall_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    (void)f;
    return need_steps(dt_s, 1.5 / fmin(q[0], q[0] * q[1]), n);
}

const plant_fx_ops truth2_thermal_wall_ops = {
    .stage = PLANT_FX_STAGE_GAS, .uses = PLANT_FX_USES_GAS_T | PLANT_FX_USES_WALL_T,
    .rhs = wall_rhs, .substeps = wall_substeps};

/* thermal_hot: q = n_c, cooling, tau_s. The compressor's discharge is hot
 * (polytropic compression with exponent n_c from ambient to P1), the pipe
 * removes a fraction `cooling` of that excess, the spring gas exchanges heat
 * with a wall held at ambient. */
static void hot_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant_params *p = &f->pl.p;
    double ratio = fmax(x[PLANT_X_P_PIPE] / p->ambient_pa, 1.0);
    double t_dis = p->temperature_k * pow(ratio, (q[0] - 1.0) / q[0]);
    double t_in = p->temperature_k + (1.0 - q[1]) * (t_dis - p->temperature_k);
    double t2 = x[PLANT_NX + PLANT_FX_XE_T2];
    spring_energy(f, x, dx, fl->spring_valve, t_in, x[PLANT_X_P_SPRING] * (p->temperature_k - t2) / (t2 * q[2]));
}

static int hot_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    (void)f;
    return need_steps(dt_s, 1.5 / q[2], n);
}

const plant_fx_ops truth2_thermal_hot_ops = {
    .stage = PLANT_FX_STAGE_GAS, .uses = PLANT_FX_USES_GAS_T, .rhs = hot_rhs, .substeps = hot_substeps};

/* ======================= area ======================= */

/* Effective area A_true = s A_fit: volume rate and pressure force both scale. */
static void area_scale(const plant_fx *f, const double *x, double *dx, double s)
{
    const plant *pl = &f->pl;
    double dv2_nom = dx[PLANT_X_V2];
    dx[PLANT_X_V2] = s * dv2_nom;
    dx[PLANT_X_P_SPRING] -= pl->zn * x[PLANT_X_P_SPRING] * (s - 1.0) * dv2_nom / x[PLANT_X_V2];
    /* the pressure force is what is left of m dv/dt after the damping */
    double f_press = dx[PLANT_X_VEL] * pl->mass_kg + pl->damping_n_s_per_m * x[PLANT_X_VEL];
    dx[PLANT_X_VEL] += (s - 1.0) * f_press * pl->inv_mass;
}

/* area_sigmoid: q = amp, centre_m (from the start height), width_m: the lobe
 * rolls onto another piston contour over the travel (a smooth step). */
static void sigmoid_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    area_scale(f, x, dx, 1.0 + q[0] * tanh((x[PLANT_X_Y] - f->y_ref_m - q[1]) / q[2]));
}

const plant_fx_ops truth2_area_sigmoid_ops = {.stage = PLANT_FX_STAGE_GEOMETRY, .rhs = sigmoid_rhs};

/* area_lobe: q = curv (per in^2 of travel), per_bar: a quadratic contour about
 * the start height, and a bellows that bulges with pressure (per bar from the
 * start pressure, kept in AUX). */
static void lobe_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[T2_AUX] = f->pl.x[PLANT_X_P_SPRING];
}

static void lobe_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double dy_in = (x[PLANT_X_Y] - f->y_ref_m) / PLANT_M_PER_IN;
    double dp_bar = (x[PLANT_X_P_SPRING] - x[PLANT_NX + T2_AUX]) / 1e5;
    area_scale(f, x, dx, 1.0 + q[0] * dy_in * dy_in + q[1] * dp_bar);
}

const plant_fx_ops truth2_area_lobe_ops = {
    .stage = PLANT_FX_STAGE_GEOMETRY, .uses = PLANT_FX_USES_AUX, .init = lobe_init, .rhs = lobe_rhs};

/* ======================= friction ======================= */

#define T2_STICK_TAU_S 0.005

/* friction_stick: q = f_static_n, kinetic_ratio, v_stick (Karnopp): inside
 * the stick band the platform holds until the other forces exceed the static
 * friction; sliding, a kinetic friction opposes the motion. */
static void stick_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    const plant *pl = &f->pl;
    double vel = x[PLANT_X_VEL], force = dx[PLANT_X_VEL] * pl->mass_kg;
    double fk = q[0] * q[1];
    if (fabs(vel) < q[2]) {
        if (fabs(force) <= q[0])
            dx[PLANT_X_VEL] = -vel / T2_STICK_TAU_S;
        else
            dx[PLANT_X_VEL] = (force - copysign(fk, force)) * pl->inv_mass;
    } else {
        dx[PLANT_X_VEL] = (force - copysign(fk, vel)) * pl->inv_mass;
    }
}

static int stick_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    (void)f;
    return q[0] > 0.0 ? need_steps(dt_s, 1.0 / T2_STICK_TAU_S, n) : n;
}

const plant_fx_ops truth2_friction_stick_ops = {
    .stage = PLANT_FX_STAGE_FORCE, .rhs = stick_rhs, .substeps = stick_substeps};

/* friction_seal: q = c2 (N s^2/m^2), f0_n, mu_per_pa, v0: a seal whose
 * friction grows with the spring's gauge pressure, smoothed through zero
 * speed, plus a drag in v^2 (air and guide wipers). */
static double seal_coulomb(const plant_fx *f, const double *q, double p2)
{
    return q[1] + q[2] * fmax(p2 - f->pl.p.ambient_pa, 0.0);
}

static void seal_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double vel = x[PLANT_X_VEL];
    double fr = seal_coulomb(f, q, x[PLANT_X_P_SPRING]) * tanh(vel / q[3]) + q[0] * vel * fabs(vel);
    dx[PLANT_X_VEL] -= fr * f->pl.inv_mass;
}

static int seal_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    double slope = seal_coulomb(f, q, f->pl.x[PLANT_X_P_SPRING] * 1.5) / q[3]; /* N s/m at v = 0 */
    return need_steps(dt_s, 0.5 * slope * f->pl.inv_mass, n);
}

const plant_fx_ops truth2_friction_seal_ops = {
    .stage = PLANT_FX_STAGE_FORCE, .rhs = seal_rhs, .substeps = seal_substeps};

/* ======================= valve dynamics ======================= */

/* Both valve forms keep the plant's valves "open" and scale the orifice
 * flows by the opening fraction (xe VALVE: spring valve, VALVE + 1: vent),
 * so an opening that moves within a tick acts within it. */
static void valves_open(plant_fx *f, const double *q, plant_inputs *eff)
{
    (void)f;
    (void)q;
    eff->spring_valve = true;
    eff->vent_valve = true;
}

static void scale_valve_flows(const plant_fx *f, const double *x, double *dx, plant_flows *fl, double fs,
                              double fv)
{
    plant_fx_replace_flows(&f->pl, x, dx, fl, fl->compressor, fs * fl->spring_valve, fv * fl->vent_valve);
}

static void clamp_valves(double *x)
{
    for (int i = 0; i < 2; i++)
        x[PLANT_NX + PLANT_FX_XE_VALVE + i] = fmin(fmax(x[PLANT_NX + PLANT_FX_XE_VALVE + i], 0.0), 1.0);
}

/* valve_lag: q = tau_open_s, tau_close_s: the armature and the flow through
 * it follow the command as first-order lags (slower on one side). */
static double lag_tau(const double *q, bool cmd, double frac)
{
    return (cmd ? 1.0 : 0.0) > frac ? q[0] : q[1];
}

static void vlag_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    double fr[2];
    for (int i = 0; i < 2; i++) {
        double frac = x[PLANT_NX + PLANT_FX_XE_VALVE + i], tau = lag_tau(q, f->cmd[i], frac);
        double target = f->cmd[i] ? 1.0 : 0.0;
        fr[i] = tau > 1e-6 ? frac : target;
        dx[PLANT_NX + PLANT_FX_XE_VALVE + i] = tau > 1e-6 ? (target - frac) / tau : 0.0;
    }
    scale_valve_flows(f, x, dx, fl, fr[0], fr[1]);
}

static void vlag_after_step(plant_fx *f, const double *q, double *x, double vel0, double h)
{
    (void)vel0;
    (void)h;
    for (int i = 0; i < 2; i++)
        if (!(lag_tau(q, f->cmd[i], x[PLANT_NX + PLANT_FX_XE_VALVE + i]) > 1e-6))
            x[PLANT_NX + PLANT_FX_XE_VALVE + i] = f->cmd[i] ? 1.0 : 0.0;
    clamp_valves(x);
}

static int vlag_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    (void)f;
    double tau = fmin(q[0] > 1e-6 ? q[0] : 1.0, q[1] > 1e-6 ? q[1] : 1.0);
    return need_steps(dt_s, 1.0 / tau, n);
}

const plant_fx_ops truth2_valve_lag_ops = {
    .stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_VALVE_X, .inputs = valves_open, .rhs = vlag_rhs,
    .after_step = vlag_after_step, .substeps = vlag_substeps};

/* valve_deadtime: q = dead_open_s, dead_close_s, stroke_s: a switch acts
 * after a dead time (the coil's current building up, the armature breaking
 * free), then the opening moves at a limited rate over a full stroke. The
 * target each valve moves to is eff[i]; pending_s[i] when it changes. */
static void dead_inputs(plant_fx *f, const double *q, plant_inputs *eff)
{
    bool cmd[2] = {eff->spring_valve, eff->vent_valve};
    for (int i = 0; i < 2; i++) {
        if (cmd[i] == f->cmd[i])
            continue;
        double dead = cmd[i] ? q[0] : q[1];
        if (dead > 1e-9) {
            f->pending_s[i] = f->pl.t_s + dead;
        } else {
            f->eff[i] = cmd[i];
            f->pending_s[i] = -1.0;
        }
    }
    valves_open(f, q, eff);
}

static void dead_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    double fr[2];
    for (int i = 0; i < 2; i++) { /* the opening holds over a substep; dead_after_step moves it */
        fr[i] = q[2] > 1e-6 ? x[PLANT_NX + PLANT_FX_XE_VALVE + i] : (f->eff[i] ? 1.0 : 0.0);
        dx[PLANT_NX + PLANT_FX_XE_VALVE + i] = 0.0;
    }
    scale_valve_flows(f, x, dx, fl, fr[0], fr[1]);
}

/* The stroke at its limited rate, stepped exactly after each substep h: a
 * ramp's rate is discontinuous at its end, and inside RK4 it chattered about
 * a small opening (negative in its stages), so a valve told to shut pumped
 * air against the pressure difference (test_truth2: shut valves pass no air). */
static void dead_after_step(plant_fx *f, const double *q, double *x, double vel0, double h)
{
    (void)vel0;
    for (int i = 0; i < 2; i++) {
        if (f->pending_s[i] >= 0.0 && f->pl.t_s >= f->pending_s[i] - 1e-9) {
            f->eff[i] = f->cmd[i];
            f->pending_s[i] = -1.0;
        }
        double *frac = &x[PLANT_NX + PLANT_FX_XE_VALVE + i], target = f->eff[i] ? 1.0 : 0.0;
        double step = q[2] > 1e-6 ? h / q[2] : 1.0;
        *frac += fmin(fmax(target - *frac, -step), step);
    }
    clamp_valves(x);
}

static int dead_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    (void)f;
    (void)q;
    return need_steps(dt_s, 400.0, n); /* the dead time to 2.5 ms */
}

const plant_fx_ops truth2_valve_deadtime_ops = {
    .stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_VALVE_X | PLANT_FX_USES_VALVE_MEM,
    .inputs = dead_inputs, .rhs = dead_rhs, .after_step = dead_after_step, .substeps = dead_substeps};

/* ======================= line delay ======================= */

/* Flows of the valves at the manifold pressure pm (in place of P1). */
static void manifold_flows(const plant *pl, double pm, double p2, double p3, double *m_s, double *m_v, double *m_a)
{
    const plant_params *p = &pl->p;
    *m_s = pl->in.spring_valve ? orifice_two_way(pl, p->spring_valve_cd_in * pl->spring_valve_area_m2,
                                                 p->spring_valve_cd_out * pl->spring_valve_area_m2, pm, p2)
                               : 0.0;
    double cdv = p->vent_valve_cd * pl->vent_valve_area_m2;
    *m_v = pl->in.vent_valve ? orifice_two_way(pl, cdv, cdv, pm, p->ambient_pa) : 0.0;
    double cda = p->acc_valve_cd * pl->acc_valve_area_m2;
    *m_a = pl->in.acc_valve && p->acc_type != PLANT_ACC_NONE ? orifice_two_way(pl, cda, cda, pm, p3) : 0.0;
}

/* dP3 for an accumulator flow m_a (plant.c's equation). */
static double acc_rate(const plant *pl, double p3, double m_a)
{
    if (pl->p.acc_type == PLANT_ACC_DIAPHRAGM) {
        double v3, dv3;
        plant_diaphragm_volume(&pl->p, p3, &v3, &dv3);
        return pl->rt * m_a / (v3 / pl->zn + p3 * dv3);
    }
    return pl->p.acc_type == PLANT_ACC_TUBE ? pl->zn * pl->rt * m_a / pl->p.acc_volume_m3 : 0.0;
}

/* line_segments: q = bore_m, volume_scale, sensor_at_valve. The pipe is three
 * equal volumes in series joined by restrictions (bore: the fittings'
 * equivalent diameter, Cd 0.7): the compressor feeds the first (P1 state),
 * the valves sit on the third (AUX2); the P1 transducer at either end. */
#define T2_SEGMENTS 3
#define T2_FITTING_CD 0.7
static double bore_cda(double d) { return T2_FITTING_CD * T2_PI / 4.0 * d * d; }

static void seg_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[T2_AUX] = f->xe[T2_AUX2] = f->pl.x[PLANT_X_P_PIPE];
}

static void seg_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    double vseg = pl->p.pipe_volume_m3 * q[1] / T2_SEGMENTS, cda = bore_cda(q[0]);
    double n0 = x[PLANT_X_P_PIPE], n1 = x[PLANT_NX + T2_AUX], n2 = x[PLANT_NX + T2_AUX2];
    double m01 = restriction_flow(pl, cda, n0, n1), m12 = restriction_flow(pl, cda, n1, n2);
    double m_s, m_v, m_a;
    manifold_flows(pl, n2, x[PLANT_X_P_SPRING], x[PLANT_X_P_ACC], &m_s, &m_v, &m_a);
    double c = pl->zn * pl->rt / vseg;
    dx[PLANT_X_P_PIPE] = c * (fl->compressor - m01);
    dx[PLANT_NX + T2_AUX] = c * (m01 - m12);
    dx[PLANT_NX + T2_AUX2] = c * (m12 - m_s - m_v - m_a);
    dx[PLANT_X_P_SPRING] += pl->zn * pl->rt * (m_s - fl->spring_valve) / x[PLANT_X_V2];
    dx[PLANT_X_P_ACC] = m_a != 0.0 ? acc_rate(pl, x[PLANT_X_P_ACC], m_a) : 0.0;
}

static int seg_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    double v = f->pl.p.pipe_volume_m3 * q[1] / T2_SEGMENTS, p = fmax(f->pl.x[PLANT_X_P_PIPE], f->xe[T2_AUX2]);
    return need_steps(dt_s, 2.0 * restriction_rate(&f->pl, bore_cda(q[0]), 1.5 * p, v), n);
}

static void seg_sensed(const plant_fx *f, const double *q, double out[4])
{
    if (q[2] > 0.5)
        out[2] = f->xe[T2_AUX2];
}

const plant_fx_ops truth2_line_segments_ops = {
    .stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX, .init = seg_init, .rhs = seg_rhs,
    .sensed = seg_sensed, .substeps = seg_substeps};

/* line_hose: q = hose_m3, fitting_m, sensor_on_hose. Between the spring valve
 * and the spring a hose (its own volume, AUX) ends in a fitting (a
 * restriction) into the spring; the P2 transducer on the spring or the hose. */
static void hose_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[T2_AUX] = f->pl.x[PLANT_X_P_SPRING];
}

static void hose_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    double ph = x[PLANT_NX + T2_AUX], zrt = pl->zn * pl->rt;
    double m_s, m_v, m_a;
    manifold_flows(pl, x[PLANT_X_P_PIPE], ph, x[PLANT_X_P_ACC], &m_s, &m_v, &m_a); /* the valve into the hose */
    double m_f = restriction_flow(pl, bore_cda(q[1]), ph, x[PLANT_X_P_SPRING]);
    dx[PLANT_X_P_PIPE] -= zrt * (m_s - fl->spring_valve) / pl->p.pipe_volume_m3;
    dx[PLANT_NX + T2_AUX] = zrt * (m_s - m_f) / q[0];
    dx[PLANT_X_P_SPRING] += zrt * (m_f - fl->spring_valve) / x[PLANT_X_V2];
}

static int hose_substeps(const plant_fx *f, const double *q, double dt_s, int n)
{
    double p = 1.5 * fmax(f->pl.x[PLANT_X_P_SPRING], f->xe[T2_AUX]);
    return need_steps(dt_s, restriction_rate(&f->pl, bore_cda(q[1]), p, q[0]), n);
}

static void hose_sensed(const plant_fx *f, const double *q, double out[4])
{
    if (q[2] > 0.5)
        out[1] = f->xe[T2_AUX];
}

const plant_fx_ops truth2_line_hose_ops = {
    .stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX, .init = hose_init, .rhs = hose_rhs,
    .sensed = hose_sensed, .substeps = hose_substeps};

/* line_transport: q = delay_s, extra_volume (fraction of the pipe's): the
 * compressor's delivery reaches the junction after a transport delay through
 * a long line whose volume adds to the junction's. The delay line holds the
 * compressor's flow of past ticks (mc_buf). */
static double compressor_flow(const plant *pl)
{
    const plant_params *p = &pl->p;
    double omega = pl->x[PLANT_X_OMEGA], p1 = pl->x[PLANT_X_P_PIPE];
    if (!pl->in.compressor || !(omega > 1e-4))
        return 0.0;
    double q = p->compressor_capacity_m3_per_rad * omega;
    if (p1 > p->ambient_pa)
        q -= p->compressor_leakage_m3_per_pa_s * (p1 - p->ambient_pa);
    return p1 * q * pl->inv_rt;
}

static void transport_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)x;
    const plant *pl = &f->pl;
    double m_c = q[0] > 0.0 ? f->mc_delayed : fl->compressor;
    dx[PLANT_X_P_PIPE] = (dx[PLANT_X_P_PIPE] + pl->zn_rt_per_v1 * (m_c - fl->compressor)) / (1.0 + q[1]);
}

static void transport_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    (void)raw;
    int nd = (int)lround(q[0] / dt_s);
    if (nd > PLANT_FX_DELAY_TICKS - 1)
        nd = PLANT_FX_DELAY_TICKS - 1;
    if (first)
        for (int i = 0; i < PLANT_FX_DELAY_TICKS; i++)
            f->mc_buf[i] = 0.0;
    f->mc_head = (f->mc_head + 1) % PLANT_FX_DELAY_TICKS;
    f->mc_buf[f->mc_head] = compressor_flow(&f->pl);
    f->mc_delayed = f->mc_buf[(f->mc_head - nd + PLANT_FX_DELAY_TICKS) % PLANT_FX_DELAY_TICKS];
}

const plant_fx_ops truth2_line_transport_ops = {
    .stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_DELAY, .rhs = transport_rhs,
    .after_tick = transport_after_tick};

/* ======================= leak ======================= */

/* The leaked mass accumulates in AUX (the conservation test reads it). */
static void spring_leak(const plant_fx *f, const double *x, double *dx, double m)
{
    dx[PLANT_X_P_SPRING] -= f->pl.zn * f->pl.rt * m / x[PLANT_X_V2];
    dx[PLANT_NX + T2_AUX] = m;
}

/* leak_orifice: q = diameter_m (Cd 0.6): a hole in the bead or a fitting,
 * choked above the critical ratio, subsonic below (eq. 8/9). */
static void lorifice_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double cda = 0.6 * T2_PI / 4.0 * q[0] * q[0];
    spring_leak(f, x, dx, plant_orifice_flow(&f->pl, cda, x[PLANT_X_P_SPRING], f->pl.p.ambient_pa));
}

const plant_fx_ops truth2_leak_orifice_ops = {
    .stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_AUX, .rhs = lorifice_rhs};

/* leak_porous: q = k (kg/(s Pa^2)): seepage through the rubber and its cords,
 * isothermal Darcy flow of a gas: m = k (P2^2 - Pa^2), never choked. */
static void lporous_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double pa = f->pl.p.ambient_pa, p2 = x[PLANT_X_P_SPRING];
    spring_leak(f, x, dx, q[0] * (p2 * p2 - pa * pa));
}

const plant_fx_ops truth2_leak_porous_ops = {
    .stage = PLANT_FX_STAGE_FLOW, .uses = PLANT_FX_USES_AUX, .rhs = lporous_rhs};

/* ======================= sensor lag ======================= */

static double quantise(double v, double lsb) { return lsb > 0.0 ? floor(v / lsb + 0.5) * lsb : v; }

/* sensor_quant: q = tau_h_s, tau_p_s, lsb_h_m, lsb_p_pa: first-order lags
 * (the transducers' own filters) and then a coarse converter. */
static void quant_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    (void)first;
    for (int c = 0; c < 4; c++)
        f->sens[c][0] = plant_fx_lag(f->sens[c][0], raw[c], c == 0 ? q[0] : q[1], dt_s);
}

static void quant_sensed(const plant_fx *f, const double *q, double out[4])
{
    for (int c = 0; c < 4; c++)
        out[c] = quantise(f->sens[c][0], c == 0 ? q[2] : q[3]);
}

const plant_fx_ops truth2_sensor_quant_ops = {
    .stage = PLANT_FX_STAGE_SENSOR, .uses = PLANT_FX_USES_SENS, .after_tick = quant_after_tick,
    .sensed = quant_sensed};

/* sensor_drift: q = h_offset_m, p_offset_pa, p_drift_pa_per_s, tau_s: the
 * transducers respond as two cascaded lags (second order), the height reads
 * off by a fixed offset, the spring's pressure transducer by an offset that
 * drifts (warming up). */
static void drift_after_tick(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first)
{
    (void)first;
    for (int c = 0; c < 4; c++) {
        f->sens[c][0] = plant_fx_lag(f->sens[c][0], raw[c], q[3], dt_s);
        f->sens[c][1] = plant_fx_lag(f->sens[c][1], f->sens[c][0], q[3], dt_s);
    }
}

static void drift_sensed(const plant_fx *f, const double *q, double out[4])
{
    for (int c = 0; c < 4; c++)
        out[c] = f->sens[c][1];
    out[0] += q[0];
    out[1] += q[1] + q[2] * f->pl.t_s;
}

const plant_fx_ops truth2_sensor_drift_ops = {
    .stage = PLANT_FX_STAGE_SENSOR, .uses = PLANT_FX_USES_SENS, .after_tick = drift_after_tick,
    .sensed = drift_sensed};

/* ======================= outside the catalogue ======================= */

/* unknown_clearance: q = clearance: the compressor's clearance volume
 * re-expands, its volumetric efficiency 1 - c ((P1/Pa)^(1/1.3) - 1) falls
 * with the pressure ratio. */
static void clearance_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    const plant *pl = &f->pl;
    double ratio = fmax(x[PLANT_X_P_PIPE] / pl->p.ambient_pa, 1.0);
    double eta = fmax(1.0 - q[0] * (pow(ratio, 1.0 / 1.3) - 1.0), 0.0);
    dx[PLANT_X_P_PIPE] -= pl->zn_rt_per_v1 * (1.0 - eta) * fl->compressor;
}

const plant_fx_ops truth2_unknown_clearance_ops = {.stage = PLANT_FX_STAGE_FLOW, .rhs = clearance_rhs};

/* unknown_stiffness: q = k_n_per_m: a linkage or bump stop in parallel with
 * the spring pulls the platform back to the start height. */
static void stiff_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    dx[PLANT_X_VEL] -= q[0] * (x[PLANT_X_Y] - f->y_ref_m) * f->pl.inv_mass;
}

const plant_fx_ops truth2_unknown_stiffness_ops = {.stage = PLANT_FX_STAGE_FORCE, .rhs = stiff_rhs};

/* unknown_creep: q = compliance_m3_per_pa, tau_s: the bead creeps, the
 * spring's volume grows viscoelastically with its pressure: a volume Vc (AUX)
 * relaxing to C (P2 - P2 at the start, in AUX2) with tau. */
static void creep_init(plant_fx *f, const double *q)
{
    (void)q;
    f->xe[T2_AUX] = 0.0;
    f->xe[T2_AUX2] = f->pl.x[PLANT_X_P_SPRING];
}

static void creep_rhs(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl)
{
    (void)fl;
    double vc = x[PLANT_NX + T2_AUX];
    double dvc = (q[0] * (x[PLANT_X_P_SPRING] - x[PLANT_NX + T2_AUX2]) - vc) / q[1];
    dx[PLANT_NX + T2_AUX] = dvc;
    dx[PLANT_X_P_SPRING] -= f->pl.zn * x[PLANT_X_P_SPRING] * dvc / (x[PLANT_X_V2] + vc);
}

const plant_fx_ops truth2_unknown_creep_ops = {
    .stage = PLANT_FX_STAGE_VOLUME, .uses = PLANT_FX_USES_AUX, .init = creep_init, .rhs = creep_rhs};
