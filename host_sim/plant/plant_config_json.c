/* The resolved config as JSON (plant.h: plant_config_write_json), from the loader's schema, built with cJSON. */
#include "plant.h"
#include "plant_config_schema.h"
#include "effects.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The SI suffix of a unit kind: its entry with factor 1, not gauge; "" for plain numbers. */
static const char *si_suffix(int kind)
{
    const ini_table *t = &plant_config_table;
    for (size_t i = 0; i < t->unit_count; i++)
        if (t->units[i].kind == kind && t->units[i].factor == 1.0 && !t->units[i].gauge)
            return t->units[i].suffix;
    return "";
}

/* A number that reads back bit for bit (%.17g; cJSON's own printer keeps 15
 * digits and can lose the last bit, which the Python side would see). */
static cJSON *exact_number(double x)
{
    char text[32];
    if (!isfinite(x))
        return cJSON_CreateNull();
    snprintf(text, sizeof text, "%.17g", x);
    return cJSON_CreateRaw(text);
}

static void add_number(cJSON *obj, const char *key, double x)
{
    cJSON_AddItemToObject(obj, key, exact_number(x));
}

/* "<base>_<SI suffix>": the field's value, in SI. */
static void json_field(cJSON *obj, const ini_field *fd, const char *base)
{
    const char *suffix = si_suffix(fd->unit);
    char key[128];
    snprintf(key, sizeof key, "%s%s%s", fd->key, suffix[0] ? "_" : "", suffix);
    const char *v = base + fd->offset;
    double x = fd->store == INI_F64 ? *(const double *)v
               : fd->store == INI_INT ? (double)*(const int *)v
                                      : (double)*(const uint32_t *)v;
    add_number(obj, key, x);
}

static void json_list(cJSON *obj, const char *key, const double *v, int n)
{
    cJSON *list = cJSON_AddArrayToObject(obj, key);
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(list, exact_number(v[i]));
}

/* The hysteresis bands with the load range plant_band_for_load() gives each
 * (covers_below_n null: every heavier load). */
static cJSON *json_bands(const plant_params *p)
{
    cJSON *list = cJSON_CreateArray();
    for (int b = 0; b < p->band_count; b++) {
        const plant_hysteresis_band *band = &p->bands[b];
        double from = 0.0;
        int last = 1;
        for (int o = 0; o < p->band_count; o++) {
            double other = p->bands[o].load_below_n;
            if (other < band->load_below_n && other > from)
                from = other;
            if (other > band->load_below_n)
                last = 0;
        }
        cJSON *item = cJSON_CreateObject();
        for (size_t i = 0; i < plant_config_table.field_count; i++)
            if (strcmp(plant_config_table.fields[i].section, PLANT_CONFIG_BANDS) == 0)
                json_field(item, &plant_config_table.fields[i], (const char *)band);
        add_number(item, "covers_from_n", from);
        if (last)
            cJSON_AddNullToObject(item, "covers_below_n");
        else
            add_number(item, "covers_below_n", band->load_below_n);
        cJSON_AddItemToArray(list, item);
    }
    return list;
}

/* The keys read by hand (INI_CUSTOM in the schema), after their section's fields. */
static void json_extras(cJSON *sec, const char *section, const plant_params *p)
{
    static const char *const acc_types[] = {"none", "tube", "diaphragm"};
    if (strcmp(section, "accumulator") == 0) {
        cJSON_AddStringToObject(sec, "type", acc_types[p->acc_type]);
        json_list(sec, "diaphragm_breaks_pa", p->diaphragm_break_pa, p->diaphragm_segments - 1);
        json_list(sec, "diaphragm_slopes_m3_per_pa", p->diaphragm_slope_m3_per_pa, p->diaphragm_segments);
        json_list(sec, "diaphragm_intercepts_m3", p->diaphragm_intercept_m3, p->diaphragm_segments);
    }
    if (strcmp(section, "spring") == 0) {
        json_list(sec, "area_cc1_poly_in2", p->area_cc1_in2, p->area_cc1_terms);
        json_list(sec, "area_cc2_poly_in2_per_in", p->area_cc2_in2_per_in, p->area_cc2_terms);
    }
}

/* "effects": {NAME: {param: value}} for the config's [effect.NAME] sections. */
static cJSON *json_effects(const plant_config *c)
{
    const plant_fx_model *models[PLANT_CONFIG_MAX_EFFECTS];
    plant_config_effect_models(c, models);
    cJSON *all = cJSON_CreateObject();
    for (int s = 0; s < PLANT_CONFIG_MAX_EFFECTS; s++) {
        if (!models[s])
            continue;
        cJSON *one = cJSON_AddObjectToObject(all, models[s]->name);
        for (int k = 0; k < models[s]->nparams; k++)
            add_number(one, models[s]->param[k], c->effect_params[s][k]);
    }
    return all;
}

static cJSON *config_json(const plant_config *c)
{
    cJSON *root = cJSON_CreateObject();
    cJSON *head = cJSON_AddObjectToObject(root, "config");
    cJSON_AddStringToObject(head, "name", c->name);
    cJSON_AddStringToObject(head, "path", c->path);
    cJSON *sec = NULL;
    const ini_table *t = &plant_config_table;
    for (size_t i = 0; i < t->field_count; i++) {
        const ini_field *fd = &t->fields[i];
        if (fd->type != INI_REAL || strcmp(fd->section, PLANT_CONFIG_BANDS) == 0)
            continue; /* the bands below, the keys read by hand with their section's fields */
        sec = cJSON_GetObjectItemCaseSensitive(root, fd->section);
        if (sec == NULL)
            sec = cJSON_AddObjectToObject(root, fd->section);
        json_field(sec, fd, (const char *)c);
        if (i + 1 == t->field_count || strcmp(t->fields[i + 1].section, fd->section) != 0)
            json_extras(sec, fd->section, &c->plant);
    }
    cJSON_AddItemToObject(root, "hysteresis", json_bands(&c->plant));
    cJSON_AddItemToObject(root, "effects", json_effects(c));
    return root;
}

int plant_config_write_json(const plant_config *c, FILE *f)
{
    cJSON *root = config_json(c);
    char *text = root ? cJSON_Print(root) : NULL;
    int rc = text && fprintf(f, "%s\n", text) >= 0 && !ferror(f) ? 0 : -1;
    free(text);
    cJSON_Delete(root);
    return rc;
}
