/* The firmware-in-the-loop run (simloop.h) on the one stepper (stepper.h). */
#include "simloop.h"

#include "leveler/status.h"
#include "runlog_firmware.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* What the firmware read (from its second tick on; the first row, before its
 * first reading, holds the transducers' values), its state, and the truth. */
static void fill_row(runlog_row *row, const sim_stepper *s, bool has_acc)
{
    *row = runlog_row_empty();
    row->t_s = s->t_s_now;
    row->true_height_m = s->sensed[0];
    row->true_p_spring_pa = s->sensed[1];
    row->true_p_pipe_pa = s->sensed[2];
    row->true_p_acc_pa = has_acc ? s->sensed[3] : NAN;
    if (s->k == 0 && s->initial_outputs) {
        row->height_m = row->true_height_m;
        row->p_spring_pa = row->true_p_spring_pa;
        row->p_pipe_pa = row->true_p_pipe_pa;
        row->p_acc_pa = row->true_p_acc_pa;
    } else {
        runlog_row_firmware_readings(row, has_acc);
    }
    runlog_row_firmware_state(row);
    row->load_n = s->in.load_n;
    row->compressor = s->out[HAL_OUT_COMPRESSOR];
    row->spring_valve = s->out[HAL_OUT_SPRING_VALVE];
    row->vent_valve = s->out[HAL_OUT_VENT_VALVE];
    row->acc_valve = s->out[HAL_OUT_ACC_VALVE];
}

/* One row per tick into the caller's buffer and the log. */
static int record(const sim_options *o, sim_result *res, const sim_stepper *s, char *err, size_t err_len)
{
    if (!o->log && !(o->rows && res->rows < o->rows_cap))
        return 0;
    runlog_row row;
    fill_row(&row, s, o->config->plant.acc_type != PLANT_ACC_NONE);
    if (o->rows && res->rows < o->rows_cap)
        o->rows[res->rows++] = row;
    if (o->log && runlog_write(o->log, &row) != 0) {
        snprintf(err, err_len, "run log: write failed at t = %.2f s", s->t_s_now);
        return -1;
    }
    return 0;
}

static void events_start(sim_events *e)
{
    memset(e, 0, sizeof *e);
    for (int c = 0; c < SIM_FAULT_CODES; c++)
        e->fault_t_s[c] = NAN;
    e->safe_from_s = e->end_stop_t_s = e->load_out_t_s = NAN;
}

/* After the firmware's decision of a tick: faults, end stops, loads. */
static void events_track(sim_events *e, const sim_stepper *s)
{
    const leveler_status *st = leveler_app_status();
    const plant_params *p = &s->cfg->plant;
    uint16_t fresh = (uint16_t)(st->latched_fault_bits & ~e->latched_bits);
    for (int c = 0; c < SIM_FAULT_CODES; c++)
        if (fresh & (1u << c))
            e->fault_t_s[c] = s->t_s_now;
    e->latched_bits |= st->latched_fault_bits;
    if (st->fault_latched && st->outputs_safe) {
        if (isnan(e->safe_from_s))
            e->safe_from_s = s->t_s_now;
        e->safe_s += SIM_TICK_S;
    }
    double y = ((const plant_fx *)s->plant)->pl.x[PLANT_X_Y], tol = 1e-9; /* sim_run's plant */
    if (!e->end_stop && (y <= p->height_min_m + tol || y >= p->height_max_m - tol)) {
        e->end_stop = y <= p->height_min_m + tol ? -1 : 1;
        e->end_stop_t_s = s->t_s_now;
    }
    double load = s->in.load_n;
    if (isnan(e->load_out_t_s) && (load < s->cfg->valid_load_min_n || load > s->cfg->valid_load_max_n)) {
        e->load_out_t_s = s->t_s_now;
        e->load_out_n = load;
    }
}

int sim_run(const sim_options *o, sim_result *res, char *err, size_t err_len)
{
    const plant_config *cfg = o->config;
    sim_load_step builtin[4];
    sim_schedule_cursor cursor = {o->steps, o->step_count, 0};
    double end_s;
    if (!o->steps) {
        cursor.count = sim_schedule_from_config(cfg, builtin, &end_s);
        cursor.steps = builtin;
    } else {
        end_s = o->steps[o->step_count - 1].t_s;
    }
    if (o->end_s > 0.0)
        end_s = o->end_s;
    memset(res, 0, sizeof *res);
    events_start(&res->events);

    static plant_fx f; /* large; one simulation at a time anyway */
    if (sim_plant_open(&f, cfg, NULL, 0, NULL, NULL) != 0) {
        snprintf(err, err_len, "%s: the config's effects cannot run", cfg->path);
        return -1;
    }
    plant_rng rng;
    plant_rng_seed(&rng, cfg->sensors.noise_seed);
    if (sim_firmware_start(cfg, o->algorithm ? o->algorithm : cfg->algorithm, err, err_len) != 0)
        return -1;
    if (o->commission && sim_firmware_commission(err, err_len) != 0)
        return -1;
    /* The run starts from a rig already running: the first tick keeps the
     * config's [initial] actuators and the firmware first decides at the end
     * of it, as Appendix B's controller does after its first step. */
    sim_schedule_writer writer = {.steps = cursor.steps, .count = cursor.count};
    sim_stepper st = {.cfg = cfg, .plant = &f, .ops = &sim_fx_plant, .commands = sim_firmware_commands,
                      .commands_user = &writer, .load = sim_load_from_schedule, .load_user = &cursor,
                      .rng = cfg->sensors.noise_counts > 0.0 ? &rng : NULL, .initial_outputs = true};
    sim_stepper_start(&st);

    const uint64_t ticks = (uint64_t)llround(end_s / SIM_TICK_S);
    double next_progress = 0.0;
    for (;;) {
        sim_stepper_decide(&st);
        if (writer.failed) {
            snprintf(err, err_len, "%s", writer.err);
            return -1;
        }
        if (st.k > 0)
            events_track(&res->events, &st);
        if (record(o, res, &st, err, err_len) != 0)
            return -1;
        res->ticks++;
        if (o->progress && st.t_s_now >= next_progress) {
            o->progress(st.t_s_now, end_s, o->progress_user);
            next_progress += end_s / 20.0;
        }
        if (st.k >= ticks)
            break;
        sim_stepper_advance(&st);
    }
    res->end_s = end_s;
    res->final_plant = f.pl;
    return 0;
}
