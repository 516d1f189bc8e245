/*
 * Portable Modbus RTU slave: framing over hal_serial_read/hal_serial_write
 * (address, CRC, silent interval); the PDU inside each frame goes to the PDU
 * server (modbus_pdu.c), which answers it from the register map.
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
#include "leveler/modbus_pdu.h"
#include "leveler/settings.h"

#define BROADCAST_ADDRESS 0u
#define ADU_OVERHEAD 3u   /* address byte + 2 CRC bytes around the PDU */
#define MIN_ADU_BYTES 4u  /* address, function code, CRC */

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
    if (broadcast) {
        leveler_modbus_pdu_serve_broadcast(pdu, pdu_len); /* never answered, not even with an exception */
        return 0;
    }
    if (resp == NULL || resp_cap <= ADU_OVERHEAD) {
        return 0;
    }
    const size_t pdu_out_len = leveler_modbus_pdu_serve(pdu, pdu_len, &resp[1], resp_cap - ADU_OVERHEAD);
    if (pdu_out_len == 0u) {
        return 0;
    }
    resp[0] = address;
    const size_t body_len = 1u + pdu_out_len;
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
