/*
 * The perturbed rig family (issue 19): rigs made by perturbing the thesis rig
 * (900 lb, diaphragm accumulator) with fixed seeds, each written as an INI
 * file that includes the thesis config and overrides what it perturbs, so
 * the one config loader (plant_config_load) validates every rig:
 *   - discharge coefficients and orifices of the spring, vent and accumulator
 *     valves: x0.75..x1.25 each;
 *   - spring and pipe volumes: x0.8..x1.2;
 *   - damping up and down: x0.5..x2 each (log-uniform);
 *   - every hysteresis band's up line: +-5 psi, its gap 8..14 psi;
 *   - accumulator charge: x0.9..x1.1 (gauge);
 *   - compressor displacement: x0.85..x1.15.
 * Uniform draws from xorshift32 seeded with seed + rig index.
 */
#ifndef LEVELER_CTLBENCH_FAMILY_H
#define LEVELER_CTLBENCH_FAMILY_H

#include <stddef.h>
#include <stdint.h>

#define CTLBENCH_FAMILY_BASE "thesis-900lb-diaphragm.ini"
#define CTLBENCH_FAMILY_BANDS 4

typedef struct {
    char file[64];                 /* rig-NN.ini */
    double spring_orifice, spring_cd_in, spring_cd_out; /* factors */
    double vent_orifice, vent_cd, acc_orifice, acc_cd;
    double spring_volume, pipe_volume, damping_up, damping_down, charge, displacement;
    double up_shift_psi[CTLBENCH_FAMILY_BANDS], gap_psi[CTLBENCH_FAMILY_BANDS];
} ctlbench_rig;

/* Draw rig `index` (0-based) of the family seeded `seed`. */
void ctlbench_family_draw(uint32_t seed, unsigned index, ctlbench_rig *rig);

/* Write rig's INI into dir (including configs_dir's base config by its absolute path). 0 or -1 with err. */
int ctlbench_family_write(const ctlbench_rig *rig, const char *dir, const char *configs_dir, char *err,
                          size_t err_len);

#endif /* LEVELER_CTLBENCH_FAMILY_H */
