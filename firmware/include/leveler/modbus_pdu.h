/*
 * The Modbus PDU server over the register map: one request PDU (function
 * code + data; no address, no CRC, no MBAP header) in, one response PDU out.
 * Both Modbus framers call it: the portable RTU slave (modbus_rtu.c) and the
 * rig's Modbus TCP server (host_sim/rig/modbus_tcp_server.c).
 *
 * Function codes 01, 02, 03, 04, 05, 06, 15, 16; every other code is answered
 * with exception 01. The checks follow the state diagrams of the Modbus
 * Application Protocol v1.1b3, in its order: function code (01), quantity
 * and request structure (03), addresses (02), then the access itself. A write
 * the register map refuses answers 03 and changes nothing. Exception 04: the
 * server cannot carry out a request it accepted (no room for the response, a
 * bit access larger than its scratch, a register-map status outside its
 * contract). Exception replies carry function | 0x80 (0x81..0xFF, never
 * wrapped); codes 0 and 0x80 have none: no response.
 *
 * No dynamic memory, no floating point; the scratch lives on the stack.
 */
#ifndef LEVELER_MODBUS_PDU_H
#define LEVELER_MODBUS_PDU_H

#include <stddef.h>
#include <stdint.h>

/* The largest PDU (Modbus Application Protocol 4.1): 256 - address - CRC. */
#define LEVELER_PDU_MAX 253u

/* Exception codes (Modbus Application Protocol v1.1b3, section 7). */
enum {
    LEVELER_PDU_ILLEGAL_FUNCTION = 0x01,
    LEVELER_PDU_ILLEGAL_DATA_ADDRESS = 0x02,
    LEVELER_PDU_ILLEGAL_DATA_VALUE = 0x03,
    LEVELER_PDU_SERVER_DEVICE_FAILURE = 0x04
};

/* Serve one request PDU of req_len bytes; the response PDU goes to resp
 * (resp_cap bytes of room). Returns its length, or 0 for no response (a
 * function code of 0 or 0x80, an empty request, or no room even for an
 * exception). A write whose acknowledgement would not fit is refused with
 * exception 04 and not carried out. */
size_t leveler_modbus_pdu_serve(const uint8_t *req, size_t req_len, uint8_t *resp, size_t resp_cap);

/* A broadcast request (RTU address 0): writes are carried out, reads are
 * skipped, nothing is answered (not even an exception). */
void leveler_modbus_pdu_serve_broadcast(const uint8_t *req, size_t req_len);

/* The exception response PDU to a request of function code fc: 2 bytes into
 * resp (room for 2 needed), or 0 when fc has none (0 or 0x80). Inline so the
 * rig's framers answer their own refusals (read-only, no write rights) with
 * it without linking the register map. */
static inline size_t leveler_modbus_pdu_exception(uint8_t fc, uint8_t code, uint8_t *resp)
{
    if ((fc & 0x7Fu) == 0u) {
        return 0;
    }
    resp[0] = (uint8_t)(fc | 0x80u);
    resp[1] = code;
    return 2;
}

#endif /* LEVELER_MODBUS_PDU_H */
