/*
 * Algorithm 3, learning from the rig's own motion (alg3.h): the coast time
 * constants that the early close predicts with, and the hysteresis lines
 * (break-away pressure up, hold pressure down) referred to the target height.
 * Learnt values go into a copy of the settings (the caller applies it, so it
 * is validated like any register write and reaches flash on the board).
 *
 * Fixed point: a line point P2 + slope * (target - h) with slope in Pa/mm and
 * heights in um: |target - h| <= 50800 um and |slope| <= 20000 Pa/mm give
 * at most 1.02e6 Pa of shift, formed in int64. Coast: travel um * 1000 / rate
 * um/s in int64, clamped to the uint16 range of the setting.
 */
#include "leveler/alg3.h"

#include "leveler/fixed_point.h"

static void begin(const leveler_settings *set, leveler_settings *learnt, bool *changed)
{
    if (!*changed) {
        *learnt = *set;
        *changed = true;
    }
}

void leveler_alg3_note_close(leveler_alg3 *a, int8_t dir, int32_t p_spring_pa, int32_t line_pa)
{
    int32_t rate = leveler_alg3_prediction_rate(a);
    int32_t along = dir > 0 ? rate : -rate;
    a->watch.close_valid = along >= LEVELER_ALG3_COAST_MIN_RATE_UM_S;
    a->watch.close_dir = dir;
    a->watch.close_height_um = leveler_alg3_height_um(a);
    a->watch.close_rate_um_s = rate;
    a->watch.close_p_spring_pa = p_spring_pa;
    a->watch.close_line_pa = line_pa;
    a->watch.still_ms = 0; /* the settle waits for rest seen after the close, not before the move */
}

/* Halfway from old towards seen, clamped to [lo, hi]; seen outside is ignored (returns old). */
static int32_t towards(int32_t old, int64_t seen, int32_t lo, int32_t hi)
{
    if (seen < lo || seen > hi) {
        return old;
    }
    return (int32_t)(((int64_t)old + seen + 1) / 2);
}

/* towards(), or (the adopt bit set: commissioning) seen itself when within [lo, hi], clearing the bit. */
static int32_t learnt_value(leveler_alg3_watch *w, uint8_t bit, int32_t old, int64_t seen, int32_t lo, int32_t hi)
{
    if ((w->adopt & bit) != 0u && seen >= lo && seen <= hi) {
        w->adopt = (uint8_t)(w->adopt & ~bit);
        return (int32_t)seen;
    }
    return towards(old, seen, lo, hi);
}

/* Coast time: travel / rate at the close (a close slower than
 * COAST_MIN_RATE teaches none). */
static int32_t coast_time_seen(leveler_alg3_watch *w, bool up, int64_t travel_um, int32_t old)
{
    if (!w->close_valid) {
        return old;
    }
    int64_t rate = w->close_rate_um_s;
    int64_t tau_ms = leveler_div_round_i64(travel_um * 1000 * (rate < 0 ? -1 : 1), rate < 0 ? -rate : rate);
    uint8_t bit = up ? LEVELER_ALG3_ADOPT_TAU_UP : LEVELER_ALG3_ADOPT_TAU_DOWN;
    return learnt_value(w, bit, old, tau_ms, LEVELER_ALG3_COAST_MIN_MS, LEVELER_ALG3_COAST_MAX_MS);
}

/* Coast stiffness: the excess over the line at the close / the travel it gave. */
static int32_t coast_k_seen(leveler_alg3_watch *w, bool up, int64_t travel_um, int32_t old)
{
    if (w->close_line_pa == 0) {
        return old;
    }
    int64_t excess = up ? (int64_t)w->close_p_spring_pa - w->close_line_pa
                        : (int64_t)w->close_line_pa - w->close_p_spring_pa;
    int64_t along_um = up ? travel_um : -travel_um;
    if (excess <= 0 || along_um <= 0) {
        return old;
    }
    int64_t seen = leveler_div_round_i64(excess * 1000, along_um);
    uint8_t bit = up ? LEVELER_ALG3_ADOPT_K_UP : LEVELER_ALG3_ADOPT_K_DOWN;
    bool adopt = (w->adopt & bit) != 0u; /* commissioning: the default may be far off on a new rig */
    if (!adopt && (seen * LEVELER_ALG3_K_FACTOR < old || seen > (int64_t)old * LEVELER_ALG3_K_FACTOR)) {
        return old; /* a coast disturbed (a load change in it) teaches nothing */
    }
    return learnt_value(w, bit, old, seen, LEVELER_ALG3_K_MIN_PA_PER_MM, LEVELER_ALG3_K_MAX_PA_PER_MM);
}

static void learn_gap(leveler_alg3 *a, const leveler_settings *set, int8_t dir, int32_t p_break_pa,
                      leveler_settings *learnt, bool *changed);
static bool line_point(leveler_alg3 *a, const leveler_settings *set, int8_t dir, int32_t p_spring_pa,
                       leveler_settings *learnt, bool *changed);

/* An early probe's platform that broke away (moved its threshold) and came to rest without the rate
 * window seeing a motion: it stopped where P2 is back on the line of its motion. That point teaches
 * the line, the gap from where the last motion stopped, and is where this motion stopped. */
static void probe_stop(leveler_alg3 *a, const leveler_settings *set, bool up, leveler_settings *learnt,
                       bool *changed)
{
    leveler_alg3_watch *w = &a->watch;
    if (leveler_alg3_probe_moved_um(a, up) < a->probe_moved_um) {
        return;
    }
    unsigned newest = (a->ring_head + LEVELER_ALG3_RATE_TICKS - 1u) % LEVELER_ALG3_RATE_TICKS;
    int32_t p = w->p_spring_ring_pa[newest];
    int8_t dir = up ? 1 : -1;
    learn_gap(a, set, dir, p, learnt, changed);
    w->line_fresh = line_point(a, set, dir, p, learnt, changed);
    w->end_valid = true;
    w->end_trusted = true;
    w->end_dir = dir;
    w->end_height_um = leveler_alg3_height_um(a);
    w->end_p_spring_pa = p;
}

void leveler_alg3_learn_coast(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt,
                              bool *changed)
{
    leveler_alg3_watch *w = &a->watch;
    int64_t travel_um = (int64_t)leveler_alg3_height_um(a) - w->close_height_um;
    int64_t along_um = w->close_dir < 0 ? -travel_um : travel_um;
    bool probe = a->probe != LEVELER_ALG3_PROBE_NONE; /* commissioning judges its own probes */
    if (!probe && w->close_dir != 0 && along_um < LEVELER_ALG3_MOVED_UM && !w->line_fresh) {
        /* closed on an estimate and nothing moved: the line lies beyond it;
         * fill or vent on until the platform breaks away */
        w->end_trusted = false; /* still the gap's reference point when the platform breaks away */
        w->lines_valid = false;
        a->retry = true;
    }
    if (set->alg3_learn == 0u || w->close_dir == 0) {
        return;
    }
    bool up = w->close_dir > 0;
    if (probe && !w->line_fresh) {
        probe_stop(a, set, up, learnt, changed);
    }
    if (probe && w->line_fresh) {
        /* a probe closed before its break-away was seen: the excess counts from the line learnt since */
        w->close_line_pa = leveler_alg3_line_estimate(a, *changed ? learnt : set, up, w->close_height_um);
    }
    int32_t old_tau = up ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    int32_t old_k = up ? set->alg3_coast_k_up_pa_per_mm : set->alg3_coast_k_down_pa_per_mm;
    int32_t new_tau = coast_time_seen(w, up, travel_um, old_tau);
    int32_t new_k = coast_k_seen(w, up, travel_um, old_k);
    w->close_dir = 0;
    if (new_tau == old_tau && new_k == old_k) {
        return;
    }
    begin(set, learnt, changed);
    if (up) {
        learnt->alg3_coast_up_ms = (uint16_t)new_tau;
        learnt->alg3_coast_k_up_pa_per_mm = new_k;
    } else {
        learnt->alg3_coast_down_ms = (uint16_t)new_tau;
        learnt->alg3_coast_k_down_pa_per_mm = new_k;
    }
}

void leveler_alg3_probe_learn(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt,
                              bool *changed)
{
    leveler_alg3_learn_coast(a, set, learnt, changed);
    a->watch.close_valid = false;
    a->watch.close_dir = 0;
}

/* P2 where the present motion began or ended: the rate (a difference over the
 * window, on a filtered height) crosses its threshold about a window after
 * the platform starts or stops, while a fill may push P2 on at several psi/s;
 * so the oldest P2 of the window is taken. */
static int32_t p_spring_at_start(const leveler_alg3 *a)
{
    return a->watch.p_spring_ring_pa[a->ring_head]; /* the slot the next tick overwrites */
}

/* A point (h, P2) on the up (dir > 0) or down line, referred to the target. */
static bool line_point(leveler_alg3 *a, const leveler_settings *set, int8_t dir, int32_t p_spring_pa,
                       leveler_settings *learnt, bool *changed)
{
    int32_t h = leveler_alg3_height_um(a);
    int64_t dh = (int64_t)leveler_alg3_target_um(set) - h;
    if (dh > LEVELER_ALG3_LINE_REACH_UM || dh < -LEVELER_ALG3_LINE_REACH_UM) {
        return false;
    }
    int64_t p = (int64_t)p_spring_pa + leveler_div_round_i64(dh * set->alg3_line_slope_pa_per_mm, 1000);
    if (p < LEVELER_ALG3_LINE_MIN_PA || p > set->overpressure_limit_pa) {
        return false;
    }
    begin(set, learnt, changed);
    bool same_load = a->watch.lines_valid;
    a->watch.lines_valid = true;
    if (dir > 0) {
        learnt->alg3_up_pa = (int32_t)p;
        if (!same_load || learnt->alg3_down_pa >= learnt->alg3_up_pa) {
            learnt->alg3_down_pa = 0; /* learnt under another load */
        }
    } else {
        learnt->alg3_down_pa = (int32_t)p;
        if (!same_load || (learnt->alg3_up_pa != 0 && learnt->alg3_up_pa <= learnt->alg3_down_pa)) {
            learnt->alg3_up_pa = 0;
        }
    }
    return true;
}

static int32_t along_slope(const leveler_settings *set, int32_t p_pa, int32_t from_um, int32_t to_um)
{
    int64_t dh = (int64_t)to_um - from_um;
    return leveler_sat_i32((int64_t)p_pa + leveler_div_round_i64(dh * set->alg3_line_slope_pa_per_mm, 1000));
}

int32_t leveler_alg3_line_estimate(const leveler_alg3 *a, const leveler_settings *set, bool up, int32_t h)
{
    const leveler_alg3_watch *w = &a->watch;
    if (w->line_fresh || w->lines_valid) {
        int32_t at_target = up ? set->alg3_up_pa : set->alg3_down_pa;
        if (at_target != 0) {
            return along_slope(set, at_target, leveler_alg3_target_um(set), h);
        }
    }
    if (!w->end_valid || !w->end_trusted) {
        return 0;
    }
    int32_t p = along_slope(set, w->end_p_spring_pa, w->end_height_um, h);
    if ((w->end_dir > 0) == up) {
        return p;
    }
    return leveler_sat_i32((int64_t)p + (up ? set->alg3_gap_pa : -set->alg3_gap_pa));
}

/* The gap seen between where the last motion stopped on the other line and
 * this break-away (both of the present load), halfway into alg3_gap_pa. */
static void learn_gap(leveler_alg3 *a, const leveler_settings *set, int8_t dir, int32_t p_break_pa,
                      leveler_settings *learnt, bool *changed)
{
    leveler_alg3_watch *w = &a->watch;
    if (!w->end_valid || w->end_dir == dir) {
        return;
    }
    int32_t other = along_slope(set, w->end_p_spring_pa, w->end_height_um, leveler_alg3_height_um(a));
    int64_t gap = dir > 0 ? (int64_t)p_break_pa - other : (int64_t)other - p_break_pa;
    int32_t old = *changed ? learnt->alg3_gap_pa : set->alg3_gap_pa;
    int32_t next = learnt_value(w, LEVELER_ALG3_ADOPT_GAP, old, gap, LEVELER_ALG3_GAP_MIN_PA, LEVELER_ALG3_GAP_MAX_PA);
    if (next != old) {
        begin(set, learnt, changed);
        learnt->alg3_gap_pa = next;
    }
}

void leveler_alg3_learn(leveler_alg3 *a, const leveler_settings *set, int32_t p_spring_pa, uint32_t dt_ms,
                        leveler_settings *learnt, bool *changed)
{
    leveler_alg3_watch *w = &a->watch;
    unsigned newest = (a->ring_head + LEVELER_ALG3_RATE_TICKS - 1u) % LEVELER_ALG3_RATE_TICKS;
    w->p_spring_ring_pa[newest] = p_spring_pa;
    int32_t rate = a->rate_um_s;
    bool still = rate < LEVELER_ALG3_STILL_UM_S && rate > -LEVELER_ALG3_STILL_UM_S;
    w->still_ms = still ? leveler_sat_add_u32(w->still_ms, dt_ms) : 0u;
    bool learn = set->alg3_learn != 0u;
    if (rate > LEVELER_ALG3_MOVING_UM_S || rate < -LEVELER_ALG3_MOVING_UM_S) {
        int8_t dir = rate > 0 ? 1 : -1;
        if (a->phase == LEVELER_ALG3_IDLE && !a->commissioning) {
            w->lines_valid = false; /* nobody asked for this motion: the load has changed */
        }
        /* a probe closes on the first millimetre, before the rate window sees the motion: its settle's */
        bool probed = a->probe != LEVELER_ALG3_PROBE_NONE && a->phase == LEVELER_ALG3_SETTLING && w->close_dir == dir;
        bool breaks_away = w->motion == 0 && ((dir > 0 && a->phase == LEVELER_ALG3_FILLING) ||
                                              (dir < 0 && a->phase == LEVELER_ALG3_VENTING) || probed);
        if (learn && breaks_away) {
            int32_t p_break = p_spring_at_start(a);
            learn_gap(a, set, dir, p_break, learnt, changed);
            a->watch.line_fresh = line_point(a, set, dir, p_break, learnt, changed);
        }
        w->motion = dir;
        w->ended = false;
    } else if (w->motion != 0 && still && !w->ended) {
        /* the motion has just ended: P2 where it ended lies on its line */
        w->ended = true;
        w->end_valid = true;
        w->end_trusted = true;
        w->end_dir = w->motion;
        w->end_height_um = leveler_alg3_height_um(a);
        w->end_p_spring_pa = p_spring_at_start(a);
    } else if (w->motion != 0 && w->still_ms >= LEVELER_ALG3_REST_MS) {
        bool sealed = a->phase == LEVELER_ALG3_IDLE || a->phase == LEVELER_ALG3_SETTLING;
        /* a platform that coasted from a fast close came to rest past its line,
         * carried by its momentum between the lines: not a point of the line */
        bool coasted = a->phase == LEVELER_ALG3_SETTLING && w->close_valid;
        if (learn && sealed && !coasted) {
            line_point(a, set, w->motion, p_spring_pa, learnt, changed);
        }
        w->motion = 0;
    }
}
