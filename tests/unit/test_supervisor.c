/* Safety supervisor: every rule, fault latching, counters and clearing. */
#include "test_support.h"

#include "leveler/supervisor.h"

static leveler_supervisor sv;
static leveler_settings set;
static leveler_measurements m;
static leveler_outputs out;
static uint32_t now;
static const leveler_outputs all_on = {true, true, true, true};
static const leveler_outputs fill = {true, true, false, false};

static int setup(void **state)
{
    (void)state;
    leveler_settings_defaults(&set);
    leveler_supervisor_init(&sv);
    m = (leveler_measurements){398780, 613633, 613633, 613633, true, 0, 0xFu};
    now = 1000;
    return 0;
}

static void step(const leveler_outputs *req, uint16_t mode)
{
    now += 10;
    leveler_supervisor_step(&sv, &set, mode, &m, req, now, 10, &out);
}

static bool all_off(void)
{
    return !out.compressor && !out.spring_valve && !out.vent_valve && !out.acc_valve;
}

static void test_passes_request_when_healthy(void **state)
{
    (void)state;
    step(&all_on, LEVELER_MODE_AUTO);
    assert_true(out.compressor && out.spring_valve && out.vent_valve && out.acc_valve);
    assert_false(sv.outputs_safe);
    assert_int_equal(sv.latched_bits, 0);
}

static void test_mode_off_and_invalid_sensors_are_safe(void **state)
{
    (void)state;
    step(&all_on, LEVELER_MODE_OFF);
    assert_true(all_off());
    assert_true(sv.outputs_safe);
    m.sensors_valid = false; /* power-up: not yet valid, no fault */
    step(&all_on, LEVELER_MODE_AUTO);
    assert_true(all_off());
    assert_int_equal(sv.latched_bits, 0);
}

static void test_sensor_fault_latches_and_holds_until_cleared(void **state)
{
    (void)state;
    m.sensors_valid = false;
    m.sensor_fault_bits = 1u << 2; /* P1 */
    step(&all_on, LEVELER_MODE_AUTO);
    assert_true(all_off());
    assert_int_equal(sv.last_fault_code, LEVELER_FAULT_SENSOR_P_PIPE);
    assert_int_equal(sv.latched_bits, LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_P_PIPE));
    assert_int_equal(sv.fault_count[3], 1);
    step(&all_on, LEVELER_MODE_AUTO);
    assert_int_equal(sv.fault_count[3], 1); /* counted once per occurrence */
    /* Sensor recovers: still held safe by the latch. */
    m.sensors_valid = true;
    m.sensor_fault_bits = 0;
    step(&all_on, LEVELER_MODE_AUTO);
    assert_true(all_off());
    leveler_supervisor_clear(&sv);
    step(&all_on, LEVELER_MODE_AUTO);
    assert_true(out.compressor);
    assert_int_equal(sv.latched_bits, 0);
}

static void test_clear_while_present_relatches(void **state)
{
    (void)state;
    m.sensors_valid = false;
    m.sensor_fault_bits = 1u;
    step(&all_on, LEVELER_MODE_AUTO);
    leveler_supervisor_clear(&sv);
    assert_int_equal(sv.latched_bits, 0);
    step(&all_on, LEVELER_MODE_AUTO);
    assert_int_equal(sv.latched_bits, LEVELER_FAULT_BIT(LEVELER_FAULT_SENSOR_HEIGHT));
    assert_int_equal(sv.fault_count[3], 1);
}

static void test_overpressure_cutoff_each_channel(void **state)
{
    (void)state;
    for (int ch = 0; ch < 3; ch++) {
        setup(NULL);
        int32_t *p = ch == 0 ? &m.p_pipe_pa : ch == 1 ? &m.p_spring_pa : &m.p_acc_pa;
        *p = set.overpressure_limit_pa; /* strict: at the limit still runs */
        step(&fill, LEVELER_MODE_AUTO);
        assert_true(out.compressor);
        *p = set.overpressure_limit_pa + 1;
        step(&fill, LEVELER_MODE_AUTO);
        assert_false(out.compressor);
        assert_true(out.spring_valve); /* only the compressor is cut */
        assert_int_equal(sv.last_fault_code, LEVELER_FAULT_OVERPRESSURE);
        assert_int_equal(sv.fault_count[0], 1);
        /* Hysteresis: no restart until 1 psi below the cut-off. */
        *p = set.overpressure_limit_pa - LEVELER_OVERPRESSURE_HYST_PA;
        step(&fill, LEVELER_MODE_AUTO);
        assert_false(out.compressor);
        *p = set.overpressure_limit_pa - LEVELER_OVERPRESSURE_HYST_PA - 1;
        step(&fill, LEVELER_MODE_AUTO);
        assert_true(out.compressor);
        assert_int_equal(sv.active_bits, 0);
        assert_int_equal(sv.latched_bits, LEVELER_FAULT_BIT(LEVELER_FAULT_OVERPRESSURE)); /* the record stays */
    }
}

static void test_overpressure_vent(void **state)
{
    (void)state;
    const leveler_outputs none = {false, false, false, false};
    m.p_pipe_pa = set.overpressure_vent_pa;
    step(&none, LEVELER_MODE_AUTO);
    assert_false(out.vent_valve);
    m.p_pipe_pa = set.overpressure_vent_pa + 1;
    step(&none, LEVELER_MODE_AUTO);
    assert_true(out.vent_valve);
    assert_false(out.spring_valve);
    m.p_pipe_pa = 613633;
    m.p_spring_pa = set.overpressure_vent_pa + 1;
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(out.vent_valve && out.spring_valve && !out.compressor && !out.acc_valve);
    m.p_spring_pa = 613633;
    m.p_acc_pa = set.overpressure_vent_pa + 1;
    step(&none, LEVELER_MODE_MANUAL);
    assert_true(out.vent_valve && out.acc_valve && !out.spring_valve);
}

static void test_run_time_limit_and_cooldown(void **state)
{
    (void)state;
    set.compressor_max_run_s = 2;
    set.compressor_cooldown_s = 1;
    set.stall_min_rise_pa = 0; /* keep the stall check quiet */
    for (int i = 0; i < 199; i++) {
        step(&fill, LEVELER_MODE_AUTO);
        assert_true(out.compressor);
    }
    step(&fill, LEVELER_MODE_AUTO); /* 2000 ms of running */
    assert_false(out.compressor);
    assert_true(out.spring_valve); /* the valves still follow the controller */
    assert_int_equal(sv.last_fault_code, LEVELER_FAULT_RUN_TIME);
    assert_int_equal(sv.fault_count[1], 1);
    assert_int_equal(sv.cooldown_left_ms, 1000);
    for (int i = 0; i < 99; i++) {
        step(&fill, LEVELER_MODE_AUTO);
        assert_false(out.compressor);
    }
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(out.compressor);
    assert_int_equal(sv.compressor_run_ms, 10);
    assert_int_equal(sv.fault_count[1], 1);
}

static void test_stall_or_leak(void **state)
{
    (void)state;
    set.stall_window_s = 1;
    for (int i = 0; i < 100; i++) { /* first step arms at t0, 100 more reach 1000 ms */
        step(&fill, LEVELER_MODE_AUTO);
        assert_true(out.compressor);
    }
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(all_off());
    assert_int_equal(sv.last_fault_code, LEVELER_FAULT_STALL);
    assert_int_equal(sv.fault_count[2], 1);
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(all_off()); /* held until cleared */
    leveler_supervisor_clear(&sv);
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(out.compressor);
    /* Charging only the accumulator (spring valve closed) is not filling. */
    const leveler_outputs charge_acc = {true, false, false, true};
    for (int i = 0; i < 300; i++) {
        step(&charge_acc, LEVELER_MODE_AUTO);
    }
    assert_true(out.compressor);
    assert_int_equal(sv.fault_count[2], 1);
}

static void test_stall_progress_resets_window(void **state)
{
    (void)state;
    set.stall_window_s = 1;
    for (int k = 0; k < 3; k++) { /* P1, P2 and height progress each count */
        for (int i = 0; i < 90; i++) {
            step(&fill, LEVELER_MODE_AUTO);
        }
        if (k == 0) {
            m.p_pipe_pa += set.stall_min_rise_pa;
        } else if (k == 1) {
            m.p_spring_pa += set.stall_min_rise_pa;
        } else {
            m.height_um += set.stall_min_rise_um;
        }
    }
    for (int i = 0; i < 90; i++) {
        step(&fill, LEVELER_MODE_AUTO);
    }
    assert_true(out.compressor);
    assert_int_equal(sv.fault_count[2], 0);
    /* A rise one short of the threshold is no progress. */
    m.p_pipe_pa += set.stall_min_rise_pa - 1;
    for (int i = 0; i < 20; i++) {
        step(&fill, LEVELER_MODE_AUTO);
    }
    assert_int_equal(sv.fault_count[2], 1);
}

static void test_counters_saturate(void **state)
{
    (void)state;
    sv.fault_count[0] = UINT16_MAX;
    m.p_acc_pa = set.overpressure_limit_pa + 1;
    step(&fill, LEVELER_MODE_AUTO);
    assert_int_equal(sv.fault_count[0], UINT16_MAX);
    assert_int_equal(sv.last_fault_code, LEVELER_FAULT_OVERPRESSURE);
}

/* Chatter: more switchings in a minute than the limit latch fault 8 and the safe state until cleared. */
static void test_chatter_fault(void **state)
{
    (void)state;
    static const leveler_outputs off = {false, false, false, false};
    set.chatter_max_per_min = 10;
    unsigned n = 0;
    while ((sv.latched_bits & LEVELER_FAULT_BIT(LEVELER_FAULT_CHATTER)) == 0u && n < 100) {
        step((n % 2) ? &off : &fill, LEVELER_MODE_AUTO);
        n++;
    }
    assert_int_equal(n, 12); /* the first step sets the outputs; the 11th switching after it is one too many */
    assert_true(all_off());
    assert_int_equal(sv.last_fault_code, LEVELER_FAULT_CHATTER);
    assert_int_not_equal(sv.latched_bits & LEVELER_FAULT_BIT(LEVELER_FAULT_CHATTER), 0);
    assert_int_equal(sv.fault_count[4], 1);
    for (unsigned i = 0; i < 7000; i++) { /* 70 s of a quiet request: still latched */
        step(&fill, LEVELER_MODE_AUTO);
    }
    assert_true(all_off());
    leveler_supervisor_clear(&sv);
    step(&fill, LEVELER_MODE_AUTO);
    assert_true(out.compressor && out.spring_valve);
    assert_int_equal(sv.latched_bits, 0);
}

/* The window is a minute: ten switchings every 70 s never trip a limit of 10; limit 0 = off. */
static void test_chatter_window_and_off(void **state)
{
    (void)state;
    static const leveler_outputs off = {false, false, false, false};
    set.chatter_max_per_min = 10;
    for (unsigned burst = 0; burst < 5; burst++) {
        for (unsigned i = 0; i < 10; i++) {
            step((i % 2) ? &off : &fill, LEVELER_MODE_AUTO);
        }
        for (unsigned i = 0; i < 7000; i++) {
            step(&off, LEVELER_MODE_AUTO);
        }
    }
    assert_int_equal(sv.latched_bits, 0);
    set.chatter_max_per_min = 0;
    for (unsigned i = 0; i < 1000; i++) {
        step((i % 2) ? &off : &fill, LEVELER_MODE_AUTO);
    }
    assert_int_equal(sv.latched_bits, 0);
    assert_false(sv.outputs_safe);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_passes_request_when_healthy, setup),
        cmocka_unit_test_setup(test_mode_off_and_invalid_sensors_are_safe, setup),
        cmocka_unit_test_setup(test_sensor_fault_latches_and_holds_until_cleared, setup),
        cmocka_unit_test_setup(test_clear_while_present_relatches, setup),
        cmocka_unit_test_setup(test_overpressure_cutoff_each_channel, setup),
        cmocka_unit_test_setup(test_overpressure_vent, setup),
        cmocka_unit_test_setup(test_run_time_limit_and_cooldown, setup),
        cmocka_unit_test_setup(test_stall_or_leak, setup),
        cmocka_unit_test_setup(test_stall_progress_resets_window, setup),
        cmocka_unit_test_setup(test_counters_saturate, setup),
        cmocka_unit_test_setup(test_chatter_fault, setup),
        cmocka_unit_test_setup(test_chatter_window_and_off, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
