/* Issue 23, item 7: the auto-clear of link faults (host_sim/rig/auto_clear.c)
 * clears sensor faults that latched during a link outage, after N s of valid
 * sensors, at most K an hour, and never anything else. Ticks of 10 ms. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include "auto_clear.h"
#include "leveler/status.h"

#define SENSOR_HEIGHT LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_HEIGHT)
#define SENSOR_P_PIPE LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE)
#define OVERPRESSURE LEVELER_FAULT_BIT(LEVELER_FAULT_OVERPRESSURE)
#define RUN_TIME LEVELER_FAULT_BIT(LEVELER_FAULT_RUN_TIME)
#define STALL LEVELER_FAULT_BIT(LEVELER_FAULT_STALL)
#define CHATTER LEVELER_FAULT_BIT(LEVELER_FAULT_CHATTER)

static uint64_t t_ms;

/* Runs ticks for ms with the given inputs; the first tick at which a clear
 * is asked for (latched then reads 0, as after clear_faults), or -1. */
static long run(rig_auto_clear *a, uint32_t ms, uint16_t *latched, bool valid, bool scan_failed)
{
    long cleared_at = -1;
    for (uint32_t k = 0; k < ms / 10; k++, t_ms += 10) {
        if (rig_auto_clear_step(a, t_ms, *latched, valid, scan_failed) == RIG_AUTO_CLEAR_NOW && cleared_at < 0) {
            cleared_at = (long)t_ms;
            *latched = 0;
        }
    }
    return cleared_at;
}

/* An outage latches faults with the link down; then valid sensors. */
static long outage_then_valid(rig_auto_clear *a, uint16_t bits, uint32_t valid_ms)
{
    uint16_t latched = 0;
    run(a, 100, &latched, true, false);
    run(a, 200, &latched, false, true); /* scans fail */
    latched = bits;
    run(a, 50, &latched, false, true);
    uint64_t back = t_ms;
    long at = run(a, valid_ms, &latched, true, false);
    return at < 0 ? -1 : at - (long)back;
}

static void link_sensor_faults_cleared_after_n_seconds(void **state)
{
    (void)state;
    rig_auto_clear a;
    rig_auto_clear_init(&a, 2000, 6);
    long after = outage_then_valid(&a, SENSOR_HEIGHT | SENSOR_P_PIPE, 5000);
    assert_int_equal(after, 2000);
    assert_int_equal(a.count, 1);
}

static void never_without_n_seconds_of_valid_sensors(void **state)
{
    (void)state;
    rig_auto_clear a;
    rig_auto_clear_init(&a, 2000, 6);
    assert_int_equal(outage_then_valid(&a, SENSOR_HEIGHT, 1990), -1);
    /* a failed scan restarts the count */
    uint16_t latched = SENSOR_HEIGHT;
    run(&a, 10, &latched, true, true);
    assert_int_equal(run(&a, 1990, &latched, true, false), -1);
    assert_true(run(&a, 20, &latched, true, false) >= 0);
}

static void never_overpressure_run_time_stall_or_chatter(void **state)
{
    (void)state;
    const uint16_t others[] = {OVERPRESSURE, RUN_TIME, STALL, CHATTER};
    for (unsigned i = 0; i < sizeof others / sizeof others[0]; i++) {
        rig_auto_clear a;
        rig_auto_clear_init(&a, 1000, 6);
        /* latched during the outage, alone or beside a link fault */
        assert_int_equal(outage_then_valid(&a, others[i], 10000), -1);
        rig_auto_clear_init(&a, 1000, 6);
        assert_int_equal(outage_then_valid(&a, (uint16_t)(others[i] | SENSOR_HEIGHT), 10000), -1);
        assert_int_equal(a.count, 0);
    }
}

static void never_a_sensor_fault_latched_with_the_link_up(void **state)
{
    (void)state;
    rig_auto_clear a;
    rig_auto_clear_init(&a, 1000, 6);
    uint16_t latched = 0;
    run(&a, 5000, &latched, true, false);
    latched = SENSOR_P_PIPE; /* out of range with every scan answered: a sensor, not the link */
    run(&a, 100, &latched, false, false);
    assert_int_equal(run(&a, 10000, &latched, true, false), -1);
    /* and a later outage does not make it a link fault */
    run(&a, 200, &latched, false, true);
    assert_int_equal(run(&a, 10000, &latched, true, false), -1);
}

static void at_most_k_an_hour(void **state)
{
    (void)state;
    rig_auto_clear a;
    rig_auto_clear_init(&a, 1000, 3);
    t_ms = 0;
    for (int k = 0; k < 3; k++)
        assert_true(outage_then_valid(&a, SENSOR_HEIGHT, 2000) >= 0);
    assert_int_equal(outage_then_valid(&a, SENSOR_HEIGHT, 60000), -1);
    assert_int_equal(a.count, 3);
    /* an hour after the first, one more is allowed */
    uint16_t latched = SENSOR_HEIGHT;
    assert_true(run(&a, 3600000, &latched, true, false) >= 0);
    assert_int_equal(a.count, 4);
}

static void off_when_after_is_zero(void **state)
{
    (void)state;
    rig_auto_clear a;
    rig_auto_clear_init(&a, 0, 6);
    assert_int_equal(outage_then_valid(&a, SENSOR_HEIGHT, 60000), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(link_sensor_faults_cleared_after_n_seconds),
        cmocka_unit_test(never_without_n_seconds_of_valid_sensors),
        cmocka_unit_test(never_overpressure_run_time_stall_or_chatter),
        cmocka_unit_test(never_a_sensor_fault_latched_with_the_link_up),
        cmocka_unit_test(at_most_k_an_hour),
        cmocka_unit_test(off_when_after_is_zero),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
