/*
 * The Modbus PDU server over the register map (leveler_regs_read /
 * leveler_regs_write); the contract is in leveler/modbus_pdu.h. The RTU slave
 * (modbus_rtu.c) and the rig's Modbus TCP server frame what it answers.
 */
#include "leveler/modbus_pdu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "leveler/regmap.h"

/* Function codes served. */
enum {
    FC_READ_COILS = 0x01,
    FC_READ_DISCRETE_INPUTS = 0x02,
    FC_READ_HOLDING_REGISTERS = 0x03,
    FC_READ_INPUT_REGISTERS = 0x04,
    FC_WRITE_SINGLE_COIL = 0x05,
    FC_WRITE_SINGLE_REGISTER = 0x06,
    FC_WRITE_MULTIPLE_COILS = 0x0F,
    FC_WRITE_MULTIPLE_REGISTERS = 0x10
};

/* Quantity limits of the specification (they keep every response <= 256 bytes). */
#define MAX_READ_BITS 2000u      /* 0x07D0 */
#define MAX_READ_REGISTERS 125u  /* 0x007D */
#define MAX_WRITE_BITS 1968u     /* 0x07B0 */
#define MAX_WRITE_REGISTERS 123u /* 0x007B */
#define COIL_ON 0xFF00u
#define COIL_OFF 0x0000u

/* Scratch for one access to the register map: a whole register read or write
 * (<= 125 words). Bit accesses must fit it too (a write is all or nothing), so
 * a bit table larger than this would answer 04 beyond it; the map has 5 coils
 * and 8 discrete inputs, and 2000 bits would cost 4 KB of RAM. */
#define SCRATCH_ITEMS 125u

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)(((uint16_t)p[0] << 8) | p[1]);
}

static void put_be16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)(v & 0xFFu);
}

/* A response PDU under construction in the caller's buffer. */
typedef struct {
    uint8_t *pdu;     /* NULL for a broadcast */
    size_t pdu_cap;   /* room for the PDU */
    size_t pdu_len;   /* bytes written; 0 = no reply */
} pdu_out;

/* The exception function code is function | 0x80, within 0x81..0xFF: a
 * request code of 0x80 or more keeps its value (it never wraps to a normal
 * reply). Codes 0 and 0x80 have none in that range: no reply. */
static void reply_exception(pdu_out *out, uint8_t function_code, uint8_t exception_code)
{
    out->pdu_len = 0; /* not even an exception fits: stay silent */
    if (out->pdu_cap >= 2u) {
        out->pdu_len = leveler_modbus_pdu_exception(function_code, exception_code, out->pdu);
    }
}

static uint8_t exception_for(leveler_reg_status status)
{
    switch (status) {
    case LEVELER_REG_ILLEGAL_ADDRESS:
        return LEVELER_PDU_ILLEGAL_DATA_ADDRESS;
    case LEVELER_REG_ILLEGAL_VALUE:
        return LEVELER_PDU_ILLEGAL_DATA_VALUE;
    case LEVELER_REG_OK:
    default:
        return LEVELER_PDU_SERVER_DEVICE_FAILURE; /* a status outside the map's contract */
    }
}

/* Address check of the specification: start..start+quantity-1 inside the table.
 * uint32_t sum: start and quantity are <= 0xFFFF, no overflow. */
static bool range_in_table(leveler_table table, uint16_t start, uint16_t quantity)
{
    return (uint32_t)start + quantity <= (uint32_t)leveler_regs_table_size(table);
}

/* The checks every read request (FC 01..04, PDU: fc, start(2), quantity(2))
 * goes through, in the specification's order: no reply to a broadcast, then
 * length and quantity (exception 03), then the address range (02). Returns
 * true with *start and *quantity set when the read may go ahead; otherwise
 * the exception (if any) is already in out. */
static bool check_read_request(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                               uint16_t max_quantity, pdu_out *out, uint16_t *start, uint16_t *quantity)
{
    const uint8_t fc = pdu[0];
    if (broadcast) {
        return false; /* reads are not broadcast */
    }
    if (pdu_len != 5u) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
        return false;
    }
    *start = be16(&pdu[1]);
    *quantity = be16(&pdu[3]);
    if (*quantity < 1u || *quantity > max_quantity) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
        return false;
    }
    if (!range_in_table(table, *start, *quantity)) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_ADDRESS);
        return false;
    }
    return true;
}

/* Bits into the response: 8 to a byte, the first in the lowest bit; the
 * unused high bits of the last byte are 0. */
static void pack_bits(const uint16_t *bits, uint16_t quantity, uint8_t *packed, size_t byte_count)
{
    memset(packed, 0, byte_count);
    for (uint16_t i = 0; i < quantity; i++) {
        if (bits[i] != 0u) {
            packed[i / 8u] = (uint8_t)(packed[i / 8u] | (1u << (i % 8u)));
        }
    }
}

/* FC 01 / 02 (bits) and 03 / 04 (registers, 2 bytes each, high byte first).
 * Request PDU: fc, start(2), quantity(2). */
static void read_items(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                       pdu_out *out)
{
    const uint8_t fc = pdu[0];
    const bool bits = table == LEVELER_TABLE_COIL || table == LEVELER_TABLE_DISCRETE_INPUT;
    uint16_t start = 0;
    uint16_t quantity = 0;
    if (!check_read_request(pdu, pdu_len, broadcast, table, bits ? MAX_READ_BITS : MAX_READ_REGISTERS, out,
                            &start, &quantity)) {
        return;
    }
    const size_t byte_count = bits ? ((size_t)quantity + 7u) / 8u : (size_t)quantity * 2u; /* <= 250 */
    /* Legal and inside the table, but larger than this server's scratch (bits
     * only: MAX_READ_REGISTERS is SCRATCH_ITEMS), or no room for the response. */
    if (quantity > SCRATCH_ITEMS || out->pdu_cap < 2u + byte_count) {
        reply_exception(out, fc, LEVELER_PDU_SERVER_DEVICE_FAILURE);
        return;
    }
    uint16_t items[SCRATCH_ITEMS];
    const leveler_reg_status status = leveler_regs_read(table, start, quantity, items);
    if (status != LEVELER_REG_OK) {
        reply_exception(out, fc, exception_for(status));
        return;
    }
    if (bits) {
        pack_bits(items, quantity, &out->pdu[2], byte_count);
    } else {
        for (uint16_t i = 0; i < quantity; i++) {
            put_be16(&out->pdu[2u + 2u * i], items[i]);
        }
    }
    out->pdu[0] = fc;
    out->pdu[1] = (uint8_t)byte_count;
    out->pdu_len = 2u + byte_count;
}

/* The response of FC 05 / 06 echoes the request; that of FC 15 / 16 is its
 * first 5 bytes. Either way it is the first echo_len bytes of the request. */
static bool room_for_echo(pdu_out *out, uint8_t fc, size_t echo_len, bool broadcast)
{
    if (broadcast || out->pdu_cap >= echo_len) {
        return true; /* a broadcast needs no room: it gets no reply */
    }
    reply_exception(out, fc, LEVELER_PDU_SERVER_DEVICE_FAILURE); /* refuse before changing anything */
    return false;
}

static void write_and_echo(const uint8_t *pdu, size_t echo_len, leveler_table table,
                           uint16_t start, uint16_t count, const uint16_t *values, pdu_out *out)
{
    const leveler_reg_status status = leveler_regs_write(table, start, count, values, NULL);
    if (status != LEVELER_REG_OK) {
        reply_exception(out, pdu[0], exception_for(status));
        return;
    }
    if (out->pdu_cap >= echo_len) { /* false only for a broadcast, which gets no reply */
        memcpy(out->pdu, pdu, echo_len);
        out->pdu_len = echo_len;
    }
}

/* FC 05 (a coil: value 0xFF00 on, 0x0000 off) and FC 06 (a holding register:
 * every value is legal here; the register map judges it). Request PDU: fc,
 * address(2), value(2); the response echoes it. */
static void write_single(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                         pdu_out *out)
{
    const uint8_t fc = pdu[0];
    if (pdu_len != 5u) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
        return;
    }
    const uint16_t address = be16(&pdu[1]);
    uint16_t value = be16(&pdu[3]);
    if (table == LEVELER_TABLE_COIL) {
        if (value != COIL_ON && value != COIL_OFF) {
            reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
            return;
        }
        value = (value == COIL_ON) ? 1u : 0u;
    }
    if (!range_in_table(table, address, 1u)) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_ADDRESS);
        return;
    }
    if (!room_for_echo(out, fc, 5u, broadcast)) {
        return;
    }
    write_and_echo(pdu, 5u, table, address, 1u, &value, out);
}

/*
 * FC 15 and 16: the request check they share. Request PDU: fc, start(2),
 * quantity(2), byte count, then the values (bits packed 8 to a byte for coils,
 * 2 bytes each for registers). True with *start and *quantity when the write
 * may go ahead; otherwise the exception is in out (or, for a broadcast, nothing
 * is owed).
 */
static bool check_write_multiple(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                                 uint16_t max_quantity, pdu_out *out, uint16_t *start, uint16_t *quantity)
{
    const uint8_t fc = pdu[0];
    if (pdu_len < 6u) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
        return false;
    }
    *start = be16(&pdu[1]);
    *quantity = be16(&pdu[3]);
    const uint8_t byte_count = pdu[5];
    const uint32_t want_bytes = table == LEVELER_TABLE_COIL ? ((uint32_t)*quantity + 7u) / 8u
                                                            : (uint32_t)*quantity * 2u;
    if (*quantity < 1u || *quantity > max_quantity || byte_count != want_bytes ||
        pdu_len != 6u + (size_t)byte_count) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_VALUE);
        return false;
    }
    if (!range_in_table(table, *start, *quantity)) {
        reply_exception(out, fc, LEVELER_PDU_ILLEGAL_DATA_ADDRESS);
        return false;
    }
    if (*quantity > SCRATCH_ITEMS) {
        /* Legal and in the table, but this server cannot hold it whole (coils only:
         * MAX_WRITE_REGISTERS is below SCRATCH_ITEMS). */
        reply_exception(out, fc, LEVELER_PDU_SERVER_DEVICE_FAILURE);
        return false;
    }
    return room_for_echo(out, fc, 5u, broadcast);
}

/* FC 15 (coils, 8 to a byte, the first in the lowest bit) and FC 16
 * (holding registers, 2 bytes each, high byte first); the response is the
 * request's first 5 bytes. */
static void write_multiple(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                           pdu_out *out)
{
    const bool bits = table == LEVELER_TABLE_COIL;
    uint16_t start, quantity;
    if (!check_write_multiple(pdu, pdu_len, broadcast, table, bits ? MAX_WRITE_BITS : MAX_WRITE_REGISTERS, out,
                              &start, &quantity)) {
        return;
    }
    uint16_t items[SCRATCH_ITEMS]; /* quantity <= SCRATCH_ITEMS: checked */
    for (uint16_t i = 0; i < quantity; i++) {
        if (bits) {
            items[i] = (uint16_t)(((unsigned)pdu[6u + i / 8u] >> (i % 8u)) & 1u);
        } else {
            items[i] = be16(&pdu[6u + 2u * i]);
        }
    }
    write_and_echo(pdu, 5u, table, start, quantity, items, out);
}

/* The function codes served, each with its handler and table. */
typedef void (*pdu_handler)(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                            pdu_out *out);
static const struct {
    uint8_t fc;
    pdu_handler handle;
    leveler_table table;
} SERVED[] = {
    {FC_READ_COILS, read_items, LEVELER_TABLE_COIL},
    {FC_READ_DISCRETE_INPUTS, read_items, LEVELER_TABLE_DISCRETE_INPUT},
    {FC_READ_HOLDING_REGISTERS, read_items, LEVELER_TABLE_HOLDING_REGISTER},
    {FC_READ_INPUT_REGISTERS, read_items, LEVELER_TABLE_INPUT_REGISTER},
    {FC_WRITE_SINGLE_COIL, write_single, LEVELER_TABLE_COIL},
    {FC_WRITE_SINGLE_REGISTER, write_single, LEVELER_TABLE_HOLDING_REGISTER},
    {FC_WRITE_MULTIPLE_COILS, write_multiple, LEVELER_TABLE_COIL},
    {FC_WRITE_MULTIPLE_REGISTERS, write_multiple, LEVELER_TABLE_HOLDING_REGISTER},
};

/* One request; broadcast: carried out without a reply (out->pdu is NULL). */
static void dispatch(const uint8_t *pdu, size_t pdu_len, bool broadcast, pdu_out *out)
{
    for (size_t i = 0; i < sizeof SERVED / sizeof SERVED[0]; i++) {
        if (SERVED[i].fc == pdu[0]) {
            SERVED[i].handle(pdu, pdu_len, broadcast, SERVED[i].table, out);
            return;
        }
    }
    reply_exception(out, pdu[0], LEVELER_PDU_ILLEGAL_FUNCTION);
}

size_t leveler_modbus_pdu_serve(const uint8_t *req, size_t req_len, uint8_t *resp, size_t resp_cap)
{
    if (req == NULL || req_len == 0u || resp == NULL) {
        return 0;
    }
    pdu_out out = {resp, resp_cap, 0};
    dispatch(req, req_len, false, &out);
    return out.pdu_len;
}

void leveler_modbus_pdu_serve_broadcast(const uint8_t *req, size_t req_len)
{
    if (req == NULL || req_len == 0u) {
        return;
    }
    pdu_out out = {NULL, 0, 0};
    dispatch(req, req_len, true, &out);
}
