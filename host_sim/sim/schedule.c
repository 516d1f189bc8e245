/* Load schedules: the config's built-in scenario, or a CSV file t_s,load_n with
 * optional register-map columns (mode, manual requests) written at each row. */
#define _POSIX_C_SOURCE 200809L
#include "stepper.h"

#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const sim_schedule_reg sim_schedule_regs[SIM_SCHEDULE_REG_COUNT] = {
    {"mode", LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_MODE, LEVELER_HR_MODE_MANUAL, -1},
    {"manual_compressor", LEVELER_TABLE_COIL, LEVELER_COIL_MANUAL_COMPRESSOR, 1, HAL_OUT_COMPRESSOR},
    {"manual_spring_valve", LEVELER_TABLE_COIL, LEVELER_COIL_MANUAL_SPRING_VALVE, 1, HAL_OUT_SPRING_VALVE},
    {"manual_vent_valve", LEVELER_TABLE_COIL, LEVELER_COIL_MANUAL_VENT_VALVE, 1, HAL_OUT_VENT_VALVE},
    {"manual_acc_valve", LEVELER_TABLE_COIL, LEVELER_COIL_MANUAL_ACC_VALVE, 1, HAL_OUT_ACC_VALVE},
};

const uint8_t sim_schedule_write_order[SIM_SCHEDULE_REG_COUNT] = {1, 2, 3, 4, 0};

size_t sim_schedule_from_config(const plant_config *cfg, sim_load_step out[4], double *end_s)
{
    size_t n = 0;
    out[n++] = (sim_load_step){.t_s = 0.0, .load_n = cfg->base_load_n};
    if (cfg->step_on_s < cfg->end_s)
        out[n++] = (sim_load_step){.t_s = cfg->step_on_s, .load_n = cfg->base_load_n + cfg->step_load_n};
    if (cfg->step_off_s < cfg->end_s)
        out[n++] = (sim_load_step){.t_s = cfg->step_off_s, .load_n = cfg->base_load_n};
    *end_s = cfg->end_s;
    return n;
}

static int parse_double(const char *s, const char *e, double *out)
{
    char buf[64];
    while (s < e && (*s == ' ' || *s == '\t'))
        s++;
    while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r' || e[-1] == '\n'))
        e--;
    size_t n = (size_t)(e - s);
    if (n == 0 || n >= sizeof buf)
        return -1;
    memcpy(buf, s, n);
    buf[n] = 0;
    char *end;
    errno = 0;
    double v = strtod(buf, &end);
    if (*end || errno == ERANGE || !isfinite(v))
        return -1;
    *out = v;
    return 0;
}

#define MAX_COLS (2 + SIM_SCHEDULE_REG_COUNT)

/* The file's columns: t_s, load_n, then the register each further column writes. */
typedef struct {
    int n;
    int reg[MAX_COLS]; /* index into sim_schedule_regs for columns 2.. */
} columns;

/* Splits a line at its commas into at most max fields (trimmed); the count, or max + 1 if more. */
static int split(char *p, char *field[], int max)
{
    int n = 0;
    for (;;) {
        char *comma = strchr(p, ',');
        if (comma)
            *comma = 0;
        char *e = p + strlen(p);
        while (*p == ' ' || *p == '\t')
            p++;
        while (e > p && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r' || e[-1] == '\n'))
            *--e = 0;
        if (n == max)
            return max + 1;
        field[n++] = p;
        if (!comma)
            return n;
        p = comma + 1;
    }
}

/* The header "t_s,load_n[,register...]": 0, or -1 with err. */
static int parse_header(char *p, const char *path, int lineno, columns *c, char *err, size_t err_len)
{
    char *f[MAX_COLS];
    int n = split(p, f, MAX_COLS);
    if (n > MAX_COLS || n < 2 || strcmp(f[0], "t_s") != 0 || strcmp(f[1], "load_n") != 0) {
        snprintf(err, err_len, "%s:%d: header: expected t_s,load_n then any of mode, manual_compressor, "
                 "manual_spring_valve, manual_vent_valve, manual_acc_valve", path, lineno);
        return -1;
    }
    c->n = n;
    for (int i = 2; i < n; i++) {
        c->reg[i] = -1;
        for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++)
            if (strcmp(f[i], sim_schedule_regs[j].name) == 0)
                c->reg[i] = j;
        for (int k = 2; k < i && c->reg[i] >= 0; k++)
            if (c->reg[k] == c->reg[i]) {
                snprintf(err, err_len, "%s:%d: %s: column given twice", path, lineno, f[i]);
                return -1;
            }
        if (c->reg[i] < 0) {
            snprintf(err, err_len, "%s:%d: %.40s: not a schedule column (mode, manual_compressor, "
                     "manual_spring_valve, manual_vent_valve, manual_acc_valve)", path, lineno, f[i]);
            return -1;
        }
    }
    return 0;
}

/* A register cell: empty = no write; else an integer 0..max. */
static int parse_reg(const char *s, int j, sim_load_step *row)
{
    if (!*s)
        return 0;
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (*end || errno || v < 0 || v > sim_schedule_regs[j].max)
        return -1;
    row->writes |= (uint8_t)(1u << j);
    row->value[j] = (uint16_t)v;
    return 0;
}

/* One data line after n rows (the last at prev_t): 0, or -1 with err. */
static int parse_row(char *p, const char *path, int lineno, const columns *c, size_t n, double prev_t,
                     sim_load_step *row, char *err, size_t err_len)
{
    char *f[MAX_COLS];
    int got = split(p, f, MAX_COLS);
    double t, load;
    if (got != c->n) {
        snprintf(err, err_len, "%s:%d: expected %d columns as the header says (got %s%d)", path, lineno, c->n,
                 got > MAX_COLS ? "more than " : "", got > MAX_COLS ? MAX_COLS : got);
        if (c->n == 2)
            snprintf(err, err_len, "%s:%d: expected two columns t_s,load_n (a header names further ones)", path,
                     lineno);
        return -1;
    }
    for (int i = 0; i < 2; i++)
        if (parse_double(f[i], f[i] + strlen(f[i]), i ? &load : &t) != 0) {
            snprintf(err, err_len, "%s:%d: %s: expected a number (got '%.20s')", path, lineno, i ? "load_n" : "t_s",
                     f[i]);
            return -1;
        }
    if (n == 0 && t != 0.0) {
        snprintf(err, err_len, "%s:%d: t_s: the first step must be at 0 s (got %g)", path, lineno, t);
        return -1;
    }
    if (n > 0 && !(t > prev_t)) {
        snprintf(err, err_len, "%s:%d: t_s: times must increase (%g after %g)", path, lineno, t, prev_t);
        return -1;
    }
    if (t > 1e7) {
        snprintf(err, err_len, "%s:%d: t_s: out of range [0, 1e7] s", path, lineno);
        return -1;
    }
    if (load < 0.0 || load > 1e5) {
        snprintf(err, err_len, "%s:%d: load_n: out of range [0, 100000] N", path, lineno);
        return -1;
    }
    *row = (sim_load_step){.t_s = t, .load_n = load, .line = lineno};
    for (int i = 2; i < c->n; i++) {
        const sim_schedule_reg *r = &sim_schedule_regs[c->reg[i]];
        if (parse_reg(f[i], c->reg[i], row) != 0) {
            snprintf(err, err_len, "%s:%d: %s: expected an integer 0..%u or empty (got '%.20s')", path, lineno,
                     r->name, r->max, f[i]);
            return -1;
        }
    }
    return 0;
}

/* Reads the rows of an open file into *v (n of them, room for *cap): 0, or -1 with err. */
static int read_rows(FILE *f, const char *path, sim_load_step **v, size_t *cap, size_t *n, int *lineno, char *err,
                     size_t err_len)
{
    columns c = {.n = 2};
    char line[512];
    while (fgets(line, sizeof line, f)) {
        ++*lineno;
        if (!strchr(line, '\n') && !feof(f)) {
            snprintf(err, err_len, "%s:%d: line longer than %zu characters", path, *lineno, sizeof line - 2);
            return -1;
        }
        char *p = line;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p == '#' || *p == '\n' || *p == '\r' || *p == 0)
            continue;
        if (*n == 0 && c.n == 2 && isalpha((unsigned char)*p)) { /* a header (only before the rows) */
            if (parse_header(p, path, *lineno, &c, err, err_len) != 0)
                return -1;
            continue;
        }
        sim_load_step row;
        if (parse_row(p, path, *lineno, &c, *n, *n ? (*v)[*n - 1].t_s : 0.0, &row, err, err_len) != 0)
            return -1;
        if (*n == *cap) {
            sim_load_step *nv = realloc(*v, 2 * *cap * sizeof **v);
            if (!nv) {
                snprintf(err, err_len, "%s: out of memory", path);
                return -1;
            }
            *v = nv;
            *cap *= 2;
        }
        (*v)[(*n)++] = row;
    }
    return 0;
}

int sim_schedule_load(const char *path, sim_load_step **steps, size_t *count, char *err, size_t err_len)
{
    *steps = NULL;
    *count = 0;
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, err_len, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    size_t cap = 64, n = 0;
    int lineno = 0;
    sim_load_step *v = malloc(cap * sizeof *v);
    int rc = v ? read_rows(f, path, &v, &cap, &n, &lineno, err, err_len) : -1;
    fclose(f);
    if (!v)
        snprintf(err, err_len, "%s: out of memory", path);
    if (rc == 0 && n < 2) {
        snprintf(err, err_len, "%s:%d: need at least two rows (start at 0 s and the end time)", path, lineno);
        rc = -1;
    }
    if (rc != 0) {
        free(v);
        return -1;
    }
    *steps = v;
    *count = n;
    return 0;
}

int sim_schedule_check_loads(const plant_config *cfg, const char *path, const sim_load_step *steps, size_t count,
                             char *err, size_t err_len)
{
    const double lo = cfg->valid_load_min_n, hi = cfg->valid_load_max_n;
    bool all_lbf = count > 0; /* every load a plausible weight in lbf: typed without converting */
    for (size_t i = 0; i < count; i++)
        all_lbf = all_lbf && steps[i].load_n >= lo / PLANT_N_PER_LBF && steps[i].load_n <= hi / PLANT_N_PER_LBF;
    for (size_t i = 0; i < count; i++) {
        double f = steps[i].load_n;
        if (f >= lo && f <= hi)
            continue;
        snprintf(err, err_len,
                 "%s:%d: load_n: %g N is outside the loads the model was fitted for, %.0f..%.0f N "
                 "(%.0f..%.0f lbf, [spring] load_min/load_max of %s)%s",
                 path, steps[i].line, f, lo, hi, lo / PLANT_N_PER_LBF, hi / PLANT_N_PER_LBF, cfg->path,
                 all_lbf ? "; these loads look like lbf: load_n is in newtons (1 lbf = 4.448 N)" : "");
        return -1;
    }
    return 0;
}
