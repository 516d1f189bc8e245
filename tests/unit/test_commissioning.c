/* The commissioning routine's ends on the fake HAL (leveler/commissioning.h), through the register map:
 * refused, a timeout when the platform never breaks away, a fault holding the safe state. (The routine
 * on a plant, done with the lines learnt: tests/sim/test_commissioning.c.) */
#include "test_support.h"

#include "leveler/alg3.h"
#include "leveler/commissioning.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "leveler/status.h"

static uint16_t read_hr_u16(uint16_t addr)
{
    uint16_t v = 0xFFFFu;
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, addr, 1, &v), LEVELER_REG_OK);
    return v;
}

static uint16_t read_coil(uint16_t addr)
{
    uint16_t v = 0xFFFFu;
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_COIL, addr, 1, &v), LEVELER_REG_OK);
    return v;
}

static bool venting(void)
{
    return !fake_hal_output(HAL_OUT_COMPRESSOR) && fake_hal_output(HAL_OUT_SPRING_VALVE) &&
           fake_hal_output(HAL_OUT_VENT_VALVE);
}

static void test_refused_under_algorithm1(void **state)
{
    (void)state;
    boot_valid();
    assert_int_equal(write_coil(LEVELER_COIL_COMMISSION, 1), LEVELER_REG_OK);
    run_ticks(1);
    assert_int_equal(read_coil(LEVELER_COIL_COMMISSION), 0);
    assert_int_equal(read_hr_u16(LEVELER_HR_COMMISSION_RESULT), LEVELER_COMMISSION_REFUSED);
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_OFF);
    /* a record of the firmware's: not writable */
    uint16_t reason = 0;
    assert_int_not_equal(write_hr_u16(LEVELER_HR_COMMISSION_RESULT, 0, &reason), LEVELER_REG_OK);
    assert_int_equal(reason, LEVELER_REASON_READ_ONLY);
}

/* Algorithm 3 on a platform at rest mid-band; the commission coil written. */
static void start_commissioning(void)
{
    boot_valid();
    assert_int_equal(write_hr_u16(LEVELER_HR_ALGORITHM, LEVELER_ALGO_HYSTERESIS_AWARE, NULL), LEVELER_REG_OK);
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(10);
    assert_int_equal(write_coil(LEVELER_COIL_COMMISSION, 1), LEVELER_REG_OK);
}

/* Rest, then the vent probe; nothing ever moves: at 60 s a timeout, algorithm 3 back in charge. */
static void test_timeout_when_nothing_moves(void **state)
{
    (void)state;
    start_commissioning();
    run_ticks(1);
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_REST);
    assert_int_equal(read_coil(LEVELER_COIL_COMMISSION), 1);
    assert_int_equal(read_hr_i32(LEVELER_HR_ALG3_UP_PA), 0); /* another load's lines forgotten */
    run_ticks(400); /* idle, and 2 s without creep */
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_PROBE_DOWN);
    assert_true(venting());
    run_ticks(LEVELER_COMMISSION_MAX_MS / LEVELER_TICK_MS - 420u);
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_PROBE_DOWN);
    run_ticks(30);
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_OFF);
    assert_int_equal(read_hr_u16(LEVELER_HR_COMMISSION_RESULT), LEVELER_COMMISSION_TIMEOUT);
    assert_int_equal(read_hr_u16(LEVELER_HR_COMMISSION_MS), LEVELER_COMMISSION_MAX_MS);
    assert_int_equal(read_coil(LEVELER_COIL_COMMISSION), 0);
}

/* A sensor fault during a probe: the supervisor holds the safe state, the routine ends on it. */
static void test_fault_ends_it(void **state)
{
    (void)state;
    start_commissioning();
    run_ticks(500);
    assert_true(venting());
    fake_hal_set_adc(HAL_ADC_HEIGHT, 4095); /* a short */
    run_ticks(20);
    assert_false(fake_hal_output(HAL_OUT_VENT_VALVE));
    assert_int_equal(read_hr_u16(LEVELER_HR_COMMISSION_RESULT), LEVELER_COMMISSION_FAULT);
    assert_int_equal(read_ir_u16(LEVELER_IR_COMMISSION_STEP), LEVELER_COMMISSION_OFF);
    assert_int_equal(read_coil(LEVELER_COIL_COMMISSION), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_refused_under_algorithm1),
        cmocka_unit_test(test_timeout_when_nothing_moves),
        cmocka_unit_test(test_fault_ends_it),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
