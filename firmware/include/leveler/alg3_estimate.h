/*
 * Algorithm 3's estimates (alg3.h): the pure computations both the controller
 * (alg3.c) and its learner (alg3_learn.c) use, at the bottom of the three:
 *  - the filtered height and its rates (first order, tau ~35 ms; differences
 *    over LEVELER_ALG3_RATE_TICKS and LEVELER_ALG3_FAST_TICKS ticks);
 *  - the coast model: the rest height predicted from the rate and the coast
 *    time, or from the excess of P2 over a line and the coast stiffness, and
 *    the early-close rule built on both;
 *  - the line estimates: the up or down hysteresis line at a height, from
 *    what the learner knows of the lines (leveler_alg3_lines).
 * Nothing here calls up: the learner and the controller pass in what they hold.
 *
 * Fixed point: heights um (int32), rates um/s (int32), pressures Pa absolute
 * (int32), slopes Pa/mm, times ms. The filter state is height * 16
 * (|height| <= 2^27 um keeps it in int32; the sensor calibration limits
 * heights to +-2e6 um). Products that can exceed int32 (rate * coast,
 * span * permille, slope * height) are formed in int64 and saturated back;
 * one rounding per division (half away from zero).
 */
#ifndef LEVELER_ALG3_ESTIMATE_H
#define LEVELER_ALG3_ESTIMATE_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/settings.h"

#define LEVELER_ALG3_RATE_TICKS 32u       /* rate = filtered height difference over 320 ms */
#define LEVELER_ALG3_FAST_TICKS 8u        /* the prediction's rate: over 80 ms */
#define LEVELER_ALG3_FILTER_DIV 4         /* first-order filter gain 1/4 per 10 ms tick */
#define LEVELER_ALG3_Q 16                 /* filter state in 1/16 um */
#define LEVELER_ALG3_STILL_UM_S 1500      /* |rate| below this: not moving (0.06 in/s) */
#define LEVELER_ALG3_MOVING_UM_S 3000     /* |rate| above this: moving (0.12 in/s) */
#define LEVELER_ALG3_FAST_UM_S 12000      /* a move this fast (0.47 in/s) heading out of the band is a load change */
#define LEVELER_ALG3_EARLY_NUM 5          /* predicted travel x 5/4: an early close is cheap, a late one costs the gap */
#define LEVELER_ALG3_EARLY_DEN 4
#define LEVELER_ALG3_COAST_STEP_MIN_UM 250 /* a coast's step shorter than this (3 height counts) is noise */
#define LEVELER_ALG3_COAST_RATIO_TOL 8     /* a first-order coast's step ratios agree within 1/8 */

/* The filtered height and its rates. */
typedef struct {
    bool primed;
    uint8_t ring_head;        /* the oldest slot of ring_um, the next to be written */
    int32_t height_q;         /* filtered height, 1/16 um */
    int32_t ring_um[LEVELER_ALG3_RATE_TICKS];
    int32_t rate_um_s;        /* over the whole window: motion / rest, learning */
    int32_t rate_fast_um_s;   /* over the last LEVELER_ALG3_FAST_TICKS: predictions (less lag) */
} leveler_alg3_height_filter;

/* What is known of the hysteresis lines besides the settings (alg3_up_pa / alg3_down_pa): kept by the
 * learner, read by the line estimate. */
typedef struct {
    bool line_fresh;          /* the line of the present move was learnt in this move */
    bool lines_valid;         /* alg3_up_pa / alg3_down_pa were learnt under the present load */
    bool end_valid;           /* where the last motion ended: on the up (+1) or down (-1) line */
    bool end_trusted;         /* ... and no close on the estimate from it has failed */
    int8_t end_dir;
    int32_t end_height_um;
    int32_t end_p_spring_pa;
} leveler_alg3_lines;

/* One tick of the filter and its rates (the first primes it: rates 0). */
void leveler_alg3_filter(leveler_alg3_height_filter *f, int32_t height_um);
/* The filtered height (um). */
int32_t leveler_alg3_height_um(const leveler_alg3_height_filter *f);
/* The rate the predictions use: over 80 ms when that is beyond LEVELER_ALG3_FAST_UM_S
 * (a fast motion, where the long window lags), else over the whole window (noise). */
int32_t leveler_alg3_prediction_rate(const leveler_alg3_height_filter *f);
/* How far the filtered height has moved up (or down) from from_um, um. */
int32_t leveler_alg3_moved_um(const leveler_alg3_height_filter *f, int32_t from_um, bool up);

/* Target height (um): alg3_target_permille of the way from the lower band edge. */
int32_t leveler_alg3_target_um(const leveler_settings *set);

/* Predicted rest height (um) if the valves closed now: height + rate * coast. */
int32_t leveler_alg3_predict_um(int32_t height_um, int32_t rate_um_s, uint16_t coast_ms);

/* A line pressure p_pa seen at from_um carried to to_um along alg3_line_slope_pa_per_mm (Pa). */
int32_t leveler_alg3_along_slope_pa(const leveler_settings *set, int32_t p_pa, int32_t from_um, int32_t to_um);

/* Whether the present load's up (or down) line is known: learnt in this move or
 * since the last load change (a motion nobody asked for), and set. */
bool leveler_alg3_line_known(const leveler_alg3_lines *lines, const leveler_settings *set, bool up);

/* Whether leveler_alg3_line_estimate's up (or down) line is estimated across
 * the gap: not known, and the last motion (trusted) stopped on the other line. */
bool leveler_alg3_line_across_gap(const leveler_alg3_lines *lines, const leveler_settings *set, bool up);

/* The up (or down) line at height h for the present load, Pa absolute, 0 when
 * unknown: the learnt line (alg3_up_pa / alg3_down_pa along the slope) when it
 * was learnt in this move or since the last load change (a motion nobody
 * asked for); else where the last motion stopped (on the line of that
 * motion), plus (or minus) alg3_gap_pa when that was the other line. */
int32_t leveler_alg3_line_estimate(const leveler_alg3_lines *lines, const leveler_settings *set, bool up, int32_t h);

/* Rest height (um) of a platform whose excess of P2 over the up line (or
 * shortfall under the down line, line_pa) carries it k_pa_per_mm Pa per mm:
 * h when the line is unknown (0), there is no excess, or k <= 0. One rounding
 * (<= 0.5 um); the travel formed in int64 and the height saturated. */
int32_t leveler_alg3_line_rest_um(bool up, int32_t h, int32_t p_spring_pa, int32_t line_pa, int32_t k_pa_per_mm);

/* Where a first-order coast comes to rest, from four heights h[0..3] taken at
 * equal spacing (dir +1 rising, -1 falling): its steps shrink by a constant
 * ratio q, so what is left after h[3] is d3 q / (1 - q) = d3^2 / (d2 - d3)
 * (Aitken's extrapolation). False (rest_um untouched) unless all three steps
 * go the dir way, the last at least LEVELER_ALG3_COAST_STEP_MIN_UM, each
 * shorter than the one before, the second at least half the first, and the two
 * ratios within 1/LEVELER_ALG3_COAST_RATIO_TOL of each other: a slow coast that
 * is first order (a fast one is at rest within a second anyway; a platform
 * stopped by its momentum against a line, the 900 lb rig's vents, shrinks by
 * 1/4 then 1/8). A falling coast stiffens as it compresses the spring's gas,
 * so its ratio falls as it goes and the extrapolation overshoots its rest
 * (1-5 mm on the 1000 lb rig's vents); a rising one softens and falls short of
 * it (0.3 mm on the 900 lb diaphragm's fills). Fixed point: steps in int64 (a
 * first step over 2^31 um is no coast), squares < 2^62, one rounding
 * (<= 0.5 um), the rest saturated to int32. */
bool leveler_alg3_coast_rest(const int32_t h[4], int8_t dir, int32_t *rest_um);

/*
 * The early-close rule of a fill (up) or vent, pure: true when the platform is
 * at the target or through the band, or when either predicted rest reaches
 * the target:
 *   by rate: h + rate * coast_ms / 1000 (only while moving the move's way
 *            faster than STILL), its travel stretched by EARLY_NUM/EARLY_DEN;
 *   by line: h +- (excess of P2 over line_pa, or under it) * 1000 / coast_k
 *            (line_pa 0 = unknown), stretched the same unless line_sure (the
 *            line was learnt at the break-away of this very move: the coast
 *            model is used as it is, issue 19).
 * Fixed point: int64 intermediates, one rounding per division (<= 0.5 um);
 * the double reference test bounds the disagreement to within that of a
 * threshold.
 */
bool leveler_alg3_close_now(const leveler_settings *set, bool up, int32_t h, int32_t rate_um_s, int32_t p_spring_pa,
                            int32_t line_pa, bool line_sure);

#endif /* LEVELER_ALG3_ESTIMATE_H */
