/*
 * The limit of a scenario (issue 19): for every load step the best a single
 * move can do on the same plant with perfect knowledge, from the state the
 * plant was in at the step (algorithm 3's: its run up to the step instant).
 * At the step instant every fill path (compressor, spring valve, and the
 * accumulator valve when one is fitted, until it stops feeding the pipe:
 * P3 <= P1) or every vent path (spring and vent valves) opens; all close
 * together at one instant on the 10 ms tick grid. It fills when the
 * platform left alone would rest below the band's target, else vents.
 * The close is searched on the simulator itself: each candidate is a
 * firmware-in-the-loop run (sim_run) of algorithm 3 up to the step, then the
 * firmware in manual mode with the move written as a schedule's manual
 * requests (like `leveler-sim --schedule` with mode = 2).
 *
 * The landing (the height at rest: at the end of the step's window, at most
 * CTLBENCH_LIMIT_LOOK_S after the step) rises with the fill's length and falls
 * with the vent's, so each search is a bisection over the grid (the
 * acceptance test checks one against the exhaustive scan). The close chosen:
 *  - the one landing nearest the band's target (its middle), when the
 *    platform is back in the band before it (the return cannot be sooner
 *    than with every path open);
 *  - else the first tick at which the platform, every path open, is back in
 *    the band, if it lands in the band from there (the fastest return that
 *    lands inside);
 *  - else the latest close that still lands in the band.
 * So the limit's return is a lower bound for a move that lands in the band.
 */
#ifndef LEVELER_CTLBENCH_LIMIT_H
#define LEVELER_CTLBENCH_LIMIT_H

#include "ctlbench.h"

#define CTLBENCH_LIMIT_LOOK_S 60.0 /* the landing is the height this long after the step (or at the next step) */
#define CTLBENCH_LIMIT_ALGORITHM 0 /* ctlbench_metrics.algorithm of the limit's run */

typedef struct {
    long open_ticks[CTLBENCH_MAX_STEPS];  /* per step (index = scenario step - 1): 0 = no move */
    long target_ticks[CTLBENCH_MAX_STEPS]; /* the close landing nearest the target */
    int dir[CTLBENCH_MAX_STEPS];          /* +1 fill (the platform left alone rests below the target), -1 vent */
    long acc_ticks[CTLBENCH_MAX_STEPS];   /* a fill's accumulator valve closes after this (P3 <= P1), 0 = none */
    double landing_m[CTLBENCH_MAX_STEPS]; /* the height at the end of the step's window */
    double target_m;
} ctlbench_limit_moves;

/*
 * The limit's move for every step of sc, each step's window scored from its
 * own run into m (algorithm CTLBENCH_LIMIT_ALGORITHM; the run-wide figures
 * over the windows put together, which log_path receives as one run log).
 * rows: as ctlbench_run's. 0 or -1 with a message in err.
 */
int ctlbench_limit(const ctlbench_scenario *sc, const char *configs_dir, const char *log_path, runlog_row *rows,
                   size_t rows_cap, ctlbench_metrics *m, ctlbench_limit_moves *mv, char *err, size_t err_len);

/*
 * One candidate: the landing height (m) when step `step` (1-based scenario
 * step) opens its paths for open_ticks (0 = no move), its direction and
 * accumulator close as in mv. cfg from ctlbench_config(sc, 3, ...). 0 or -1.
 */
int ctlbench_limit_landing(const ctlbench_scenario *sc, const plant_config *cfg, const ctlbench_limit_moves *mv,
                           size_t step, long open_ticks, double *landing_m, char *err, size_t err_len);

/* The last tick a move of step `step` may stay open for (the landing's look ahead). */
long ctlbench_limit_max_ticks(const ctlbench_scenario *sc, size_t step);

#endif /* LEVELER_CTLBENCH_LIMIT_H */
