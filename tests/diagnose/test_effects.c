/*
 * The effects library under the sanitizers (the ctypes build has none):
 * every candidate and truth variant integrates a charge/rest/vent cycle to
 * finite states; parameters at "off" give the nominal plant exactly; a
 * parameter outside its range is refused; the leak empties the spring and a
 * closed plant without effects keeps its mass. Pairs (two effects at once):
 * every pair of candidates and of truth variants stays finite; a pair whose
 * second effect is at its nominal values is the single effect bit for bit (in
 * either order); a leak with a sensor offset reads the leak-only plant plus the
 * offset; pairs that share a state or are one effect twice are refused.
 * (A lagging valve with a hose behind it: the pair stays finite only if the
 * hose takes what the valve passes, the models replacing flows in turn.)
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>

#include <cmocka.h>

#include "effects.h"

/* The blind test's truth variants (host_sim/blindtest/truth.c), tested here too. */
extern const plant_fx_model truth_catalogue[];
extern const int truth_catalogue_count;

enum { THERMAL = 1, AREA, FRICTION, VALVE_DYNAMICS, LINE_DELAY, LEAK, SENSOR_LAG };

static const plant_fx_model *candidate(int id)
{
    const plant_fx_model *m = plant_fx_find(plant_fx_catalogue, plant_fx_catalogue_count, id);
    assert_non_null(m);
    return m;
}

static const plant_fx_model *truth(int id)
{
    const plant_fx_model *m = plant_fx_find(truth_catalogue, truth_catalogue_count, id);
    assert_non_null(m);
    return m;
}

/* The thesis's 900 lb plant without its end stops (13.76..17.61 in): the free spring. */
static plant_params thesis(void)
{
    plant_config cfg;
    plant_config_defaults(&cfg);
    cfg.plant.height_min_m = 0.0;
    cfg.plant.height_max_m = 1.0;
    return cfg.plant;
}

/* 30 s: charge 8 s, rest 7 s, vent 6 s, rest; load 900 lb then 1100 lb from 5 s;
 * the inputs set every 10 ms, the plant advanced on ticks of dt_s (a divisor
 * of 10 ms) in this many RK4 substeps a tick. */
static void cycle_on(plant_fx *f, double dt_s, int substeps)
{
    int per = (int)lround(0.01 / dt_s);
    for (int k = 0; k < 3000; k++) {
        double t = k * 0.01;
        plant_inputs in = {t < 8.0, t < 8.0 || (t >= 15.0 && t < 21.0), t >= 15.0 && t < 21.0, false,
                           t < 5.0 ? 4003.4 : 4893.0};
        for (int j = 0; j < per; j++) {
            plant_fx_set_inputs(f, &in);
            plant_fx_advance(f, dt_s, substeps);
        }
    }
}

static void cycle_substeps(plant_fx *f, int substeps) { cycle_on(f, 0.01, substeps); }

static void cycle(plant_fx *f) { cycle_substeps(f, 10); }

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
    static const struct { bool truth; int id; double p[PLANT_FX_MAX_PARAMS]; } cases[] = {
        {false, THERMAL, {5.0}},
        {false, AREA, {2.0, -50.0, 0.03}},
        {false, FRICTION, {100.0, 50.0, 0.005}},
        {false, VALVE_DYNAMICS, {0.1, 0.2, 0.3}},
        {false, LINE_DELAY, {0.2, 3e-4}},
        {false, LINE_DELAY, {0.1, -1.5e-4, 1e-3, 0.01}}, /* stiffest corner: a big tube, a fast resistance */
        {false, LINE_DELAY, {0.0, 0.0, 0.0, 0.3, 1e-9, 5.0, 1.0, 0.0}}, /* the smallest hose, a wide fitting */
        {false, LINE_DELAY, {0.0, 0.0, 0.0, 0.3, 4e-4, 0.2, 1.0, 0.0}}, /* a big hose behind a narrow fitting */
        {false, LEAK, {2e-8}},
        {false, SENSOR_LAG, {0.3, 0.1, 2000.0, 0.001}},
        {true, THERMAL, {8.0, 300.0, 10.0}},
        {true, AREA, {0.05, -0.03, 0.0, 0.04, -0.05}},
        {true, FRICTION, {100.0, 60.0, 0.004, 2e5, 2000.0}},
        {true, VALVE_DYNAMICS, {0.1, 0.15, 0.3, 0.8}},
        {true, LINE_DELAY, {3e-4, 1e-8}},
        {true, LINE_DELAY, {1e-4, 1e-8, 0.6}},
        {true, LEAK, {1e-16}},
        {true, SENSOR_LAG, {0.3, 0.15, 0.1, 3000.0, 0.005, 5e-4}},
    };
    plant_params p = thesis();
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const plant_fx_model *m = cases[i].truth ? truth(cases[i].id) : candidate(cases[i].id);
        static plant_fx f;
        assert_int_equal(plant_fx_init(&f, &p, m, cases[i].p), 0);
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
    /* "off" values: thermal tau 0, area 0/0/0, friction 0/0, valve 0/0/lag 0,
     * line 0/0, leak 0, sensor 0/0/0/0 */
    static const struct { int id; double p[PLANT_FX_MAX_PARAMS]; } off[] = {
        {THERMAL, {0}}, {AREA, {0}}, {FRICTION, {0, 0, 0.005}},
        {VALVE_DYNAMICS, {0, 0, 0}}, {LINE_DELAY, {0, 0}}, {LEAK, {0}},
        {SENSOR_LAG, {0}},
    };
    for (size_t i = 0; i < sizeof off / sizeof off[0]; i++) {
        static plant_fx f;
        assert_int_equal(plant_fx_init(&f, &p, candidate(off[i].id), off[i].p), 0);
        cycle(&f);
        for (int s = 0; s < PLANT_NX; s++)
            assert_true(f.pl.x[s] == ref.x[s]);
    }
}

/* The line candidate's tube behind a resistance and the truth generator's tube
 * behind a laminar conductance are two codings of one physics: the same tube
 * (volume V, conductance G = V / (Z n R T tau)) must give the same plant. The
 * truth's RK4 at 400 substeps a tick is the reference; the candidate steps
 * the tube's exchange exactly (split from the config's 2 RK4 substeps) and
 * ends the cycle within 50 Pa of P1, 10 Pa of P2 and 5 um (measured: 22 Pa,
 * 2 um), however fast the resistance (tau 2 ms: RK4 needed 400 substeps). */
static void test_line_tube_matches_the_truth_tube(void **state)
{
    (void)state;
    plant_params p = thesis();
    static const double tube[3][2] = {{2e-4, 1e-8}, {2e-4, 1e-6}, {1e-3, 1e-8}}; /* m^3, kg/(s Pa) */
    for (int i = 0; i < 3; i++) {
        static plant_fx cand, tr;
        const double tp[PLANT_FX_MAX_PARAMS] = {tube[i][0], tube[i][1], 0.0};
        assert_int_equal(plant_fx_init(&tr, &p, truth(LINE_DELAY), tp), 0);
        const double cp[PLANT_FX_MAX_PARAMS] = {0.0, 0.0, tube[i][0], tube[i][0] / (tr.pl.zn * tr.pl.rt * tube[i][1])};
        assert_int_equal(plant_fx_init(&cand, &p, candidate(LINE_DELAY), cp), 0);
        cycle_substeps(&cand, 2);
        cycle_substeps(&tr, 400);
        assert_true(fabs(cand.pl.x[PLANT_X_P_PIPE] - tr.pl.x[PLANT_X_P_PIPE]) < 50.0);
        assert_true(fabs(cand.pl.x[PLANT_X_P_SPRING] - tr.pl.x[PLANT_X_P_SPRING]) < 10.0);
        assert_true(fabs(cand.pl.x[PLANT_X_Y] - tr.pl.x[PLANT_X_Y]) < 5e-6);
    }
}

/* A hose between the spring valve and the spring, behind the spring's fitting.
 * During a charge the air crosses the fitting, so the hose stands above the
 * spring; once the valves shut the two equalise, and a transducer on the hose
 * then reads the spring's pressure. A tiny hose behind a wide fitting is the
 * nominal plant (its volume is 0.5 % of the spring's). */
static void test_line_hose(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx nominal, hose, tiny;
    const double q[PLANT_FX_MAX_PARAMS] = {0, 0, 0, 0.3, 2e-4, 0.3, 1.0, 0};
    const double q_tiny[PLANT_FX_MAX_PARAMS] = {0, 0, 0, 0.3, 2e-5, 50.0, 0, 0};
    assert_int_equal(plant_fx_init(&nominal, &p, NULL, NULL), 0);
    assert_int_equal(plant_fx_init(&hose, &p, candidate(LINE_DELAY), q), 0);
    assert_int_equal(plant_fx_init(&tiny, &p, candidate(LINE_DELAY), q_tiny), 0);
    plant_inputs charge = {true, true, false, false, 4893.0};
    for (int k = 0; k < 300; k++) {
        plant_fx_set_inputs(&hose, &charge);
        plant_fx_advance(&hose, 0.01, 10);
    }
    assert_true(hose.xe[PLANT_FX_XE_AUX + 1] > hose.pl.x[PLANT_X_P_SPRING] + 1000.0);
    cycle(&hose);
    cycle(&tiny);
    cycle(&nominal);
    double ph = hose.xe[PLANT_FX_XE_AUX + 1], s[4];
    assert_true(fabs(ph - hose.pl.x[PLANT_X_P_SPRING]) < 10.0);
    plant_fx_sensed(&hose, s);
    assert_true(s[1] == ph);
    double p_spring_pa = nominal.pl.x[PLANT_X_P_SPRING];
    assert_true(fabs(tiny.pl.x[PLANT_X_P_SPRING] - p_spring_pa) < 1e-3 * p_spring_pa);
    assert_true(fabs(tiny.pl.x[PLANT_X_Y] - nominal.pl.x[PLANT_X_Y]) < 1e-3);
}

/* The hose's exchange is implicit and split from the RK4 substeps, half a tick
 * before and half after them. The reference is the same equations on 0.1 ms
 * ticks (the splitting's error vanishes). At the config's 10 ms ticks and 2
 * substeps, a small hose behind a wide fitting (explicit RK4 needed 40
 * substeps a tick), a big one behind a narrow fitting and one between end the
 * cycle within 6 um of the height and 15 Pa of P2 and of the hose (measured:
 * 2.8, 0.8, 4.1 um; 4.4, 3.5, 8.2 Pa). The explicit RK4 that stepped the hose
 * before (40 substeps a tick for the small one) ended 7 um and 128 Pa off. */
static void test_line_hose_split_converges(void **state)
{
    (void)state;
    plant_params p = thesis();
    static const double hoses[3][2] = {{2e-5, 4.0}, {4e-4, 0.3}, {1e-4, 1.0}}; /* m^3, fitting rel. */
    for (int i = 0; i < 3; i++) {
        static plant_fx coarse, fine;
        const double q[PLANT_FX_MAX_PARAMS] = {0, 0, 0, 0.3, hoses[i][0], hoses[i][1], 1.0, 0};
        assert_int_equal(plant_fx_init(&coarse, &p, candidate(LINE_DELAY), q), 0);
        assert_int_equal(plant_fx_init(&fine, &p, candidate(LINE_DELAY), q), 0);
        cycle_substeps(&coarse, 2);
        cycle_on(&fine, 1e-4, 1);
        assert_true(fabs(coarse.pl.x[PLANT_X_P_SPRING] - fine.pl.x[PLANT_X_P_SPRING]) < 15.0);
        assert_true(fabs(coarse.xe[PLANT_FX_XE_AUX + 1] - fine.xe[PLANT_FX_XE_AUX + 1]) < 15.0);
        assert_true(fabs(coarse.pl.x[PLANT_X_Y] - fine.pl.x[PLANT_X_Y]) < 6e-6);
    }
}

/* The valve candidate's delays act inside a tick: an opening delay of 105 ms
 * lands the plant between the 100 ms and 110 ms ones, near their middle (a
 * switch on the 10 ms tick grid would give one of the two): the fit sees a
 * slope, not a staircase. */
static void test_valve_delay_between_ticks(void **state)
{
    (void)state;
    plant_params p = thesis();
    const double delays[3] = {0.100, 0.105, 0.110};
    double p2[3];
    for (int i = 0; i < 3; i++) {
        static plant_fx f;
        const double q[PLANT_FX_MAX_PARAMS] = {delays[i], 0.0, 0.0};
        assert_int_equal(plant_fx_init(&f, &p, candidate(VALVE_DYNAMICS), q), 0);
        plant_inputs in = {true, true, false, false, 4893.0};
        for (int k = 0; k < 100; k++) {
            plant_fx_set_inputs(&f, &in);
            plant_fx_advance(&f, 0.01, 10);
        }
        p2[i] = f.pl.x[PLANT_X_P_SPRING];
    }
    double span = fabs(p2[0] - p2[2]);
    assert_true(span > 1.0); /* Pa, after 1 s: the 10 ms later opening shows */
    assert_true(fabs(p2[1] - 0.5 * (p2[0] + p2[2])) < 0.1 * span);
}

/* The spring's pressure over 3 s: spring valve open, the vent opened at 1.0 s
 * and shut at 2.0 s; at the times asked (s, on the 10 ms grid, in order). */
static void vent_pulse(const double q[PLANT_FX_MAX_PARAMS], const double *at, int n, double *p2)
{
    plant_params p = thesis();
    static plant_fx f;
    assert_int_equal(plant_fx_init(&f, &p, candidate(VALVE_DYNAMICS), q), 0);
    for (int k = 0, j = 0; k < 300 && j < n; k++) {
        double t = k * 0.01;
        while (j < n && fabs(t - at[j]) < 1e-9)
            p2[j++] = f.pl.x[PLANT_X_P_SPRING];
        plant_inputs in = {false, true, t >= 1.0 - 1e-9 && t < 2.0 - 1e-9, false, 4003.4};
        plant_fx_set_inputs(&f, &in);
        plant_fx_advance(&f, 0.01, 10);
    }
}

/* The valve candidate's opening lag tau: over a long opening a first-order
 * opening passes the air a pure delay of tau passes (what it lacks after the
 * opening it passes after the closing), so 0.6 s into the pulse it stands with
 * the delayed valve, not with the prompt one, and after the pulse with both;
 * it starts passing air before the delay's instant; tau -> 0 is the prompt valve. */
static void test_valve_opening_lag(void **state)
{
    (void)state;
    const double tau = 0.05, at[4] = {1.0, 1.02, 1.6, 2.6};
    const double prompt[PLANT_FX_MAX_PARAMS] = {0}, lag[PLANT_FX_MAX_PARAMS] = {0, 0, tau},
                 delay[PLANT_FX_MAX_PARAMS] = {tau, tau, 0}, tiny[PLANT_FX_MAX_PARAMS] = {0, 0, 1e-4};
    double pn[4], pl[4], pd[4], pt[4];
    vent_pulse(prompt, at, 4, pn);
    vent_pulse(lag, at, 4, pl);
    vent_pulse(delay, at, 4, pd);
    vent_pulse(tiny, at, 4, pt);
    double drop = pn[0] - pn[3];
    assert_true(drop > 5e3); /* Pa: the vent lets the spring down */
    assert_true(fabs(pl[2] - pd[2]) < 0.25 * fabs(pn[2] - pd[2]));
    assert_true(fabs(pl[3] - pn[3]) < 0.01 * drop && fabs(pl[3] - pd[3]) < 0.01 * drop);
    double early = pn[0] - pn[1]; /* what the prompt valve vents in 20 ms */
    assert_true(fabs(pd[1] - pd[0]) < 0.01 * early && pl[1] < pd[1] - 0.05 * early); /* venting before 50 ms */
    for (int j = 0; j < 4; j++)
        assert_true(fabs(pt[j] - pn[j]) < 1e-3 * drop);
}

/* The thermal candidate's warming wall and the first truth family's thermal
 * wall are two codings of one physics (the truth: the wall's capacity ratio c,
 * the candidate: the gas's share 1/c): the same plant to rounding. A warm
 * delivery (30 % above ambient) raises the shut pipe's pressure 30 % faster in
 * the first tick of a charge, the heat exchange being slow. */
static void test_thermal_extensions(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx cand, tr, cold, warm;
    const double tp[PLANT_FX_MAX_PARAMS] = {8.0, 300.0, 4.0};
    const double cp[PLANT_FX_MAX_PARAMS] = {8.0, 1.0 / 4.0, 300.0, 0.0};
    assert_int_equal(plant_fx_init(&tr, &p, truth(THERMAL), tp), 0);
    assert_int_equal(plant_fx_init(&cand, &p, candidate(THERMAL), cp), 0);
    cycle(&cand);
    cycle(&tr);
    assert_true(fabs(cand.pl.x[PLANT_X_P_SPRING] - tr.pl.x[PLANT_X_P_SPRING]) < 1e-6 * tr.pl.x[PLANT_X_P_SPRING]);
    assert_true(fabs(cand.pl.x[PLANT_X_Y] - tr.pl.x[PLANT_X_Y]) < 1e-9);
    assert_true(fabs(cand.xe[PLANT_FX_XE_TW] - tr.xe[PLANT_FX_XE_TW]) < 1e-6);
    const double qc[PLANT_FX_MAX_PARAMS] = {600.0, 0.0, 600.0, 0.0}, qw[PLANT_FX_MAX_PARAMS] = {600.0, 0.0, 600.0, 0.3};
    assert_int_equal(plant_fx_init(&cold, &p, candidate(THERMAL), qc), 0);
    assert_int_equal(plant_fx_init(&warm, &p, candidate(THERMAL), qw), 0);
    double p1 = cold.pl.x[PLANT_X_P_PIPE];
    plant_inputs in = {true, false, false, false, 4003.4};
    plant_fx_set_inputs(&cold, &in);
    plant_fx_set_inputs(&warm, &in);
    plant_fx_advance(&cold, 0.01, 10);
    plant_fx_advance(&warm, 0.01, 10);
    double rise = (warm.pl.x[PLANT_X_P_PIPE] - p1) / (cold.pl.x[PLANT_X_P_PIPE] - p1);
    assert_true(cold.pl.x[PLANT_X_P_PIPE] > p1);
    assert_true(fabs(rise - 1.3) < 0.013);
}

/* On an accumulator rig the thermal candidate with a fast exchange is the
 * isothermal plant (n = 1): the accumulator's flow belongs to the pipe's
 * energy balance like any other (it was left out once, and the candidate then
 * lost the pipe's air into a charging accumulator). */
static void test_thermal_isothermal_limit_with_accumulator(void **state)
{
    (void)state;
    plant_config cfg;
    char err[256];
    assert_int_equal(plant_config_load(CONFIG_DIR "/thesis-900lb-diaphragm.ini", &cfg, err, sizeof err), 0);
    plant_params p = cfg.plant;
    p.polytropic_n = 1.0;
    static plant_fx iso, fast;
    const double q[PLANT_FX_MAX_PARAMS] = {0.02};
    assert_int_equal(plant_fx_init(&iso, &p, NULL, NULL), 0);
    assert_int_equal(plant_fx_init(&fast, &p, candidate(THERMAL), q), 0);
    for (int k = 0; k < 600; k++) {
        double t = k * 0.01;
        /* the compressor charges the pipe and the accumulator, spring valve shut */
        plant_inputs in = {true, false, false, t >= 1.0, 4003.4};
        plant_fx_set_inputs(&iso, &in);
        plant_fx_set_inputs(&fast, &in);
        plant_fx_advance(&iso, 0.01, 10);
        plant_fx_advance(&fast, 0.01, 10);
    }
    assert_true(iso.pl.x[PLANT_X_P_ACC] > p.init_p_pipe_pa + 1e5); /* the accumulator did charge */
    assert_true(fabs(fast.pl.x[PLANT_X_P_PIPE] - iso.pl.x[PLANT_X_P_PIPE]) < 2e-3 * iso.pl.x[PLANT_X_P_PIPE]);
    assert_true(fabs(fast.pl.x[PLANT_X_P_ACC] - iso.pl.x[PLANT_X_P_ACC]) < 2e-3 * iso.pl.x[PLANT_X_P_ACC]);
}

static void test_out_of_range_is_refused(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx f;
    const double leak[PLANT_FX_MAX_PARAMS] = {-1e-8}, nan_tau[PLANT_FX_MAX_PARAMS] = {NAN};
    assert_int_equal(plant_fx_init(&f, &p, candidate(LEAK), leak), -1);
    assert_int_equal(plant_fx_init(&f, &p, candidate(THERMAL), nan_tau), -1);
    assert_null(plant_fx_find(plant_fx_catalogue, plant_fx_catalogue_count, 42)); /* unknown */
}

static void test_leak_empties_and_closed_plant_keeps_mass(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx none, leak;
    const double k[PLANT_FX_MAX_PARAMS] = {1e-16};
    assert_int_equal(plant_fx_init(&none, &p, NULL, NULL), 0);
    assert_int_equal(plant_fx_init(&leak, &p, truth(LEAK), k), 0);
    plant_inputs in = {false, false, false, false, 4003.4};
    plant_fx_set_inputs(&none, &in);
    plant_fx_set_inputs(&leak, &in);
    /* settle the initial velocity of the program's state, then watch 20 s */
    for (int k = 0; k < 500; k++) {
        plant_fx_advance(&none, 0.01, 10);
        plant_fx_advance(&leak, 0.01, 10);
    }
    double p_none = none.pl.x[PLANT_X_P_SPRING], p_leak = leak.pl.x[PLANT_X_P_SPRING];
    for (int k = 0; k < 2000; k++) {
        plant_fx_advance(&none, 0.01, 10);
        plant_fx_advance(&leak, 0.01, 10);
    }
    assert_true(fabs(none.pl.x[PLANT_X_P_SPRING] - p_none) < 1.0);   /* Pa: nothing flows */
    assert_true(leak.pl.x[PLANT_X_P_SPRING] < p_leak - 1000.0);       /* the leak lost pressure */
}


/* Every parameter set here is "on"; per id, for pairs. */
static const double *on_params(bool is_truth, int id)
{
    static const double cand[8][PLANT_FX_MAX_PARAMS] = {
        {0}, {5.0}, {2.0, -50.0, 0.03}, {100.0, 50.0, 0.005}, {0.1, 0.2, 0.3},
        {0.1, -1.5e-4, 2e-4, 0.5, 1e-4, 0.5, 1.0, 1.0}, {2e-8}, {0.3, 0.1, 2000.0, 0.001}};
    static const double tru[8][PLANT_FX_MAX_PARAMS] = {
        {0}, {8.0, 300.0, 10.0}, {0.05, -0.03, 0.0, 0.04, -0.05}, {100.0, 60.0, 0.004, 2e5, 2000.0},
        {0.1, 0.15, 0.3, 0.8}, {1e-4, 1e-8, 0.6}, {1e-16}, {0.3, 0.15, 0.1, 3000.0, 0.005, 5e-4}};
    return is_truth ? tru[id] : cand[id];
}

static void test_every_pair_stays_finite(void **state)
{
    (void)state;
    plant_params p = thesis();
    for (int t = 0; t < 2; t++)
        for (int a = THERMAL; a <= SENSOR_LAG; a++)
            for (int b = a + 1; b <= SENSOR_LAG; b++) {
                const plant_fx_model *m[2] = {t ? truth(a) : candidate(a), t ? truth(b) : candidate(b)};
                double q[2 * PLANT_FX_MAX_PARAMS];
                memcpy(q, on_params(t, a), PLANT_FX_MAX_PARAMS * sizeof q[0]);
                memcpy(q + PLANT_FX_MAX_PARAMS, on_params(t, b), PLANT_FX_MAX_PARAMS * sizeof q[0]);
                static plant_fx f;
                assert_int_equal(plant_fx_init_models(&f, &p, 2, m, q), 0);
                cycle(&f);
                assert_finite(&f);
            }
}

/* Same plant state and same sensed values, bit for bit. */
static void assert_same(const plant_fx *a, const plant_fx *b)
{
    for (int s = 0; s < PLANT_NX; s++)
        assert_true(a->pl.x[s] == b->pl.x[s]);
    double sa[4], sb[4];
    plant_fx_sensed(a, sa);
    plant_fx_sensed(b, sb);
    for (int c = 0; c < 4; c++)
        assert_true(sa[c] == sb[c] || (isnan(sa[c]) && isnan(sb[c])));
}

/* A pair with one effect "on" and the other at its nominal ("off") values is
 * the single "on" effect, whichever comes first in the call. */
static void test_pair_with_a_nominal_second_is_the_single(void **state)
{
    (void)state;
    static const double off[8][PLANT_FX_MAX_PARAMS] = {
        {0}, {0}, {0}, {0, 0, 0.005}, {0, 0, 0}, {0, 0}, {0}, {0}};
    plant_params p = thesis();
    for (int a = THERMAL; a <= SENSOR_LAG; a++)
        for (int b = THERMAL; b <= SENSOR_LAG; b++) {
            if (a == b)
                continue;
            static plant_fx single, pair;
            assert_int_equal(plant_fx_init(&single, &p, candidate(a), on_params(false, a)), 0);
            const plant_fx_model *m[2] = {candidate(b), candidate(a)};
            double q[2 * PLANT_FX_MAX_PARAMS];
            memcpy(q, off[b], PLANT_FX_MAX_PARAMS * sizeof q[0]);
            memcpy(q + PLANT_FX_MAX_PARAMS, on_params(false, a), PLANT_FX_MAX_PARAMS * sizeof q[0]);
            assert_int_equal(plant_fx_init_models(&pair, &p, 2, m, q), 0);
            cycle(&single);
            cycle(&pair);
            assert_same(&single, &pair);
        }
}

/* A leak and a sensor's P2 offset act independently: the pair reads the
 * leak-only plant's P2 plus the offset, and the leak has lost air against the
 * nominal plant (so the pair did act twice): the platform sits lower (its
 * pressure is held by the load). */
static void test_leak_and_sensor_offset_add_up(void **state)
{
    (void)state;
    plant_params p = thesis();
    const double offset_pa = 2500.0;
    static plant_fx nominal, leak, pair;
    const double k[PLANT_FX_MAX_PARAMS] = {2e-8};
    double q[2 * PLANT_FX_MAX_PARAMS] = {0};
    q[0] = 2e-8;
    q[PLANT_FX_MAX_PARAMS + 2] = offset_pa;
    const plant_fx_model *m[2] = {candidate(LEAK), candidate(SENSOR_LAG)};
    assert_int_equal(plant_fx_init(&nominal, &p, NULL, NULL), 0);
    assert_int_equal(plant_fx_init(&leak, &p, candidate(LEAK), k), 0);
    assert_int_equal(plant_fx_init_models(&pair, &p, 2, m, q), 0);
    cycle(&nominal);
    cycle(&leak);
    cycle(&pair);
    double s_nom[4], s_leak[4], s_pair[4];
    plant_fx_sensed(&nominal, s_nom);
    plant_fx_sensed(&leak, s_leak);
    plant_fx_sensed(&pair, s_pair);
    assert_true(s_pair[1] == s_leak[1] + offset_pa);
    assert_true(s_pair[0] == s_leak[0]);
    assert_true(s_leak[0] < s_nom[0] - 1e-3);
}

static void test_pairs_that_cannot_run_together_are_refused(void **state)
{
    (void)state;
    plant_params p = thesis();
    static plant_fx f;
    const plant_fx_model *same[2] = {candidate(LEAK), candidate(LEAK)};
    const plant_fx_model *two_sensors[2] = {candidate(SENSOR_LAG), truth(SENSOR_LAG)};
    const plant_fx_model *two_tubes[2] = {candidate(LINE_DELAY), truth(LINE_DELAY)};
    const plant_fx_model *three[3] = {candidate(LEAK), candidate(AREA), candidate(THERMAL)};
    assert_int_equal(plant_fx_init_models(&f, &p, 2, same, NULL), PLANT_FX_PAIR_REFUSED);
    assert_int_equal(plant_fx_init_models(&f, &p, 2, two_sensors, NULL), PLANT_FX_PAIR_REFUSED);
    assert_int_equal(plant_fx_init_models(&f, &p, 2, two_tubes, NULL), PLANT_FX_PAIR_REFUSED);
    assert_int_equal(plant_fx_init_models(&f, &p, 3, three, NULL), PLANT_FX_PAIR_REFUSED);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_kind_stays_finite),
        cmocka_unit_test(test_off_is_the_nominal_plant),
        cmocka_unit_test(test_out_of_range_is_refused),
        cmocka_unit_test(test_line_tube_matches_the_truth_tube),
        cmocka_unit_test(test_line_hose),
        cmocka_unit_test(test_line_hose_split_converges),
        cmocka_unit_test(test_valve_delay_between_ticks),
        cmocka_unit_test(test_valve_opening_lag),
        cmocka_unit_test(test_thermal_extensions),
        cmocka_unit_test(test_thermal_isothermal_limit_with_accumulator),
        cmocka_unit_test(test_leak_empties_and_closed_plant_keeps_mass),
        cmocka_unit_test(test_every_pair_stays_finite),
        cmocka_unit_test(test_pair_with_a_nominal_second_is_the_single),
        cmocka_unit_test(test_leak_and_sensor_offset_add_up),
        cmocka_unit_test(test_pairs_that_cannot_run_together_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
