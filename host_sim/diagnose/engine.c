/*
 * The engine's handle (engine.h): a config read once, its resolved form, its
 * effects and motor balance. Runs (engine_run.c), stepping (engine_step.c) and
 * schedules (engine_schedule.c) sit beside it.
 *
 * Built as a shared library WITHOUT sanitizers (a sanitized .so cannot be
 * dlopen'ed from the venv python; CMakeLists.txt); the sanitized test build
 * checks the same plant and effects through tests/diagnose/test_effects.c.
 */
#define _POSIX_C_SOURCE 200809L /* open_memstream */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "engine_internal.h"
#include "plant.h"
#include "stepper.h"

int engine_abi_version(void) { return ENGINE_ABI; }

double engine_tick_s(void) { return SIM_TICK_S; }

/* The config's effects at their models' nominal values (ENGINE_EFFECTS_NOMINAL). */
static void effects_at_nominal(plant_config *cfg)
{
    engine_catalogue c; /* a config's own effects are candidates */
    (void)engine_catalogue_find(ENGINE_CANDIDATES, &c);
    for (int s = 0; s < PLANT_CONFIG_MAX_EFFECTS; s++) {
        const plant_fx_model *m = cfg->effect_id[s] ? plant_fx_find(c.table, c.count, cfg->effect_id[s]) : NULL;
        for (int j = 0; m && j < m->nparams; j++)
            cfg->effect_params[s][j] = m->nominal[j];
    }
}

engine *engine_open(const char *config_path, int flags, char *err, int err_len)
{
    engine *e = calloc(1, sizeof *e);
    if (!e) {
        snprintf(err, (size_t)err_len, "%s: out of memory", config_path ? config_path : "(built-in)");
        return NULL;
    }
    if (!config_path) {
        plant_config_defaults(&e->cfg);
    } else if (plant_config_load(config_path, &e->cfg, err, (size_t)err_len) != 0) {
        free(e);
        return NULL;
    }
    if (flags & ENGINE_EFFECTS_NOMINAL)
        effects_at_nominal(&e->cfg);
    snprintf(e->name, sizeof e->name, "%s", config_path ? config_path : "(built-in)");
    return e;
}

void engine_close(engine *e) { free(e); }

int engine_config_json(const engine *e, char *buf, int buf_len, char *err, int err_len)
{
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f || plant_config_write_json(&e->cfg, f) != 0 || fclose(f) != 0) {
        snprintf(err, (size_t)err_len, "%s: cannot write the config as JSON", e->name);
        free(text);
        return -1;
    }
    int rc = (int)len;
    if (buf && (size_t)buf_len <= len) {
        snprintf(err, (size_t)err_len, "config JSON: %zu bytes, buffer %d", len + 1, buf_len);
        rc = -1;
    } else if (buf) {
        memcpy(buf, text, len + 1);
    }
    free(text);
    return rc;
}

void engine_config_effects(const engine *e, int32_t *ids, double *params)
{
    for (int s = 0; s < PLANT_FX_MAX_MODELS; s++) {
        ids[s] = e->cfg.effect_id[s];
        memcpy(params + s * PLANT_FX_MAX_PARAMS, e->cfg.effect_params[s], sizeof e->cfg.effect_params[s]);
    }
}

double engine_motor_speed(const engine *e, double p1_pa, double duty)
{
    return plant_motor_steady_speed(&e->cfg.plant, p1_pa, duty);
}

int engine_algorithm(const engine *e) { return e->cfg.algorithm; }
