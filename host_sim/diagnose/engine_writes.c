/* engine_writes.h: a request's schedule rows checked and taken. */
#include <stdio.h>
#include <stdlib.h>

#include "engine_writes.h"

/* Row i's cells into row; -1 with err for a value out of range or a time not increasing. */
static int take_row(int i, const double *t_s, const int32_t *values, sim_load_step *row, char *err, int err_len)
{
    for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++) {
        int32_t v = values[i * SIM_SCHEDULE_REG_COUNT + j];
        if (v < -1 || v > sim_schedule_regs[j].max || (i > 0 && !(t_s[i] > t_s[i - 1]))) {
            snprintf(err, (size_t)err_len, "schedule writes row %d: %s = %d at %g s", i, sim_schedule_regs[j].name,
                     (int)v, t_s[i]);
            return -1;
        }
        if (v >= 0) {
            row->writes |= (uint8_t)(1u << j);
            row->value[j] = (uint16_t)v;
        }
    }
    return 0;
}

int engine_writes_take(int n, const double *t_s, const double *load_n, const int32_t *values, sim_load_step **rows,
                       char *err, int err_len)
{
    *rows = NULL;
    if (n < 0 || n > ENGINE_MAX_WRITE_ROWS) {
        snprintf(err, (size_t)err_len, "schedule writes: %d rows (at most %d)", n, ENGINE_MAX_WRITE_ROWS);
        return -1;
    }
    if (n == 0)
        return 0;
    sim_load_step *v = calloc((size_t)n, sizeof *v);
    if (!v) {
        snprintf(err, (size_t)err_len, "schedule writes: out of memory");
        return -1;
    }
    for (int i = 0; i < n; i++) {
        v[i] = (sim_load_step){.t_s = t_s[i], .load_n = load_n ? load_n[i] : 0.0};
        if (take_row(i, t_s, values, &v[i], err, err_len) != 0) {
            free(v);
            return -1;
        }
    }
    *rows = v;
    return 0;
}
