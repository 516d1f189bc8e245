/*
 * hal.h over the plant simulator, and the firmware as the stepper's commands
 * hook (simloop.h). The simulator owns time and the sensor counts; the
 * firmware's outputs are read back after each tick. The serial link is silent
 * (no supervisor attached in the simulator).
 */
#include "leveler/hal.h"
#include "simloop.h"

#include <string.h>

#include "commission.h"
#include "leveler/app.h"

static struct {
    uint16_t counts[HAL_ADC_COUNT];
    bool outputs[HAL_OUT_COUNT];
    uint32_t now_ms;
} hal_state;

int sim_firmware_start(const plant_config *cfg, int algorithm, char *err, size_t err_len)
{
    memset(&hal_state, 0, sizeof hal_state);
    leveler_app_init();
    return sim_commission(cfg, algorithm, err, err_len);
}

void sim_firmware_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT])
{
    (void)user;
    sim_stepper_counts(s, hal_state.counts);
    hal_state.now_ms = (uint32_t)(s->k * LEVELER_TICK_MS);
    leveler_app_tick();
    memcpy(out, hal_state.outputs, sizeof hal_state.outputs);
}

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    if ((unsigned)channel >= HAL_ADC_COUNT || !counts)
        return false;
    *counts = hal_state.counts[channel];
    return true;
}

void hal_output_set(hal_output output, bool on)
{
    if ((unsigned)output < HAL_OUT_COUNT)
        hal_state.outputs[output] = on;
}

uint32_t hal_now_ms(void)
{
    return hal_state.now_ms;
}

size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    (void)buf;
    (void)max_len;
    return 0;
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    (void)buf;
    return len;
}
