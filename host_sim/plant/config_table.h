/*
 * The config loader's tables (plant_config.c), shared with the JSON writer
 * (plant_config_json.c) so that --dump-config names every key the way the
 * loader reads it. Internal to host_sim/plant.
 */
#ifndef LEVELER_CONFIG_TABLE_H
#define LEVELER_CONFIG_TABLE_H

#include <stddef.h>

/* ---- units ---- */

typedef enum {
    K_NONE, K_INT, K_PABS, K_PGAUGE, K_PDIFF, K_VOLUME, K_LENGTH, K_VEL, K_MASS, K_FORCE, K_LDAMP,
    K_TIME, K_ANGVEL, K_TEMP, K_GASR, K_INERTIA, K_KT, K_RDAMP, K_CAP, K_LEAK, K_SLOPE, K_VOLT, K_COUNTS
} kind;

typedef struct {
    kind k;
    const char *suffix;
    double factor; /* SI = value * factor (+ ambient when gauge) */
    int gauge;     /* K_PABS written as gauge: ambient added at the end */
} unit;

/* ---- fields ---- */

typedef enum { T_DOUBLE, T_INT, T_U32 } ftype;

typedef struct {
    const char *section; /* "hysteresis" = every [hysteresis.N]; offset then into the band */
    const char *base;
    kind k;
    ftype t;
    size_t offset;
    double min_si, max_si;
} field;

extern const unit units[];
extern const size_t config_unit_count;
extern const field fields[];
extern const size_t config_field_count;

#endif /* LEVELER_CONFIG_TABLE_H */
