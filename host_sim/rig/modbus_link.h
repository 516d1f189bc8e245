/*
 * The Modbus link to the rig's I/O module (RTU or TCP, libmodbus), shared by
 * the sensor scan and the coil outputs. It keeps request and reply in step:
 *
 * - before every request, stale bytes are flushed; on RTU, where a reply
 *   carries no transaction id, a request that timed out is followed by a
 *   drain: bytes are discarded until the line is quiet for timeout_ms, so a
 *   reply arriving after the timeout is thrown away, never taken as the next
 *   request's answer (rig_link_end);
 * - libmodbus checks each reply's transaction id (TCP) / address and CRC (RTU)
 *   and reports a mismatch as an error;
 * - after an error the link is flushed; after RIG_LINK_RECONNECT_AFTER failed
 *   requests in a row (or a dead socket) a TCP link is closed and opened
 *   again, which discards whatever the old connection still carried; while
 *   the module stays silent the next reconnect waits twice as many failures
 *   (up to 100, about a second);
 * - a module that cannot be reached is retried once a second.
 */
#ifndef LEVELER_RIG_MODBUS_LINK_H
#define LEVELER_RIG_MODBUS_LINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <modbus.h>

#include "rig_config.h"

#define RIG_LINK_RECONNECT_AFTER 3
#define RIG_LINK_DRAIN_MAX 8 /* RTU: read windows at most after a timeout (a babbling line ends it) */

typedef struct rig_link rig_link;

typedef struct {
    uint32_t failed_requests;
    uint32_t reconnects;
    uint32_t late_bytes_discarded; /* RTU: reads of a late reply discarded after a timeout */
    uint32_t connects; /* successful connects (RTU: the port opened); a change = a new session with the module */
} rig_link_stats;

/* NULL (message in err) on a bad device or host; an unreachable module is not an error. */
rig_link *rig_link_open(const rig_config *cfg, char *err, size_t err_len);
void rig_link_close(rig_link *l);

/* Before a request: the context, connected and with nothing stale pending;
 * NULL while the module cannot be reached. */
modbus_t *rig_link_begin(rig_link *l);
/* After it: ok = the reply was the one asked for (errno as libmodbus left it otherwise). */
void rig_link_end(rig_link *l, bool ok);

rig_link_stats rig_link_get_stats(const rig_link *l);

#endif
