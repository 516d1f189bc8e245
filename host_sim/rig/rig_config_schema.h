/*
 * The rig config's schema for the one INI reader (ini_table.h):
 * rig_config_schema.c. Internal to host_sim/rig (rig_config.c loads with it).
 */
#ifndef LEVELER_RIG_CONFIG_SCHEMA_H
#define LEVELER_RIG_CONFIG_SCHEMA_H

#include "ini_table.h"
#include "rig_config.h"

/* What one load keeps besides the config (ini_load.user). */
typedef struct {
    bool seen_channel[HAL_ADC_COUNT + 1]; /* a [sensor.X] of the file turned the channel on (the load last) */
    bool seen_watchdog_register;
} rig_config_state;

extern const ini_table rig_config_table;

#endif
