/*
 * Commissioning a new rig (issue 19; docs/controller.md "Commissioning"):
 * the coil `commission` starts a short identification sequence that algorithm
 * 3 runs on its own outputs, under the safety supervisor like any move, and
 * feeds to its own learner (alg3_learn.c):
 *   1. rest: all valves shut until algorithm 3 is idle and the platform has
 *      moved less than CREEP in CREEP_MS; how far the height strayed meanwhile
 *      is the sensor noise the probes must see past;
 *   2. a vent probe: vent until the platform has moved twice that noise plus
 *      LEVELER_ALG3_PROBE_MOVED_MIN_UM, then close (the rate window sees a
 *      break-away late, and the excess vented meanwhile carries a lightly
 *      damped platform far): where it comes to rest P2 is on the down line;
 *      the travel after the close against the excess at it is the coast
 *      stiffness down. If that taught no line, again, closing at the
 *      break-away the rate window sees;
 *   3. a fill probe, the same (the accumulator, when fitted, only for the
 *      first half of the way up from the down line): the up line, the gap
 *      from stop to stop, the coast stiffness up. Vent first: the fill ends on
 *      the up line with little travel, so the levelling after it fills from
 *      that line without crossing the gap again;
 *   4. level: algorithm 3 takes over with the lines learnt and brings the
 *      platform into the band (nothing to do when it is in it); the routine
 *      ends once it is at rest inside and its creep would not carry it out.
 * The learnt values are settings (kept in flash); the first observation of
 * the gap and of each coast stiffness and time replaces the default instead
 * of moving it halfway. The outcome, its duration and the two lines learnt
 * are recorded in read-only settings (commission_*), kept in flash too.
 * The routine ends within LEVELER_COMMISSION_MAX_MS (then: timeout, and
 * algorithm 3 goes on as usual); writing the coil 0, leaving mode auto or
 * algorithm 3, or a fault holding the safe state aborts it.
 */
#ifndef LEVELER_COMMISSIONING_H
#define LEVELER_COMMISSIONING_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/alg3.h"
#include "leveler/settings.h"
#include "leveler/status.h"

#define LEVELER_COMMISSION_MAX_MS 60000u
#define LEVELER_COMMISSION_CREEP_UM 1000  /* at rest: moved less than this (above sensor noise) ... */
#define LEVELER_COMMISSION_CREEP_MS 2000u /* ... in this long (a slow creep is no rest) */
#define LEVELER_COMMISSION_CREEP_PROJECT 2 /* the end: the last window's creep, 2 more of it, stays inside */

/* registers.json commission_step */
typedef enum {
    LEVELER_COMMISSION_OFF = 0,
    LEVELER_COMMISSION_REST = 1,
    LEVELER_COMMISSION_PROBE_UP = 2,
    LEVELER_COMMISSION_PROBE_DOWN = 3,
    LEVELER_COMMISSION_LEVEL = 4
} leveler_commission_phase;

/* registers.json commission_result */
typedef enum {
    LEVELER_COMMISSION_NEVER = 0,
    LEVELER_COMMISSION_DONE = 1,
    LEVELER_COMMISSION_TIMEOUT = 2,
    LEVELER_COMMISSION_ABORTED = 3,
    LEVELER_COMMISSION_REFUSED = 4,
    LEVELER_COMMISSION_FAULT = 5
} leveler_commission_result;

typedef struct {
    uint8_t step;    /* leveler_commission_phase */
    uint32_t start_ms;
    int32_t up_pa;   /* the lines as the probes left them (a later load change forgets the settings') */
    int32_t down_pa;
    int32_t rest_um; /* where the platform was when it last looked at rest, since rest_ms */
    uint32_t rest_ms;
    int32_t spread_um; /* the farthest the height strayed from rest_um since (sensor noise at rest) */
} leveler_commission;

void leveler_commission_init(leveler_commission *c);

/*
 * One tick, before the controller's: starts the routine when cmd->commission
 * was written 1 (or refuses it), drives algorithm 3's probes, ends it (the
 * result into the settings, cmd->commission back to 0). held_by_fault: a
 * latched fault holds the safe state.
 */
void leveler_commission_tick(leveler_commission *c, leveler_alg3 *a, const leveler_settings *set,
                             leveler_command *cmd, bool held_by_fault, uint32_t now_ms);

#endif /* LEVELER_COMMISSIONING_H */
