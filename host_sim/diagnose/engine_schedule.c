/*
 * The simulator's schedule rules without a plant (engine.h): so the diagnosis
 * asks, and never re-implements, which load and which mode and manual
 * requests are in force when.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "engine.h"
#include "engine_writes.h"
#include "leveler/app.h"
#include "leveler/regmap.h"
#include "simloop.h"

const char *engine_schedule_column(int j)
{
    return j >= 0 && j < SIM_SCHEDULE_REG_COUNT ? sim_schedule_regs[j].name : NULL;
}

int engine_schedule_column_output(int j)
{
    return j >= 0 && j < SIM_SCHEDULE_REG_COUNT ? sim_schedule_regs[j].output : -1;
}

int engine_schedule_read(const char *path, int cap, double *t_s, double *load_n, int32_t *values, char *err,
                         int err_len)
{
    sim_load_step *v = NULL;
    size_t n = 0;
    if (sim_schedule_load(path, &v, &n, err, (size_t)err_len) != 0)
        return -1;
    if (n > (size_t)cap) {
        snprintf(err, (size_t)err_len, "%s: %zu rows (at most %d)", path, n, cap);
        free(v);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        t_s[i] = v[i].t_s;
        load_n[i] = v[i].load_n;
        for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++)
            values[i * SIM_SCHEDULE_REG_COUNT + j] = (v[i].writes & (1u << j)) ? v[i].value[j] : -1;
    }
    free(v);
    return (int)n;
}

/* What each schedule register holds now, read back from the firmware's register map. */
static int read_regs(int32_t *regs, char *err, int err_len)
{
    for (int j = 0; j < SIM_SCHEDULE_REG_COUNT; j++) {
        const sim_schedule_reg *r = &sim_schedule_regs[j];
        uint16_t v = 0;
        if (leveler_regs_read((leveler_table)r->table, r->address, 1, &v) != LEVELER_REG_OK) {
            snprintf(err, (size_t)err_len, "register %s: not readable", r->name);
            return -1;
        }
        regs[j] = v;
    }
    return 0;
}

int engine_schedule_apply(int rows, const double *row_t_s, const double *row_load_n, const int32_t *values, int n,
                          const double *t_s, double *load_out, int32_t *regs_out, char *err, int err_len)
{
    if (rows < 1) {
        snprintf(err, (size_t)err_len, "schedule: no rows");
        return -1;
    }
    sim_load_step *v = NULL;
    if (engine_writes_take(rows, row_t_s, row_load_n, values, &v, err, err_len) != 0)
        return -1;
    sim_schedule_cursor cursor = {v, (size_t)rows, 0};
    sim_schedule_writer writer = {.steps = v, .count = (size_t)rows};
    leveler_app_init();
    int rc = 0;
    for (int i = 0; i < n && rc == 0; i++) {
        load_out[i] = sim_schedule_load_at(&cursor, t_s[i]);
        sim_schedule_write_due(&writer, t_s[i]);
        if (writer.failed) {
            snprintf(err, (size_t)err_len, "%s", writer.err);
            rc = -1;
        } else {
            rc = read_regs(regs_out + (size_t)i * SIM_SCHEDULE_REG_COUNT, err, err_len);
        }
    }
    free(v);
    return rc;
}

void engine_scenario_loads(double base_load_n, double step_load_n, double step_on_s, double step_off_s,
                           double end_s, int n, const double *t_s, double *load_n)
{
    plant_config cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.base_load_n = base_load_n;
    cfg.step_load_n = step_load_n;
    cfg.step_on_s = step_on_s;
    cfg.step_off_s = step_off_s;
    cfg.end_s = end_s;
    sim_load_step steps[4];
    double end;
    sim_schedule_cursor c = {steps, sim_schedule_from_config(&cfg, steps, &end), 0};
    for (int i = 0; i < n; i++)
        load_n[i] = sim_schedule_load_at(&c, t_s[i]);
}
