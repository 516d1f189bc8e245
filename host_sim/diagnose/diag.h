/*
 * The diagnosis library's one run (diag_shim.c), for its ctypes entry points
 * and for the blind test's truth library (host_sim/blindtest/truth_shim.c),
 * which runs its own effect models through it.
 */
#ifndef LEVELER_DIAG_H
#define LEVELER_DIAG_H

#include <stdint.h>

#include "effects.h"

/* diag_simulate() with fx_kinds (0 = none) looked up in another table of effect models. */
int diag_run(const plant_fx_model *table, int table_count, const char *config_path, int n, const double *t_s,
             const double *load_n, const int32_t *commands, const double *p1_track, const int32_t *fx_kinds,
             const double *fx_params, const double *init, double *out, int32_t *cmd_out, char *err, int err_len);

#endif /* LEVELER_DIAG_H */
