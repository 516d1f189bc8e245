/*
 * Unmodelled effects as corrections to the nominal plant (effects.h).
 *
 * Parameters by kind (SI; "off" = the value that gives the nominal plant):
 *  candidates
 *   1 thermal   p0 tau_thermal_s (0 = off: fixed polytropic n)
 *   2 area      A = A_nom (1 + a0 + a1 d + a2 d^2), d = y - y_ref held within +-50 mm:
 *               p0 a1 rel/m, p1 a2 rel/m^2, p2 a0 relative (0, 0, 0 = off)
 *   3 friction  p0 coulomb N, p1 stribeck N, p2 stribeck velocity m/s
 *   4 valve     p0 open delay s, p1 close delay s, p2 ISO 6358 b (0 = eq. 8), p3 outflow C scale
 *   5 line      p0 transport delay s, p1 dead volume of the tube added at the junction m^3 (0, 0 = off)
 *   6 leak      p0 orifice area m^2 (Cd 1)
 *   7 sensor    p0 pressure lag s, p1 height lag s, p2 P2 offset Pa, p3 height offset m
 *  truth variants (100 + kind)
 *   101 thermal p0 gas-wall tau s, p1 wall-ambient tau s, p2 wall/gas heat capacity ratio
 *   102 area    p0..p4 relative area deviation at y_ref + (-2..2) * 20 mm (linear between)
 *   103 friction (LuGre) p0 Fc N, p1 Fs N, p2 vs m/s, p3 sigma0 N/m, p4 sigma1 N s/m
 *   104 valve   p0 opening tau s, p1 closing tau s, p2 Cd slope against (1 - Pd/Pu), p3 outflow scale
 *   105 line    p0 tube volume m^3, p1 linear conductance kg/(s Pa)
 *   106 leak    p0 K kg/(s Pa^2): m = K (P2^2 - Pa^2)
 *   107 sensor  p0 first pressure lag s, p1 second pressure lag s, p2 height lag s,
 *               p3 P2 offset Pa, p4 pressure gain error (relative), p5 height offset m
 */
#include "effects.h"

#include <math.h>
#include <string.h>

enum { XE_T2 = 0, XE_T1 = 1, XE_TW = 2, XE_Z = 3, XE_PL = 4, XE_U = 4 };
/* XE_U (valve opening fractions) uses slots 4 and 5; the truth line uses slot 4: never both. */

typedef struct {
    int kind;
    int nparams;
    double lo[PLANT_FX_MAX_PARAMS], hi[PLANT_FX_MAX_PARAMS];
} fx_range;

/* Physical ranges (also the fitting bounds in effects.py; off values included). */
static const fx_range RANGES[] = {
    {PLANT_FX_THERMAL, 1, {0.0}, {600.0}},
    {PLANT_FX_AREA, 3, {-10.0, -1000.0, -0.3}, {10.0, 1000.0, 0.3}},
    {PLANT_FX_FRICTION, 3, {0.0, 0.0, 1e-5}, {2000.0, 2000.0, 1.0}},
    {PLANT_FX_VALVE, 4, {0.0, 0.0, 0.0, 0.05}, {1.0, 1.0, 0.9, 5.0}},
    {PLANT_FX_LINE, 2, {0.0, 0.0}, {1.2, 0.01}},
    {PLANT_FX_LEAK, 1, {0.0}, {1e-5}},
    {PLANT_FX_SENSOR, 4, {0.0, 0.0, -1e5, -0.05}, {10.0, 10.0, 1e5, 0.05}},
    {PLANT_FX_TRUTH + PLANT_FX_THERMAL, 3, {0.01, 0.01, 0.01}, {600.0, 6000.0, 1000.0}},
    {PLANT_FX_TRUTH + PLANT_FX_AREA, 5, {-0.5, -0.5, -0.5, -0.5, -0.5}, {0.5, 0.5, 0.5, 0.5, 0.5}},
    {PLANT_FX_TRUTH + PLANT_FX_FRICTION, 5, {0.0, 0.0, 1e-5, 1e3, 0.0}, {2000.0, 2000.0, 1.0, 1e8, 1e6}},
    {PLANT_FX_TRUTH + PLANT_FX_VALVE, 4, {1e-3, 1e-3, 0.0, 0.05}, {1.0, 1.0, 0.9, 5.0}},
    {PLANT_FX_TRUTH + PLANT_FX_LINE, 2, {1e-7, 1e-12}, {1e-2, 1e-3}},
    {PLANT_FX_TRUTH + PLANT_FX_LEAK, 1, {0.0}, {1e-12}},
    {PLANT_FX_TRUTH + PLANT_FX_SENSOR, 6, {0.0, 0.0, 0.0, -1e5, -0.5, -0.05}, {10.0, 10.0, 10.0, 1e5, 0.5, 0.05}},
};

static const fx_range *range_of(int kind)
{
    for (size_t i = 0; i < sizeof RANGES / sizeof RANGES[0]; i++)
        if (RANGES[i].kind == kind)
            return &RANGES[i];
    return NULL;
}

int plant_fx_init(plant_fx *f, const plant_params *p, const plant_fx_spec *fx)
{
    memset(f, 0, sizeof *f);
    plant_init(&f->pl, p);
    f->fx = *fx;
    if (fx->kind != PLANT_FX_NONE) {
        const fx_range *r = range_of(fx->kind);
        if (!r)
            return -1;
        for (int i = 0; i < r->nparams; i++)
            if (!(fx->p[i] >= r->lo[i] && fx->p[i] <= r->hi[i]))
                return -1;
    }
    f->y_ref_m = p->init_height_m;
    f->xe[XE_T2] = f->xe[XE_T1] = f->xe[XE_TW] = p->temperature_k;
    if (fx->kind == PLANT_FX_TRUTH + PLANT_FX_LINE)
        f->xe[XE_PL] = p->init_p_pipe_pa;
    f->pending_s[0] = f->pending_s[1] = -1.0;
    return 0;
}

static bool is_kind(const plant_fx *f, int kind) { return f->fx.kind == kind; }

/* Applies opening/closing delays (candidate valve) to the commanded valve states. */
static bool delayed_valve(plant_fx *f, int i, bool cmd)
{
    double open_d = f->fx.p[0], close_d = f->fx.p[1], t = f->pl.t_s;
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

void plant_fx_set_inputs(plant_fx *f, const plant_inputs *in)
{
    plant_inputs eff = *in;
    if (is_kind(f, PLANT_FX_VALVE)) {
        eff.spring_valve = delayed_valve(f, 0, in->spring_valve);
        eff.vent_valve = delayed_valve(f, 1, in->vent_valve);
    }
    f->cmd[0] = in->spring_valve; /* truth valve: the commanded state drives the opening fraction */
    f->cmd[1] = in->vent_valve;
    plant_set_inputs(&f->pl, &eff);
}

/* ISO 6358: m = m_choked(pu) * phi(r), phi = sqrt(1 - ((r - b)/(1 - b))^2) above b. */
static double iso6358_flow(const plant *pl, double cd_area, double pu, double pd, double b)
{
    if (pu <= pd)
        return 0.0;
    double m_choked = cd_area * pl->flow_choked * pu;
    double r = pd / pu;
    if (r <= b)
        return m_choked;
    double s = (r - b) / (1.0 - b);
    return m_choked * sqrt(fmax(0.0, 1.0 - s * s));
}

/* Mass flow pipe -> spring (+) through a valve of the given Cd A per direction. */
static double two_way(const plant *pl, double cda_fwd, double cda_back, double pa, double pb, double b)
{
    if (b > 0.0)
        return pa > pb ? iso6358_flow(pl, cda_fwd, pa, pb, b) : -iso6358_flow(pl, cda_back, pb, pa, b);
    return pa > pb ? plant_orifice_flow(pl, cda_fwd, pa, pb) : -plant_orifice_flow(pl, cda_back, pb, pa);
}

/* Relative area correction and its slope at height y. */
static double area_scale(const plant_fx *f, double y)
{
    double d = y - f->y_ref_m;
    if (is_kind(f, PLANT_FX_AREA)) {
        /* the rolling lobe's area stops changing past +-50 mm */
        d = fmax(-0.05, fmin(0.05, d));
        return 1.0 + f->fx.p[2] + f->fx.p[0] * d + f->fx.p[1] * d * d;
    }
    /* truth: piecewise linear over knots y_ref + (-2..2) * 20 mm, flat outside */
    double u = d / 0.020 + 2.0;
    if (u <= 0.0)
        return 1.0 + f->fx.p[0];
    if (u >= 4.0)
        return 1.0 + f->fx.p[4];
    int k = (int)u;
    double w = u - k;
    return 1.0 + (1.0 - w) * f->fx.p[k] + w * f->fx.p[k + 1];
}

static double sgn(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

/* LuGre's Stribeck curve g(v) = Fc + Fs exp(-(v/vs)^2), never below 1 mN. */
static double lugre_g(const double *q, double v)
{
    return fmax(q[0] + q[1] * exp(-(v / q[2]) * (v / q[2])), 1e-3);
}

/* Exact bristle update over h at constant velocity v:
 * z -> z_ss + (z - z_ss) exp(-s0 |v| h / g), z_ss = g sign(v) / s0. Unconditionally stable. */
static double lugre_z_update(const double *q, double z, double v, double h)
{
    if (v == 0.0)
        return z;
    double g = lugre_g(q, v);
    double z_ss = g * sgn(v) / q[3];
    return z_ss + (z - z_ss) * exp(-q[3] * fabs(v) * h / g);
}

static void fx_derivatives(const plant_fx *f, const double *x, double *dx)
{
    const plant *pl = &f->pl;
    const plant_params *p = &pl->p;
    plant_flows fl;
    plant_derivatives(pl, x, dx, &fl);
    const double *xe = x + PLANT_NX;
    double *dxe = dx + PLANT_NX;
    for (int i = 0; i < PLANT_FX_NX; i++)
        dxe[i] = 0.0;
    const double pa = p->ambient_pa, p1 = x[PLANT_X_P1], p2 = x[PLANT_X_P2];
    const double v2 = x[PLANT_X_V2], y = x[PLANT_X_Y], vel = x[PLANT_X_VEL];
    const double zn = pl->zn, rt = pl->rt, v1 = p->pipe_volume_m3;
    const double *q = f->fx.p;
    /* net force on the platform other than what we add, N */
    double m_s_new = fl.spring_valve, m_v_new = fl.vent_valve, m_c_new = fl.compressor;

    switch (f->fx.kind) {
    case PLANT_FX_THERMAL:
    case PLANT_FX_TRUTH + PLANT_FX_THERMAL: {
        if (!(q[0] > 0.0))
            return; /* off: the fixed polytropic exponent */
        /* Energy balance of the gas in spring and pipe (ideal gas, U = P V/(k-1)):
         *   dP/dt = Z k (R T_src m - P dV/dt)/V + P (Tw - T)/(T tau)
         *   dT/dt = T (dP/P + dV/V) - m R T^2/(P V)
         * in place of the fixed exponent n. Inflow from the compressor at ambient. */
        double k = p->heat_ratio_k, z = p->compressibility, r = p->gas_constant_j_per_kg_k;
        double t2 = xe[XE_T2], t1 = xe[XE_T1];
        double tw = is_kind(f, PLANT_FX_THERMAL) ? p->temperature_k : xe[XE_TW];
        double tau = q[0];
        double m_s = fl.spring_valve, m_v = fl.vent_valve, m_c = fl.compressor;
        double dv2 = dx[PLANT_X_V2];
        double t_s_src = m_s > 0.0 ? t1 : t2; /* gas crossing the solenoid valve */
        double d_p2 = z * k * (r * t_s_src * m_s - p2 * dv2) / v2 + p2 * (tw - t2) / (t2 * tau);
        double d_t2 = t2 * (d_p2 / p2 + dv2 / v2) - m_s * r * t2 * t2 / (p2 * v2);
        double d_p1 = z * k * r * (p->temperature_k * m_c - t_s_src * m_s - t1 * m_v) / v1 +
                      p1 * (p->temperature_k - t1) / (t1 * tau);
        double d_t1 = t1 * d_p1 / p1 - (m_c - m_s - m_v) * r * t1 * t1 / (p1 * v1);
        dx[PLANT_X_P2] = d_p2;
        dx[PLANT_X_P1] = d_p1;
        dxe[XE_T2] = d_t2;
        dxe[XE_T1] = d_t1;
        if (!is_kind(f, PLANT_FX_THERMAL)) {
            /* wall: heated by the gas (capacity ratio q2), cooled by the room (tau q1) */
            dxe[XE_TW] = (t2 - tw) / (tau * q[2]) + (p->temperature_k - tw) / q[1];
        }
        return;
    }
    case PLANT_FX_AREA:
    case PLANT_FX_TRUTH + PLANT_FX_AREA: {
        /* Area scaled by s(y): volume rate and pressure force scale with it. */
        double s = area_scale(f, y);
        double dv2_nom = dx[PLANT_X_V2];
        double dv2 = dv2_nom * s;
        dx[PLANT_X_V2] = dv2;
        dx[PLANT_X_P2] -= zn * p2 * (dv2 - dv2_nom) / v2;
        double f_press = dx[PLANT_X_VEL] * pl->mass_kg + pl->damping_n_s_per_m * vel;
        dx[PLANT_X_VEL] += f_press * (s - 1.0) / pl->mass_kg;
        return;
    }
    case PLANT_FX_FRICTION: {
        /* Coulomb + Stribeck; below 0.1 mm/s the guide sticks up to Fc + Fs. */
        double f_other = dx[PLANT_X_VEL] * pl->mass_kg;
        double fs = q[0] + q[1];
        if (!(fs > 0.0))
            return; /* off */
        double ff;
        if (fabs(vel) < 1e-4) {
            ff = -fmax(-fs, fmin(fs, f_other)) - 2.0e5 * vel;
        } else {
            ff = -sgn(vel) * (q[0] + q[1] * exp(-(vel / q[2]) * (vel / q[2])));
        }
        dx[PLANT_X_VEL] += ff / pl->mass_kg;
        return;
    }
    case PLANT_FX_TRUTH + PLANT_FX_FRICTION: {
        /* LuGre: dz/dt = v - s0 |v| z / g(v), F = s0 z + s1 dz/dt (opposes motion).
         * The bristle state is stiff at speed (s0 |v| / g up to thousands per second),
         * so it is held within an RK4 step and advanced exactly after it (lugre_z_update). */
        double g = lugre_g(q, vel);
        double z = xe[XE_Z];
        double dz = vel - q[3] * fabs(vel) * z / g;
        double ff = -(q[3] * z + q[4] * dz);
        dx[PLANT_X_VEL] += ff / pl->mass_kg;
        return;
    }
    case PLANT_FX_VALVE: {
        if (q[2] > 0.0 || q[3] != 1.0) {
            double a = pl->spring_valve_area_m2;
            m_s_new = pl->in.spring_valve ? two_way(pl, p->spring_valve_cd_in * a, p->spring_valve_cd_out * a * q[3],
                                                    p1, p2, q[2]) : 0.0;
            m_v_new = pl->in.vent_valve ? two_way(pl, p->vent_valve_cd * pl->vent_valve_area_m2 * q[3],
                                                  p->vent_valve_cd * pl->vent_valve_area_m2, p1, pa, q[2]) : 0.0;
        }
        break;
    }
    case PLANT_FX_TRUTH + PLANT_FX_VALVE: {
        /* Opening fractions u follow the command with first-order lags; Cd falls
         * linearly with (1 - Pd/Pu) (slope q2); outflows scaled by q3. */
        for (int i = 0; i < 2; i++) {
            double u = xe[XE_U + i], target = f->cmd[i] ? 1.0 : 0.0;
            dxe[XE_U + i] = (target - u) / (target > u ? q[0] : q[1]);
        }
        double us = fmin(1.0, fmax(0.0, xe[XE_U])), uv = fmin(1.0, fmax(0.0, xe[XE_U + 1]));
        double a = pl->spring_valve_area_m2;
        double hi = fmax(p1, p2), lo = fmin(p1, p2);
        double cd_scale = 1.0 - q[2] * (1.0 - lo / hi);
        m_s_new = us * cd_scale * two_way(pl, p->spring_valve_cd_in * a, p->spring_valve_cd_out * a * q[3], p1, p2, 0.0);
        double cdv = 1.0 - q[2] * (1.0 - fmin(pa, p1) / fmax(pa, p1));
        m_v_new = uv * cdv * two_way(pl, p->vent_valve_cd * pl->vent_valve_area_m2 * q[3],
                                     p->vent_valve_cd * pl->vent_valve_area_m2, p1, pa, 0.0);
        break;
    }
    case PLANT_FX_LINE:
        /* The compressor's flow reaches the junction after the transport delay q0;
         * the tube adds its dead volume q1 to the junction (pipe) volume. */
        if (q[0] > 0.0)
            m_c_new = f->mc_delayed;
        break;
    case PLANT_FX_TRUTH + PLANT_FX_LINE: {
        /* Compressor -> tube volume q0 -> laminar conductance q1 -> junction. */
        double pl_pa = xe[XE_PL];
        double m_line = q[1] * (pl_pa - p1);
        dxe[XE_PL] = zn * rt * (fl.compressor - m_line) / q[0];
        m_c_new = m_line;
        break;
    }
    case PLANT_FX_LEAK: {
        double m_leak = plant_orifice_flow(pl, q[0], p2, pa);
        dx[PLANT_X_P2] -= zn * rt * m_leak / v2;
        return;
    }
    case PLANT_FX_TRUTH + PLANT_FX_LEAK: {
        double m_leak = p2 > pa ? q[0] * (p2 * p2 - pa * pa) : 0.0;
        dx[PLANT_X_P2] -= zn * rt * m_leak / v2;
        return;
    }
    default:
        return;
    }
    /* Flow corrections: the pressure equations of plant.c with the new flows. */
    dx[PLANT_X_P1] += zn * rt * ((m_c_new - fl.compressor) - (m_s_new - fl.spring_valve) - (m_v_new - fl.vent_valve)) / v1;
    dx[PLANT_X_P2] += zn * rt * (m_s_new - fl.spring_valve) / v2;
    if (f->fx.kind == PLANT_FX_LINE)
        dx[PLANT_X_P1] *= v1 / (v1 + q[1]);
}

static void fx_rhs(const void *ctx, const double *x, double *dx)
{
    fx_derivatives(ctx, x, dx);
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
    plant_rk4_step(pl, x, N, fx_rhs, f, h);
    if (f->fx.kind == PLANT_FX_TRUTH + PLANT_FX_FRICTION)
        x[PLANT_NX + XE_Z] = lugre_z_update(f->fx.p, f->xe[XE_Z], 0.5 * (vel + x[PLANT_X_VEL]), h);
    memcpy(pl->x, x, sizeof pl->x);
    memcpy(f->xe, x + PLANT_NX, sizeof f->xe);
}

static double lag(double state, double target, double tau, double dt)
{
    return tau > 1e-6 ? state + (target - state) * (1.0 - exp(-dt / tau)) : target;
}

void plant_fx_advance(plant_fx *f, double dt_s, int substeps)
{
    if (f->fx.kind == PLANT_FX_NONE) {
        plant_advance(&f->pl, dt_s, substeps);
    } else {
        if (substeps < 1)
            substeps = 1;
        for (int i = 0; i < substeps; i++)
            rk4_step(f, dt_s / substeps);
    }
    /* transport delay: compressor flow of this tick, read back delay/dt ticks later */
    if (is_kind(f, PLANT_FX_LINE)) {
        double dx[PLANT_NX];
        plant_flows fl;
        plant_derivatives(&f->pl, f->pl.x, dx, &fl);
        int d = (int)lround(f->fx.p[0] / dt_s);
        if (d > PLANT_FX_DELAY_TICKS - 1)
            d = PLANT_FX_DELAY_TICKS - 1;
        f->mc_head = (f->mc_head + 1) % PLANT_FX_DELAY_TICKS;
        f->mc_buf[f->mc_head] = fl.compressor;
        f->mc_delayed = f->mc_buf[(f->mc_head - d + PLANT_FX_DELAY_TICKS) % PLANT_FX_DELAY_TICKS];
    }
    /* transducer filters */
    const plant *pl = &f->pl;
    double raw[4] = {pl->x[PLANT_X_Y], pl->x[PLANT_X_P2], pl->x[PLANT_X_P1],
                     pl->p.acc_type == PLANT_ACC_NONE ? pl->p.ambient_pa : pl->x[PLANT_X_P3]};
    if (!f->sens_ready) {
        for (int c = 0; c < 4; c++)
            f->sens[c][0] = f->sens[c][1] = raw[c];
        f->sens_ready = true;
        return;
    }
    const double *q = f->fx.p;
    if (is_kind(f, PLANT_FX_SENSOR)) {
        f->sens[0][0] = lag(f->sens[0][0], raw[0], q[1], dt_s);
        for (int c = 1; c < 4; c++)
            f->sens[c][0] = lag(f->sens[c][0], raw[c], q[0], dt_s);
    } else if (is_kind(f, PLANT_FX_TRUTH + PLANT_FX_SENSOR)) {
        f->sens[0][0] = lag(f->sens[0][0], raw[0], q[2], dt_s);
        for (int c = 1; c < 4; c++) {
            f->sens[c][0] = lag(f->sens[c][0], raw[c], q[0], dt_s);
            f->sens[c][1] = lag(f->sens[c][1], f->sens[c][0], q[1], dt_s);
        }
    }
}

void plant_fx_sensed(const plant_fx *f, double out[4])
{
    const plant *pl = &f->pl;
    out[0] = pl->x[PLANT_X_Y];
    out[1] = pl->x[PLANT_X_P2];
    out[2] = pl->x[PLANT_X_P1];
    out[3] = pl->p.acc_type == PLANT_ACC_NONE ? pl->p.ambient_pa : pl->x[PLANT_X_P3];
    const double *q = f->fx.p;
    if (is_kind(f, PLANT_FX_SENSOR) && f->sens_ready) {
        for (int c = 0; c < 4; c++)
            out[c] = f->sens[c][0];
        out[1] += q[2];
        out[0] += q[3];
    } else if (is_kind(f, PLANT_FX_TRUTH + PLANT_FX_SENSOR) && f->sens_ready) {
        out[0] = f->sens[0][0] + q[5];
        for (int c = 1; c < 4; c++) {
            double pa = pl->p.ambient_pa;
            out[c] = pa + (f->sens[c][1] - pa) * (1.0 + q[4]);
        }
        out[1] += q[3];
    }
}
