/*
 * One 10 ms tick at a time (engine.h), for the processor-in-the-loop harness
 * (host_sim/pil/leveler_pil/plant.py): the emulated STM32F103 image is the
 * controller; the engine holds the plant and knows nothing of the emulator.
 * Also the holding registers a commissioning engineer writes for a config
 * (commission.c run on the host build of the firmware, read back through
 * the register map).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "engine.h"
#include "engine_internal.h"
#include "leveler/regmap.h"
#include "simloop.h"

/* The stepper's commands hook: the outputs the image set (GPIOB), handed in
 * by engine_step_decide(). */
static void image_outputs(sim_stepper *st, void *user, bool out[HAL_OUT_COUNT])
{
    (void)st;
    memcpy(out, ((engine *)user)->step_outputs, HAL_OUT_COUNT * sizeof out[0]);
}

int engine_step_open(engine *e, char *err, int err_len)
{
    if (sim_plant_open(&e->step_fx, &e->cfg, NULL, 0, NULL, NULL) != 0) {
        snprintf(err, (size_t)err_len, "%s: the config's effects cannot run", e->name);
        return -1;
    }
    plant_rng_seed(&e->step_rng, e->cfg.sensors.noise_seed);
    e->step_cursor =
        (sim_schedule_cursor){e->step_rows, sim_schedule_from_config(&e->cfg, e->step_rows, &e->step_end_s), 0};
    e->stepper = (sim_stepper){.cfg = &e->cfg, .plant = &e->step_fx, .ops = &sim_fx_plant,
                               .commands = image_outputs, .commands_user = e, .load = sim_load_from_schedule,
                               .load_user = &e->step_cursor,
                               .rng = e->cfg.sensors.noise_counts > 0.0 ? &e->step_rng : NULL,
                               .initial_outputs = true};
    sim_stepper_start(&e->stepper);
    return e->cfg.algorithm;
}

double engine_step_end_s(const engine *e) { return e->step_end_s; }

void engine_step_counts(engine *e, int noisy, uint16_t counts[4])
{
    sim_stepper *s = &e->stepper;
    s->ops->sensed(s->plant, s->sensed);
    plant_counts(&e->cfg.sensors, s->sensed, noisy ? s->rng : NULL, counts);
}

void engine_step_decide(engine *e, const int32_t outputs[4], int32_t applied[4])
{
    for (int i = 0; i < 4; i++)
        e->step_outputs[i] = outputs[i] != 0;
    sim_stepper_decide(&e->stepper);
    for (int i = 0; i < 4; i++)
        applied[i] = e->stepper.out[i];
}

void engine_step_state(const engine *e, double out[6])
{
    const plant *pl = &e->step_fx.pl;
    out[0] = e->stepper.t_s_now;
    out[1] = pl->x[PLANT_X_Y];
    out[2] = pl->x[PLANT_X_P_SPRING];
    out[3] = pl->x[PLANT_X_P_PIPE];
    out[4] = pl->p.acc_type == PLANT_ACC_NONE ? NAN : pl->x[PLANT_X_P_ACC];
    out[5] = e->stepper.in.load_n;
}

void engine_step_advance(engine *e) { (void)sim_stepper_advance(&e->stepper); }

/* The holding register at a is 1 or 2 words (a write of its value back tells), 0 for a gap. */
static uint16_t register_words(uint16_t a, uint16_t size, uint16_t *values)
{
    for (uint16_t w = 1; w <= 2 && a + w <= size; w++)
        if (leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, a, w, &values[a], NULL) == LEVELER_REG_OK)
            return w;
    return 0;
}

/* The registers as runs FC 16 writes (at most 123 registers each). */
static int register_runs(uint16_t size, uint16_t *values, uint16_t *runs, int max_runs, char *err, int err_len)
{
    int n = 0;
    for (uint16_t a = 0; a < size;) {
        uint16_t len = register_words(a, size, values);
        if (len == 0) {
            a++; /* a gap in the table: reads pass over it (it reads 0) */
            continue;
        }
        if (n > 0 && runs[2 * n - 2] + runs[2 * n - 1] == a && runs[2 * n - 1] + len <= 123u) {
            runs[2 * n - 1] = (uint16_t)(runs[2 * n - 1] + len); /* joins the run */
        } else {
            if (n >= max_runs) {
                snprintf(err, (size_t)err_len, "more than %d register runs", max_runs);
                return -1;
            }
            runs[2 * n] = a;
            runs[2 * n + 1] = len;
            n++;
        }
        a = (uint16_t)(a + len);
    }
    return n;
}

int engine_commission_registers(engine *e, int algorithm, uint16_t *runs, int max_runs, uint16_t *values,
                                int max_values, char *err, int err_len)
{
    /* the host firmware, reset and commissioned as leveler-sim does it */
    if (sim_firmware_start(&e->cfg, algorithm ? algorithm : e->cfg.algorithm, err, (size_t)err_len) != 0)
        return -1;
    uint16_t size = leveler_regs_table_size(LEVELER_TABLE_HOLDING_REGISTER);
    if (size > max_values) {
        snprintf(err, (size_t)err_len, "holding table has %u registers, room for %d", size, max_values);
        return -1;
    }
    if (leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, 0, size, values) != LEVELER_REG_OK) {
        snprintf(err, (size_t)err_len, "holding registers 0..%u unreadable", size - 1u);
        return -1;
    }
    return register_runs(size, values, runs, max_runs, err, err_len);
}
