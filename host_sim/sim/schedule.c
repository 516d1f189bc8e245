/* Load schedules: the config's built-in scenario, or a CSV file t_s,load_n. */
#define _POSIX_C_SOURCE 200809L
#include "stepper.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

size_t sim_schedule_from_config(const plant_config *cfg, sim_load_step out[4], double *end_s)
{
    size_t n = 0;
    out[n++] = (sim_load_step){0.0, cfg->base_load_n};
    if (cfg->step_on_s < cfg->end_s)
        out[n++] = (sim_load_step){cfg->step_on_s, cfg->base_load_n + cfg->step_load_n};
    if (cfg->step_off_s < cfg->end_s)
        out[n++] = (sim_load_step){cfg->step_off_s, cfg->base_load_n};
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

/* One data line "t_s,load_n" after n rows (the last at prev_t): 0, or -1 with err. */
static int parse_row(char *p, const char *path, int lineno, size_t n, double prev_t, sim_load_step *row, char *err,
                     size_t err_len)
{
    char *comma = strchr(p, ',');
    double t, load;
    if (!comma || strchr(comma + 1, ',')) {
        snprintf(err, err_len, "%s:%d: expected two columns t_s,load_n", path, lineno);
        return -1;
    }
    if (parse_double(p, comma, &t) != 0 || parse_double(comma + 1, p + strlen(p), &load) != 0) {
        snprintf(err, err_len, "%s:%d: t_s and load_n must be numbers", path, lineno);
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
    *row = (sim_load_step){t, load};
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
    sim_load_step *v = malloc(cap * sizeof *v);
    char line[256];
    int lineno = 0, rc = 0;
    while (v && rc == 0 && fgets(line, sizeof line, f)) {
        lineno++;
        char *p = line;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p == '#' || *p == '\n' || *p == '\r' || *p == 0)
            continue;
        if (strncmp(p, "t_s,load_n", 10) == 0 && n == 0)
            continue;
        sim_load_step row;
        rc = parse_row(p, path, lineno, n, n ? v[n - 1].t_s : 0.0, &row, err, err_len);
        if (rc == 0 && n == cap) {
            cap *= 2;
            sim_load_step *nv = realloc(v, cap * sizeof *v);
            if (!nv)
                free(v);
            v = nv;
        }
        if (rc == 0 && v)
            v[n++] = row;
    }
    fclose(f);
    if (!v) {
        snprintf(err, err_len, "%s: out of memory", path);
        return -1;
    }
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
