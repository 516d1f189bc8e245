/* The reader's value types (ini_values.c), for its handler (ini_table.c). Internal to host_sim/ini. */
#ifndef LEVELER_INI_VALUES_H
#define LEVELER_INI_VALUES_H

#include "ini_table.h"

/* Reads value as field f's type into obj (u: the key's unit, NULL for none): 1, or 0 after ini_file_fail. */
int ini_table_value(ini_file *r, const ini_field *f, const ini_unit *u, void *obj, const char *section,
                    const char *key, const char *value);

#endif
