/*
 * The plant config's schema (docs/config-format.md): every key with its unit
 * kind, SI range and place in plant_config, for the one INI reader
 * (ini_table.h). Values are converted to SI on load; a key names its unit
 * (volume_in3, charge_psig); gauge pressures get the ambient pressure added
 * once the file is read.
 */
#include "plant_config_schema.h"

#include <stddef.h>

/* ---- units ---- */

#define LBF_IN (PLANT_N_PER_LBF * PLANT_M_PER_IN)
#define IN3 (PLANT_M_PER_IN * PLANT_M_PER_IN * PLANT_M_PER_IN)

static const ini_unit units[] = {
    {K_PABS, "pa", 1.0, 0}, {K_PABS, "kpa", 1e3, 0}, {K_PABS, "bar", 1e5, 0},
    {K_PABS, "psia", PLANT_PA_PER_PSI, 0}, {K_PABS, "pag", 1.0, 1}, {K_PABS, "psig", PLANT_PA_PER_PSI, 1},
    {K_PGAUGE, "pag", 1.0, 0}, {K_PGAUGE, "psig", PLANT_PA_PER_PSI, 0},
    {K_PDIFF, "pad", 1.0, 0}, {K_PDIFF, "psi", PLANT_PA_PER_PSI, 0},
    {K_VOLUME, "m3", 1.0, 0}, {K_VOLUME, "l", 1e-3, 0}, {K_VOLUME, "cm3", 1e-6, 0}, {K_VOLUME, "in3", IN3, 0},
    {K_LENGTH, "m", 1.0, 0}, {K_LENGTH, "mm", 1e-3, 0}, {K_LENGTH, "in", PLANT_M_PER_IN, 0},
    {K_VEL, "m_per_s", 1.0, 0}, {K_VEL, "in_per_s", PLANT_M_PER_IN, 0},
    {K_MASS, "kg", 1.0, 0}, {K_MASS, "lbm", PLANT_KG_PER_LBM, 0},
    {K_FORCE, "n", 1.0, 0}, {K_FORCE, "lbf", PLANT_N_PER_LBF, 0},
    {K_LDAMP, "n_s_per_m", 1.0, 0}, {K_LDAMP, "lbf_s_per_in", PLANT_N_PER_LBF / PLANT_M_PER_IN, 0},
    {K_TIME, "s", 1.0, 0}, {K_TIME, "ms", 1e-3, 0},
    {K_ANGVEL, "rad_per_s", 1.0, 0}, {K_ANGVEL, "rpm", 2.0 * 3.14159265358979323846 / 60.0, 0},
    {K_TEMP, "k", 1.0, 0}, {K_TEMP, "rankine", 5.0 / 9.0, 0},
    {K_GASR, "j_per_kg_k", 1.0, 0},
    {K_GASR, "in_lbf_per_lbm_r", LBF_IN / (PLANT_KG_PER_LBM * 5.0 / 9.0), 0},
    {K_INERTIA, "kg_m2", 1.0, 0}, {K_INERTIA, "lbf_in_s2", LBF_IN, 0},
    {K_KT, "n_m_per_v", 1.0, 0}, {K_KT, "lbf_in_per_v", LBF_IN, 0},
    {K_RDAMP, "n_m_s", 1.0, 0}, {K_RDAMP, "lbf_in_s", LBF_IN, 0},
    {K_CAP, "m3_per_rad", 1.0, 0}, {K_CAP, "in3_per_rad", IN3, 0},
    {K_LEAK, "m3_per_pa_s", 1.0, 0}, {K_LEAK, "in3_per_psi_s", IN3 / PLANT_PA_PER_PSI, 0},
    {K_SLOPE, "pa_per_m", 1.0, 0}, {K_SLOPE, "psi_per_in", PLANT_PA_PER_PSI / PLANT_M_PER_IN, 0},
    {K_VOLT, "v", 1.0, 0},
    {K_COUNTS, "counts", 1.0, 0},
};

/* ---- fields ---- */

/* A quantity: [section] key_UNIT (or plain key for K_NONE, K_INT), SI range. */
#define Q(section, key, kind, store, offset, min_si, max_si) \
    {section, key, INI_REAL, store, offset, min_si, max_si, kind, 0, NULL, NULL}
#define HAND(section, key, fn) {section, key, INI_CUSTOM, INI_F64, 0, 0, 0, K_NONE, 0, NULL, fn}
#define PP(m) offsetof(plant_config, plant.m)
#define SP(m) offsetof(plant_config, sensors.m)
#define CF(m) offsetof(plant_config, m)
#define HB(m) offsetof(plant_hysteresis_band, m)

static const ini_field fields[] = {
    Q("ambient", "pressure", K_PABS, INI_F64, PP(ambient_pa), 50e3, 120e3),
    Q("ambient", "temperature", K_TEMP, INI_F64, PP(temperature_k), 200, 400),
    Q("ambient", "gas_constant", K_GASR, INI_F64, PP(gas_constant_j_per_kg_k), 250, 320),
    Q("ambient", "compressibility", K_NONE, INI_F64, PP(compressibility), 0.5, 1.5),
    Q("ambient", "polytropic_exponent", K_NONE, INI_F64, PP(polytropic_n), 1.0, 1.67),
    Q("ambient", "specific_heat_ratio", K_NONE, INI_F64, PP(heat_ratio_k), 1.01, 1.67),
    Q("motor", "torque_constant", K_KT, INI_F64, PP(motor_torque_constant_nm_per_v), 0.001, 10),
    Q("motor", "supply", K_VOLT, INI_F64, PP(motor_supply_v), 0, 60),
    Q("motor", "inertia", K_INERTIA, INI_F64, PP(motor_inertia_kg_m2), 1e-5, 10),
    Q("motor", "damping", K_RDAMP, INI_F64, PP(motor_damping_nm_s), 0, 10),
    Q("motor", "torque_coefficient", K_NONE, INI_F64, PP(motor_torque_coefficient), 0, 10),
    Q("compressor", "capacity", K_CAP, INI_F64, PP(compressor_capacity_m3_per_rad), 1e-9, 1e-4),
    Q("compressor", "leakage", K_LEAK, INI_F64, PP(compressor_leakage_m3_per_pa_s), 0, 1e-9),
    Q("pipe", "volume", K_VOLUME, INI_F64, PP(pipe_volume_m3), 1e-6, 1e-2),
    Q("spring_valve", "orifice_diameter", K_LENGTH, INI_F64, PP(spring_valve_diameter_m), 0.1e-3, 50e-3),
    Q("spring_valve", "cd_into_spring", K_NONE, INI_F64, PP(spring_valve_cd_in), 0.01, 1),
    Q("spring_valve", "cd_out_of_spring", K_NONE, INI_F64, PP(spring_valve_cd_out), 0.01, 1),
    Q("vent_valve", "orifice_diameter", K_LENGTH, INI_F64, PP(vent_valve_diameter_m), 0.1e-3, 50e-3),
    Q("vent_valve", "cd", K_NONE, INI_F64, PP(vent_valve_cd), 0.01, 1),
    Q("accumulator", "volume", K_VOLUME, INI_F64, PP(acc_volume_m3), 1e-6, 0.1),
    Q("accumulator", "charge", K_PABS, INI_F64, PP(acc_charge_pa), 101325, 1480276),
    Q("accumulator", "orifice_diameter", K_LENGTH, INI_F64, PP(acc_valve_diameter_m), 0.1e-3, 50e-3),
    Q("accumulator", "cd", K_NONE, INI_F64, PP(acc_valve_cd), 0.01, 1),
    Q("spring", "volume", K_VOLUME, INI_F64, PP(spring_volume0_m3), 1e-5, 0.1),
    Q(PLANT_CONFIG_BANDS, "load_below", K_FORCE, INI_F64, HB(load_below_n), 1, 1e5),
    Q(PLANT_CONFIG_BANDS, "up_slope", K_SLOPE, INI_F64, HB(up_slope_pa_per_m), -1e8, 1e8),
    Q(PLANT_CONFIG_BANDS, "up_intercept", K_PGAUGE, INI_F64, HB(up_intercept_pag), -1e7, 1e7),
    Q(PLANT_CONFIG_BANDS, "down_offset", K_PDIFF, INI_F64, HB(down_offset_pa), 0, 1e6),
    Q("platform", "extra_mass", K_MASS, INI_F64, PP(extra_mass_kg), 0, 1000),
    Q("platform", "damping_up", K_LDAMP, INI_F64, PP(damping_up_n_s_per_m), 0, 1e6),
    Q("platform", "damping_down", K_LDAMP, INI_F64, PP(damping_down_n_s_per_m), 0, 1e6),
    Q("platform", "velocity_deadband", K_VEL, INI_F64, PP(velocity_deadband_m_per_s), 0, 1),
    Q("spring", "load_min", K_FORCE, INI_F64, CF(valid_load_min_n), 0, 1e5),
    Q("spring", "load_max", K_FORCE, INI_F64, CF(valid_load_max_n), 0, 1e5),
    Q("platform", "height_min", K_LENGTH, INI_F64, PP(height_min_m), 0, 2),
    Q("platform", "height_max", K_LENGTH, INI_F64, PP(height_max_m), 0, 2),
    Q("initial", "height", K_LENGTH, INI_F64, PP(init_height_m), 0, 2),
    Q("initial", "velocity", K_VEL, INI_F64, PP(init_velocity_m_per_s), -1, 1),
    Q("initial", "p_pipe", K_PABS, INI_F64, PP(init_p_pipe_pa), 50e3, 2e6),
    Q("initial", "p_spring", K_PABS, INI_F64, PP(init_p_spring_pa), 50e3, 2e6),
    Q("initial", "motor_speed", K_ANGVEL, INI_F64, PP(init_motor_speed_rad_per_s), 0, 1000),
    Q("initial", "compressor", K_INT, INI_INT, CF(init_compressor), 0, 1),
    Q("initial", "spring_valve", K_INT, INI_INT, CF(init_spring_valve), 0, 1),
    Q("initial", "vent_valve", K_INT, INI_INT, CF(init_vent_valve), 0, 1),
    Q("initial", "acc_valve", K_INT, INI_INT, CF(init_acc_valve), 0, 1),
    Q("scenario", "base_load", K_FORCE, INI_F64, CF(base_load_n), 0, 1e5),
    Q("scenario", "step_load", K_FORCE, INI_F64, CF(step_load_n), -1e5, 1e5),
    Q("scenario", "step_on", K_TIME, INI_F64, CF(step_on_s), 0, 1e6),
    Q("scenario", "step_off", K_TIME, INI_F64, CF(step_off_s), 0, 1e6),
    Q("scenario", "end", K_TIME, INI_F64, CF(end_s), 0.01, 1e7),
    Q("controller", "algorithm", K_INT, INI_INT, CF(algorithm), 1, 3),
    Q("controller", "band_lower", K_LENGTH, INI_F64, CF(band_lower_m), 0, 1),
    Q("controller", "band_upper", K_LENGTH, INI_F64, CF(band_upper_m), 0, 1),
    Q("controller", "chatter_max_per_min", K_INT, INI_INT, CF(chatter_max_per_min), 0, 600),
    Q("sensors", "height_lo", K_COUNTS, INI_F64, SP(height_lo_counts), 0, 4095),
    Q("sensors", "height_hi", K_COUNTS, INI_F64, SP(height_hi_counts), 0, 4095),
    Q("sensors", "height_lo", K_LENGTH, INI_F64, SP(height_lo_m), -2, 2),
    Q("sensors", "height_hi", K_LENGTH, INI_F64, SP(height_hi_m), -2, 2),
    Q("sensors", "pressure_lo", K_COUNTS, INI_F64, SP(pressure_lo_counts), 0, 4095),
    Q("sensors", "pressure_hi", K_COUNTS, INI_F64, SP(pressure_hi_counts), 0, 4095),
    Q("sensors", "pressure_lo", K_PABS, INI_F64, SP(pressure_lo_pa), 0, 2e6),
    Q("sensors", "pressure_hi", K_PABS, INI_F64, SP(pressure_hi_pa), 0, 2e6),
    Q("sensors", "noise", K_COUNTS, INI_F64, SP(noise_counts), 0, 100),
    Q("sensors", "noise_seed", K_INT, INI_U32, SP(noise_seed), 0, 4294967295.0),
    Q("solver", "substeps_per_tick", K_INT, INI_INT, CF(substeps_per_tick), 1, 1000),

    /* the keys read by hand: strings and lists (plant_config_lists.c) */
    HAND("config", "include", plant_config_key_include),
    HAND("config", "name", plant_config_key_name),
    HAND("accumulator", "type", plant_config_key_acc_type),
    HAND("spring", "area_cc1_poly_in2", plant_config_key_area_poly),
    HAND("spring", "area_cc2_poly_in2_per_in", plant_config_key_area_poly),
    HAND("accumulator", "diaphragm_breaks_psia", plant_config_key_diaphragm_breaks),
    HAND("accumulator", "diaphragm_slopes_in3_per_psi", plant_config_key_diaphragm_segments),
    HAND("accumulator", "diaphragm_intercepts_in3", plant_config_key_diaphragm_segments),
};

const ini_table plant_config_table = {
    .fields = fields,
    .field_count = sizeof fields / sizeof fields[0],
    .units = units,
    .unit_count = sizeof units / sizeof units[0],
    .max_instances = PLANT_MAX_BANDS,
    .see = "docs/config-format.md",
    .instance = plant_config_band,
    .other = plant_config_effect_section,
    .stored = plant_config_stored,
    .gauge_offset = plant_config_ambient_pa,
};
