/*
 * hal.h over the plant simulator. The simulator owns time and the sensor
 * counts; the firmware's outputs are read back after each tick. The serial
 * link is silent (no supervisor attached in the simulator).
 */
#include "leveler/hal.h"
#include "simloop.h"

#include <string.h>

static struct {
    uint16_t counts[HAL_ADC_COUNT];
    bool outputs[HAL_OUT_COUNT];
    uint32_t now_ms;
} hal_state;

void sim_hal_reset(void)
{
    memset(&hal_state, 0, sizeof hal_state);
}

void sim_hal_set_counts(const uint16_t counts[4])
{
    memcpy(hal_state.counts, counts, sizeof hal_state.counts);
}

void sim_hal_set_time_ms(uint32_t now_ms)
{
    hal_state.now_ms = now_ms;
}

void sim_hal_get_outputs(bool out[5])
{
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
