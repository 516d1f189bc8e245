/*
 * Plant model of the thesis rig (Chapter III, eq. 1-32), double precision, SI
 * inside: compressor + motor, pipe/junction volume P1, spring solenoid valve,
 * vent valve, accumulator branch (tube or diaphragm) with its valve, air
 * spring P2 and volume, platform with hysteresis force law and direction-
 * dependent damping.
 *
 * No global state: everything lives in a plant value, so Python (ctypes), the
 * rig's Modbus server and the simulator can run as many as they like.
 * The right-hand side of the ODE is ONE function, plant_derivatives(), and
 * ONE RK4 step integrates it (plant_rk4_step); unmodelled effects
 * (host_sim/plant/effects.h) add their corrections to its result and their
 * states after PLANT_NX, and step through the same plant_rk4_step.
 *
 * Configuration files: docs/config-format.md.
 */
#ifndef LEVELER_PLANT_H
#define LEVELER_PLANT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#define PLANT_MAX_BANDS 8
#define PLANT_MAX_POLY 6
#define PLANT_MAX_DIAPHRAGM_SEGMENTS 8
#define PLANT_NAME_MAX 64
#define PLANT_PATH_MAX 512
/* [effect.NAME] sections of a config (effects.h: PLANT_FX_MAX_MODELS, PLANT_FX_MAX_PARAMS) */
#define PLANT_CONFIG_MAX_EFFECTS 2
#define PLANT_CONFIG_EFFECT_PARAMS 8

/* Unit conversions used by the loader, the tests and the reports. */
#define PLANT_PA_PER_PSI 6894.757293168361
#define PLANT_M_PER_IN 0.0254
#define PLANT_N_PER_LBF 4.4482216152605
#define PLANT_KG_PER_LBM 0.45359237
#define PLANT_STANDARD_GRAVITY 9.80665

typedef enum { PLANT_ACC_NONE = 0, PLANT_ACC_TUBE = 1, PLANT_ACC_DIAPHRAGM = 2 } plant_acc_type;

/* One hysteresis band: applies while load < load_below_n (the band with the
 * largest load_below_n also covers heavier loads). Lines are gauge pressure:
 * UP = up_slope * y + up_intercept, DP = UP - down_offset. */
typedef struct {
    double load_below_n;
    double up_slope_pa_per_m;
    double up_intercept_pag;
    double down_offset_pa;
} plant_hysteresis_band;

typedef struct {
    /* ambient and gas */
    double ambient_pa;
    double temperature_k;
    double gas_constant_j_per_kg_k;
    double compressibility;  /* Z */
    double polytropic_n;
    double heat_ratio_k;
    /* compressor motor (eq. 3, 15) */
    double motor_torque_constant_nm_per_v;
    double motor_supply_v;
    double motor_inertia_kg_m2;
    double motor_damping_nm_s;
    double motor_torque_coefficient; /* 2.0: load torque = coef * Dc * (P1 - Pa) */
    /* compressor (eq. 1, 2, 20) */
    double compressor_capacity_m3_per_rad;
    double compressor_leakage_m3_per_pa_s;
    /* pipe / junction */
    double pipe_volume_m3;
    /* spring solenoid valve */
    double spring_valve_diameter_m;
    double spring_valve_cd_in;  /* pipe -> spring */
    double spring_valve_cd_out; /* spring -> pipe */
    /* vent valve */
    double vent_valve_diameter_m;
    double vent_valve_cd;
    /* accumulator branch */
    int acc_type; /* plant_acc_type */
    double acc_volume_m3; /* tube */
    double acc_charge_pa; /* absolute; initial P3 */
    double acc_valve_diameter_m;
    double acc_valve_cd;
    /* diaphragm accumulator: V(P3) piecewise linear, segment i for P3 below
     * break i, the last one above every break (figure 22, Appendix B) */
    int diaphragm_segments;
    double diaphragm_break_pa[PLANT_MAX_DIAPHRAGM_SEGMENTS - 1];
    double diaphragm_slope_m3_per_pa[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    double diaphragm_intercept_m3[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    int diaphragm_slope_count, diaphragm_intercept_count; /* as given, checked against segments */
    /* air spring */
    double spring_volume0_m3; /* at the initial height */
    double area_cc1_in2[PLANT_MAX_POLY]; /* CC1 = sum c[i] (load_lbf/100)^i, in^2 */
    int area_cc1_terms;
    double area_cc2_in2_per_in[PLANT_MAX_POLY];
    int area_cc2_terms;
    /* hysteresis */
    plant_hysteresis_band bands[PLANT_MAX_BANDS];
    int band_count;
    /* platform */
    double extra_mass_kg;
    double damping_up_n_s_per_m;
    double damping_down_n_s_per_m;
    double velocity_deadband_m_per_s;
    double height_min_m;
    double height_max_m;
    /* initial state */
    double init_height_m;
    double init_velocity_m_per_s;
    double init_p_pipe_pa;
    double init_p_spring_pa;
    double init_motor_speed_rad_per_s;
} plant_params;

/* Plant state -> ADC counts: two-point linear spans, 12-bit, optional noise. */
typedef struct {
    double height_lo_counts, height_hi_counts;
    double height_lo_m, height_hi_m;
    double pressure_lo_counts, pressure_hi_counts;
    double pressure_lo_pa, pressure_hi_pa;
    double noise_counts; /* standard deviation; 0 = none */
    uint32_t noise_seed;
} plant_sensor_params;

/* Everything a configuration file holds. */
typedef struct {
    plant_params plant;
    plant_sensor_params sensors;
    int algorithm; /* 1, 2 or 3 */
    int chatter_max_per_min; /* the supervisor's chatter limit written at start; -1 = firmware default */
    double band_lower_m;
    double band_upper_m;
    /* The loads the area fit and the hysteresis lines were measured for ([spring]
     * load_min / load_max): a run outside them is outside the model's valid range. */
    double valid_load_min_n, valid_load_max_n;
    double base_load_n;
    double step_load_n;
    double step_on_s;
    double step_off_s;
    double end_s;
    int substeps_per_tick;
    /* Actuators over the first tick, before the controller's first decision:
     * a run starts from a rig already running (Appendix B starts mid-charge,
     * motor := true, solenoid := true, and its controller first acts after the
     * first step). 0 or 1: compressor, spring valve, vent valve, accumulator valve. */
    int init_compressor, init_spring_valve, init_vent_valve, init_acc_valve;
    /* Unmodelled effects the plant runs ([effect.NAME] sections, the catalogue
     * host_sim/plant/effects.json): ids (0 = none) and SI parameters in the
     * catalogue's order; every program that runs the plant runs them. */
    int effect_id[PLANT_CONFIG_MAX_EFFECTS];
    double effect_params[PLANT_CONFIG_MAX_EFFECTS][PLANT_CONFIG_EFFECT_PARAMS];
    char name[PLANT_NAME_MAX];
    char path[PLANT_PATH_MAX];
} plant_config;

/* The thesis 900 lb case (parameter table, Appendix B program): the built-in
 * config, host_sim/configs/thesis-900lb.ini compiled into the program. */
void plant_config_defaults(plant_config *out);

/* Defaults, then the file (docs/config-format.md). 0 on success; else -1 and
 * err = "file:line: [section] key = value: reason (allowed range ...)"
 * (without " = value" where the reason is an unknown key or section). */
int plant_config_load(const char *path, plant_config *out, char *err, size_t err_len);

/* The resolved config as JSON, SI, keys named like the INI's with the SI
 * unit suffix (band_lower_m, pressure_pa, ...), hysteresis bands with the load
 * range each covers (plant_band_for_load). The one source Python reads
 * (leveler-sim --dump-config; scripts/leveler/config.py). 0, or -1 on a write error. */
int plant_config_write_json(const plant_config *c, FILE *f);

/* Consistency checks of a whole config (also run by the loader). */
int plant_config_check(const plant_config *cfg, char *err, size_t err_len);

/* ---- model ---- */

enum {
    PLANT_X_OMEGA = 0, /* motor speed, rad/s */
    PLANT_X_P_PIPE,    /* pipe / junction pressure (P1), Pa abs */
    PLANT_X_P_SPRING,  /* spring pressure (P2), Pa abs */
    PLANT_X_P_ACC,     /* accumulator pressure (P3), Pa abs */
    PLANT_X_V2,        /* spring volume, m^3 */
    PLANT_X_Y,         /* platform height, m */
    PLANT_X_VEL,       /* platform velocity, m/s (up +) */
    PLANT_NX
};

typedef struct {
    bool compressor;
    bool spring_valve;
    bool vent_valve;
    bool acc_valve;
    double load_n;
} plant_inputs;

/* Mass flows of one derivative evaluation, kg/s (diagnostics, tests). */
typedef struct {
    double compressor;   /* into the pipe */
    double spring_valve; /* pipe -> spring (+) */
    double vent_valve;   /* pipe -> ambient (+) */
    double acc_valve;    /* pipe -> accumulator (+) */
} plant_flows;

/* The subsonic orifice law, the hottest call of a simulation, is Cd A Pu sqrt(1 - r) times a smooth
 * shape of the pressure ratio r, r^(1/k) sqrt((1 - r^((k-1)/k)) / (1 - r)) sqrt(2k/((k-1) R T)): one
 * division, and a square root beside the polynomial, where the law as written takes two divisions and a
 * square root after r^(1/k) (libm's pow: once a quarter of a diagnosis's time). The shape is a degree-6
 * polynomial on each of 32 equal segments of the subsonic ratios, interpolated at Chebyshev nodes when
 * the plant is set up; the flow is within a few ULP of the law worked in long double
 * (tests/sim/test_plant.c). */
#define PLANT_ORIFICE_SEGMENTS 32
#define PLANT_ORIFICE_DEGREE 6

typedef struct {
    plant_params p;
    plant_inputs in;
    double x[PLANT_NX];
    double t_s;
    double damping_n_s_per_m; /* the damping in force: kept while |v| < deadband */
    /* cached from p and in.load_n (plant_set_inputs) */
    double load_cached_n;
    double mass_kg;
    double inv_mass;
    double area_cc1_m2;
    double area_cc2_m2_per_m;
    const plant_hysteresis_band *band;
    /* constants derived from p (plant_init) */
    double crit_ratio;        /* (2/(k+1))^(k/(k-1)) */
    /* the orifice law's shape over the subsonic ratios [crit_ratio, 1], piecewise (orifice_shape, plant.c) */
    double orifice_scale;     /* segments per unit of r */
    double orifice_c[PLANT_ORIFICE_SEGMENTS][PLANT_ORIFICE_DEGREE + 1];
    double flow_choked;       /* sqrt(k/(R T)) (2/(k+1))^((k+1)/(2(k-1))) */
    double spring_valve_area_m2, vent_valve_area_m2, acc_valve_area_m2;
    double rt;                /* R T */
    double zn;                /* Z n */
    double inv_rt, inv_inertia;
    double zn_rt_per_v1;      /* Z n R T / V1 */
} plant;

/* State = the params' initial state, inputs all off at the initial load of 0. */
void plant_init(plant *pl, const plant_params *p);
/* Valves, compressor and load for the next steps. A load change updates the
 * moving mass, effective area and hysteresis band (the volume stays: it is
 * integrated). */
void plant_set_inputs(plant *pl, const plant_inputs *in);
/* The ODE right-hand side at state x, with the inputs and damping in force.
 * flows may be NULL. */
void plant_derivatives(const plant *pl, const double x[PLANT_NX], double dxdt[PLANT_NX], plant_flows *flows);
/* Right-hand side of an ODE over x[0..n): the plant's states first. */
typedef void (*plant_rhs_fn)(const void *ctx, const double *x, double *dxdt);
#define PLANT_RK4_MAX_NX 16
/* THE classical RK4 step of h over x[0..n) (n <= PLANT_RK4_MAX_NX; x starts with
 * the plant's PLANT_NX states): damping chosen from the velocity at its start
 * (kept while at rest), pl->t_s advanced, then the platform's end stops. */
void plant_rk4_step(plant *pl, double *x, int n, plant_rhs_fn rhs, const void *ctx, double h);
/* plant_rk4_step of the nominal plant on pl->x. */
void plant_step(plant *pl, double dt_s);
/* substeps equal RK4 steps covering dt_s. */
void plant_advance(plant *pl, double dt_s, int substeps);

/* Effective area at height y for a load (m^2). */
double plant_effective_area_m2(const plant_params *p, double load_n, double y_m);
/* The band for a load, and its lines (gauge Pa) at height y. */
/* The spring's volume at height y_m under load_n: the config's volume
 * (spring_volume0, at [initial] height) plus the area swept between them. */
double plant_spring_volume_at(const plant_params *p, double load_n, double y_m);
const plant_hysteresis_band *plant_band_for_load(const plant_params *p, double load_n);
double plant_up_limit_pag(const plant_hysteresis_band *b, double y_m);
double plant_down_limit_pag(const plant_hysteresis_band *b, double y_m);
/* Diaphragm accumulator volume and dV/dP at P3 ([accumulator] diaphragm_*). */
void plant_diaphragm_volume(const plant_params *p, double p3_pa, double *v_m3, double *dv_dp_m3_per_pa);
/* Accumulator volume now (tube: fixed). */
double plant_acc_volume_m3(const plant *pl);
/* Orifice mass flow (eq. 8/9 with exponent 1/k), kg/s, from pu to pd (pu >= pd). */
double plant_orifice_flow(const plant *pl, double cd_area_m2, double pu_pa, double pd_pa);
/* Motor speed where the torques balance (eq. 3 with d omega/dt = 0) with the
 * compressor switched on a fraction `duty` of the time (switching much faster
 * than the motor's J/D): 0 when the pipe pressure stalls it. */
double plant_motor_steady_speed(const plant_params *p, double p1_pa, double duty);

/* ---- sensors ---- */

/* Deterministic noise source (xorshift64*), one per simulation. */
typedef struct {
    uint64_t s;
    bool have_spare;
    double spare;
} plant_rng;
void plant_rng_seed(plant_rng *r, uint32_t seed);

/* What ideal transducers report: height m, P2, P1, P3 Pa abs (P3 reads
 * ambient without an accumulator). */
void plant_sensed(const plant *pl, double out[4]);
/* THE mapping of sensed values to ADC counts for HAL channels 0 height, 1 P2,
 * 2 P1, 3 P3: the config's two-point spans, rounded, clamped 0..4095, plus
 * noise when sp->noise_counts > 0 and rng is given. */
void plant_counts(const plant_sensor_params *sp, const double sensed[4], plant_rng *rng, uint16_t counts[4]);
/* plant_counts of plant_sensed. */
void plant_sensor_counts(const plant *pl, const plant_sensor_params *sp, plant_rng *rng, uint16_t counts[4]);

#endif /* LEVELER_PLANT_H */
