/*
 * Auto-clear of link faults ([faults] in rig.ini): a stall of the sensor
 * module (a cable, a module restart) makes every scan fail, the firmware's
 * sensors go faulty and their faults latch, holding the outputs safe until a
 * clear_faults write. The rig clears such faults by itself, and only those:
 *
 * - a latched bit counts as a link fault only if it is a sensor fault (codes
 *   4-7) that latched while the module link was down (a scan failed within
 *   the last RIG_AUTO_CLEAR_LINK_RECENT_MS); any other latched bit
 *   (overpressure, run time, stall, chatter, a sensor out of range with the
 *   link up) blocks the auto-clear until an operator clears it;
 * - the sensors must have been valid, with every scan answered, for
 *   after_ms in a row;
 * - at most max_per_hour clears in any 3600 s; past that the faults stay
 *   latched for the operator.
 * Each clear is counted (input register link_faults_auto_cleared) and
 * printed by the caller. after_ms = 0: off.
 */
#ifndef LEVELER_RIG_AUTO_CLEAR_H
#define LEVELER_RIG_AUTO_CLEAR_H

#include <stdbool.h>
#include <stdint.h>

#define RIG_AUTO_CLEAR_MAX_PER_HOUR 60
#define RIG_AUTO_CLEAR_LINK_RECENT_MS 1000u

typedef struct {
    uint32_t after_ms;
    uint32_t max_per_hour;
    uint16_t prev_latched;
    uint16_t link_bits;       /* latched while the link was down */
    uint16_t other_bits;      /* latched otherwise: for the operator */
    bool link_ever_failed;
    uint64_t last_link_failure_ms;
    bool valid_run;
    uint64_t valid_since_ms;
    uint64_t recent_ms[RIG_AUTO_CLEAR_MAX_PER_HOUR]; /* times of the clears within the last hour, oldest first */
    uint32_t recent;
    uint32_t count;
    bool limit_reported;      /* the hourly limit was hit (reported once per hour) */
} rig_auto_clear;

void rig_auto_clear_init(rig_auto_clear *a, uint32_t after_ms, uint32_t max_per_hour);

typedef enum { RIG_AUTO_CLEAR_NO = 0, RIG_AUTO_CLEAR_NOW, RIG_AUTO_CLEAR_LIMIT } rig_auto_clear_verdict;

/* One tick after leveler_app_tick(): latched fault bits, sensors valid, and
 * whether this tick's scan failed. NOW: clear the latched faults
 * (leveler_app_clear_faults) this tick; LIMIT: it would, but the hourly
 * limit is reached (returned once until a clear is allowed again). */
rig_auto_clear_verdict rig_auto_clear_step(rig_auto_clear *a, uint64_t now_ms, uint16_t latched, bool sensors_valid,
                                           bool scan_failed);

#endif
