/*
 * The RTU slave on the scripted HAL, for what libmodbus cannot provoke over a
 * pty: exception 04, broadcast reads and exceptions, the exact frame gap at
 * each baud, replies written in pieces, oversized frames.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "hal_stream.h"
#include "leveler/app.h"
#include "leveler/modbus_rtu.h"
#include "leveler/settings.h"
#include "rtu_harness.h"

/* Holding-register addresses from firmware/regmap/registers.json. */
#define REG_STALL_WINDOW_S 14u
#define REG_MODBUS_BAUD_DIV100 24u
#define REG_SENSOR_FAULT_BITS 8u /* input register, one word */

static uint8_t resp[LEVELER_RTU_MAX_ADU];

static int fresh_firmware(void **state)
{
    (void)state;
    hal_stream_reset(1000, 256, 256, false);
    leveler_app_init();
    leveler_modbus_rtu_init();
    return 0;
}

static size_t frame(uint8_t *buf, const uint8_t *body, size_t len)
{
    memcpy(buf, body, len);
    return rtu_test_frame(buf, len);
}

static void test_reference_crc_matches_the_specification_example(void **state)
{
    (void)state;
    /* Modbus over serial line v1.02 / common example: 01 03 00 00 00 0A -> C5 CD */
    uint8_t req[8];
    assert_int_equal(frame(req, (const uint8_t[]){0x01, 0x03, 0x00, 0x00, 0x00, 0x0A}, 6), 8);
    assert_int_equal(req[6], 0xC5);
    assert_int_equal(req[7], 0xCD);
    const size_t n = leveler_modbus_rtu_handle(req, sizeof req, resp, sizeof resp);
    assert_int_equal(n, 5u + 20u);
    const uint16_t crc = rtu_test_crc16(resp, n - 2);
    assert_int_equal(resp[n - 2], crc & 0xFF);
    assert_int_equal(resp[n - 1], crc >> 8);
}

static void test_exception_04_when_the_reply_does_not_fit(void **state)
{
    (void)state;
    uint8_t req[16];
    size_t len = frame(req, (const uint8_t[]){0x01, 0x03, 0x00, 0x00, 0x00, 0x0A}, 6);
    assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, 8), 5);
    assert_int_equal(resp[1], 0x83);
    assert_int_equal(resp[2], 0x04);

    /* a write that could not be acknowledged is not carried out */
    const uint16_t window = leveler_settings_current()->stall_window_s;
    len = frame(req, (const uint8_t[]){0x01, 0x06, 0x00, REG_STALL_WINDOW_S, 0x00, 0x21}, 6);
    assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, 7), 5);
    assert_int_equal(resp[1], 0x86);
    assert_int_equal(resp[2], 0x04);
    assert_int_equal(leveler_settings_current()->stall_window_s, window);
    /* and with room it is */
    assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 8);
    assert_int_equal(leveler_settings_current()->stall_window_s, 0x21);
}

/* Exception function codes stay within 0x81..0xFF (issue 13): 0x83 is
 * answered 83 01, never "03 01" (a normal FC 03 reply); 0x41 -> C1; 0 and
 * 0x80 have none (0x80 is outside the range): no reply. */
static void test_exception_function_codes_never_wrap(void **state)
{
    (void)state;
    static const uint8_t asked[] = {0x83, 0xFF, 0x81, 0x41, 0x2B};
    for (size_t i = 0; i < sizeof asked; i++) {
        uint8_t req[16];
        size_t len = frame(req, (const uint8_t[]){0x01, asked[i], 0x00, 0x00, 0x00, 0x01}, 6);
        assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 5);
        assert_int_equal(resp[1], asked[i] | 0x80);
        assert_true(resp[1] >= 0x81);
        assert_int_equal(resp[2], 0x01);
    }
    static const uint8_t none[] = {0x00, 0x80};
    for (size_t i = 0; i < sizeof none; i++) {
        uint8_t req[16];
        size_t len = frame(req, (const uint8_t[]){0x01, none[i], 0x00, 0x00, 0x00, 0x01}, 6);
        assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 0);
    }
}

static void test_broadcast_reads_and_exceptions_are_silent(void **state)
{
    (void)state;
    uint8_t req[16];
    size_t len = frame(req, (const uint8_t[]){0x00, 0x03, 0x00, 0x00, 0x00, 0x01}, 6);
    assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 0);
    len = frame(req, (const uint8_t[]){0x00, 0x2B, 0x0E, 0x01, 0x00}, 5);
    assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 0);
    len = frame(req, (const uint8_t[]){0x00, 0x06, 0x00, REG_STALL_WINDOW_S, 0x00, 0x22}, 6);
    assert_int_equal(leveler_modbus_rtu_handle(req, len, NULL, 0), 0);
    assert_int_equal(leveler_settings_current()->stall_window_s, 0x22);
}

/* Feed one request at once, then poll every ms: the reply must start exactly
 * when the 3.5-character silence has passed, rounded up to whole ms. */
static void test_frame_gap_follows_the_baud(void **state)
{
    (void)state;
    static const uint16_t bauds_div100[] = {12, 24, 48, 96, 192, 384, 576, 1152};
    for (size_t b = 0; b < sizeof bauds_div100 / sizeof bauds_div100[0]; b++) {
        const double baud = 100.0 * bauds_div100[b];
        const double gap_s = baud > 19200.0 ? 1.75e-3 : 3.5 * 11.0 / baud;
        uint32_t want_ms = (uint32_t)ceil(gap_s * 1000.0 - 1e-9);
        want_ms = want_ms < 2u ? 2u : want_ms;

        fresh_firmware(NULL);
        uint8_t req[16];
        size_t len = frame(req, (const uint8_t[]){0x01, 0x06, 0x00, REG_MODBUS_BAUD_DIV100,
                                                  (uint8_t)(bauds_div100[b] >> 8),
                                                  (uint8_t)bauds_div100[b]}, 6);
        assert_int_equal(leveler_modbus_rtu_handle(req, len, resp, sizeof resp), 8);
        assert_int_equal(leveler_settings_current()->modbus_baud_div100, bauds_div100[b]);

        len = frame(req, (const uint8_t[]){0x01, 0x04, 0x00, REG_SENSOR_FAULT_BITS, 0x00, 0x01}, 6);
        hal_stream_feed(req, len);
        leveler_modbus_rtu_poll(); /* bytes taken in at t0 */
        const uint32_t t0 = hal_stream.now_ms;
        while (hal_stream.tx_len == 0 && hal_stream.now_ms - t0 < 100u) {
            hal_stream.now_ms++;
            leveler_modbus_rtu_poll();
        }
        assert_int_equal(hal_stream.now_ms - t0, want_ms);
        assert_int_equal(hal_stream.tx_len, 7);
    }
}

static void test_pause_inside_the_gap_keeps_one_frame(void **state)
{
    (void)state;
    uint8_t req[16];
    const size_t len = frame(req, (const uint8_t[]){0x01, 0x03, 0x00, 0x00, 0x00, 0x02}, 6);
    /* 19200 baud: gap 3 ms. A 2 ms pause mid-frame is not an end of frame. */
    hal_stream_feed(req, 4);
    leveler_modbus_rtu_poll();
    hal_stream.now_ms += 2;
    hal_stream_feed(req + 4, len - 4);
    leveler_modbus_rtu_poll();
    for (int i = 0; i < 5; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
    assert_int_equal(hal_stream.tx_len, 9);

    /* a 3 ms pause splits it into two frames with bad CRCs: no reply */
    hal_stream.tx_len = 0;
    hal_stream_feed(req, 4);
    leveler_modbus_rtu_poll();
    hal_stream.now_ms += 3;
    hal_stream_feed(req + 4, len - 4);
    leveler_modbus_rtu_poll();
    for (int i = 0; i < 10; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
    assert_int_equal(hal_stream.tx_len, 0);
}

static void test_reply_written_in_pieces_is_whole(void **state)
{
    (void)state;
    uint8_t req[16];
    const size_t len = frame(req, (const uint8_t[]){0x01, 0x03, 0x00, 0x00, 0x00, 0x19}, 6);
    const size_t want = leveler_modbus_rtu_handle(req, len, resp, sizeof resp);
    assert_int_equal(want, 5u + 50u);
    hal_stream.tx_chunk = 7; /* a UART that takes 7 bytes per call */
    hal_stream_feed(req, len);
    for (int i = 0; i < 20; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
    assert_int_equal(hal_stream.tx_len, want);
    assert_memory_equal(hal_stream.tx, resp, want);
}

static void test_oversized_frame_is_dropped_to_the_gap(void **state)
{
    (void)state;
    static uint8_t big[300 + 2];
    memset(big, 0, sizeof big);
    big[0] = 0x01;
    big[1] = 0x10; /* a write of many registers: executed it would change settings */
    const uint32_t generation = leveler_settings_generation();
    hal_stream_feed(big, rtu_test_frame(big, 300));
    for (int i = 0; i < 10; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
    assert_int_equal(hal_stream.tx_len, 0);
    assert_int_equal(leveler_settings_generation(), generation);
    /* the next frame after the gap is served */
    uint8_t req[16];
    hal_stream_feed(req, frame(req, (const uint8_t[]){0x01, 0x04, 0x00, REG_SENSOR_FAULT_BITS, 0x00, 0x01}, 6));
    for (int i = 0; i < 10; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
    assert_int_equal(hal_stream.tx_len, 7);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_reference_crc_matches_the_specification_example, fresh_firmware),
        cmocka_unit_test_setup(test_exception_04_when_the_reply_does_not_fit, fresh_firmware),
        cmocka_unit_test_setup(test_broadcast_reads_and_exceptions_are_silent, fresh_firmware),
        cmocka_unit_test_setup(test_exception_function_codes_never_wrap, fresh_firmware),
        cmocka_unit_test_setup(test_frame_gap_follows_the_baud, fresh_firmware),
        cmocka_unit_test_setup(test_pause_inside_the_gap_keeps_one_frame, fresh_firmware),
        cmocka_unit_test_setup(test_reply_written_in_pieces_is_whole, fresh_firmware),
        cmocka_unit_test_setup(test_oversized_frame_is_dropped_to_the_gap, fresh_firmware),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
