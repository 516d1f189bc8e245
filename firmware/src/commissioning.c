/*
 * The commissioning routine (commissioning.h): a state machine over
 * algorithm 3's probes. Times in ms (differences only), heights in um.
 */
#include "leveler/commissioning.h"

#include <string.h>

#include "leveler/fixed_point.h"

void leveler_commission_init(leveler_commission *c)
{
    memset(c, 0, sizeof(*c));
}

/* The outcome into the read-only settings (kept in flash with the rest); the routine ends. */
static void finish(leveler_commission *c, leveler_alg3 *a, const leveler_settings *set, leveler_command *cmd,
                   uint16_t result, uint32_t now_ms)
{
    leveler_settings next = *set;
    uint32_t took_ms = now_ms - c->start_ms;
    next.commission_result = result;
    next.commission_ms = (uint16_t)(took_ms > UINT16_MAX ? UINT16_MAX : took_ms);
    next.commission_up_pa = result == LEVELER_COMMISSION_REFUSED ? set->commission_up_pa : c->up_pa;
    next.commission_down_pa = result == LEVELER_COMMISSION_REFUSED ? set->commission_down_pa : c->down_pa;
    (void)leveler_settings_apply(&next); /* within range by construction */
    a->hold = false;
    a->commissioning = false;
    a->watch.adopt = 0;
    cmd->commission = false;
    c->step = LEVELER_COMMISSION_OFF;
}

static bool eligible(const leveler_settings *set)
{
    return set->algorithm == (uint16_t)LEVELER_ALGO_HYSTERESIS_AWARE && set->mode == (uint16_t)LEVELER_MODE_AUTO &&
           set->alg3_learn != 0u;
}

/* The command: the lines of another load forgotten, the learner told to adopt, algorithm 3 held. */
static void start(leveler_commission *c, leveler_alg3 *a, const leveler_settings *set, leveler_command *cmd,
                  uint32_t now_ms)
{
    c->start_ms = now_ms;
    if (!eligible(set)) {
        finish(c, a, set, cmd, LEVELER_COMMISSION_REFUSED, now_ms);
        return;
    }
    leveler_settings next = *set;
    next.alg3_up_pa = 0;
    next.alg3_down_pa = 0;
    (void)leveler_settings_apply(&next);
    a->watch.lines.lines_valid = false;
    a->watch.adopt = LEVELER_ALG3_ADOPT_ALL;
    a->hold = true;
    a->commissioning = true;
    c->up_pa = 0;
    c->down_pa = 0;
    c->step = LEVELER_COMMISSION_REST;
}

/* Algorithm 3 idle (a move's settle over) and the platform moving less than CREEP in CREEP_MS (a creep
 * slower than the rate calls moving is no rest; the rate itself is too noisy to wait for): the next probe
 * may start, or the end be judged. */
static bool quiet(leveler_commission *c, const leveler_alg3 *a, uint32_t now_ms)
{
    int32_t h = leveler_alg3_height_um(&a->filter);
    bool still = a->filter.primed && a->phase == LEVELER_ALG3_IDLE;
    int64_t crept = (int64_t)h - c->rest_um;
    if (!still || crept > LEVELER_COMMISSION_CREEP_UM || crept < -LEVELER_COMMISSION_CREEP_UM) {
        c->rest_um = h;
        c->rest_ms = now_ms;
        c->spread_um = 0;
        return false;
    }
    crept = crept < 0 ? -crept : crept;
    c->spread_um = crept > c->spread_um ? (int32_t)crept : c->spread_um;
    return now_ms - c->rest_ms >= LEVELER_COMMISSION_CREEP_MS;
}

static void probe(leveler_commission *c, leveler_alg3 *a, bool up, uint8_t kind, uint32_t now_ms)
{
    /* alg3's move direction: -1 fills (a departure below), +1 vents; an early probe closes once moved
     * twice what the height strayed at rest (noise) */
    int32_t moved_um = leveler_sat_i32(2 * (int64_t)c->spread_um + LEVELER_ALG3_PROBE_MOVED_MIN_UM);
    if (leveler_alg3_probe(a, up ? -1 : 1, kind, moved_um, now_ms)) {
        c->step = up ? LEVELER_COMMISSION_PROBE_UP : LEVELER_COMMISSION_PROBE_DOWN;
    }
}

/* In the band, and a creep still under way (the drift over the rest window, under CREEP) would not carry
 * it out within CREEP_PROJECT windows. */
static bool stays_in_band(const leveler_commission *c, const leveler_alg3 *a, const leveler_settings *set)
{
    int32_t h = leveler_alg3_height_um(&a->filter);
    int64_t ahead = (int64_t)h + ((int64_t)h - c->rest_um) * LEVELER_COMMISSION_CREEP_PROJECT;
    return a->out_dir == 0 && h >= set->band_lower_um && h <= set->band_upper_um && ahead >= set->band_lower_um &&
           ahead <= set->band_upper_um;
}

/* What the probe just ended taught, into the settings (the platform has stopped: quiet()). */
static void learn_probe(leveler_alg3 *a, const leveler_settings *set)
{
    leveler_settings learnt;
    bool changed = false;
    leveler_alg3_probe_learn(a, set, &learnt, &changed);
    if (changed) {
        (void)leveler_settings_apply(&learnt); /* validated; a refused value leaves the old one */
    }
}

/* The sequence: rest, a vent probe (closed early; again closed at the break-away when that taught no
 * line), a fill probe, level. */
static void advance(leveler_commission *c, leveler_alg3 *a, const leveler_settings *set, leveler_command *cmd,
                    uint32_t now_ms)
{
    if (!quiet(c, a, now_ms)) {
        return;
    }
    if (c->step == LEVELER_COMMISSION_PROBE_DOWN || c->step == LEVELER_COMMISSION_PROBE_UP) {
        learn_probe(a, set);
    }
    if (c->step == LEVELER_COMMISSION_REST) {
        probe(c, a, false, LEVELER_ALG3_PROBE_EARLY, now_ms);
    } else if (c->step == LEVELER_COMMISSION_PROBE_DOWN && !a->watch.lines.line_fresh) {
        probe(c, a, false, LEVELER_ALG3_PROBE_BREAK, now_ms);
    } else if (c->step == LEVELER_COMMISSION_PROBE_DOWN) {
        c->down_pa = set->alg3_down_pa;
        probe(c, a, true, LEVELER_ALG3_PROBE_EARLY, now_ms);
    } else if (c->step == LEVELER_COMMISSION_PROBE_UP && !a->watch.lines.line_fresh) {
        probe(c, a, true, LEVELER_ALG3_PROBE_BREAK, now_ms);
    } else if (c->step == LEVELER_COMMISSION_PROBE_UP) {
        c->up_pa = set->alg3_up_pa;
        c->down_pa = set->alg3_down_pa != 0 ? set->alg3_down_pa : c->down_pa;
        a->hold = false; /* algorithm 3 levels with what it learnt */
        c->step = LEVELER_COMMISSION_LEVEL;
    } else if (stays_in_band(c, a, set)) {
        finish(c, a, set, cmd, LEVELER_COMMISSION_DONE, now_ms);
    }
}

void leveler_commission_tick(leveler_commission *c, leveler_alg3 *a, const leveler_settings *set,
                             leveler_command *cmd, bool held_by_fault, uint32_t now_ms)
{
    if (c->step == LEVELER_COMMISSION_OFF) {
        if (cmd->commission) {
            start(c, a, set, cmd, now_ms);
        }
        return;
    }
    if (!cmd->commission || !eligible(set)) {
        finish(c, a, set, cmd, LEVELER_COMMISSION_ABORTED, now_ms);
    } else if (held_by_fault) {
        finish(c, a, set, cmd, LEVELER_COMMISSION_FAULT, now_ms);
    } else if (now_ms - c->start_ms >= LEVELER_COMMISSION_MAX_MS) {
        finish(c, a, set, cmd, LEVELER_COMMISSION_TIMEOUT, now_ms);
    } else {
        advance(c, a, set, cmd, now_ms);
    }
}
