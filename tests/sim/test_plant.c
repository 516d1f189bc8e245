/*
 * Plant model tests (cmocka): conservation, equalisation, valve-flow
 * continuity at the critical ratio, RK4 order, config-file errors, the plant
 * under an exact double-precision copy of the program's controller, the
 * firmware in the loop switching on the same ticks as that controller, and
 * the accumulator's benefit with the firmware in the loop.
 */
#define _POSIX_C_SOURCE 200809L
#include <float.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "plant.h"
#include "simloop.h"
#include "leveler/app.h"
#include "leveler/status.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

#ifndef CONFIG_DIR
#error CONFIG_DIR must point at host_sim/configs
#endif

static const double PSI = PLANT_PA_PER_PSI, IN = PLANT_M_PER_IN, LBF = PLANT_N_PER_LBF;

static void thesis_plant(plant *pl, plant_config *cfg)
{
    plant_config_defaults(cfg);
    plant_init(pl, &cfg->plant);
}

static void set(plant *pl, int comp, int sol, int vent, int acc, double load_n)
{
    plant_inputs in = {comp != 0, sol != 0, vent != 0, acc != 0, load_n};
    plant_set_inputs(pl, &in);
}

/* Every valve closed, compressor off: no air moves, so P1 and P3 stay and the
 * spring follows its polytrope P2 V2^(Z n) = const while the platform moves. */
static void test_conservation_closed(void **state)
{
    (void)state;
    static plant pl;
    static plant_config cfg;
    thesis_plant(&pl, &cfg);
    cfg.plant.acc_type = PLANT_ACC_TUBE;
    plant_init(&pl, &cfg.plant);
    pl.x[PLANT_X_P_SPRING] = 100.0 * PSI; /* above the 900 lb upper line: the platform rises */
    set(&pl, 0, 0, 0, 0, 900.0 * LBF);
    double zn = pl.zn;
    double inv0 = pl.x[PLANT_X_P_SPRING] * pow(pl.x[PLANT_X_V2], zn);
    double p1 = pl.x[PLANT_X_P_PIPE], p3 = pl.x[PLANT_X_P_ACC], y0 = pl.x[PLANT_X_Y];
    for (int i = 0; i < 300; i++)
        plant_step(&pl, 0.01);
    assert_true(pl.x[PLANT_X_Y] - y0 > 0.5 * IN); /* it really moved */
    double inv = pl.x[PLANT_X_P_SPRING] * pow(pl.x[PLANT_X_V2], zn);
    assert_true(fabs(inv / inv0 - 1.0) < 1e-7);
    assert_true(pl.x[PLANT_X_P_PIPE] == p1);
    assert_true(pl.x[PLANT_X_P_ACC] == p3);
}

/* Spring valve open, compressor off, platform at rest between the lines:
 * P1 and P2 equalise, and with both volumes fixed the air content
 * sum V P / (Z n R T) is conserved, so the final pressure is the
 * volume-weighted mean. */
static void equalise(double h, double max_diff_pa)
{
    static plant pl;
    static plant_config cfg;
    thesis_plant(&pl, &cfg);
    pl.x[PLANT_X_VEL] = 0.0;
    pl.x[PLANT_X_P_PIPE] = 120.0 * PSI;
    pl.x[PLANT_X_P_SPRING] = 89.0 * PSI;
    set(&pl, 0, 1, 0, 0, 900.0 * LBF);
    double v1 = cfg.plant.pipe_volume_m3, v2 = pl.x[PLANT_X_V2];
    double expect = (v1 * pl.x[PLANT_X_P_PIPE] + v2 * pl.x[PLANT_X_P_SPRING]) / (v1 + v2);
    int n = (int)lround(5.0 / h);
    for (int i = 0; i < n; i++)
        plant_step(&pl, h);
    print_message("h = %g s, after 5 s: P1 - P2 = %.4g Pa, P2 - expected = %.4g Pa\n", h,
                  pl.x[PLANT_X_P_PIPE] - pl.x[PLANT_X_P_SPRING], pl.x[PLANT_X_P_SPRING] - expect);
    assert_true(fabs(pl.x[PLANT_X_Y] - cfg.plant.init_height_m) < 1e-12); /* stayed in the dead zone */
    assert_true(fabs(pl.x[PLANT_X_P_PIPE] - pl.x[PLANT_X_P_SPRING]) < max_diff_pa);
    /* the air content is conserved whatever the step */
    double content = v1 * pl.x[PLANT_X_P_PIPE] + v2 * pl.x[PLANT_X_P_SPRING];
    assert_true(fabs(content / ((v1 + v2) * expect) - 1.0) < 1e-9);
    assert_true(fabs(pl.x[PLANT_X_P_SPRING] - expect) < max_diff_pa);
}

/* Near equal pressures the orifice flow goes like sqrt(dP) (infinite
 * gain), so an explicit step leaves a small chatter of P1 - P2 that
 * shrinks with h^2: < 0.05 psi at the simulator's 10 ms, < 0.002 psi at 1 ms. */
static void test_equalisation(void **state)
{
    (void)state;
    equalise(0.01, 0.05 * PSI);
    equalise(0.001, 0.002 * PSI);
}

/* Eq. (8) with exponent 1/k meets eq. (9) at the critical ratio, and the
 * subsonic branch peaks there. */
static void test_valve_continuity(void **state)
{
    (void)state;
    static plant pl;
    static plant_config cfg;
    thesis_plant(&pl, &cfg);
    double k = cfg.plant.heat_ratio_k;
    double crit = pow(2.0 / (k + 1.0), k / (k - 1.0));
    assert_true(fabs(pl.crit_ratio - crit) < 1e-15);
    double pu = 100.0 * PSI, cda = 1e-6;
    double below = plant_orifice_flow(&pl, cda, pu, pu * crit * (1.0 - 1e-9));
    double above = plant_orifice_flow(&pl, cda, pu, pu * crit * (1.0 + 1e-9));
    assert_true(fabs(above / below - 1.0) < 1e-6);
    assert_true(plant_orifice_flow(&pl, cda, pu, pu * crit * 1.05) < below);
    /* choked flow from first principles: Cd A Pu sqrt(k/(R T)) (2/(k+1))^((k+1)/(2(k-1))) */
    double rt = cfg.plant.gas_constant_j_per_kg_k * cfg.plant.temperature_k;
    double ref = cda * pu * sqrt(k / rt) * pow(2.0 / (k + 1.0), (k + 1.0) / (2.0 * (k - 1.0)));
    assert_true(fabs(below / ref - 1.0) < 1e-9);
    assert_true(plant_orifice_flow(&pl, cda, pu, pu) == 0.0);
}

/* The subsonic orifice law by its table (plant.h) against eq. (8) worked in long double, the difference
 * 1 - r^((k-1)/k) by expm1l (in double it cancels near r = 1): within 4 ULP over the whole subsonic range,
 * for the thesis's k and two others a config may give. Pu = 1 Pa, so the law sees r = Pd exactly. */
static void test_orifice_table(void **state)
{
    (void)state;
    static plant pl;
    static plant_config cfg;
    const double ks[] = {1.4, 1.3, 1.67};
    for (size_t j = 0; j < sizeof ks / sizeof ks[0]; j++) {
        thesis_plant(&pl, &cfg);
        cfg.plant.heat_ratio_k = ks[j];
        plant_init(&pl, &cfg.plant);
        long double k = ks[j], rt = (long double)cfg.plant.gas_constant_j_per_kg_k * cfg.plant.temperature_k;
        double worst = 0.0;
        const int n = 200000;
        for (int i = 0; i < n; i++) {
            double r = pl.crit_ratio + (1.0 - pl.crit_ratio) * (i + 0.5) / n;
            long double ref = sqrtl(2.0L * k / ((k - 1.0L) * rt)) * powl(r, 1.0L / k) *
                              sqrtl(-expm1l((k - 1.0L) / k * logl(r)));
            double rel = fabs((double)(plant_orifice_flow(&pl, 1.0, 1.0, r) / ref - 1.0L));
            worst = rel > worst ? rel : worst;
        }
        printf("k %.2f: worst %.2f ULP\n", ks[j], worst / DBL_EPSILON);
        assert_true(worst <= 4.0 * DBL_EPSILON);
        double near1 = nextafter(1.0, 0.0); /* the flow vanishes like sqrt(1 - r) */
        assert_true(plant_orifice_flow(&pl, 1.0, 1.0, near1) > 0.0);
    }
}

/* RK4 order on a smooth stretch (compressor spinning into a closed pipe,
 * platform rising above the upper line, no switching): the error falls
 * about 16x when the step halves. */
static void run_smooth(double h, double t_end, double x[PLANT_NX])
{
    static plant pl;
    static plant_config cfg;
    thesis_plant(&pl, &cfg);
    pl.x[PLANT_X_P_SPRING] = 100.0 * PSI;
    pl.x[PLANT_X_VEL] = 0.01;
    set(&pl, 1, 0, 0, 0, 900.0 * LBF);
    int n = (int)lround(t_end / h);
    for (int i = 0; i < n; i++)
        plant_step(&pl, h);
    memcpy(x, pl.x, sizeof pl.x);
}

static void test_rk4_order(void **state)
{
    (void)state;
    const double t_end = 0.4;
    double ref[PLANT_NX], a[PLANT_NX], b[PLANT_NX];
    run_smooth(t_end / 2560, t_end, ref);
    run_smooth(t_end / 40, t_end, a);
    run_smooth(t_end / 80, t_end, b);
    const int idx[] = {PLANT_X_OMEGA, PLANT_X_P_PIPE, PLANT_X_P_SPRING, PLANT_X_Y, PLANT_X_VEL};
    for (size_t i = 0; i < sizeof idx / sizeof idx[0]; i++) {
        double ea = fabs(a[idx[i]] - ref[idx[i]]), eb = fabs(b[idx[i]] - ref[idx[i]]);
        double ratio = ea / eb;
        print_message("state %d: error %.3e (h) %.3e (h/2) ratio %.1f\n", idx[i], ea, eb, ratio);
        assert_true(ratio > 12.0 && ratio < 20.0);
    }
}

/* ---- config errors ---- */

static char tmpdir[] = "/tmp/leveler-plant-test-XXXXXX";

static const char *write_file(const char *name, const char *text)
{
    static char path[4][512];
    static int slot;
    char *p = path[slot++ % 4];
    snprintf(p, 512, "%s/%s", tmpdir, name);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    return p;
}

static void expect_error(const char *text, const char *must1, const char *must2)
{
    static plant_config cfg;
    char err[1024];
    const char *p = write_file("bad.ini", text);
    assert_int_equal(plant_config_load(p, &cfg, err, sizeof err), -1);
    print_message("%s\n", err);
    assert_non_null(strstr(err, must1));
    if (must2)
        assert_non_null(strstr(err, must2));
}

static void test_config_errors(void **state)
{
    (void)state;
    expect_error("[spring]\n\nvolume_in3 = -5\n", "bad.ini:3: [spring] volume_in3 = -5", "out of range [0.610237, 6102.37] in3");
    expect_error("[spring]\nvolume_in3 = 270\nvolume_m3 = 0.004\n", "bad.ini:3:", "given twice");
    expect_error("[spring]\nvolume_gallons = 1\n", "bad.ini:2: [spring] volume_gallons", "volume_m3");
    expect_error("[spring]\ncolour = red\n", "bad.ini:2: [spring] colour", "unknown key");
    /* the diaphragm curve */
    expect_error("[accumulator]\ndiaphragm_breaks_psia = 40 30\n", "bad.ini:2: [accumulator] diaphragm_breaks_psia",
                 "breaks must rise");
    expect_error("[accumulator]\ndiaphragm_breaks_psia = 40 106.7\n", "diaphragm_breaks_psia gives 3 segments",
                 "diaphragm_slopes_in3_per_psi has 4");
    expect_error("[accumulator]\ndiaphragm_intercepts_in3 = 20 13.8176 -8028.85463 390\n", "segments 3 and 4 meet",
                 "within 0.1 %");
    expect_error("[accumulator]\ndiaphragm_slopes_in3_per_psi = 0 0.1546 75.531097 -1\n",
                 "bad.ini:2: [accumulator] diaphragm_slopes_in3_per_psi", "out of range [0, 1000]");
    expect_error("[springs]\nvolume_in3 = 1\n", "bad.ini:2:", "unknown section");
    expect_error("[pipe]\nvolume_in3 = 12.5x\n", "bad.ini:2:", "not a number");
    expect_error("[controller]\nband_lower_in = 15.9\nband_upper_in = 15.8\n", "band_lower must be below", NULL);
    expect_error("[accumulator]\ntype = bladder\n", "bad.ini:2: [accumulator] type", "none, tube, diaphragm");
    expect_error("[ambient]\npressure_psig = 100\n", "bad.ini:2: [ambient] pressure_psig", "out of range");
    expect_error("[accumulator]\ncharge_psig = 300\n", "charge_psig", "out of range [-0.00405122, 199.996] psig");
    /* include: the included file's own errors keep its name and line */
    write_file("base.ini", "[pipe]\n\nvolume_in3 = 0\n");
    expect_error("[config]\ninclude = base.ini\n", "base.ini:3: [pipe] volume_in3", "out of range");
    /* issue 13: repeated keys and sections name both lines, long lines, names, directories */
    expect_error("[spring]\nvolume_in3 = 270\n\nvolume_in3 = 280\n", "bad.ini:4: [spring] volume_in3",
                 "repeated (first at line 2)");
    expect_error("[spring]\nvolume_in3 = 270\nvolume_m3 = 0.004\n", "bad.ini:3:", "(first at line 2");
    expect_error("[pipe]\nvolume_in3 = 12\n[spring]\nvolume_in3 = 270\n[pipe]\n", "bad.ini:5: [pipe]",
                 "section repeated (first at line 1)");
    static char long_text[6000];
    snprintf(long_text, sizeof long_text, "[config]\n; %05000d\n[pipe]\nvolume_in3 = 12\n", 0);
    expect_error(long_text, "bad.ini:2:", "line longer than");
    expect_error("[config]\nname = caf\xc3\n", "bad.ini:2: [config] name", "UTF-8");
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load("/tmp", &cfg, err, sizeof err), -1);
    assert_non_null(strstr(err, "/tmp: not a regular file (a directory)"));
}

static void test_config_units_and_include(void **state)
{
    (void)state;
    static plant_config a, b;
    char err[1024];
    assert_int_equal(plant_config_load(CONFIG_DIR "/thesis-900lb.ini", &a, err, sizeof err), 0);
    assert_int_equal(plant_config_load(CONFIG_DIR "/thesis-1000lb.ini", &b, err, sizeof err), 0);
    assert_string_equal(b.name, "thesis-1000lb");
    assert_true(fabs(a.plant.spring_volume0_m3 - 270.0 * IN * IN * IN) < 1e-12);
    assert_true(fabs(b.plant.spring_volume0_m3 - 210.0 * IN * IN * IN) < 1e-12);
    assert_true(fabs(b.plant.damping_down_n_s_per_m - 160.0 * LBF / IN) < 1e-9);
    assert_true(fabs(a.plant.acc_charge_pa - 126.7 * PSI) < 1e-6); /* 112 psig + 14.7 */
    /* SI spelling of the same quantities gives the same values */
    const char *si = write_file("si.ini",
                                "[config]\ninclude = " CONFIG_DIR "/thesis-900lb.ini\n"
                                "[spring]\nvolume_m3 = 0.00442450728\n"
                                "[ambient]\npressure_pa = 101352.93\ntemperature_k = 297.2222222222\n"
                                "[accumulator]\ncharge_pa = 873565.75\n");
    assert_int_equal(plant_config_load(si, &b, err, sizeof err), 0);
    assert_true(fabs(b.plant.spring_volume0_m3 / a.plant.spring_volume0_m3 - 1.0) < 1e-6);
    assert_true(fabs(b.plant.temperature_k / a.plant.temperature_k - 1.0) < 1e-9);
    assert_true(fabs(b.plant.acc_charge_pa / a.plant.acc_charge_pa - 1.0) < 1e-6);
    /* the diaphragm curve of the thesis (README: figure 22 as Appendix B has it) */
    static const double p_psia[] = {30.0, 100.0, 110.0, 120.0};
    static const double v_in3[] = {20.0, 0.1546 * 100.0 + 13.8176, 75.531097 * 110.0 - 8028.85463, 0.75 * 120.0 + 398.975};
    for (int i = 0; i < 4; i++) {
        double v, dv;
        plant_diaphragm_volume(&a.plant, p_psia[i] * PSI, &v, &dv);
        assert_true(fabs(v / (IN * IN * IN) - v_in3[i]) < 1e-9 * v_in3[i]);
    }
    /* the defaults are the thesis 900 lb file (compiled in from it), to the bit */
    static plant_config d;
    plant_config_defaults(&d);
    assert_true(fabs(d.plant.bands[2].up_intercept_pag - 141.5 * PSI) < 1e-6);
    assert_string_equal(d.name, "thesis-900lb");
    assert_string_equal(d.path, "");
    assert_memory_equal(&d.plant, &a.plant, sizeof d.plant);
    assert_memory_equal(&d.sensors, &a.sensors, sizeof d.sensors);
    assert_true(d.band_lower_m == a.band_lower_m && d.valid_load_max_n == a.valid_load_max_n &&
                d.base_load_n == a.base_load_n && d.end_s == a.end_s && d.substeps_per_tick == a.substeps_per_tick);
}

/* ---- the plant under the program's own controller (exact heights) ---- */

/* Appendix B's on_off without accumulator, on the exact height (band from the config). */
static void program_controller(const plant_config *cfg, const plant *pl, plant_inputs *in)
{
    double y = pl->x[PLANT_X_Y];
    in->acc_valve = false;
    if (y < cfg->band_lower_m) {
        in->compressor = true;
        in->spring_valve = true;
        in->vent_valve = false;
    } else if (y > cfg->band_upper_m) {
        in->compressor = false;
        in->spring_valve = true;
        in->vent_valve = true;
    } else {
        in->compressor = in->spring_valve = in->vent_valve = false;
    }
}

#define PROGRAM_STEPS 5500 /* 55 s of 0.01 s steps */

typedef struct {
    double y_m[PROGRAM_STEPS + 1];
    bool out[PROGRAM_STEPS + 1][3]; /* compressor, solenoid, vent over the step from t_k */
} program_run;

/* Appendix B's loop: the initial booleans (motor, solenoid on) over the first
 * step, then after every 0.01 s the controller on the exact y. The plant
 * advances each 0.01 s in `substeps` RK4 steps (the program: 1; 0 = the
 * config's [solver] substeps_per_tick). */
static void run_program(const char *config, int substeps, program_run *r)
{
    static plant pl;
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load(config, &cfg, err, sizeof err), 0);
    plant_init(&pl, &cfg.plant);
    plant_inputs in = {cfg.init_compressor != 0, cfg.init_spring_valve != 0, cfg.init_vent_valve != 0, false, 0.0};
    for (int k = 0; k <= PROGRAM_STEPS; k++) {
        double t = k * 0.01;
        if (k > 0)
            program_controller(&cfg, &pl, &in);
        in.load_n = cfg.base_load_n + ((t >= cfg.step_on_s - 0.005 && t < cfg.step_off_s - 0.005) ? cfg.step_load_n : 0.0);
        r->y_m[k] = pl.x[PLANT_X_Y];
        r->out[k][0] = in.compressor;
        r->out[k][1] = in.spring_valve;
        r->out[k][2] = in.vent_valve;
        plant_set_inputs(&pl, &in);
        plant_advance(&pl, 0.01, substeps > 0 ? substeps : cfg.substeps_per_tick);
    }
}

/* With the parameter-table values the program's loop, its own 0.01 s step
 * included, reproduces the published 900 lb figures: lowest 14.53 in, highest
 * 17.54 in. */
/* The one scenario-to-load rule (stepper.h): the load over the tick from t is
 * the last step at or before t + half a tick; a schedule file names its line. */
static void test_schedule_rule_and_file_errors(void **state)
{
    (void)state;
    plant_config cfg;
    plant_config_defaults(&cfg);
    sim_load_step steps[4];
    double end_s;
    size_t n = sim_schedule_from_config(&cfg, steps, &end_s);
    assert_int_equal(n, 3);
    assert_true(end_s == 55.0);
    sim_schedule_cursor c = {steps, n, 0};
    const double base = cfg.base_load_n, loaded = cfg.base_load_n + cfg.step_load_n;
    assert_true(sim_schedule_load_at(&c, 0.0) == base);
    assert_true(sim_schedule_load_at(&c, 4.99) == base);
    assert_true(sim_schedule_load_at(&c, 4.996) == loaded); /* 5 s minus less than half a tick */
    assert_true(sim_schedule_load_at(&c, 34.99) == loaded);
    assert_true(sim_schedule_load_at(&c, 35.0) == base);
    assert_true(sim_schedule_load_at(&c, 1e6) == base); /* past the end: the last load holds */

    static const struct { const char *text, *words; } bad[] = {
        {"t_s,load_n\n0,4003\n5,4892\n4,1\n", "bad.csv:4: t_s: times must increase"},
        {"1,4003\n2,4003\n", "bad.csv:1: t_s: the first step must be at 0 s"},
        {"0,4003\n", "bad.csv:1: need at least two rows"},
        {"0,4003,1\n5,1\n", "bad.csv:1: expected two columns"},
        {"0,4003\n5,x\n", "bad.csv:2: load_n: expected a number (got 'x')"},
        {"0,4003\n,4003\n", "bad.csv:2: t_s: expected a number (got '')"},
        {"0,4003\n5,-1\n", "bad.csv:2: load_n: out of range"},
        {"t_s,load_n,mode\n0,4003,\n5,4003,3\n", "bad.csv:3: mode: expected an integer 0..2 or empty"},
        {"t_s,load_n,manual_spring_valve\n0,4003,1\n5,4003,on\n", "bad.csv:3: manual_spring_valve: expected"},
        {"t_s,load_n,manual_valve\n0,4003,1\n", "bad.csv:1: manual_valve: not a schedule column"},
        {"t_s,load_n,mode,mode\n0,4003,1,1\n", "bad.csv:1: mode: column given twice"},
        {"t_s,load_n,mode\n0,4003,1,1\n5,4003,\n", "bad.csv:2: expected 3 columns as the header says"},
        {"load_n,t_s\n0,4003\n", "bad.csv:1: header: expected t_s,load_n"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sim_load_step *v = NULL;
        size_t count = 0;
        char err[512];
        assert_int_equal(sim_schedule_load(write_file("bad.csv", bad[i].text), &v, &count, err, sizeof err), -1);
        if (!strstr(err, bad[i].words))
            fail_msg("%s: expected '%s'", err, bad[i].words);
        assert_null(v);
    }
    sim_load_step *v = NULL;
    size_t count = 0;
    char err[512];
    assert_int_equal(sim_schedule_load(write_file("ok.csv", "# loads\nt_s,load_n\n0,4003\n5,4892\n55,4003\n"), &v,
                                       &count, err, sizeof err),
                     0);
    assert_int_equal(count, 3);
    assert_true(v[1].t_s == 5.0 && v[1].load_n == 4892.0);
    assert_int_equal(v[1].writes, 0); /* a load file writes no register */
    free(v);
    /* register columns in any order; an empty cell writes nothing */
    assert_int_equal(sim_schedule_load(write_file("ok.csv", "t_s,load_n,manual_spring_valve,mode\n0,4003,,\n"
                                                            "5,4003,1,2\n6,4003,0,\n9,4003,,1\n"),
                                       &v, &count, err, sizeof err),
                     0);
    assert_int_equal(count, 4);
    assert_int_equal(v[0].writes, 0);
    assert_int_equal(v[1].writes, (1u << 0) | (1u << 2)); /* sim_schedule_regs: mode, ..., spring valve */
    assert_int_equal(v[1].value[0], 2);
    assert_int_equal(v[1].value[2], 1);
    assert_int_equal(v[2].writes, 1u << 2);
    assert_int_equal(v[2].value[2], 0);
    assert_string_equal(sim_schedule_regs[2].name, "manual_spring_valve");
    free(v);
}

/* A schedule's mode and manual rows reach the firmware through its register
 * map: in manual mode the outputs are the requests (still supervised), mode
 * off holds them safe whatever is requested, and back in auto the controller
 * decides again. The compressor against shut valves fills only the pipe. */
static void test_schedule_manual_rows(void **state)
{
    (void)state;
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load(CONFIG_DIR "/thesis-900lb.ini", &cfg, err, sizeof err), 0);
    sim_load_step *steps = NULL;
    size_t n = 0;
    const char *text = "t_s,load_n,mode,manual_compressor,manual_spring_valve,manual_vent_valve\n"
                       "0,4003.4,,,,\n2,4003.4,2,1,0,0\n4,4003.4,,,1,\n4.5,4003.4,,0,0,\n"
                       "5,4003.4,0,1,1,1\n6,4003.4,1,0,0,0\n8,4003.4,,,,\n";
    assert_int_equal(sim_schedule_load(write_file("manual.csv", text), &steps, &n, err, sizeof err), 0);
    static runlog_row rows[900];
    sim_options o = {.config = &cfg, .steps = steps, .step_count = n, .rows = rows, .rows_cap = 900};
    static sim_result res;
    assert_int_equal(sim_run(&o, &res, err, sizeof err), 0);
    free(steps);
    assert_int_equal(res.rows, 801);
    for (size_t i = 1; i < res.rows; i++) { /* row i: the outputs the firmware set at tick i */
        double t = rows[i].t_s;
        bool c = rows[i].compressor, sv = rows[i].spring_valve, vv = rows[i].vent_valve;
        if (t >= 2.0 && t < 4.0)
            assert_true(c && !sv && !vv);
        else if (t >= 4.0 && t < 4.5)
            assert_true(c && sv && !vv);
        else if (t >= 4.5 && t < 6.0) /* manual off, then mode off with everything requested */
            assert_true(!c && !sv && !vv);
    }
    assert_true(rows[390].true_p_pipe_pa > rows[200].true_p_pipe_pa + 20e3);            /* the pipe filled */
    assert_true(fabs(rows[390].true_p_spring_pa - rows[200].true_p_spring_pa) < 1e3); /* the spring did not */
    assert_true(rows[440].true_p_spring_pa > rows[390].true_p_spring_pa + 1e3);        /* until its valve opened */
    uint16_t mode = 0;
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_MODE, 1, &mode), LEVELER_REG_OK);
    assert_int_equal(mode, LEVELER_HR_MODE_AUTO);
}

static void test_program_controller_900(void **state)
{
    (void)state;
    static program_run r;
    run_program(CONFIG_DIR "/thesis-900lb.ini", 1, &r);
    double ymin = 1.0, ymax = 0.0;
    for (int k = 0; k <= PROGRAM_STEPS; k++) {
        double t = k * 0.01;
        if (t > 5.0 && t < 35.0 && r.y_m[k] < ymin)
            ymin = r.y_m[k];
        if (t > 35.0 && r.y_m[k] > ymax)
            ymax = r.y_m[k];
    }
    print_message("program controller: lowest %.3f in, highest %.3f in\n", ymin / IN, ymax / IN);
    assert_true(fabs(ymin / IN - 14.53) < 0.05);
    assert_true(fabs(ymax / IN - 17.54) < 0.05);
}

/* The firmware in the loop (fixed point, 12-bit height, thesis configs whose
 * band edges lie on code transitions) switches exactly as the program's
 * controller on the exact double-precision height: same actuators at every
 * one of the 5501 ticks, so the same trajectory. */
static void firmware_equals_program(const char *config)
{
    static program_run r;
    run_program(config, 0, &r);
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load(config, &cfg, err, sizeof err), 0);
    static runlog_row rows[PROGRAM_STEPS + 1];
    sim_options o = {.config = &cfg, .rows = rows, .rows_cap = PROGRAM_STEPS + 1};
    static sim_result res;
    assert_int_equal(sim_run(&o, &res, err, sizeof err), 0);
    assert_int_equal(res.rows, PROGRAM_STEPS + 1);
    int switches = 0;
    double worst_dy = 0.0;
    for (int k = 0; k <= PROGRAM_STEPS; k++) {
        if (rows[k].compressor != r.out[k][0] || rows[k].spring_valve != r.out[k][1] || rows[k].vent_valve != r.out[k][2])
            fail_msg("%s: t = %.2f s: firmware %d%d%d, program %d%d%d (compressor, solenoid, vent)", config,
                     rows[k].t_s, rows[k].compressor, rows[k].spring_valve, rows[k].vent_valve, r.out[k][0], r.out[k][1],
                     r.out[k][2]);
        if (k > 0 && memcmp(r.out[k], r.out[k - 1], sizeof r.out[k]) != 0)
            switches++;
        worst_dy = fmax(worst_dy, fabs(rows[k].true_height_m - r.y_m[k]));
    }
    print_message("%s: %d switchings, all on the same tick; largest height difference %.3g m\n", config, switches,
                  worst_dy);
    assert_true(switches >= 4); /* charge after the step, stop, vent after the removal, stop */
    assert_true(worst_dy < 1e-9);
}

static void test_firmware_equals_program_900(void **state)
{
    (void)state;
    firmware_equals_program(CONFIG_DIR "/thesis-900lb.ini");
}

static void test_firmware_equals_program_1000(void **state)
{
    (void)state;
    firmware_equals_program(CONFIG_DIR "/thesis-1000lb.ini");
}

/* ---- firmware in the loop: the accumulator shortens the return ---- */

static double return_time_after_step(const char *config, int algorithm)
{
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load(config, &cfg, err, sizeof err), 0);
    static runlog_row rows[5600];
    sim_options o = {.config = &cfg, .algorithm = algorithm, .rows = rows, .rows_cap = 5600};
    static sim_result res;
    assert_int_equal(sim_run(&o, &res, err, sizeof err), 0);
    assert_int_equal(res.rows, 5501);
    /* after the +200 lb step at 5 s: first time back at the band's lower edge after the bottom */
    size_t i = 500;
    while (i < res.rows && rows[i].true_height_m > cfg.band_lower_m - 0.5 * IN) /* wait for the drop */
        i++;
    while (i < res.rows && rows[i].true_height_m < cfg.band_lower_m)
        i++;
    assert_true(i < 3500); /* before the load comes off */
    return rows[i].t_s - 5.0;
}

static void test_accumulator_faster(void **state)
{
    (void)state;
    double without = return_time_after_step(CONFIG_DIR "/thesis-900lb.ini", 1);
    double tube = return_time_after_step(CONFIG_DIR "/thesis-900lb-tube.ini", 2);
    print_message("return after +200 lb: %.2f s without, %.2f s with the 112 psig tube (algorithm 2)\n", without, tube);
    assert_true(tube < without - 1.0);
}

/* [controller] chatter_max_per_min reaches the firmware's supervisor: algorithm 2
 * with 2 counts of noise switches its compressor at the charge limit every few
 * ticks, so the product default latches the chatter fault and a limit of 0 does not. */
static uint16_t latched_after_noisy_run(const char *controller_extra)
{
    char text[1024];
    snprintf(text, sizeof text,
             "[config]\ninclude = %s/thesis-900lb-diaphragm.ini\n\n[sensors]\nnoise_counts = 2\n"
             "noise_seed = 3\n\n[controller]\n%s",
             CONFIG_DIR, controller_extra);
    static plant_config cfg;
    char err[1024];
    assert_int_equal(plant_config_load(write_file("chatter.ini", text), &cfg, err, sizeof err), 0);
    sim_options o = {.config = &cfg, .algorithm = 2, .end_s = 30.0};
    static sim_result res;
    assert_int_equal(sim_run(&o, &res, err, sizeof err), 0);
    return leveler_app_status()->latched_fault_bits;
}

/* plant_spring_volume_at (the replay's start volume, engine_run.c) against the
 * plant's own integration of dV2 = Ae dy: the platform lifted by filling the
 * spring, then dropped by venting it, under one load; the volume the plant
 * carries at each height is the one the function gives for that height. */
static void test_volume_at_height_follows_the_plant(void **state)
{
    (void)state;
    plant pl;
    plant_config cfg;
    plant_config_defaults(&cfg);
    cfg.plant.height_min_m = 0.0; /* no end stops (the thesis file's hold the platform at 17.61 in): */
    cfg.plant.height_max_m = 1.0; /* the relation is the free spring's */
    plant_init(&pl, &cfg.plant);
    const double load = 900.0 * LBF;
    set(&pl, 1, 1, 0, 0, load);
    double worst = 0.0, ymin = 1.0, ymax = 0.0;
    for (int k = 0; k < 3000; k++) {
        if (k == 1500)
            set(&pl, 0, 1, 1, 0, load);
        plant_step(&pl, 0.01);
        double v = plant_spring_volume_at(&cfg.plant, load, pl.x[PLANT_X_Y]);
        worst = fmax(worst, fabs(v - pl.x[PLANT_X_V2]));
        ymin = fmin(ymin, pl.x[PLANT_X_Y]);
        ymax = fmax(ymax, pl.x[PLANT_X_Y]);
    }
    assert_true(ymax - ymin > 0.5 * IN); /* the platform did travel */
    /* RK4 on a volume of 4.4e-3 m3: agreement to round-off, over a travel of inches */
    assert_true(worst < 1e-12);
    double y0 = cfg.plant.init_height_m;
    assert_true(plant_spring_volume_at(&cfg.plant, load, y0) == cfg.plant.spring_volume0_m3);
    /* an inch higher holds about Ae x 1 in more (Ae ~ 100 in^2 at 900 lb) */
    double dv = plant_spring_volume_at(&cfg.plant, load, y0 + IN) - cfg.plant.spring_volume0_m3;
    double ae = plant_effective_area_m2(&cfg.plant, load, y0 + 0.5 * IN);
    assert_true(fabs(dv - ae * IN) < 1e-12);
}

/* A closed spring that lifts the platform onto its top stop and stays there
 * for 20 s: the spring keeps the volume it has at the stop's height
 * (plant_spring_volume_at) and its polytrope P2 V2^(Z n), and both steps used
 * by the tools (the diagnosis's 5 ms, the truths' 2.5 ms) agree. A clamp after
 * each step let the spring swell on the stop by a step-size dependent amount. */
static void hold_on_top_stop(double h, double *v2, double *p2)
{
    plant pl;
    plant_config cfg;
    thesis_plant(&pl, &cfg);
    pl.x[PLANT_X_P_SPRING] = 100.0 * PSI; /* well above the 900 lb upper line */
    set(&pl, 0, 0, 0, 0, 900.0 * LBF);
    double inv0 = pl.x[PLANT_X_P_SPRING] * pow(pl.x[PLANT_X_V2], pl.zn);
    int steps = (int)(20.0 / h + 0.5);
    for (int i = 0; i < steps; i++)
        plant_step(&pl, h);
    assert_true(pl.x[PLANT_X_Y] == cfg.plant.height_max_m);
    double at_stop = plant_spring_volume_at(&cfg.plant, 900.0 * LBF, cfg.plant.height_max_m);
    assert_true(fabs(pl.x[PLANT_X_V2] / at_stop - 1.0) < 1e-9);
    double inv = pl.x[PLANT_X_P_SPRING] * pow(pl.x[PLANT_X_V2], pl.zn);
    assert_true(fabs(inv / inv0 - 1.0) < 1e-7);
    *v2 = pl.x[PLANT_X_V2];
    *p2 = pl.x[PLANT_X_P_SPRING];
}

static void test_end_stop_holds_the_spring(void **state)
{
    (void)state;
    double v5, p5, v25, p25;
    hold_on_top_stop(0.005, &v5, &p5);
    hold_on_top_stop(0.0025, &v25, &p25);
    assert_true(fabs(v5 / v25 - 1.0) < 1e-9);
    assert_true(fabs(p5 - p25) < 1.0); /* Pa, on about 700 kPa */
}

static void test_config_chatter_limit(void **state)
{
    (void)state;
    const uint16_t chatter = (uint16_t)(1u << (LEVELER_FAULT_CHATTER - 1));
    assert_true(latched_after_noisy_run("") & chatter);
    assert_false(latched_after_noisy_run("chatter_max_per_min = 0\n") & chatter);
    expect_error("[controller]\nchatter_max_per_min = 601\n", "chatter_max_per_min", NULL);
}

static int setup(void **state)
{
    (void)state;
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_conservation_closed),
        cmocka_unit_test(test_equalisation),
        cmocka_unit_test(test_valve_continuity),
        cmocka_unit_test(test_orifice_table),
        cmocka_unit_test(test_rk4_order),
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_config_units_and_include),
        cmocka_unit_test(test_schedule_rule_and_file_errors),
        cmocka_unit_test(test_schedule_manual_rows),
        cmocka_unit_test(test_program_controller_900),
        cmocka_unit_test(test_firmware_equals_program_900),
        cmocka_unit_test(test_firmware_equals_program_1000),
        cmocka_unit_test(test_accumulator_faster),
        cmocka_unit_test(test_config_chatter_limit),
        cmocka_unit_test(test_volume_at_height_follows_the_plant),
        cmocka_unit_test(test_end_stop_holds_the_spring),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
