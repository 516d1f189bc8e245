/*
 * Acceptance of algorithm 3: the short scorecard suite (ctlbench.h) run with
 * algorithms 1, 2 and 3 here, and algorithm 3 asserted against the other two
 * of the same run (no stored figures), plus the learnt hysteresis lines
 * against the simulator's own lines.
 */
#define _XOPEN_SOURCE 700
#include <math.h>
#include <unistd.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ctlbench.h"
#include "ctlbench_limit.h"
#include "ctlbench_family.h"
#include "leveler/alg3.h"
#include "leveler/settings.h"

#define IN_M PLANT_M_PER_IN

static ctlbench_scenario suite[8];
static size_t count;
static ctlbench_metrics m[8][3];
static ctlbench_metrics lim[8];
static ctlbench_limit_moves moves[8];
static runlog_row *rows;

static int run_suite(void **state)
{
    (void)state;
    count = ctlbench_suite(true, CTLBENCH_RANDOM_SEED, suite, 8);
    size_t cap = ctlbench_rows_needed(suite, count);
    rows = malloc(cap * sizeof *rows);
    if (!rows)
        return -1;
    char err[512];
    for (size_t i = 0; i < count; i++)
        for (int a = 1; a <= 3; a++) {
            if (ctlbench_run(&suite[i], a, CONFIG_DIR, NULL, rows, cap, &m[i][a - 1], err, sizeof err) != 0) {
                fprintf(stderr, "%s, algorithm %d: %s\n", suite[i].name, a, err);
                return -1;
            }
        }
    for (size_t i = 0; i < count; i++)
        if (ctlbench_limit(&suite[i], CONFIG_DIR, NULL, rows, cap, &lim[i], &moves[i], err, sizeof err) != 0) {
            fprintf(stderr, "%s, the limit: %s\n", suite[i].name, err);
            return -1;
        }
    return 0;
}

static int done(void **state)
{
    (void)state;
    free(rows);
    return 0;
}

static const ctlbench_metrics *runs(const char *name)
{
    for (size_t i = 0; i < count; i++)
        if (strcmp(suite[i].name, name) == 0)
            return m[i];
    fail_msg("scenario %s not in the short suite", name);
    return NULL;
}

/* Thesis steps without an accumulator: no slower than algorithm 1, fewer
 * switchings, no more air out of the vent, no overshoot through the band. */
static void test_no_accumulator_beats_algorithm1(void **state)
{
    (void)state;
    const ctlbench_metrics *r = runs("thesis-900lb");
    assert_true(r[2].return_median_s <= r[0].return_median_s);
    assert_true(r[2].switchings_per_step < r[0].switchings_per_step);
    assert_true(r[2].vented_kg <= r[0].vented_kg);
    assert_int_equal(r[2].unsettled_steps, 0);
    assert_true(r[2].overshoot_max_m <= 0.05 * IN_M);
    assert_true(r[0].overshoot_max_m > 0.05 * IN_M); /* the thesis's algorithm does shoot through */
}

/* Diaphragm accumulator, +200 lb: back in the band to stay where algorithm 2
 * never settles, with fewer switchings, and no overshoot. */
static void test_diaphragm_settles_where_algorithm2_cycles(void **state)
{
    (void)state;
    const ctlbench_metrics *r = runs("thesis-900lb-diaphragm");
    assert_true(r[2].step[0].settled);
    assert_false(r[1].step[0].settled);
    assert_true(r[2].step[0].return_s < r[1].step[0].return_s);
    assert_true(r[2].step[0].switchings < r[1].step[0].switchings);
    assert_true(r[2].overshoot_max_m <= 0.05 * IN_M);
    assert_true(r[2].vented_kg < r[1].vented_kg);
}

/* At rest with 2 counts of noise: algorithms 1 and 2 hunt, algorithm 3 neither
 * switches nor leaves the band, and no fault is latched. */
static void test_rest_with_noise(void **state)
{
    (void)state;
    const char *names[] = {"rest-900lb-noise2", "rest-900lb-diaphragm-noise2"};
    for (size_t i = 0; i < 2; i++) {
        const ctlbench_metrics *r = runs(names[i]);
        assert_int_equal(r[2].rest_switchings, 0);
        assert_true(r[2].rest_outside_s == 0.0);
        assert_true(r[0].rest_switchings > 0 || r[1].rest_switchings > 0);
        assert_int_equal(r[2].latched_faults, 0);
    }
}

/* The switchings at rest by cause: on the suite's rest runs they add up to the count at rest, and the
 * thesis's algorithms hunt after their return where algorithm 3 does not. */
static void test_rest_split_on_the_suite(void **state)
{
    (void)state;
    const char *names[] = {"rest-900lb-noise2", "rest-900lb-diaphragm-noise2"};
    for (size_t i = 0; i < 2; i++) {
        const ctlbench_metrics *r = runs(names[i]);
        for (int a = 0; a < 3; a++)
            assert_int_equal(r[a].rest_returning + r[a].rest_recharge + r[a].rest_moves, r[a].rest_switchings);
        assert_true(r[0].rest_moves > 0 || r[1].rest_moves > 0);
        assert_int_equal(r[2].rest_moves, 0);
    }
}

/* One row every 10 ms with the outputs given over [from_s, to_s). */
static void outputs_on(runlog_row *rs, size_t n, double from_s, double to_s, int comp, int spring, int vent, int acc)
{
    for (size_t i = (size_t)llround(from_s / 0.01); i < n && i < (size_t)llround(to_s / 0.01); i++) {
        rs[i].compressor = comp;
        rs[i].spring_valve = spring;
        rs[i].vent_valve = vent;
        rs[i].acc_valve = acc;
    }
}

/* Hand-made rows: a vent that closes 0.2 s after the platform is back to stay (the return's, though in
 * the rest window), a recharge, then a fill at rest; a switching before the window is not counted. */
static void test_rest_split_by_hand(void **state)
{
    (void)state;
    ctlbench_scenario sc;
    ctlbench_thesis_rest(&sc, "split", "thesis-900lb.ini", 0.0, 1u, 600.0);
    size_t n = (size_t)llround(sc.rest_to_s / 0.01) + 1;
    runlog_row *rs = calloc(n, sizeof *rs);
    assert_non_null(rs);
    for (size_t i = 0; i < n; i++)
        rs[i].t_s = (double)i * 0.01;
    outputs_on(rs, n, 50.0, 51.0, 0, 1, 1, 0);   /* before the window */
    outputs_on(rs, n, 95.5, 96.2, 0, 1, 1, 0);   /* the return's last vent, back to stay at 96.0 s */
    outputs_on(rs, n, 100.0, 110.0, 1, 0, 0, 1); /* a recharge */
    outputs_on(rs, n, 300.0, 300.3, 1, 1, 0, 0); /* a fill at rest */
    ctlbench_metrics mm;
    memset(&mm, 0, sizeof mm);
    mm.step_count = 2;
    mm.step[1] = (ctlbench_step){.t_s = 35.0, .settled = true, .return_s = 61.0};
    ctlbench_rest_split(&sc, rs, n, &mm);
    assert_int_equal(mm.rest_returning, 2);
    assert_int_equal(mm.rest_recharge, 2);
    assert_int_equal(mm.rest_moves, 2);
    mm.step[1].settled = false; /* never back to stay: every switching in the window is the return's */
    ctlbench_rest_split(&sc, rs, n, &mm);
    assert_int_equal(mm.rest_returning, 6);
    assert_int_equal(mm.rest_recharge + mm.rest_moves, 0);
    free(rs);
}

/* The learnt lines while the 900 lb thesis case runs with algorithm 3, read
 * just before the removal (35 s, 1100 lb on) and at the end (900 lb). */
static int32_t up_before_pa, down_end_pa;

static void watch_settings(double t_s, double end_s, void *user)
{
    (void)end_s;
    (void)user;
    if (t_s < 35.0)
        up_before_pa = leveler_settings_current()->alg3_up_pa;
    down_end_pa = leveler_settings_current()->alg3_down_pa;
}

static double plant_line_pa(const plant_config *cfg, double load_lbf, bool up, double y_m)
{
    const plant_hysteresis_band *b = plant_band_for_load(&cfg->plant, load_lbf * PLANT_N_PER_LBF);
    return (up ? plant_up_limit_pag(b, y_m) : plant_down_limit_pag(b, y_m)) + cfg->plant.ambient_pa;
}

/* Learning: the break-away pressure learnt under 1100 lb and the hold pressure
 * learnt after the removal lie on the simulator's own UPlimit/DPlimit lines of
 * those loads at the target height, within 1 psi. */
static void test_learnt_lines_match_the_plant(void **state)
{
    (void)state;
    static plant_config cfg;
    char err[256];
    assert_int_equal(plant_config_load(CONFIG_DIR "/thesis-900lb.ini", &cfg, err, sizeof err), 0);
    sim_options so = {.config = &cfg, .algorithm = 3, .end_s = 95.0, .progress = watch_settings};
    static sim_result res;
    assert_int_equal(sim_run(&so, &res, err, sizeof err), 0);
    double y = leveler_alg3_target_um(leveler_settings_current()) * 1e-6;
    double up = plant_line_pa(&cfg, 1100.0, true, y), down = plant_line_pa(&cfg, 900.0, false, y);
    printf("learnt up %.2f psia (plant, 1100 lb: %.2f), down %.2f psia (plant, 900 lb: %.2f)\n",
           up_before_pa / PLANT_PA_PER_PSI, up / PLANT_PA_PER_PSI, down_end_pa / PLANT_PA_PER_PSI,
           down / PLANT_PA_PER_PSI);
    assert_true(fabs(up_before_pa - up) < PLANT_PA_PER_PSI);
    assert_true(fabs(down_end_pa - down) < PLANT_PA_PER_PSI);
}

/* The limit starts every step from algorithm 3's state at the step: on every step of the short suite it
 * lands in the band, settles, and is back to stay no later than algorithm 3 (it is a lower bound). */
static void test_limit_bounds_algorithm3(void **state)
{
    (void)state;
    for (size_t i = 0; i < count; i++)
        for (size_t k = 0; k < lim[i].step_count; k++) {
            const ctlbench_step *l = &lim[i].step[k], *a3 = &m[i][2].step[k];
            printf("%s step %zu: limit %.2f s (open %.2f s, lands %.3f in), alg 3 %.2f s\n", suite[i].name, k + 1,
                   l->return_s, moves[i].open_ticks[k] * 0.01, moves[i].landing_m[k] / IN_M, a3->return_s);
            assert_true(l->settled);
            assert_true(moves[i].landing_m[k] >= 15.6 * IN_M && moves[i].landing_m[k] <= 15.8 * IN_M);
            assert_true(l->return_s <= a3->return_s + 1e-9);
        }
}

/* The bisection against the exhaustive scan: the diaphragm's +200 lb step, every open time 0..5 s on the
 * 10 ms grid; the landing never falls as the fill lengthens, and none lands nearer the target than the
 * searched one. */
static void test_limit_search_is_the_scan(void **state)
{
    (void)state;
    size_t i = 0;
    while (i < count && strcmp(suite[i].name, "thesis-900lb-diaphragm") != 0)
        i++;
    assert_true(i < count);
    static plant_config cfg;
    char err[256];
    assert_int_equal(ctlbench_config(&suite[i], 3, CONFIG_DIR, &cfg, err, sizeof err), 0);
    const ctlbench_limit_moves *mv = &moves[i];
    double best = INFINITY, prev = -INFINITY, searched = NAN;
    long best_k = -1;
    for (long k = 0; k <= 500; k++) {
        double h;
        assert_int_equal(ctlbench_limit_landing(&suite[i], &cfg, mv, 1, k, &h, err, sizeof err), 0);
        assert_true(h >= prev - 1e-6);
        prev = h;
        if (fabs(h - mv->target_m) < best)
            best = fabs(h - mv->target_m), best_k = k;
        if (k == mv->target_ticks[0])
            searched = fabs(h - mv->target_m);
    }
    printf("scan: nearest the target after %.2f s (%.4f in off); search: %.2f s\n", best_k * 0.01, best / IN_M,
           mv->target_ticks[0] * 0.01);
    assert_true(mv->target_ticks[0] > 0 && mv->target_ticks[0] <= 500);
    assert_true(searched <= best + 1e-12);
}

/* The perturbed family: every rig's INI file passes the config loader, its values are the thesis
 * rig's times the drawn factors, and the factors lie in the ranges. */
static void test_family_rigs_load_as_drawn(void **state)
{
    (void)state;
    static plant_config base, rig;
    char err[512], dir[] = "/tmp/leveler-family-XXXXXX", path[600];
    assert_non_null(mkdtemp(dir));
    assert_int_equal(plant_config_load(CONFIG_DIR "/" CTLBENCH_FAMILY_BASE, &base, err, sizeof err), 0);
    for (unsigned i = 0; i < 24; i++) {
        ctlbench_rig r;
        ctlbench_family_draw(19u, i, &r);
        assert_int_equal(ctlbench_family_write(&r, dir, CONFIG_DIR, err, sizeof err), 0);
        snprintf(path, sizeof path, "%s/%s", dir, r.file);
        if (plant_config_load(path, &rig, err, sizeof err) != 0)
            fail_msg("%s", err);
        const plant_params *b = &base.plant, *p = &rig.plant;
        assert_true(r.spring_orifice >= 0.75 && r.spring_orifice <= 1.25 && r.vent_cd >= 0.75 && r.vent_cd <= 1.25);
        assert_true(r.damping_up >= 0.5 && r.damping_up <= 2.0 && r.charge >= 0.9 && r.charge <= 1.1);
        assert_true(fabs(p->spring_volume0_m3 / b->spring_volume0_m3 - r.spring_volume) < 1e-6);
        assert_true(fabs(p->vent_valve_cd / b->vent_valve_cd - r.vent_cd) < 1e-4);
        assert_true(fabs(p->compressor_capacity_m3_per_rad / b->compressor_capacity_m3_per_rad - r.displacement) < 1e-6);
        assert_true(fabs((p->acc_charge_pa - p->ambient_pa) / (b->acc_charge_pa - b->ambient_pa) - r.charge) < 1e-6);
        for (int k = 0; k < CTLBENCH_FAMILY_BANDS; k++) {
            assert_true(r.gap_psi[k] >= 8.0 && r.gap_psi[k] <= 14.0 && fabs(r.up_shift_psi[k]) <= 5.0);
            assert_true(fabs(p->bands[k].down_offset_pa / PLANT_PA_PER_PSI - r.gap_psi[k]) < 1e-3);
            assert_true(fabs((p->bands[k].up_intercept_pag - b->bands[k].up_intercept_pag) / PLANT_PA_PER_PSI -
                             r.up_shift_psi[k]) < 1e-3);
        }
        assert_int_equal(remove(path), 0);
    }
    assert_int_equal(rmdir(dir), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_accumulator_beats_algorithm1),
        cmocka_unit_test(test_diaphragm_settles_where_algorithm2_cycles),
        cmocka_unit_test(test_rest_with_noise),
        cmocka_unit_test(test_rest_split_on_the_suite),
        cmocka_unit_test(test_rest_split_by_hand),
        cmocka_unit_test(test_learnt_lines_match_the_plant),
        cmocka_unit_test(test_limit_bounds_algorithm3),
        cmocka_unit_test(test_limit_search_is_the_scan),
        cmocka_unit_test(test_family_rigs_load_as_drawn),
    };
    return cmocka_run_group_tests(tests, run_suite, done);
}
