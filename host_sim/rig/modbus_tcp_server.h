/*
 * The Modbus TCP server of leveler-rig (configured in [supervision]): MBAP
 * framing (mbap.c) around the firmware's PDU server (leveler/modbus_pdu.h),
 * which answers from the register map as the RTU slave does.
 *
 * - Several clients at once; sockets are non-blocking and a request is only
 *   handled once its whole MBAP frame has arrived, so no client can hold up
 *   the 10 ms tick. rig_modbus_tcp_server_serve() waits at most timeout_ms.
 * - Writes go through the firmware's validation: a refused write is answered
 *   with exception 03 (ILLEGAL DATA VALUE) and changes nothing.
 * - read_only: every write function (05, 06, 15, 16) is answered with
 *   exception 01 (ILLEGAL FUNCTION): the server does not offer writing. This
 *   write policy (and writers, write_socket below) is checked here, before
 *   the PDU server.
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
#ifndef LEVELER_RIG_MODBUS_TCP_SERVER_H
#define LEVELER_RIG_MODBUS_TCP_SERVER_H

#include <stddef.h>
#include <stdint.h>

#include "rig_config.h"

typedef struct rig_modbus_tcp_server rig_modbus_tcp_server;

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
} rig_modbus_tcp_server_stats;

rig_modbus_tcp_server *rig_modbus_tcp_server_open(const rig_config *cfg, char *err, size_t err_len);
uint16_t rig_modbus_tcp_server_port(const rig_modbus_tcp_server *srv);
void rig_modbus_tcp_server_serve(rig_modbus_tcp_server *srv, int timeout_ms);
rig_modbus_tcp_server_stats rig_modbus_tcp_server_get_stats(const rig_modbus_tcp_server *srv);
void rig_modbus_tcp_server_close(rig_modbus_tcp_server *srv);

#endif
