/* The firmware-in-the-loop run (simloop.h). */
#include "simloop.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "leveler/app.h"
#include "leveler/hal.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

#include "commission.h"

static void fill_row(runlog_row *row, const plant *pl, double t_s, const bool out[5])
{
    row->t_s = t_s;
    row->height_m = pl->x[PLANT_X_Y];
    row->p_spring_pa = pl->x[PLANT_X_P2];
    row->p_pipe_pa = pl->x[PLANT_X_P1];
    row->p_acc_pa = pl->p.acc_type == PLANT_ACC_NONE ? NAN : pl->x[PLANT_X_P3];
    row->load_n = pl->in.load_n;
    row->compressor = out[HAL_OUT_COMPRESSOR];
    row->solenoid = out[HAL_OUT_SPRING_VALVE];
    row->vent = out[HAL_OUT_VENT_VALVE];
    row->acc_valve = out[HAL_OUT_ACC_VALVE];
}

int sim_run(const sim_options *o, sim_result *res, char *err, size_t err_len)
{
    const plant_config *cfg = o->config;
    sim_load_step builtin[4];
    const sim_load_step *steps = o->steps;
    size_t nsteps = o->step_count;
    double end_s;
    if (!steps) {
        nsteps = sim_schedule_from_config(cfg, builtin, &end_s);
        steps = builtin;
    } else {
        end_s = steps[nsteps - 1].t_s;
    }
    if (o->end_s > 0.0)
        end_s = o->end_s;
    int algorithm = o->algorithm ? o->algorithm : cfg->algorithm;
    memset(res, 0, sizeof *res);

    static plant pl; /* large; one simulation at a time anyway */
    plant_init(&pl, &cfg->plant);
    plant_rng rng;
    plant_rng_seed(&rng, cfg->sensors.noise_seed);
    plant_rng *rngp = cfg->sensors.noise_counts > 0.0 ? &rng : NULL;

    sim_hal_reset();
    leveler_app_init();
    if (sim_commission(cfg, algorithm, err, err_len) != 0)
        return -1;

    const uint32_t tick_ms = LEVELER_TICK_MS;
    const double tick_s = tick_ms / 1000.0;
    const uint64_t ticks = (uint64_t)llround(end_s / tick_s);
    size_t step_i = 0;
    plant_inputs in = {false, false, false, false, steps[0].load_n};
    bool out[5];
    uint16_t counts[4];
    double next_progress = 0.0;

    for (uint64_t k = 0;; k++) {
        double t = (double)k * tick_s;
        if (k == 0) {
            /* The run starts from a rig already running: the first tick keeps
             * the config's [initial] actuators and the firmware first decides
             * at the end of it, as Appendix B's controller does after its first
             * step. */
            sim_initial_outputs(cfg, out);
        } else {
            /* sense and control at t */
            plant_sensor_counts(&pl, &cfg->sensors, rngp, counts);
            sim_hal_set_counts(counts);
            sim_hal_set_time_ms((uint32_t)(k * tick_ms));
            leveler_app_tick();
            sim_hal_get_outputs(out);
        }
        /* the load for the interval starting at t (half a tick of slack against rounding) */
        while (step_i + 1 < nsteps && steps[step_i + 1].t_s <= t + 0.5 * tick_s)
            step_i++;
        in.load_n = steps[step_i].load_n;
        in.compressor = out[HAL_OUT_COMPRESSOR];
        in.spring_valve = out[HAL_OUT_SPRING_VALVE];
        in.vent_valve = out[HAL_OUT_VENT_VALVE];
        in.acc_valve = out[HAL_OUT_ACC_VALVE];
        plant_set_inputs(&pl, &in);
        if (o->log || (o->rows && res->rows < o->rows_cap)) {
            runlog_row row;
            fill_row(&row, &pl, t, out);
            if (o->rows && res->rows < o->rows_cap)
                o->rows[res->rows++] = row;
            if (o->log && runlog_write(o->log, &row) != 0) {
                snprintf(err, err_len, "run log: write failed at t = %.2f s", t);
                return -1;
            }
        }
        res->ticks++;
        if (o->progress && t >= next_progress) {
            o->progress(t, end_s, o->progress_user);
            next_progress += end_s / 20.0;
        }
        if (k >= ticks)
            break;
        plant_advance(&pl, tick_s, cfg->substeps_per_tick);
    }
    res->end_s = end_s;
    res->final_plant = pl;
    return 0;
}
