/*
 * The PDU server (leveler/modbus_pdu.h) on its own, without a framer: request
 * and response PDUs as the Modbus Application Protocol v1.1b3 spells them
 * (function code + data; exceptions function | 0x80 with codes 01..04 of its
 * section 7), and a read/write round trip through the register map that the
 * firmware's settings confirm. Register addresses come from registers.json
 * (the generated leveler/regmap_addr.h).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "hal_stream.h"
#include "leveler/app.h"
#include "leveler/modbus_pdu.h"
#include "leveler/regmap_addr.h"
#include "leveler/settings.h"

static uint8_t resp[LEVELER_PDU_MAX];

static int fresh_firmware(void **state)
{
    (void)state;
    hal_stream_reset(1000, 256, 256, false);
    leveler_app_init();
    memset(resp, 0xAA, sizeof resp);
    return 0;
}

#define HI(v) (uint8_t)(((v) >> 8) & 0xFFu)
#define LO(v) (uint8_t)((v) & 0xFFu)

/* Serves req and checks the response is exactly want (want_len bytes). */
static void expect_response(const uint8_t *req, size_t req_len, const uint8_t *want, size_t want_len)
{
    const size_t n = leveler_modbus_pdu_serve(req, req_len, resp, sizeof resp);
    assert_int_equal(n, want_len);
    assert_memory_equal(resp, want, want_len);
}

#define SERVE(req, ...)                                                                            \
    do {                                                                                           \
        static const uint8_t want_[] = {__VA_ARGS__};                                              \
        expect_response((req), sizeof(req), want_, sizeof want_);                                  \
    } while (0)

static void test_exception_01_illegal_function(void **state)
{
    (void)state;
    static const uint8_t read_exception_status[] = {0x07};  /* serial line only */
    static const uint8_t read_device_id[] = {0x2B, 0x0E, 0x01, 0x00};
    static const uint8_t user_code[] = {0x41, 0x00, 0x00};
    static const uint8_t high_code[] = {0x83, 0x00, 0x00, 0x00, 0x01}; /* stays 0x83, never "03 01" */
    SERVE(read_exception_status, 0x87, 0x01);
    SERVE(read_device_id, 0xAB, 0x01);
    SERVE(user_code, 0xC1, 0x01);
    SERVE(high_code, 0x83, 0x01);
    /* 0 and 0x80 have no exception function code in 0x81..0xFF: no response */
    static const uint8_t zero[] = {0x00, 0x00, 0x00, 0x00, 0x01};
    static const uint8_t eighty[] = {0x80, 0x00, 0x00, 0x00, 0x01};
    assert_int_equal(leveler_modbus_pdu_serve(zero, sizeof zero, resp, sizeof resp), 0);
    assert_int_equal(leveler_modbus_pdu_serve(eighty, sizeof eighty, resp, sizeof resp), 0);
}

static void test_exception_02_illegal_data_address(void **state)
{
    (void)state;
    const uint16_t hr_last = LEVELER_HR_TABLE_SIZE - 1u;
    const uint8_t past_holding[] = {0x03, HI(hr_last), LO(hr_last), 0x00, 0x02}; /* one past the end */
    static const uint8_t input_ffff[] = {0x04, 0xFF, 0xFF, 0x00, 0x01};
    const uint8_t coil_past[] = {0x05, HI(LEVELER_COIL_TABLE_SIZE), LO(LEVELER_COIL_TABLE_SIZE), 0xFF, 0x00};
    const uint8_t register_past[] = {0x06, HI(LEVELER_HR_TABLE_SIZE), LO(LEVELER_HR_TABLE_SIZE), 0x00, 0x01};
    const uint8_t inputs_past[] = {0x02, 0x00, 0x00, HI(LEVELER_DI_TABLE_SIZE + 1u), LO(LEVELER_DI_TABLE_SIZE + 1u)};
    SERVE(past_holding, 0x83, 0x02);
    SERVE(input_ffff, 0x84, 0x02);
    SERVE(coil_past, 0x85, 0x02);
    SERVE(register_past, 0x86, 0x02);
    SERVE(inputs_past, 0x82, 0x02);
}

static void test_exception_03_illegal_data_value(void **state)
{
    (void)state;
    static const uint8_t quantity_zero[] = {0x03, 0x00, 0x00, 0x00, 0x00};
    static const uint8_t quantity_126[] = {0x03, 0x00, 0x00, 0x00, 0x7E};  /* 125 is the most */
    static const uint8_t bits_2001[] = {0x01, 0x00, 0x00, 0x07, 0xD1};     /* 2000 is the most */
    static const uint8_t short_read[] = {0x04, 0x00, 0x00, 0x00};
    static const uint8_t coil_value[] = {0x05, 0x00, 0x00, 0x12, 0x34};    /* only FF00 / 0000 */
    static const uint8_t byte_count[] = {0x10, 0x00, 0x0E, 0x00, 0x01, 0x04, 0x00, 0x21, 0x00, 0x00};
    /* quantity is checked before the address (0xFFFF would be 02) */
    static const uint8_t order[] = {0x03, 0xFF, 0xFF, 0x00, 0x00};
    SERVE(quantity_zero, 0x83, 0x03);
    SERVE(quantity_126, 0x83, 0x03);
    SERVE(bits_2001, 0x81, 0x03);
    SERVE(short_read, 0x84, 0x03);
    SERVE(coil_value, 0x85, 0x03);
    SERVE(byte_count, 0x90, 0x03);
    SERVE(order, 0x83, 0x03);
    /* a value outside the register's range ([1, 600] s): refused, nothing changes */
    const uint16_t window = leveler_settings_current()->stall_window_s;
    static const uint8_t out_of_range[] = {0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x00};
    SERVE(out_of_range, 0x86, 0x03);
    assert_int_equal(leveler_settings_current()->stall_window_s, window);
}

static void test_exception_04_when_the_response_does_not_fit(void **state)
{
    (void)state;
    static const uint8_t read10[] = {0x03, 0x00, 0x00, 0x00, 0x0A}; /* needs 2 + 20 bytes */
    assert_int_equal(leveler_modbus_pdu_serve(read10, sizeof read10, resp, 21), 2);
    assert_int_equal(resp[0], 0x83);
    assert_int_equal(resp[1], 0x04);
    /* a write whose echo (5 bytes) would not fit is not carried out */
    const uint16_t window = leveler_settings_current()->stall_window_s;
    static const uint8_t write[] = {0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x21};
    assert_int_equal(leveler_modbus_pdu_serve(write, sizeof write, resp, 4), 2);
    assert_int_equal(resp[0], 0x86);
    assert_int_equal(resp[1], 0x04);
    assert_int_equal(leveler_settings_current()->stall_window_s, window);
    /* no room even for an exception: no response */
    assert_int_equal(leveler_modbus_pdu_serve(write, sizeof write, resp, 1), 0);
    assert_int_equal(leveler_settings_current()->stall_window_s, window);
}

static void test_single_register_round_trip(void **state)
{
    (void)state;
    static const uint8_t write[] = {0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x21};
    static const uint8_t read[] = {0x03, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x01};
    assert_int_not_equal(leveler_settings_current()->stall_window_s, 0x21); /* the write changes it */
    SERVE(write, 0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x21); /* the echo */
    SERVE(read, 0x03, 0x02, 0x00, 0x21);
    assert_int_equal(leveler_settings_current()->stall_window_s, 0x21);
}

/* FC 16 over two int32 registers (high word first), then FC 03; a write that
 * breaks the band order (lower >= upper) is refused whole. */
static void test_multiple_registers_round_trip_all_or_nothing(void **state)
{
    (void)state;
    /* lower 100000 um = 0x000186A0, upper 200000 um = 0x00030D40 */
    static const uint8_t write[] = {0x10, 0x00, LEVELER_HR_BAND_LOWER_UM, 0x00, 0x04, 0x08,
                                    0x00, 0x01, 0x86, 0xA0, 0x00, 0x03, 0x0D, 0x40};
    static const uint8_t read[] = {0x03, 0x00, LEVELER_HR_BAND_LOWER_UM, 0x00, 0x04};
    SERVE(write, 0x10, 0x00, LEVELER_HR_BAND_LOWER_UM, 0x00, 0x04);
    SERVE(read, 0x03, 0x08, 0x00, 0x01, 0x86, 0xA0, 0x00, 0x03, 0x0D, 0x40);
    assert_int_equal(leveler_settings_current()->band_lower_um, 100000);
    assert_int_equal(leveler_settings_current()->band_upper_um, 200000);

    /* lower 300000 um = 0x000493E0 above upper 150000 um = 0x000249F0: refused, nothing changes */
    static const uint8_t crossed[] = {0x10, 0x00, LEVELER_HR_BAND_LOWER_UM, 0x00, 0x04, 0x08,
                                      0x00, 0x04, 0x93, 0xE0, 0x00, 0x02, 0x49, 0xF0};
    SERVE(crossed, 0x90, 0x03);
    SERVE(read, 0x03, 0x08, 0x00, 0x01, 0x86, 0xA0, 0x00, 0x03, 0x0D, 0x40);
    assert_int_equal(leveler_settings_current()->band_lower_um, 100000);
}

static void test_broadcast_writes_without_response(void **state)
{
    (void)state;
    static const uint8_t write[] = {0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x22};
    leveler_modbus_pdu_serve_broadcast(write, sizeof write);
    assert_int_equal(leveler_settings_current()->stall_window_s, 0x22);
    static const uint8_t refused[] = {0x06, 0x00, LEVELER_HR_STALL_WINDOW_S, 0x00, 0x00};
    leveler_modbus_pdu_serve_broadcast(refused, sizeof refused);
    assert_int_equal(leveler_settings_current()->stall_window_s, 0x22);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_exception_01_illegal_function, fresh_firmware),
        cmocka_unit_test_setup(test_exception_02_illegal_data_address, fresh_firmware),
        cmocka_unit_test_setup(test_exception_03_illegal_data_value, fresh_firmware),
        cmocka_unit_test_setup(test_exception_04_when_the_response_does_not_fit, fresh_firmware),
        cmocka_unit_test_setup(test_single_register_round_trip, fresh_firmware),
        cmocka_unit_test_setup(test_multiple_registers_round_trip_all_or_nothing, fresh_firmware),
        cmocka_unit_test_setup(test_broadcast_writes_without_response, fresh_firmware),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
