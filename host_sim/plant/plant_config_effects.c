/*
 * [effect.NAME] sections of a plant config (docs/config-format.md): the
 * unmodelled effects of the catalogue (effects.json, plant_fx_catalogue) that
 * the plant runs, keyed by the catalogue's parameter names (SI, the unit in
 * the name) and checked against its accepted ranges. A parameter not given
 * keeps the catalogue's nominal value (the nominal plant's). The loader
 * (plant_config_reader.c) reports file:line; this file knows the catalogue.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "effects.h"

_Static_assert(PLANT_CONFIG_MAX_EFFECTS == PLANT_FX_MAX_MODELS, "one config slot per effect the plant runs at once");
_Static_assert(PLANT_CONFIG_EFFECT_PARAMS == PLANT_FX_MAX_PARAMS, "one config value per effect parameter");

static const plant_fx_model *by_name(const char *name)
{
    for (int i = 0; i < plant_fx_catalogue_count; i++)
        if (strcmp(plant_fx_catalogue[i].name, name) == 0)
            return &plant_fx_catalogue[i];
    return NULL;
}

static void known_names(char *buf, size_t len, const plant_fx_model *m)
{
    buf[0] = 0;
    for (int i = 0; i < (m ? m->nparams : plant_fx_catalogue_count); i++) {
        size_t used = strlen(buf);
        snprintf(buf + used, len - used, "%s%s", used ? ", " : "", m ? m->param[i] : plant_fx_catalogue[i].name);
    }
}

/* The slot of effect m: its own, else a free one filled with the nominal values; -1 if none is free. */
static int slot_of(plant_config *cfg, const plant_fx_model *m)
{
    for (int s = 0; s < PLANT_CONFIG_MAX_EFFECTS; s++)
        if (cfg->effect_id[s] == m->id)
            return s;
    for (int s = 0; s < PLANT_CONFIG_MAX_EFFECTS; s++)
        if (cfg->effect_id[s] == 0) {
            cfg->effect_id[s] = m->id;
            for (int k = 0; k < PLANT_CONFIG_EFFECT_PARAMS; k++)
                cfg->effect_params[s][k] = k < m->nparams ? m->nominal[k] : 0.0;
            return s;
        }
    return -1;
}

int plant_config_effect_key(plant_config *cfg, const char *effect, const char *key, double value, char *msg,
                            size_t len)
{
    char names[512];
    const plant_fx_model *m = by_name(effect);
    if (!m) {
        known_names(names, sizeof names, NULL);
        snprintf(msg, len, "unknown effect '%s' (host_sim/plant/effects.json: %s)", effect, names);
        return -1;
    }
    int k = 0;
    while (k < m->nparams && strcmp(m->param[k], key) != 0)
        k++;
    if (k == m->nparams) {
        known_names(names, sizeof names, m);
        snprintf(msg, len, "unknown parameter of %s (its parameters: %s)", m->name, names);
        return -1;
    }
    if (!(value >= m->lo[k] && value <= m->hi[k])) {
        snprintf(msg, len, "out of range [%.6g, %.6g]", m->lo[k], m->hi[k]);
        return -1;
    }
    int s = slot_of(cfg, m);
    if (s < 0) {
        snprintf(msg, len, "at most %d effects in one config", PLANT_CONFIG_MAX_EFFECTS);
        return -1;
    }
    cfg->effect_params[s][k] = value;
    return 0;
}

void plant_config_effect_models(const plant_config *cfg, const plant_fx_model *models[PLANT_CONFIG_MAX_EFFECTS])
{
    for (int s = 0; s < PLANT_CONFIG_MAX_EFFECTS; s++)
        models[s] = cfg->effect_id[s] ? plant_fx_find(plant_fx_catalogue, plant_fx_catalogue_count,
                                                       cfg->effect_id[s])
                                      : NULL;
}

int plant_config_effects_check(const plant_config *cfg, char *msg, size_t len)
{
    const plant_fx_model *models[PLANT_CONFIG_MAX_EFFECTS];
    plant_config_effect_models(cfg, models);
    if (!models[0] || !models[1])
        return 0;
    static plant_fx scratch; /* large; the loader runs one config at a time */
    if (plant_fx_init_models(&scratch, &cfg->plant, PLANT_CONFIG_MAX_EFFECTS, models, &cfg->effect_params[0][0]) !=
        0) {
        snprintf(msg, len, "[effect.%s] and [effect.%s] cannot run together (they share a state of the plant)",
                 models[0]->name, models[1]->name);
        return -1;
    }
    return 0;
}
