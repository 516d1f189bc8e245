/*
 * The plant config's keys read by hand (INI_CUSTOM in plant_config_schema.c):
 * the include, the name, the accumulator type and the number lists (the
 * effective-area polynomials, the diaphragm curve in thesis units).
 */
#define _POSIX_C_SOURCE 200809L
#include "plant_config_schema.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* "a b, c": 1..max finite numbers. 0, or -1. */
static int parse_list(const char *s, double *out, int max, int *count)
{
    int n = 0;
    const char *p = s;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == ',')
            p++;
        if (!*p)
            break;
        char *end;
        errno = 0;
        double v = strtod(p, &end);
        if (end == p || errno == ERANGE || !isfinite(v) || n >= max)
            return -1;
        out[n++] = v;
        p = end;
    }
    if (n == 0)
        return -1;
    *count = n;
    return 0;
}

int plant_config_key_include(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                             const char *value)
{
    (void)f;
    (void)cfg;
    if (r->keys_seen != 1)
        return ini_file_fail(r, section, key, value, "include must be the first key of the file");
    plant_config_include(r, section, key, value); /* its errors are the load's */
    return 1;
}

int plant_config_key_name(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                          const char *value)
{
    (void)f;
    plant_config *c = cfg;
    if (!ini_utf8_valid(value))
        return ini_file_fail(r, section, key, value, "name must be valid UTF-8");
    if (!value[0] || strlen(value) >= PLANT_NAME_MAX)
        return ini_file_fail(r, section, key, value, "name must be 1..%d characters", PLANT_NAME_MAX - 1);
    snprintf(c->name, sizeof c->name, "%s", value);
    return 1;
}

int plant_config_key_acc_type(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                              const char *value)
{
    (void)f;
    plant_config *c = cfg;
    if (strcmp(value, "none") == 0)
        c->plant.acc_type = PLANT_ACC_NONE;
    else if (strcmp(value, "tube") == 0)
        c->plant.acc_type = PLANT_ACC_TUBE;
    else if (strcmp(value, "diaphragm") == 0)
        c->plant.acc_type = PLANT_ACC_DIAPHRAGM;
    else
        return ini_file_fail(r, section, key, value, "allowed: none, tube, diaphragm");
    return 1;
}

int plant_config_key_area_poly(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                               const char *value)
{
    (void)f;
    plant_params *p = &((plant_config *)cfg)->plant;
    int cc1 = strcmp(key, "area_cc1_poly_in2") == 0;
    double *dst = cc1 ? p->area_cc1_in2 : p->area_cc2_in2_per_in;
    int *cnt = cc1 ? &p->area_cc1_terms : &p->area_cc2_terms;
    double tmp[PLANT_MAX_POLY];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_POLY, &n) != 0)
        return ini_file_fail(r, section, key, value, "expected 1..%d numbers (coefficients of DL^0, DL^1, ...)",
                             PLANT_MAX_POLY);
    memset(dst, 0, sizeof(double) * PLANT_MAX_POLY);
    memcpy(dst, tmp, sizeof(double) * (size_t)n);
    *cnt = n;
    return 1;
}

/* Thesis units, converted to SI here; counts are checked together in plant_config_check. */
int plant_config_key_diaphragm_breaks(ini_file *r, const ini_field *f, void *cfg, const char *section,
                                      const char *key, const char *value)
{
    (void)f;
    plant_params *p = &((plant_config *)cfg)->plant;
    double tmp[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_DIAPHRAGM_SEGMENTS - 1, &n) != 0)
        return ini_file_fail(r, section, key, value, "expected 1..%d pressures, psia, rising",
                             PLANT_MAX_DIAPHRAGM_SEGMENTS - 1);
    for (int i = 0; i < n; i++) {
        if (!(tmp[i] > 0.0 && tmp[i] < 300.0) || (i > 0 && !(tmp[i] > tmp[i - 1])))
            return ini_file_fail(r, section, key, value, "break %d: %g psia; breaks must rise, each in (0, 300) psia",
                                 i + 1, tmp[i]);
        p->diaphragm_break_pa[i] = tmp[i] * PLANT_PA_PER_PSI;
    }
    p->diaphragm_segments = n + 1;
    return 1;
}

int plant_config_key_diaphragm_segments(ini_file *r, const ini_field *f, void *cfg, const char *section,
                                        const char *key, const char *value)
{
    (void)f;
    static const double in3 = PLANT_M_PER_IN * PLANT_M_PER_IN * PLANT_M_PER_IN;
    plant_params *p = &((plant_config *)cfg)->plant;
    int slope = strcmp(key, "diaphragm_slopes_in3_per_psi") == 0;
    double tmp[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_DIAPHRAGM_SEGMENTS, &n) != 0)
        return ini_file_fail(r, section, key, value, "expected 1..%d numbers, one per segment",
                             PLANT_MAX_DIAPHRAGM_SEGMENTS);
    for (int i = 0; i < n; i++) {
        if (slope && !(tmp[i] >= 0.0 && tmp[i] <= 1000.0))
            return ini_file_fail(r, section, key, value, "segment %d: %g in^3/psi out of range [0, 1000]", i + 1,
                                 tmp[i]);
        if (slope)
            p->diaphragm_slope_m3_per_pa[i] = tmp[i] * in3 / PLANT_PA_PER_PSI;
        else
            p->diaphragm_intercept_m3[i] = tmp[i] * in3;
    }
    *(slope ? &p->diaphragm_slope_count : &p->diaphragm_intercept_count) = n;
    return 1;
}
