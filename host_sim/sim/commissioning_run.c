/* The commissioning routine on a config's plant (commissioning_run.h). */
#include "commissioning_run.h"

#include <math.h>
#include <string.h>

#include "leveler/alg3.h"
#include "leveler/commissioning.h"
#include "leveler/settings.h"
#include "leveler/status.h"

const char *sim_commissioning_result_name(uint16_t result)
{
    static const char *const names[] = {"never run", "done", "timed out", "aborted", "refused", "fault"};
    return result < sizeof names / sizeof names[0] ? names[result] : "?";
}

static void fill_truth(const plant_config *cfg, const leveler_settings *set, sim_commissioning *o)
{
    o->target_m = leveler_alg3_target_um(set) * 1e-6;
    const plant_hysteresis_band *b = plant_band_for_load(&cfg->plant, cfg->base_load_n);
    o->true_up_pa = plant_up_limit_pag(b, o->target_m) + cfg->plant.ambient_pa;
    o->true_down_pa = plant_down_limit_pag(b, o->target_m) + cfg->plant.ambient_pa;
}

int sim_commissioning_run(const plant_config *cfg, double end_s, runlog *log, sim_commissioning *out, char *err,
                          size_t err_len)
{
    sim_load_step hold = {.t_s = 0.0, .load_n = cfg->base_load_n};
    sim_options so = {.config = cfg, .algorithm = LEVELER_ALGO_HYSTERESIS_AWARE, .steps = &hold, .step_count = 1,
                      .end_s = end_s > 0.0 ? end_s : SIM_COMMISSIONING_END_S, .log = log, .commission = true};
    static sim_result res;
    if (sim_run(&so, &res, err, err_len) != 0)
        return -1;
    const leveler_settings *set = leveler_settings_current();
    memset(out, 0, sizeof *out);
    out->result = set->commission_result;
    out->took_s = set->commission_ms / 1000.0;
    out->up_pa = set->commission_up_pa;
    out->down_pa = set->commission_down_pa;
    out->gap_pa = set->alg3_gap_pa;
    out->k_up_pa_per_mm = set->alg3_coast_k_up_pa_per_mm;
    out->k_down_pa_per_mm = set->alg3_coast_k_down_pa_per_mm;
    out->coast_up_ms = set->alg3_coast_up_ms;
    out->coast_down_ms = set->alg3_coast_down_ms;
    out->moves = leveler_app_status()->alg3_moves;
    out->latched_faults = leveler_app_status()->latched_fault_bits;
    out->final_height_m = res.final_plant.x[PLANT_X_Y];
    out->in_band = out->final_height_m >= cfg->band_lower_m && out->final_height_m <= cfg->band_upper_m;
    fill_truth(cfg, set, out);
    return 0;
}
