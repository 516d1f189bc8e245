/*
 * libleveler_truth.so: the diagnosis library's run with the blind test's
 * truth variants (truth.c, catalogued in truth.json) in place of the
 * candidates, for scripts/leveler/diagnose/blindtest.py (ctypes); truth2_simulate
 * the same with the second family (truth2.c, truth2.json: forms written from the
 * physics alone).
 */
#include "diag.h"

extern const plant_fx_model truth_catalogue[];
extern const int truth_catalogue_count;
extern const plant_fx_model truth2_catalogue[];
extern const int truth2_catalogue_count;

/* As diag_simulate (host_sim/diagnose/diag_shim.c), fx_kinds naming truth variants. */
int truth_simulate(const char *config_path, int n, const double *t_s, const double *load_n,
                   const int32_t *commands, const double *p1_track, const int32_t *fx_kinds, const double *fx_params,
                   const double *init, double *out, int32_t *cmd_out, char *err, int err_len)
{
    return diag_run(truth_catalogue, truth_catalogue_count, config_path, n, t_s, load_n, commands, p1_track,
                    fx_kinds, fx_params, init, out, cmd_out, err, err_len);
}

/* As truth_simulate, fx_kinds naming forms of the second family (truth2.json ids). */
int truth2_simulate(const char *config_path, int n, const double *t_s, const double *load_n,
                    const int32_t *commands, const double *p1_track, const int32_t *fx_kinds, const double *fx_params,
                    const double *init, double *out, int32_t *cmd_out, char *err, int err_len)
{
    return diag_run(truth2_catalogue, truth2_catalogue_count, config_path, n, t_s, load_n, commands, p1_track,
                    fx_kinds, fx_params, init, out, cmd_out, err, err_len);
}
