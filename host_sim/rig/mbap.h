/*
 * MBAP framing (Modbus Messaging on TCP/IP v1.0b, 3.1.3) shared by the rig's
 * Modbus TCP server and leveler-mbaps: a 7-byte header (transaction id,
 * protocol id 0, length of what follows, unit id) before each PDU.
 */
#ifndef LEVELER_RIG_MBAP_H
#define LEVELER_RIG_MBAP_H

#include <stddef.h>
#include <stdint.h>

#include "leveler/modbus_pdu.h"

#define MBAP_HEADER_LEN 7u
#define MBAP_FRAME_MAX (MBAP_HEADER_LEN + LEVELER_PDU_MAX)

/* The first frame of the len bytes at buf: its length (header + PDU) when it
 * is whole; 0 while it is not; -1 when the bytes are not Modbus TCP (protocol
 * id other than 0, length outside 2..254, function code 0 or 0x80, which have
 * no exception reply). */
int mbap_frame_length(const uint8_t *buf, size_t len);

/* The response frame to the request frame req whose PDU (pdu_len bytes) is
 * already at rsp + MBAP_HEADER_LEN: writes the header (the request's
 * transaction id, protocol id and unit id) and returns the frame length. */
size_t mbap_wrap_response(const uint8_t *req, uint8_t *rsp, size_t pdu_len);

/* The exception response frame to the request frame req (function code | 0x80,
 * then code) into rsp (room for MBAP_HEADER_LEN + 2). Returns its length.
 * req is a frame mbap_frame_length() accepted (its function code has an
 * exception reply). */
size_t mbap_exception_response(const uint8_t *req, uint8_t code, uint8_t *rsp);

#endif
