/*
 * Supervision server of leveler-rig: Modbus TCP (libmodbus builds every reply)
 * over the firmware's register map (leveler_regs_read / leveler_regs_write).
 *
 * - Several clients at once; sockets are non-blocking and a request is only
 *   handled once its whole MBAP frame has arrived, so no client can hold up
 *   the 10 ms tick. rig_supervision_serve() waits at most timeout_ms.
 * - Writes go through the firmware's validation: a refused write is answered
 *   with exception 03 (ILLEGAL DATA VALUE) and changes nothing.
 * - read_only: every write function (05, 06, 15, 16) is answered with
 *   exception 01 (ILLEGAL FUNCTION): the server does not offer writing.
 * - Function codes other than 01-06, 15, 16: exception 01.
 * - writers: only clients from these addresses may write; others get exception 01.
 * - write_socket: a Unix socket (mode 0660) whose clients may write; with it
 *   no TCP client writes, whatever its address (another local process can
 *   take any loopback address; it cannot pass the socket's permissions).
 *   leveler-mbaps connects here after checking the client certificate's role.
 * - A request must arrive whole within request_timeout_ms of its first byte
 *   (slow clients are dropped); a client with no complete request for
 *   idle_timeout_ms is dropped (single bytes do not keep it); so is one whose
 *   bytes are not Modbus TCP (protocol id other than 0, length outside
 *   2..254, function code 0 or 0x80).
 * - All slots taken: a new connection takes the slot of a client that has
 *   not completed a request within 20 ms of connecting (oldest first), else
 *   of one with no complete request for request_timeout_ms, else of the
 *   least recently active client (nothing buffered, quiet for 20 ms): it
 *   gives way. Only while every client is mid-request does a new connection
 *   wait in the kernel's backlog, in order. So neither idle or slow
 *   connections nor clients that keep polling can shut out another.
 * - Every whole request of a segment is answered (pipelining), at most 8 per
 *   client per call for fairness; the rest on the next call, without waiting
 *   for new bytes.
 * - Exception replies carry function | 0x80 (0x81..0xFF, never wrapped).
 */
#ifndef LEVELER_RIG_SUPERVISION_H
#define LEVELER_RIG_SUPERVISION_H

#include <stddef.h>
#include <stdint.h>

#include "rig_config.h"

typedef struct rig_supervision rig_supervision;

typedef struct {
    uint32_t accepted;
    uint32_t evicted;        /* idle or slow clients dropped to make room for a new one */
    uint32_t evicted_active; /* of those, polling clients that gave way as the least recently active */
    uint32_t dropped_idle;
    uint32_t dropped_slow;   /* a request not whole within request_timeout_ms */
    uint32_t refused_writes; /* writes from an address not in [supervision] writers */
    uint32_t dropped_garbage;
    uint32_t requests;
    uint32_t exceptions;
} rig_supervision_stats;

rig_supervision *rig_supervision_open(const rig_config *cfg, char *err, size_t err_len);
uint16_t rig_supervision_port(const rig_supervision *sv);
void rig_supervision_serve(rig_supervision *sv, int timeout_ms);
rig_supervision_stats rig_supervision_get_stats(const rig_supervision *sv);
void rig_supervision_close(rig_supervision *sv);

#endif
