/* The app loop end to end on the fake HAL: power-up, control transitions, manual mode, LED. */
#include "test_support.h"

#include "leveler/alg3.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "leveler/status.h"

#define BELOW_UM 380000.0
#define ABOVE_UM 420000.0

static bool outputs(bool c, bool s, bool v, bool a)
{
    return fake_hal_output(HAL_OUT_COMPRESSOR) == c && fake_hal_output(HAL_OUT_SPRING_VALVE) == s &&
           fake_hal_output(HAL_OUT_VENT_VALVE) == v && fake_hal_output(HAL_OUT_ACC_VALVE) == a;
}

static void test_power_up_safe_until_sensors_valid(void **state)
{
    (void)state;
    fake_hal_reset();
    leveler_app_init();
    for (unsigned o = 0; o < HAL_OUT_COUNT; o++) {
        assert_int_equal(fake_hal_output_writes((hal_output)o), 1); /* set safe at once */
    }
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    unsigned good = leveler_settings_current()->sensor_good_samples;
    run_ticks(good - 1u);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(leveler_app_status()->control_state, LEVELER_STATE_SAFE);
    run_ticks(1);
    assert_true(outputs(1, 1, 0, 0));
    for (unsigned o = 0; o < HAL_OUT_COUNT; o++) {
        assert_int_equal(fake_hal_output_writes((hal_output)o), 1u + good); /* every output every tick */
    }
    assert_int_equal(leveler_app_status()->uptime_ms, good * 10u);
}

static void test_algorithm1_transitions(void **state)
{
    (void)state;
    boot_valid();
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_CONTROL_STATE), LEVELER_STATE_IN_BAND);
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2); /* the spike filter takes a big step one tick late */
    assert_true(outputs(1, 1, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_CONTROL_STATE), LEVELER_STATE_CHARGING);
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2);
    assert_true(outputs(0, 0, 0, 0));
    set_sensors(ABOVE_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2);
    assert_true(outputs(0, 1, 1, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_CONTROL_STATE), LEVELER_STATE_DISCHARGING);
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2);
    assert_true(outputs(0, 0, 0, 0));
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2);
    set_sensors(ABOVE_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000); /* straight across the band */
    run_ticks(2);
    assert_true(outputs(0, 1, 1, 0));
}

static void test_algorithm2_through_registers(void **state)
{
    (void)state;
    boot_valid();
    assert_int_equal(write_hr_u16(LEVELER_HR_ALGORITHM, LEVELER_ALGO_ACCUMULATOR, NULL), LEVELER_REG_OK);
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, 800000);
    run_ticks(2);
    assert_true(outputs(1, 1, 0, 1));
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, 500000);
    run_ticks(2);
    assert_true(outputs(1, 0, 0, 1)); /* in band: charge the accumulator */
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, 900000); /* above its maximum charge */
    run_ticks(2);
    assert_true(outputs(0, 0, 0, 0));
    set_sensors(ABOVE_UM, P_NOMINAL_PA, P_NOMINAL_PA, 500000);
    run_ticks(2);
    assert_true(outputs(0, 1, 1, 1));
}

/* Algorithm 3 through the register map: selected at run time, reports its phase,
 * waits for a confirmed departure, and leaves P3 out without an accumulator. */
static void test_algorithm3_through_registers(void **state)
{
    (void)state;
    boot_valid();
    assert_int_equal(write_hr_u16(LEVELER_HR_ALGORITHM, LEVELER_ALGO_HYSTERESIS_AWARE, NULL), LEVELER_REG_OK);
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(100);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_ALG3_PHASE), LEVELER_ALG3_IDLE);
    /* 0.02 in under the band: confirmed once 250 um*s have gathered, about half a second */
    set_sensors(leveler_settings_current()->band_lower_um - 500.0, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    fake_hal_set_adc(HAL_ADC_P_ACC, 0); /* no accumulator, no P3 transducer */
    run_ticks(30);
    assert_true(outputs(0, 0, 0, 0));
    run_ticks(40);
    assert_true(outputs(1, 1, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_ALG3_PHASE), LEVELER_ALG3_FILLING);
    assert_int_equal(read_ir_u16(LEVELER_IR_CONTROL_STATE), LEVELER_STATE_CHARGING);
    assert_int_equal(read_ir_u16(LEVELER_IR_ALG3_MOVES), 1);
    assert_int_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS), 0);
    /* mode off: safe, and algorithm 3 starts again from idle */
    assert_int_equal(write_hr_u16(LEVELER_HR_MODE, LEVELER_MODE_OFF, NULL), LEVELER_REG_OK);
    run_ticks(2);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_ALG3_PHASE), LEVELER_ALG3_IDLE);
}

static void test_mode_off_and_manual(void **state)
{
    (void)state;
    boot_valid();
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(2);
    assert_true(outputs(1, 1, 0, 0));
    assert_int_equal(write_hr_u16(LEVELER_HR_MODE, LEVELER_MODE_OFF, NULL), LEVELER_REG_OK);
    run_ticks(1);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(write_hr_u16(LEVELER_HR_MODE, LEVELER_MODE_MANUAL, NULL), LEVELER_REG_OK);
    run_ticks(1);
    assert_true(outputs(0, 0, 0, 0)); /* manual: only what the coils ask */
    assert_int_equal(write_coil(LEVELER_COIL_MANUAL_ACC_VALVE, 1), LEVELER_REG_OK);
    assert_int_equal(write_coil(LEVELER_COIL_MANUAL_COMPRESSOR, 1), LEVELER_REG_OK);
    run_ticks(1);
    assert_true(outputs(1, 0, 0, 1));
    /* Still supervised: overpressure cuts the compressor in manual too. */
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, 1200000, P_NOMINAL_PA);
    run_ticks(2);
    assert_true(outputs(0, 0, 0, 1));
    uint16_t di[8];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_DISCRETE_INPUT, 0, 8, di), 0);
    assert_int_equal(di[LEVELER_DI_COMPRESSOR_ON], 0);
    assert_int_equal(di[LEVELER_DI_ACC_VALVE_OPEN], 1);
    assert_int_equal(di[LEVELER_DI_FAULT_LATCHED], 1);
}

static void test_sensor_fault_safe_and_led(void **state)
{
    (void)state;
    boot_valid();
    assert_true(fake_hal_output(HAL_OUT_STATUS_LED)); /* steady on when all is well */
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(2);
    assert_true(outputs(1, 1, 0, 0));
    fake_hal_set_adc(HAL_ADC_HEIGHT, 4095); /* short */
    run_ticks(leveler_settings_current()->sensor_bad_samples);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_SENSOR_FAULT_BITS), 1);
    assert_int_equal(read_ir_u16(LEVELER_IR_RAW_HEIGHT_COUNTS), 4095);
    /* Fault latched: the LED blinks at 4 Hz. */
    unsigned on = 0, changes = 0;
    bool last = fake_hal_output(HAL_OUT_STATUS_LED);
    for (int i = 0; i < 100; i++) {
        run_ticks(1);
        bool led = fake_hal_output(HAL_OUT_STATUS_LED);
        on += led;
        changes += led != last;
        last = led;
    }
    assert_in_range(on, 40, 60);
    assert_in_range(changes, 7, 9);
}

/* Algorithm 1 does without P3 (the thesis rig had no accumulator transducer):
 * an open P3 input is reported but neither faults nor stops control. Under
 * algorithm 2 the same input is a latched sensor fault and the safe state. */
static void test_unused_p3_channel_needs_no_transducer(void **state)
{
    (void)state;
    boot_valid();
    set_sensors(BELOW_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    fake_hal_set_adc(HAL_ADC_P_ACC, 0); /* open wire */
    run_ticks(leveler_settings_current()->sensor_bad_samples + 2u);
    assert_int_equal(read_ir_u16(LEVELER_IR_SENSOR_FAULT_BITS), 1u << HAL_ADC_P_ACC);
    assert_int_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS), 0);
    assert_true(leveler_app_status()->sensors_valid);
    assert_true(outputs(1, 1, 0, 0)); /* still charging */

    uint16_t algo2 = LEVELER_ALGO_ACCUMULATOR;
    assert_int_equal(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_ALGORITHM, 1, &algo2, NULL),
                     LEVELER_REG_OK);
    run_ticks(1);
    assert_true(outputs(0, 0, 0, 0));
    assert_int_equal(read_ir_u16(LEVELER_IR_LAST_FAULT_CODE), 7); /* P3 sensor */
    assert_int_not_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS) & (1u << 6), 0);
}

static void test_target_reports_and_clock_wrap(void **state)
{
    (void)state;
    fake_hal_reset();
    fake_hal_set_time_ms(UINT32_MAX - 50u); /* the clock wraps during the run */
    leveler_app_report_clock_fault(true);
    leveler_app_report_reset_cause(true);
    leveler_app_init();
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(30);
    assert_int_equal(leveler_app_status()->uptime_ms, 300);
    assert_true(leveler_app_status()->sensors_valid);
    assert_true(leveler_app_status()->clock_fault);
    assert_true(leveler_app_status()->watchdog_reset);
    uint16_t bits[2] = {0, 0};
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_DISCRETE_INPUT, LEVELER_DI_CLOCK_FAULT, 2, bits), LEVELER_REG_OK);
    assert_int_equal(bits[0], 1);
    assert_int_equal(bits[1], 1);
    leveler_app_report_tick_overrun();
    leveler_app_report_tick_cycles(500);
    leveler_app_report_tick_cycles(200);
    uint16_t w[4];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, LEVELER_IR_TICK_OVERRUNS, 4, w), 0);
    assert_int_equal(w[1], 1);
    assert_int_equal(w[3], 500);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_power_up_safe_until_sensors_valid),
        cmocka_unit_test(test_algorithm1_transitions),
        cmocka_unit_test(test_algorithm2_through_registers),
        cmocka_unit_test(test_algorithm3_through_registers),
        cmocka_unit_test(test_mode_off_and_manual),
        cmocka_unit_test(test_sensor_fault_safe_and_led),
        cmocka_unit_test(test_unused_p3_channel_needs_no_transducer),
        cmocka_unit_test(test_target_reports_and_clock_wrap),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
