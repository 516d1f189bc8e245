/*
 * leveler-ctlbench-family: algorithm 3 with the product defaults and learning
 * on over the perturbed rig family (ctlbench_family.h). Per rig: the 900 lb
 * thesis steps then 10 minutes at rest with 4 counts of sensor noise; it
 * prints the switchings at rest, each step's return against that rig's limit
 * (ctlbench_limit.h) and the overshoot, names the worst rig; then the same
 * steps after the firmware's commissioning routine (leveler/commissioning.h),
 * against their limit, and the worst rig after it; writes DIR/family.json
 * and the rigs' INI files in DIR.
 *
 *   leveler-ctlbench-family [--out DIR] [--configs DIR] [--rigs N] [--seed S] [--logs]
 *
 * Exit status: 0 done (figures reported, not judged), 1 a run failed, 2 bad input.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdbool.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cjson/cJSON.h>

#include "cli.h"
#include "ctlbench.h"
#include "ctlbench_family.h"
#include "ctlbench_limit.h"
#include "commissioning_run.h"
#include "leveler/commissioning.h"
#include "leveler/settings.h"

#ifndef LEVELER_SOURCE_DIR
#define LEVELER_SOURCE_DIR "."
#endif

#define MAX_RIGS 64
#define NOISE_COUNTS 4.0
#define REST_S 600.0
#define IN_PER_M (1.0 / PLANT_M_PER_IN)

typedef struct {
    ctlbench_rig rig;
    ctlbench_metrics a3, lim;
    double ratio[2];  /* +200 lb, -200 lb: algorithm 3's return over the limit's */
    double worst;
    /* after commissioning (ctlbench_thesis_commissioned): the steps against their limit */
    ctlbench_metrics a3c, limc;
    double ratio_c[2], worst_c;
    uint16_t commission_result;
    double commission_s;
} rig_result;

/* Algorithm 3's return over the limit's, the limit's taken as at least LOAD_S: a return within the first
 * second is the load's doing (the scorecard's rule), and a limit that never left the band is no zero. */
#define LOAD_S 1.0
static double ratio(const ctlbench_step *a3, const ctlbench_step *lim)
{
    if (a3->return_s <= 0.0)
        return 1.0;
    return a3->return_s / (lim->return_s > LOAD_S ? lim->return_s : LOAD_S);
}

/* DIR/<name>-<who>.csv when the logs are asked for, else NULL (no log written). */
static const char *log_path(char *buf, size_t len, const char *out, const char *name, const char *who, bool logs)
{
    if (!logs)
        return NULL;
    snprintf(buf, len, "%s/%s-%s.csv", out, name, who);
    return buf;
}

/* The rig after commissioning: the routine, then the thesis steps, against their limit. */
static int run_commissioned(const char *out, bool logs, rig_result *r, runlog_row *rows, size_t cap, char *err,
                            size_t err_len)
{
    ctlbench_scenario sc;
    char name[CTLBENCH_NAME_MAX], lp[1024];
    snprintf(name, sizeof name, "%.*s-commissioned", (int)(strlen(r->rig.file) - 4), r->rig.file);
    ctlbench_thesis_commissioned(&sc, name, r->rig.file, NOISE_COUNTS, 104u);
    ctlbench_limit_moves mv;
    if (ctlbench_run(&sc, 3, out, log_path(lp, sizeof lp, out, name, "alg3", logs), rows, cap, &r->a3c, err,
                     err_len) != 0)
        return -1;
    r->commission_result = leveler_settings_current()->commission_result; /* the firmware after the run */
    r->commission_s = leveler_settings_current()->commission_ms / 1000.0;
    if (ctlbench_limit(&sc, out, log_path(lp, sizeof lp, out, name, "limit", logs), rows, cap, &r->limc, &mv, err,
                       err_len) != 0)
        return -1;
    r->worst_c = 0.0;
    for (size_t k = 0; k < 2 && k < r->a3c.step_count; k++) {
        r->ratio_c[k] = ratio(&r->a3c.step[k], &r->limc.step[k]);
        r->worst_c = r->ratio_c[k] > r->worst_c ? r->ratio_c[k] : r->worst_c;
    }
    return 0;
}

/* One rig: written, loaded by the config loader, run with algorithm 3 and its limit, then commissioned. */
static int run_rig(const char *out, const char *configs, bool logs, rig_result *r, runlog_row *rows, size_t cap,
                   char *err, size_t err_len)
{
    if (ctlbench_family_write(&r->rig, out, configs, err, err_len) != 0)
        return -1;
    ctlbench_scenario sc;
    char name[CTLBENCH_NAME_MAX], lp[1024];
    snprintf(name, sizeof name, "%.*s", (int)(strlen(r->rig.file) - 4), r->rig.file);
    ctlbench_thesis_rest(&sc, name, r->rig.file, NOISE_COUNTS, 104u, REST_S);
    ctlbench_limit_moves mv;
    if (ctlbench_run(&sc, 3, out, log_path(lp, sizeof lp, out, name, "alg3", logs), rows, cap, &r->a3, err,
                     err_len) != 0 ||
        ctlbench_limit(&sc, out, log_path(lp, sizeof lp, out, name, "limit", logs), rows, cap, &r->lim, &mv, err,
                       err_len) != 0)
        return -1;
    r->worst = 0.0;
    for (size_t k = 0; k < 2 && k < r->a3.step_count; k++) {
        r->ratio[k] = ratio(&r->a3.step[k], &r->lim.step[k]);
        r->worst = r->ratio[k] > r->worst ? r->ratio[k] : r->worst;
    }
    return run_commissioned(out, logs, r, rows, cap, err, err_len);
}

static void print_rig(const rig_result *r)
{
    const ctlbench_metrics *a = &r->a3, *l = &r->lim;
    printf("  %-10s %8u %8.2f %8.2f %7.2fx %8.2f %8.2f %7.2fx %9.3f %6u %6.1f\n", r->rig.file, a->rest_switchings,
           a->step[0].return_s, l->step[0].return_s, r->ratio[0], a->step[1].return_s, l->step[1].return_s,
           r->ratio[1], a->overshoot_max_m * IN_PER_M, a->unsettled_steps, a->switchings_per_step);
}

static void print_rig_commissioned(const rig_result *r)
{
    const ctlbench_metrics *a = &r->a3c, *l = &r->limc;
    printf("  %-10s %-9s %6.2f %8.2f %8.2f %7.2fx %8.2f %8.2f %7.2fx %9.3f %6u\n", r->rig.file,
           sim_commissioning_result_name(r->commission_result), r->commission_s, a->step[0].return_s,
           l->step[0].return_s, r->ratio_c[0], a->step[1].return_s, l->step[1].return_s, r->ratio_c[1],
           a->overshoot_max_m * IN_PER_M, a->unsettled_steps);
}

/* The two steps of one run (algorithm 3 against the limit), its overshoot and unsettled steps, into o. */
static void json_steps(cJSON *o, const ctlbench_metrics *a3, const ctlbench_metrics *lim, const double ratio[2])
{
    cJSON *steps = cJSON_AddArrayToObject(o, "steps");
    for (size_t k = 0; k < 2; k++) {
        cJSON *s = cJSON_CreateObject();
        cJSON_AddNumberToObject(s, "alg3_return_s", a3->step[k].return_s);
        cJSON_AddNumberToObject(s, "limit_return_s", lim->step[k].return_s);
        cJSON_AddNumberToObject(s, "ratio", isfinite(ratio[k]) ? ratio[k] : -1.0);
        cJSON_AddNumberToObject(s, "switchings", a3->step[k].switchings);
        cJSON_AddItemToArray(steps, s);
    }
    cJSON_AddNumberToObject(o, "overshoot_in", a3->overshoot_max_m * IN_PER_M);
    cJSON_AddNumberToObject(o, "unsettled_steps", a3->unsettled_steps);
}

static cJSON *json_commissioned(const rig_result *r)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "result", sim_commissioning_result_name(r->commission_result));
    cJSON_AddNumberToObject(o, "took_s", r->commission_s);
    json_steps(o, &r->a3c, &r->limc, r->ratio_c);
    return o;
}

static cJSON *json_rig(const rig_result *r)
{
    const ctlbench_rig *g = &r->rig;
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "file", g->file);
    const double f[] = {g->spring_orifice, g->spring_cd_in, g->spring_cd_out, g->vent_orifice, g->vent_cd,
                        g->acc_orifice, g->acc_cd, g->spring_volume, g->pipe_volume, g->damping_up,
                        g->damping_down, g->charge, g->displacement};
    cJSON_AddItemToObject(o, "factors", cJSON_CreateDoubleArray(f, (int)(sizeof f / sizeof f[0])));
    cJSON_AddItemToObject(o, "up_shift_psi", cJSON_CreateDoubleArray(g->up_shift_psi, CTLBENCH_FAMILY_BANDS));
    cJSON_AddItemToObject(o, "gap_psi", cJSON_CreateDoubleArray(g->gap_psi, CTLBENCH_FAMILY_BANDS));
    cJSON_AddNumberToObject(o, "rest_switchings", r->a3.rest_switchings);
    cJSON_AddNumberToObject(o, "rest_returning", r->a3.rest_returning);
    cJSON_AddNumberToObject(o, "rest_recharge", r->a3.rest_recharge);
    cJSON_AddNumberToObject(o, "rest_moves", r->a3.rest_moves);
    json_steps(o, &r->a3, &r->lim, r->ratio);
    cJSON_AddItemToObject(o, "commissioned", json_commissioned(r));
    return o;
}

static size_t worst_commissioned(const rig_result *r, size_t n);

static int write_json(const char *out, const rig_result *r, size_t n, size_t worst)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "noise_counts", NOISE_COUNTS);
    cJSON_AddStringToObject(root, "worst", r[worst].rig.file);
    cJSON_AddStringToObject(root, "worst_commissioned", r[worst_commissioned(r, n)].rig.file);
    cJSON *list = cJSON_AddArrayToObject(root, "rigs");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(list, json_rig(&r[i]));
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    char path[1200];
    snprintf(path, sizeof path, "%s/family.json", out);
    FILE *f = text ? fopen(path, "w") : NULL;
    int ok = f && fprintf(f, "%s\n", text) >= 0;
    free(text);
    if (!f || fclose(f) != 0 || !ok) {
        fprintf(stderr, "leveler-ctlbench-family: writing %s failed\n", path);
        return -1;
    }
    return 0;
}

enum { OPT_OUT = 0x100, OPT_CONFIGS, OPT_RIGS, OPT_SEED, OPT_LOGS };

static const cli_option family_options[] = {
    {"out", OPT_OUT, "DIR", "the rigs' INI files and family.json (default build/ctlfamily)", 0},
    {"configs", OPT_CONFIGS, "DIR", "the thesis configs (default <source>/host_sim/configs)", 0},
    {"rigs", OPT_RIGS, "N", "rigs in the family, 1..64 (default 24)", 0},
    {"seed", OPT_SEED, "S", "the family's seed (default 19)", 0},
    {"logs", OPT_LOGS, NULL, "also write each run's log (docs/log-format.md) as DIR/<rig>[-commissioned]-{alg3,limit}.csv",
     0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec family_cli = {
    .prog = "leveler-ctlbench-family",
    .usage = "[--out DIR] [--configs DIR] [--rigs N] [--seed S] [--logs]",
    .about = "Algorithm 3 (defaults, learning on) over rigs made by perturbing the thesis rig: switchings at\n"
             "rest with 4 counts of noise, return against each rig's limit, overshoot; the worst rig named.",
    .opts = family_options,
};

typedef struct {
    const char *out, *configs;
    int rigs, seed;
    bool logs;
} family_args;

static int family_option(void *user, int key, const char *v)
{
    family_args *a = user;
    switch (key) {
    case OPT_OUT: a->out = v; break;
    case OPT_CONFIGS: a->configs = v; break;
    case OPT_RIGS: return cli_int(&family_cli, "rigs", v, 1, MAX_RIGS, &a->rigs);
    case OPT_SEED: return cli_int(&family_cli, "seed", v, 0, 1000000, &a->seed);
    case OPT_LOGS: a->logs = true; break;
    }
    return 0;
}

/* The worst rig: the largest return ratio, then the most switchings at rest. */
static size_t worst_of(const rig_result *r, size_t n)
{
    size_t w = 0;
    for (size_t i = 1; i < n; i++)
        if (r[i].worst > r[w].worst ||
            (r[i].worst == r[w].worst && r[i].a3.rest_switchings > r[w].a3.rest_switchings))
            w = i;
    return w;
}

/* The switchings at rest by what made them: a return still under way, a recharge, a move (hunting). */
static void print_rest_split(const rig_result *r, size_t n)
{
    unsigned sum[3] = {0, 0, 0}, rigs[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        const unsigned k[3] = {r[i].a3.rest_returning, r[i].a3.rest_recharge, r[i].a3.rest_moves};
        for (size_t j = 0; j < 3; j++) {
            sum[j] += k[j];
            rigs[j] += k[j] > 0;
        }
    }
    printf("switchings at rest: %u on %u rigs while the removal's return was still under way, %u on %u rigs\n"
           "  by the accumulator's recharge alone, %u on %u rigs by a fill or vent after the return (hunting)\n",
           sum[0], rigs[0], sum[1], rigs[1], sum[2], rigs[2]);
}

static void print_table(const rig_result *r, size_t n, size_t w, int seed)
{
    printf("leveler perturbed rig family: %zu rigs (seed %d) from %s, algorithm 3 with the product defaults and\n"
           "learning on; 900 lb thesis steps then 10 min at rest with %g counts of noise; returns in s\n",
           n, seed, CTLBENCH_FAMILY_BASE, NOISE_COUNTS);
    printf("  %-10s %8s %8s %8s %8s %8s %8s %8s %9s %6s %6s\n", "rig", "sw. rest", "+200 a3", "limit", "ratio",
           "-200 a3", "limit", "ratio", "overshoot", "unset", "sw/st");
    for (size_t i = 0; i < n; i++)
        print_rig(&r[i]);
    unsigned hunting = 0;
    size_t most = 0, over = 0;
    for (size_t i = 0; i < n; i++) {
        hunting += r[i].a3.rest_switchings > 0;
        most = r[i].a3.rest_switchings > r[most].a3.rest_switchings ? i : most;
        over = r[i].a3.overshoot_max_m > r[over].a3.overshoot_max_m ? i : over;
    }
    printf("(ratio: over the limit's return, taken as at least %.0f s; unset: steps never settled; sw/st: "
           "switchings per step)\n", LOAD_S);
    printf("rigs that switched at rest: %u of %zu (most: %s, %u); largest overshoot %.3f in (%s)\n", hunting, n,
           r[most].rig.file, r[most].a3.rest_switchings, r[over].a3.overshoot_max_m * IN_PER_M, r[over].rig.file);
    printf("worst rig: %s (return %.2fx its limit, %u switchings at rest, overshoot %.3f in)\n", r[w].rig.file,
           r[w].worst, r[w].a3.rest_switchings, r[w].a3.overshoot_max_m * IN_PER_M);
    print_rest_split(r, n);
}

/* The worst rig after commissioning: the largest return ratio. */
static size_t worst_commissioned(const rig_result *r, size_t n)
{
    size_t w = 0;
    for (size_t i = 1; i < n; i++)
        w = r[i].worst_c > r[w].worst_c ? i : w;
    return w;
}

/* After commissioning: every step's return against its limit (target 1.5x), overshoot (0.05 in). */
static void print_commissioned(const rig_result *r, size_t n)
{
    printf("\nafter commissioning (the routine from 0 s, then +200 lb %.0f s later, removed 30 s after; "
           "same noise):\n", LEVELER_COMMISSION_MAX_MS / 1000.0 + 5.0);
    printf("  %-10s %-9s %6s %8s %8s %8s %8s %8s %8s %9s %6s\n", "rig", "commiss.", "took", "+200 a3", "limit",
           "ratio", "-200 a3", "limit", "ratio", "overshoot", "unset");
    size_t w = worst_commissioned(r, n);
    unsigned done = 0, within = 0, calm = 0;
    for (size_t i = 0; i < n; i++) {
        print_rig_commissioned(&r[i]);
        done += r[i].commission_result == 1u;
        within += r[i].worst_c <= 1.5;
        calm += r[i].a3c.overshoot_max_m * IN_PER_M <= 0.05;
    }
    printf("commissioning done within 60 s on %u of %zu rigs; every step within 1.5x its limit on %u, overshoot "
           "<= 0.05 in on %u\n", done, n, within, calm);
    printf("worst rig after commissioning: %s (return %.2fx its limit, overshoot %.3f in, %u unsettled)\n",
           r[w].rig.file, r[w].worst_c, r[w].a3c.overshoot_max_m * IN_PER_M, r[w].a3c.unsettled_steps);
}

int main(int argc, char **argv)
{
    family_args a = {.out = "build/ctlfamily", .configs = LEVELER_SOURCE_DIR "/host_sim/configs", .rigs = 24,
                     .seed = 19};
    int prc = cli_parse(&family_cli, argc, argv, family_option, &a, NULL);
    if (prc != CLI_CONTINUE)
        return prc;
    if (mkdir(a.out, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "leveler-ctlbench-family: cannot create %s: %s\n", a.out, strerror(errno));
        return CLI_EXIT_BAD_INPUT;
    }
    static rig_result r[MAX_RIGS];
    ctlbench_scenario probe;
    ctlbench_thesis_rest(&probe, "probe", CTLBENCH_FAMILY_BASE, NOISE_COUNTS, 104u, REST_S);
    size_t cap = ctlbench_rows_needed(&probe, 1);
    runlog_row *rows = malloc(cap * sizeof *rows);
    char err[1024];
    for (int i = 0; rows && i < a.rigs; i++) {
        ctlbench_family_draw((uint32_t)a.seed, (unsigned)i, &r[i].rig);
        fprintf(stderr, "leveler-ctlbench-family: [%d/%d] %s\n", i + 1, a.rigs, r[i].rig.file);
        if (run_rig(a.out, a.configs, a.logs, &r[i], rows, cap, err, sizeof err) != 0) {
            fprintf(stderr, "leveler-ctlbench-family: %s: %s\n", r[i].rig.file, err);
            free(rows);
            return CLI_EXIT_FAILED;
        }
    }
    free(rows);
    if (!rows)
        return CLI_EXIT_FAILED;
    size_t w = worst_of(r, (size_t)a.rigs);
    print_table(r, (size_t)a.rigs, w, a.seed);
    print_commissioned(r, (size_t)a.rigs);
    return write_json(a.out, r, (size_t)a.rigs, w) == 0 ? CLI_EXIT_OK : CLI_EXIT_FAILED;
}
