#include "leveler/settings.h"

#include <string.h>

#include "leveler/regmap.h"
#include "leveler/regmap_desc.h"
#include "internal.h"

/* Defaults come from registers.json (the generated descriptor table). */
static leveler_settings g_settings;
static bool g_settings_loaded;
static uint32_t g_generation;

void leveler_settings_defaults(leveler_settings *out)
{
    memset(out, 0, sizeof(*out));
    for (uint16_t i = 0; i < leveler_reg_table_count(); i++) {
        const leveler_reg_desc *d = &leveler_reg_table[i];
        if (d->region == LEVELER_REGION_SETTINGS && d->has_default) {
            leveler_reg_field_set(d, out, d->default_value);
        }
    }
}

static bool baud_listed(uint16_t baud_div100)
{
    static const uint16_t listed[] = {12u, 24u, 48u, 96u, 192u, 384u, 576u, 1152u};
    for (size_t i = 0; i < sizeof(listed) / sizeof(listed[0]); i++) {
        if (listed[i] == baud_div100) {
            return true;
        }
    }
    return false;
}

uint16_t leveler_settings_check(const leveler_settings *s)
{
    /* Each field against its registers.json range. */
    for (uint16_t i = 0; i < leveler_reg_table_count(); i++) {
        const leveler_reg_desc *d = &leveler_reg_table[i];
        if (d->region != LEVELER_REGION_SETTINGS) {
            continue;
        }
        int64_t v = leveler_reg_field_get(d, s);
        if (v < d->min || v > d->max) {
            return ((d->flags & LEVELER_REGFLAG_ENUM) != 0u) ? LEVELER_REASON_BAD_ENUM : LEVELER_REASON_OUT_OF_RANGE;
        }
    }
    if (!baud_listed(s->modbus_baud_div100)) {
        return LEVELER_REASON_BAD_ENUM;
    }
    /* Consistency. */
    if (s->band_lower_um >= s->band_upper_um) {
        return LEVELER_REASON_BAND_ORDER;
    }
    if (s->overpressure_vent_pa < s->overpressure_limit_pa) {
        return LEVELER_REASON_LIMIT_ORDER;
    }
    /* Charging the accumulator past the cut-off would only trip the supervisor. */
    if (s->acc_charge_max_pa > s->overpressure_limit_pa) {
        return LEVELER_REASON_LIMIT_ORDER;
    }
    /* Learnt hysteresis lines: the platform breaks away upwards above where it comes down. */
    if (s->alg3_up_pa != 0 && s->alg3_down_pa != 0 && s->alg3_down_pa >= s->alg3_up_pa) {
        return LEVELER_REASON_LIMIT_ORDER;
    }
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        const leveler_calibration *cal = &s->calibration[c];
        if (cal->raw_lo == cal->raw_hi || cal->eng_lo == cal->eng_hi) {
            return LEVELER_REASON_CALIBRATION;
        }
    }
    return LEVELER_REASON_NONE;
}

static void ensure_loaded(void)
{
    if (!g_settings_loaded) {
        leveler_settings_defaults(&g_settings);
        g_settings_loaded = true;
    }
}

const leveler_settings *leveler_settings_current(void)
{
    ensure_loaded();
    return &g_settings;
}

uint16_t leveler_settings_apply(const leveler_settings *s)
{
    uint16_t reason = leveler_settings_check(s);
    if (reason != LEVELER_REASON_NONE) {
        return reason;
    }
    ensure_loaded();
    bool changed = false;
    for (uint16_t i = 0; i < leveler_reg_table_count(); i++) { /* field by field: padding may differ */
        const leveler_reg_desc *d = &leveler_reg_table[i];
        if (d->region == LEVELER_REGION_SETTINGS &&
            leveler_reg_field_get(d, &g_settings) != leveler_reg_field_get(d, s)) {
            changed = true;
        }
    }
    if (changed) {
        g_settings = *s;
        g_generation++;
    }
    return LEVELER_REASON_NONE;
}

uint32_t leveler_settings_generation(void)
{
    return g_generation;
}

void leveler_settings_reset(void)
{
    leveler_settings_defaults(&g_settings);
    g_settings_loaded = true;
}
