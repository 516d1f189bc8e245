/*
 * Algorithm 3, learning from the rig's own motion (alg3_learn.h): the coast
 * time constants that the early close predicts with, and the hysteresis lines
 * (break-away pressure up, hold pressure down) referred to the target height.
 * It reads the estimates below it and what the controller shows it (the
 * view); it writes only its own watch and the learnt settings.
 *
 * Fixed point: a line point P2 + slope * (target - h) with slope in Pa/mm and
 * heights in um: |target - h| <= 50800 um and |slope| <= 20000 Pa/mm give
 * at most 1.02e6 Pa of shift, formed in int64. Coast: travel um * 1000 / rate
 * um/s in int64, clamped to the uint16 range of the setting.
 */
#include "leveler/alg3_learn.h"

#include "leveler/fixed_point.h"

static void begin(const leveler_settings *set, leveler_settings *learnt, bool *changed)
{
    if (!*changed) {
        *learnt = *set;
        *changed = true;
    }
}

void leveler_alg3_note_close(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, int8_t dir,
                             int32_t p_spring_pa, int32_t line_pa)
{
    int32_t rate = leveler_alg3_prediction_rate(f);
    int32_t along = dir > 0 ? rate : -rate;
    w->close_valid = along >= LEVELER_ALG3_COAST_MIN_RATE_UM_S;
    w->close_dir = dir;
    w->close_height_um = leveler_alg3_height_um(f);
    w->close_rate_um_s = rate;
    w->close_p_spring_pa = p_spring_pa;
    w->close_line_pa = line_pa;
    w->still_ms = 0; /* the settle waits for rest seen after the close, not before the move */
}

void leveler_alg3_forget_close(leveler_alg3_watch *w)
{
    w->close_valid = false;
    w->close_dir = 0;
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

static void learn_gap(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, const leveler_settings *set,
                      int8_t dir, int32_t p_break_pa, leveler_settings *learnt, bool *changed);
static bool line_point(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, const leveler_settings *set,
                       int8_t dir, int32_t p_spring_pa, leveler_settings *learnt, bool *changed);

/* The ring slot of the newest P2 (the slot of the filter's newest height). */
static unsigned newest_slot(const leveler_alg3_height_filter *f)
{
    return (f->ring_head + LEVELER_ALG3_RATE_TICKS - 1u) % LEVELER_ALG3_RATE_TICKS;
}

/* A motion the dir way (+1 up) stopped at the filtered height with P2 p: where the line estimate starts. */
static void stopped_at(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, int8_t dir, int32_t p)
{
    w->lines.end_valid = true;
    w->lines.end_trusted = true;
    w->lines.end_dir = dir;
    w->lines.end_height_um = leveler_alg3_height_um(f);
    w->lines.end_p_spring_pa = p;
}

/* An early probe's platform that broke away (moved its threshold) and came to rest without the rate
 * window seeing a motion: it stopped where P2 is back on the line of its motion. That point teaches
 * the line, the gap from where the last motion stopped, and is where this motion stopped. */
static void probe_stop(leveler_alg3_watch *w, const leveler_alg3_view *v, const leveler_settings *set, bool up,
                       leveler_settings *learnt, bool *changed)
{
    const leveler_alg3_height_filter *f = v->filter;
    if (leveler_alg3_moved_um(f, v->move_from_um, up) < v->probe_moved_um) {
        return;
    }
    int32_t p = w->p_spring_ring_pa[newest_slot(f)];
    int8_t dir = up ? 1 : -1;
    learn_gap(w, f, set, dir, p, learnt, changed);
    w->lines.line_fresh = line_point(w, f, set, dir, p, learnt, changed);
    stopped_at(w, f, dir, p);
}

/* Closed on an estimate and nothing moved: the line lies beyond it (a probe: commissioning judges its own). */
static leveler_alg3_verdict judge_close(leveler_alg3_watch *w, const leveler_alg3_view *v, int64_t travel_um)
{
    int64_t along_um = w->close_dir < 0 ? -travel_um : travel_um;
    if (v->probe || w->close_dir == 0 || along_um >= LEVELER_ALG3_MOVED_UM || w->lines.line_fresh) {
        return LEVELER_ALG3_VERDICT_NONE;
    }
    w->lines.end_trusted = false; /* still the gap's reference point when the platform breaks away */
    w->lines.lines_valid = false;
    return LEVELER_ALG3_VERDICT_RETRY;
}

/* Closed on an estimated line with an excess that should have carried the platform K_FACTOR times
 * farther than it went, and it broke away (moved) before it came to rest: the estimate lay beyond the
 * line (an end point taken while a valve still moved P2, 320 ms of a vent's fall). The platform rests
 * on its line now, so the next estimate starts from there rather than closing at once on the same
 * error, move after move (a creep of 0.1 s bursts). */
static void short_close(leveler_alg3_watch *w, const leveler_alg3_view *v, const leveler_settings *set,
                        int64_t travel_um)
{
    bool up = w->close_dir > 0;
    int64_t excess = up ? (int64_t)w->close_p_spring_pa - w->close_line_pa
                        : (int64_t)w->close_line_pa - w->close_p_spring_pa;
    int64_t along_um = up ? travel_um : -travel_um;
    int64_t k = up ? set->alg3_coast_k_up_pa_per_mm : set->alg3_coast_k_down_pa_per_mm;
    if (v->probe || w->close_dir == 0 || w->close_line_pa == 0 || w->lines.line_fresh || excess <= 0 ||
        along_um < LEVELER_ALG3_MOVED_UM || along_um * k * LEVELER_ALG3_K_FACTOR >= excess * 1000) {
        return;
    }
    stopped_at(w, v->filter, w->close_dir, w->p_spring_ring_pa[newest_slot(v->filter)]);
    w->lines.lines_valid = false;
}

leveler_alg3_verdict leveler_alg3_learn_coast(leveler_alg3_watch *w, const leveler_alg3_view *v,
                                              const leveler_settings *set, leveler_settings *learnt, bool *changed)
{
    int64_t travel_um = (int64_t)leveler_alg3_height_um(v->filter) - w->close_height_um;
    leveler_alg3_verdict verdict = judge_close(w, v, travel_um);
    short_close(w, v, *changed ? learnt : set, travel_um);
    if (set->alg3_learn == 0u || w->close_dir == 0) {
        return verdict;
    }
    bool up = w->close_dir > 0;
    if (v->probe && !w->lines.line_fresh) {
        probe_stop(w, v, set, up, learnt, changed);
    }
    if (v->probe && w->lines.line_fresh) {
        /* a probe closed before its break-away was seen: the excess counts from the line learnt since */
        w->close_line_pa = leveler_alg3_line_estimate(&w->lines, *changed ? learnt : set, up, w->close_height_um);
    }
    int32_t old_tau = up ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    int32_t old_k = up ? set->alg3_coast_k_up_pa_per_mm : set->alg3_coast_k_down_pa_per_mm;
    int32_t new_tau = coast_time_seen(w, up, travel_um, old_tau);
    int32_t new_k = coast_k_seen(w, up, travel_um, old_k);
    w->close_dir = 0;
    if (new_tau == old_tau && new_k == old_k) {
        return verdict;
    }
    begin(set, learnt, changed);
    if (up) {
        learnt->alg3_coast_up_ms = (uint16_t)new_tau;
        learnt->alg3_coast_k_up_pa_per_mm = new_k;
    } else {
        learnt->alg3_coast_down_ms = (uint16_t)new_tau;
        learnt->alg3_coast_k_down_pa_per_mm = new_k;
    }
    return verdict;
}

/* P2 where the present motion began or ended: the rate (a difference over the
 * window, on a filtered height) crosses its threshold about a window after
 * the platform starts or stops, while a fill may push P2 on at several psi/s;
 * so the oldest P2 of the window is taken. */
static int32_t p_spring_at_start(const leveler_alg3_watch *w, const leveler_alg3_height_filter *f)
{
    return w->p_spring_ring_pa[f->ring_head]; /* the slot the next tick overwrites */
}

/* A point (h, P2) on the up (dir > 0) or down line, referred to the target. */
static bool line_point(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, const leveler_settings *set,
                       int8_t dir, int32_t p_spring_pa, leveler_settings *learnt, bool *changed)
{
    int32_t h = leveler_alg3_height_um(f);
    int64_t dh = (int64_t)leveler_alg3_target_um(set) - h;
    if (dh > LEVELER_ALG3_LINE_REACH_UM || dh < -LEVELER_ALG3_LINE_REACH_UM) {
        return false;
    }
    int64_t p = (int64_t)p_spring_pa + leveler_div_round_i64(dh * set->alg3_line_slope_pa_per_mm, 1000);
    if (p < LEVELER_ALG3_LINE_MIN_PA || p > set->overpressure_limit_pa) {
        return false;
    }
    begin(set, learnt, changed);
    bool same_load = w->lines.lines_valid;
    w->lines.lines_valid = true;
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

/* The gap seen between where the last motion stopped on the other line and
 * this break-away (both of the present load), halfway into alg3_gap_pa. */
static void learn_gap(leveler_alg3_watch *w, const leveler_alg3_height_filter *f, const leveler_settings *set,
                      int8_t dir, int32_t p_break_pa, leveler_settings *learnt, bool *changed)
{
    const leveler_alg3_lines *lines = &w->lines;
    if (!lines->end_valid || lines->end_dir == dir) {
        return;
    }
    int32_t other = leveler_alg3_along_slope_pa(set, lines->end_p_spring_pa, lines->end_height_um,
                                                leveler_alg3_height_um(f));
    int64_t gap = dir > 0 ? (int64_t)p_break_pa - other : (int64_t)other - p_break_pa;
    int32_t old = *changed ? learnt->alg3_gap_pa : set->alg3_gap_pa;
    int32_t next = learnt_value(w, LEVELER_ALG3_ADOPT_GAP, old, gap, LEVELER_ALG3_GAP_MIN_PA, LEVELER_ALG3_GAP_MAX_PA);
    if (next != old) {
        begin(set, learnt, changed);
        learnt->alg3_gap_pa = next;
    }
}

void leveler_alg3_learn(leveler_alg3_watch *w, const leveler_alg3_view *v, const leveler_settings *set,
                        int32_t p_spring_pa, uint32_t dt_ms, leveler_settings *learnt, bool *changed)
{
    const leveler_alg3_height_filter *f = v->filter;
    w->p_spring_ring_pa[newest_slot(f)] = p_spring_pa;
    int32_t rate = f->rate_um_s;
    bool still = rate < LEVELER_ALG3_STILL_UM_S && rate > -LEVELER_ALG3_STILL_UM_S;
    w->still_ms = still ? leveler_sat_add_u32(w->still_ms, dt_ms) : 0u;
    bool learn = set->alg3_learn != 0u;
    if (rate > LEVELER_ALG3_MOVING_UM_S || rate < -LEVELER_ALG3_MOVING_UM_S) {
        int8_t dir = rate > 0 ? 1 : -1;
        bool idle = v->valves_dir == 0 && !v->settling;
        if (idle && !v->commissioning) {
            w->lines.lines_valid = false; /* nobody asked for this motion: the load has changed */
            w->lines.end_trusted = false; /* and where the last motion ended is the old load's */
        }
        /* a probe closes on the first millimetre, before the rate window sees the motion: its settle's */
        bool probed = v->probe && v->settling && w->close_dir == dir;
        bool breaks_away = w->motion == 0 && (v->valves_dir == dir || probed) && !v->topup;
        if (learn && breaks_away) {
            int32_t p_break = p_spring_at_start(w, f);
            learn_gap(w, f, set, dir, p_break, learnt, changed);
            w->lines.line_fresh = line_point(w, f, set, dir, p_break, learnt, changed);
        }
        w->motion = dir;
        w->ended = false;
    } else if (w->motion != 0 && still && !w->ended) {
        /* the motion has just ended: P2 where it ended lies on its line */
        w->ended = true;
        stopped_at(w, f, w->motion, p_spring_at_start(w, f));
    } else if (w->motion != 0 && w->still_ms >= LEVELER_ALG3_REST_MS) {
        bool sealed = v->valves_dir == 0; /* idle or settling */
        /* a platform that coasted from a fast close came to rest past its line,
         * carried by its momentum between the lines: not a point of the line */
        bool coasted = v->settling && w->close_valid;
        if (learn && sealed && !coasted) {
            line_point(w, f, set, w->motion, p_spring_pa, learnt, changed);
        }
        w->motion = 0;
    }
}
