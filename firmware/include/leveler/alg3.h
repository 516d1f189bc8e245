/*
 * Algorithm 3: hysteresis-aware leveling (docs/controller.md).
 *
 * The thesis's band rules act on every sample at the band edge and fill or
 * vent until the edge is crossed; with sensor noise they hunt, and the spring's
 * hysteresis makes every overshoot through the band cost a full crossing of
 * the gap between the up and down lines in air. Algorithm 3:
 *  - filters the height (first order, tau ~35 ms) and estimates its rate
 *    (difference over LEVELER_ALG3_RATE_TICKS ticks);
 *  - acts only on a confirmed departure: outside the band for alg3_persist_ms
 *    AND the distance outside integrated over time (a cumulative sum that the
 *    time inside the band draws back down) >= alg3_confirm_um_s: a 1 in
 *    load-step drop confirms within a tick or two, a rest 0.001 in outside
 *    after about 10 s whatever the noise, noise around a height inside never;
 *  - or on a fast move (a load change) whose predicted rest lies outside the
 *    band, before the band edge is even reached;
 *  - acts only when the predicted rest lies outside the band (a platform
 *    still coasting back is left alone);
 *  - fills or vents towards a target inside the band (alg3_target_permille)
 *    and closes early, when either predicted rest height reaches the target:
 *    height + rate * coast time, or (once the platform has broken away in this
 *    move, so the line is the present load's) height + the excess of P2 over
 *    the up line (below the down line) / alg3_coast_k_pa_per_mm. An early
 *    close is cheap (a further move the same way starts at once, the platform
 *    sits on that line), a late one costs a crossing of the whole hysteresis
 *    gap; so the earlier of the two predictions wins;
 *  - then waits with the valves closed until the platform is at rest
 *    (at most alg3_settle_ms) before it may act again;
 *  - corrects a small departure (under LEVELER_ALG3_FINE_UM) without the
 *    accumulator and, once P2 is within LEVELER_ALG3_BURST_ZONE_PA of the
 *    line (or at once when the line is unknown), in bursts with a settle
 *    after each, from LEVELER_ALG3_BURST_MS, doubling while they move
 *    nothing: a step of a hysteresis system cannot be smaller than what the
 *    excess at the break-away carries, so the excess is built up in steps;
 *  - gives every output a minimum on and off time (dwell.h);
 *  - learns the coast times and the hysteresis lines from the rig's own
 *    motion (alg3_learn.c) and keeps them in the settings (flash);
 *  - with an accumulator: keeps it charged while at rest (compressor with a
 *    recharge hysteresis, never while a departure is pending), opens it with
 *    the spring valve while it can help a fill, and while venting lets the
 *    spring's surplus into it while it is below the spring and its charge
 *    (air kept, not blown off).
 * Pure apart from its own state: the same inputs give the same outputs.
 */
#ifndef LEVELER_ALG3_H
#define LEVELER_ALG3_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/control.h"
#include "leveler/dwell.h"
#include "leveler/settings.h"
#include "leveler/status.h"

typedef enum {
    LEVELER_ALG3_IDLE = 0,
    LEVELER_ALG3_FILLING = 1,
    LEVELER_ALG3_VENTING = 2,
    LEVELER_ALG3_SETTLING = 3
} leveler_alg3_phase;

#define LEVELER_ALG3_RATE_TICKS 32u       /* rate = filtered height difference over 320 ms */
#define LEVELER_ALG3_FAST_TICKS 8u        /* the prediction's rate: over 80 ms */
#define LEVELER_ALG3_FILTER_DIV 4         /* first-order filter gain 1/4 per 10 ms tick */
#define LEVELER_ALG3_Q 16                 /* filter state in 1/16 um */
#define LEVELER_ALG3_STILL_UM_S 1500      /* |rate| below this: not moving (0.06 in/s) */
#define LEVELER_ALG3_MOVING_UM_S 3000     /* |rate| above this: moving (0.12 in/s) */
#define LEVELER_ALG3_REST_MS 300u         /* not moving this long = at rest */
#define LEVELER_ALG3_RECHARGE_HYST_PA 13790 /* accumulator recharge starts 2 psi below the charge */
#define LEVELER_ALG3_ACC_HELP_PA 6895     /* P3 must exceed P2 by 1 psi for its valve to open in a fill */
#define LEVELER_ALG3_LINE_REACH_UM 50800  /* line points farther than 2 in from the target are not used */
#define LEVELER_ALG3_LINE_MIN_PA 120000   /* a spring carrying the platform holds more than this (abs) */
#define LEVELER_ALG3_COAST_MIN_RATE_UM_S 12000 /* closes slower than this (0.47 in/s) teach no coast time */
#define LEVELER_ALG3_COAST_MIN_MS 20
#define LEVELER_ALG3_COAST_MAX_MS 5000
#define LEVELER_ALG3_K_MIN_PA_PER_MM 50
#define LEVELER_ALG3_K_MAX_PA_PER_MM 20000
#define LEVELER_ALG3_FINE_UM 2540          /* a departure under 0.1 in is corrected in bursts */
#define LEVELER_ALG3_BURST_MS 100u        /* the first burst of a fine move */
#define LEVELER_ALG3_BURST_MAX_MS 1600u   /* a burst that moved nothing doubles the next, up to this */
#define LEVELER_ALG3_ACC_MIN_UM 12700     /* the accumulator helps only departures beyond 0.5 in (or fast ones) */
#define LEVELER_ALG3_BURST_ZONE_PA 3000   /* bursts start this close to the line (0.44 psi) */
#define LEVELER_ALG3_MOVED_UM 500        /* a close followed by less travel than this (0.02 in) moved nothing */
#define LEVELER_ALG3_K_FACTOR 3          /* a coast stiffness seen more than 3x off the learnt one is rejected */
#define LEVELER_ALG3_FAST_UM_S 12000     /* a move this fast (0.47 in/s) heading out of the band is a load change */
#define LEVELER_ALG3_SETTLE_REST_MS 1000u /* a settle ends after this long at rest */
#define LEVELER_ALG3_EARLY_NUM 5          /* predicted travel x 5/4: an early close is cheap, a late one costs the gap */
#define LEVELER_ALG3_EARLY_DEN 4
#define LEVELER_ALG3_GAP_MIN_PA 5000
#define LEVELER_ALG3_GAP_MAX_PA 300000
#define LEVELER_ALG3_PROBE_REACH_UM 12700 /* a probe closes 0.5 in from where it started whatever it saw */
#define LEVELER_ALG3_PROBE_MOVED_MIN_UM 250   /* an early probe closes once moved this far at least ... */
#define LEVELER_ALG3_PROBE_MOVED_MAX_UM 2540  /* ... (more with sensor noise: the caller's) and at most */

/* A commissioning probe (commission.h): a move that ends at what it is to show, not at the target. */
typedef enum {
    LEVELER_ALG3_PROBE_NONE = 0,
    LEVELER_ALG3_PROBE_BREAK = 1, /* closes once the platform broke away (the learner saw the motion) */
    LEVELER_ALG3_PROBE_EARLY = 2  /* ... or moved probe_moved_um from its start, whichever is first: less
                                   * excess; the line is then learnt where the platform stops */
} leveler_alg3_probe_kind;

/* watch.adopt bits: the next observation replaces the setting instead of moving it halfway (commissioning
 * starts from nothing on a new rig). */
#define LEVELER_ALG3_ADOPT_GAP 0x01u
#define LEVELER_ALG3_ADOPT_TAU_UP 0x02u
#define LEVELER_ALG3_ADOPT_TAU_DOWN 0x04u
#define LEVELER_ALG3_ADOPT_K_UP 0x08u
#define LEVELER_ALG3_ADOPT_K_DOWN 0x10u
#define LEVELER_ALG3_ADOPT_ALL 0x1Fu

/* What the learner saw (alg3_learn.c). */
typedef struct {
    uint32_t still_ms;        /* time |rate| < STILL */
    int8_t motion;            /* +1 rising, -1 falling, 0 at rest: the last confirmed motion */
    bool close_valid;         /* a move closed with a rate worth learning from */
    int8_t close_dir;
    int32_t close_height_um;
    int32_t close_rate_um_s;
    int32_t close_p_spring_pa;
    bool line_fresh;          /* the line of the present move was learnt in this move */
    bool ended;               /* the present motion's end is recorded */
    bool lines_valid;         /* alg3_up_pa / alg3_down_pa were learnt under the present load */
    int32_t close_line_pa;    /* the line of the move at the close, 0 unknown */
    bool end_valid;           /* where the last motion ended: on the up (+1) or down (-1) line */
    bool end_trusted;         /* ... and no close on the estimate from it has failed */
    int8_t end_dir;
    int32_t end_height_um;
    int32_t end_p_spring_pa;
    int32_t p_spring_ring_pa[LEVELER_ALG3_RATE_TICKS]; /* P2 history, same slots as heights */
    uint8_t adopt;            /* LEVELER_ALG3_ADOPT_* still to be taken as seen */
} leveler_alg3_watch;

typedef struct {
    bool primed;
    int32_t height_q;         /* filtered height, 1/16 um */
    int32_t ring_um[LEVELER_ALG3_RATE_TICKS];
    uint8_t ring_head;
    uint8_t ring_fill;
    int32_t rate_um_s;        /* over the whole window: motion / rest, learning */
    int32_t rate_fast_um_s;   /* over the last LEVELER_ALG3_FAST_TICKS: predictions (less lag) */
    uint8_t phase;            /* leveler_alg3_phase */
    uint32_t phase_start_ms;
    uint32_t last_ms;         /* previous step */
    int8_t out_dir;           /* -1 below the band, +1 above, 0 in */
    uint32_t out_since_ms;
    int64_t out_area_um_ms;   /* distance outside the band integrated over time (cumulative sum, >= 0) */
    bool recharging;          /* accumulator charge in progress */
    bool fine;                /* the present move corrects a small departure: in bursts near the line */
    bool use_acc;             /* the present fill may draw on the accumulator (a large or fast departure) */
    bool retry;               /* the last move closed on an estimate and moved nothing: go on as it was */
    bool bursting;            /* a burst of a fine move is under way since burst_start_ms */
    uint32_t burst_start_ms;
    uint16_t burst_ms;        /* length of the present burst */
    uint16_t moves;
    uint8_t probe;            /* leveler_alg3_probe_kind of the present move */
    int32_t probe_from_um;    /* where the probe started */
    int32_t probe_moved_um;   /* an early probe closes once moved this far */
    bool hold;                /* commissioning in charge: idle acts on no departure (commissioning.h) */
    bool commissioning;       /* the load is held: a motion nobody asked for is a creep, not a load change */
    leveler_dwell dwell;
    leveler_alg3_watch watch;
} leveler_alg3;

void leveler_alg3_init(leveler_alg3 *a, uint32_t now_ms);

/*
 * One tick: measurements (height um, P2/P1/P3 Pa absolute) -> outputs asked
 * for. Returns the band state for the status. `held` = the supervisor held the
 * safe state last tick (or the mode is not auto): the controller restarts from
 * idle. When learning changes a setting, *learnt holds the new settings and
 * the function sets *learnt_changed (the caller applies them).
 */
leveler_control_state leveler_alg3_step(leveler_alg3 *a, const leveler_settings *set, int32_t height_um,
                                        int32_t p_spring_pa, int32_t p_pipe_pa, int32_t p_acc_pa, uint32_t now_ms,
                                        bool held, leveler_outputs *out, leveler_settings *learnt,
                                        bool *learnt_changed);

/* Commissioning (commissioning.h): start a probe move, fill (dir < 0 as for a departure below: -1) or
 * vent (+1), of the given kind (an early one closes once moved moved_um, clamped to PROBE_MOVED_MIN..MAX);
 * the accumulator only for the first half of a fill's way up. Only from idle: returns false otherwise. */
bool leveler_alg3_probe(leveler_alg3 *a, int8_t dir, uint8_t kind, int32_t moved_um, uint32_t now_ms);

/* Learn from the last probe (coast, and the line where it stopped: leveler_alg3_learn_coast), once the
 * caller has seen the platform stop; its settle does not (a slow creep goes on below the rate's rest). */
void leveler_alg3_probe_learn(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt,
                              bool *changed);

/* How far the platform moved the probe's way since the present (or last) probe started, um. */
int32_t leveler_alg3_probe_moved_um(const leveler_alg3 *a, bool up);

/* The outputs actually driven this tick (after the supervisor), for the dwell timers. */
void leveler_alg3_driven(leveler_alg3 *a, const leveler_outputs *driven, uint32_t now_ms);

/* Target height (um): alg3_target_permille of the way from the lower band edge. */
int32_t leveler_alg3_target_um(const leveler_settings *set);

/* Filter and rate (exposed for the double-reference test), and the filtered height (um). */
void leveler_alg3_filter(leveler_alg3 *a, int32_t height_um);
int32_t leveler_alg3_height_um(const leveler_alg3 *a);
/* The rate the predictions use: over 80 ms when that is beyond LEVELER_ALG3_FAST_UM_S
 * (a fast motion, where the long window lags), else over the whole window (noise). */
int32_t leveler_alg3_prediction_rate(const leveler_alg3 *a);

/* Learning (alg3_learn.c), only while settings.alg3_learn is on. Line points:
 * when the platform breaks away in a fill or a vent, P2 (half the rate window
 * back, where the motion began) lies on the up or down line; when a rise or a
 * fall stops with the spring valve closed, P2 lies on the line of that motion.
 * A point is referred to the target height along alg3_line_slope_pa_per_mm and
 * rejected unless it lies within LEVELER_ALG3_LINE_REACH_UM of the target and
 * between LEVELER_ALG3_LINE_MIN_PA and the overpressure limit. A new point on
 * one line that crosses the other line's value means the load changed: the
 * other line is forgotten (0). Called once per tick after the phase logic. */
void leveler_alg3_learn(leveler_alg3 *a, const leveler_settings *set, int32_t p_spring_pa, uint32_t dt_ms,
                        leveler_settings *learnt, bool *changed);
/* Record a closing move (fill or vent ended by prediction) for coast learning. */
void leveler_alg3_note_close(leveler_alg3 *a, int8_t dir, int32_t p_spring_pa, int32_t line_pa);
/* At rest after a close: learn the coast time (travel / rate at the close) and
 * the coast stiffness (excess over the line at the close / travel) from the
 * recorded close; a close on an estimate after which nothing moved forgets
 * the estimate. */
void leveler_alg3_learn_coast(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt,
                              bool *changed);

/* The up (or down) line at height h for the present load, Pa absolute, 0 when
 * unknown: the learnt line (alg3_up_pa / alg3_down_pa along the slope) when it
 * was learnt in this move or since the last load change (a motion nobody
 * asked for); else where the last motion stopped (on the line of that
 * motion), plus (or minus) alg3_gap_pa when that was the other line. */
int32_t leveler_alg3_line_estimate(const leveler_alg3 *a, const leveler_settings *set, bool up, int32_t h);

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

/* Predicted rest height (um) if the valves closed now: height + rate * coast. */
int32_t leveler_alg3_predict_um(int32_t height_um, int32_t rate_um_s, uint16_t coast_ms);

#endif /* LEVELER_ALG3_H */
