/*
 * Algorithm 3, the phase logic (alg3.h), on its estimates (alg3_estimate.c)
 * and its learner (alg3_learn.c): it shows the learner what it is doing and
 * acts on the learner's verdicts.
 *
 * Fixed point: heights um (int32), rates um/s (int32), pressures Pa absolute
 * (int32), times ms (uint32, differences only, so wrap-around is harmless).
 * Products that can exceed int32 (excess * dt) are formed in int64 and
 * saturated back.
 */
#include "leveler/alg3.h"

#include <string.h>

#include "leveler/fixed_point.h"

void leveler_alg3_init(leveler_alg3 *a, uint32_t now_ms)
{
    memset(a, 0, sizeof(*a));
    a->phase = LEVELER_ALG3_IDLE;
    a->phase_start_ms = now_ms;
    a->last_ms = now_ms;
    leveler_dwell_init(&a->dwell, now_ms, UINT16_MAX);
}

/* A one-sided cumulative sum of the distance outside a band edge: it grows
 * while the filtered height is outside and shrinks while it is inside, so a
 * platform resting a hair outside is found in time through any noise, and
 * noise around a height inside the band never adds up. The side changes only
 * after its sum is back to 0. The sum is capped at the confirmation level (a
 * long excursion must not take as long to forget) and cleared when a move
 * starts. dt is clamped to a minute: no overflow. */
static void track_departure(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms, uint32_t dt_ms)
{
    int64_t below = (int64_t)set->band_lower_um - h;
    int64_t above = (int64_t)h - set->band_upper_um;
    int64_t dt = dt_ms > 60000u ? 60000 : (int64_t)dt_ms;
    if (a->out_dir != 0) {
        int64_t cap = (int64_t)set->alg3_confirm_um_s * 1000;
        int64_t d = a->out_dir < 0 ? below : above;
        a->out_area_um_ms += d * dt;
        if (a->out_area_um_ms > cap) {
            a->out_area_um_ms = cap;
        }
        if (a->out_area_um_ms <= 0 && d <= 0) {
            a->out_dir = 0;
        }
        if (a->out_area_um_ms < 0) {
            a->out_area_um_ms = 0;
        }
    }
    if (a->out_dir == 0 && (below > 0 || above > 0)) {
        a->out_dir = below > 0 ? -1 : 1;
        a->out_since_ms = now_ms;
        a->out_area_um_ms = (below > 0 ? below : above) * dt;
        if (a->out_area_um_ms > (int64_t)set->alg3_confirm_um_s * 1000) {
            a->out_area_um_ms = (int64_t)set->alg3_confirm_um_s * 1000;
        }
    }
}

/* Rest height predicted from the rate and the learnt coast time of the move's direction. */
static int32_t rate_prediction(const leveler_alg3 *a, const leveler_settings *set, int32_t h)
{
    int32_t rate = a->filter.rate_um_s;
    uint16_t coast = rate >= 0 ? set->alg3_coast_up_ms : set->alg3_coast_down_ms;
    return leveler_alg3_predict_um(h, rate, coast);
}

/* Which side of the band a height is on: -1 below, +1 above, 0 inside. */
static int8_t side(const leveler_settings *set, int32_t h)
{
    if (h < set->band_lower_um) {
        return -1;
    }
    return (h > set->band_upper_um) ? 1 : 0;
}

/* Confirmed: long and far enough outside, or a load change under way (a fast
 * move whose predicted rest lies outside). Acted on only while the predicted
 * rest lies outside on that side: a platform coasting back is left alone. */
static int8_t fast_departure(const leveler_alg3 *a, const leveler_settings *set, int32_t h)
{
    int8_t rest_side = side(set, rate_prediction(a, set, h));
    int32_t rate = a->filter.rate_um_s;
    bool fast = rate >= LEVELER_ALG3_FAST_UM_S || rate <= -LEVELER_ALG3_FAST_UM_S;
    return (fast && rest_side != 0 && (rest_side > 0) == (rate > 0)) ? rest_side : 0;
}

static int8_t departure(const leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms)
{
    int8_t fast = fast_departure(a, set, h);
    if (fast != 0) {
        return fast;
    }
    int8_t rest_side = side(set, rate_prediction(a, set, h));
    bool confirmed = a->out_dir != 0 && now_ms - a->out_since_ms >= set->alg3_persist_ms &&
                     a->out_area_um_ms >= (int64_t)set->alg3_confirm_um_s * 1000;
    return (confirmed && rest_side == a->out_dir) ? a->out_dir : 0;
}

static void enter(leveler_alg3 *a, uint8_t phase, uint32_t now_ms)
{
    a->phase = phase;
    a->phase_start_ms = now_ms;
}

/* A fine move's next burst: the first LEVELER_ALG3_BURST_MS; after one that moved nothing twice as
 * long up to LEVELER_ALG3_BURST_MAX_MS; after a burst that long, LEVELER_ALG3_REACH_MS, closed once
 * the platform moves (burst_done): a line that far is no burst's size away (the compressor alone
 * raised P2 by 107 kPa in 30 bursts, 26 of them 1.6 s, over 72 s on the 1000 lb diaphragm's random loads). */
static uint16_t next_burst_ms(const leveler_alg3 *a)
{
    if (!a->retry) {
        return (uint16_t)LEVELER_ALG3_BURST_MS;
    }
    if (a->burst_ms >= LEVELER_ALG3_BURST_MAX_MS) {
        return (uint16_t)LEVELER_ALG3_REACH_MS;
    }
    return (uint16_t)(a->burst_ms >= LEVELER_ALG3_BURST_MAX_MS / 2u ? LEVELER_ALG3_BURST_MAX_MS : 2u * a->burst_ms);
}

/* dir: -1 fill, +1 vent. off_um: how far outside the band (a fast move: far). */
static void start_move(leveler_alg3 *a, int8_t dir, int64_t off_um, uint32_t now_ms)
{
    int32_t rate = a->filter.rate_um_s;
    bool still = rate < LEVELER_ALG3_MOVING_UM_S && rate > -LEVELER_ALG3_MOVING_UM_S;
    bool fine = off_um < LEVELER_ALG3_FINE_UM && still;
    a->use_acc = off_um >= LEVELER_ALG3_ACC_MIN_UM || (a->retry && a->use_acc);
    a->burst_ms = next_burst_ms(a);
    a->assist = false;
    a->move_from_um = leveler_alg3_height_um(&a->filter);
    a->retry = false;
    a->topup = false;
    a->topups = 0;
    a->out_dir = 0; /* the departure is being dealt with: a new one must be seen afresh */
    a->out_area_um_ms = 0;
    a->fine = fine;
    a->bursting = false;
    a->recharging = false; /* a recharge starts again only in the band */
    enter(a, dir < 0 ? LEVELER_ALG3_FILLING : LEVELER_ALG3_VENTING, now_ms);
    a->watch.lines.line_fresh = false;
    a->moves = leveler_sat_inc_u16(a->moves);
    a->probe = LEVELER_ALG3_PROBE_NONE;
}

bool leveler_alg3_probe(leveler_alg3 *a, int8_t dir, uint8_t kind, int32_t moved_um, uint32_t now_ms)
{
    if (a->phase != LEVELER_ALG3_IDLE || !a->filter.primed) {
        return false;
    }
    a->retry = false;
    start_move(a, dir, 0, now_ms);
    a->fine = false;
    a->use_acc = dir < 0; /* a fill: until half way up (moving()), then never again in this probe */
    a->probe = kind;
    a->probe_moved_um = moved_um < LEVELER_ALG3_PROBE_MOVED_MIN_UM   ? LEVELER_ALG3_PROBE_MOVED_MIN_UM
                        : moved_um > LEVELER_ALG3_PROBE_MOVED_MAX_UM ? LEVELER_ALG3_PROBE_MOVED_MAX_UM
                                                                     : moved_um;
    return true;
}

static void idle(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms)
{
    if (a->hold) {
        return; /* commissioning decides when to move */
    }
    int8_t dir = departure(a, set, h, now_ms);
    if (dir != 0) {
        bool fast = fast_departure(a, set, h) != 0;
        int64_t off = dir < 0 ? (int64_t)set->band_lower_um - h : (int64_t)h - set->band_upper_um;
        start_move(a, dir, fast ? INT32_MAX : off, now_ms);
    }
}

/* A fine move: with the line known, P2 goes on towards it in one go while it
 * is farther than the burst zone; then one burst, and the settle that follows
 * shows whether it moved. A burst that moved nothing drops the estimate and
 * makes the next burst twice as long (up to LEVELER_ALG3_BURST_MAX_MS), so a
 * line farther than thought is still reached in a few bursts. */
static bool burst_done(leveler_alg3 *a, bool up, int32_t p_spring_pa, int32_t line, uint32_t now_ms)
{
    if (!a->fine) {
        return false;
    }
    int64_t short_of_line = up ? (int64_t)line - p_spring_pa : (int64_t)p_spring_pa - line;
    if (!a->bursting && (line == 0 || short_of_line <= LEVELER_ALG3_BURST_ZONE_PA)) {
        a->bursting = true;
        a->burst_start_ms = now_ms;
    }
    bool reaching = a->burst_ms > LEVELER_ALG3_BURST_MAX_MS;
    bool moved = leveler_alg3_moved_um(&a->filter, a->move_from_um, up) >= LEVELER_ALG3_ASSIST_MOVED_UM ||
                 a->watch.motion == (up ? 1 : -1);
    return a->bursting && (now_ms - a->burst_start_ms >= a->burst_ms || (reaching && moved));
}

/* How far the platform moved the probe's way since it started (um). */
int32_t leveler_alg3_probe_moved_um(const leveler_alg3 *a, bool up)
{
    return leveler_alg3_moved_um(&a->filter, a->move_from_um, up);
}

/* A probe's end: the break-away seen (the learner registered a motion the probe's way), or (an early
 * probe) moved probe_moved_um from its start, seen sooner than the rate window sees a motion (the
 * learner takes the line where it stops, alg3_learn.c), or PROBE_REACH whatever was seen. */
static bool probe_done(const leveler_alg3 *a, bool up)
{
    int32_t moved = leveler_alg3_probe_moved_um(a, up);
    bool early = a->probe == LEVELER_ALG3_PROBE_EARLY && moved >= a->probe_moved_um;
    return early || moved > LEVELER_ALG3_PROBE_REACH_UM || a->watch.motion == (up ? 1 : -1);
}

/* A fill the compressor alone has not broken away in LEVELER_ALG3_ASSIST_MS draws on the accumulator
 * too: the hysteresis gap, not the distance outside the band, sets the air a fill needs (a small drop
 * can sit a whole gap under the line). Only for the first half of the way to a line it knows or
 * estimates (as a probe does): the break-away comes on the compressor alone, with a small excess,
 * even when the line lies lower than estimated (the rate sees a break-away ~150 ms late, a heavily
 * damped platform's creep later still). Never in bursts or a probe. */
static bool assist(const leveler_alg3 *a, const leveler_settings *set, bool up, int32_t p_spring_pa, int32_t line,
                   uint32_t now_ms)
{
    if (!up || a->probe != LEVELER_ALG3_PROBE_NONE || a->bursting || a->watch.motion == 1 ||
        now_ms - a->phase_start_ms < LEVELER_ALG3_ASSIST_MS ||
        leveler_alg3_moved_um(&a->filter, a->move_from_um, true) >= LEVELER_ALG3_ASSIST_MOVED_UM) {
        return false; /* a creep up slower than the rate's motion is a break-away too */
    }
    return (int64_t)line - p_spring_pa > set->alg3_gap_pa / 2; /* no line (0): never */
}

/* A top-up (short_coast) closes where the coast stiffness the short coast before it showed lands
 * the platform halfway from the target to the band's upper edge, with no stretch (that stiffness is
 * this rig's at this load), or at the target; at once when the line is no longer the present load's
 * (a load change in the move). Halfway: the line's slope is a setting, and an error in it moves the
 * landing as far as the top-up carries the platform; short costs a burst, long the gap. */
static bool topup_done(const leveler_alg3 *a, const leveler_settings *set, int32_t h, int32_t p_spring_pa,
                       int32_t line)
{
    if (line == 0 || !leveler_alg3_line_known(&a->watch.lines, set, false)) {
        return true;
    }
    int32_t target = leveler_alg3_target_um(set);
    int32_t aim = (int32_t)(((int64_t)target + set->band_upper_um) / 2);
    int32_t rest = leveler_alg3_line_rest_um(false, h, p_spring_pa, line, a->topup_k_pa_per_mm);
    return h <= target || rest <= aim;
}

/* The line a move closes on. A down line estimated across the gap (from where a rise stopped on its
 * up line) is aimed an eighth of the gap under: the default gap is what the lightly damped 900 lb rig
 * shows from the end of a drop, which stops past its line on its momentum; the thesis's lines lie
 * 72-76 kPa apart, and a vent closing on the plain estimate lands short and creeps in by bursts
 * (thesis-1000lb -200 lb). Fills keep it: a fill not closing on it at all was measured worse. */
static int32_t close_line(const leveler_alg3 *a, const leveler_settings *set, bool up, int32_t line)
{
    bool across_gap = leveler_alg3_line_across_gap(&a->watch.lines, set, up);
    return (up || !across_gap || line == 0) ? line : leveler_sat_i32((int64_t)line - set->alg3_gap_pa / 8);
}

/* Filling or venting: close when leveler_alg3_close_now() says so, or a burst is done (a probe:
 * probe_done; a top-up: topup_done). */
static void moving(leveler_alg3 *a, const leveler_settings *set, int32_t h, int32_t p_spring_pa, uint32_t now_ms)
{
    bool up = a->phase == LEVELER_ALG3_FILLING;
    int32_t line = leveler_alg3_line_estimate(&a->watch.lines, set, up, h);
    bool burst = burst_done(a, up, p_spring_pa, line, now_ms);
    a->assist = assist(a, set, up, p_spring_pa, line, now_ms);
    /* the line broke away from in this move is the present load's: its coast needs no stretch */
    bool sure = a->watch.lines.line_fresh;
    bool done = a->probe != LEVELER_ALG3_PROBE_NONE ? probe_done(a, up)
                : a->topup                          ? topup_done(a, set, h, p_spring_pa, line)
                                                    : leveler_alg3_close_now(set, up, h,
                                                                             leveler_alg3_prediction_rate(&a->filter),
                                                                             p_spring_pa, close_line(a, set, up, line),
                                                                             sure);
    if (a->probe != LEVELER_ALG3_PROBE_NONE && up) {
        /* a probe crossing the gap draws on the accumulator for its first half (an estimated line: the
         * other line's stop plus the gap), then breaks away on the compressor alone: a small excess */
        a->use_acc = a->use_acc && line != 0 && (int64_t)p_spring_pa < (int64_t)line - set->alg3_gap_pa / 2;
    }
    if (done || burst) {
        leveler_alg3_note_close(&a->watch, &a->filter, up ? 1 : -1, p_spring_pa, line);
        a->close_line_known = line != 0 && leveler_alg3_line_known(&a->watch.lines, set, up);
        a->coast_um[0] = h; /* the coast's first height: the close's */
        a->coast_samples = 1;
        a->coast_rest_valid = false;
        a->coast_peak_um_s = 0;
        a->coast_slowed = false;
        enter(a, LEVELER_ALG3_SETTLING, now_ms);
    }
}

/* What the learner is shown of the controller's state. */
static leveler_alg3_view learner_view(const leveler_alg3 *a)
{
    leveler_alg3_view v;
    v.filter = &a->filter;
    v.valves_dir = a->phase == LEVELER_ALG3_FILLING ? 1 : a->phase == LEVELER_ALG3_VENTING ? -1 : 0;
    v.settling = a->phase == LEVELER_ALG3_SETTLING;
    v.commissioning = a->commissioning;
    v.probe = a->probe != LEVELER_ALG3_PROBE_NONE;
    v.topup = a->topup;
    v.move_from_um = a->move_from_um;
    v.probe_moved_um = a->probe_moved_um;
    return v;
}

/* The coast learnt from the close just settled; the verdict acted on. */
static void learn_coast(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt, bool *changed)
{
    leveler_alg3_view view = learner_view(a);
    if (leveler_alg3_learn_coast(&a->watch, &view, set, learnt, changed) == LEVELER_ALG3_VERDICT_RETRY) {
        a->retry = true; /* fill or vent on as it was, in a longer burst */
    }
}

void leveler_alg3_probe_learn(leveler_alg3 *a, const leveler_settings *set, leveler_settings *learnt,
                              bool *changed)
{
    learn_coast(a, set, learnt, changed);
    leveler_alg3_forget_close(&a->watch);
}

/* The coast stiffness (Pa/mm) a coast shows that will rest at rest_um: the excess over its line at
 * the close over the travel from there; 0 when the close's line was not the present load's, there
 * was no excess, the travel is under LEVELER_ALG3_MOVED_UM or the stiffness is LEVELER_ALG3_K_FACTOR
 * off the learnt one (a coast a load change disturbed). */
static int32_t coast_k(const leveler_alg3 *a, const leveler_settings *set, int32_t rest_um)
{
    const leveler_alg3_watch *w = &a->watch;
    bool up = w->close_dir > 0;
    int64_t excess = up ? (int64_t)w->close_p_spring_pa - w->close_line_pa
                        : (int64_t)w->close_line_pa - w->close_p_spring_pa;
    int64_t travel = up ? (int64_t)rest_um - w->close_height_um : (int64_t)w->close_height_um - rest_um;
    if (!a->close_line_known || excess <= 0 || travel < LEVELER_ALG3_MOVED_UM) {
        return 0;
    }
    int64_t k = leveler_div_round_i64(excess * 1000, travel);
    int64_t old = up ? set->alg3_coast_k_up_pa_per_mm : set->alg3_coast_k_down_pa_per_mm;
    bool off = k * LEVELER_ALG3_K_FACTOR < old || k > old * LEVELER_ALG3_K_FACTOR;
    return (off || k < LEVELER_ALG3_K_MIN_PA_PER_MM || k > LEVELER_ALG3_K_MAX_PA_PER_MM) ? 0 : (int32_t)k;
}

/* Samples the coast's height since the close every LEVELER_ALG3_COAST_SAMPLE_MS (the last four,
 * the first the close's) and, on a sample that shows a first-order coast, extrapolates where it will
 * rest (leveler_alg3_coast_rest) into coast_rest_um (coast_rest_valid: the last sample showed one). */
static void sample_coast(leveler_alg3 *a, int32_t h, uint32_t now_ms)
{
    if (now_ms - a->phase_start_ms < (uint32_t)a->coast_samples * LEVELER_ALG3_COAST_SAMPLE_MS) {
        return;
    }
    if (a->coast_samples >= 4u) {
        memmove(&a->coast_um[0], &a->coast_um[1], 3u * sizeof(a->coast_um[0]));
    }
    a->coast_um[a->coast_samples >= 4u ? 3u : a->coast_samples] = h;
    a->coast_samples = (uint8_t)(a->coast_samples < UINT8_MAX ? a->coast_samples + 1u : UINT8_MAX);
    a->coast_rest_valid = a->coast_samples >= 4u && a->watch.close_dir != 0 &&
                          leveler_alg3_coast_rest(a->coast_um, a->watch.close_dir, &a->coast_rest_um);
}

/* A vent's coast that will rest short of the band (sample_coast) is topped up at once instead of
 * after it has crept to rest (8 s on the 1000 lb rig, whose damping down is 16 times the 900 lb
 * rig's): the vent again, closing on the coast stiffness this coast shows (coast_k, topup_done).
 * Only when the extrapolation puts the rest more than half the band above it (a rest put just
 * outside may lie inside); after a close on the present load's line (the excess it coasts on is
 * known); never for a probe; at most LEVELER_ALG3_TOPUPS_MAX times per departure. Not a fill's: a
 * rising coast softens as P2 falls and its extrapolation falls short of its rest, so a top-up there
 * could carry the platform through the band (seen on the 900 lb diaphragm's random loads); a falling
 * one's overshoots its rest, and a vent's top-up errs short. True: a top-up started. */
static bool short_coast(leveler_alg3 *a, const leveler_settings *set, uint32_t now_ms)
{
    int64_t band = (int64_t)set->band_upper_um - set->band_lower_um;
    if (!a->coast_rest_valid || a->probe != LEVELER_ALG3_PROBE_NONE ||
        a->watch.close_dir >= 0 || a->topups >= LEVELER_ALG3_TOPUPS_MAX ||
        a->coast_rest_um <= (int64_t)set->band_upper_um + band / 2) {
        return false;
    }
    int32_t k = coast_k(a, set, a->coast_rest_um);
    if (k == 0) {
        return false;
    }
    uint8_t topups = a->topups;
    leveler_alg3_forget_close(&a->watch);
    start_move(a, 1, (int64_t)a->coast_rest_um - set->band_upper_um, now_ms);
    a->fine = false; /* sized by the coast's stiffness, not in bursts */
    a->topup = true;
    a->topups = (uint8_t)(topups + 1u);
    a->topup_k_pa_per_mm = k;
    return true;
}

/* Still by the rate is not yet at rest while the coast's extrapolation (sample_coast) has more than
 * a quarter band to go and will take the platform to another side of the band: a heavily damped
 * platform (the 1000 lb rig's damping down is 16 times the 900 lb rig's) creeps into the band under
 * LEVELER_ALG3_STILL_UM_S for seconds, and a settle ended there vented the creep again, through the
 * band. A creep that will rest outside anyway is acted on as before. */
static bool creeping(const leveler_alg3 *a, const leveler_settings *set, int32_t h)
{
    int64_t band = (int64_t)set->band_upper_um - set->band_lower_um;
    int64_t left = (int64_t)a->coast_rest_um - h;
    return a->coast_rest_valid && (left < 0 ? -left : left) > band / 4 && side(set, a->coast_rest_um) != side(set, h);
}

/* A fast motion the close's own way after its coast had slowed to half its fastest, now faster than
 * the coast ever went: a load change (a coast only slows). Tracks the coast's fastest motion
 * (um/s, the filter's rate: far inside int32, so its negation cannot overflow). */
static bool pushed_on(leveler_alg3 *a, int8_t fast)
{
    int32_t along = a->watch.close_dir < 0 ? -a->filter.rate_um_s : a->filter.rate_um_s;
    bool pushed = fast != 0 && fast == a->watch.close_dir && a->coast_slowed && along > a->coast_peak_um_s;
    if (along > a->coast_peak_um_s) {
        a->coast_peak_um_s = along;
    } else if (along < a->coast_peak_um_s / 2) {
        a->coast_slowed = true;
    }
    return pushed;
}

/* Valves closed until the platform is at rest (or alg3_settle_ms); then the
 * coast is learnt from. A fast motion against the move just closed, or one
 * the move's own way that pushed_on sees, is a load change and is acted on at
 * once; a vent's coast that will rest short of the band is topped up at once
 * (short_coast). */
static void settling(leveler_alg3 *a, const leveler_settings *set, int32_t h, uint32_t now_ms,
                     leveler_settings *learnt, bool *changed)
{
    int8_t fast = fast_departure(a, set, h);
    bool pushed = pushed_on(a, fast);
    if (pushed) {
        a->watch.lines.lines_valid = false; /* the load has changed: its lines, and where the */
        a->watch.lines.end_trusted = false; /* last motion ended, are the old load's */
    }
    if (fast != 0 && (fast == -a->watch.close_dir || pushed)) {
        leveler_alg3_forget_close(&a->watch);
        start_move(a, fast, INT32_MAX, now_ms);
        return;
    }
    sample_coast(a, h, now_ms);
    if (short_coast(a, set, now_ms)) {
        return;
    }
    uint32_t in_phase = now_ms - a->phase_start_ms;
    bool at_rest = a->watch.still_ms >= LEVELER_ALG3_SETTLE_REST_MS && !creeping(a, set, h);
    if (at_rest || in_phase >= set->alg3_settle_ms) {
        if (a->probe != LEVELER_ALG3_PROBE_NONE) {
            /* a probe's coast may creep on below the rate's rest: commissioning learns from it once
             * the platform has truly stopped (leveler_alg3_probe_learn) */
            enter(a, LEVELER_ALG3_IDLE, now_ms);
            return;
        }
        if (at_rest) {
            learn_coast(a, set, learnt, changed);
        }
        leveler_alg3_forget_close(&a->watch);
        enter(a, LEVELER_ALG3_IDLE, now_ms);
    }
}

/* The outputs of the phase. */
static void phase_outputs(leveler_alg3 *a, const leveler_settings *set, int32_t p_spring_pa, int32_t p_pipe_pa,
                          int32_t p_acc_pa, leveler_outputs *out)
{
    bool acc = set->alg3_accumulator != 0u;
    memset(out, 0, sizeof(*out));
    if (a->phase == LEVELER_ALG3_FILLING) {
        out->compressor = true;
        out->spring_valve = true;
        out->acc_valve =
            acc && (a->use_acc || a->assist) && (int64_t)p_acc_pa > (int64_t)p_spring_pa + LEVELER_ALG3_ACC_HELP_PA;
        return;
    }
    if (a->phase == LEVELER_ALG3_VENTING) {
        /* the vent bleeds the pipe first: a pipe left above P2 by a fill or a recharge would
         * otherwise blow into the spring and lift the platform the wrong way (0.13 in seen);
         * for LEVELER_ALG3_BLEED_MAX_MS at most (a P1 reading stuck high must not stop a vent) */
        bool bleeding = (int64_t)p_pipe_pa > (int64_t)p_spring_pa + LEVELER_ALG3_ACC_HELP_PA &&
                        a->last_ms - a->phase_start_ms < LEVELER_ALG3_BLEED_MAX_MS;
        out->spring_valve = !bleeding;
        out->vent_valve = true;
        out->acc_valve = acc && (int64_t)p_acc_pa + LEVELER_ALG3_ACC_HELP_PA < (int64_t)p_spring_pa &&
                         p_acc_pa < set->acc_charge_max_pa;
        return;
    }
    /* a recharge starts in the band; one under way goes on through a departure not yet confirmed
     * (noise at the band's edge would otherwise cut it every tick it reads outside) */
    if (a->phase == LEVELER_ALG3_IDLE && acc && (a->out_dir == 0 || a->recharging)) {
        if ((int64_t)p_acc_pa < (int64_t)set->acc_charge_max_pa - LEVELER_ALG3_RECHARGE_HYST_PA) {
            a->recharging = a->recharging || a->out_dir == 0;
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
    *learnt_changed = false;
    uint32_t dt_ms = now_ms - a->last_ms;
    a->last_ms = now_ms;
    if (held) { /* safe state or not in auto: start again from idle with a fresh filter */
        a->filter.primed = false;
        a->recharging = false;
        enter(a, LEVELER_ALG3_IDLE, now_ms);
        memset(out, 0, sizeof(*out));
        return LEVELER_STATE_IN_BAND;
    }
    leveler_alg3_filter(&a->filter, height_um);
    int32_t h = leveler_alg3_height_um(&a->filter);
    track_departure(a, set, h, now_ms, dt_ms);
    if (a->phase == LEVELER_ALG3_IDLE) {
        idle(a, set, h, now_ms);
    } else if (a->phase == LEVELER_ALG3_SETTLING) {
        settling(a, set, h, now_ms, learnt, learnt_changed);
    } else {
        moving(a, set, h, p_spring_pa, now_ms);
    }
    phase_outputs(a, set, p_spring_pa, p_pipe_pa, p_acc_pa, out);
    leveler_dwell_apply(&a->dwell, set->alg3_min_on_ms, set->alg3_min_off_ms, now_ms, out);
    leveler_alg3_view view = learner_view(a);
    leveler_alg3_learn(&a->watch, &view, set, p_spring_pa, dt_ms, learnt, learnt_changed);
    return band_state(a->phase);
}

void leveler_alg3_driven(leveler_alg3 *a, const leveler_outputs *driven, uint32_t now_ms)
{
    leveler_dwell_note(&a->dwell, driven, now_ms);
}
