/* Controller benchmark: the scenario suite and the figures of a run (ctlbench.h). */
#include "ctlbench.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "leveler/commissioning.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "leveler/status.h"

#define TICK_S 0.01
#define THESIS_END_S 95.0   /* 60 s after the removal at 35 s, to see whether it settles */
#define REST_SETTLE_S 60.0  /* the return before the scored rest */
/* A load change throws the platform about for up to a second before any valve
 * acts; entering the band in that time is the load's doing, not a return. */
#define LOAD_MOTION_S 1.0

static const char *const THESIS_CONFIGS[] = {"thesis-900lb",  "thesis-900lb-tube",  "thesis-900lb-diaphragm",
                                             "thesis-1000lb", "thesis-1000lb-tube", "thesis-1000lb-diaphragm"};
static const double LOAD_900_N = 900.0 * PLANT_N_PER_LBF;
static const double STEP_N = 200.0 * PLANT_N_PER_LBF;

static void name_scenario(ctlbench_scenario *sc, const char *name, const char *config)
{
    snprintf(sc->name, sizeof sc->name, "%s", name);
    snprintf(sc->config, sizeof sc->config, "%s.ini", config);
}

/* The thesis procedure: base load, +200 lb at 5 s, removed at 35 s. */
static void thesis(ctlbench_scenario *sc, const char *config, double base_lbf)
{
    memset(sc, 0, sizeof *sc);
    name_scenario(sc, config, config);
    sc->kind = CTLBENCH_THESIS;
    double base = base_lbf * PLANT_N_PER_LBF;
    sc->steps[0] = (sim_load_step){.t_s = 0.0, .load_n = base};
    sc->steps[1] = (sim_load_step){.t_s = 5.0, .load_n = base + STEP_N};
    sc->steps[2] = (sim_load_step){.t_s = 35.0, .load_n = base};
    sc->step_count = 3;
    sc->end_s = THESIS_END_S;
}

void ctlbench_thesis_rest(ctlbench_scenario *sc, const char *name, const char *config_file, double noise,
                          uint32_t seed, double rest_s)
{
    memset(sc, 0, sizeof *sc);
    snprintf(sc->name, sizeof sc->name, "%s", name);
    snprintf(sc->config, sizeof sc->config, "%s", config_file);
    sc->kind = CTLBENCH_REST;
    sc->noise_counts = noise;
    sc->noise_seed = seed;
    sc->steps[0] = (sim_load_step){.t_s = 0.0, .load_n = LOAD_900_N};
    sc->steps[1] = (sim_load_step){.t_s = 5.0, .load_n = LOAD_900_N + STEP_N};
    sc->steps[2] = (sim_load_step){.t_s = 35.0, .load_n = LOAD_900_N};
    sc->step_count = 3;
    sc->rest_from_s = 35.0 + REST_SETTLE_S;
    sc->rest_to_s = sc->rest_from_s + rest_s;
    sc->end_s = sc->rest_to_s;
}

void ctlbench_thesis_commissioned(ctlbench_scenario *sc, const char *name, const char *config_file, double noise,
                                  uint32_t seed)
{
    double t0 = LEVELER_COMMISSION_MAX_MS / 1000.0;
    memset(sc, 0, sizeof *sc);
    snprintf(sc->name, sizeof sc->name, "%s", name);
    snprintf(sc->config, sizeof sc->config, "%s", config_file);
    sc->kind = CTLBENCH_THESIS;
    sc->noise_counts = noise;
    sc->noise_seed = seed;
    sc->commission = true;
    sc->steps[0] = (sim_load_step){.t_s = 0.0, .load_n = LOAD_900_N};
    sc->steps[1] = (sim_load_step){.t_s = t0 + 5.0, .load_n = LOAD_900_N + STEP_N};
    sc->steps[2] = (sim_load_step){.t_s = t0 + 35.0, .load_n = LOAD_900_N};
    sc->step_count = 3;
    sc->end_s = t0 + 35.0 + REST_SETTLE_S;
}

/* A config's name in scenario names: without the thesis- prefix the suite's own carry. */
static const char *short_name(const char *config)
{
    return strncmp(config, "thesis-", 7) == 0 ? config + 7 : config;
}

/* The thesis steps then rest_s of rest (the hunting case), seed 100 + noise. */
static void rest(ctlbench_scenario *sc, const char *config, double noise, double rest_s)
{
    char name[CTLBENCH_NAME_MAX], file[CTLBENCH_NAME_MAX];
    snprintf(name, sizeof name, "rest-%s-noise%g", short_name(config), noise);
    snprintf(file, sizeof file, "%s.ini", config);
    ctlbench_thesis_rest(sc, name, file, noise, 100u + (uint32_t)noise, rest_s);
}

/* Deterministic uniform in [0, 1) (xorshift32). */
static double uniform(uint32_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return (double)*s / 4294967296.0;
}

/* Load steps of 50..300 lb at 20..60 s intervals, the load kept within
 * 900..1200 lb (the thesis's hysteresis bands), 1 count of noise. */
static void random_steps(ctlbench_scenario *sc, const char *config, uint32_t seed, size_t steps)
{
    memset(sc, 0, sizeof *sc);
    char name[CTLBENCH_NAME_MAX];
    snprintf(name, sizeof name, "random-%s", short_name(config));
    name_scenario(sc, name, config);
    sc->kind = CTLBENCH_RANDOM;
    sc->noise_counts = 1.0;
    sc->noise_seed = seed;
    uint32_t s = seed;
    double load_lbf = 900.0, t = 0.0;
    sc->steps[0] = (sim_load_step){.t_s = 0.0, .load_n = load_lbf * PLANT_N_PER_LBF};
    for (size_t i = 1; i <= steps && i < CTLBENCH_MAX_STEPS; i++) {
        t += (i == 1) ? 5.0 : 20.0 + 40.0 * uniform(&s);
        double mag = 50.0 + 250.0 * uniform(&s);
        double sign = uniform(&s) < 0.5 ? -1.0 : 1.0;
        if (load_lbf + sign * mag < 900.0 || load_lbf + sign * mag > 1200.0)
            sign = -sign;
        if (load_lbf + sign * mag < 900.0 || load_lbf + sign * mag > 1200.0)
            mag = sign > 0 ? 1200.0 - load_lbf : load_lbf - 900.0;
        load_lbf += sign * round(mag);
        sc->steps[i] = (sim_load_step){.t_s = round(t), .load_n = load_lbf * PLANT_N_PER_LBF};
        sc->step_count = i + 1;
    }
    sc->end_s = sc->steps[sc->step_count - 1].t_s + 60.0;
}

size_t ctlbench_suite_for(const char *config, bool short_suite, uint32_t random_seed, ctlbench_scenario *out,
                          size_t cap)
{
    size_t n = 0;
    if (cap < 3)
        return 0;
    thesis(&out[n++], config, 900.0);
    rest(&out[n++], config, 2.0, short_suite ? 120.0 : 600.0);
    if (!short_suite)
        random_steps(&out[n++], config, random_seed, 24);
    return n;
}

size_t ctlbench_suite(bool short_suite, uint32_t random_seed, ctlbench_scenario *out, size_t cap)
{
    static const double noises[] = {0.0, 1.0, 2.0, 4.0};
    size_t n = 0;
    if (short_suite) {
        if (cap >= 4) {
            thesis(&out[n++], "thesis-900lb", 900.0);
            thesis(&out[n++], "thesis-900lb-diaphragm", 900.0);
            rest(&out[n++], "thesis-900lb", 2.0, 120.0);
            rest(&out[n++], "thesis-900lb-diaphragm", 2.0, 120.0);
        }
        return n;
    }
    for (size_t i = 0; i < sizeof THESIS_CONFIGS / sizeof THESIS_CONFIGS[0] && n < cap; i++)
        thesis(&out[n++], THESIS_CONFIGS[i], strstr(THESIS_CONFIGS[i], "1000") ? 1000.0 : 900.0);
    for (size_t i = 0; i < 4 && n + 1 < cap; i++) {
        rest(&out[n++], "thesis-900lb", noises[i], 600.0);
        rest(&out[n++], "thesis-900lb-diaphragm", noises[i], 600.0);
    }
    if (n < cap)
        random_steps(&out[n++], "thesis-900lb", random_seed, 24);
    if (n < cap)
        random_steps(&out[n++], "thesis-900lb-diaphragm", random_seed, 24);
    return n;
}

size_t ctlbench_rows_needed(const ctlbench_scenario *sc, size_t count)
{
    double end = 0.0;
    for (size_t i = 0; i < count; i++)
        end = sc[i].end_s > end ? sc[i].end_s : end;
    return (size_t)llround(end / TICK_S) + 2;
}

/* The outputs of a log row as bits (the run-log's actuator columns, in one place). */
static unsigned row_bits(const runlog_row *r)
{
    return (unsigned)((r->compressor > 0) | (r->spring_valve > 0) << 1 | (r->vent_valve > 0) << 2 | (r->acc_valve > 0) << 3);
}

typedef struct {
    double lower_m, upper_m;
} band;

static double outside_m(const band *b, double h)
{
    if (h < b->lower_m)
        return b->lower_m - h;
    return h > b->upper_m ? h - b->upper_m : 0.0;
}

/* Figures of one load step over rows [i0, i1). */
static void score_step(const runlog_row *rows, size_t i0, size_t i1, const band *b, ctlbench_step *st)
{
    double t0 = st->t_s;
    bool out_before = false, entered = false;
    size_t last_entry = i0;
    for (size_t i = i0; i < i1; i++) {
        double off = outside_m(b, rows[i].true_height_m);
        if (off > 0.0) {
            st->left_band = true;
            out_before = true;
            if (entered && off > st->overshoot_m)
                st->overshoot_m = off;
        } else if (out_before) {
            out_before = false;
            last_entry = i;
            if (!entered && rows[i].t_s >= t0 + LOAD_MOTION_S) {
                entered = true;
                st->first_entry_s = rows[i].t_s - t0;
            }
        }
        if (i > 0 && row_bits(&rows[i]) != row_bits(&rows[i - 1]))
            st->switchings++;
    }
    st->settled = i1 > i0 && outside_m(b, rows[i1 - 1].true_height_m) == 0.0;
    if (!st->left_band)
        st->return_s = 0.0;
    else if (st->settled)
        st->return_s = rows[last_entry].t_s - t0;
    else
        st->return_s = rows[i1 - 1].t_s - t0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static size_t row_at(double t_s, size_t rows)
{
    size_t i = (size_t)llround(t_s / TICK_S);
    return i < rows ? i : rows;
}

void ctlbench_aggregate(ctlbench_metrics *m)
{
    double returns[CTLBENCH_MAX_STEPS];
    unsigned sw = 0;
    m->return_worst_s = m->overshoot_max_m = 0.0;
    m->unsettled_steps = 0;
    for (size_t k = 0; k < m->step_count; k++) {
        const ctlbench_step *st = &m->step[k];
        returns[k] = st->return_s;
        m->return_worst_s = st->return_s > m->return_worst_s ? st->return_s : m->return_worst_s;
        m->overshoot_max_m = st->overshoot_m > m->overshoot_max_m ? st->overshoot_m : m->overshoot_max_m;
        m->unsettled_steps += st->settled ? 0u : 1u;
        sw += st->switchings;
    }
    qsort(returns, m->step_count, sizeof returns[0], cmp_double);
    size_t k = m->step_count;
    m->return_median_s = k == 0 ? 0.0 : (k % 2 ? returns[k / 2] : 0.5 * (returns[k / 2 - 1] + returns[k / 2]));
    m->switchings_per_step = k == 0 ? 0.0 : (double)sw / (double)k;
}

static void score_steps(const ctlbench_scenario *sc, const runlog_row *rows, size_t n, const band *b,
                        ctlbench_metrics *m)
{
    m->step_count = sc->step_count - 1;
    for (size_t s = 1; s < sc->step_count; s++) {
        ctlbench_step *st = &m->step[s - 1];
        st->t_s = sc->steps[s].t_s;
        st->load_change_n = sc->steps[s].load_n - sc->steps[s - 1].load_n;
        double t_end = s + 1 < sc->step_count ? sc->steps[s + 1].t_s : sc->end_s + TICK_S;
        score_step(rows, row_at(st->t_s, n), row_at(t_end, n), b, st);
    }
    ctlbench_aggregate(m);
}

/* The first row at or after the last step's back-to-stay with the spring and vent valves shut: the
 * return's own close comes a few ticks after the platform is back in the band. n when it never settled. */
static size_t return_over(const runlog_row *rows, size_t n, const ctlbench_metrics *m)
{
    if (m->step_count == 0)
        return 0;
    const ctlbench_step *last = &m->step[m->step_count - 1];
    if (!last->settled)
        return n;
    size_t i = row_at(last->t_s + last->return_s, n);
    while (i < n && (rows[i].spring_valve > 0 || rows[i].vent_valve > 0))
        i++;
    return i;
}

void ctlbench_rest_split(const ctlbench_scenario *sc, const runlog_row *rows, size_t n, ctlbench_metrics *m)
{
    m->rest_returning = m->rest_recharge = m->rest_moves = 0;
    if (sc->kind != CTLBENCH_REST)
        return;
    size_t over = return_over(rows, n, m);
    for (size_t i = 1; i < n; i++) {
        const runlog_row *r = &rows[i], *p = &rows[i - 1];
        if (r->t_s < sc->rest_from_s || r->t_s >= sc->rest_to_s || row_bits(r) == row_bits(p))
            continue;
        bool valves = (r->spring_valve > 0) != (p->spring_valve > 0) || (r->vent_valve > 0) != (p->vent_valve > 0);
        if (i <= over)
            m->rest_returning++;
        else if (valves)
            m->rest_moves++;
        else
            m->rest_recharge++;
    }
}

/* Run-wide figures: switchings, compressor time, air out of the vent, time outside, the rest window. */
static void score_run(const ctlbench_scenario *sc, const runlog_row *rows, size_t n, const band *b, const plant *pl,
                      ctlbench_metrics *m)
{
    double cda = pl->p.vent_valve_cd * pl->vent_valve_area_m2;
    m->rest_switchings_per_min = NAN;
    for (size_t i = 0; i < n; i++) {
        const runlog_row *r = &rows[i];
        bool in_rest = sc->kind == CTLBENCH_REST && r->t_s >= sc->rest_from_s && r->t_s < sc->rest_to_s;
        bool switched = i > 0 && row_bits(r) != row_bits(&rows[i - 1]);
        m->switchings += switched;
        m->compressor_on_s += r->compressor > 0 ? TICK_S : 0.0;
        if (r->vent_valve > 0 && r->true_p_pipe_pa > pl->p.ambient_pa)
            m->vented_kg += plant_orifice_flow(pl, cda, r->true_p_pipe_pa, pl->p.ambient_pa) * TICK_S;
        double off = outside_m(b, r->true_height_m);
        m->outside_s += off > 0.0 ? TICK_S : 0.0;
        if (in_rest) {
            m->rest_switchings += switched;
            m->rest_outside_s += off > 0.0 ? TICK_S : 0.0;
        }
    }
    if (sc->kind == CTLBENCH_REST)
        m->rest_switchings_per_min = m->rest_switchings / ((sc->rest_to_s - sc->rest_from_s) / 60.0);
}

int ctlbench_config(const ctlbench_scenario *sc, int algorithm, const char *configs_dir, plant_config *cfg,
                    char *err, size_t err_len)
{
    char path[PLANT_PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", configs_dir, sc->config);
    if (plant_config_load(path, cfg, err, err_len) != 0)
        return -1;
    /* The end stops are the config's ([platform] height_min / height_max: the
     * thesis configs set the spring's travel, 13.76..17.61 in). */
    cfg->sensors.noise_counts = sc->noise_counts;
    cfg->sensors.noise_seed = sc->noise_seed;
    /* Algorithms 1 and 2 run as the thesis has them: no chatter fault to stop their hunting. */
    if (algorithm != 3)
        cfg->chatter_max_per_min = 0;
    return 0;
}

void ctlbench_score(const ctlbench_scenario *sc, const plant_config *cfg, const runlog_row *rows, const sim_result *res,
                    int algorithm, ctlbench_metrics *m)
{
    memset(m, 0, sizeof *m);
    m->algorithm = algorithm;
    band b = {cfg->band_lower_m, cfg->band_upper_m};
    score_steps(sc, rows, res->rows, &b, m);
    score_run(sc, rows, res->rows, &b, &res->final_plant, m);
    ctlbench_rest_split(sc, rows, res->rows, m);
    m->latched_faults = leveler_app_status()->latched_fault_bits;
}

int ctlbench_simulate(const ctlbench_scenario *sc, const sim_options *so, const char *log_path, sim_result *res,
                      char *err, size_t err_len)
{
    runlog *rl = NULL;
    if (log_path) {
        runlog_options lo = {.path = log_path, .config_name = sc->name, .source = "sim"};
        if (!(rl = runlog_open(&lo, err, err_len)))
            return -1;
    }
    sim_options o = *so;
    o.log = rl;
    int rc = sim_run(&o, res, err, err_len);
    if (rl && runlog_close(rl) != 0 && rc == 0) {
        snprintf(err, err_len, "%s: close failed", log_path);
        rc = -1;
    }
    return rc;
}

int ctlbench_run(const ctlbench_scenario *sc, int algorithm, const char *configs_dir, const char *log_path,
                 runlog_row *rows, size_t rows_cap, ctlbench_metrics *m, char *err, size_t err_len)
{
    static plant_config cfg;
    if (ctlbench_config(sc, algorithm, configs_dir, &cfg, err, err_len) != 0)
        return -1;
    sim_options so = {.config = &cfg, .algorithm = algorithm, .steps = sc->steps, .step_count = sc->step_count,
                      .end_s = sc->end_s, .rows = rows, .rows_cap = rows_cap, .commission = sc->commission};
    static sim_result res;
    if (ctlbench_simulate(sc, &so, log_path, &res, err, err_len) != 0)
        return -1;
    ctlbench_score(sc, &cfg, rows, &res, algorithm, m);
    return 0;
}
