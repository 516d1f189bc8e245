/*
 * leveler-ctlbench: the controller scorecard. Runs the scenario suite
 * (ctlbench.h) with algorithms 1, 2 and 3, prints a table per scenario and
 * the targets with algorithm 3 beside algorithms 1 and 2 of the same
 * run, and writes per scenario a PNG (python -m leveler.ctlbench_plot over
 * the run logs) and scorecard.json.
 *
 *   leveler-ctlbench [--out DIR] [--configs DIR] [--short] [--no-plots] [--random-seed S]
 *
 * Exit status: 0 done (targets missed are reported, not failed), 1 a run failed, 2 bad input.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cjson/cJSON.h>

#include "cli.h"
#include "ctlbench.h"
#include "ctlbench_limit.h"
#include "leveler/version.h"
#include "pyrun.h"

#ifndef LEVELER_SOURCE_DIR
#define LEVELER_SOURCE_DIR "."
#endif

#define MAX_SCENARIOS 32
#define IN_PER_M (1.0 / PLANT_M_PER_IN)

typedef struct {
    ctlbench_scenario sc;
    ctlbench_metrics m[4]; /* algorithms 1, 2, 3 and the limit */
    ctlbench_limit_moves limit;
} scored;

#define LIMIT 3 /* m[LIMIT]: the limit's run */

/* Algorithm 3's return over the limit's on one step; NAN when the limit never left the band. */
static double ratio_to_limit(const ctlbench_step *a3, const ctlbench_step *lim)
{
    if (lim->return_s <= 0.0)
        return a3->return_s <= 0.0 ? 1.0 : NAN;
    return a3->return_s / lim->return_s;
}

/* Median and worst of algorithm 3's per-step ratios to the limit (steps where both are defined). */
static void ratios(const ctlbench_metrics *m, double *median, double *worst)
{
    double r[CTLBENCH_MAX_STEPS];
    size_t k = 0;
    *worst = NAN;
    for (size_t i = 0; i < m[2].step_count; i++) {
        double v = ratio_to_limit(&m[2].step[i], &m[LIMIT].step[i]);
        if (isnan(v))
            continue;
        r[k++] = v;
        *worst = isnan(*worst) || v > *worst ? v : *worst;
    }
    for (size_t i = 1; i < k; i++)
        for (size_t j = i; j > 0 && r[j - 1] > r[j]; j--) {
            double t = r[j];
            r[j] = r[j - 1];
            r[j - 1] = t;
        }
    *median = k == 0 ? NAN : (k % 2 ? r[k / 2] : 0.5 * (r[k / 2 - 1] + r[k / 2]));
}

static void row3(const char *label, const char *fmt, double a, double b, double c, double d)
{
    char buf[4][32];
    const double v[4] = {a, b, c, d};
    for (int i = 0; i < 4; i++) {
        if (isnan(v[i]))
            snprintf(buf[i], sizeof buf[i], "-");
        else
            snprintf(buf[i], sizeof buf[i], fmt, v[i]);
    }
    printf("  %-40s %12s %12s %12s %12s\n", label, buf[0], buf[1], buf[2], buf[3]);
}

/* Latched fault bits as codes: "none" or "1,8". */
static void fault_codes(uint16_t bits, char *out, size_t len)
{
    out[0] = 0;
    for (unsigned code = 1; code <= 16; code++)
        if (bits & (1u << (code - 1)))
            snprintf(out + strlen(out), len - strlen(out), "%s%u", out[0] ? "," : "", code);
    if (!out[0])
        snprintf(out, len, "none");
}

/* One figure of the four runs (algorithms 1, 2, 3, the limit): FIELD is an expression of m[i]. */
#define ROW4(label, fmt, FIELD) \
    do { \
        double v_[4]; \
        for (int i = 0; i < 4; i++) \
            v_[i] = (double)(FIELD); \
        row3(label, fmt, v_[0], v_[1], v_[2], v_[3]); \
    } while (0)

/* The thesis procedure's two steps, one line per figure, and algorithm 3's ratio to the limit. */
static void print_thesis_steps(const ctlbench_metrics *m)
{
    for (size_t k = 0; k < m[0].step_count; k++) {
        char label[64];
        double lb = m[0].step[k].load_change_n / PLANT_N_PER_LBF;
        snprintf(label, sizeof label, "%+.0f lb at %.0f s: first entry (s)", lb, m[0].step[k].t_s);
        ROW4(label, "%.2f", m[i].step[k].first_entry_s);
        snprintf(label, sizeof label, "%+.0f lb at %.0f s: back to stay (s)", lb, m[0].step[k].t_s);
        ROW4(label, "%.2f", m[i].step[k].return_s);
        snprintf(label, sizeof label, "%+.0f lb at %.0f s: alg 3 / limit", lb, m[0].step[k].t_s);
        row3(label, "%.2fx", NAN, NAN, ratio_to_limit(&m[2].step[k], &m[LIMIT].step[k]), NAN);
    }
}

static void print_scenario(const scored *s)
{
    const ctlbench_scenario *sc = &s->sc;
    const ctlbench_metrics *m = s->m;
    printf("\n== %s (%s, noise %g counts, %zu load steps, %.0f s) ==\n", sc->name, sc->config, sc->noise_counts,
           sc->step_count - 1, sc->end_s);
    printf("  %-40s %12s %12s %12s %12s\n", "", "alg 1", "alg 2", "alg 3", "limit");
    if (sc->kind == CTLBENCH_THESIS)
        print_thesis_steps(m);
    ROW4("return to stay, median (s)", "%.2f", m[i].return_median_s);
    ROW4("return to stay, worst (s)", "%.2f", m[i].return_worst_s);
    double med, worst;
    ratios(m, &med, &worst);
    row3("alg 3 / limit per step, median", "%.2fx", NAN, NAN, med, NAN);
    row3("alg 3 / limit per step, worst", "%.2fx", NAN, NAN, worst, NAN);
    ROW4("steps never settled", "%.0f", m[i].unsettled_steps);
    ROW4("overshoot beyond the band (in)", "%.3f", m[i].overshoot_max_m * IN_PER_M);
    ROW4("switchings per step", "%.1f", m[i].switchings_per_step);
    if (sc->kind == CTLBENCH_REST) {
        ROW4("switchings per minute at rest", "%.2f", m[i].rest_switchings_per_min);
        ROW4("switchings at rest (scored window)", "%.0f", m[i].rest_switchings);
        ROW4("outside the band at rest (s)", "%.2f", m[i].rest_outside_s);
    }
    ROW4("compressor on (s)", "%.1f", m[i].compressor_on_s);
    ROW4("air vented (kg)", "%.4f", m[i].vented_kg);
    ROW4("time outside the band (s)", "%.1f", m[i].outside_s);
    char codes[4][40];
    for (int a = 0; a < 4; a++)
        fault_codes(m[a].latched_faults, codes[a], sizeof codes[a]);
    printf("  %-40s %12s %12s %12s %12s\n", "latched fault codes", codes[0], codes[1], codes[2], codes[3]);
}

static bool has_accumulator(const ctlbench_scenario *sc, const char *kind)
{
    return strstr(sc->config, kind) != NULL;
}

static void verdict(const char *target, const char *where, const char *figure, double a1, double a2, double a3,
                    bool met, unsigned *missed)
{
    printf("  %-34s %-26s %-22s %9.3f %9.3f %9.3f  %s\n", target, where, figure, a1, a2, a3, met ? "met" : "MISSED");
    *missed += met ? 0u : 1u;
}

/* Fewer, or none where the other had none either. */
static bool fewer(double mine, double theirs)
{
    return mine < theirs || (mine == 0.0 && theirs == 0.0);
}

/* The targets, algorithm 3 against algorithms 1 and 2 of the same run. */
static unsigned print_targets(const scored *s, size_t n)
{
    unsigned missed = 0;
    printf("\n== targets (algorithm 3 beside algorithms 1 and 2 of this run) ==\n");
    printf("  %-34s %-26s %-22s %9s %9s %9s\n", "target", "scenario", "figure", "alg 1", "alg 2", "alg 3");
    for (size_t i = 0; i < n; i++) {
        const ctlbench_scenario *sc = &s[i].sc;
        const ctlbench_metrics *m = s[i].m;
        if (sc->kind == CTLBENCH_REST) {
            verdict("rest: 0 switchings", sc->name, "switchings at rest", m[0].rest_switchings,
                    m[1].rest_switchings, m[2].rest_switchings, m[2].rest_switchings == 0, &missed);
            verdict("rest: never outside the band", sc->name, "outside at rest (s)", m[0].rest_outside_s,
                    m[1].rest_outside_s, m[2].rest_outside_s, m[2].rest_outside_s == 0.0, &missed);
        }
        if (sc->kind == CTLBENCH_THESIS && has_accumulator(sc, "diaphragm")) {
            const ctlbench_step *st = m[2].step; /* +200 lb */
            verdict("diaphragm: fewer switchings", sc->name, "+200 lb switchings", m[0].step[0].switchings,
                    m[1].step[0].switchings, st->switchings, fewer(st->switchings, m[1].step[0].switchings), &missed);
        }
        if (sc->kind != CTLBENCH_REST && !has_accumulator(sc, "tube") && !has_accumulator(sc, "diaphragm")) {
            verdict("no acc: median return <= alg 1", sc->name, "median return (s)", m[0].return_median_s,
                    m[1].return_median_s, m[2].return_median_s, m[2].return_median_s <= m[0].return_median_s,
                    &missed);
            verdict("no acc: fewer switchings/step", sc->name, "switchings per step", m[0].switchings_per_step,
                    m[1].switchings_per_step, m[2].switchings_per_step,
                    fewer(m[2].switchings_per_step, m[0].switchings_per_step), &missed);
            verdict("no acc: no more air vented", sc->name, "air vented (kg)", m[0].vented_kg, m[1].vented_kg,
                    m[2].vented_kg, m[2].vented_kg <= m[0].vented_kg, &missed);
        }
        verdict("overshoot after a return <= 0.05 in", sc->name, "overshoot (in)", m[0].overshoot_max_m * IN_PER_M,
                m[1].overshoot_max_m * IN_PER_M, m[2].overshoot_max_m * IN_PER_M,
                m[2].overshoot_max_m * IN_PER_M <= 0.05, &missed);
    }
    printf("  %u target line(s) missed\n", missed);
    return missed;
}

/* Algorithm 3 against the limit (issue 19): every thesis step back to stay within 1.25x the limit's
 * return; over a random sequence the median within 1.25x, the worst within 2x, every step settled. */
static unsigned print_limit_targets(const scored *s, size_t n)
{
    unsigned missed = 0;
    printf("\n== targets against the limit (the best single move, ctlbench_limit.h) ==\n");
    printf("  %-34s %-26s %-22s %9s %9s %9s\n", "target", "scenario", "figure", "limit", "alg 3", "ratio");
    for (size_t i = 0; i < n; i++) {
        const ctlbench_scenario *sc = &s[i].sc;
        const ctlbench_metrics *m = s[i].m;
        double med, worst;
        ratios(m, &med, &worst);
        if (sc->kind == CTLBENCH_THESIS)
            for (size_t k = 0; k < m[2].step_count; k++) {
                double r = ratio_to_limit(&m[2].step[k], &m[LIMIT].step[k]);
                verdict("thesis: return <= 1.25x limit", sc->name,
                        m[2].step[k].load_change_n > 0 ? "+200 lb return (s)" : "-200 lb return (s)",
                        m[LIMIT].step[k].return_s, m[2].step[k].return_s, r,
                        m[2].step[k].settled && !(r > 1.25), &missed);
            }
        if (sc->kind == CTLBENCH_RANDOM) {
            verdict("random: median return <= 1.25x", sc->name, "median ratio", m[LIMIT].return_median_s,
                    m[2].return_median_s, med, !(med > 1.25), &missed);
            verdict("random: worst return <= 2x", sc->name, "worst ratio", m[LIMIT].return_worst_s,
                    m[2].return_worst_s, worst, !(worst > 2.0) && m[2].unsettled_steps == 0, &missed);
        }
    }
    printf("  %u target line(s) missed\n", missed);
    return missed;
}

/* A figure to its printed resolution (decimals), null when not defined. */
static void add_fixed(cJSON *o, const char *key, double v, int decimals)
{
    char text[64];
    if (!isfinite(v)) {
        cJSON_AddNullToObject(o, key);
        return;
    }
    snprintf(text, sizeof text, "%.*f", decimals, v);
    cJSON_AddRawToObject(o, key, text);
}

static cJSON *json_step(const ctlbench_step *st)
{
    cJSON *o = cJSON_CreateObject();
    add_fixed(o, "t_s", st->t_s, 2);
    add_fixed(o, "load_change_lbf", st->load_change_n / PLANT_N_PER_LBF, 0);
    add_fixed(o, "first_entry_s", st->first_entry_s, 3);
    add_fixed(o, "return_s", st->return_s, 3);
    cJSON_AddBoolToObject(o, "settled", st->settled);
    add_fixed(o, "overshoot_in", st->overshoot_m * IN_PER_M, 4);
    cJSON_AddNumberToObject(o, "switchings", st->switchings);
    return o;
}

static cJSON *json_metrics(const ctlbench_metrics *m)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "algorithm", m->algorithm);
    add_fixed(o, "return_median_s", m->return_median_s, 3);
    add_fixed(o, "return_worst_s", m->return_worst_s, 3);
    cJSON_AddNumberToObject(o, "unsettled_steps", m->unsettled_steps);
    add_fixed(o, "overshoot_in", m->overshoot_max_m * IN_PER_M, 4);
    add_fixed(o, "switchings_per_step", m->switchings_per_step, 3);
    cJSON_AddNumberToObject(o, "switchings", m->switchings);
    if (!isnan(m->rest_switchings_per_min)) {
        cJSON_AddNumberToObject(o, "rest_switchings", m->rest_switchings);
        add_fixed(o, "rest_switchings_per_min", m->rest_switchings_per_min, 3);
        add_fixed(o, "rest_outside_s", m->rest_outside_s, 2);
    }
    add_fixed(o, "compressor_on_s", m->compressor_on_s, 2);
    add_fixed(o, "vented_kg", m->vented_kg, 5);
    add_fixed(o, "outside_s", m->outside_s, 2);
    cJSON_AddNumberToObject(o, "latched_faults", m->latched_faults);
    cJSON *steps = cJSON_AddArrayToObject(o, "steps");
    for (size_t k = 0; k < m->step_count; k++)
        cJSON_AddItemToArray(steps, json_step(&m->step[k]));
    return o;
}

/* The limit's run (algorithm 0), its moves, and algorithm 3's ratio to it per step. */
static cJSON *json_limit(const scored *s)
{
    const ctlbench_metrics *m = s->m;
    cJSON *o = json_metrics(&m[LIMIT]);
    add_fixed(o, "target_in", s->limit.target_m * IN_PER_M, 4);
    cJSON *steps = cJSON_GetObjectItem(o, "steps");
    for (size_t k = 0; k < m[LIMIT].step_count; k++) {
        cJSON *st = cJSON_GetArrayItem(steps, (int)k);
        add_fixed(st, "open_s", (double)s->limit.open_ticks[k] * 0.01, 2);
        add_fixed(st, "target_open_s", (double)s->limit.target_ticks[k] * 0.01, 2);
        add_fixed(st, "landing_in", s->limit.landing_m[k] * IN_PER_M, 4);
        add_fixed(st, "alg3_ratio", ratio_to_limit(&m[2].step[k], &m[LIMIT].step[k]), 3);
    }
    double med, worst;
    ratios(m, &med, &worst);
    add_fixed(o, "alg3_ratio_median", med, 3);
    add_fixed(o, "alg3_ratio_worst", worst, 3);
    return o;
}

static cJSON *json_scorecard(const scored *s, size_t n)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "version", LEVELER_VERSION);
    cJSON *list = cJSON_AddArrayToObject(root, "scenarios");
    for (size_t i = 0; i < n; i++) {
        cJSON *sc = cJSON_CreateObject();
        cJSON_AddStringToObject(sc, "name", s[i].sc.name);
        cJSON_AddStringToObject(sc, "config", s[i].sc.config);
        cJSON_AddNumberToObject(sc, "noise_counts", s[i].sc.noise_counts);
        cJSON_AddNumberToObject(sc, "seed", s[i].sc.noise_seed); /* a random sequence's too */
        add_fixed(sc, "end_s", s[i].sc.end_s, 0);
        cJSON *runs = cJSON_AddArrayToObject(sc, "runs");
        for (int a = 0; a < 3; a++)
            cJSON_AddItemToArray(runs, json_metrics(&s[i].m[a]));
        cJSON_AddItemToObject(sc, "limit", json_limit(&s[i]));
        cJSON_AddItemToArray(list, sc);
    }
    return root;
}

/* scorecard.json, written whole then renamed. */
static int write_json(const char *dir, const scored *s, size_t n)
{
    char path[1200], tmp[1220];
    snprintf(path, sizeof path, "%s/scorecard.json", dir);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    cJSON *root = json_scorecard(s, n);
    char *text = root ? cJSON_Print(root) : NULL;
    cJSON_Delete(root);
    FILE *f = text ? fopen(tmp, "w") : NULL;
    if (!f) {
        fprintf(stderr, "leveler-ctlbench: %s: %s\n", tmp, text ? strerror(errno) : "out of memory");
        free(text);
        return -1;
    }
    int wrote = fprintf(f, "%s\n", text) >= 0;
    free(text);
    if (fclose(f) != 0 || !wrote || rename(tmp, path) != 0) {
        fprintf(stderr, "leveler-ctlbench: writing %s failed: %s\n", path, strerror(errno));
        return -1;
    }
    return 0;
}

/* One python run draws every scenario's PNG from its three logs. */
static int plot_all(const char *dir, const char *configs, const scored *s, size_t n)
{
    const char *args[MAX_SCENARIOS + 6];
    size_t k = 0;
    args[k++] = "--dir";
    args[k++] = dir;
    args[k++] = "--configs";
    args[k++] = configs;
    for (size_t i = 0; i < n && k < MAX_SCENARIOS + 5; i++)
        args[k++] = s[i].sc.name;
    args[k] = NULL;
    int rc = sim_python_module("leveler-ctlbench", "ctlbench_plot", args);
    if (rc == -2)
        fprintf(stderr, "leveler-ctlbench: %s/leveler/ctlbench_plot.py missing; no PNGs\n", sim_python_scripts_dir());
    return rc == 0 ? 0 : -1;
}

enum { OPT_OUT = 0x100, OPT_CONFIGS, OPT_CONFIG, OPT_SHORT, OPT_NO_PLOTS, OPT_QUIET, OPT_RANDOM_SEED };

static const cli_option bench_options[] = {
    {"out", OPT_OUT, "DIR", "logs, one PNG per scenario and scorecard.json (default build/ctlbench)", 0},
    {"configs", OPT_CONFIGS, "DIR", "the INI files (default <source>/host_sim/configs)", 0},
    {"config", OPT_CONFIG, "FILE", "the suite on this one config instead (a rig of yours: steps, rest, random)", 0},
    {"short", OPT_SHORT, NULL, "the acceptance test's short suite", 0},
    {"no-plots", OPT_NO_PLOTS, NULL, "no logs and no PNGs (figures only)", 0},
    {"quiet", OPT_QUIET, NULL, "no progress lines", 0},
    {"random-seed", OPT_RANDOM_SEED, "S", "draw the random load sequences from seed S (default 2026): another sequence", 0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec bench_cli = {
    .prog = "leveler-ctlbench",
    .usage = "[--out DIR] [--configs DIR | --config FILE] [--short] [--no-plots] [--quiet]"
             " [--random-seed S]",
    .about = "The controller scorecard: algorithms 1, 2 and 3 over the scenario suite (targets missed are\n"
             "reported, not failed).",
    .opts = bench_options,
};

typedef struct {
    const char *out, *configs, *config;
    bool short_suite, plots, quiet;
    int random_seed;
} bench_args;

static int bench_option(void *user, int key, const char *v)
{
    bench_args *a = user;
    switch (key) {
    case OPT_OUT: a->out = v; break;
    case OPT_CONFIGS: a->configs = v; break;
    case OPT_CONFIG: a->config = v; break;
    case OPT_SHORT: a->short_suite = true; break;
    case OPT_NO_PLOTS: a->plots = false; break;
    case OPT_QUIET: a->quiet = true; break;
    case OPT_RANDOM_SEED: return cli_int(&bench_cli, "random-seed", v, 0, 2000000000, &a->random_seed);
    }
    return 0;
}

static int run_all(const char *configs, const char *out, bool plots, bool quiet, scored *s, size_t n)
{
    size_t cap = ctlbench_rows_needed(&s[0].sc, 1);
    for (size_t i = 1; i < n; i++)
        cap = ctlbench_rows_needed(&s[i].sc, 1) > cap ? ctlbench_rows_needed(&s[i].sc, 1) : cap;
    runlog_row *rows = malloc(cap * sizeof *rows);
    if (!rows) {
        fprintf(stderr, "leveler-ctlbench: out of memory for %zu rows\n", cap);
        return -1;
    }
    char err[1024], log[1200];
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0; i++) {
        if (!quiet)
            fprintf(stderr, "leveler-ctlbench: [%zu/%zu] %s\n", i + 1, n, s[i].sc.name);
        for (int a = 1; a <= 3 && rc == 0; a++) {
            snprintf(log, sizeof log, "%s/%s-alg%d.csv", out, s[i].sc.name, a);
            if (ctlbench_run(&s[i].sc, a, configs, plots ? log : NULL, rows, cap, &s[i].m[a - 1], err, sizeof err) != 0) {
                fprintf(stderr, "leveler-ctlbench: %s, algorithm %d: %s\n", s[i].sc.name, a, err);
                rc = -1;
            }
        }
        snprintf(log, sizeof log, "%s/%s-limit.csv", out, s[i].sc.name);
        if (rc == 0 && ctlbench_limit(&s[i].sc, configs, plots ? log : NULL, rows, cap, &s[i].m[LIMIT], &s[i].limit,
                                      err, sizeof err) != 0) {
            fprintf(stderr, "leveler-ctlbench: %s, the limit: %s\n", s[i].sc.name, err);
            rc = -1;
        }
    }
    free(rows);
    return rc;
}

/* --config FILE: its folder (the configs folder of the suite) and its name without .ini. 0, or 2 after a message. */
static int one_config(const char *file, char *folder, size_t folder_len, char *stem, size_t stem_len)
{
    const char *slash = strrchr(file, '/');
    const char *base = slash ? slash + 1 : file;
    size_t len = strlen(base);
    if (len < 5 || strcmp(base + len - 4, ".ini") != 0 || len - 4 >= stem_len) {
        fprintf(stderr, "leveler-ctlbench: --config %s: give an INI file (NAME.ini, NAME under %zu characters)\n",
                file, stem_len);
        return 2;
    }
    snprintf(stem, stem_len, "%.*s", (int)(len - 4), base);
    if (slash)
        snprintf(folder, folder_len, "%.*s", (int)(slash - file), file);
    else
        snprintf(folder, folder_len, ".");
    return 0;
}

int main(int argc, char **argv)
{
    bench_args a = {.out = "build/ctlbench", .configs = LEVELER_SOURCE_DIR "/host_sim/configs", .plots = true,
                    .random_seed = (int)CTLBENCH_RANDOM_SEED};
    int prc = cli_parse(&bench_cli, argc, argv, bench_option, &a, NULL);
    if (prc != CLI_CONTINUE)
        return prc;
    const char *out = a.out, *configs = a.configs;
    bool short_suite = a.short_suite, plots = a.plots;
    if (mkdir(out, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "leveler-ctlbench: cannot create %s: %s\n", out, strerror(errno));
        return 2;
    }
    static scored s[MAX_SCENARIOS];
    static ctlbench_scenario suite[MAX_SCENARIOS];
    static char folder[PLANT_PATH_MAX], stem[CTLBENCH_NAME_MAX];
    if (a.config && one_config(a.config, folder, sizeof folder, stem, sizeof stem) != 0)
        return 2;
    if (a.config)
        configs = folder;
    size_t n = a.config ? ctlbench_suite_for(stem, short_suite, (uint32_t)a.random_seed, suite, MAX_SCENARIOS)
                        : ctlbench_suite(short_suite, (uint32_t)a.random_seed, suite, MAX_SCENARIOS);
    for (size_t i = 0; i < n; i++)
        s[i].sc = suite[i];
    if (run_all(configs, out, plots, a.quiet, s, n) != 0)
        return 1;
    printf("leveler controller scorecard: algorithms 1 and 2 (the thesis's) and 3 (docs/controller.md),\n"
           "firmware in the loop, product defaults (algorithms 1 and 2 without the chatter fault, as published);\n"
           "times from the load step; fault codes: 1 overpressure, 2 run time, 3 stall, 4-7 sensors, 8 chatter\n");
    for (size_t i = 0; i < n; i++)
        print_scenario(&s[i]);
    print_targets(s, n);
    print_limit_targets(s, n);
    if (write_json(out, s, n) != 0 || (plots && plot_all(out, configs, s, n) != 0))
        return 1;
    printf("\nwritten: %s/scorecard.json%s\n", out, plots ? " and one PNG per scenario" : "");
    return 0;
}
