/*
 * Candidate unmodelled effects and their "truth" variants, as an optional
 * extension of the plant (plant.h). Used by the sim-to-real diagnosis
 * (docs/diagnosis.md, scripts/leveler/diagnose/) through ctypes.
 *
 * A plant_fx is a plant plus a few extra states and per-tick memories. With
 * kind PLANT_FX_NONE (or every parameter at its "off" value) it reproduces
 * the nominal plant step for step: the extension only ADDS corrections to
 * plant_derivatives()'s result, using the flows it reports.
 *
 * Candidates (kinds 1..7) are what the diagnosis fits. Truth variants
 * (kinds 101..107) generate the blind test's "real" logs; each has a
 * DIFFERENT functional form from its candidate, so a fit is never exact:
 *   thermal    candidate: one gas-to-wall time constant, wall at ambient
 *              truth:     gas-wall and wall-ambient time constants (wall temperature state)
 *   area       candidate: A_nom(y) (1 + a0 + a1 (y - y0) + a2 (y - y0)^2)
 *              truth:     A_nom(y) times a piecewise-linear table over 5 heights
 *   friction   candidate: Coulomb + Stribeck, stick below a velocity threshold
 *              truth:     LuGre (bristle state z)
 *   valve      candidate: pure opening/closing delays, ISO 6358 flow (b, C_out)
 *              truth:     first-order opening fractions, Cd falling with pressure ratio
 *   line       candidate: transport delay of the compressor flow, tube dead volume at the junction
 *              truth:     a lumped tube volume with a linear (laminar) conductance
 *   leak       candidate: orifice (eq. 8/9) spring -> ambient
 *              truth:     laminar capillary leak, m = K (P2^2 - Pa^2)
 *   sensor     candidate: first-order lags, offsets
 *              truth:     two cascaded lags on pressure, gain error, offsets
 * Parameter order per kind: see the table in effects.c (and effects.py).
 */
#ifndef LEVELER_PLANT_EFFECTS_H
#define LEVELER_PLANT_EFFECTS_H

#include "plant.h"

typedef enum {
    PLANT_FX_NONE = 0,
    PLANT_FX_THERMAL = 1,
    PLANT_FX_AREA = 2,
    PLANT_FX_FRICTION = 3,
    PLANT_FX_VALVE = 4,
    PLANT_FX_LINE = 5,
    PLANT_FX_LEAK = 6,
    PLANT_FX_SENSOR = 7,
    PLANT_FX_TRUTH = 100 /* + one of the above: the truth-generator variant */
} plant_fx_kind;

#define PLANT_FX_MAX_PARAMS 8
#define PLANT_FX_NX 6           /* extra ODE states */
#define PLANT_FX_DELAY_TICKS 128 /* transport-delay memory, ticks */

typedef struct {
    int kind;                          /* plant_fx_kind */
    double p[PLANT_FX_MAX_PARAMS];     /* meaning per kind: effects.c */
} plant_fx_spec;

typedef struct {
    plant pl;
    plant_fx_spec fx;
    double xe[PLANT_FX_NX];
    double y_ref_m;            /* height the area corrections are centred on */
    /* valve delays: commanded and effective states, pending switch time */
    bool cmd[2], eff[2];
    double pending_s[2];
    /* transport delay of the compressor flow */
    double mc_buf[PLANT_FX_DELAY_TICKS];
    int mc_head;
    double mc_delayed;
    /* transducer filters: [height, p2, p1, p3][stage] */
    double sens[4][2];
    bool sens_ready;
} plant_fx;

/* Returns 0, or -1 if the spec is unknown or a parameter is out of its range. */
int plant_fx_init(plant_fx *f, const plant_params *p, const plant_fx_spec *fx);
/* Inputs for the next steps (valve delays act here, at the plant's current time). */
void plant_fx_set_inputs(plant_fx *f, const plant_inputs *in);
/* RK4 over dt_s in substeps, extra states included; then the per-tick memories. */
void plant_fx_advance(plant_fx *f, double dt_s, int substeps);
/* What the transducers report: height m, P2, P1, P3 Pa abs (P3 = ambient without accumulator). */
void plant_fx_sensed(const plant_fx *f, double out[4]);

#endif /* LEVELER_PLANT_EFFECTS_H */
