/*
 * Plant model: the equations of Chapter III in SI (plant.h).
 *
 * Pressure equations (eq. 16, 17, 31/32) with beta = Z n P and weight flow
 * taken as mass flow (g = gc):
 *   dP1/dt = Z n R T (m_c - m_s - m_v - m_a) / V1
 *   dP2/dt = Z n (R T m_s - P2 dV2/dt) / V2,       dV2/dt = A(y, load) v
 *   dP3/dt = R T m_a / (V3/(Z n) + P3 dV3/dP3)      (tube: dV3/dP3 = 0)
 * Motor (eq. 15, the program's alp): J dw/dt = Kt e - B w - c Dc (P1 - Pa).
 * Compressor (eq. 20): m_c = P1 (Dc w - Cc (P1 - Pa)) / (R T) while the motor runs.
 * Platform (eq. 27): m dv/dt = (P2 - Pa - Plimit) A - B v, with Plimit = UPlimit
 * above the upper line, DPlimit below the lower one, and no pressure force in
 * between (only damping).
 */
#include "plant.h"

#include <math.h>
#include <string.h>

#define PLANT_PI 3.14159265358979323846

static double poly(const double *c, int n, double x)
{
    double acc = 0.0;
    for (int i = n - 1; i >= 0; i--)
        acc = acc * x + c[i];
    return acc;
}

static void area_coefficients(const plant_params *p, double load_n, double *cc1_m2, double *cc2_m2_per_m)
{
    /* Thesis polynomial: DL = load in lbf / 100, CC1 in in^2, CC2 in in^2/in. */
    double dl = load_n / PLANT_N_PER_LBF / 100.0;
    double cc1_in2 = poly(p->area_cc1_in2, p->area_cc1_terms, dl);
    double cc2_in2_per_in = poly(p->area_cc2_in2_per_in, p->area_cc2_terms, dl);
    *cc1_m2 = cc1_in2 * PLANT_M_PER_IN * PLANT_M_PER_IN;
    *cc2_m2_per_m = cc2_in2_per_in * PLANT_M_PER_IN; /* in^2/in -> m^2/m */
}

double plant_effective_area_m2(const plant_params *p, double load_n, double y_m)
{
    double cc1, cc2;
    area_coefficients(p, load_n, &cc1, &cc2);
    return cc1 + cc2 * y_m;
}

double plant_spring_volume_at(const plant_params *p, double load_n, double y_m)
{
    /* dV2 = Ae dy with Ae = cc1 + cc2 y (eq. 17), integrated exactly */
    double cc1, cc2, y0 = p->init_height_m;
    area_coefficients(p, load_n, &cc1, &cc2);
    return p->spring_volume0_m3 + cc1 * (y_m - y0) + 0.5 * cc2 * (y_m * y_m - y0 * y0);
}

const plant_hysteresis_band *plant_band_for_load(const plant_params *p, double load_n)
{
    /* Smallest load_below above the load; else the band with the largest load_below. */
    const plant_hysteresis_band *best = NULL, *largest = NULL;
    for (int i = 0; i < p->band_count; i++) {
        const plant_hysteresis_band *b = &p->bands[i];
        if (!largest || b->load_below_n > largest->load_below_n)
            largest = b;
        if (load_n < b->load_below_n && (!best || b->load_below_n < best->load_below_n))
            best = b;
    }
    return best ? best : largest;
}

double plant_up_limit_pag(const plant_hysteresis_band *b, double y_m)
{
    return b->up_slope_pa_per_m * y_m + b->up_intercept_pag;
}

double plant_down_limit_pag(const plant_hysteresis_band *b, double y_m)
{
    return plant_up_limit_pag(b, y_m) - b->down_offset_pa;
}

void plant_diaphragm_volume(const plant_params *p, double p3_pa, double *v_m3, double *dv_dp_m3_per_pa)
{
    /* Piecewise linear in P3 (the config's segments; thesis: figure 22 as the
     * program has it, continuous at its breakpoints). */
    int i = 0;
    while (i < p->diaphragm_segments - 1 && p3_pa >= p->diaphragm_break_pa[i])
        i++;
    *dv_dp_m3_per_pa = p->diaphragm_slope_m3_per_pa[i];
    *v_m3 = p->diaphragm_slope_m3_per_pa[i] * p3_pa + p->diaphragm_intercept_m3[i];
}

double plant_acc_volume_m3(const plant *pl)
{
    if (pl->p.acc_type == PLANT_ACC_DIAPHRAGM) {
        double v, dv;
        plant_diaphragm_volume(&pl->p, pl->x[PLANT_X_P_ACC], &v, &dv);
        return v;
    }
    return pl->p.acc_volume_m3;
}

_Static_assert(PLANT_ORIFICE_DEGREE == 6, "orifice_shape's Estrin scheme is written for degree 6");

/* The shape for crit_ratio <= r <= 1 (outside, the end segments' polynomials), s/m (kg/s per Pa m^2). */
static double orifice_shape(const plant *pl, double r)
{
    double u = (r - pl->crit_ratio) * pl->orifice_scale;
    /* a NaN ratio (a state blown up in a fit's wild trial) takes segment 0 and returns NaN, not a wild read */
    int s = u > 0.0 ? (u < PLANT_ORIFICE_SEGMENTS ? (int)u : PLANT_ORIFICE_SEGMENTS - 1) : 0;
    double t = u - s - 0.5;
    const double *c = pl->orifice_c[s];
    /* Estrin's scheme: half the dependent steps of Horner's (this call sits on the derivatives' path) */
    double t2 = t * t, t4 = t2 * t2;
    return (c[0] + c[1] * t) + t2 * (c[2] + c[3] * t) + t4 * ((c[4] + c[5] * t) + t2 * c[6]);
}

/* The shape at r in long double: r^(1/k) sqrt((1 - r^((k-1)/k)) / (1 - r)) times sqrt(2k/((k-1) R T)),
 * the difference by expm1 (no cancellation near 1), its limit (k-1)/k at 1. */
static long double orifice_shape_exact(long double r, long double k, long double rt)
{
    long double a = (k - 1.0L) / k;
    long double ratio = r < 1.0L ? -expm1l(a * logl(r)) / (1.0L - r) : a;
    return powl(r, 1.0L / k) * sqrtl(ratio * 2.0L * k / ((k - 1.0L) * rt));
}

/* One segment's polynomial in t = -1/2..1/2 (r = r0 + (t + 1/2) / scale, centred: smaller terms, less
 * rounding): the Newton form through the shape at the Chebyshev nodes, expanded to powers of t, in long
 * double and rounded once. */
static void orifice_segment(double r0, double scale, double k, double rt, double c[PLANT_ORIFICE_DEGREE + 1])
{
    enum { N = PLANT_ORIFICE_DEGREE + 1 };
    long double t[N], d[N], q[N] = {1.0L}, cl[N] = {0.0L};
    for (int i = 0; i < N; i++) {
        t[i] = -0.5L * cosl((2 * i + 1) * PLANT_PI / (2 * N));
        d[i] = orifice_shape_exact(r0 + (t[i] + 0.5L) / scale, k, rt);
    }
    for (int j = 1; j < N; j++)
        for (int i = N - 1; i >= j; i--)
            d[i] = (d[i] - d[i - 1]) / (t[i] - t[i - j]);
    for (int j = 0; j < N; j++) { /* c += d[j] q, then q *= (t - t[j]) */
        for (int i = 0; i < N; i++)
            cl[i] += d[j] * q[i];
        for (int i = N - 1; i >= 0; i--)
            q[i] = (i > 0 ? q[i - 1] : 0.0L) - t[j] * q[i];
    }
    for (int i = 0; i < N; i++)
        c[i] = (double)cl[i];
}

/* The table depends on k and R T alone, and a diagnosis sets up some 15,000 plants with the same gas:
 * the last one built is kept (per thread): building it in long double, about 80 us, was 4 % of a diagnosis. */
static _Thread_local struct {
    bool built;
    double k, rt;
    double c[PLANT_ORIFICE_SEGMENTS][PLANT_ORIFICE_DEGREE + 1];
} last_table;

static void orifice_table(plant *pl)
{
    double k = pl->p.heat_ratio_k;
    pl->orifice_scale = PLANT_ORIFICE_SEGMENTS / (1.0 - pl->crit_ratio);
    if (!last_table.built || last_table.k != k || last_table.rt != pl->rt) {
        for (int s = 0; s < PLANT_ORIFICE_SEGMENTS; s++)
            orifice_segment(pl->crit_ratio + s / pl->orifice_scale, pl->orifice_scale, k, pl->rt, last_table.c[s]);
        last_table.k = k;
        last_table.rt = pl->rt;
        last_table.built = true;
    }
    memcpy(pl->orifice_c, last_table.c, sizeof pl->orifice_c);
}

double plant_orifice_flow(const plant *pl, double cd_area_m2, double pu_pa, double pd_pa)
{
    /* Eq. (8)/(9). Eq. (8) has the exponent 1/k on the pressure ratio; the
     * program of Appendix B uses (k-1)/k in its solenoid and vent branches.
     * We follow eq. (8): with 1/k the flow is continuous at the critical ratio.
     * Subsonic: Cd A Pu sqrt(1 - r) times the shape (plant.h); the square
     * root runs beside the shape's polynomial, not after it. */
    if (pu_pa <= pd_pa)
        return 0.0;
    double r = pd_pa / pu_pa;
    if (r <= pl->crit_ratio)
        return cd_area_m2 * pl->flow_choked * pu_pa;
    return cd_area_m2 * pu_pa * sqrt(1.0 - r) * orifice_shape(pl, r);
}

double plant_motor_steady_speed(const plant_params *p, double p1_pa, double duty)
{
    double drive = duty * p->motor_torque_constant_nm_per_v * p->motor_supply_v;
    double load = p->motor_torque_coefficient * p->compressor_capacity_m3_per_rad * (p1_pa - p->ambient_pa);
    if (!(p->motor_damping_nm_s > 0.0) || drive <= load)
        return 0.0;
    return (drive - load) / p->motor_damping_nm_s;
}

void plant_derivatives(const plant *pl, const double x[PLANT_NX], double dxdt[PLANT_NX], plant_flows *flows)
{
    const plant_params *p = &pl->p;
    const plant_inputs *in = &pl->in;
    const double pa = p->ambient_pa;
    double omega = x[PLANT_X_OMEGA], p1 = x[PLANT_X_P_PIPE], p2 = x[PLANT_X_P_SPRING], p3 = x[PLANT_X_P_ACC];
    double v2 = x[PLANT_X_V2], y = x[PLANT_X_Y], vel = x[PLANT_X_VEL];

    /* Motor (the program's alp): the pressure torque acts only while turning forward. */
    double torque = in->compressor ? p->motor_torque_constant_nm_per_v * p->motor_supply_v : 0.0;
    double alpha;
    if (omega > 1e-6)
        torque -= p->motor_damping_nm_s * omega +
                  p->motor_torque_coefficient * p->compressor_capacity_m3_per_rad * (p1 - pa);
    else if (omega < -1e-6)
        torque -= p->motor_damping_nm_s * omega;
    alpha = torque * pl->inv_inertia;

    /* Compressor delivers only while the motor is switched on and turning. */
    double m_c = 0.0;
    if (in->compressor && omega > 1e-4) {
        double q = p->compressor_capacity_m3_per_rad * omega;
        if (p1 > pa)
            q -= p->compressor_leakage_m3_per_pa_s * (p1 - pa);
        m_c = p1 * q * pl->inv_rt;
    }

    /* Spring solenoid valve: its own Cd for each direction. Closed valves cost nothing. */
    double m_s = 0.0;
    if (in->spring_valve) {
        if (p1 > p2)
            m_s = plant_orifice_flow(pl, p->spring_valve_cd_in * pl->spring_valve_area_m2, p1, p2);
        else if (p2 > p1)
            m_s = -plant_orifice_flow(pl, p->spring_valve_cd_out * pl->spring_valve_area_m2, p2, p1);
    }
    double m_v = 0.0;
    if (in->vent_valve) {
        double cda = p->vent_valve_cd * pl->vent_valve_area_m2;
        m_v = p1 > pa ? plant_orifice_flow(pl, cda, p1, pa) : -plant_orifice_flow(pl, cda, pa, p1);
    }
    double m_a = 0.0;
    if (in->acc_valve && p->acc_type != PLANT_ACC_NONE) {
        double cda = p->acc_valve_cd * pl->acc_valve_area_m2;
        m_a = p1 > p3 ? plant_orifice_flow(pl, cda, p1, p3) : -plant_orifice_flow(pl, cda, p3, p1);
    }

    /* Air spring geometry at this height and the current load. */
    double area = pl->area_cc1_m2 + pl->area_cc2_m2_per_m * y;
    double dv2 = area * vel;

    /* Hysteresis force law (eq. 27). */
    double pg = p2 - pa;
    double up = plant_up_limit_pag(pl->band, y);
    double down = up - pl->band->down_offset_pa;
    double force = 0.0;
    if (pg > up)
        force = (pg - up) * area;
    else if (pg < down)
        force = (pg - down) * area;
    force -= pl->damping_n_s_per_m * vel;


    double d_p1 = pl->zn_rt_per_v1 * (m_c - m_s - m_v - m_a);
    double d_p2 = pl->zn * (pl->rt * m_s - p2 * dv2) / v2;
    double d_p3 = 0.0;
    if (m_a != 0.0) {
        if (p->acc_type == PLANT_ACC_DIAPHRAGM) {
            double v3, dv3;
            plant_diaphragm_volume(p, p3, &v3, &dv3);
            d_p3 = pl->rt * m_a / (v3 / pl->zn + p3 * dv3);
        } else {
            d_p3 = pl->zn * pl->rt * m_a / p->acc_volume_m3;
        }
    }

    dxdt[PLANT_X_OMEGA] = alpha;
    dxdt[PLANT_X_P_PIPE] = d_p1;
    dxdt[PLANT_X_P_SPRING] = d_p2;
    dxdt[PLANT_X_P_ACC] = d_p3;
    dxdt[PLANT_X_V2] = dv2;
    dxdt[PLANT_X_Y] = vel;
    dxdt[PLANT_X_VEL] = force * pl->inv_mass;
    if (flows) {
        flows->compressor = m_c;
        flows->spring_valve = m_s;
        flows->vent_valve = m_v;
        flows->acc_valve = m_a;
    }
}

static void update_load(plant *pl, double load_n)
{
    pl->load_cached_n = load_n;
    pl->mass_kg = load_n / PLANT_STANDARD_GRAVITY + pl->p.extra_mass_kg;
    pl->inv_mass = 1.0 / pl->mass_kg;
    area_coefficients(&pl->p, load_n, &pl->area_cc1_m2, &pl->area_cc2_m2_per_m);
    pl->band = plant_band_for_load(&pl->p, load_n);
}

void plant_init(plant *pl, const plant_params *p)
{
    memset(pl, 0, sizeof *pl);
    pl->p = *p;
    double k = p->heat_ratio_k;
    pl->crit_ratio = pow(2.0 / (k + 1.0), k / (k - 1.0));
    pl->rt = p->gas_constant_j_per_kg_k * p->temperature_k;
    orifice_table(pl);
    pl->zn = p->compressibility * p->polytropic_n;
    /* reciprocals: the derivatives multiply (they run 4x per RK4 step) */
    pl->inv_rt = 1.0 / pl->rt;
    pl->inv_inertia = 1.0 / p->motor_inertia_kg_m2;
    pl->zn_rt_per_v1 = pl->zn * pl->rt / p->pipe_volume_m3;
    pl->flow_choked = sqrt(k / pl->rt) * pow(2.0 / (k + 1.0), (k + 1.0) / (2.0 * (k - 1.0)));
    pl->spring_valve_area_m2 = PLANT_PI / 4.0 * p->spring_valve_diameter_m * p->spring_valve_diameter_m;
    pl->vent_valve_area_m2 = PLANT_PI / 4.0 * p->vent_valve_diameter_m * p->vent_valve_diameter_m;
    pl->acc_valve_area_m2 = PLANT_PI / 4.0 * p->acc_valve_diameter_m * p->acc_valve_diameter_m;
    pl->x[PLANT_X_OMEGA] = p->init_motor_speed_rad_per_s;
    pl->x[PLANT_X_P_PIPE] = p->init_p_pipe_pa;
    pl->x[PLANT_X_P_SPRING] = p->init_p_spring_pa;
    pl->x[PLANT_X_P_ACC] = p->acc_type == PLANT_ACC_NONE ? p->ambient_pa : p->acc_charge_pa;
    pl->x[PLANT_X_V2] = p->spring_volume0_m3;
    pl->x[PLANT_X_Y] = p->init_height_m;
    pl->x[PLANT_X_VEL] = p->init_velocity_m_per_s;
    /* Program: B is only assigned from the velocity, starting from 0 (Pascal globals). */
    pl->damping_n_s_per_m = 0.0;
    update_load(pl, 0.0);
}

void plant_set_inputs(plant *pl, const plant_inputs *in)
{
    pl->in = *in;
    if (in->load_n != pl->load_cached_n)
        update_load(pl, in->load_n);
}

/* On an end stop the stop's reaction cancels whatever pushes the platform
 * further into it: no acceleration into the stop, so the platform stays and
 * the spring's volume with it. (A clamp after the step alone let the velocity
 * grow again each step and kept the volume swept past the stop: the spring
 * swelled on the stop at a rate set by the step size.) */
static void pin_at_stops(const plant *pl, const double *x, double *dxdt)
{
    double y = x[PLANT_X_Y], vel = x[PLANT_X_VEL], acc = dxdt[PLANT_X_VEL];
    if ((y >= pl->p.height_max_m && vel >= 0.0 && acc > 0.0) ||
        (y <= pl->p.height_min_m && vel <= 0.0 && acc < 0.0))
        dxdt[PLANT_X_VEL] = 0.0;
}

/* A step that carried the platform past a stop: the platform stops there, and
 * the volume it swept beyond the stop is given back along the spring's
 * polytrope P2 V2^(Z n) = const (the closed spring's law over that instant). */
static void end_stops(const plant *pl, double *x)
{
    double y = x[PLANT_X_Y], stop;
    if (y > pl->p.height_max_m)
        stop = pl->p.height_max_m;
    else if (y < pl->p.height_min_m)
        stop = pl->p.height_min_m;
    else
        return;
    double area = pl->area_cc1_m2 + pl->area_cc2_m2_per_m * 0.5 * (y + stop);
    double v_old = x[PLANT_X_V2], v_new = v_old - area * (y - stop);
    x[PLANT_X_P_SPRING] *= pow(v_old / v_new, pl->zn);
    x[PLANT_X_V2] = v_new;
    x[PLANT_X_Y] = stop;
    if ((y > stop && x[PLANT_X_VEL] > 0.0) || (y < stop && x[PLANT_X_VEL] < 0.0))
        x[PLANT_X_VEL] = 0.0;
}

void plant_rk4_step(plant *pl, double *x, int n, plant_rhs_fn rhs, const void *ctx, double h)
{
    /* Damping follows the direction of motion at the start of the step; while
     * the platform is (nearly) at rest the last value is kept (the program). */
    double vel = x[PLANT_X_VEL];
    if (vel > pl->p.velocity_deadband_m_per_s)
        pl->damping_n_s_per_m = pl->p.damping_up_n_s_per_m;
    else if (vel < -pl->p.velocity_deadband_m_per_s)
        pl->damping_n_s_per_m = pl->p.damping_down_n_s_per_m;

    double k1[PLANT_RK4_MAX_NX], k2[PLANT_RK4_MAX_NX], k3[PLANT_RK4_MAX_NX], k4[PLANT_RK4_MAX_NX];
    double xt[PLANT_RK4_MAX_NX];
    rhs(ctx, x, k1);
    pin_at_stops(pl, x, k1);
    for (int i = 0; i < n; i++)
        xt[i] = x[i] + 0.5 * h * k1[i];
    rhs(ctx, xt, k2);
    pin_at_stops(pl, xt, k2);
    for (int i = 0; i < n; i++)
        xt[i] = x[i] + 0.5 * h * k2[i];
    rhs(ctx, xt, k3);
    pin_at_stops(pl, xt, k3);
    for (int i = 0; i < n; i++)
        xt[i] = x[i] + h * k3[i];
    rhs(ctx, xt, k4);
    pin_at_stops(pl, xt, k4);
    for (int i = 0; i < n; i++)
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    pl->t_s += h;
    end_stops(pl, x);
}

static void nominal_rhs(const void *ctx, const double *x, double *dxdt)
{
    plant_derivatives(ctx, x, dxdt, NULL);
}

void plant_step(plant *pl, double h)
{
    plant_rk4_step(pl, pl->x, PLANT_NX, nominal_rhs, pl, h);
}

void plant_advance(plant *pl, double dt_s, int substeps)
{
    if (substeps < 1)
        substeps = 1;
    double h = dt_s / substeps;
    for (int i = 0; i < substeps; i++)
        plant_step(pl, h);
}

/* ---- sensors ---- */

void plant_rng_seed(plant_rng *r, uint32_t seed)
{
    /* splitmix64 of the seed, so that seed 0 is fine too */
    uint64_t z = (uint64_t)seed + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    r->s = (z ^ (z >> 31)) | 1u;
    r->have_spare = false;
    r->spare = 0.0;
}

static double rng_uniform(plant_rng *r)
{
    r->s ^= r->s >> 12;
    r->s ^= r->s << 25;
    r->s ^= r->s >> 27;
    uint64_t v = r->s * 0x2545F4914F6CDD1Dull;
    return ((double)(v >> 11) + 0.5) * (1.0 / 9007199254740992.0); /* (0,1) */
}

static double rng_gauss(plant_rng *r)
{
    if (r->have_spare) {
        r->have_spare = false;
        return r->spare;
    }
    double u1 = rng_uniform(r), u2 = rng_uniform(r);
    double mag = sqrt(-2.0 * log(u1));
    r->spare = mag * sin(2.0 * PLANT_PI * u2);
    r->have_spare = true;
    return mag * cos(2.0 * PLANT_PI * u2);
}

static uint16_t to_counts(double value, double eng_lo, double eng_hi, double raw_lo, double raw_hi,
                          double noise_sd, plant_rng *rng)
{
    double c = raw_lo + (value - eng_lo) * (raw_hi - raw_lo) / (eng_hi - eng_lo);
    if (noise_sd > 0.0 && rng)
        c += noise_sd * rng_gauss(rng);
    c = floor(c + 0.5);
    if (c < 0.0)
        c = 0.0;
    if (c > 4095.0)
        c = 4095.0;
    return (uint16_t)c;
}

void plant_sensed(const plant *pl, double out[4])
{
    out[0] = pl->x[PLANT_X_Y];
    out[1] = pl->x[PLANT_X_P_SPRING];
    out[2] = pl->x[PLANT_X_P_PIPE];
    out[3] = pl->p.acc_type == PLANT_ACC_NONE ? pl->p.ambient_pa : pl->x[PLANT_X_P_ACC];
}

void plant_counts(const plant_sensor_params *sp, const double sensed[4], plant_rng *rng, uint16_t counts[4])
{
    counts[0] = to_counts(sensed[0], sp->height_lo_m, sp->height_hi_m, sp->height_lo_counts,
                          sp->height_hi_counts, sp->noise_counts, rng);
    for (int i = 1; i < 4; i++)
        counts[i] = to_counts(sensed[i], sp->pressure_lo_pa, sp->pressure_hi_pa, sp->pressure_lo_counts,
                              sp->pressure_hi_counts, sp->noise_counts, rng);
}

void plant_sensor_counts(const plant *pl, const plant_sensor_params *sp, plant_rng *rng, uint16_t counts[4])
{
    double sensed[4];
    plant_sensed(pl, sensed);
    plant_counts(sp, sensed, rng, counts);
}
