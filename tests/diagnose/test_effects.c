/*
 * The effects library under the sanitizers (the ctypes build has none):
 * every candidate and truth variant integrates a charge/rest/vent cycle to
 * finite states; parameters at "off" give the nominal plant exactly; a
 * parameter outside its range is refused; the leak empties the spring and a
 * closed plant without effects keeps its mass.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>

#include <cmocka.h>

#include "effects.h"

static plant_params thesis(void)
{
    plant_config cfg;
    plant_config_defaults(&cfg);
    return cfg.plant;
}

/* 30 s: charge 8 s, rest 7 s, vent 6 s, rest; load 900 lb then 1100 lb from 5 s. */
static void cycle(plant_fx *f)
{
    for (int k = 0; k < 3000; k++) {
        double t = k * 0.01;
        plant_inputs in = {t < 8.0, t < 8.0 || (t >= 15.0 && t < 21.0), t >= 15.0 && t < 21.0, false,
                           t < 5.0 ? 4003.4 : 4893.0};
        plant_fx_set_inputs(f, &in);
        plant_fx_advance(f, 0.01, 10);
    }
}

static void assert_finite(const plant_fx *f)
{
    for (int i = 0; i < PLANT_NX; i++)
        assert_true(isfinite(f->pl.x[i]));
    double s[4];
    plant_fx_sensed(f, s);
    for (int i = 0; i < 4; i++)
        assert_true(isfinite(s[i]));
}

static void test_every_kind_stays_finite(void **state)
{
    (void)state;
    static const struct { int kind; double p[PLANT_FX_MAX_PARAMS]; } cases[] = {
        {PLANT_FX_THERMAL, {5.0}},
        {PLANT_FX_AREA, {2.0, -50.0, 0.03}},
        {PLANT_FX_FRICTION, {100.0, 50.0, 0.005}},
        {PLANT_FX_VALVE, {0.1, 0.2, 0.3, 0.8}},
        {PLANT_FX_LINE, {0.2, 3e-4}},
        {PLANT_FX_LEAK, {2e-8}},
        {PLANT_FX_SENSOR, {0.3, 0.1, 2000.0, 0.001}},
        {PLANT_FX_TRUTH + PLANT_FX_THERMAL, {8.0, 300.0, 10.0}},
        {PLANT_FX_TRUTH + PLANT_FX_AREA, {0.05, -0.03, 0.0, 0.04, -0.05}},
        {PLANT_FX_TRUTH + PLANT_FX_FRICTION, {100.0, 60.0, 0.004, 2e5, 2000.0}},
        {PLANT_FX_TRUTH + PLANT_FX_VALVE, {0.1, 0.15, 0.3, 0.8}},
        {PLANT_FX_TRUTH + PLANT_FX_LINE, {3e-4, 1e-8}},
        {PLANT_FX_TRUTH + PLANT_FX_LEAK, {1e-16}},
        {PLANT_FX_TRUTH + PLANT_FX_SENSOR, {0.3, 0.15, 0.1, 3000.0, 0.005, 5e-4}},
    };
    plant_params p = thesis();
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        plant_fx_spec spec = {cases[i].kind, {0}};
        memcpy(spec.p, cases[i].p, sizeof spec.p);
        static plant_fx f;
        assert_int_equal(plant_fx_init(&f, &p, &spec), 0);
        cycle(&f);
        assert_finite(&f);
    }
}

static void test_off_is_the_nominal_plant(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant ref;
    plant_init(&ref, &p);
    for (int k = 0; k < 3000; k++) {
        double t = k * 0.01;
        plant_inputs in = {t < 8.0, t < 8.0 || (t >= 15.0 && t < 21.0), t >= 15.0 && t < 21.0, false,
                           t < 5.0 ? 4003.4 : 4893.0};
        plant_set_inputs(&ref, &in);
        plant_advance(&ref, 0.01, 10);
    }
    /* "off" values: thermal tau 0, area 0/0/0, friction 0/0, valve 0/0/b 0/scale 1,
     * line 0/0, leak 0, sensor 0/0/0/0 */
    static const struct { int kind; double p[PLANT_FX_MAX_PARAMS]; } off[] = {
        {PLANT_FX_THERMAL, {0}}, {PLANT_FX_AREA, {0}}, {PLANT_FX_FRICTION, {0, 0, 0.005}},
        {PLANT_FX_VALVE, {0, 0, 0, 1.0}}, {PLANT_FX_LINE, {0, 0}}, {PLANT_FX_LEAK, {0}},
        {PLANT_FX_SENSOR, {0}},
    };
    for (size_t i = 0; i < sizeof off / sizeof off[0]; i++) {
        plant_fx_spec spec = {off[i].kind, {0}};
        memcpy(spec.p, off[i].p, sizeof spec.p);
        static plant_fx f;
        assert_int_equal(plant_fx_init(&f, &p, &spec), 0);
        cycle(&f);
        for (int s = 0; s < PLANT_NX; s++)
            assert_true(f.pl.x[s] == ref.x[s]);
    }
}

static void test_out_of_range_is_refused(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx f;
    plant_fx_spec leak = {PLANT_FX_LEAK, {-1e-8}};
    assert_int_equal(plant_fx_init(&f, &p, &leak), -1);
    plant_fx_spec nan_tau = {PLANT_FX_THERMAL, {NAN}};
    assert_int_equal(plant_fx_init(&f, &p, &nan_tau), -1);
    plant_fx_spec unknown = {42, {0}};
    assert_int_equal(plant_fx_init(&f, &p, &unknown), -1);
}

static void test_leak_empties_and_closed_plant_keeps_mass(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx none, leak;
    plant_fx_spec s0 = {PLANT_FX_NONE, {0}}, s1 = {PLANT_FX_TRUTH + PLANT_FX_LEAK, {1e-16}};
    assert_int_equal(plant_fx_init(&none, &p, &s0), 0);
    assert_int_equal(plant_fx_init(&leak, &p, &s1), 0);
    plant_inputs in = {false, false, false, false, 4003.4};
    plant_fx_set_inputs(&none, &in);
    plant_fx_set_inputs(&leak, &in);
    /* settle the initial velocity of the program's state, then watch 20 s */
    for (int k = 0; k < 500; k++) {
        plant_fx_advance(&none, 0.01, 10);
        plant_fx_advance(&leak, 0.01, 10);
    }
    double p_none = none.pl.x[PLANT_X_P2], p_leak = leak.pl.x[PLANT_X_P2];
    for (int k = 0; k < 2000; k++) {
        plant_fx_advance(&none, 0.01, 10);
        plant_fx_advance(&leak, 0.01, 10);
    }
    assert_true(fabs(none.pl.x[PLANT_X_P2] - p_none) < 1.0);   /* Pa: nothing flows */
    assert_true(leak.pl.x[PLANT_X_P2] < p_leak - 1000.0);       /* the leak lost pressure */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_kind_stays_finite),
        cmocka_unit_test(test_off_is_the_nominal_plant),
        cmocka_unit_test(test_out_of_range_is_refused),
        cmocka_unit_test(test_leak_empties_and_closed_plant_keeps_mass),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
