/* Sensor sampling: oversampling, range/stuck/stale detection, spike filter, debounce. */
#include "test_support.h"

#include "leveler/fixed_point.h"
#include "leveler/sensors.h"

static leveler_sensors s;
static leveler_settings set;
static uint32_t now;

static int setup(void **state)
{
    (void)state;
    fake_hal_reset();
    leveler_settings_defaults(&set);
    now = 5000;
    leveler_sensors_init(&s, now);
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        fake_hal_set_adc((hal_adc_channel)c, 2000);
    }
    return 0;
}

static void tick(unsigned n)
{
    for (unsigned i = 0; i < n; i++) {
        now += 10;
        leveler_sensors_sample(&s, &set, now);
    }
}

static void test_oversamples_four_reads_per_tick(void **state)
{
    (void)state;
    const uint16_t script[] = {1000, 1001, 1002, 1004};
    fake_hal_script_adc(HAL_ADC_HEIGHT, script, 4);
    tick(1);
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        assert_int_equal(fake_hal_adc_reads((hal_adc_channel)c), LEVELER_OVERSAMPLE);
    }
    assert_int_equal(s.ch[0].value, leveler_cal_convert(&set.calibration[0], 4007, 4));
    assert_int_equal(s.ch[0].raw_counts, 1002); /* 1001.75 rounded */
    assert_false(s.ch[0].valid);                /* not valid before sensor_good_samples */
    tick(set.sensor_good_samples - 1u);
    assert_true(leveler_sensors_all_valid(&s));
}

static void test_out_of_range_thresholds(void **state)
{
    (void)state;
    set.sensor_bad_samples = 3;
    fake_hal_set_adc(HAL_ADC_P_PIPE, LEVELER_ADC_OPEN_BELOW_COUNTS); /* 5 %: still in range */
    fake_hal_set_adc(HAL_ADC_P_ACC, LEVELER_ADC_SHORT_ABOVE_COUNTS); /* 95 %: still in range */
    tick(set.sensor_good_samples);
    assert_true(leveler_sensors_all_valid(&s));
    fake_hal_set_adc(HAL_ADC_P_PIPE, LEVELER_ADC_OPEN_BELOW_COUNTS - 1u);
    fake_hal_set_adc(HAL_ADC_P_ACC, LEVELER_ADC_SHORT_ABOVE_COUNTS + 1u);
    int32_t held = s.ch[2].value;
    tick(2);
    assert_int_equal(leveler_sensors_fault_bits(&s), 0); /* debounce: not yet */
    assert_int_equal(s.ch[2].bad_reasons, LEVELER_SENSOR_BAD_RANGE);
    assert_int_equal(s.ch[2].value, held); /* a bad sample never becomes the value */
    tick(1);
    assert_int_equal(leveler_sensors_fault_bits(&s), (1u << 2) | (1u << 3));
    assert_false(leveler_sensors_all_valid(&s));
}

static void test_debounce_recovery(void **state)
{
    (void)state;
    set.sensor_bad_samples = 4;
    set.sensor_good_samples = 6;
    tick(6);
    assert_true(s.ch[1].valid);
    fake_hal_set_adc(HAL_ADC_P_SPRING, 0);
    tick(3);
    fake_hal_set_adc(HAL_ADC_P_SPRING, 2000);
    tick(1); /* a good one resets the bad run */
    fake_hal_set_adc(HAL_ADC_P_SPRING, 0);
    tick(3);
    assert_false(s.ch[1].faulty);
    tick(1);
    assert_true(s.ch[1].faulty);
    fake_hal_set_adc(HAL_ADC_P_SPRING, 2000);
    tick(5);
    assert_true(s.ch[1].faulty);
    tick(1);
    assert_false(s.ch[1].faulty);
    assert_true(s.ch[1].valid);
}

static void test_stale_readings(void **state)
{
    (void)state;
    set.sensor_bad_samples = 1000; /* so only the stale timer can make it faulty */
    set.sensor_stale_ms = 100;
    tick(set.sensor_good_samples);
    fake_hal_set_adc_fail(HAL_ADC_HEIGHT, true);
    tick(9);
    assert_int_equal(s.ch[0].bad_reasons, LEVELER_SENSOR_BAD_NO_READING);
    assert_false(s.ch[0].faulty);
    tick(1); /* 100 ms without a reading */
    assert_true(s.ch[0].faulty);
    assert_true((s.ch[0].bad_reasons & LEVELER_SENSOR_BAD_STALE) != 0u);
    /* One failed read out of four is still a fresh reading (the other three). */
    fake_hal_set_adc_fail(HAL_ADC_HEIGHT, false);
    const uint16_t script[] = {2000, 2000, 2000};
    fake_hal_script_adc(HAL_ADC_HEIGHT, script, 3);
    tick(1);
    assert_int_equal(s.ch[0].bad_reasons, 0);
}

static void test_failed_reads_debounce(void **state)
{
    (void)state;
    tick(set.sensor_good_samples);
    fake_hal_set_adc_fail(HAL_ADC_P_ACC, true);
    tick(set.sensor_bad_samples - 1u);
    assert_false(s.ch[3].faulty);
    tick(1);
    assert_true(s.ch[3].faulty); /* hal.h: a failed read is a bad sample */
}

static void test_stuck_detection(void **state)
{
    (void)state;
    tick(200); /* default sensor_stuck_s = 0: a frozen reading is fine */
    assert_true(leveler_sensors_all_valid(&s));
    set.sensor_stuck_s = 1;
    set.sensor_bad_samples = 1;
    fake_hal_set_adc(HAL_ADC_HEIGHT, 2001); /* a change restarts the stuck timer */
    tick(100); /* the change tick + 99: 990 ms frozen */
    assert_false(s.ch[0].faulty);
    tick(1);
    assert_true(s.ch[0].faulty);
    assert_true((s.ch[0].bad_reasons & LEVELER_SENSOR_BAD_STUCK) != 0u);
    assert_true(s.ch[1].faulty); /* the others never changed at all */
}

static void test_spike_filter(void **state)
{
    (void)state;
    tick(set.sensor_good_samples);
    int32_t v0 = s.ch[0].value;
    fake_hal_set_adc(HAL_ADC_HEIGHT, 2000 + LEVELER_SPIKE_LIMIT_COUNTS); /* at the limit: accepted */
    tick(1);
    assert_int_not_equal(s.ch[0].value, v0);
    fake_hal_set_adc(HAL_ADC_HEIGHT, 2000);
    tick(1);
    assert_int_equal(s.ch[0].value, v0);
    /* A lone spike is held and never seen. */
    fake_hal_set_adc(HAL_ADC_HEIGHT, 3500);
    tick(1);
    assert_int_equal(s.ch[0].value, v0);
    fake_hal_set_adc(HAL_ADC_HEIGHT, 2000);
    tick(1);
    assert_int_equal(s.ch[0].value, v0);
    /* A real step is taken one tick late. */
    fake_hal_set_adc(HAL_ADC_HEIGHT, 3000);
    tick(1);
    assert_int_equal(s.ch[0].value, v0);
    tick(1);
    assert_int_equal(s.ch[0].value, leveler_cal_convert(&set.calibration[0], 12000, 4));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_oversamples_four_reads_per_tick, setup),
        cmocka_unit_test_setup(test_out_of_range_thresholds, setup),
        cmocka_unit_test_setup(test_debounce_recovery, setup),
        cmocka_unit_test_setup(test_stale_readings, setup),
        cmocka_unit_test_setup(test_failed_reads_debounce, setup),
        cmocka_unit_test_setup(test_stuck_detection, setup),
        cmocka_unit_test_setup(test_spike_filter, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
