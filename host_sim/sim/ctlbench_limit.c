/* The limit of a scenario: the best single move per load step (ctlbench_limit.h). */
#include "ctlbench_limit.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "leveler/settings.h"

#define LIMIT_ROWS (CTLBENCH_MAX_STEPS + 3)
/* The firmware before the step: algorithm 3 (the state the limit starts from is its run's). */
#define LIMIT_FIRMWARE_ALGORITHM 3

typedef struct {
    bool on[HAL_OUT_COUNT];
} outputs;

/* A schedule row at t_s under load_n that writes manual mode and every manual request. */
static sim_load_step manual_row(double t_s, double load_n, const outputs *o)
{
    sim_load_step r = {.t_s = t_s, .load_n = load_n};
    for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++) {
        const sim_schedule_reg *reg = &sim_schedule_regs[j];
        r.writes |= (uint8_t)(1u << j);
        r.value[j] = reg->output < 0 ? (uint16_t)LEVELER_MODE_MANUAL : (uint16_t)o->on[reg->output];
    }
    return r;
}

/* A step's move: fill (+1) or vent (-1), every path open for `open` ticks; the accumulator's closes after
 * `acc` ticks (when it stops feeding the pipe). */
typedef struct {
    int dir;
    long open, acc;
} move;

/* Every fill path (the accumulator's with it when fitted and still open) or every vent path. */
static outputs paths(const plant_config *cfg, int dir, bool acc_open)
{
    outputs o = {{false}};
    bool fill = dir > 0;
    o.on[HAL_OUT_COMPRESSOR] = fill;
    o.on[HAL_OUT_SPRING_VALVE] = true;
    o.on[HAL_OUT_VENT_VALVE] = !fill;
    o.on[HAL_OUT_ACC_VALVE] = fill && acc_open && cfg->plant.acc_type != PLANT_ACC_NONE;
    return o;
}

/* The scenario's loads up to step `step` (algorithm 3 in charge), then from the step instant manual
 * mode: the move's paths open, then everything shut. Returns the count. */
static size_t schedule(const ctlbench_scenario *sc, const plant_config *cfg, size_t step, const move *mv,
                       sim_load_step out[LIMIT_ROWS])
{
    size_t n = 0;
    for (size_t k = 0; k < step && k < sc->step_count; k++)
        out[n++] = (sim_load_step){.t_s = sc->steps[k].t_s, .load_n = sc->steps[k].load_n};
    const sim_load_step *st = &sc->steps[step];
    outputs shut = {{false}};
    outputs o = mv->open > 0 ? paths(cfg, mv->dir, mv->acc > 0) : shut;
    out[n++] = manual_row(st->t_s, st->load_n, &o);
    if (mv->open > 0 && mv->acc > 0 && mv->acc < mv->open) {
        outputs no_acc = paths(cfg, mv->dir, false);
        out[n++] = manual_row(st->t_s + (double)mv->acc * SIM_TICK_S, st->load_n, &no_acc);
    }
    if (mv->open > 0)
        out[n++] = manual_row(st->t_s + (double)mv->open * SIM_TICK_S, st->load_n, &shut);
    return n;
}

static double window_end_s(const ctlbench_scenario *sc, size_t step)
{
    return step + 1 < sc->step_count ? sc->steps[step + 1].t_s : sc->end_s;
}

long ctlbench_limit_max_ticks(const ctlbench_scenario *sc, size_t step)
{
    double t = sc->steps[step].t_s, end = window_end_s(sc, step);
    if (end > t + CTLBENCH_LIMIT_LOOK_S)
        end = t + CTLBENCH_LIMIT_LOOK_S;
    return lround((end - t) / SIM_TICK_S) - 1;
}

/* Step `step`'s move, run to end_s (rows optional). */
static int run_move(const ctlbench_scenario *sc, const plant_config *cfg, size_t step, const move *mv, double end_s,
                    runlog_row *rows, size_t rows_cap, sim_result *res, char *err, size_t err_len)
{
    static sim_load_step rows_in[LIMIT_ROWS];
    size_t n = schedule(sc, cfg, step, mv, rows_in);
    sim_options so = {.config = cfg, .algorithm = LIMIT_FIRMWARE_ALGORITHM, .steps = rows_in, .step_count = n,
                      .end_s = end_s, .rows = rows, .rows_cap = rows_cap, .commission = sc->commission};
    return sim_run(&so, res, err, err_len);
}

static move move_of(const ctlbench_limit_moves *mv, size_t step, long open)
{
    return (move){.dir = mv->dir[step - 1], .open = open, .acc = mv->acc_ticks[step - 1]};
}

int ctlbench_limit_landing(const ctlbench_scenario *sc, const plant_config *cfg, const ctlbench_limit_moves *mv,
                           size_t step, long open_ticks, double *landing_m, char *err, size_t err_len)
{
    static sim_result res;
    double end = sc->steps[step].t_s + (double)(ctlbench_limit_max_ticks(sc, step) + 1) * SIM_TICK_S;
    move m = move_of(mv, step, open_ticks);
    if (run_move(sc, cfg, step, &m, end, NULL, 0, &res, err, err_len) != 0)
        return -1;
    *landing_m = res.final_plant.x[PLANT_X_Y];
    return 0;
}

/* The first open time (ticks) whose landing lies at `level` or beyond it the move's way (strictly beyond
 * when strict), by bisection over 0..max (the landing is monotonic in the open time); max + 1 when none.
 * *h_at gets its landing (or the longest move's). */
static long first_beyond(const ctlbench_scenario *sc, const plant_config *cfg, const ctlbench_limit_moves *mv,
                         size_t step, double level, bool strict, double *h_at, int *rc, char *err, size_t err_len)
{
    long lo = -1, hi = ctlbench_limit_max_ticks(sc, step) + 1; /* beyond(lo) false, beyond(hi) true */
    double h_hi = NAN, dir = mv->dir[step - 1];
    while (hi - lo > 1 && *rc == 0) {
        long mid = lo + (hi - lo) / 2;
        double h = NAN;
        *rc = ctlbench_limit_landing(sc, cfg, mv, step, mid, &h, err, err_len);
        double d = dir * (h - level);
        if (strict ? d > 0.0 : d >= 0.0)
            hi = mid, h_hi = h;
        else
            lo = mid, *h_at = h;
    }
    if (!isnan(h_hi))
        *h_at = h_hi;
    return hi;
}

/* The close landing nearest the target: the first at or beyond it, or the one before. */
static long nearest_target(const ctlbench_scenario *sc, const plant_config *cfg, const ctlbench_limit_moves *mv,
                           size_t step, int *rc, char *err, size_t err_len)
{
    double h_hi = NAN, h_lo = NAN;
    long max = ctlbench_limit_max_ticks(sc, step);
    long hi = first_beyond(sc, cfg, mv, step, mv->target_m, false, &h_hi, rc, err, err_len);
    if (*rc != 0 || hi == 0)
        return 0;
    if (hi > max)
        return max;
    *rc = ctlbench_limit_landing(sc, cfg, mv, step, hi - 1, &h_lo, err, err_len);
    return fabs(h_lo - mv->target_m) <= fabs(h_hi - mv->target_m) ? hi - 1 : hi;
}

/* With every path open to the look-ahead's end: the tick (after the step) at which the platform is back in
 * the band (LONG_MAX when never) and, for a fill with an accumulator, the first at which the accumulator
 * no longer feeds the pipe (P3 <= P1; mv->acc_ticks, else the whole move). */
static long open_run(const ctlbench_scenario *sc, const plant_config *cfg, ctlbench_limit_moves *mv, size_t step,
                     runlog_row *rows, size_t rows_cap, int *rc, char *err, size_t err_len)
{
    static sim_result res;
    static ctlbench_metrics m;
    long max = ctlbench_limit_max_ticks(sc, step);
    move all = move_of(mv, step, max);
    *rc = run_move(sc, cfg, step, &all, window_end_s(sc, step), rows, rows_cap, &res, err, err_len);
    if (*rc != 0)
        return LONG_MAX;
    size_t i0 = (size_t)llround(sc->steps[step].t_s / SIM_TICK_S);
    for (size_t i = i0 + 1; mv->acc_ticks[step - 1] > 0 && i < res.rows && (long)(i - i0) < max; i++)
        if (rows[i].true_p_acc_pa <= rows[i].true_p_pipe_pa) {
            mv->acc_ticks[step - 1] = (long)(i - i0);
            break;
        }
    ctlbench_score(sc, cfg, rows, &res, CTLBENCH_LIMIT_ALGORITHM, &m);
    const ctlbench_step *st = &m.step[step - 1];
    return st->first_entry_s > 0.0 ? lround(st->first_entry_s / SIM_TICK_S) : LONG_MAX;
}

/* The limit's close for one step (ctlbench_limit.h's rule). The move fills when the platform left alone
 * would rest below the target, else vents. */
static int search_step(const ctlbench_scenario *sc, const plant_config *cfg, ctlbench_limit_moves *mv, size_t step,
                       runlog_row *rows, size_t rows_cap, char *err, size_t err_len)
{
    double h0 = NAN;
    mv->dir[step - 1] = 1;
    if (ctlbench_limit_landing(sc, cfg, mv, step, 0, &h0, err, err_len) != 0)
        return -1;
    mv->dir[step - 1] = h0 < mv->target_m ? 1 : -1;
    bool acc = mv->dir[step - 1] > 0 && cfg->plant.acc_type != PLANT_ACC_NONE;
    mv->acc_ticks[step - 1] = acc ? LONG_MAX : 0;
    int rc = 0;
    long entry = open_run(sc, cfg, mv, step, rows, rows_cap, &rc, err, err_len);
    long target = rc == 0 ? nearest_target(sc, cfg, mv, step, &rc, err, err_len) : 0;
    mv->target_ticks[step - 1] = mv->open_ticks[step - 1] = target;
    if (rc != 0 || target == 0 || entry == LONG_MAX || entry <= target)
        return rc;
    double h;
    double far = mv->dir[step - 1] > 0 ? cfg->band_upper_m : cfg->band_lower_m;
    long last_inside = first_beyond(sc, cfg, mv, step, far, true, &h, &rc, err, err_len) - 1;
    long c = entry < last_inside ? entry : last_inside;
    mv->open_ticks[step - 1] = c > target ? c : target;
    return rc;
}

/* The rows of [from_s, to_s) from a step's run into the limit's put-together rows. */
static size_t stitch(runlog_row *dst, size_t cap, const runlog_row *src, size_t src_n, double from_s, double to_s)
{
    size_t i0 = (size_t)llround(from_s / SIM_TICK_S), i1 = (size_t)llround(to_s / SIM_TICK_S);
    i1 = i1 < src_n ? i1 : src_n;
    i1 = i1 < cap ? i1 : cap;
    for (size_t i = i0; i < i1; i++)
        dst[i] = src[i];
    return i1 > i0 ? i1 : i0;
}

/* The put-together run log (one row per tick, as a run's). */
static int write_log(const ctlbench_scenario *sc, const char *path, const runlog_row *rows, size_t n, char *err,
                     size_t err_len)
{
    runlog_options lo = {.path = path, .config_name = sc->name, .source = "sim"};
    runlog *rl = runlog_open(&lo, err, err_len);
    if (!rl)
        return -1;
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0; i++)
        rc = runlog_write(rl, &rows[i]);
    if (runlog_close(rl) != 0 || rc != 0) {
        snprintf(err, err_len, "%s: write failed", path);
        return -1;
    }
    return 0;
}

/* Every step's move searched, then run over its window, its rows put into `rows`. */
static int run_steps(const ctlbench_scenario *sc, const plant_config *cfg, ctlbench_limit_moves *mv,
                     runlog_row *rows, runlog_row *work, size_t cap, sim_result *res, char *err, size_t err_len)
{
    size_t n = 0;
    for (size_t s = 1; s < sc->step_count; s++) {
        if (search_step(sc, cfg, mv, s, work, cap, err, err_len) != 0)
            return -1;
        double end = window_end_s(sc, s);
        move chosen = move_of(mv, s, mv->open_ticks[s - 1]);
        if (run_move(sc, cfg, s, &chosen, end, work, cap, res, err, err_len) != 0)
            return -1;
        mv->landing_m[s - 1] = res->rows ? work[res->rows - 1].true_height_m : NAN;
        n = stitch(rows, cap, work, res->rows, s == 1 ? 0.0 : sc->steps[s].t_s,
                   s + 1 < sc->step_count ? end : end + SIM_TICK_S);
    }
    res->rows = n;
    return 0;
}

int ctlbench_limit(const ctlbench_scenario *sc, const char *configs_dir, const char *log_path, runlog_row *rows,
                   size_t rows_cap, ctlbench_metrics *m, ctlbench_limit_moves *mv, char *err, size_t err_len)
{
    static plant_config cfg;
    if (ctlbench_config(sc, LIMIT_FIRMWARE_ALGORITHM, configs_dir, &cfg, err, err_len) != 0)
        return -1;
    memset(mv, 0, sizeof *mv);
    mv->target_m = 0.5 * (cfg.band_lower_m + cfg.band_upper_m);
    runlog_row *work = malloc(rows_cap * sizeof *work);
    if (!work) {
        snprintf(err, err_len, "out of memory for %zu rows", rows_cap);
        return -1;
    }
    static sim_result res;
    int rc = run_steps(sc, &cfg, mv, rows, work, rows_cap, &res, err, err_len);
    free(work);
    if (rc != 0 || (log_path && write_log(sc, log_path, rows, res.rows, err, err_len) != 0))
        return -1;
    ctlbench_score(sc, &cfg, rows, &res, CTLBENCH_LIMIT_ALGORITHM, m);
    return 0;
}
