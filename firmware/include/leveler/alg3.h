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
 *  - a vent whose down line is only estimated across the gap (from where a
 *    rise stopped) aims an eighth of alg3_gap_pa under that estimate;
 *  - then waits with the valves closed until the platform is at rest
 *    (at most alg3_settle_ms; a slow creep whose extrapolated rest lies on
 *    another side of the band is not yet rest) before it may act again,
 *    unless a vent's coast, extrapolated from its heights every
 *    LEVELER_ALG3_COAST_SAMPLE_MS, will rest short of the band: then it is
 *    topped up at once, the vent again, closing on the stiffness that very
 *    coast showed;
 *  - corrects a small departure (under LEVELER_ALG3_FINE_UM) without the
 *    accumulator and, once P2 is within LEVELER_ALG3_BURST_ZONE_PA of the
 *    line (or at once when the line is unknown), in bursts with a settle
 *    after each, from LEVELER_ALG3_BURST_MS, doubling while they move
 *    nothing: a step of a hysteresis system cannot be smaller than what the
 *    excess at the break-away carries, so the excess is built up in steps;
 *    after a LEVELER_ALG3_BURST_MAX_MS burst that moved nothing, one burst
 *    runs on until the platform moves;
 *  - gives every output a minimum on and off time (dwell.h);
 *  - learns the coast times and the hysteresis lines from the rig's own
 *    motion (alg3_learn.h) and keeps them in the settings (flash);
 *  - with an accumulator: keeps it charged while at rest (compressor with a
 *    recharge hysteresis, never while a departure is pending), opens it with
 *    the spring valve while it can help a fill, and while venting lets the
 *    spring's surplus into it while it is below the spring and its charge
 *    (air kept, not blown off).
 * Pure apart from its own state: the same inputs give the same outputs.
 *
 * Three layers, none calling up: the estimates (alg3_estimate.h: filter,
 * coast model, line estimates), the learner on them (alg3_learn.h: shown what
 * the controller does, it returns verdicts), and this controller on both.
 */
#ifndef LEVELER_ALG3_H
#define LEVELER_ALG3_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/alg3_learn.h"
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

#define LEVELER_ALG3_RECHARGE_HYST_PA 13790 /* accumulator recharge starts 2 psi below the charge */
#define LEVELER_ALG3_ACC_HELP_PA 6895     /* P3 must exceed P2 by 1 psi for its valve to open in a fill */
#define LEVELER_ALG3_FINE_UM 2540          /* a departure under 0.1 in is corrected in bursts */
#define LEVELER_ALG3_BURST_MS 100u        /* the first burst of a fine move */
#define LEVELER_ALG3_BURST_MAX_MS 1600u   /* a burst that moved nothing doubles the next, up to this ... */
#define LEVELER_ALG3_REACH_MS 60000u      /* ... and after one that long, the next runs until the platform
                                           * moves (this long at most): the line is far (a load added while
                                           * the platform sat between the lines) */
#define LEVELER_ALG3_ACC_MIN_UM 12700     /* the accumulator helps departures beyond 0.5 in (or fast ones) ... */
#define LEVELER_ALG3_ASSIST_MS 2000u      /* ... and the first half of the gap of any fill the compressor alone
                                           * has not broken away in 2 s */
#define LEVELER_ALG3_ASSIST_MOVED_UM 1000 /* a fill that rose this far (above sensor noise) has broken away */
#define LEVELER_ALG3_BURST_ZONE_PA 3000   /* bursts start this close to the line (0.44 psi) */
#define LEVELER_ALG3_SETTLE_REST_MS 1000u /* a settle ends after this long at rest */
#define LEVELER_ALG3_BLEED_MAX_MS 1500u   /* a vent bleeds a charged pipe this long at most (0.7 s seen) */
#define LEVELER_ALG3_COAST_SAMPLE_MS 500u /* a settle samples its coast's height this often ... */
#define LEVELER_ALG3_TOPUPS_MAX 1         /* ... and tops up a short one at most this often per departure */
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

typedef struct {
    leveler_alg3_height_filter filter;
    uint8_t phase;            /* leveler_alg3_phase */
    uint32_t phase_start_ms;
    uint32_t last_ms;         /* previous step */
    int8_t out_dir;           /* -1 below the band, +1 above, 0 in */
    uint32_t out_since_ms;
    int64_t out_area_um_ms;   /* distance outside the band integrated over time (cumulative sum, >= 0) */
    bool recharging;          /* accumulator charge in progress */
    bool fine;                /* the present move corrects a small departure: in bursts near the line */
    bool use_acc;             /* the present fill may draw on the accumulator (a large or fast departure) */
    bool assist;              /* ... or it does now: a fill that has not broken away (LEVELER_ALG3_ASSIST_MS) */
    bool retry;               /* the last move closed on an estimate and moved nothing: go on as it was */
    bool bursting;            /* a burst of a fine move is under way since burst_start_ms */
    uint32_t burst_start_ms;
    uint16_t burst_ms;        /* length of the present burst */
    uint16_t moves;
    bool close_line_known;    /* the last close's line was the present load's (learnt, not estimated) */
    bool topup;               /* the present move tops up a short vent coast (short_coast in alg3.c) */
    uint8_t topups;           /* top-ups since the departure's first move */
    int32_t topup_k_pa_per_mm; /* the coast stiffness the short coast showed: the top-up closes on it */
    uint8_t coast_samples;    /* heights sampled in the present settle (coast_um: the last four) */
    int32_t coast_um[4];
    bool coast_rest_valid;    /* the last sample showed a first-order coast, to rest at coast_rest_um */
    int32_t coast_peak_um_s;  /* the present settle's fastest motion the close's way (um/s) */
    bool coast_slowed;        /* ... and it has since slowed to half that */
    int32_t coast_rest_um;
    int32_t move_from_um;     /* where the present (or last) move started, a probe's too */
    uint8_t probe;            /* leveler_alg3_probe_kind of the present move */
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

#endif /* LEVELER_ALG3_H */
