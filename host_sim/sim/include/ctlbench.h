/*
 * Controller benchmark (a scorecard, not a timed test): a suite of scenarios
 * run with the firmware in the loop (sim_run) for algorithms 1, 2 and 3, and
 * the control-quality figures of each run. docs/controller.md defines every
 * figure; leveler-ctlbench prints them (ctlbench_main.c), the acceptance test
 * (tests/sim/test_ctlbench.c) runs the short suite.
 */
#ifndef LEVELER_CTLBENCH_H
#define LEVELER_CTLBENCH_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "simloop.h"

#define CTLBENCH_MAX_STEPS 64
#define CTLBENCH_NAME_MAX 64

typedef enum { CTLBENCH_THESIS = 0, CTLBENCH_REST = 1, CTLBENCH_RANDOM = 2 } ctlbench_kind;

typedef struct {
    char name[CTLBENCH_NAME_MAX];
    char config[CTLBENCH_NAME_MAX]; /* file name under the configs folder */
    int kind;                       /* ctlbench_kind */
    double noise_counts;            /* sensor noise, standard deviation in ADC counts */
    uint32_t noise_seed;
    sim_load_step steps[CTLBENCH_MAX_STEPS]; /* steps[0] at 0 s is the base load */
    size_t step_count;
    double end_s;
    double rest_from_s, rest_to_s;  /* REST: the window at rest that is scored */
    bool commission;                /* the firmware's commissioning routine runs from 0 s (sim_options) */
} ctlbench_scenario;

/* One load step (steps[1..]): from its time to the next step's (or the end). */
typedef struct {
    double t_s;
    double load_change_n;
    bool left_band;        /* the platform went outside the band in the window */
    bool settled;          /* in the band at the end of the window */
    double first_entry_s;  /* back in the band the first time, 1 s or more after the step (0: never left) */
    double return_s;       /* in the band and staying there until the window's end (window length if not) */
    double overshoot_m;    /* after the first entry: farthest outside the band (shooting through it, or a
                            * later departure within the step's window) */
    unsigned switchings;   /* ticks on which any output changed */
} ctlbench_step;

typedef struct {
    int algorithm;
    size_t step_count;
    ctlbench_step step[CTLBENCH_MAX_STEPS];
    double return_median_s, return_worst_s;
    unsigned unsettled_steps;
    double overshoot_max_m;
    double switchings_per_step;
    unsigned switchings;        /* whole run */
    double rest_switchings_per_min; /* REST window (NAN otherwise) */
    unsigned rest_switchings;
    /* rest_switchings split (ctlbench_rest_split): while the last step's return was still under way (up to
     * the first tick at or after its back-to-stay with the spring and vent valves shut; all of them if it
     * never settled), the compressor and accumulator valve alone after it (a recharge), and switchings of
     * the spring or vent valve after it (a fill or vent at rest: hunting) */
    unsigned rest_returning, rest_recharge, rest_moves;
    double rest_outside_s;
    double compressor_on_s;
    double vented_kg;
    double outside_s;           /* time outside the band over the whole run */
    uint16_t latched_faults;    /* firmware latched fault bits at the end */
} ctlbench_metrics;

/* The random load sequences' seed unless the user gives another. */
#define CTLBENCH_RANDOM_SEED 2026u

/* The suite: full (the scenarios) or short (the acceptance test's);
 * random_seed draws the random load sequences (full suite only).
 * Fills out[0..cap-1]; returns the count. */
size_t ctlbench_suite(bool short_suite, uint32_t random_seed, ctlbench_scenario *out, size_t cap);
/* The suite on one config (a rig of the user's: the file config.ini in the
 * configs folder): the thesis steps at 900 lb, the rest with 2 counts of noise
 * and (full suite) the random load sequence. Returns the count. */
size_t ctlbench_suite_for(const char *config, bool short_suite, uint32_t random_seed, ctlbench_scenario *out,
                          size_t cap);

/*
 * Run one scenario with one algorithm. configs_dir holds the INI files;
 * log_path (optional) receives the run log. rows/rows_cap: a caller buffer of
 * at least end_s/0.01 + 2 rows. 0 or -1 with a message in err.
 */
int ctlbench_run(const ctlbench_scenario *sc, int algorithm, const char *configs_dir, const char *log_path,
                 runlog_row *rows, size_t rows_cap, ctlbench_metrics *m, char *err, size_t err_len);

/* The 900 lb thesis steps (+200 lb at 5 s, removed at 35 s), then rest_s of
 * rest scored from 60 s after the removal, with `noise` counts of sensor noise. */
void ctlbench_thesis_rest(ctlbench_scenario *sc, const char *name, const char *config_file, double noise,
                          uint32_t seed, double rest_s);

/* The 900 lb thesis steps after commissioning: the coil written at 0 s, the base load held for
 * LEVELER_COMMISSION_MAX_MS, then +200 lb 5 s later, removed 30 s after that, 60 s to settle. */
void ctlbench_thesis_commissioned(ctlbench_scenario *sc, const char *name, const char *config_file, double noise,
                                  uint32_t seed);

/* The scenario's config as the runs use it: loaded from configs_dir, the
 * scenario's noise, and for algorithms 1 and 2 (and the limit, 0) no chatter
 * fault. 0 or -1 with the loader's message. */
int ctlbench_config(const ctlbench_scenario *sc, int algorithm, const char *configs_dir, plant_config *cfg,
                    char *err, size_t err_len);

/* sim_run with an optional run log at log_path (so->log is ignored). */
int ctlbench_simulate(const ctlbench_scenario *sc, const sim_options *so, const char *log_path, sim_result *res,
                      char *err, size_t err_len);

/* The figures of a finished run (its rows from t = 0) into m. */
void ctlbench_score(const ctlbench_scenario *sc, const plant_config *cfg, const runlog_row *rows, const sim_result *res,
                    int algorithm, ctlbench_metrics *m);

/* m->rest_returning, rest_recharge and rest_moves of a REST run from its rows and m->step[] (scored). */
void ctlbench_rest_split(const ctlbench_scenario *sc, const runlog_row *rows, size_t n, ctlbench_metrics *m);

/* The figures over the steps (median, worst, unsettled, overshoot, switchings per step) from m->step[]. */
void ctlbench_aggregate(ctlbench_metrics *m);

/* Rows the longest scenario of a suite needs. */
size_t ctlbench_rows_needed(const ctlbench_scenario *sc, size_t count);

#endif /* LEVELER_CTLBENCH_H */
