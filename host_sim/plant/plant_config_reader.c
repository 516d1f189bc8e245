/*
 * Loading a plant config (docs/config-format.md): the built-in thesis-900lb
 * file, then the user's file and its includes over it, read by the one INI
 * reader (ini_table.h) with the schema of plant_config_schema.c; then what a
 * file must give together, and the physical checks (plant_config_check.c).
 */
#define _POSIX_C_SOURCE 200809L
#include "plant_config_schema.h"
#include "effects.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* host_sim/configs/thesis-900lb.ini, compiled in (plant_config_builtin.c, made by CMake from the file). */
extern const char plant_config_builtin_ini[];
#define BUILTIN_NAME "thesis-900lb.ini (built in)"

/* What one load keeps across its files (ini_load.user). */
typedef struct {
    int *gauge;                           /* per field and band: given as gauge, ambient still to add */
    int band_seen[PLANT_MAX_BANDS];
    unsigned band_keys[PLANT_MAX_BANDS];  /* bit i: the i-th band field given for the band */
    char edge_where[PLANT_PATH_MAX + 16]; /* file:line of the last band_lower/band_upper */
    int depth;                            /* of includes */
} load_state;

static size_t first_band_field(void)
{
    size_t i = 0;
    while (strcmp(plant_config_table.fields[i].section, PLANT_CONFIG_BANDS) != 0)
        i++;
    return i;
}

void *plant_config_band(ini_file *r, const char *section, const char *group, const char *key, int *index)
{
    const char *digits = section + strlen(group);
    char *end;
    long n = strtol(digits, &end, 10);
    if (*end || end == digits || n < 1 || n > PLANT_MAX_BANDS) {
        ini_file_fail(r, section, key, NULL, "unknown section [%s] (see %s)", section, plant_config_table.see);
        return NULL;
    }
    *index = (int)n - 1;
    return &((plant_config *)r->load->config)->plant.bands[n - 1];
}

/* [effect.NAME] (plant_config_effects.c): -1 for other sections. */
int plant_config_effect_section(ini_file *r, const char *section, const char *key, const char *value)
{
    if (strncmp(section, "effect.", 7) != 0)
        return -1;
    double v;
    char msg[600];
    if (ini_parse_number(value, &v) != 0)
        return ini_file_fail(r, section, key, value, "not a number");
    if (plant_config_effect_key(r->load->config, section + 7, key, v, msg, sizeof msg) != 0)
        return ini_file_fail(r, section, key, value, "%s", msg);
    return 1;
}

void plant_config_stored(ini_file *r, const ini_field *f, int index, const ini_unit *u)
{
    load_state *st = r->load->user;
    size_t i = (size_t)(f - plant_config_table.fields);
    st->gauge[i * PLANT_MAX_BANDS + (size_t)index] = u && u->gauge;
    if (strcmp(f->section, PLANT_CONFIG_BANDS) == 0) {
        st->band_seen[index] = 1;
        st->band_keys[index] |= 1u << (i - first_band_field());
    }
    if (strcmp(f->section, "controller") == 0 && strncmp(f->key, "band_", 5) == 0)
        snprintf(st->edge_where, sizeof st->edge_where, "%s:%u", r->guard.path, r->guard.line);
}

double plant_config_ambient_pa(const void *cfg)
{
    return ((const plant_config *)cfg)->plant.ambient_pa;
}

int plant_config_include(ini_file *r, const char *section, const char *key, const char *value)
{
    load_state *st = r->load->user;
    if (st->depth >= 4)
        return ini_file_fail(r, section, key, value, "includes nested more than 4 deep"), -1;
    char inc[PLANT_PATH_MAX];
    const char *path = r->guard.path;
    const char *slash = strrchr(path, '/');
    if (value[0] != '/' && slash)
        snprintf(inc, sizeof inc, "%.*s/%s", (int)(slash - path), path, value);
    else
        snprintf(inc, sizeof inc, "%s", value);
    st->depth++;
    int rc = ini_table_read(r->load, inc);
    st->depth--;
    return rc;
}

/* What a file must give together: all four keys of a [hysteresis.N] it names,
 * and a band whose upper edge is above its lower one. 0 or -1 with err. */
static int check_given(const load_state *st, const plant_config *c, const char *path, char *err, size_t err_len)
{
    const ini_table *t = &plant_config_table;
    size_t first = first_band_field();
    for (int b = 0; b < PLANT_MAX_BANDS; b++) {
        if (!st->band_seen[b])
            continue;
        for (size_t i = first; i < t->field_count && strcmp(t->fields[i].section, PLANT_CONFIG_BANDS) == 0; i++)
            if (!(st->band_keys[b] & (1u << (i - first)))) {
                char list[256];
                ini_table_unit_list(t, t->fields[i].unit, list, sizeof list);
                snprintf(err, err_len, "%s: [hysteresis.%d] %s: missing (with a unit suffix: %s)", path, b + 1,
                         t->fields[i].key, list);
                return -1;
            }
    }
    if (st->edge_where[0] && !(c->band_upper_m > c->band_lower_m)) {
        snprintf(err, err_len, "%s: [controller] band_lower must be below band_upper (%.6g m, %.6g m)",
                 st->edge_where, c->band_lower_m, c->band_upper_m);
        return -1;
    }
    return 0;
}

/* After the files: gauge values get the (now final) ambient, the bands are counted. */
static void finish(const load_state *st, plant_config *out)
{
    const ini_table *t = &plant_config_table;
    for (size_t i = 0; i < t->field_count; i++)
        for (int b = 0; b < PLANT_MAX_BANDS; b++)
            if (st->gauge[i * PLANT_MAX_BANDS + (size_t)b]) {
                char *base = strcmp(t->fields[i].section, PLANT_CONFIG_BANDS) == 0 ? (char *)&out->plant.bands[b]
                                                                                   : (char *)out;
                *(double *)(base + t->fields[i].offset) += out->plant.ambient_pa;
            }
    /* bands: as many as before (the built-in file's 4); a file may add more */
    for (int b = 0; b < PLANT_MAX_BANDS; b++)
        if (st->band_seen[b] && b + 1 > out->plant.band_count)
            out->plant.band_count = b + 1;
}

/* Reads path (or text, named path) over out, then checks the whole. 0, or -1 with err. */
static int read_over(plant_config *out, const char *path, const char *text, char *err, size_t err_len)
{
    load_state st = {0};
    st.gauge = calloc(plant_config_table.field_count * PLANT_MAX_BANDS, sizeof *st.gauge);
    if (!st.gauge) {
        snprintf(err, err_len, "%s: out of memory", path);
        return -1;
    }
    ini_load load = {.table = &plant_config_table, .config = out, .user = &st, .err = err, .err_len = err_len};
    int rc = text ? ini_table_read_text(&load, path, text) : ini_table_read(&load, path);
    if (rc == 0) {
        finish(&st, out);
        rc = check_given(&st, out, path, err, err_len);
        if (rc == 0)
            rc = plant_config_check(out, err, err_len);
        char msg[400];
        if (rc == 0 && plant_config_effects_check(out, msg, sizeof msg) != 0) {
            snprintf(err, err_len, "%s: %s", out->path[0] ? out->path : "(config)", msg);
            rc = -1;
        }
    }
    free(st.gauge);
    return rc;
}

void plant_config_defaults(plant_config *c)
{
    memset(c, 0, sizeof *c);
    c->chatter_max_per_min = -1; /* not given: the firmware's own default stays */
    char err[1024];
    if (read_over(c, BUILTIN_NAME, plant_config_builtin_ini, err, sizeof err) != 0) {
        fprintf(stderr, "leveler: the built-in config does not load: %s\n", err);
        abort(); /* the build checked it: tests/sim/test_plant.c */
    }
}

int plant_config_load(const char *path, plant_config *out, char *err, size_t err_len)
{
    plant_config_defaults(out);
    snprintf(out->path, sizeof out->path, "%s", path);
    /* default name: file name without .ini */
    const char *slash = strrchr(path, '/');
    snprintf(out->name, sizeof out->name, "%s", slash ? slash + 1 : path);
    char *dot = strrchr(out->name, '.');
    if (dot && strcmp(dot, ".ini") == 0)
        *dot = 0;
    return read_over(out, path, NULL, err, err_len);
}
