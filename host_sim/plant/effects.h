/*
 * Unmodelled effects as an optional extension of the plant (plant.h), for the
 * sim-to-real diagnosis (docs/diagnosis.md, scripts/leveler/diagnose/).
 *
 * A plant_fx is a plant plus a few extra states and per-tick memories, driven
 * by up to two effect models at once (a pair: two effects in one rig). Without
 * a model (or with every parameter at its nominal value) it reproduces the
 * nominal plant step for step: a model only ADDS corrections to
 * plant_derivatives()'s result, using the flows it reports, and steps through
 * the plant's one RK4 step (plant_rk4_step).
 *
 * Two models compose in the order of their stage (plant_fx_stage): the
 * geometry first (the area scales dV2), then the gas (the thermal balance
 * rewrites dP from that dV2), forces on the guide, additive flow corrections
 * (valve, leak), the junction's volume (the line scales the whole dP1), and the
 * transducers last. Each model declares the state slots and memories it owns
 * (plant_fx_ops.uses); a pair that would share one is refused.
 *
 * The candidate effects the diagnosis fits are catalogued once, in
 * effects.json (names, ids, parameters, ranges): the table
 * plant_fx_catalogue is generated from it, their models are in
 * effects_candidates.c, one set of functions per effect. The blind test's
 * truth variants are NOT part of the product: they live in host_sim/blindtest/
 * and plug in through the same plant_fx_model.
 */
#ifndef LEVELER_PLANT_EFFECTS_H
#define LEVELER_PLANT_EFFECTS_H

#include "plant.h"

#define PLANT_FX_MAX_PARAMS 8
#define PLANT_FX_MAX_MODELS 2    /* effects at once */
#define PLANT_FX_NX 8            /* extra ODE states */
#define PLANT_FX_DELAY_TICKS 128 /* transport-delay memory, ticks */

/* Extra state slots (a model uses the ones it needs). */
enum {
    PLANT_FX_XE_T2 = 0, PLANT_FX_XE_T1 = 1, PLANT_FX_XE_TW = 2, PLANT_FX_XE_Z = 3, PLANT_FX_XE_AUX = 4,
    PLANT_FX_XE_VALVE = 6 /* two: spring and vent valve opening fractions */
};

/* What a model owns (plant_fx_ops.uses): two models of a pair may not share any. */
enum {
    PLANT_FX_USES_GAS_T = 1 << 0,   /* xe T2, T1: gas temperatures */
    PLANT_FX_USES_WALL_T = 1 << 1,  /* xe TW */
    PLANT_FX_USES_Z = 1 << 2,       /* xe Z */
    PLANT_FX_USES_AUX = 1 << 3,     /* xe AUX, AUX + 1 */
    PLANT_FX_USES_VALVE_X = 1 << 4, /* xe VALVE, VALVE + 1 */
    PLANT_FX_USES_VALVE_MEM = 1 << 5, /* eff[], pending_s[], open_frac[], opening[]: delayed valve states */
    PLANT_FX_USES_DELAY = 1 << 6,   /* mc_buf: the compressor flow's delay line */
    PLANT_FX_USES_SENS = 1 << 7     /* sens[][]: the transducer filters, and what they report */
};

/* Where a model's corrections go in the sum (see above); lower first. */
typedef enum {
    PLANT_FX_STAGE_GEOMETRY = 0, PLANT_FX_STAGE_GAS, PLANT_FX_STAGE_FORCE, PLANT_FX_STAGE_FLOW,
    PLANT_FX_STAGE_VOLUME, PLANT_FX_STAGE_SENSOR
} plant_fx_stage;

typedef struct plant_fx plant_fx;

/* What an effect does, as functions; any may be NULL (nothing to do). q: the
 * model's own parameters (plant_fx.q of its slot). */
typedef struct {
    plant_fx_stage stage;
    unsigned uses; /* PLANT_FX_USES_* */
    void (*init)(plant_fx *f, const double *q);
    /* commanded -> effective inputs, at the plant's current time */
    void (*inputs)(plant_fx *f, const double *q, plant_inputs *effective);
    /* corrections to dx (plant_derivatives()'s, with the models before this one's
     * corrections) at state x (plant + extra); fl: the flows as the models before
     * this one left them (the nominal ones, unless plant_fx_replace_flows changed them) */
    void (*rhs)(const plant_fx *f, const double *q, const double *x, double *dx, plant_flows *fl);
    /* before each RK4 step of h, on the state x (plant + extra) */
    void (*before_step)(plant_fx *f, const double *q, double *x, double h);
    /* after each RK4 step: vel0 the velocity at its start */
    void (*after_step)(plant_fx *f, const double *q, double *x, double vel0, double h);
    /* after each tick of dt_s: memories and filters; raw: what ideal
     * transducers read now; first: the first tick (the filters start from raw) */
    void (*after_tick)(plant_fx *f, const double *q, const double raw[4], double dt_s, bool first);
    /* what the transducers report, from the filtered values in out */
    void (*sensed)(const plant_fx *f, const double *q, double out[4]);
    /* RK4 substeps over dt_s that keep a stiff extension stable (at least the given) */
    int (*substeps)(const plant_fx *f, const double *q, double dt_s, int substeps);
} plant_fx_ops;

/* One catalogued effect. */
typedef struct {
    const char *name;
    int id;
    int nparams;
    double lo[PLANT_FX_MAX_PARAMS], hi[PLANT_FX_MAX_PARAMS]; /* accepted ranges, SI */
    const plant_fx_ops *ops;
    const char *param[PLANT_FX_MAX_PARAMS];  /* names, SI suffixed (the config's keys) */
    double nominal[PLANT_FX_MAX_PARAMS];     /* the nominal plant's values; NaN: none given */
} plant_fx_model;

/* The candidates (generated from effects.json). */
extern const plant_fx_model plant_fx_catalogue[];
extern const int plant_fx_catalogue_count;
/* The catalogue entry with this id in a table, or NULL. */
const plant_fx_model *plant_fx_find(const plant_fx_model *table, int count, int id);

struct plant_fx {
    plant pl;
    int nmodels;                 /* 0: the nominal plant */
    const plant_fx_model *model[PLANT_FX_MAX_MODELS]; /* in stage order */
    double q[PLANT_FX_MAX_MODELS][PLANT_FX_MAX_PARAMS];
    double xe[PLANT_FX_NX];
    double y_ref_m;            /* height the area corrections are centred on */
    /* valve delays: commanded and effective states, pending switch time, the
     * open share of the current tick; the last tick's length */
    bool cmd[2], eff[2];
    double pending_s[2];
    double open_frac[2];
    /* a valve's opening as a lag (valve_dynamics' opening_tau_s): the opening
     * at the tick's start, the effective state before the tick's switch and the
     * switch's offset into the tick (s; -1: no switch in it) */
    double opening[2];
    bool eff_before[2];
    double switch_in_s[2];
    double tick_s;
    int substep, substeps; /* the RK4 substep under way in this tick, of how many */
    /* transport delay of the compressor flow */
    double mc_buf[PLANT_FX_DELAY_TICKS];
    int mc_head;
    double mc_delayed;
    /* transducer filters: [height, p2, p1, p3][stage] */
    double sens[4][2];
    bool sens_ready;
};

/* model NULL = nominal. Returns 0, or -1 if a parameter is outside the model's range. */
int plant_fx_init(plant_fx *f, const plant_params *p, const plant_fx_model *model, const double *params);
/* Up to PLANT_FX_MAX_MODELS models at once (NULL entries skipped), params
 * PLANT_FX_MAX_PARAMS doubles per entry, in the entries' order. Returns 0; -1
 * if a parameter is outside its model's range; PLANT_FX_PAIR_REFUSED if two
 * models are one effect or share a state slot or memory (plant_fx_ops.uses). */
#define PLANT_FX_PAIR_REFUSED (-2)
int plant_fx_init_models(plant_fx *f, const plant_params *p, int n, const plant_fx_model *const *models,
                         const double *params);
/* Inputs for the next steps (valve delays act here, at the plant's current time). */
void plant_fx_set_inputs(plant_fx *f, const plant_inputs *in);
/* RK4 over dt_s in substeps, extra states included; then the per-tick memories. */
void plant_fx_advance(plant_fx *f, double dt_s, int substeps);
/* What the transducers report: height m, P2, P1, P3 Pa abs (P3 = ambient without accumulator). */
void plant_fx_sensed(const plant_fx *f, double out[4]);

/* ---- the config's effects ([effect.NAME] sections, plant_config_effects.c) ---- */

/* One key of [effect.<effect>]: key = value (SI) into cfg; 0, or -1 with the
 * reason in msg (unknown effect or parameter, out of the catalogue's range,
 * more effects than the plant runs at once). */
int plant_config_effect_key(plant_config *cfg, const char *effect, const char *key, double value, char *msg,
                            size_t len);
/* The catalogue entries of the config's effects, NULL for an empty slot. */
void plant_config_effect_models(const plant_config *cfg, const plant_fx_model *models[PLANT_CONFIG_MAX_EFFECTS]);
/* 0 if the config's effects can run together, else -1 with msg. */
int plant_config_effects_check(const plant_config *cfg, char *msg, size_t len);

/* ---- building blocks shared by candidate and truth models ---- */

/* Eq. 8/9 both ways: mass flow a -> b (+), Cd A per direction. */
double plant_fx_two_way(const plant *pl, double cda_fwd, double cda_back, double pa, double pb);
/* The pressure equations of plant.c with new compressor/spring/vent flows in
 * place of fl's; fl becomes them, so that a later model replaces what this one
 * left (a hose behind a lagging valve), not the nominal flows. */
void plant_fx_replace_flows(const plant *pl, const double *x, double *dx, plant_flows *fl, double m_c,
                            double m_s, double m_v);
/* Energy balance of the gas in spring and pipe with a wall at tw and time constant tau. */
void plant_fx_thermal_balance(const plant_fx *f, const double *x, double *dx, const plant_flows *fl, double tau,
                              double tw);
/* The same with the compressor's air entering the pipe at t_in (K) instead of ambient. */
void plant_fx_thermal_balance_in(const plant_fx *f, const double *x, double *dx, const plant_flows *fl, double tau,
                                 double tw, double t_in);
/* Effective area scaled by s at this state: volume rate and pressure force scale with it. */
void plant_fx_scale_area(const plant_fx *f, const double *x, double *dx, double s);
/* First-order lag over dt towards target (tau ~ 0: the target). */
double plant_fx_lag(double state, double target, double tau, double dt);

#endif /* LEVELER_PLANT_EFFECTS_H */
