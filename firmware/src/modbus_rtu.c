/*
 * Portable Modbus RTU slave: framing over hal_serial_read/hal_serial_write,
 * the PDU server over the register map (leveler_regs_read/leveler_regs_write).
 *
 * Function codes 01, 02, 03, 04, 05, 06, 15, 16. The checks of each function
 * follow the state diagrams of the Modbus Application Protocol v1.1b3, in its
 * order: function code (exception 01), then quantity and request structure
 * (03), then addresses (02), then the access itself. A write the register map
 * refuses answers 03 and changes nothing (the map writes all or nothing).
 * Exception 04 is reserved for a server that cannot carry out a request it
 * accepted (a register-map status outside its contract, a response buffer too
 * small, a bit write larger than the scratch buffer).
 *
 * Framing (Modbus over Serial Line v1.02, 2.5.1.1): a frame ends after a
 * silence of 3.5 characters (11 bits each); 1.75 ms fixed above 19200 baud.
 * Time comes from hal_now_ms() in whole milliseconds, so the gap is rounded up
 * and never less than 2 ms. Frames longer than LEVELER_RTU_MAX_ADU are dropped
 * up to the next gap. Broadcast (address 0) writes are carried out without a
 * reply; broadcast reads are ignored; frames for other addresses are ignored.
 *
 * No dynamic memory; all buffers are fixed. Never blocks: poll() moves what the
 * HAL has, answers at most one frame and returns.
 */
#include "leveler/modbus_rtu.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "leveler/hal.h"
#include "leveler/regmap.h"
#include "leveler/settings.h"

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

/* Exception codes (Modbus Application Protocol v1.1b3, section 7). */
enum {
    EXC_ILLEGAL_FUNCTION = 0x01,
    EXC_ILLEGAL_DATA_ADDRESS = 0x02,
    EXC_ILLEGAL_DATA_VALUE = 0x03,
    EXC_SERVER_DEVICE_FAILURE = 0x04
};

/* Quantity limits of the specification (they keep every response <= 256 bytes). */
#define MAX_READ_BITS 2000u      /* 0x07D0 */
#define MAX_READ_REGISTERS 125u  /* 0x007D */
#define MAX_WRITE_BITS 1968u     /* 0x07B0 */
#define MAX_WRITE_REGISTERS 123u /* 0x007B */

#define BROADCAST_ADDRESS 0u
#define ADU_OVERHEAD 3u   /* address byte + 2 CRC bytes around the PDU */
#define MIN_ADU_BYTES 4u  /* address, function code, CRC */
#define COIL_ON 0xFF00u
#define COIL_OFF 0x0000u

/* Scratch for one access to the register map: a whole register read or write
 * (<= 125 words). Bit accesses must fit it too (a write is all or nothing), so
 * a bit table larger than this would answer 04 beyond it; the map has 5 coils
 * and 8 discrete inputs, and 2000 bits would cost 4 KB of RAM. */
#define SCRATCH_ITEMS 125u

#define GAP_MIN_MS 2u
#define FAST_BAUD_DIV100 192u    /* above this the gap is a fixed 1.75 ms */
#define HAL_READS_PER_POLL 4u    /* bounds the time one poll() can take */

/* ---- CRC ------------------------------------------------------------------ */

/* CRC-16/MODBUS: reflected polynomial 0xA001, initial value 0xFFFF, sent low
 * byte first. Bitwise (no 512-byte table) since frames are short. */
static uint16_t crc16_modbus(const uint8_t *data, size_t len)
{
    uint16_t crc = 0xFFFFu;
    for (size_t i = 0; i < len; i++) {
        crc ^= data[i];
        for (unsigned bit = 0; bit < 8u; bit++) {
            if ((crc & 1u) != 0u) {
                crc = (uint16_t)((crc >> 1) ^ 0xA001u);
            } else {
                crc = (uint16_t)(crc >> 1);
            }
        }
    }
    return crc;
}

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)(((uint16_t)p[0] << 8) | p[1]);
}

static void put_be16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)(v & 0xFFu);
}

/* ---- PDU server ------------------------------------------------------------ */

/* A response PDU under construction, written after the address byte of resp. */
typedef struct {
    uint8_t *pdu;     /* resp + 1 */
    size_t pdu_cap;   /* room for the PDU, CRC excluded */
    size_t pdu_len;   /* bytes written; 0 = no reply */
} pdu_out;

/* The exception function code is function | 0x80, within 0x81..0xFF: a
 * request code of 0x80 or more keeps its value (it never wraps to a normal
 * reply). Codes 0 and 0x80 have none in that range: no reply. */
static void reply_exception(pdu_out *out, uint8_t function_code, uint8_t exception_code)
{
    if (out->pdu_cap < 2u || (function_code & 0x7Fu) == 0u) {
        out->pdu_len = 0; /* not even an exception fits: stay silent */
        return;
    }
    out->pdu[0] = (uint8_t)(function_code | 0x80u);
    out->pdu[1] = exception_code;
    out->pdu_len = 2;
}

static uint8_t exception_for(leveler_reg_status status)
{
    switch (status) {
    case LEVELER_REG_ILLEGAL_ADDRESS:
        return EXC_ILLEGAL_DATA_ADDRESS;
    case LEVELER_REG_ILLEGAL_VALUE:
        return EXC_ILLEGAL_DATA_VALUE;
    case LEVELER_REG_OK:
    default:
        return EXC_SERVER_DEVICE_FAILURE; /* a status outside the map's contract */
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
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return false;
    }
    *start = be16(&pdu[1]);
    *quantity = be16(&pdu[3]);
    if (*quantity < 1u || *quantity > max_quantity) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return false;
    }
    if (!range_in_table(table, *start, *quantity)) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_ADDRESS);
        return false;
    }
    return true;
}

/* FC 01 / 02. Request PDU: fc, start(2), quantity(2). */
static void read_bits(const uint8_t *pdu, size_t pdu_len, bool broadcast, leveler_table table,
                      pdu_out *out)
{
    const uint8_t fc = pdu[0];
    uint16_t start = 0;
    uint16_t quantity = 0;
    if (!check_read_request(pdu, pdu_len, broadcast, table, MAX_READ_BITS, out, &start, &quantity)) {
        return;
    }
    if (quantity > SCRATCH_ITEMS) {
        /* Legal and inside the table, but larger than this server's scratch. */
        reply_exception(out, fc, EXC_SERVER_DEVICE_FAILURE);
        return;
    }
    const size_t byte_count = ((size_t)quantity + 7u) / 8u; /* <= 16 */
    if (out->pdu_cap < 2u + byte_count) {
        reply_exception(out, fc, EXC_SERVER_DEVICE_FAILURE);
        return;
    }
    uint16_t bits[SCRATCH_ITEMS];
    const leveler_reg_status status = leveler_regs_read(table, start, quantity, bits);
    if (status != LEVELER_REG_OK) {
        reply_exception(out, fc, exception_for(status));
        return;
    }
    uint8_t *packed = &out->pdu[2];
    memset(packed, 0, byte_count); /* unused high bits of the last byte are 0 */
    for (uint16_t i = 0; i < quantity; i++) {
        if (bits[i] != 0u) {
            packed[i / 8u] = (uint8_t)(packed[i / 8u] | (1u << (i % 8u)));
        }
    }
    out->pdu[0] = fc;
    out->pdu[1] = (uint8_t)byte_count;
    out->pdu_len = 2u + byte_count;
}

/* FC 03 / 04. Request PDU: fc, start(2), quantity(2). */
static void read_registers(const uint8_t *pdu, size_t pdu_len, bool broadcast,
                           leveler_table table, pdu_out *out)
{
    const uint8_t fc = pdu[0];
    uint16_t start = 0;
    uint16_t quantity = 0;
    if (!check_read_request(pdu, pdu_len, broadcast, table, MAX_READ_REGISTERS, out, &start, &quantity)) {
        return;
    }
    const size_t byte_count = (size_t)quantity * 2u; /* <= 250 */
    if (out->pdu_cap < 2u + byte_count) {
        reply_exception(out, fc, EXC_SERVER_DEVICE_FAILURE);
        return;
    }
    uint16_t words[SCRATCH_ITEMS];
    const leveler_reg_status status = leveler_regs_read(table, start, quantity, words);
    if (status != LEVELER_REG_OK) {
        reply_exception(out, fc, exception_for(status));
        return;
    }
    out->pdu[0] = fc;
    out->pdu[1] = (uint8_t)byte_count;
    for (uint16_t i = 0; i < quantity; i++) {
        put_be16(&out->pdu[2u + 2u * i], words[i]);
    }
    out->pdu_len = 2u + byte_count;
}

/* The response of FC 05 / 06 echoes the request; that of FC 15 / 16 is its
 * first 5 bytes. Either way it is the first echo_len bytes of the request. */
static bool room_for_echo(pdu_out *out, uint8_t fc, size_t echo_len, bool broadcast)
{
    if (broadcast || out->pdu_cap >= echo_len) {
        return true; /* a broadcast needs no room: it gets no reply */
    }
    reply_exception(out, fc, EXC_SERVER_DEVICE_FAILURE); /* refuse before changing anything */
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

/* FC 05. Request PDU: fc, address(2), value(2) = 0xFF00 on / 0x0000 off. */
static void write_single_coil(const uint8_t *pdu, size_t pdu_len, bool broadcast, pdu_out *out)
{
    const uint8_t fc = pdu[0];
    if (pdu_len != 5u) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return;
    }
    const uint16_t address = be16(&pdu[1]);
    const uint16_t value = be16(&pdu[3]);
    if (value != COIL_ON && value != COIL_OFF) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return;
    }
    if (!range_in_table(LEVELER_TABLE_COIL, address, 1u)) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_ADDRESS);
        return;
    }
    if (!room_for_echo(out, fc, 5u, broadcast)) {
        return;
    }
    const uint16_t bit = (value == COIL_ON) ? 1u : 0u;
    write_and_echo(pdu, 5u, LEVELER_TABLE_COIL, address, 1u, &bit, out);
}

/* FC 06. Request PDU: fc, address(2), value(2). Every value is legal here;
 * the register map judges it. */
static void write_single_register(const uint8_t *pdu, size_t pdu_len, bool broadcast,
                                  pdu_out *out)
{
    const uint8_t fc = pdu[0];
    if (pdu_len != 5u) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return;
    }
    const uint16_t address = be16(&pdu[1]);
    const uint16_t value = be16(&pdu[3]);
    if (!range_in_table(LEVELER_TABLE_HOLDING_REGISTER, address, 1u)) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_ADDRESS);
        return;
    }
    if (!room_for_echo(out, fc, 5u, broadcast)) {
        return;
    }
    write_and_echo(pdu, 5u, LEVELER_TABLE_HOLDING_REGISTER, address, 1u, &value, out);
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
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return false;
    }
    *start = be16(&pdu[1]);
    *quantity = be16(&pdu[3]);
    const uint8_t byte_count = pdu[5];
    const uint32_t want_bytes = table == LEVELER_TABLE_COIL ? ((uint32_t)*quantity + 7u) / 8u
                                                            : (uint32_t)*quantity * 2u;
    if (*quantity < 1u || *quantity > max_quantity || byte_count != want_bytes ||
        pdu_len != 6u + (size_t)byte_count) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_VALUE);
        return false;
    }
    if (!range_in_table(table, *start, *quantity)) {
        reply_exception(out, fc, EXC_ILLEGAL_DATA_ADDRESS);
        return false;
    }
    if (*quantity > SCRATCH_ITEMS) {
        /* Legal and in the table, but this server cannot hold it whole (coils only:
         * MAX_WRITE_REGISTERS is below SCRATCH_ITEMS). */
        reply_exception(out, fc, EXC_SERVER_DEVICE_FAILURE);
        return false;
    }
    return room_for_echo(out, fc, 5u, broadcast);
}

/* FC 15. */
static void write_multiple_coils(const uint8_t *pdu, size_t pdu_len, bool broadcast,
                                 pdu_out *out)
{
    uint16_t start, quantity;
    if (!check_write_multiple(pdu, pdu_len, broadcast, LEVELER_TABLE_COIL, MAX_WRITE_BITS, out, &start,
                              &quantity)) {
        return;
    }
    uint16_t bits[SCRATCH_ITEMS];
    for (uint16_t i = 0; i < quantity; i++) {
        bits[i] = (uint16_t)((pdu[6u + i / 8u] >> (i % 8u)) & 1u);
    }
    write_and_echo(pdu, 5u, LEVELER_TABLE_COIL, start, quantity, bits, out);
}

/* FC 16. */
static void write_multiple_registers(const uint8_t *pdu, size_t pdu_len, bool broadcast,
                                     pdu_out *out)
{
    uint16_t start, quantity;
    if (!check_write_multiple(pdu, pdu_len, broadcast, LEVELER_TABLE_HOLDING_REGISTER, MAX_WRITE_REGISTERS, out,
                              &start, &quantity)) {
        return;
    }
    uint16_t words[SCRATCH_ITEMS]; /* quantity <= 123 */
    for (uint16_t i = 0; i < quantity; i++) {
        words[i] = be16(&pdu[6u + 2u * i]);
    }
    write_and_echo(pdu, 5u, LEVELER_TABLE_HOLDING_REGISTER, start, quantity, words, out);
}

size_t leveler_modbus_rtu_handle(const uint8_t *req, size_t req_len, uint8_t *resp, size_t resp_cap)
{
    if (req == NULL || req_len < MIN_ADU_BYTES || req_len > LEVELER_RTU_MAX_ADU) {
        return 0;
    }
    const uint16_t crc_received =
        (uint16_t)(req[req_len - 2u] | ((uint16_t)req[req_len - 1u] << 8));
    if (crc16_modbus(req, req_len - 2u) != crc_received) {
        return 0;
    }
    const uint8_t address = req[0];
    const bool broadcast = (address == BROADCAST_ADDRESS);
    if (!broadcast && address != leveler_settings_current()->modbus_address) {
        return 0;
    }

    const uint8_t *pdu = &req[1];
    const size_t pdu_len = req_len - ADU_OVERHEAD; /* >= 1: the function code */
    pdu_out out = {NULL, 0, 0};
    if (resp != NULL && resp_cap > ADU_OVERHEAD) {
        out.pdu = &resp[1];
        out.pdu_cap = resp_cap - ADU_OVERHEAD;
    }

    switch (pdu[0]) {
    case FC_READ_COILS:
        read_bits(pdu, pdu_len, broadcast, LEVELER_TABLE_COIL, &out);
        break;
    case FC_READ_DISCRETE_INPUTS:
        read_bits(pdu, pdu_len, broadcast, LEVELER_TABLE_DISCRETE_INPUT, &out);
        break;
    case FC_READ_HOLDING_REGISTERS:
        read_registers(pdu, pdu_len, broadcast, LEVELER_TABLE_HOLDING_REGISTER, &out);
        break;
    case FC_READ_INPUT_REGISTERS:
        read_registers(pdu, pdu_len, broadcast, LEVELER_TABLE_INPUT_REGISTER, &out);
        break;
    case FC_WRITE_SINGLE_COIL:
        write_single_coil(pdu, pdu_len, broadcast, &out);
        break;
    case FC_WRITE_SINGLE_REGISTER:
        write_single_register(pdu, pdu_len, broadcast, &out);
        break;
    case FC_WRITE_MULTIPLE_COILS:
        write_multiple_coils(pdu, pdu_len, broadcast, &out);
        break;
    case FC_WRITE_MULTIPLE_REGISTERS:
        write_multiple_registers(pdu, pdu_len, broadcast, &out);
        break;
    default:
        reply_exception(&out, pdu[0], EXC_ILLEGAL_FUNCTION);
        break;
    }

    if (broadcast || out.pdu_len == 0u) {
        return 0; /* broadcasts are never answered, not even with an exception */
    }
    resp[0] = address;
    const size_t body_len = 1u + out.pdu_len;
    const uint16_t crc = crc16_modbus(resp, body_len);
    resp[body_len] = (uint8_t)(crc & 0xFFu);
    resp[body_len + 1u] = (uint8_t)(crc >> 8);
    return body_len + 2u;
}

/* ---- Framing over the HAL -------------------------------------------------- */

static struct {
    uint8_t rx[LEVELER_RTU_MAX_ADU];
    size_t rx_len;
    bool rx_overflow;       /* bytes beyond a full rx: drop the frame at the gap */
    uint32_t last_rx_ms;    /* hal_now_ms() when bytes were last taken in */
    uint8_t tx[LEVELER_RTU_MAX_ADU];
    size_t tx_len;
    size_t tx_sent;         /* tx_sent < tx_len: a response is still going out */
} rtu;

/*
 * Silent interval that ends a frame, in whole ms, from the baud in force.
 * 3.5 characters of 11 bits = 38.5 bit times = 38500 / baud ms
 * = 385 / baud_div100 ms, rounded up: (385 + div - 1) / div. Operands are
 * <= 385 + 192, no overflow. Above 19200 baud the specification fixes
 * 1.75 ms, which rounds up to the 2 ms minimum.
 */
static uint32_t frame_gap_ms(void)
{
    uint32_t div = leveler_settings_current()->modbus_baud_div100;
    if (div > FAST_BAUD_DIV100) {
        return GAP_MIN_MS;
    }
    div += (uint32_t)(div == 0u); /* the map never holds 0; never divide by it */
    return (385u + div - 1u) / div; /* >= 3 ms at 19200 baud and below */
}

void leveler_modbus_rtu_init(void)
{
    memset(&rtu, 0, sizeof rtu);
    rtu.last_rx_ms = hal_now_ms();
}

static void send_pending(void)
{
    if (rtu.tx_sent < rtu.tx_len) {
        const size_t moved = hal_serial_write(&rtu.tx[rtu.tx_sent], rtu.tx_len - rtu.tx_sent);
        /* a HAL claiming more than it was given must not run us off the buffer */
        rtu.tx_sent += (moved < rtu.tx_len - rtu.tx_sent) ? moved : rtu.tx_len - rtu.tx_sent;
    }
}

/* The gap has passed: answer the frame (if whole and the line is free), then
 * start the next one. */
static void close_frame(void)
{
    const bool tx_idle = rtu.tx_sent >= rtu.tx_len;
    if (!rtu.rx_overflow && tx_idle) {
        rtu.tx_len = leveler_modbus_rtu_handle(rtu.rx, rtu.rx_len, rtu.tx, sizeof rtu.tx);
        rtu.tx_sent = 0;
    }
    /* else: an oversized frame, or a request sent over our own reply: dropped */
    rtu.rx_len = 0;
    rtu.rx_overflow = false;
}

static void take_bytes_in(uint32_t now_ms)
{
    for (unsigned i = 0; i < HAL_READS_PER_POLL; i++) {
        size_t moved;
        if (rtu.rx_len < sizeof rtu.rx) {
            const size_t room = sizeof rtu.rx - rtu.rx_len;
            moved = hal_serial_read(&rtu.rx[rtu.rx_len], room);
            rtu.rx_len += (moved < room) ? moved : room;
        } else {
            uint8_t discard[32];
            moved = hal_serial_read(discard, sizeof discard);
            if (moved > 0u) {
                rtu.rx_overflow = true;
            }
        }
        if (moved == 0u) {
            return;
        }
        rtu.last_rx_ms = now_ms;
    }
}

void leveler_modbus_rtu_poll(void)
{
    const uint32_t now_ms = hal_now_ms();
    send_pending();
    /* Close the frame before taking new bytes in: bytes waiting in the HAL
     * after a full gap belong to the next frame. Unsigned difference: the
     * millisecond counter may wrap. */
    if (rtu.rx_len > 0u && (uint32_t)(now_ms - rtu.last_rx_ms) >= frame_gap_ms()) {
        close_frame();
        send_pending();
    }
    take_bytes_in(now_ms);
}
