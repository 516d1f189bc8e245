/* Every control rule of both algorithms, band edges included. */
#include "test_support.h"

#include "leveler/control.h"

#define LOWER 396240
#define UPPER 401320
#define ACC_MAX 873566
#define P1 613633

typedef struct {
    bool c, s, v, a;
} want;

static leveler_control_state decide(uint16_t algo, int32_t h, int32_t p1, int32_t p3, leveler_outputs *o)
{
    return leveler_control_decide(algo, LOWER, UPPER, ACC_MAX, h, p1, p3, o);
}

static void check(const leveler_outputs *o, want w)
{
    assert_int_equal(o->compressor, w.c);
    assert_int_equal(o->spring_valve, w.s);
    assert_int_equal(o->vent_valve, w.v);
    assert_int_equal(o->acc_valve, w.a);
}

static void test_algorithm1_rules_and_edges(void **state)
{
    (void)state;
    leveler_outputs o;
    const want charge = {1, 1, 0, 0}, discharge = {0, 1, 1, 0}, rest = {0, 0, 0, 0};
    /* Accumulator pressure above and below P1: algorithm 1 never opens its valve. */
    for (int k = 0; k < 2; k++) {
        int32_t p3 = k ? P1 + 100000 : P1 - 100000;
        assert_int_equal(decide(1, LOWER - 1, P1, p3, &o), LEVELER_STATE_CHARGING);
        check(&o, charge);
        assert_int_equal(decide(1, 0, P1, p3, &o), LEVELER_STATE_CHARGING);
        check(&o, charge);
        assert_int_equal(decide(1, LOWER, P1, p3, &o), LEVELER_STATE_IN_BAND); /* edge: in band (strict <) */
        check(&o, rest);
        assert_int_equal(decide(1, (LOWER + UPPER) / 2, P1, p3, &o), LEVELER_STATE_IN_BAND);
        check(&o, rest);
        assert_int_equal(decide(1, UPPER, P1, p3, &o), LEVELER_STATE_IN_BAND); /* edge: in band (strict >) */
        check(&o, rest);
        assert_int_equal(decide(1, UPPER + 1, P1, p3, &o), LEVELER_STATE_DISCHARGING);
        check(&o, discharge);
        assert_int_equal(decide(1, INT32_MAX, P1, p3, &o), LEVELER_STATE_DISCHARGING);
        check(&o, discharge);
    }
}

static void test_algorithm2_below_band(void **state)
{
    (void)state;
    leveler_outputs o;
    assert_int_equal(decide(2, LOWER - 1, P1, P1 + 1, &o), LEVELER_STATE_CHARGING);
    check(&o, (want){1, 1, 0, 1}); /* P3 > P1: the accumulator helps */
    decide(2, LOWER - 1, P1, P1, &o);
    check(&o, (want){1, 1, 0, 0}); /* strict: equal keeps it closed */
    decide(2, LOWER - 1, P1, P1 - 1, &o);
    check(&o, (want){1, 1, 0, 0});
    decide(2, LOWER - 1, P1, ACC_MAX + 50000, &o); /* the charge limit plays no part below band */
    check(&o, (want){1, 1, 0, 1});
}

static void test_algorithm2_above_band(void **state)
{
    (void)state;
    leveler_outputs o;
    assert_int_equal(decide(2, UPPER + 1, P1, P1 - 1, &o), LEVELER_STATE_DISCHARGING);
    check(&o, (want){0, 1, 1, 1}); /* P3 < P1 and below max: surplus air charges it */
    decide(2, UPPER + 1, P1, P1, &o);
    check(&o, (want){0, 1, 1, 0}); /* program: strict P3 < P1 */
    decide(2, UPPER + 1, P1, P1 + 1, &o);
    check(&o, (want){0, 1, 1, 0});
    /* program (not the text): never charged past the maximum, even when P3 < P1 */
    decide(2, UPPER + 1, ACC_MAX + 100000, ACC_MAX, &o);
    check(&o, (want){0, 1, 1, 0});
    decide(2, UPPER + 1, ACC_MAX + 100000, ACC_MAX - 1, &o);
    check(&o, (want){0, 1, 1, 1});
}

static void test_algorithm2_in_band(void **state)
{
    (void)state;
    leveler_outputs o;
    for (int edge = 0; edge < 3; edge++) {
        int32_t h = edge == 0 ? LOWER : edge == 1 ? UPPER : (LOWER + UPPER) / 2;
        assert_int_equal(decide(2, h, P1, P1 - 1, &o), LEVELER_STATE_IN_BAND);
        check(&o, (want){1, 0, 0, 1}); /* P3 < P1 < max: charge it */
        decide(2, h, P1, P1, &o);
        check(&o, (want){1, 0, 0, 0}); /* equal: compressor on, valve closed */
        decide(2, h, P1, P1 + 1, &o);
        check(&o, (want){1, 0, 0, 0}); /* P3 > P1, below max: pump the pipe up first */
        decide(2, h, P1, ACC_MAX - 1, &o);
        check(&o, (want){1, 0, 0, 0});
        decide(2, h, P1, ACC_MAX, &o);
        check(&o, (want){0, 0, 0, 0}); /* program: P3 >= max stops */
        /* program (not the text): at max the compressor stops even when P3 < P1 */
        decide(2, h, ACC_MAX + 100000, ACC_MAX, &o);
        check(&o, (want){0, 0, 0, 0});
        decide(2, h, ACC_MAX + 100000, ACC_MAX - 1, &o);
        check(&o, (want){1, 0, 0, 1});
    }
}

static void test_unknown_algorithm_is_safe(void **state)
{
    (void)state;
    leveler_outputs o = {true, true, true, true};
    assert_int_equal(decide(0, LOWER - 1, P1, P1, &o), LEVELER_STATE_SAFE);
    check(&o, (want){0, 0, 0, 0});
    assert_int_equal(decide(3, UPPER + 1, P1, P1, &o), LEVELER_STATE_SAFE);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_algorithm1_rules_and_edges), cmocka_unit_test(test_algorithm2_below_band),
        cmocka_unit_test(test_algorithm2_above_band),      cmocka_unit_test(test_algorithm2_in_band),
        cmocka_unit_test(test_unknown_algorithm_is_safe),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
