/*
 * Algorithm 3's estimates (alg3_estimate.h): the filter, the coast model and
 * the line estimates. Pure apart from the filter's own state.
 */
#include "leveler/alg3_estimate.h"

#include "leveler/app.h"
#include "leveler/fixed_point.h"

int32_t leveler_alg3_height_um(const leveler_alg3_height_filter *f)
{
    return (int32_t)leveler_div_round_i64(f->height_q, LEVELER_ALG3_Q);
}

int32_t leveler_alg3_prediction_rate(const leveler_alg3_height_filter *f)
{
    bool fast = f->rate_fast_um_s >= LEVELER_ALG3_FAST_UM_S || f->rate_fast_um_s <= -LEVELER_ALG3_FAST_UM_S;
    return fast ? f->rate_fast_um_s : f->rate_um_s;
}

int32_t leveler_alg3_moved_um(const leveler_alg3_height_filter *f, int32_t from_um, bool up)
{
    int32_t h = leveler_alg3_height_um(f);
    return leveler_sat_i32(up ? (int64_t)h - from_um : (int64_t)from_um - h);
}

void leveler_alg3_filter(leveler_alg3_height_filter *f, int32_t height_um)
{
    int64_t x_q = (int64_t)height_um * LEVELER_ALG3_Q;
    if (!f->primed) {
        f->primed = true;
        f->height_q = leveler_sat_i32(x_q);
        for (unsigned i = 0; i < LEVELER_ALG3_RATE_TICKS; i++) {
            f->ring_um[i] = height_um;
        }
        f->ring_head = 0;
        f->rate_um_s = 0;
        f->rate_fast_um_s = 0;
        return;
    }
    /* Truncating division: the state moves by (x - state)/4 rounded toward zero,
     * at most 1/16 um short of the exact filter per tick (it cannot drift: a
     * remaining difference of >= 4 LSB always moves it). */
    f->height_q = leveler_sat_i32((int64_t)f->height_q + (x_q - (int64_t)f->height_q) / LEVELER_ALG3_FILTER_DIV);
    int32_t h = leveler_alg3_height_um(f);
    int32_t oldest = f->ring_um[f->ring_head]; /* LEVELER_ALG3_RATE_TICKS ticks ago */
    int32_t recent = f->ring_um[(f->ring_head + LEVELER_ALG3_RATE_TICKS - LEVELER_ALG3_FAST_TICKS) %
                                LEVELER_ALG3_RATE_TICKS];
    f->ring_um[f->ring_head] = h;
    f->ring_head = (uint8_t)((f->ring_head + 1u) % LEVELER_ALG3_RATE_TICKS);
    f->rate_um_s = leveler_sat_i32(leveler_div_round_i64(((int64_t)h - (int64_t)oldest) * 1000,
                                                         (int64_t)LEVELER_ALG3_RATE_TICKS * LEVELER_TICK_MS));
    f->rate_fast_um_s = leveler_sat_i32(leveler_div_round_i64(((int64_t)h - (int64_t)recent) * 1000,
                                                              (int64_t)LEVELER_ALG3_FAST_TICKS * LEVELER_TICK_MS));
}

int32_t leveler_alg3_target_um(const leveler_settings *set)
{
    int64_t span = (int64_t)set->band_upper_um - (int64_t)set->band_lower_um;
    return leveler_sat_i32((int64_t)set->band_lower_um +
                           leveler_div_round_i64(span * (int64_t)set->alg3_target_permille, 1000));
}

int32_t leveler_alg3_predict_um(int32_t height_um, int32_t rate_um_s, uint16_t coast_ms)
{
    return leveler_sat_i32((int64_t)height_um + leveler_div_round_i64((int64_t)rate_um_s * (int64_t)coast_ms, 1000));
}

int32_t leveler_alg3_along_slope_pa(const leveler_settings *set, int32_t p_pa, int32_t from_um, int32_t to_um)
{
    int64_t dh = (int64_t)to_um - from_um;
    return leveler_sat_i32((int64_t)p_pa + leveler_div_round_i64(dh * set->alg3_line_slope_pa_per_mm, 1000));
}

bool leveler_alg3_line_known(const leveler_alg3_lines *lines, const leveler_settings *set, bool up)
{
    return (lines->line_fresh || lines->lines_valid) && (up ? set->alg3_up_pa : set->alg3_down_pa) != 0;
}

bool leveler_alg3_line_across_gap(const leveler_alg3_lines *lines, const leveler_settings *set, bool up)
{
    return !leveler_alg3_line_known(lines, set, up) && lines->end_valid && lines->end_trusted &&
           (lines->end_dir > 0) != up;
}

int32_t leveler_alg3_line_estimate(const leveler_alg3_lines *lines, const leveler_settings *set, bool up, int32_t h)
{
    if (leveler_alg3_line_known(lines, set, up)) {
        return leveler_alg3_along_slope_pa(set, up ? set->alg3_up_pa : set->alg3_down_pa, leveler_alg3_target_um(set),
                                           h);
    }
    if (!lines->end_valid || !lines->end_trusted) {
        return 0;
    }
    int32_t p = leveler_alg3_along_slope_pa(set, lines->end_p_spring_pa, lines->end_height_um, h);
    if (!leveler_alg3_line_across_gap(lines, set, up)) {
        return p;
    }
    return leveler_sat_i32((int64_t)p + (up ? set->alg3_gap_pa : -set->alg3_gap_pa));
}

int32_t leveler_alg3_line_rest_um(bool up, int32_t h, int32_t p_spring_pa, int32_t line_pa, int32_t k_pa_per_mm)
{
    int64_t excess = up ? (int64_t)p_spring_pa - line_pa : (int64_t)line_pa - p_spring_pa;
    if (line_pa == 0 || excess <= 0 || k_pa_per_mm <= 0) {
        return h;
    }
    int64_t travel_um = leveler_div_round_i64(excess * 1000, k_pa_per_mm);
    return leveler_sat_i32(up ? (int64_t)h + travel_um : (int64_t)h - travel_um);
}

/* The line prediction with the learnt coast stiffness of the move's direction. */
static int32_t line_prediction(const leveler_settings *set, bool up, int32_t h, int32_t p_spring_pa, int32_t line_pa)
{
    int32_t k = up ? set->alg3_coast_k_up_pa_per_mm : set->alg3_coast_k_down_pa_per_mm;
    return leveler_alg3_line_rest_um(up, h, p_spring_pa, line_pa, k);
}

bool leveler_alg3_coast_rest(const int32_t h[4], int8_t dir, int32_t *rest_um)
{
    int64_t sign = dir < 0 ? -1 : 1;
    int64_t d1 = ((int64_t)h[1] - h[0]) * sign, d2 = ((int64_t)h[2] - h[1]) * sign, d3 = ((int64_t)h[3] - h[2]) * sign;
    if (d3 < LEVELER_ALG3_COAST_STEP_MIN_UM || d2 <= d3 || d1 <= d2 || d1 > INT32_MAX || 2 * d2 < d1) {
        return false; /* not moving the dir way, not slowing, a fast stop, or a jump no platform makes */
    }
    /* the same ratio twice: |d3/d2 - d2/d1| <= d2/d1 / 8, i.e. |d3 d1 - d2^2| <= d2^2 / 8 (products
     * < 2^62; an integer is over the quotient exactly when it is over its floor) */
    int64_t mismatch = d3 * d1 - d2 * d2;
    if ((mismatch < 0 ? -mismatch : mismatch) > d2 * d2 / LEVELER_ALG3_COAST_RATIO_TOL) {
        return false;
    }
    int64_t more = leveler_div_round_i64(d3 * d3, d2 - d3);
    *rest_um = leveler_sat_i32((int64_t)h[3] + sign * more);
    return true;
}

/* A prediction with its travel stretched by EARLY_NUM/EARLY_DEN (an estimate's hedge). */
static int64_t stretched(int32_t h, int32_t pred)
{
    return (int64_t)h + ((int64_t)pred - h) * LEVELER_ALG3_EARLY_NUM / LEVELER_ALG3_EARLY_DEN;
}

bool leveler_alg3_close_now(const leveler_settings *set, bool up, int32_t h, int32_t rate_um_s, int32_t p_spring_pa,
                            int32_t line_pa, bool line_sure)
{
    int32_t target = leveler_alg3_target_um(set);
    int32_t along = up ? rate_um_s : -rate_um_s;
    uint16_t coast = up ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    int64_t by_rate = along > LEVELER_ALG3_STILL_UM_S ? stretched(h, leveler_alg3_predict_um(h, rate_um_s, coast)) : h;
    int32_t line_rest = line_prediction(set, up, h, p_spring_pa, line_pa);
    /* P2 past the line is an excess that carries the platform the move's way only once it moves that
     * way: while it still goes the other way (the load changed) P2 there is the squeeze, not an excess */
    int64_t by_line = along < -LEVELER_ALG3_STILL_UM_S ? h : line_sure ? (int64_t)line_rest : stretched(h, line_rest);
    if (up) {
        return h >= target || h > set->band_upper_um || by_rate >= target || by_line >= target;
    }
    return h <= target || h < set->band_lower_um || by_rate <= target || by_line <= target;
}
