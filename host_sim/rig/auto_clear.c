/* Auto-clear of link faults (auto_clear.h). */
#include "auto_clear.h"

#include <string.h>

#include "leveler/status.h"

#define SENSOR_FAULT_BITS                                                                                \
    ((uint16_t)(LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_HEIGHT) | LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_SPRING) | \
                LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE) | LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_ACC)))
#define HOUR_MS 3600000u

void rig_auto_clear_init(rig_auto_clear *a, uint32_t after_ms, uint32_t max_per_hour)
{
    memset(a, 0, sizeof *a);
    a->after_ms = after_ms;
    a->max_per_hour = max_per_hour > RIG_AUTO_CLEAR_MAX_PER_HOUR ? RIG_AUTO_CLEAR_MAX_PER_HOUR : max_per_hour;
}

/* Sorts each newly latched bit into link_bits or other_bits. */
static void attribute(rig_auto_clear *a, uint64_t now_ms, uint16_t latched)
{
    if (latched == 0) {
        a->link_bits = a->other_bits = 0;
    } else {
        uint16_t fresh = (uint16_t)(latched & ~a->prev_latched);
        bool link_down = a->link_ever_failed && now_ms - a->last_link_failure_ms < RIG_AUTO_CLEAR_LINK_RECENT_MS;
        uint16_t link = link_down ? (uint16_t)(fresh & SENSOR_FAULT_BITS) : 0u;
        a->link_bits |= link;
        a->other_bits |= (uint16_t)(fresh & ~link);
    }
    a->prev_latched = latched;
}

/* Forgets clears older than an hour; true if one more is allowed now. */
static bool within_hourly_limit(rig_auto_clear *a, uint64_t now_ms)
{
    uint32_t old = 0;
    while (old < a->recent && now_ms - a->recent_ms[old] >= HOUR_MS)
        old++;
    memmove(a->recent_ms, a->recent_ms + old, (a->recent - old) * sizeof a->recent_ms[0]);
    a->recent -= old;
    if (old > 0)
        a->limit_reported = false;
    return a->recent < a->max_per_hour;
}

rig_auto_clear_verdict rig_auto_clear_step(rig_auto_clear *a, uint64_t now_ms, uint16_t latched, bool sensors_valid,
                                           bool scan_failed)
{
    if (scan_failed) {
        a->link_ever_failed = true;
        a->last_link_failure_ms = now_ms;
    }
    attribute(a, now_ms, latched);
    bool valid = sensors_valid && !scan_failed;
    if (valid && !a->valid_run)
        a->valid_since_ms = now_ms;
    a->valid_run = valid;
    if (a->after_ms == 0 || latched == 0 || a->other_bits != 0 || (latched & ~a->link_bits) != 0 || !valid ||
        now_ms - a->valid_since_ms < a->after_ms)
        return RIG_AUTO_CLEAR_NO;
    if (!within_hourly_limit(a, now_ms)) {
        if (a->limit_reported)
            return RIG_AUTO_CLEAR_NO;
        a->limit_reported = true;
        return RIG_AUTO_CLEAR_LIMIT;
    }
    a->recent_ms[a->recent++] = now_ms;
    if (a->count != UINT32_MAX)
        a->count++;
    a->link_bits = 0;
    a->prev_latched = 0; /* what re-latches next tick is sorted afresh */
    return RIG_AUTO_CLEAR_NOW;
}
