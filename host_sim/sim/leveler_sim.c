/*
 * leveler-sim: the unchanged firmware against the plant model.
 *
 *   leveler-sim --config FILE [--schedule FILE] [--algorithm 1|2|3] --log run.csv
 *               [--summary run.json] [--plot run.png] [--units thesis|si] [--end-s S]
 *   leveler-sim --dump-config [--config FILE]
 *   leveler-sim --commission --config FILE [--log run.csv] [--end-s S]
 *
 * Writes the run log (runlog.h format). With --summary/--plot it then runs
 *   $LEVELER_PYTHON -m leveler.report --log run.csv ... (PYTHONPATH=<source>/scripts)
 * which prints the thesis comparison table. LEVELER_PYTHON and
 * LEVELER_SCRIPTS_DIR in the environment override the built-in paths.
 * Options as --opt VALUE or --opt=VALUE (host_sim/cli); --help, --version.
 * Exit status: 0 done, 1 the run or the report failed, 2 bad input (an option, the config, the schedule).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "commissioning_run.h"
#include "pyrun.h"
#include "runlog_firmware.h"
#include "simloop.h"

enum { OPT_CONFIG = 0x100, OPT_LOG, OPT_SCHEDULE, OPT_ALGORITHM, OPT_SUMMARY, OPT_PLOT, OPT_UNITS, OPT_END_S,
       OPT_DUMP, OPT_QUIET, OPT_FAIL_ON_FAULT, OPT_COMMISSION };

static const cli_option sim_options_list[] = {
    {"config", OPT_CONFIG, "FILE", "plant, sensors, controller settings, scenario (docs/config-format.md)", 0},
    {"schedule", OPT_SCHEDULE, "FILE",
     "load steps, CSV t_s,load_n (replaces the config's scenario); optional\n"
     "columns mode, manual_compressor, manual_spring_valve, manual_vent_valve,\n"
     "manual_acc_valve are written through the register map at each row", 0},
    {"algorithm", OPT_ALGORITHM, "1|2|3",
     "1 no accumulator, 2 accumulator, 3 hysteresis-aware (docs/controller.md)\n(default: the config's)", 0},
    {"log", OPT_LOG, "FILE", "run log, one row per 10 ms tick (\"-\" = stdout)", 0},
    {"summary", OPT_SUMMARY, "FILE", "event figures as JSON (runs python -m leveler.report)", 0},
    {"plot", OPT_PLOT, "FILE", "figure of the run (runs python -m leveler.report)", 0},
    {"units", OPT_UNITS, "thesis|si", "units of the printed comparison table (default thesis)", 0},
    {"end-s", OPT_END_S, "S", "simulate to S seconds (holds the last load past the schedule)", 0},
    {"dump-config", OPT_DUMP, NULL,
     "print the resolved config (the built-in one without --config)\n"
     "as JSON in SI units and exit (what scripts/leveler/config.py reads)", 0},
    {"quiet", OPT_QUIET, NULL, "no progress lines on long runs", 0},
    {"fail-on-fault", OPT_FAIL_ON_FAULT, NULL, "exit 1 when the supervisor latched a fault during the run", 0},
    {"commission", OPT_COMMISSION, NULL,
     "run the firmware's commissioning routine on the config's plant (base load\n"
     "held, algorithm 3) and print what it learnt beside the plant's own lines and\n"
     "the time it took; --log optional; exit 1 unless it is done within 60 s", 0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec sim_cli = {
    .prog = "leveler-sim",
    .usage = "--config FILE [--schedule FILE] [--algorithm 1|2|3] --log run.csv\n"
             "[--summary run.json] [--plot run.png] [--units thesis|si] [--end-s S] [--quiet]\n"
             "[--fail-on-fault]\n"
             "|--dump-config [--config FILE]\n"
             "|--commission --config FILE [--log run.csv] [--end-s S]",
    .about = "The unchanged firmware against the plant model: writes the run log (docs/log-format.md).",
    .opts = sim_options_list,
};

static void progress(double t_s, double end_s, void *user)
{
    if (end_s >= 600.0 && !*(const int *)user)
        fprintf(stderr, "leveler-sim: %.0f / %.0f s simulated\n", t_s, end_s);
}

/* --dump-config: 0, 2 on a config error. */
static int dump_config(const char *config)
{
    static plant_config cfg;
    char err[1024];
    if (config && plant_config_load(config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 2;
    }
    if (!config)
        plant_config_defaults(&cfg);
    return plant_config_write_json(&cfg, stdout) == 0 && fflush(stdout) == 0 ? 0 : 1;
}

static int run_report(const char *log, const char *summary, const char *plot, const char *config, const char *units,
                      int not_thesis)
{
    const char *args[16];
    int n = 0;
    args[n++] = "--log";
    args[n++] = log;
    if (summary) {
        args[n++] = "--summary";
        args[n++] = summary;
    }
    if (plot) {
        args[n++] = "--plot";
        args[n++] = plot;
    }
    if (config) {
        args[n++] = "--config";
        args[n++] = config;
    }
    args[n++] = "--units";
    args[n++] = units;
    if (not_thesis) /* another schedule or algorithm: no thesis column */
        args[n++] = "--no-thesis";
    args[n] = NULL;
    int rc = sim_python_module("leveler-sim", "report", args);
    if (rc == -2) {
        fprintf(stderr,
                "leveler-sim: the log is written, but --summary/--plot need the analysis module "
                "%s/leveler/report.py, which is not there (yet); run it later with: PYTHONPATH=%s %s -m "
                "leveler.report --log %s\n",
                sim_python_scripts_dir(), sim_python_scripts_dir(), sim_python_path(), log);
        return 1;
    }
    return rc;
}

typedef struct {
    const char *config, *schedule, *log, *summary, *plot, *units;
    int algorithm; /* 0 = the config's */
    int dump, quiet, fail_on_fault, commission;
    double end_s;
} sim_args;

/* One option with its value v: 0, or the exit status (2) after a message. */
static int parse_option(void *user, int key, const char *v)
{
    sim_args *a = user;
    switch (key) {
    case OPT_CONFIG: a->config = v; return 0;
    case OPT_SCHEDULE: a->schedule = v; return 0;
    case OPT_LOG: a->log = v; return 0;
    case OPT_SUMMARY: a->summary = v; return 0;
    case OPT_PLOT: a->plot = v; return 0;
    case OPT_DUMP: a->dump = 1; return 0;
    case OPT_QUIET: a->quiet = 1; return 0;
    case OPT_FAIL_ON_FAULT: a->fail_on_fault = 1; return 0;
    case OPT_COMMISSION: a->commission = 1; return 0;
    case OPT_UNITS:
        if (strcmp(v, "thesis") != 0 && strcmp(v, "si") != 0)
            return cli_bad_value(&sim_cli, "units", v, "thesis or si");
        a->units = v;
        return 0;
    case OPT_ALGORITHM:
        if (strcmp(v, "1") != 0 && strcmp(v, "2") != 0 && strcmp(v, "3") != 0)
            return cli_bad_value(&sim_cli, "algorithm", v, "1, 2 or 3");
        a->algorithm = v[0] - '0';
        return 0;
    case OPT_END_S:
        return cli_double(&sim_cli, "end-s", v, 1e-9, 1e7, &a->end_s);
    }
    return CLI_EXIT_BAD_INPUT;
}

/* CLI_CONTINUE to go on, else the exit status (0 after --help/--version). */
static int parse_args(int argc, char **argv, sim_args *a)
{
    *a = (sim_args){.units = "thesis"};
    int rc = cli_parse(&sim_cli, argc, argv, parse_option, a, NULL);
    if (rc != CLI_CONTINUE || a->dump)
        return rc;
    if (a->commission && a->config && !a->schedule && !a->summary && !a->plot && !a->algorithm)
        return CLI_CONTINUE;
    if (a->commission) {
        fprintf(stderr, "leveler-sim: --commission needs --config FILE and takes only --log and --end-s besides\n");
        return CLI_EXIT_BAD_INPUT;
    }
    if (!a->config || !a->log) {
        fprintf(stderr, "leveler-sim: --config and --log are required (see leveler-sim --help)\n");
        return CLI_EXIT_BAD_INPUT;
    }
    if ((a->summary || a->plot) && strcmp(a->log, "-") == 0) {
        fprintf(stderr, "leveler-sim: --summary/--plot need --log to be a file\n");
        return CLI_EXIT_BAD_INPUT;
    }
    return CLI_CONTINUE;
}

/* The run in a paragraph: faults, what the outputs did, the model's valid range. */
static void print_summary(const plant_config *cfg, const sim_result *res)
{
    const sim_events *e = &res->events;
    printf("summary: ");
    if (!e->latched_bits)
        printf("no fault latched.");
    for (int c = 0; c < SIM_FAULT_CODES; c++)
        if (e->latched_bits & (1u << c))
            printf("the supervisor latched %s at %.2f s. ", runlog_fault_name(c + 1), e->fault_t_s[c]);
    if (e->latched_bits && !isnan(e->safe_from_s))
        printf("The outputs were held safe from %.2f s for %.2f s of the %.2f s run (a rig needs a clear_faults "
               "write to resume).",
               e->safe_from_s, e->safe_s, res->end_s);
    printf("\n");
    const double in = PLANT_M_PER_IN;
    if (e->end_stop)
        printf("warning: the platform reached its %s end stop (%.2f in, [platform] height_%s) at %.2f s: the model "
               "is valid only inside the spring's travel, %.2f..%.2f in.\n",
               e->end_stop < 0 ? "bottom" : "top", (e->end_stop < 0 ? cfg->plant.height_min_m : cfg->plant.height_max_m) / in,
               e->end_stop < 0 ? "min" : "max", e->end_stop_t_s, cfg->plant.height_min_m / in,
               cfg->plant.height_max_m / in);
    if (!isnan(e->load_out_t_s))
        printf("warning: the load %.0f N (%.0f lbf) at %.2f s is outside the loads the model was fitted for, "
               "%.0f..%.0f lbf ([spring] load_min/load_max).\n",
               e->load_out_n, e->load_out_n / PLANT_N_PER_LBF, e->load_out_t_s,
               cfg->valid_load_min_n / PLANT_N_PER_LBF, cfg->valid_load_max_n / PLANT_N_PER_LBF);
    printf("final height %.3f in (%.4f m)\n", res->final_plant.x[PLANT_X_Y] / in, res->final_plant.x[PLANT_X_Y]);
}

/* Load, open the log, run, close: the exit status. *not_thesis: the run is not
 * a thesis case (the thesis ran its own scenario, algorithm 1 without and 2
 * with an accumulator). */
static int simulate(const sim_args *a, int *not_thesis)
{
    static plant_config cfg;
    char err[1024];
    if (plant_config_load(a->config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 2;
    }
    sim_load_step *steps = NULL;
    size_t nsteps = 0;
    if (a->schedule && (sim_schedule_load(a->schedule, &steps, &nsteps, err, sizeof err) != 0 ||
                        sim_schedule_check_loads(&cfg, a->schedule, steps, nsteps, err, sizeof err) != 0)) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        free(steps);
        return 2;
    }
    runlog_options lo = {.path = a->log, .config_name = cfg.name, .source = "sim", .buffered = 1};
    runlog *rl = runlog_open(&lo, err, sizeof err);
    if (!rl) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        free(steps);
        return 2;
    }
    int algorithm = a->algorithm ? a->algorithm : cfg.algorithm;
    *not_thesis = a->schedule != NULL || algorithm != (cfg.plant.acc_type == PLANT_ACC_NONE ? 1 : 2);
    sim_options so = {.config = &cfg, .algorithm = a->algorithm, .steps = steps, .step_count = nsteps,
                      .end_s = a->end_s, .log = rl, .progress = progress, .progress_user = (void *)&a->quiet};
    static sim_result res;
    int rc = sim_run(&so, &res, err, sizeof err);
    free(steps);
    if (runlog_close(rl) != 0 && rc == 0) {
        fprintf(stderr, "leveler-sim: closing %s failed: %s\n", a->log, strerror(errno));
        return 1;
    }
    if (rc != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 1;
    }
    if (!a->quiet || res.events.latched_bits)
        print_summary(&cfg, &res);
    return a->fail_on_fault && res.events.latched_bits ? 1 : 0;
}

static void print_commissioning(const sim_commissioning *c)
{
    const double psi = PLANT_PA_PER_PSI;
    printf("commissioning: %s after %.2f s (%u moves of algorithm 3 in the run)\n",
           sim_commissioning_result_name(c->result), c->took_s, c->moves);
    printf("  up line at the target %.3f in: learnt %.2f psia, the plant's %.2f psia (%+.2f psi)\n",
           c->target_m / PLANT_M_PER_IN, c->up_pa / psi, c->true_up_pa / psi, (c->up_pa - c->true_up_pa) / psi);
    printf("  down line:                     learnt %.2f psia, the plant's %.2f psia (%+.2f psi)\n", c->down_pa / psi,
           c->true_down_pa / psi, (c->down_pa - c->true_down_pa) / psi);
    printf("  gap %.2f psi (lines %.2f psi apart); coast up %u ms, %d Pa/mm; coast down %u ms, %d Pa/mm\n",
           c->gap_pa / psi, (c->true_up_pa - c->true_down_pa) / psi, c->coast_up_ms, c->k_up_pa_per_mm,
           c->coast_down_ms, c->k_down_pa_per_mm);
    printf("  platform %.3f in at the end of the run: %s the band\n", c->final_height_m / PLANT_M_PER_IN,
           c->in_band ? "inside" : "OUTSIDE");
}

/* --commission: 0 done within 60 s and in the band, 1 not, 2 bad input. */
static int commission(const sim_args *a)
{
    static plant_config cfg;
    char err[1024];
    if (plant_config_load(a->config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 2;
    }
    runlog *rl = NULL;
    if (a->log) {
        runlog_options lo = {.path = a->log, .config_name = cfg.name, .source = "sim", .buffered = 1};
        if (!(rl = runlog_open(&lo, err, sizeof err))) {
            fprintf(stderr, "leveler-sim: %s\n", err);
            return 2;
        }
    }
    sim_commissioning c;
    int rc = sim_commissioning_run(&cfg, a->end_s, rl, &c, err, sizeof err);
    if (rl && runlog_close(rl) != 0 && rc == 0) {
        fprintf(stderr, "leveler-sim: closing %s failed: %s\n", a->log, strerror(errno));
        return 1;
    }
    if (rc != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 1;
    }
    print_commissioning(&c);
    return c.result == 1 && c.in_band ? 0 : 1;
}

int main(int argc, char **argv)
{
    sim_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc != CLI_CONTINUE)
        return rc;
    if (a.dump)
        return dump_config(a.config);
    if (a.commission)
        return commission(&a);
    int not_thesis = 1;
    rc = simulate(&a, &not_thesis);
    if (rc != 2 && (a.summary || a.plot)) {
        int report = run_report(a.log, a.summary, a.plot, a.config, a.units, not_thesis);
        rc = rc ? rc : report;
    }
    return rc;
}
