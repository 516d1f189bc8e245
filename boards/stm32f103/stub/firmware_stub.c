/*
 * Private stand-in for firmware/ (leveler_firmware), used only when that
 * target does not exist yet, so the board image can be built and sized.
 * Behaves like a controller that never switches anything on.
 */
#include <string.h>

#include "leveler/app.h"
#include "leveler/hal.h"
#include "leveler/regmap.h"
#include "leveler/settings.h"

static leveler_settings s_settings;
static uint32_t s_generation;
static uint32_t s_tick_cycles_worst;
static bool s_clock_fault;

void leveler_settings_defaults(leveler_settings *out)
{
    memset(out, 0, sizeof *out);
    out->mode = LEVELER_MODE_AUTO;
    out->algorithm = LEVELER_ALGO_NO_ACCUMULATOR;
    out->modbus_address = 1;
    out->modbus_baud_div100 = 192;
}
const leveler_settings *leveler_settings_current(void) { return &s_settings; }
uint16_t leveler_settings_check(const leveler_settings *s) { return s->modbus_address == 0u ? 2u : 0u; }
uint16_t leveler_settings_apply(const leveler_settings *s)
{
    uint16_t reason = leveler_settings_check(s);
    if (reason == 0u) {
        s_settings = *s;
        s_generation++;
    }
    return reason;
}
uint32_t leveler_settings_generation(void) { return s_generation; }

void leveler_app_init(void)
{
    for (int out = 0; out < (int)HAL_OUT_COUNT; out++) {
        hal_output_set((hal_output)out, false);
    }
    leveler_settings_defaults(&s_settings);
}
void leveler_app_tick(void)
{
    uint16_t counts;
    for (int ch = 0; ch < (int)HAL_ADC_COUNT; ch++) {
        (void)hal_adc_read((hal_adc_channel)ch, &counts);
    }
}
void leveler_app_report_tick_overrun(void) {}
void leveler_app_report_tick_cycles(uint32_t cycles)
{
    if (cycles > s_tick_cycles_worst) {
        s_tick_cycles_worst = cycles;
    }
}
void leveler_app_report_clock_fault(bool hse_failed) { s_clock_fault = hse_failed; }

leveler_reg_status leveler_regs_read(leveler_table table, uint16_t addr, uint16_t count, uint16_t *out)
{
    (void)table;
    (void)addr;
    for (uint16_t i = 0; i < count; i++) {
        out[i] = 0;
    }
    return LEVELER_REG_OK;
}
