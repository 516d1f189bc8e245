/*
 * Configuration files for the plant (docs/config-format.md), parsed with libinih.
 * Every key carries its unit; values are converted to SI on load, checked
 * against a physical range, and unknown or repeated keys are errors that name
 * the file, the line, the field and the allowed range.
 */
#define _POSIX_C_SOURCE 200809L
#include "ini_guard.h"
#include "plant.h"
#include "config_table.h"
#include "effects.h"

#include <errno.h>
#include <ini.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- units ---- */


#define LBF_IN (PLANT_N_PER_LBF * PLANT_M_PER_IN)
#define IN3 (PLANT_M_PER_IN * PLANT_M_PER_IN * PLANT_M_PER_IN)

const unit units[] = {
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


#define PP(m) offsetof(plant_config, plant.m)
#define SP(m) offsetof(plant_config, sensors.m)
#define CF(m) offsetof(plant_config, m)
#define HB(m) offsetof(plant_hysteresis_band, m)

const field fields[] = {
    {"ambient", "pressure", K_PABS, T_DOUBLE, PP(ambient_pa), 50e3, 120e3},
    {"ambient", "temperature", K_TEMP, T_DOUBLE, PP(temperature_k), 200, 400},
    {"ambient", "gas_constant", K_GASR, T_DOUBLE, PP(gas_constant_j_per_kg_k), 250, 320},
    {"ambient", "compressibility", K_NONE, T_DOUBLE, PP(compressibility), 0.5, 1.5},
    {"ambient", "polytropic_exponent", K_NONE, T_DOUBLE, PP(polytropic_n), 1.0, 1.67},
    {"ambient", "specific_heat_ratio", K_NONE, T_DOUBLE, PP(heat_ratio_k), 1.01, 1.67},
    {"motor", "torque_constant", K_KT, T_DOUBLE, PP(motor_torque_constant_nm_per_v), 0.001, 10},
    {"motor", "supply", K_VOLT, T_DOUBLE, PP(motor_supply_v), 0, 60},
    {"motor", "inertia", K_INERTIA, T_DOUBLE, PP(motor_inertia_kg_m2), 1e-5, 10},
    {"motor", "damping", K_RDAMP, T_DOUBLE, PP(motor_damping_nm_s), 0, 10},
    {"motor", "torque_coefficient", K_NONE, T_DOUBLE, PP(motor_torque_coefficient), 0, 10},
    {"compressor", "capacity", K_CAP, T_DOUBLE, PP(compressor_capacity_m3_per_rad), 1e-9, 1e-4},
    {"compressor", "leakage", K_LEAK, T_DOUBLE, PP(compressor_leakage_m3_per_pa_s), 0, 1e-9},
    {"pipe", "volume", K_VOLUME, T_DOUBLE, PP(pipe_volume_m3), 1e-6, 1e-2},
    {"spring_valve", "orifice_diameter", K_LENGTH, T_DOUBLE, PP(spring_valve_diameter_m), 0.1e-3, 50e-3},
    {"spring_valve", "cd_into_spring", K_NONE, T_DOUBLE, PP(spring_valve_cd_in), 0.01, 1},
    {"spring_valve", "cd_out_of_spring", K_NONE, T_DOUBLE, PP(spring_valve_cd_out), 0.01, 1},
    {"vent_valve", "orifice_diameter", K_LENGTH, T_DOUBLE, PP(vent_valve_diameter_m), 0.1e-3, 50e-3},
    {"vent_valve", "cd", K_NONE, T_DOUBLE, PP(vent_valve_cd), 0.01, 1},
    {"accumulator", "volume", K_VOLUME, T_DOUBLE, PP(acc_volume_m3), 1e-6, 0.1},
    {"accumulator", "charge", K_PABS, T_DOUBLE, PP(acc_charge_pa), 101325, 1480276},
    {"accumulator", "orifice_diameter", K_LENGTH, T_DOUBLE, PP(acc_valve_diameter_m), 0.1e-3, 50e-3},
    {"accumulator", "cd", K_NONE, T_DOUBLE, PP(acc_valve_cd), 0.01, 1},
    {"spring", "volume", K_VOLUME, T_DOUBLE, PP(spring_volume0_m3), 1e-5, 0.1},
    {"hysteresis", "load_below", K_FORCE, T_DOUBLE, HB(load_below_n), 1, 1e5},
    {"hysteresis", "up_slope", K_SLOPE, T_DOUBLE, HB(up_slope_pa_per_m), -1e8, 1e8},
    {"hysteresis", "up_intercept", K_PGAUGE, T_DOUBLE, HB(up_intercept_pag), -1e7, 1e7},
    {"hysteresis", "down_offset", K_PDIFF, T_DOUBLE, HB(down_offset_pa), 0, 1e6},
    {"platform", "extra_mass", K_MASS, T_DOUBLE, PP(extra_mass_kg), 0, 1000},
    {"platform", "damping_up", K_LDAMP, T_DOUBLE, PP(damping_up_n_s_per_m), 0, 1e6},
    {"platform", "damping_down", K_LDAMP, T_DOUBLE, PP(damping_down_n_s_per_m), 0, 1e6},
    {"platform", "velocity_deadband", K_VEL, T_DOUBLE, PP(velocity_deadband_m_per_s), 0, 1},
    {"spring", "load_min", K_FORCE, T_DOUBLE, CF(valid_load_min_n), 0, 1e5},
    {"spring", "load_max", K_FORCE, T_DOUBLE, CF(valid_load_max_n), 0, 1e5},
    {"platform", "height_min", K_LENGTH, T_DOUBLE, PP(height_min_m), 0, 2},
    {"platform", "height_max", K_LENGTH, T_DOUBLE, PP(height_max_m), 0, 2},
    {"initial", "height", K_LENGTH, T_DOUBLE, PP(init_height_m), 0, 2},
    {"initial", "velocity", K_VEL, T_DOUBLE, PP(init_velocity_m_per_s), -1, 1},
    {"initial", "p_pipe", K_PABS, T_DOUBLE, PP(init_p_pipe_pa), 50e3, 2e6},
    {"initial", "p_spring", K_PABS, T_DOUBLE, PP(init_p_spring_pa), 50e3, 2e6},
    {"initial", "motor_speed", K_ANGVEL, T_DOUBLE, PP(init_motor_speed_rad_per_s), 0, 1000},
    {"initial", "compressor", K_INT, T_INT, CF(init_compressor), 0, 1},
    {"initial", "spring_valve", K_INT, T_INT, CF(init_spring_valve), 0, 1},
    {"initial", "vent_valve", K_INT, T_INT, CF(init_vent_valve), 0, 1},
    {"initial", "acc_valve", K_INT, T_INT, CF(init_acc_valve), 0, 1},
    {"scenario", "base_load", K_FORCE, T_DOUBLE, CF(base_load_n), 0, 1e5},
    {"scenario", "step_load", K_FORCE, T_DOUBLE, CF(step_load_n), -1e5, 1e5},
    {"scenario", "step_on", K_TIME, T_DOUBLE, CF(step_on_s), 0, 1e6},
    {"scenario", "step_off", K_TIME, T_DOUBLE, CF(step_off_s), 0, 1e6},
    {"scenario", "end", K_TIME, T_DOUBLE, CF(end_s), 0.01, 1e7},
    {"controller", "algorithm", K_INT, T_INT, CF(algorithm), 1, 3},
    {"controller", "band_lower", K_LENGTH, T_DOUBLE, CF(band_lower_m), 0, 1},
    {"controller", "band_upper", K_LENGTH, T_DOUBLE, CF(band_upper_m), 0, 1},
    {"controller", "chatter_max_per_min", K_INT, T_INT, CF(chatter_max_per_min), 0, 600},
    {"sensors", "height_lo", K_COUNTS, T_DOUBLE, SP(height_lo_counts), 0, 4095},
    {"sensors", "height_hi", K_COUNTS, T_DOUBLE, SP(height_hi_counts), 0, 4095},
    {"sensors", "height_lo", K_LENGTH, T_DOUBLE, SP(height_lo_m), -2, 2},
    {"sensors", "height_hi", K_LENGTH, T_DOUBLE, SP(height_hi_m), -2, 2},
    {"sensors", "pressure_lo", K_COUNTS, T_DOUBLE, SP(pressure_lo_counts), 0, 4095},
    {"sensors", "pressure_hi", K_COUNTS, T_DOUBLE, SP(pressure_hi_counts), 0, 4095},
    {"sensors", "pressure_lo", K_PABS, T_DOUBLE, SP(pressure_lo_pa), 0, 2e6},
    {"sensors", "pressure_hi", K_PABS, T_DOUBLE, SP(pressure_hi_pa), 0, 2e6},
    {"sensors", "noise", K_COUNTS, T_DOUBLE, SP(noise_counts), 0, 100},
    {"sensors", "noise_seed", K_INT, T_U32, SP(noise_seed), 0, 4294967295.0},
    {"solver", "substeps_per_tick", K_INT, T_INT, CF(substeps_per_tick), 1, 1000},
};
#define FIELD_COUNT (sizeof fields / sizeof fields[0])
const size_t config_unit_count = sizeof units / sizeof units[0];
const size_t config_field_count = FIELD_COUNT;

/* Keys handled by hand (strings, lists). */
static const char *const special_keys[][2] = {
    {"config", "include"}, {"config", "name"}, {"accumulator", "type"},
    {"spring", "area_cc1_poly_in2"}, {"spring", "area_cc2_poly_in2_per_in"},
    {"accumulator", "diaphragm_breaks_psia"}, {"accumulator", "diaphragm_slopes_in3_per_psi"},
    {"accumulator", "diaphragm_intercepts_in3"},
};
#define SPECIAL_COUNT (sizeof special_keys / sizeof special_keys[0])
#define SLOT_COUNT (FIELD_COUNT * PLANT_MAX_BANDS + SPECIAL_COUNT)

/* ---- parse context ---- */

typedef struct {
    plant_config *cfg;
    int gauge[FIELD_COUNT * PLANT_MAX_BANDS]; /* value written as gauge: add ambient at the end */
    int band_seen[PLANT_MAX_BANDS];
    unsigned band_keys[PLANT_MAX_BANDS]; /* bit i: fields[i] given for the band */
    char edge_where[PLANT_PATH_MAX + 16]; /* file:line of the last band_lower/band_upper */
    char *err;
    size_t err_len;
    int failed;
    int depth;
} load_ctx;

typedef struct {
    ini_guard guard; /* the file, real line numbers, repeated keys and sections */
    const char *path;
    int keys_seen;
    unsigned seen_line[SLOT_COUNT]; /* line where each quantity was given (any unit); 0 = not yet */
    load_ctx *ctx;
} file_ctx;

static void fail(file_ctx *fc, const char *section, const char *name, const char *value, const char *fmt, ...)
{
    load_ctx *ctx = fc->ctx;
    if (ctx->failed)
        return;
    ctx->failed = 1;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (name)
        snprintf(ctx->err, ctx->err_len, "%s:%u: [%s] %s = %s: %s", fc->path, fc->guard.line, section, name,
                 value ? value : "", msg);
    else
        snprintf(ctx->err, ctx->err_len, "%s:%u: %s", fc->path, fc->guard.line, msg);
}

static int parse_number(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno == ERANGE || !isfinite(v))
        return -1;
    while (*end == ' ' || *end == '\t')
        end++;
    if (*end)
        return -1;
    *out = v;
    return 0;
}

static int parse_list(const char *s, double *out, int max, int *count)
{
    int n = 0;
    const char *p = s;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == ',')
            p++;
        if (!*p)
            break;
        char *end;
        errno = 0;
        double v = strtod(p, &end);
        if (end == p || errno == ERANGE || !isfinite(v) || n >= max)
            return -1;
        out[n++] = v;
        p = end;
    }
    if (n == 0)
        return -1;
    *count = n;
    return 0;
}

static int load_file(load_ctx *ctx, const char *path);

static int band_index(const char *section)
{
    if (strncmp(section, "hysteresis.", 11) != 0)
        return -1;
    char *end;
    long n = strtol(section + 11, &end, 10);
    if (*end || end == section + 11 || n < 1 || n > PLANT_MAX_BANDS)
        return -2;
    return (int)n - 1;
}

static int is_known_section(const char *s)
{
    static const char *const names[] = {"config", "ambient", "motor", "compressor", "pipe", "spring_valve",
                                        "vent_valve", "accumulator", "spring", "platform", "initial",
                                        "scenario", "controller", "sensors", "solver"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(s, names[i]) == 0)
            return 1;
    return band_index(s) >= 0;
}

static void allowed_suffixes(kind k, char *buf, size_t len)
{
    buf[0] = 0;
    for (size_t i = 0; i < sizeof units / sizeof units[0]; i++)
        if (units[i].k == k) {
            size_t used = strlen(buf);
            snprintf(buf + used, len - used, "%s_%s", used ? ", " : "", units[i].suffix);
        }
}

/* The keys read by hand (strings, lists): 1 done, 0 failed (message set). */
static int key_include(file_ctx *fc, const char *section, const char *name, const char *value)
{
    load_ctx *ctx = fc->ctx;
    if (fc->keys_seen != 1) {
        fail(fc, section, name, value, "include must be the first key of the file");
        return 0;
    }
    if (ctx->depth >= 4) {
        fail(fc, section, name, value, "includes nested more than 4 deep");
        return 0;
    }
    char inc[PLANT_PATH_MAX];
    const char *slash = strrchr(fc->path, '/');
    if (value[0] != '/' && slash)
        snprintf(inc, sizeof inc, "%.*s/%s", (int)(slash - fc->path), fc->path, value);
    else
        snprintf(inc, sizeof inc, "%s", value);
    ctx->depth++;
    load_file(ctx, inc);
    ctx->depth--;
    return 1;
}

static int key_name(file_ctx *fc, const char *section, const char *name, const char *value)
{
    plant_config *cfg = fc->ctx->cfg;
    if (!ini_utf8_valid(value)) {
        fail(fc, section, name, value, "name must be valid UTF-8");
        return 0;
    }
    if (!value[0] || strlen(value) >= PLANT_NAME_MAX) {
        fail(fc, section, name, value, "name must be 1..%d characters", PLANT_NAME_MAX - 1);
        return 0;
    }
    snprintf(cfg->name, sizeof cfg->name, "%s", value);
    return 1;
}

static int key_acc_type(file_ctx *fc, const char *section, const char *name, const char *value)
{
    plant_config *cfg = fc->ctx->cfg;
    if (strcmp(value, "none") == 0)
        cfg->plant.acc_type = PLANT_ACC_NONE;
    else if (strcmp(value, "tube") == 0)
        cfg->plant.acc_type = PLANT_ACC_TUBE;
    else if (strcmp(value, "diaphragm") == 0)
        cfg->plant.acc_type = PLANT_ACC_DIAPHRAGM;
    else {
        fail(fc, section, name, value, "allowed: none, tube, diaphragm");
        return 0;
    }
    return 1;
}

static int key_area_poly(file_ctx *fc, const char *section, const char *name, const char *value)
{
    plant_config *cfg = fc->ctx->cfg;
    int cc1 = strcmp(name, "area_cc1_poly_in2") == 0;
    double *dst = cc1 ? cfg->plant.area_cc1_in2 : cfg->plant.area_cc2_in2_per_in;
    int *cnt = cc1 ? &cfg->plant.area_cc1_terms : &cfg->plant.area_cc2_terms;
    double tmp[PLANT_MAX_POLY];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_POLY, &n) != 0) {
        fail(fc, section, name, value, "expected 1..%d numbers (coefficients of DL^0, DL^1, ...)", PLANT_MAX_POLY);
        return 0;
    }
    memset(dst, 0, sizeof(double) * PLANT_MAX_POLY);
    memcpy(dst, tmp, sizeof(double) * (size_t)n);
    *cnt = n;
    return 1;
}

/* Thesis units, converted to SI here; counts are checked together in plant_config_check. */
static int key_diaphragm_breaks(file_ctx *fc, const char *section, const char *name, const char *value)
{
    plant_params *p = &fc->ctx->cfg->plant;
    double tmp[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_DIAPHRAGM_SEGMENTS - 1, &n) != 0) {
        fail(fc, section, name, value, "expected 1..%d pressures, psia, rising", PLANT_MAX_DIAPHRAGM_SEGMENTS - 1);
        return 0;
    }
    for (int i = 0; i < n; i++) {
        if (!(tmp[i] > 0.0 && tmp[i] < 300.0) || (i > 0 && !(tmp[i] > tmp[i - 1]))) {
            fail(fc, section, name, value, "break %d: %g psia; breaks must rise, each in (0, 300) psia", i + 1, tmp[i]);
            return 0;
        }
        p->diaphragm_break_pa[i] = tmp[i] * PLANT_PA_PER_PSI;
    }
    p->diaphragm_segments = n + 1;
    return 1;
}

static int key_diaphragm_segments(file_ctx *fc, const char *section, const char *name, const char *value)
{
    static const double in3 = PLANT_M_PER_IN * PLANT_M_PER_IN * PLANT_M_PER_IN;
    plant_params *p = &fc->ctx->cfg->plant;
    int slope = strcmp(name, "diaphragm_slopes_in3_per_psi") == 0;
    double tmp[PLANT_MAX_DIAPHRAGM_SEGMENTS];
    int n;
    if (parse_list(value, tmp, PLANT_MAX_DIAPHRAGM_SEGMENTS, &n) != 0) {
        fail(fc, section, name, value, "expected 1..%d numbers, one per segment", PLANT_MAX_DIAPHRAGM_SEGMENTS);
        return 0;
    }
    for (int i = 0; i < n; i++) {
        if (slope && !(tmp[i] >= 0.0 && tmp[i] <= 1000.0)) {
            fail(fc, section, name, value, "segment %d: %g in^3/psi out of range [0, 1000]", i + 1, tmp[i]);
            return 0;
        }
        if (slope)
            p->diaphragm_slope_m3_per_pa[i] = tmp[i] * in3 / PLANT_PA_PER_PSI;
        else
            p->diaphragm_intercept_m3[i] = tmp[i] * in3;
    }
    *(slope ? &p->diaphragm_slope_count : &p->diaphragm_intercept_count) = n;
    return 1;
}

typedef int (*key_fn)(file_ctx *fc, const char *section, const char *name, const char *value);

/* The key's hand reader (special_keys[i]), by position. */
static const key_fn special_readers[] = {
    key_include, key_name, key_acc_type, key_area_poly, key_area_poly,
    key_diaphragm_breaks, key_diaphragm_segments, key_diaphragm_segments,
};
_Static_assert(sizeof special_readers / sizeof special_readers[0] == SPECIAL_COUNT, "one reader per special key");

static size_t first_band_field(void)
{
    size_t i = 0;
    while (strcmp(fields[i].section, "hysteresis") != 0)
        i++;
    return i;
}

/* What a file must give together: all four keys of a [hysteresis.N] it names,
 * and a band whose upper edge is above its lower one. 0 or -1 with err. */
static int check_given(const load_ctx *ctx, const char *path)
{
    const plant_config *c = ctx->cfg;
    for (int b = 0; b < PLANT_MAX_BANDS; b++) {
        if (!ctx->band_seen[b])
            continue;
        for (size_t i = first_band_field(); i < FIELD_COUNT && strcmp(fields[i].section, "hysteresis") == 0; i++)
            if (!(ctx->band_keys[b] & (1u << (i - first_band_field())))) {
                char list[256];
                allowed_suffixes(fields[i].k, list, sizeof list);
                snprintf(ctx->err, ctx->err_len, "%s: [hysteresis.%d] %s: missing (with a unit suffix: %s)", path,
                         b + 1, fields[i].base, list);
                return -1;
            }
    }
    if (ctx->edge_where[0] && !(c->band_upper_m > c->band_lower_m)) {
        snprintf(ctx->err, ctx->err_len, "%s: [controller] band_lower must be below band_upper (%.6g m, %.6g m)",
                 ctx->edge_where, c->band_lower_m, c->band_upper_m);
        return -1;
    }
    return 0;
}

/* A special key (special_keys): -1 if name is not one, else handled (1 ok, 0 failed). */
static int read_special(file_ctx *fc, const char *section, const char *name, const char *value)
{
    for (size_t i = 0; i < SPECIAL_COUNT; i++) {
        if (strcmp(section, special_keys[i][0]) == 0 && strcmp(name, special_keys[i][1]) == 0) {
            size_t slot = FIELD_COUNT * PLANT_MAX_BANDS + i;
            if (fc->seen_line[slot]) {
                fail(fc, section, name, value, "given twice in this file (first at line %u)", fc->seen_line[slot]);
                return 0;
            }
            fc->seen_line[slot] = fc->guard.line;
            return special_readers[i](fc, section, name, value) != 0 ? !fc->ctx->failed : 0;
        }
    }
    return -1;
}

/* Does name = f's base + one of its unit suffixes? 1 (with *u, NULL for plain
 * numbers), 0 if not, -1 if the base matches but the suffix is not allowed. */
static int match_field(const field *f, const char *name, const unit **u)
{
    size_t bl = strlen(f->base);
    *u = NULL;
    if (strncmp(name, f->base, bl) != 0)
        return 0;
    if (f->k == K_NONE || f->k == K_INT)
        return name[bl] == 0;
    if (name[bl] != '_')
        return 0;
    for (size_t j = 0; j < sizeof units / sizeof units[0]; j++)
        if (units[j].k == f->k && strcmp(units[j].suffix, name + bl + 1) == 0)
            *u = &units[j];
    return *u ? 1 : -1;
}

/* Field i (of band, or -1) given as name = value in unit u: checked, converted, stored. */
static int store_field(file_ctx *fc, size_t i, int band, const unit *u, const char *section, const char *name,
                       const char *value)
{
    load_ctx *ctx = fc->ctx;
    const field *f = &fields[i];
    size_t slot = i * PLANT_MAX_BANDS + (size_t)(band >= 0 ? band : 0);
    if (fc->seen_line[slot]) {
        fail(fc, section, name, value, "%s given twice in this file (first at line %u, possibly under another unit)",
             f->base, fc->seen_line[slot]);
        return 0;
    }
    fc->seen_line[slot] = fc->guard.line;
    double v;
    if (parse_number(value, &v) != 0) {
        fail(fc, section, name, value, "not a number");
        return 0;
    }
    double factor = u ? u->factor : 1.0;
    int gauge = u ? u->gauge : 0;
    double off = gauge ? ctx->cfg->plant.ambient_pa : 0.0;
    double si = v * factor + off;
    if (si < f->min_si || si > f->max_si) {
        fail(fc, section, name, value, "out of range [%.6g, %.6g] %s", (f->min_si - off) / factor,
             (f->max_si - off) / factor, u ? u->suffix : "");
        return 0;
    }
    if ((f->t == T_INT || f->t == T_U32) && v != floor(v)) {
        fail(fc, section, name, value, "must be a whole number in [%.10g, %.10g]", f->min_si, f->max_si);
        return 0;
    }
    char *dst = (band >= 0 ? (char *)&ctx->cfg->plant.bands[band] : (char *)ctx->cfg) + f->offset;
    if (f->t == T_DOUBLE)
        *(double *)dst = v * factor; /* gauge: ambient added at the end (it may come later) */
    else if (f->t == T_INT)
        *(int *)dst = (int)v;
    else
        *(uint32_t *)dst = (uint32_t)v;
    ctx->gauge[slot] = gauge;
    if (band >= 0) {
        ctx->band_seen[band] = 1;
        ctx->band_keys[band] |= 1u << (i - first_band_field());
    }
    if (strcmp(section, "controller") == 0 && strncmp(name, "band_", 5) == 0)
        snprintf(ctx->edge_where, sizeof ctx->edge_where, "%s:%u", fc->path, fc->guard.line);
    return 1;
}

/* A key of an [effect.NAME] section (plant_config_effects.c): 1 done, 0 failed. */
static int read_effect(file_ctx *fc, const char *section, const char *name, const char *value)
{
    double v;
    char msg[600];
    if (parse_number(value, &v) != 0) {
        fail(fc, section, name, value, "not a number");
        return 0;
    }
    if (plant_config_effect_key(fc->ctx->cfg, section + 7, name, v, msg, sizeof msg) != 0) {
        fail(fc, section, name, value, "%s", msg);
        return 0;
    }
    return 1;
}

static int handler(void *user, const char *section, const char *name, const char *value)
{
    file_ctx *fc = user;
    if (fc->ctx->failed)
        return 0;
    if (ini_guard_key(&fc->guard, section, name, fc->ctx->err, fc->ctx->err_len) != 0) {
        fc->ctx->failed = 1;
        return 0;
    }
    fc->keys_seen++;
    if (strncmp(section, "effect.", 7) == 0)
        return read_effect(fc, section, name, value);
    if (!is_known_section(section)) {
        fail(fc, section, name, value, "unknown section [%s] (see docs/config-format.md)", section);
        return 0;
    }
    int special = read_special(fc, section, name, value);
    if (special >= 0)
        return special;
    int band = band_index(section);
    const char *fsection = band >= 0 ? "hysteresis" : section;
    int base_matched = -1;
    for (size_t i = 0; i < FIELD_COUNT; i++) {
        const unit *u;
        int m = strcmp(fields[i].section, fsection) == 0 ? match_field(&fields[i], name, &u) : 0;
        if (m > 0)
            return store_field(fc, i, band, u, section, name, value);
        if (m < 0)
            base_matched = (int)i;
    }
    if (base_matched >= 0) {
        char list[256];
        allowed_suffixes(fields[base_matched].k, list, sizeof list);
        fail(fc, section, name, value, "unit suffix not allowed for %s; use %s%s", fields[base_matched].base,
             fields[base_matched].base, list);
    } else {
        fail(fc, section, name, value, "unknown key (see docs/config-format.md)");
    }
    return 0;
}

static int load_file(load_ctx *ctx, const char *path)
{
    file_ctx *fc = calloc(1, sizeof *fc);
    if (!fc) {
        snprintf(ctx->err, ctx->err_len, "%s: out of memory", path);
        ctx->failed = 1;
        return -1;
    }
    fc->path = path;
    fc->ctx = ctx;
    char err[512];
    if (ini_guard_open(&fc->guard, path, err, sizeof err) != 0) {
        if (!ctx->failed)
            snprintf(ctx->err, ctx->err_len, "%s", err);
        ctx->failed = 1;
        free(fc);
        return -1;
    }
    int rc = ini_parse_stream(ini_guard_reader, &fc->guard, handler, fc);
    if (!ctx->failed && ini_guard_finish(&fc->guard, rc, ctx->err, ctx->err_len) != 0)
        ctx->failed = 1;
    ini_guard_close(&fc->guard);
    free(fc);
    return ctx->failed ? -1 : 0;
}

/* The parameter table: gas, motor, compressor, valves, accumulator, spring. */
static void defaults_gas_and_flow(plant_params *p)
{
    const double psi = PLANT_PA_PER_PSI;
    p->ambient_pa = 14.7 * psi;
    p->temperature_k = 535.0 * 5.0 / 9.0;
    p->gas_constant_j_per_kg_k = 640.08 * LBF_IN / (PLANT_KG_PER_LBM * 5.0 / 9.0);
    p->compressibility = 0.95;
    p->polytropic_n = 1.1;
    p->heat_ratio_k = 1.4;
    p->motor_torque_constant_nm_per_v = 0.926 * LBF_IN;
    p->motor_supply_v = 13.5;
    p->motor_inertia_kg_m2 = 0.25 * LBF_IN;
    p->motor_damping_nm_s = 0.1 * LBF_IN;
    p->motor_torque_coefficient = 2.0;
    p->compressor_capacity_m3_per_rad = 0.0161 * IN3;
    p->compressor_leakage_m3_per_pa_s = 0.0001 * IN3 / psi;
    p->pipe_volume_m3 = 12.5 * IN3;
    p->spring_valve_diameter_m = 2.0e-3;
    p->spring_valve_cd_in = 0.8;
    p->spring_valve_cd_out = 0.4;
    p->vent_valve_diameter_m = 2.2e-3;
    p->vent_valve_cd = 0.12;
    p->acc_type = PLANT_ACC_NONE;
    p->acc_volume_m3 = 50.0 * IN3;
    p->acc_charge_pa = 126.7 * psi;
    p->acc_valve_diameter_m = 2.2e-3;
    p->acc_valve_cd = 0.3;
    p->spring_volume0_m3 = 270.0 * IN3;
    static const double cc1[] = {-12.176065, 6.711826, -0.644472, 0.026514, -0.000393};
    static const double cc2[] = {0.1271, 0.0121};
    memcpy(p->area_cc1_in2, cc1, sizeof cc1);
    p->area_cc1_terms = 5;
    memcpy(p->area_cc2_in2_per_in, cc2, sizeof cc2);
    p->area_cc2_terms = 2;
}

/* Hysteresis lines (Appendix B, psig), platform and initial state. */
static void defaults_bands_and_platform(plant_params *p)
{
    const double psi = PLANT_PA_PER_PSI, in = PLANT_M_PER_IN, lbf = PLANT_N_PER_LBF;
    static const double band_tab[4][4] = {
        {950, -3.43, 130.0, 11.0}, {1050, -3.67, 139.33, 10.5}, {1150, -3.5, 141.5, 10.5}, {1250, -3.67, 149.33, 10.5}};
    for (int i = 0; i < 4; i++) {
        p->bands[i].load_below_n = band_tab[i][0] * lbf;
        p->bands[i].up_slope_pa_per_m = band_tab[i][1] * psi / in;
        p->bands[i].up_intercept_pag = band_tab[i][2] * psi;
        p->bands[i].down_offset_pa = band_tab[i][3] * psi;
    }
    p->band_count = 4;
    p->extra_mass_kg = 50.0 * PLANT_KG_PER_LBM;
    p->damping_up_n_s_per_m = 62.0 * lbf / in;
    p->damping_down_n_s_per_m = 10.0 * lbf / in;
    p->velocity_deadband_m_per_s = 0.0001 * in;
    p->height_min_m = 0.0;
    p->height_max_m = 1.0;
    p->init_height_m = 15.65 * in;
    p->init_velocity_m_per_s = 0.5067 * in;
    p->init_p_pipe_pa = 89.0 * psi;
    p->init_p_spring_pa = 89.0 * psi;
    p->init_motor_speed_rad_per_s = 83.2649;
}

/* The diaphragm accumulator of figure 22. */
static void defaults_diaphragm(plant_params *p)
{
    const double psi = PLANT_PA_PER_PSI, in = PLANT_M_PER_IN;
    /* diaphragm accumulator, figure 22 as Appendix B has it (psia -> in^3) */
    static const double breaks_psia[] = {40.0, 106.7, 112.7};
    static const double slopes[] = {0.0, 0.1546, 75.531097, 0.75};
    static const double intercepts[] = {20.0, 13.8176, -8028.85463, 398.975};
    p->diaphragm_segments = 4;
    p->diaphragm_slope_count = p->diaphragm_intercept_count = 4;
    for (int i = 0; i < 4; i++) {
        if (i < 3)
            p->diaphragm_break_pa[i] = breaks_psia[i] * psi;
        p->diaphragm_slope_m3_per_pa[i] = slopes[i] * in * in * in / psi;
        p->diaphragm_intercept_m3[i] = intercepts[i] * in * in * in;
    }
}

void plant_config_defaults(plant_config *c)
{
    memset(c, 0, sizeof *c);
    defaults_gas_and_flow(&c->plant);
    defaults_bands_and_platform(&c->plant);
    defaults_diaphragm(&c->plant);
    const double in = PLANT_M_PER_IN, lbf = PLANT_N_PER_LBF;
    c->init_compressor = 1; /* the program's motor := true; solenoid := true */
    c->init_spring_valve = 1;
    c->init_vent_valve = 0;
    c->init_acc_valve = 0;

    plant_sensor_params *s = &c->sensors;
    s->height_lo_counts = 410;
    s->height_hi_counts = 3686;
    s->height_lo_m = (15.6 - 1915.5 * 0.2 / 66.0) * in; /* band edges on code transitions (thesis-900lb.ini) */
    s->height_hi_m = (15.6 + 1360.5 * 0.2 / 66.0) * in;
    s->pressure_lo_counts = 410;
    s->pressure_hi_counts = 3686;
    s->pressure_lo_pa = 101325;
    s->pressure_hi_pa = 1480276;
    s->noise_counts = 0;
    s->noise_seed = 1;

    c->algorithm = 1;
    c->chatter_max_per_min = -1; /* not given: the firmware's own default stays */
    c->band_lower_m = 15.6 * in;
    c->band_upper_m = 15.8 * in;
    c->valid_load_min_n = 0.0; /* unchecked unless the config says */
    c->valid_load_max_n = 1e5;
    c->base_load_n = 900.0 * lbf;
    c->step_load_n = 200.0 * lbf;
    c->step_on_s = 5.0;
    c->step_off_s = 35.0;
    c->end_s = 55.0;
    c->substeps_per_tick = 2; /* convergence study: tests/sim/test_acceptance.py */
    snprintf(c->name, sizeof c->name, "thesis-900lb");
}

static int cfail(char *err, size_t len, const plant_config *c, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(err, len, "%s: %s", c->path[0] ? c->path : "(config)", msg);
    return -1;
}

int plant_config_check(const plant_config *c, char *err, size_t len)
{
    const plant_params *p = &c->plant;
    if (c->band_lower_m >= c->band_upper_m)
        return cfail(err, len, c, "[controller] band_lower must be below band_upper");
    if (p->height_min_m >= p->height_max_m)
        return cfail(err, len, c, "[platform] height_min must be below height_max");
    if (p->init_height_m < p->height_min_m || p->init_height_m > p->height_max_m)
        return cfail(err, len, c, "[initial] height outside [platform] height_min..height_max");
    if (p->band_count < 1)
        return cfail(err, len, c, "at least one [hysteresis.N] band is required");
    for (int i = 0; i < p->band_count; i++) {
        const plant_hysteresis_band *b = &p->bands[i];
        if (b->load_below_n <= 0)
            return cfail(err, len, c, "[hysteresis.%d] needs load_below, up_slope, up_intercept, down_offset", i + 1);
    }
    if (c->sensors.height_lo_counts == c->sensors.height_hi_counts || c->sensors.height_lo_m == c->sensors.height_hi_m)
        return cfail(err, len, c, "[sensors] height span is empty");
    if (c->sensors.pressure_lo_counts == c->sensors.pressure_hi_counts ||
        c->sensors.pressure_lo_pa == c->sensors.pressure_hi_pa)
        return cfail(err, len, c, "[sensors] pressure span is empty");
    if (p->diaphragm_slope_count != p->diaphragm_segments || p->diaphragm_intercept_count != p->diaphragm_segments)
        return cfail(err, len, c,
                     "[accumulator] diaphragm_breaks_psia gives %d segments, but diaphragm_slopes_in3_per_psi has %d "
                     "and diaphragm_intercepts_in3 %d values (one per segment)",
                     p->diaphragm_segments, p->diaphragm_slope_count, p->diaphragm_intercept_count);
    for (int i = 0; i < p->diaphragm_segments; i++) {
        /* V must stay positive over the segment and join its neighbour (air in the
         * accumulator is P3 V: a jump in V would create or destroy air) */
        double lo = i == 0 ? p->ambient_pa * 0.5 : p->diaphragm_break_pa[i - 1];
        double hi = i == p->diaphragm_segments - 1 ? 2e6 : p->diaphragm_break_pa[i];
        double v_lo = p->diaphragm_slope_m3_per_pa[i] * lo + p->diaphragm_intercept_m3[i];
        double v_hi = p->diaphragm_slope_m3_per_pa[i] * hi + p->diaphragm_intercept_m3[i];
        if (!(v_lo > 1e-7 && v_hi > 1e-7))
            return cfail(err, len, c, "[accumulator] diaphragm segment %d: volume %.4g in^3 at %.4g psia (must stay > 0)",
                         i + 1, fmin(v_lo, v_hi) / pow(PLANT_M_PER_IN, 3), (v_lo < v_hi ? lo : hi) / PLANT_PA_PER_PSI);
        if (i + 1 < p->diaphragm_segments) {
            double v_next = p->diaphragm_slope_m3_per_pa[i + 1] * hi + p->diaphragm_intercept_m3[i + 1];
            if (fabs(v_next - v_hi) > 1e-3 * fmax(v_hi, v_next))
                return cfail(err, len, c,
                             "[accumulator] diaphragm segments %d and %d meet at %.6g psia with %.6g and %.6g in^3 "
                             "(must join within 0.1 %%)",
                             i + 1, i + 2, hi / PLANT_PA_PER_PSI, v_hi / pow(PLANT_M_PER_IN, 3),
                             v_next / pow(PLANT_M_PER_IN, 3));
        }
    }
    if (c->step_on_s > c->step_off_s)
        return cfail(err, len, c, "[scenario] step_on must not be after step_off");
    if (c->valid_load_min_n >= c->valid_load_max_n)
        return cfail(err, len, c, "[spring] load_min must be below load_max");
    /* The effective area must stay physical over the range the fit was made for
     * (the thesis fit is negative at no load). */
    for (double load_lbf = 700.0; load_lbf <= 1500.0; load_lbf += 50.0)
        for (double y_in = 10.0; y_in <= 20.0; y_in += 1.0) {
            double a_in2 = plant_effective_area_m2(p, load_lbf * PLANT_N_PER_LBF, y_in * PLANT_M_PER_IN) /
                           (PLANT_M_PER_IN * PLANT_M_PER_IN);
            if (!(a_in2 >= 1.0 && a_in2 <= 1000.0))
                return cfail(err, len, c,
                             "[spring] area_cc1_poly_in2/area_cc2_poly_in2_per_in give %.4g in^2 at %g lbf, %g in "
                             "(allowed 1..1000 in^2 for 700..1500 lbf, 10..20 in)",
                             a_in2, load_lbf, y_in);
        }
    return 0;
}

int plant_config_load(const char *path, plant_config *out, char *err, size_t err_len)
{
    plant_config_defaults(out);
    out->plant.band_count = 4;
    load_ctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx) {
        snprintf(err, err_len, "%s: out of memory", path);
        return -1;
    }
    ctx->cfg = out;
    ctx->err = err;
    ctx->err_len = err_len;
    snprintf(out->path, sizeof out->path, "%s", path);
    /* default name: file name without .ini */
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    snprintf(out->name, sizeof out->name, "%s", base);
    char *dot = strrchr(out->name, '.');
    if (dot && strcmp(dot, ".ini") == 0)
        *dot = 0;
    int rc = load_file(ctx, path);
    if (rc == 0) {
        /* gauge values: ambient is known now */
        for (size_t i = 0; i < FIELD_COUNT; i++)
            for (int b = 0; b < PLANT_MAX_BANDS; b++)
                if (ctx->gauge[i * PLANT_MAX_BANDS + (size_t)b]) {
                    char *base_ptr = strcmp(fields[i].section, "hysteresis") == 0 ? (char *)&out->plant.bands[b]
                                                                                    : (char *)out;
                    *(double *)(base_ptr + fields[i].offset) += out->plant.ambient_pa;
                }
        /* bands: the defaults count 4; a file may add more */
        int count = 4;
        for (int b = 0; b < PLANT_MAX_BANDS; b++)
            if (ctx->band_seen[b] && b + 1 > count)
                count = b + 1;
        out->plant.band_count = count;
        rc = check_given(ctx, path);
        if (rc == 0)
            rc = plant_config_check(out, err, err_len);
        char msg[400];
        if (rc == 0 && plant_config_effects_check(out, msg, sizeof msg) != 0)
            rc = cfail(err, err_len, out, "%s", msg);
    }
    free(ctx);
    return rc;
}
