/* Register map: reads, validated all-or-nothing writes, refusals with reasons, coils. */
#include <stdio.h>

#include "test_support.h"

#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "leveler/status.h"

static int setup(void **state)
{
    (void)state;
    boot_valid();
    return 0;
}

static void test_table_sizes(void **state)
{
    (void)state;
    assert_int_equal(leveler_regs_table_size(LEVELER_TABLE_HOLDING_REGISTER), LEVELER_HR_TABLE_SIZE);
    assert_int_equal(leveler_regs_table_size(LEVELER_TABLE_INPUT_REGISTER), LEVELER_IR_TABLE_SIZE);
    assert_int_equal(leveler_regs_table_size(LEVELER_TABLE_COIL), 6);
    assert_int_equal(leveler_regs_table_size(LEVELER_TABLE_DISCRETE_INPUT), 10); /* registers.json: 0..9 */
    assert_int_equal(leveler_regs_table_size((leveler_table)9), 0);
}

static void test_defaults_valid_and_readable(void **state)
{
    (void)state;
    leveler_settings d;
    leveler_settings_defaults(&d);
    assert_int_equal(leveler_settings_check(&d), LEVELER_REASON_NONE);
    uint16_t w[2];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_BAND_LOWER_UM, 2, w), 0);
    assert_int_equal(w[0], 396240u >> 16); /* high word first */
    assert_int_equal(w[1], 396240u & 0xFFFFu);
    assert_int_equal(read_hr_i32(LEVELER_HR_BAND_UPPER_UM), 401320);
    /* firmware_version: major*10000 + minor*100 + patch of the VERSION file's text */
    unsigned major, minor, patch;
    assert_int_equal(sscanf(LEVELER_VERSION, "%u.%u.%u", &major, &minor, &patch), 3);
    assert_int_equal(read_ir_u16(LEVELER_IR_FIRMWARE_VERSION), major * 10000u + minor * 100u + patch);
    /* Status registers mirror the app. */
    uint16_t h[2];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, LEVELER_IR_HEIGHT_UM, 2, h), 0);
    assert_int_equal((int32_t)(((uint32_t)h[0] << 16) | h[1]), leveler_app_status()->height_um);
    uint16_t bits[8];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_DISCRETE_INPUT, 0, 8, bits), 0);
    assert_int_equal(bits[LEVELER_DI_SENSORS_VALID], 1);
    assert_int_equal(bits[LEVELER_DI_FAULT_LATCHED], 0);
}

static void test_whole_holding_table_reads_with_gaps(void **state)
{
    (void)state;
    uint16_t all[LEVELER_HR_TABLE_SIZE];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, 0, LEVELER_HR_TABLE_SIZE, all), 0);
    assert_int_equal(all[LEVELER_HR_MODE], LEVELER_MODE_AUTO);
    assert_int_equal(all[30], 0); /* a gap reads 0 */
    assert_int_equal(all[LEVELER_HR_CAL_HEIGHT_RAW_HI], 3686);
}

static void test_read_errors(void **state)
{
    (void)state;
    uint16_t w[4];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_TABLE_SIZE - 1u, 2, w),
                     LEVELER_REG_ILLEGAL_ADDRESS);
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, 0, 0, w), LEVELER_REG_ILLEGAL_ADDRESS);
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_BAND_LOWER_UM + 1u, 1, w),
                     LEVELER_REG_ILLEGAL_ADDRESS); /* low half only */
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_ALGORITHM, 2, w),
                     LEVELER_REG_ILLEGAL_ADDRESS); /* high half only */
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, 0xFFFFu, 2, w), LEVELER_REG_ILLEGAL_ADDRESS);
}

static void test_accepts_valid_write(void **state)
{
    (void)state;
    uint32_t gen = leveler_settings_generation();
    uint16_t reason = 99;
    assert_int_equal(write_hr_i32(LEVELER_HR_BAND_LOWER_UM, 390000, &reason), LEVELER_REG_OK);
    assert_int_equal(reason, LEVELER_REASON_NONE);
    assert_int_equal(leveler_settings_current()->band_lower_um, 390000);
    assert_int_equal(read_hr_i32(LEVELER_HR_BAND_LOWER_UM), 390000);
    assert_int_equal(leveler_settings_generation(), gen + 1u);
    /* Writing the same value again is no change. */
    assert_int_equal(write_hr_i32(LEVELER_HR_BAND_LOWER_UM, 390000, NULL), LEVELER_REG_OK);
    assert_int_equal(leveler_settings_generation(), gen + 1u);
    /* Negative int32 round trip (calibration). */
    assert_int_equal(write_hr_i32(LEVELER_HR_CAL_HEIGHT_ENG_LO, -1500000, NULL), LEVELER_REG_OK);
    assert_int_equal(read_hr_i32(LEVELER_HR_CAL_HEIGHT_ENG_LO), -1500000);
    /* Both band edges in one request, moved past each other's old values. */
    uint16_t band[4] = {0, 10000, 0, 20000};
    assert_int_equal(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_BAND_LOWER_UM, 4, band, NULL),
                     LEVELER_REG_OK);
    assert_int_equal(leveler_settings_current()->band_upper_um, 20000);
    assert_int_equal(write_hr_u16(LEVELER_HR_MODBUS_BAUD_DIV100, 1152, NULL), LEVELER_REG_OK);
}

/* Each refusal: status, reason, register, nothing changed. */
static void expect_refused(int status, uint16_t reason, int want_status, uint16_t want_reason)
{
    assert_int_equal(status, want_status);
    assert_int_equal(reason, want_reason);
    assert_int_equal(read_ir_u16(LEVELER_IR_LAST_REFUSAL_REASON), want_reason);
}

/* The call fills r; read it only after the call returns. */
#define REFUSED(call, want_status, want_reason)                                                            \
    do {                                                                                                   \
        r = 0xEEEEu;                                                                                       \
        int status_ = (call);                                                                              \
        expect_refused(status_, r, (want_status), (want_reason));                                          \
    } while (0)

static void test_refusals(void **state)
{
    (void)state;
    leveler_settings before = *leveler_settings_current();
    uint32_t gen = leveler_settings_generation();
    uint16_t r = 0;
    REFUSED(write_hr_i32(LEVELER_HR_BAND_LOWER_UM, 401320, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_BAND_ORDER); /* lower == upper */
    REFUSED(write_hr_i32(LEVELER_HR_BAND_UPPER_UM, 1000001, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_i32(LEVELER_HR_OVERPRESSURE_VENT_PA, 1135538, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_LIMIT_ORDER);
    REFUSED(write_hr_i32(LEVELER_HR_ACC_CHARGE_MAX_PA, 1135540, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_LIMIT_ORDER);
    REFUSED(write_hr_u16(LEVELER_HR_MODE, 3, &r), LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_BAD_ENUM);
    REFUSED(write_hr_u16(LEVELER_HR_ALGORITHM, 0, &r), LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_BAD_ENUM);
    REFUSED(write_hr_u16(LEVELER_HR_ALGORITHM, 4, &r), LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_BAD_ENUM);
    /* algorithm 3 settings: ranges from registers.json, the learnt lines in order */
    REFUSED(write_hr_u16(LEVELER_HR_ALG3_TARGET_PERMILLE, 900, &r), LEVELER_REG_ILLEGAL_VALUE,
            LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_u16(LEVELER_HR_ALG3_ACCUMULATOR, 2, &r), LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_BAD_ENUM);
    REFUSED(write_hr_u16(LEVELER_HR_ALG3_SETTLE_MS, 50, &r), LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_u16(LEVELER_HR_ALG3_COAST_UP_MS, 10, &r), LEVELER_REG_ILLEGAL_VALUE,
            LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_i32(LEVELER_HR_ALG3_LINE_SLOPE_PA_PER_MM, 1, &r), LEVELER_REG_ILLEGAL_VALUE,
            LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_u16(LEVELER_HR_CHATTER_MAX_PER_MIN, 601, &r), LEVELER_REG_ILLEGAL_VALUE,
            LEVELER_REASON_OUT_OF_RANGE);
    {
        uint16_t lines[4] = {0x000A, 0x0000, 0x000A, 0x0000}; /* up 655360 Pa, down the same: not below it */
        REFUSED(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_ALG3_UP_PA, 4, lines, &r),
                LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_LIMIT_ORDER);
        /* all or nothing: a good minimum on time beside a bad off time changes neither */
        uint16_t times[2] = {200, 10001};
        REFUSED(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_ALG3_MIN_ON_MS, 2, times, &r),
                LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_OUT_OF_RANGE);
    }
    REFUSED(write_hr_u16(LEVELER_HR_MODBUS_BAUD_DIV100, 100, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_BAD_ENUM);
    REFUSED(write_hr_u16(LEVELER_HR_CAL_P_PIPE_RAW_LO, 3686, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_CALIBRATION);
    REFUSED(write_hr_i32(LEVELER_HR_CAL_P_ACC_ENG_HI, 101325, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_CALIBRATION);
    REFUSED(write_hr_u16(LEVELER_HR_SENSOR_STALE_MS, 9, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_OUT_OF_RANGE);
    REFUSED(write_hr_u16(LEVELER_HR_BAND_LOWER_UM + 1u, 7, &r), LEVELER_REG_ILLEGAL_ADDRESS,
                   LEVELER_REASON_SPLIT_VALUE);
    REFUSED(write_hr_u16(LEVELER_HR_BAND_LOWER_UM, 0, &r), LEVELER_REG_ILLEGAL_ADDRESS,
                   LEVELER_REASON_SPLIT_VALUE);
    REFUSED(write_hr_u16(30, 0, &r), LEVELER_REG_ILLEGAL_ADDRESS, LEVELER_REASON_READ_ONLY); /* gap */
    uint16_t one = 1;
    REFUSED(leveler_regs_write(LEVELER_TABLE_INPUT_REGISTER, 0, 1, &one, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_READ_ONLY);
    REFUSED(leveler_regs_write(LEVELER_TABLE_COIL, 0, 1, (uint16_t[]){2}, &r), LEVELER_REG_ILLEGAL_VALUE,
                   LEVELER_REASON_OUT_OF_RANGE);
    /* All or nothing: a good mode followed by a bad algorithm changes neither. */
    uint16_t two[2] = {LEVELER_MODE_MANUAL, 7};
    REFUSED(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_MODE, 2, two, &r),
                   LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_BAD_ENUM);
    assert_int_equal(leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_TABLE_SIZE, 1, two, &r),
                     LEVELER_REG_ILLEGAL_ADDRESS);
    assert_memory_equal(&before, leveler_settings_current(), sizeof(before));
    assert_int_equal(leveler_settings_generation(), gen);
    assert_int_equal(leveler_settings_apply(&(leveler_settings){0}), LEVELER_REASON_BAD_ENUM);
}

static void test_coils(void **state)
{
    (void)state;
    assert_int_equal(write_coil(LEVELER_COIL_MANUAL_VENT_VALVE, 1), LEVELER_REG_OK);
    uint16_t c[5];
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_COIL, 0, 5, c), 0);
    assert_int_equal(c[LEVELER_COIL_MANUAL_VENT_VALVE], 1);
    assert_int_equal(c[LEVELER_COIL_MANUAL_COMPRESSOR], 0);
    /* clear_faults: an action that reads back 0 (P1 is used by every algorithm) */
    fake_hal_set_adc(HAL_ADC_P_PIPE, 0);
    run_ticks(leveler_settings_current()->sensor_bad_samples);
    fake_hal_set_adc(HAL_ADC_P_PIPE, counts_for(HAL_ADC_P_PIPE, P_NOMINAL_PA));
    run_ticks(leveler_settings_current()->sensor_good_samples);
    assert_int_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS), LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE));
    assert_int_equal(read_ir_u16(LEVELER_IR_LAST_FAULT_CODE), LEVELER_FAULT_SENSOR_P_PIPE);
    assert_int_equal(read_ir_u16(LEVELER_IR_FAULT_COUNT_SENSOR), 1);
    assert_int_equal(write_coil(LEVELER_COIL_CLEAR_FAULTS, 0), LEVELER_REG_OK); /* 0 does nothing */
    assert_int_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS), LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE));
    assert_int_equal(write_coil(LEVELER_COIL_CLEAR_FAULTS, 1), LEVELER_REG_OK);
    assert_int_equal(read_ir_u16(LEVELER_IR_LATCHED_FAULT_BITS), 0);
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_COIL, 0, 1, c), 0);
    assert_int_equal(c[0], 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_table_sizes, setup),
        cmocka_unit_test_setup(test_defaults_valid_and_readable, setup),
        cmocka_unit_test_setup(test_whole_holding_table_reads_with_gaps, setup),
        cmocka_unit_test_setup(test_read_errors, setup),
        cmocka_unit_test_setup(test_accepts_valid_write, setup),
        cmocka_unit_test_setup(test_refusals, setup),
        cmocka_unit_test_setup(test_coils, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
