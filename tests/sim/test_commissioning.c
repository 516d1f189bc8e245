/*
 * The commissioning routine (leveler/commissioning.h) on rigs of the perturbed
 * family (ctlbench_family.h, seed 19) and on the thesis rig: done within 60 s
 * with the platform in the band, and the learnt lines within LINE_TOL_PSI of
 * the rig's own hysteresis lines (its config's, at the controller's target
 * height for the load carried: an expectation the firmware never sees).
 * Each run is the firmware in the loop; the rig is written and loaded by the
 * config loader like any user's.
 */
#define _XOPEN_SOURCE 700
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "commissioning_run.h"
#include "ctlbench_family.h"
#include "leveler/commissioning.h"

#define LINE_TOL_PSI 1.0
#define FAMILY_SEED 19u

/* Run and print; the number of expectations missed (each named). */
static int check(const char *name, const plant_config *cfg)
{
    sim_commissioning c;
    char err[512];
    if (sim_commissioning_run(cfg, 0.0, NULL, &c, err, sizeof err) != 0)
        fail_msg("%s: %s", name, err);
    const double psi = PLANT_PA_PER_PSI;
    double gap_true = c.true_up_pa - c.true_down_pa;
    printf("%-12s %s in %5.2f s, %u moves; up %.2f (plant %.2f) down %.2f (plant %.2f) psia; gap %.2f (%.2f) psi; "
           "k up/down %d/%d Pa/mm; end %.3f in\n",
           name, sim_commissioning_result_name(c.result), c.took_s, c.moves, c.up_pa / psi, c.true_up_pa / psi,
           c.down_pa / psi, c.true_down_pa / psi, c.gap_pa / psi, gap_true / psi, c.k_up_pa_per_mm,
           c.k_down_pa_per_mm, c.final_height_m / PLANT_M_PER_IN);
    const struct {
        bool ok;
        const char *what;
    } expect[] = {
        {c.result == LEVELER_COMMISSION_DONE, "done"},
        {c.took_s <= LEVELER_COMMISSION_MAX_MS / 1000.0, "within 60 s"},
        {c.in_band, "the platform in the band at the end"},
        {c.latched_faults == 0, "no fault latched"},
        {fabs(c.up_pa - c.true_up_pa) <= LINE_TOL_PSI * psi, "the up line"},
        {fabs(c.down_pa - c.true_down_pa) <= LINE_TOL_PSI * psi, "the down line"},
        /* the gap it levels with: the lines' distance, as the rig has it */
        {fabs(c.gap_pa - gap_true) <= 2.0 * LINE_TOL_PSI * psi, "the gap"},
    };
    int missed = 0;
    for (size_t i = 0; i < sizeof expect / sizeof expect[0]; i++)
        if (!expect[i].ok) {
            printf("  %s: MISSED %s\n", name, expect[i].what);
            missed++;
        }
    return missed;
}

static void test_thesis_rig(void **state)
{
    (void)state;
    static plant_config cfg;
    char err[512];
    assert_int_equal(plant_config_load(CONFIG_DIR "/" CTLBENCH_FAMILY_BASE, &cfg, err, sizeof err), 0);
    assert_int_equal(check("thesis", &cfg), 0);
}

static void test_family_rigs(void **state)
{
    (void)state;
    static const unsigned rigs[] = {RIGS};
    static plant_config cfg;
    char err[512], dir[] = "/tmp/leveler-commission-XXXXXX", path[600];
    int missed = 0;
    assert_non_null(mkdtemp(dir));
    for (size_t i = 0; i < sizeof rigs / sizeof rigs[0]; i++) {
        ctlbench_rig r;
        ctlbench_family_draw(FAMILY_SEED, rigs[i] - 1u, &r);
        assert_int_equal(ctlbench_family_write(&r, dir, CONFIG_DIR, err, sizeof err), 0);
        snprintf(path, sizeof path, "%s/%s", dir, r.file);
        if (plant_config_load(path, &cfg, err, sizeof err) != 0)
            fail_msg("%s", err);
        missed += check(r.file, &cfg);
        assert_int_equal(remove(path), 0);
    }
    assert_int_equal(rmdir(dir), 0);
    assert_int_equal(missed, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_thesis_rig),
        cmocka_unit_test(test_family_rigs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
