/*
 * The plant config's schema (plant_config_schema.c): its units and its table
 * of fields for the one INI reader (ini_table.h), shared by the loader
 * (plant_config_reader.c) and the JSON writer (plant_config_json.c), so that
 * --dump-config names every key the way the loader reads it. Internal to
 * host_sim/plant.
 */
#ifndef LEVELER_PLANT_CONFIG_SCHEMA_H
#define LEVELER_PLANT_CONFIG_SCHEMA_H

#include "ini_table.h"
#include "plant.h"

/* Unit kinds (ini_unit.kind); K_NONE and K_INT have no units: plain keys. */
typedef enum {
    K_NONE, K_INT, K_PABS, K_PGAUGE, K_PDIFF, K_VOLUME, K_LENGTH, K_VEL, K_MASS, K_FORCE, K_LDAMP,
    K_TIME, K_ANGVEL, K_TEMP, K_GASR, K_INERTIA, K_KT, K_RDAMP, K_CAP, K_LEAK, K_SLOPE, K_VOLT, K_COUNTS
} plant_config_kind;

/* The section of the [hysteresis.N] fields (offsets into plant_hysteresis_band). */
#define PLANT_CONFIG_BANDS "hysteresis."

/* The table: the quantities (in the order --dump-config writes them), then the
 * keys read by hand (INI_CUSTOM, plant_config_lists.c). The reader's hooks are
 * plant_config_reader.c's. */
extern const ini_table plant_config_table;

/* The keys read by hand (plant_config_lists.c). */
int plant_config_key_include(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                             const char *value);
int plant_config_key_name(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                          const char *value);
int plant_config_key_acc_type(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                              const char *value);
int plant_config_key_area_poly(ini_file *r, const ini_field *f, void *cfg, const char *section, const char *key,
                               const char *value);
int plant_config_key_diaphragm_breaks(ini_file *r, const ini_field *f, void *cfg, const char *section,
                                      const char *key, const char *value);
int plant_config_key_diaphragm_segments(ini_file *r, const ini_field *f, void *cfg, const char *section,
                                        const char *key, const char *value);

/* The reader's hooks (plant_config_reader.c). */
void *plant_config_band(ini_file *r, const char *section, const char *group, const char *key, int *index);
int plant_config_effect_section(ini_file *r, const char *section, const char *key, const char *value);
void plant_config_stored(ini_file *r, const ini_field *f, int index, const ini_unit *u);
double plant_config_ambient_pa(const void *cfg);

/* include = value: the file (relative to the including one) read into the same load
 * (plant_config_reader.c). 0, or -1 with the load's error set. */
int plant_config_include(ini_file *r, const char *section, const char *key, const char *value);

#endif /* LEVELER_PLANT_CONFIG_SCHEMA_H */
