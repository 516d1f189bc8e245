/*
 * Algorithm 3's learner (alg3.h), between the estimates (alg3_estimate.h)
 * below and the controller (alg3.c) above: it learns the coast times, the
 * coast stiffness and the hysteresis lines from the rig's own motion, only
 * while settings.alg3_learn is on. It never calls up: the controller shows it
 * what it is doing (leveler_alg3_view) and acts on its verdicts
 * (leveler_alg3_verdict). Learnt values go into a copy of the settings
 * (*learnt, *changed: the caller applies it, so it is validated like any
 * register write and reaches flash on the board).
 *
 * Line points: when the platform breaks away in a fill or a vent, P2 (half the
 * rate window back, where the motion began) lies on the up or down line; when
 * a rise or a fall stops with the spring valve closed, P2 lies on the line of
 * that motion. A point is referred to the target height along
 * alg3_line_slope_pa_per_mm and rejected unless it lies within
 * LEVELER_ALG3_LINE_REACH_UM of the target and between LEVELER_ALG3_LINE_MIN_PA
 * and the overpressure limit. A new point on one line that crosses the other
 * line's value means the load changed: the other line is forgotten (0).
 */
#ifndef LEVELER_ALG3_LEARN_H
#define LEVELER_ALG3_LEARN_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/alg3_estimate.h"
#include "leveler/settings.h"

#define LEVELER_ALG3_REST_MS 300u         /* not moving this long = at rest */
#define LEVELER_ALG3_LINE_REACH_UM 50800  /* line points farther than 2 in from the target are not used */
#define LEVELER_ALG3_LINE_MIN_PA 120000   /* a spring carrying the platform holds more than this (abs) */
#define LEVELER_ALG3_COAST_MIN_RATE_UM_S 12000 /* closes slower than this (0.47 in/s) teach no coast time */
#define LEVELER_ALG3_COAST_MIN_MS 20
#define LEVELER_ALG3_COAST_MAX_MS 5000
#define LEVELER_ALG3_K_MIN_PA_PER_MM 50
#define LEVELER_ALG3_K_MAX_PA_PER_MM 20000
#define LEVELER_ALG3_MOVED_UM 500        /* a close followed by less travel than this (0.02 in) moved nothing */
#define LEVELER_ALG3_K_FACTOR 3          /* a coast stiffness seen more than 3x off the learnt one is rejected */
#define LEVELER_ALG3_GAP_MIN_PA 5000
#define LEVELER_ALG3_GAP_MAX_PA 300000

/* watch.adopt bits: the next observation replaces the setting instead of moving it halfway (commissioning
 * starts from nothing on a new rig). */
#define LEVELER_ALG3_ADOPT_GAP 0x01u
#define LEVELER_ALG3_ADOPT_TAU_UP 0x02u
#define LEVELER_ALG3_ADOPT_TAU_DOWN 0x04u
#define LEVELER_ALG3_ADOPT_K_UP 0x08u
#define LEVELER_ALG3_ADOPT_K_DOWN 0x10u
#define LEVELER_ALG3_ADOPT_ALL 0x1Fu

/* What the learner saw. */
typedef struct {
    uint32_t still_ms;        /* time |rate| < STILL */
    int8_t motion;            /* +1 rising, -1 falling, 0 at rest: the last confirmed motion */
    bool close_valid;         /* a move closed with a rate worth learning from */
    int8_t close_dir;
    bool ended;               /* the present motion's end is recorded */
    int32_t close_height_um;
    int32_t close_rate_um_s;
    int32_t close_p_spring_pa;
    int32_t close_line_pa;    /* the line of the move at the close, 0 unknown */
    leveler_alg3_lines lines; /* what the line estimate reads */
    int32_t p_spring_ring_pa[LEVELER_ALG3_RATE_TICKS]; /* P2 history, same slots as the filter's heights */
    uint8_t adopt;            /* LEVELER_ALG3_ADOPT_* still to be taken as seen */
} leveler_alg3_watch;

/* What the controller shows the learner at each call (it fills this in from its own state). */
typedef struct {
    const leveler_alg3_height_filter *filter;
    int8_t valves_dir;        /* +1 filling, -1 venting, 0 valves closed (idle or settling) */
    bool settling;            /* valves closed after a move, until the platform is at rest */
    bool commissioning;       /* the load is held: a motion nobody asked for is a creep, not a load change */
    bool probe;               /* the present (or last) move is a commissioning probe */
    bool topup;               /* the present move tops up a coast still under way: its start is no break-away */
    int32_t move_from_um;     /* where the present (or last) move (a probe) started */
    int32_t probe_moved_um;   /* an early probe closes once moved this far */
} leveler_alg3_view;

/* What a settle's lesson asks of the controller. */
typedef enum {
    LEVELER_ALG3_VERDICT_NONE = 0,
    LEVELER_ALG3_VERDICT_RETRY = 1 /* the move closed on an estimated line and nothing moved: the line lies
                                    * beyond it; fill or vent on (in a longer burst) until it breaks away */
} leveler_alg3_verdict;

/* Once per tick, after the phase logic: P2's history, rest, motion, line points and the gap. */
void leveler_alg3_learn(leveler_alg3_watch *w, const leveler_alg3_view *v, const leveler_settings *set,
                        int32_t p_spring_pa, uint32_t dt_ms, leveler_settings *learnt, bool *changed);

/* Record a closing move (fill or vent ended by prediction, dir +1 up) for coast learning. */
void leveler_alg3_note_close(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, int8_t dir,
                             int32_t p_spring_pa, int32_t line_pa);

/* At rest after a close: learn the coast time (travel / rate at the close) and
 * the coast stiffness (excess over the line at the close / travel) from the
 * recorded close; a close on an estimate after which nothing moved forgets
 * the estimate and returns LEVELER_ALG3_VERDICT_RETRY (never for a probe:
 * commissioning judges its own); a close on an estimate that carried the
 * platform under a third of its predicted travel puts the estimate's point
 * where it rests (it moved: it rests on its line). The controller then forgets the close
 * (leveler_alg3_forget_close). */
leveler_alg3_verdict leveler_alg3_learn_coast(leveler_alg3_watch *w, const leveler_alg3_view *v,
                                              const leveler_settings *set, leveler_settings *learnt, bool *changed);

/* The recorded close is done with (learnt from, or disturbed by a load change). */
void leveler_alg3_forget_close(leveler_alg3_watch *w);

#endif /* LEVELER_ALG3_LEARN_H */
