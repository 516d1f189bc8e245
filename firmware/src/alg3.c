/*
 * Algorithm 3, the phase logic (alg3.h). Learning is in alg3_learn.c.
 *
 * Fixed point: heights um (int32), rates um/s (int32), pressures Pa absolute
 * (int32), times ms (uint32, differences only, so wrap-around is harmless).
 * The filter state is height * 16 (|height| <= 2^27 um keeps it in int32; the
 * sensor calibration limits heights to +-2e6 um). Products that can exceed
 * int32 (rate * coast, span * permille, excess * dt) are formed in int64 and
 * saturated back.
 */
#include "leveler/alg3.h"

#include <string.h>

#include "leveler/app.h"
#include "leveler/fixed_point.h"

void leveler_alg3_init(leveler_alg3 *a, uint32_t now_ms)
{
    memset(a, 0, sizeof(*a));
    a->phase = LEVELER_ALG3_IDLE;
    a->phase_start_ms = now_ms;
    a->last_ms = now_ms;
    leveler_dwell_init(&a->dwell, now_ms, UINT16_MAX);
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

int32_t leveler_alg3_height_um(const leveler_alg3 *a)
{
    return (int32_t)leveler_div_round_i64(a->height_q, LEVELER_ALG3_Q);
}

void leveler_alg3_filter(leveler_alg3 *a, int32_t height_um)
{
    int64_t x_q = (int64_t)height_um * LEVELER_ALG3_Q;
    if (!a->primed) {
        a->primed = true;
        a->height_q = leveler_sat_i32(x_q);
        for (unsigned i = 0; i < LEVELER_ALG3_RATE_TICKS; i++) {
            a->ring_um[i] = height_um;
        }
        a->ring_head = 0;
        a->rate_um_s = 0;
        return;
    }
    /* Truncating division: the state moves by (x - state)/4 rounded toward zero,
     * at most 1/16 um short of the exact filter per tick (it cannot drift: a
     * remaining difference of >= 4 LSB always moves it). */
    a->height_q = leveler_sat_i32((int64_t)a->height_q + (x_q - (int64_t)a->height_q) / LEVELER_ALG3_FILTER_DIV);
    int32_t h = leveler_alg3_height_um(a);
    int32_t oldest = a->ring_um[a->ring_head]; /* LEVELER_ALG3_RATE_TICKS ticks ago */
    a->ring_um[a->ring_head] = h;
    a->ring_head = (uint8_t)((a->ring_head + 1u) % LEVELER_ALG3_RATE_TICKS);
    a->rate_um_s = leveler_sat_i32(leveler_div_round_i64(((int64_t)h - (int64_t)oldest) * 1000,
                                                         (int64_t)LEVELER_ALG3_RATE_TICKS * LEVELER_TICK_MS));
}

/* Where the filtered height is against the band, and for how long and how far. */
static void track_departure(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms, uint32_t dt_ms)
{
    int8_t dir = 0;
    int64_t excess = 0;
    if (h < set->band_lower_um) {
        dir = -1;
        excess = (int64_t)set->band_lower_um - h;
    } else if (h > set->band_upper_um) {
        dir = 1;
        excess = (int64_t)h - set->band_upper_um;
    }
    if (dir != a->out_dir) {
        a->out_dir = dir;
        a->out_since_ms = now_ms;
        a->out_area_um_ms = 0;
        return;
    }
    if (dir != 0 && a->out_area_um_ms < INT64_MAX / 2) { /* excess <= 2^32, dt <= 2^32: no overflow */
        a->out_area_um_ms += excess * (int64_t)dt_ms;
    }
}

static bool departure_confirmed(const leveler_alg3 *a, const leveler_settings *set, uint32_t now_ms)
{
    return a->out_dir != 0 && now_ms - a->out_since_ms >= set->alg3_persist_ms &&
           a->out_area_um_ms >= (int64_t)set->alg3_confirm_um_s * 1000;
}

static void enter(leveler_alg3 *a, uint8_t phase, uint32_t now_ms)
{
    a->phase = phase;
    a->phase_start_ms = now_ms;
}

/* In band (or waiting): act on a confirmed departure unless the platform is
 * already on its way back (its predicted rest is inside the band). */
static void idle(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms)
{
    if (!departure_confirmed(a, set, now_ms)) {
        return;
    }
    uint16_t coast = a->out_dir < 0 ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    int32_t pred = leveler_alg3_predict_um(h, a->rate_um_s, coast);
    bool returning = (a->out_dir < 0) ? (a->rate_um_s > LEVELER_ALG3_MOVING_UM_S && pred >= set->band_lower_um)
                                      : (a->rate_um_s < -LEVELER_ALG3_MOVING_UM_S && pred <= set->band_upper_um);
    if (returning) {
        return;
    }
    enter(a, a->out_dir < 0 ? LEVELER_ALG3_FILLING : LEVELER_ALG3_VENTING, now_ms);
    a->moves = leveler_sat_inc_u16(a->moves);
}

/* Filling or venting: close when the platform is predicted to come to rest at
 * the target, or is there, or has gone through the band. */
static void moving(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms)
{
    int32_t target = leveler_alg3_target_um(set);
    bool up = a->phase == LEVELER_ALG3_FILLING;
    int32_t rate = up ? a->rate_um_s : -a->rate_um_s; /* along the move */
    int32_t pred = leveler_alg3_predict_um(h, a->rate_um_s, up ? set->alg3_coast_up_ms : set->alg3_coast_down_ms);
    bool there = up ? (h >= target || h > set->band_upper_um) : (h <= target || h < set->band_lower_um);
    bool coasts_there = rate > LEVELER_ALG3_STILL_UM_S && (up ? pred >= target : pred <= target);
    if (there || coasts_there) {
        leveler_alg3_note_close(a, up ? 1 : -1);
        enter(a, LEVELER_ALG3_SETTLING, now_ms);
    }
}

static void settling(leveler_alg3 *a, const leveler_settings *set, uint32_t now_ms, leveler_settings *learnt,
                     bool *changed)
{
    uint32_t in_phase = now_ms - a->phase_start_ms;
    bool at_rest = in_phase >= LEVELER_ALG3_REST_MS && a->watch.still_ms >= LEVELER_ALG3_REST_MS;
    if (at_rest || in_phase >= set->alg3_settle_ms) {
        leveler_alg3_learn_coast(a, set, learnt, changed);
        enter(a, LEVELER_ALG3_IDLE, now_ms);
    }
}

/* The outputs of the phase. With an accumulator: recharged at rest (with a
 * hysteresis, so pressure noise does not cycle the compressor), opened in a
 * fill while it holds more than the spring, shut while venting. */
static void phase_outputs(leveler_alg3 *a, const leveler_settings *set, int32_t p_spring_pa, int32_t p_acc_pa,
                          leveler_outputs *out)
{
    bool acc = set->alg3_accumulator != 0u;
    memset(out, 0, sizeof(*out));
    if (a->phase == LEVELER_ALG3_FILLING) {
        out->compressor = true;
        out->spring_valve = true;
        out->acc_valve = acc && (int64_t)p_acc_pa > (int64_t)p_spring_pa + LEVELER_ALG3_ACC_HELP_PA;
        return;
    }
    if (a->phase == LEVELER_ALG3_VENTING) {
        out->spring_valve = true;
        out->vent_valve = true;
        return;
    }
    if (a->phase == LEVELER_ALG3_IDLE && acc) {
        if ((int64_t)p_acc_pa < (int64_t)set->acc_charge_max_pa - LEVELER_ALG3_RECHARGE_HYST_PA) {
            a->recharging = true;
        } else if (p_acc_pa >= set->acc_charge_max_pa) {
            a->recharging = false;
        }
        out->compressor = a->recharging;
        out->acc_valve = a->recharging;
    }
}

static leveler_control_state band_state(uint8_t phase)
{
    if (phase == LEVELER_ALG3_FILLING) {
        return LEVELER_STATE_CHARGING;
    }
    return (phase == LEVELER_ALG3_VENTING) ? LEVELER_STATE_DISCHARGING : LEVELER_STATE_IN_BAND;
}

leveler_control_state leveler_alg3_step(leveler_alg3 *a, const leveler_settings *set, int32_t height_um,
                                        int32_t p_spring_pa, int32_t p_pipe_pa, int32_t p_acc_pa, uint32_t now_ms,
                                        bool held, leveler_outputs *out, leveler_settings *learnt,
                                        bool *learnt_changed)
{
    (void)p_pipe_pa;
    *learnt_changed = false;
    uint32_t dt_ms = now_ms - a->last_ms;
    a->last_ms = now_ms;
    if (held) { /* safe state or not in auto: start again from idle with a fresh filter */
        a->primed = false;
        a->recharging = false;
        enter(a, LEVELER_ALG3_IDLE, now_ms);
        memset(out, 0, sizeof(*out));
        return LEVELER_STATE_IN_BAND;
    }
    leveler_alg3_filter(a, height_um);
    int32_t h = leveler_alg3_height_um(a);
    track_departure(a, set, h, now_ms, dt_ms);
    if (a->phase == LEVELER_ALG3_IDLE) {
        idle(a, set, h, now_ms);
    } else if (a->phase == LEVELER_ALG3_SETTLING) {
        settling(a, set, now_ms, learnt, learnt_changed);
    } else {
        moving(a, set, h, now_ms);
    }
    phase_outputs(a, set, p_spring_pa, p_acc_pa, out);
    leveler_dwell_apply(&a->dwell, set->alg3_min_on_ms, set->alg3_min_off_ms, now_ms, out);
    leveler_alg3_learn(a, set, p_spring_pa, dt_ms, learnt, learnt_changed);
    return band_state(a->phase);
}

void leveler_alg3_driven(leveler_alg3 *a, const leveler_outputs *driven, uint32_t now_ms)
{
    leveler_dwell_note(&a->dwell, driven, now_ms);
}
