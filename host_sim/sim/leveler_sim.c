/*
 * leveler-sim: the unchanged firmware against the plant model.
 *
 *   leveler-sim --config FILE [--schedule FILE] [--algorithm 1|2|3] --log run.csv
 *               [--summary run.json] [--plot run.png] [--units thesis|si] [--end-s S]
 *   leveler-sim --dump-config [--config FILE]
 *
 * Writes the run log (runlog.h format). With --summary/--plot it then runs
 *   $LEVELER_PYTHON -m leveler.report --log run.csv ... (PYTHONPATH=<source>/scripts)
 * which prints the thesis comparison table. LEVELER_PYTHON and
 * LEVELER_SCRIPTS_DIR in the environment override the built-in paths.
 * Exit status: 0 ok, 2 usage or configuration error, 1 run or report failure.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pyrun.h"
#include "simloop.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: leveler-sim --config FILE [--schedule FILE] [--algorithm 1|2|3] --log run.csv\n"
            "                   [--summary run.json] [--plot run.png] [--units thesis|si] [--end-s S]\n"
            "  --config FILE      plant, sensors, controller settings, scenario (docs/config-format.md)\n"
            "  --schedule FILE    load steps, CSV t_s,load_n (replaces the config's scenario); optional\n"
            "                     columns mode, manual_compressor, manual_spring_valve, manual_vent_valve,\n"
            "                     manual_acc_valve are written through the register map at each row\n"
            "  --algorithm 1|2|3  1 no accumulator, 2 accumulator, 3 hysteresis-aware (docs/controller.md)\n"
            "                     (default: the config's)\n"
            "  --log FILE         run log, one row per 10 ms tick (\"-\" = stdout)\n"
            "  --summary FILE     event figures as JSON (runs python -m leveler.report)\n"
            "  --plot FILE        figure of the run (runs python -m leveler.report)\n"
            "  --units thesis|si  units of the printed comparison table (default thesis)\n"
            "  --end-s S          simulate to S seconds (holds the last load past the schedule)\n"
            "  --dump-config      print the resolved config (the built-in one without --config)\n"
            "                     as JSON in SI units and exit (what scripts/leveler/config.py reads)\n");
}

static void progress(double t_s, double end_s, void *user)
{
    (void)user;
    if (end_s >= 600.0)
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

static int run_report(const char *log, const char *summary, const char *plot, const char *config, const char *units)
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
    int dump;
    double end_s;
} sim_args;

/* One option with its value v. 0, or the exit status (2) after a message. */
static int parse_option(sim_args *a, const char *opt, const char *v)
{
    if (strcmp(opt, "--config") == 0)
        a->config = v;
    else if (strcmp(opt, "--schedule") == 0)
        a->schedule = v;
    else if (strcmp(opt, "--log") == 0)
        a->log = v;
    else if (strcmp(opt, "--summary") == 0)
        a->summary = v;
    else if (strcmp(opt, "--plot") == 0)
        a->plot = v;
    else if (strcmp(opt, "--units") == 0) {
        if (strcmp(v, "thesis") != 0 && strcmp(v, "si") != 0) {
            fprintf(stderr, "leveler-sim: --units must be thesis or si, not '%s'\n", v);
            return 2;
        }
        a->units = v;
    } else if (strcmp(opt, "--algorithm") == 0) {
        if (strcmp(v, "1") != 0 && strcmp(v, "2") != 0 && strcmp(v, "3") != 0) {
            fprintf(stderr, "leveler-sim: --algorithm must be 1, 2 or 3, not '%s'\n", v);
            return 2;
        }
        a->algorithm = v[0] - '0';
    } else if (strcmp(opt, "--end-s") == 0) {
        char *e;
        a->end_s = strtod(v, &e);
        if (*e || !(a->end_s > 0.0 && a->end_s <= 1e7)) {
            fprintf(stderr, "leveler-sim: --end-s must be a number in (0, 1e7], not '%s'\n", v);
            return 2;
        }
    } else {
        fprintf(stderr, "leveler-sim: unknown option '%s'\n", opt);
        usage(stderr);
        return 2;
    }
    return 0;
}

/* -1 to go on, else the exit status (0 after --help). */
static int parse_args(int argc, char **argv, sim_args *a)
{
    *a = (sim_args){.units = "thesis"};
    for (int i = 1; i < argc; i++) {
        const char *opt = argv[i];
        if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (strcmp(opt, "--dump-config") == 0) {
            a->dump = 1;
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "leveler-sim: %s needs a value\n", opt);
            usage(stderr);
            return 2;
        }
        int rc = parse_option(a, opt, argv[++i]);
        if (rc != 0)
            return rc;
    }
    if (a->dump)
        return -1;
    if (!a->config || !a->log) {
        fprintf(stderr, "leveler-sim: --config and --log are required\n");
        usage(stderr);
        return 2;
    }
    if ((a->summary || a->plot) && strcmp(a->log, "-") == 0) {
        fprintf(stderr, "leveler-sim: --summary/--plot need --log to be a file\n");
        return 2;
    }
    return -1;
}

/* Load, open the log, run, close: the exit status. */
static int simulate(const sim_args *a)
{
    static plant_config cfg;
    char err[1024];
    if (plant_config_load(a->config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 2;
    }
    sim_load_step *steps = NULL;
    size_t nsteps = 0;
    if (a->schedule && sim_schedule_load(a->schedule, &steps, &nsteps, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        return 2;
    }
    runlog_options lo = {.path = a->log, .config_name = cfg.name, .source = "sim", .buffered = 1};
    runlog *rl = runlog_open(&lo, err, sizeof err);
    if (!rl) {
        fprintf(stderr, "leveler-sim: %s\n", err);
        free(steps);
        return 2;
    }
    sim_options so = {.config = &cfg, .algorithm = a->algorithm, .steps = steps, .step_count = nsteps,
                      .end_s = a->end_s, .log = rl, .progress = progress};
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
    return 0;
}

int main(int argc, char **argv)
{
    sim_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc >= 0)
        return rc;
    if (a.dump)
        return dump_config(a.config);
    rc = simulate(&a);
    if (rc == 0 && (a.summary || a.plot))
        rc = run_report(a.log, a.summary, a.plot, a.config, a.units);
    return rc;
}
