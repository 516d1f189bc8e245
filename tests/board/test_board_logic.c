/*
 * Board arithmetic and policies (boards/stm32f103/portable/board_logic.c)
 * against double-precision references and the reference manual.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "board_logic.h"

/* ---- ADC oversampling ---- */

static void oversample_mean_matches_double_reference(void **state)
{
    (void)state;
    enum { CHANNELS = 4, SAMPLES = 16 };
    uint16_t buffer[CHANNELS * SAMPLES];
    srand(7);
    for (int trial = 0; trial < 500; trial++) {
        for (int i = 0; i < CHANNELS * SAMPLES; i++) {
            buffer[i] = (uint16_t)(rand() % 4096);
        }
        for (uint32_t ch = 0; ch < CHANNELS; ch++) {
            double sum = 0.0;
            for (int s = 0; s < SAMPLES; s++) {
                sum += buffer[s * CHANNELS + (int)ch];
            }
            double expect = floor(sum / SAMPLES + 0.5); /* round half up */
            assert_int_equal(adc_oversample_mean(buffer, ch, CHANNELS, SAMPLES), (uint16_t)expect);
        }
    }
}

static void oversample_mean_of_full_scale_and_bad_arguments(void **state)
{
    (void)state;
    uint16_t buffer[64];
    for (int i = 0; i < 64; i++) {
        buffer[i] = (i % 4 == 2) ? 4095u : (uint16_t)(0xF000u | 100u); /* junk above bit 11 */
    }
    assert_int_equal(adc_oversample_mean(buffer, 2, 4, 16), 4095);
    assert_int_equal(adc_oversample_mean(buffer, 0, 4, 16), 100); /* only the 12-bit result counts */
    assert_int_equal(adc_oversample_mean(buffer, 4, 4, 16), 0);
    assert_int_equal(adc_oversample_mean(buffer, 0, 4, 0), 0);
}

/* ---- USART baud rate ---- */

static void brr_for_19200_at_72mhz_is_the_reference_manual_value(void **state)
{
    (void)state;
    /* RM0008 27.3.4, Table 192: 72 MHz, 19.2 kBps -> USARTDIV 234.375 = BRR 0xEA6. */
    assert_int_equal(usart_brr(72000000u, 19200u), 0xEA6);
    /* 36 MHz, 9600 -> USARTDIV 234.375 as well. */
    assert_int_equal(usart_brr(36000000u, 9600u), 0xEA6);
}

static void every_register_map_baud_is_within_one_percent(void **state)
{
    (void)state;
    /* modbus_baud_div100 values listed in registers.json, on the clocks the board can run at. */
    const uint32_t bauds[] = {1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200};
    const uint32_t clocks[] = {72000000u, 64000000u, 8000000u};
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        for (size_t b = 0; b < sizeof bauds / sizeof bauds[0]; b++) {
            uint16_t brr = usart_brr(clocks[c], bauds[b]);
            double exact = (double)clocks[c] / bauds[b];
            assert_int_equal(brr, (uint16_t)floor(exact + 0.5));
            double actual = (double)clocks[c] / brr;
            assert_true(fabs(actual - bauds[b]) / bauds[b] < 0.01);
            assert_int_equal(usart_baud_from_brr(clocks[c], brr), (uint32_t)floor(actual + 0.5));
        }
    }
}

static void impossible_baud_rates_are_refused(void **state)
{
    (void)state;
    assert_int_equal(usart_brr(72000000u, 0u), 0);
    assert_int_equal(usart_brr(72000000u, 1000u), 0);      /* divider 72000 > 0xFFFF */
    assert_int_equal(usart_brr(8000000u, 1000000u), 0);    /* divider 8 < 16 */
    /* Near 2^32 the rounding must not overflow: 0xFFFF * 65536 / 65536 is exact,
     * UINT32_MAX / 65536 = 65535.99998 rounds to 65536, out of range. */
    assert_int_equal(usart_brr(0xFFFFu * 65536u, 65536u), 0xFFFF);
    assert_int_equal(usart_brr(UINT32_MAX, 65536u), 0);
    assert_int_equal(usart_baud_from_brr(72000000u, 0u), 0);
}

/* ---- Blink codes ---- */

static void code_zero_is_steady_on(void **state)
{
    (void)state;
    for (uint32_t t = 0; t < 10000u; t += 10u) {
        assert_true(blink_code_led_on(0, t));
    }
}

static void code_n_flashes_n_times_per_period(void **state)
{
    (void)state;
    for (uint16_t code = 1; code <= 20; code++) {
        uint32_t n = code > BLINK_MAX_CODE ? BLINK_MAX_CODE : code;
        uint32_t period = blink_code_period_ms(code);
        assert_int_equal(period, n * (BLINK_ON_MS + BLINK_OFF_MS) + BLINK_PAUSE_MS);
        uint32_t rising = 0, on_ms = 0;
        bool previous = false; /* each period ends in the dark pause */
        for (uint32_t t = 0; t < period; t++) {
            bool on = blink_code_led_on(code, 5u * period + t); /* any whole period */
            rising += on && !previous;
            on_ms += on;
            previous = on;
        }
        assert_int_equal(rising, n);
        assert_int_equal(on_ms, n * BLINK_ON_MS);
        assert_false(blink_code_led_on(code, period - 1u)); /* pause at the end */
    }
}

/* ---- Settings persistence policy ---- */

static void persists_once_after_changes_settle(void **state)
{
    (void)state;
    persist_policy p;
    persist_policy_init(&p, 5, 1000);
    assert_false(persist_policy_due(&p, 5, 100000, 500)); /* nothing changed */

    /* A burst of writes: each restarts the settle time. */
    assert_false(persist_policy_due(&p, 6, 2000, 500));
    assert_false(persist_policy_due(&p, 7, 2300, 500));
    assert_false(persist_policy_due(&p, 8, 2600, 500));
    assert_false(persist_policy_due(&p, 8, 3099, 500));
    assert_true(persist_policy_due(&p, 8, 3100, 500));
    persist_policy_saved(&p, 8);
    assert_false(persist_policy_due(&p, 8, 9000, 500));
}

static void settle_time_is_wrap_safe(void **state)
{
    (void)state;
    persist_policy p;
    persist_policy_init(&p, 0, UINT32_MAX - 100u);
    assert_false(persist_policy_due(&p, 1, UINT32_MAX - 100u, 500));
    assert_false(persist_policy_due(&p, 1, 398u, 500)); /* 499 ms later, across the wrap */
    assert_true(persist_policy_due(&p, 1, 399u, 500));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(oversample_mean_matches_double_reference),
        cmocka_unit_test(oversample_mean_of_full_scale_and_bad_arguments),
        cmocka_unit_test(brr_for_19200_at_72mhz_is_the_reference_manual_value),
        cmocka_unit_test(every_register_map_baud_is_within_one_percent),
        cmocka_unit_test(impossible_baud_rates_are_refused),
        cmocka_unit_test(code_zero_is_steady_on),
        cmocka_unit_test(code_n_flashes_n_times_per_period),
        cmocka_unit_test(persists_once_after_changes_settle),
        cmocka_unit_test(settle_time_is_wrap_safe),
    };
    return cmocka_run_group_tests_name("board_logic", tests, NULL, NULL);
}
