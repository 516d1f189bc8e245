#define _POSIX_C_SOURCE 200809L
#include "sensor_module.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One register the scan needs. */
typedef struct {
    rig_module_table table;
    uint16_t address;
} wanted_reg;

struct rig_sensors {
    const rig_config *cfg;
    rig_link *link;
    bool valid[HAL_ADC_COUNT];
    uint16_t counts[HAL_ADC_COUNT];
    bool load_valid;
    double load_n;
    bool time_valid;
    uint32_t time_ms;
    uint32_t failed_scans;
};

double rig_channel_convert(const rig_channel *ch, uint16_t raw)
{
    double x = ch->is_signed ? (double)(int16_t)raw : (double)raw;
    return ch->out_lo + (x - ch->raw_lo) * (ch->out_hi - ch->out_lo) / (ch->raw_hi - ch->raw_lo);
}

uint16_t rig_channel_counts(const rig_channel *ch, uint16_t raw)
{
    double c = rint(rig_channel_convert(ch, raw));
    if (!(c > 0))
        return 0;
    if (c > HAL_ADC_MAX_COUNTS)
        return HAL_ADC_MAX_COUNTS;
    return (uint16_t)c;
}

rig_sensors *rig_sensors_open(const rig_config *cfg, rig_link *link, char *err, size_t err_len)
{
    rig_sensors *s = calloc(1, sizeof *s);
    if (s == NULL) {
        snprintf(err, err_len, "sensor module: out of memory");
        return NULL;
    }
    s->cfg = cfg;
    s->link = link;
    return s;
}

void rig_sensors_close(rig_sensors *s)
{
    free(s);
}

/* Read one table's span [lo, hi] into regs[lo..hi]; false on failure. */
static bool read_span(rig_sensors *s, rig_module_table table, uint16_t lo, uint16_t hi, uint16_t *regs)
{
    modbus_t *ctx = rig_link_begin(s->link);
    if (ctx == NULL)
        return false;
    int n = hi - lo + 1;
    int got = table == RIG_TABLE_INPUT ? modbus_read_input_registers(ctx, lo, n, regs + lo)
                                       : modbus_read_registers(ctx, lo, n, regs + lo);
    rig_link_end(s->link, got == n);
    return got == n;
}

void rig_sensors_scan(rig_sensors *s)
{
    const rig_config *cfg = s->cfg;
    memset(s->valid, 0, sizeof s->valid);
    s->load_valid = false;
    s->time_valid = false;
    /* Registers wanted, by table. */
    wanted_reg want[HAL_ADC_COUNT + 3];
    int n_want = 0;
    for (int c = 0; c < HAL_ADC_COUNT; c++)
        if (cfg->channel[c].enabled)
            want[n_want++] = (wanted_reg){cfg->channel[c].table, cfg->channel[c].address};
    if (cfg->load.enabled)
        want[n_want++] = (wanted_reg){cfg->load.table, cfg->load.address};
    if (cfg->clock == RIG_CLOCK_LOCKSTEP) {
        want[n_want++] = (wanted_reg){RIG_TABLE_INPUT, cfg->lockstep_time_register};
        want[n_want++] = (wanted_reg){RIG_TABLE_INPUT, (uint16_t)(cfg->lockstep_time_register + 1)};
    }

    static uint16_t regs[2][65536]; /* by table, indexed by address */
    bool ok[2] = {true, true};
    for (int t = 0; t < 2; t++) {
        int lo = 65536, hi = -1;
        for (int i = 0; i < n_want; i++) {
            if ((int)want[i].table != t)
                continue;
            lo = want[i].address < lo ? want[i].address : lo;
            hi = want[i].address > hi ? want[i].address : hi;
        }
        if (hi < 0)
            continue;
        if (hi - lo < MODBUS_MAX_READ_REGISTERS) {
            ok[t] = read_span(s, (rig_module_table)t, (uint16_t)lo, (uint16_t)hi, regs[t]);
        } else {
            for (int i = 0; i < n_want && ok[t]; i++)
                if ((int)want[i].table == t)
                    ok[t] = read_span(s, (rig_module_table)t, want[i].address, want[i].address, regs[t]);
        }
    }
    if (!ok[0] || !ok[1])
        s->failed_scans++;

    for (int c = 0; c < HAL_ADC_COUNT; c++) {
        const rig_channel *ch = &cfg->channel[c];
        if (ch->enabled && ok[ch->table]) {
            s->counts[c] = rig_channel_counts(ch, regs[ch->table][ch->address]);
            s->valid[c] = true;
        }
    }
    if (cfg->load.enabled && ok[cfg->load.table]) {
        s->load_n = rig_channel_convert(&cfg->load, regs[cfg->load.table][cfg->load.address]);
        s->load_valid = true;
    }
    if (cfg->clock == RIG_CLOCK_LOCKSTEP && ok[RIG_TABLE_INPUT]) {
        uint16_t r = cfg->lockstep_time_register;
        s->time_ms = ((uint32_t)regs[RIG_TABLE_INPUT][r] << 16) | regs[RIG_TABLE_INPUT][r + 1];
        s->time_valid = true;
    }
}

bool rig_sensors_counts(const rig_sensors *s, hal_adc_channel channel, uint16_t *counts)
{
    if (s == NULL || (unsigned)channel >= HAL_ADC_COUNT || !s->valid[channel])
        return false;
    *counts = s->counts[channel];
    return true;
}

bool rig_sensors_load_n(const rig_sensors *s, double *load_n)
{
    if (s == NULL || !s->load_valid)
        return false;
    *load_n = s->load_n;
    return true;
}

bool rig_sensors_module_time_ms(const rig_sensors *s, uint32_t *time_ms)
{
    if (s == NULL || !s->time_valid)
        return false;
    *time_ms = s->time_ms;
    return true;
}

int rig_sensors_step(rig_sensors *s, uint16_t step_ms)
{
    modbus_t *ctx = rig_link_begin(s->link);
    if (ctx == NULL)
        return -1;
    bool ok = modbus_write_register(ctx, s->cfg->lockstep_step_register, step_ms) == 1;
    rig_link_end(s->link, ok);
    return ok ? 0 : -1;
}

uint32_t rig_sensors_failed_scans(const rig_sensors *s)
{
    return s->failed_scans;
}
