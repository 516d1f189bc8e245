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

void leveler_alg3_note_close(leveler_alg3 *a, int8_t dir)
{
    int32_t along = dir > 0 ? a->rate_um_s : -a->rate_um_s;
    a->watch.close_valid = along >= LEVELER_ALG3_COAST_MIN_RATE_UM_S;
    a->watch.close_dir = dir;
    a->watch.close_height_um = leveler_alg3_height_um(a);
    a->watch.close_rate_um_s = a->rate_um_s;
}

/* Coast time seen: travel after the close / rate at the close. Implausible
 * (backwards, or outside 20 ms..5 s) is ignored; else halfway towards it. */
void leveler_alg3_learn_coast(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt, bool *changed)
{
    if (!a->watch.close_valid || set->alg3_learn == 0u) {
        a->watch.close_valid = false;
        return;
    }
    a->watch.close_valid = false;
    int64_t travel = (int64_t)leveler_alg3_height_um(a) - a->watch.close_height_um;
    int64_t seen_ms = leveler_div_round_i64(travel * 1000 * (a->watch.close_rate_um_s < 0 ? -1 : 1),
                                            a->watch.close_rate_um_s < 0 ? -(int64_t)a->watch.close_rate_um_s
                                                                         : (int64_t)a->watch.close_rate_um_s);
    if (seen_ms < LEVELER_ALG3_COAST_MIN_MS || seen_ms > LEVELER_ALG3_COAST_MAX_MS) {
        return;
    }
    uint16_t old = a->watch.close_dir > 0 ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    uint16_t next = (uint16_t)(((uint32_t)old + (uint32_t)seen_ms + 1u) / 2u);
    if (next == old) {
        return;
    }
    begin(set, learnt, changed);
    if (a->watch.close_dir > 0) {
        learnt->alg3_coast_up_ms = next;
    } else {
        learnt->alg3_coast_down_ms = next;
    }
}

/* P2 where the present motion began: half the rate window back. */
static int32_t p_spring_at_start(const leveler_alg3 *a)
{
    unsigned newest = (a->ring_head + LEVELER_ALG3_RATE_TICKS - 1u) % LEVELER_ALG3_RATE_TICKS;
    unsigned back = (newest + LEVELER_ALG3_RATE_TICKS - LEVELER_ALG3_RATE_TICKS / 2u) % LEVELER_ALG3_RATE_TICKS;
    return a->watch.p_spring_ring_pa[back];
}

/* A point (h, P2) on the up (dir > 0) or down line, referred to the target. */
static void line_point(const leveler_alg3 *a, const leveler_settings *set, int8_t dir, int32_t p_spring_pa,
                       leveler_settings *learnt, bool *changed)
{
    int32_t h = leveler_alg3_height_um(a);
    int64_t dh = (int64_t)leveler_alg3_target_um(set) - h;
    if (dh > LEVELER_ALG3_LINE_REACH_UM || dh < -LEVELER_ALG3_LINE_REACH_UM) {
        return;
    }
    int64_t p = (int64_t)p_spring_pa + leveler_div_round_i64(dh * set->alg3_line_slope_pa_per_mm, 1000);
    if (p < LEVELER_ALG3_LINE_MIN_PA || p > set->overpressure_limit_pa) {
        return;
    }
    begin(set, learnt, changed);
    if (dir > 0) {
        learnt->alg3_up_pa = (int32_t)p;
        if (learnt->alg3_down_pa >= learnt->alg3_up_pa) {
            learnt->alg3_down_pa = 0; /* learnt under another load */
        }
    } else {
        learnt->alg3_down_pa = (int32_t)p;
        if (learnt->alg3_up_pa != 0 && learnt->alg3_up_pa <= learnt->alg3_down_pa) {
            learnt->alg3_up_pa = 0;
        }
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
        bool breaks_away = w->motion == 0 && ((dir > 0 && a->phase == LEVELER_ALG3_FILLING) ||
                                              (dir < 0 && a->phase == LEVELER_ALG3_VENTING));
        if (learn && breaks_away) {
            line_point(a, set, dir, p_spring_at_start(a), learnt, changed);
        }
        w->motion = dir;
    } else if (w->motion != 0 && w->still_ms >= LEVELER_ALG3_REST_MS) {
        bool sealed = a->phase == LEVELER_ALG3_IDLE || a->phase == LEVELER_ALG3_SETTLING;
        if (learn && sealed) {
            line_point(a, set, w->motion, p_spring_pa, learnt, changed);
        }
        w->motion = 0;
    }
}
