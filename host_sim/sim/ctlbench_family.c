/* The perturbed rig family (ctlbench_family.h). */
#define _XOPEN_SOURCE 700
#include "ctlbench_family.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plant.h"

/* Deterministic uniform in [lo, hi) (xorshift32; the state never 0). */
static double draw(uint32_t *s, double lo, double hi)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return lo + (hi - lo) * ((double)*s / 4294967296.0);
}

void ctlbench_family_draw(uint32_t seed, unsigned index, ctlbench_rig *r)
{
    uint32_t s = (seed + index) * 2654435761u;
    s = s ? s : 1u;
    for (int i = 0; i < 8; i++)
        (void)draw(&s, 0, 1); /* let nearby seeds part */
    memset(r, 0, sizeof *r);
    snprintf(r->file, sizeof r->file, "rig-%02u.ini", index + 1);
    r->spring_orifice = draw(&s, 0.75, 1.25);
    r->spring_cd_in = draw(&s, 0.75, 1.25);
    r->spring_cd_out = draw(&s, 0.75, 1.25);
    r->vent_orifice = draw(&s, 0.75, 1.25);
    r->vent_cd = draw(&s, 0.75, 1.25);
    r->acc_orifice = draw(&s, 0.75, 1.25);
    r->acc_cd = draw(&s, 0.75, 1.25);
    r->spring_volume = draw(&s, 0.8, 1.2);
    r->pipe_volume = draw(&s, 0.8, 1.2);
    r->damping_up = exp2(draw(&s, -1.0, 1.0));
    r->damping_down = exp2(draw(&s, -1.0, 1.0));
    r->charge = draw(&s, 0.9, 1.1);
    r->displacement = draw(&s, 0.85, 1.15);
    for (int b = 0; b < CTLBENCH_FAMILY_BANDS; b++) {
        r->up_shift_psi[b] = draw(&s, -5.0, 5.0);
        r->gap_psi[b] = draw(&s, 8.0, 14.0);
    }
}

/* The overrides, in SI (the loader takes every unit; values from the base config times the factors). */
static void write_keys(FILE *f, const ctlbench_rig *r, const plant_params *p)
{
    fprintf(f, "[compressor]\ncapacity_m3_per_rad = %.9g\n\n", p->compressor_capacity_m3_per_rad * r->displacement);
    fprintf(f, "[pipe]\nvolume_m3 = %.9g\n\n", p->pipe_volume_m3 * r->pipe_volume);
    fprintf(f, "[spring_valve]\norifice_diameter_m = %.9g\ncd_into_spring = %.6f\ncd_out_of_spring = %.6f\n\n",
            p->spring_valve_diameter_m * r->spring_orifice, p->spring_valve_cd_in * r->spring_cd_in,
            p->spring_valve_cd_out * r->spring_cd_out);
    fprintf(f, "[vent_valve]\norifice_diameter_m = %.9g\ncd = %.6f\n\n", p->vent_valve_diameter_m * r->vent_orifice,
            p->vent_valve_cd * r->vent_cd);
    fprintf(f, "[accumulator]\norifice_diameter_m = %.9g\ncd = %.6f\ncharge_pag = %.1f\n\n",
            p->acc_valve_diameter_m * r->acc_orifice, p->acc_valve_cd * r->acc_cd,
            (p->acc_charge_pa - p->ambient_pa) * r->charge);
    fprintf(f, "[spring]\nvolume_m3 = %.9g\n\n", p->spring_volume0_m3 * r->spring_volume);
    fprintf(f, "[platform]\ndamping_up_n_s_per_m = %.3f\ndamping_down_n_s_per_m = %.3f\n",
            p->damping_up_n_s_per_m * r->damping_up, p->damping_down_n_s_per_m * r->damping_down);
    for (int b = 0; b < p->band_count && b < CTLBENCH_FAMILY_BANDS; b++)
        fprintf(f, "\n[hysteresis.%d]\nup_intercept_pag = %.1f\ndown_offset_psi = %.3f\n", b + 1,
                p->bands[b].up_intercept_pag + r->up_shift_psi[b] * PLANT_PA_PER_PSI, r->gap_psi[b]);
}

int ctlbench_family_write(const ctlbench_rig *rig, const char *dir, const char *configs_dir, char *err,
                          size_t err_len)
{
    char base[PLANT_PATH_MAX], path[PLANT_PATH_MAX + 80];
    snprintf(base, sizeof base, "%s/%s", configs_dir, CTLBENCH_FAMILY_BASE);
    char *abs = realpath(base, NULL);
    static plant_config cfg;
    if (!abs) {
        snprintf(err, err_len, "%s: %s", base, strerror(errno));
        return -1;
    }
    if (plant_config_load(abs, &cfg, err, err_len) != 0) {
        free(abs);
        return -1;
    }
    snprintf(path, sizeof path, "%s/%s", dir, rig->file);
    FILE *f = fopen(path, "w");
    if (!f) {
        snprintf(err, err_len, "%s: %s", path, strerror(errno));
        free(abs);
        return -1;
    }
    fprintf(f, "; %s: the thesis rig perturbed (leveler-ctlbench-family; ctlbench_family.h)\n", rig->file);
    fprintf(f, "[config]\ninclude = %s\nname = %.*s\n\n", abs, (int)(strlen(rig->file) - 4), rig->file);
    free(abs);
    write_keys(f, rig, &cfg.plant);
    if (fclose(f) != 0) {
        snprintf(err, err_len, "%s: write failed", path);
        return -1;
    }
    return 0;
}
