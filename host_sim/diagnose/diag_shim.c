/*
 * ctypes entry point of the sim-to-real diagnosis (scripts/leveler/diagnose/cplant.py):
 * one call simulates one whole run of the C plant with one effect switched on,
 * either replaying logged actuator commands open loop or with the unchanged
 * firmware in the loop (hal_sim.c, as host_sim/sim/simloop.c does it).
 *
 * Built as a shared library WITHOUT sanitizers (a sanitized .so cannot be
 * dlopen'ed from the venv python; host_sim/diagnose/CMakeLists.txt); the
 * sanitized test build checks the effects through tests/diagnose/test_effects.c.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "effects.h"
#include "leveler/app.h"
#include "leveler/hal.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "commission.h"
#include "plant.h"
#include "simloop.h"

/* Version of this ABI; cplant.py refuses a library with another. */
int diag_abi_version(void) { return 1; }

/* Loads a config file; 0 or -1 with the loader's file:line message in err. */
int diag_config_check(const char *path, char *err, int err_len)
{
    static plant_config cfg;
    return plant_config_load(path, &cfg, err, (size_t)err_len);
}

/* Sensed value -> 12-bit counts over the config's spans (no noise: the blind
 * test adds noise to the logged values itself). */
static uint16_t to_counts(double v, double eng_lo, double eng_hi, double raw_lo, double raw_hi)
{
    double c = floor(raw_lo + (v - eng_lo) * (raw_hi - raw_lo) / (eng_hi - eng_lo) + 0.5);
    return (uint16_t)(c < 0.0 ? 0.0 : (c > 4095.0 ? 4095.0 : c));
}

/*
 * Simulate one run.
 *   config_path      plant config (INI)
 *   n, t_s, load_n   the run's time base and load schedule (load for the interval from t_s[i])
 *   commands         n x 4 (compressor, solenoid, vent, acc_valve) to replay, or NULL for the
 *                    firmware in the loop (then t_s must be the 10 ms tick grid from 0)
 *   fx_kind, fx_params  effect (effects.h), PLANT_FX_MAX_PARAMS doubles
 *   init             height m, P2, P1 Pa at t_s[0]; NaN = the config's. Given (even all
 *                    NaN), the platform starts at rest and, closed loop, the firmware
 *                    decides from the first tick; NULL = the config's initial state
 *                    whole, its velocity and [initial] actuators included (leveler-sim)
 *   out              n x 4: height, P2, P1, P3 as the transducers report them at t_s[i]
 *   cmd_out          n x 4: the actuator states in force from t_s[i] (may be NULL)
 * Returns 0, or -1 with a message in err.
 */
int diag_simulate(const char *config_path, int n, const double *t_s, const double *load_n,
                  const int32_t *commands, int fx_kind, const double *fx_params, const double *init,
                  double *out, int32_t *cmd_out, char *err, int err_len)
{
    static plant_config cfg;
    static plant_fx f;
    if (plant_config_load(config_path, &cfg, err, (size_t)err_len) != 0)
        return -1;
    if (n < 1) {
        snprintf(err, (size_t)err_len, "no samples");
        return -1;
    }
    plant_params p = cfg.plant;
    if (init) {
        if (isfinite(init[0]))
            p.init_height_m = init[0];
        if (isfinite(init[1]))
            p.init_p_spring_pa = init[1];
        if (isfinite(init[2]))
            p.init_p_pipe_pa = init[2];
        p.init_velocity_m_per_s = 0.0;
    }
    plant_fx_spec spec;
    memset(&spec, 0, sizeof spec);
    spec.kind = fx_kind;
    if (fx_params)
        memcpy(spec.p, fx_params, sizeof spec.p);
    if (plant_fx_init(&f, &p, &spec) != 0) {
        snprintf(err, (size_t)err_len, "effect %d: unknown kind or parameter out of range", fx_kind);
        return -1;
    }
    const double tick_s = LEVELER_TICK_MS / 1000.0;
    bool closed = commands == NULL;
    if (closed) {
        sim_hal_reset();
        leveler_app_init();
        if (sim_commission(&cfg, cfg.algorithm, err, (size_t)err_len) != 0)
            return -1;
    }
    const plant_sensor_params *s = &cfg.sensors;
    for (int i = 0; i < n; i++) {
        double sensed[4];
        plant_fx_sensed(&f, sensed);
        plant_inputs in = {false, false, false, false, load_n[i]};
        if (closed) {
            bool o[HAL_OUT_COUNT];
            if (i == 0 && !init) {
                /* From the config's own initial state (a rig already running, as
                 * leveler-sim starts): the first tick under its [initial]
                 * actuators, the firmware's first decision at its end. From a
                 * given state (init: a log's first state, at rest) the firmware
                 * decides from the first tick. */
                sim_initial_outputs(&cfg, o);
            } else {
                uint16_t counts[4];
                counts[0] =
                    to_counts(sensed[0], s->height_lo_m, s->height_hi_m, s->height_lo_counts, s->height_hi_counts);
                for (int c = 1; c < 4; c++)
                    counts[c] = to_counts(sensed[c], s->pressure_lo_pa, s->pressure_hi_pa, s->pressure_lo_counts,
                                          s->pressure_hi_counts);
                sim_hal_set_counts(counts);
                sim_hal_set_time_ms((uint32_t)llround(t_s[i] * 1000.0));
                leveler_app_tick();
                sim_hal_get_outputs(o);
            }
            in.compressor = o[HAL_OUT_COMPRESSOR];
            in.spring_valve = o[HAL_OUT_SPRING_VALVE];
            in.vent_valve = o[HAL_OUT_VENT_VALVE];
            in.acc_valve = o[HAL_OUT_ACC_VALVE];
        } else {
            in.compressor = commands[4 * i] != 0;
            in.spring_valve = commands[4 * i + 1] != 0;
            in.vent_valve = commands[4 * i + 2] != 0;
            in.acc_valve = commands[4 * i + 3] != 0;
        }
        plant_fx_set_inputs(&f, &in);
        memcpy(&out[4 * i], sensed, sizeof sensed);
        if (cmd_out) {
            cmd_out[4 * i] = in.compressor;
            cmd_out[4 * i + 1] = in.spring_valve;
            cmd_out[4 * i + 2] = in.vent_valve;
            cmd_out[4 * i + 3] = in.acc_valve;
        }
        if (i + 1 < n) {
            double dt = t_s[i + 1] - t_s[i];
            if (!(dt > 0.0)) {
                snprintf(err, (size_t)err_len, "t_s[%d]: time not increasing", i + 1);
                return -1;
            }
            if (closed && fabs(dt - tick_s) > 1e-6) {
                snprintf(err, (size_t)err_len, "t_s[%d]: closed loop needs the 10 ms tick grid", i + 1);
                return -1;
            }
            int sub = (int)lround(dt / tick_s * cfg.substeps_per_tick);
            plant_fx_advance(&f, dt, sub < 1 ? 1 : sub);
        }
    }
    return 0;
}
