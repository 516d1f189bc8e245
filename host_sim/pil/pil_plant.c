/*
 * ctypes entry points of the processor-in-the-loop harness (host_sim/pil/plant.py):
 * the project's C plant stepped one 10 ms tick at a time, and the holding
 * registers a commissioning engineer writes for a config (commission.c run on
 * the host build of the firmware, then read back through the register map).
 * The emulated STM32F103 image is the controller; this library only holds
 * the plant and knows nothing of the emulator.
 *
 * One plant per process (static state), like the firmware it stands beside.
 * Built without sanitizers so the venv python can dlopen it.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "commission.h"
#include "leveler/app.h"
#include "leveler/hal.h"
#include "leveler/regmap.h"
#include "plant.h"
#include "simloop.h"
#include "stepper.h"

static plant_config s_cfg;
static plant_fx s_fx; /* with the config's effects */
static const plant *const s_plant = &s_fx.pl;
static plant_rng s_rng;
static sim_load_step s_steps[4];
static sim_schedule_cursor s_cursor;
static sim_stepper s_stepper;
static double s_end_s;
static bool s_outputs[HAL_OUT_COUNT]; /* what the emulated image drives, for the commands hook */

/* Version of this ABI; plant.py refuses a library with another. */
int pil_abi_version(void) { return 3; }

/* The stepper's commands hook: the outputs the image set (GPIOB), handed in
 * by pil_decide(); the emulated image, not this library, runs the firmware. */
static void image_outputs(sim_stepper *st, void *user, bool out[HAL_OUT_COUNT])
{
    (void)st;
    (void)user;
    memcpy(out, s_outputs, sizeof s_outputs);
}

/* Loads a config and puts the plant in its initial state at t = 0 behind the
 * one stepper (host_sim/sim/stepper.h). Returns the config's algorithm, or -1
 * with "file:line: ..." in err. */
int pil_open(const char *config_path, char *err, int err_len)
{
    if (plant_config_load(config_path, &s_cfg, err, (size_t)err_len) != 0)
        return -1;
    if (sim_plant_open(&s_fx, &s_cfg, NULL, 0, NULL, NULL) != 0) {
        snprintf(err, (size_t)err_len, "%s: the config's effects cannot run", config_path);
        return -1;
    }
    plant_rng_seed(&s_rng, s_cfg.sensors.noise_seed);
    s_cursor = (sim_schedule_cursor){s_steps, sim_schedule_from_config(&s_cfg, s_steps, &s_end_s), 0};
    s_stepper = (sim_stepper){.cfg = &s_cfg, .plant = &s_fx, .ops = &sim_fx_plant,
                              .commands = image_outputs, .load = sim_load_from_schedule,
                              .load_user = &s_cursor, .rng = s_cfg.sensors.noise_counts > 0.0 ? &s_rng : NULL,
                              .initial_outputs = true};
    sim_stepper_start(&s_stepper);
    return s_cfg.algorithm;
}

double pil_end_s(void) { return s_end_s; }

/* The four transducers as 12-bit ADC counts now (height, P2, P1, P3). noisy:
 * with the config's seeded noise, one draw per call as leveler-sim draws one
 * per tick; 0 for readings outside the run (boot, commissioning). */
void pil_sensor_counts(int noisy, uint16_t counts[4])
{
    s_stepper.ops->sensed(s_stepper.plant, s_stepper.sensed);
    plant_counts(&s_cfg.sensors, s_stepper.sensed, noisy ? s_stepper.rng : NULL, counts);
}

/* Decides the tick starting now: the image's outputs (compressor, spring,
 * vent, acc; the config's [initial] ones at the first tick) and the scheduled
 * load become the plant's inputs. applied = what the plant got. */
void pil_decide(const int32_t outputs[4], int32_t applied[4])
{
    for (int i = 0; i < 4; i++)
        s_outputs[i] = outputs[i] != 0;
    sim_stepper_decide(&s_stepper);
    for (int i = 0; i < 4; i++)
        applied[i] = s_stepper.out[i];
}

/* t, height m, P2, P1, P3 Pa (NaN without accumulator), load N of the tick decided last. */
void pil_state(double out[6])
{
    out[0] = s_stepper.t_s_now;
    out[1] = s_plant->x[PLANT_X_Y];
    out[2] = s_plant->x[PLANT_X_P2];
    out[3] = s_plant->x[PLANT_X_P1];
    out[4] = s_plant->p.acc_type == PLANT_ACC_NONE ? NAN : s_plant->x[PLANT_X_P3];
    out[5] = s_stepper.in.load_n;
}

/* One 10 ms tick of RK4 (the config's sub-steps) under the inputs decided last. */
void pil_advance(void) { (void)sim_stepper_advance(&s_stepper); }

/*
 * The holding registers after commissioning for this config (algorithm 0 =
 * the config's), as runs of consecutive registers a master can write with
 * FC 16: runs[2k] = first address, runs[2k+1] = count; values[addr] = value.
 * Returns the number of runs, or -1 with a message in err.
 */
int pil_commission_registers(int algorithm, uint16_t *runs, int max_runs, uint16_t *values, int max_values,
                             char *err, int err_len)
{
    /* the host firmware, reset and commissioned as leveler-sim does it */
    if (sim_firmware_start(&s_cfg, algorithm ? algorithm : s_cfg.algorithm, err, (size_t)err_len) != 0)
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
    int n = 0;
    for (uint16_t a = 0; a < size;) {
        /* Reads pass over gaps (they read 0); a write of the value back tells a
         * register (1 or 2 words) from a gap. */
        uint16_t len = 0;
        for (uint16_t w = 1; w <= 2 && len == 0 && a + w <= size; w++)
            if (leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, a, w, &values[a], NULL) == LEVELER_REG_OK)
                len = w;
        if (len == 0) {
            a++; /* a gap in the table */
            continue;
        }
        if (n > 0 && runs[2 * n - 2] + runs[2 * n - 1] == a && runs[2 * n - 1] + len <= 123u) {
            runs[2 * n - 1] += len; /* joins the run (FC 16 writes at most 123 registers) */
        } else {
            if (n >= max_runs) {
                snprintf(err, (size_t)err_len, "more than %d register runs", max_runs);
                return -1;
            }
            runs[2 * n] = a;
            runs[2 * n + 1] = len;
            n++;
        }
        a += len;
    }
    return n;
}
