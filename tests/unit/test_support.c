#include "test_support.h"

#include <math.h>

#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

uint16_t counts_for(hal_adc_channel channel, double value)
{
    leveler_settings d;
    leveler_settings_defaults(&d);
    const leveler_calibration *c = &d.calibration[channel];
    double counts = c->raw_lo + (value - c->eng_lo) * (c->raw_hi - c->raw_lo) / (double)(c->eng_hi - c->eng_lo);
    long r = lround(counts);
    if (r < 0) {
        r = 0;
    }
    if (r > 4095) {
        r = 4095;
    }
    return (uint16_t)r;
}

void set_sensors(double height_um, double p_spring_pa, double p_pipe_pa, double p_acc_pa)
{
    fake_hal_set_adc(HAL_ADC_HEIGHT, counts_for(HAL_ADC_HEIGHT, height_um));
    fake_hal_set_adc(HAL_ADC_P_SPRING, counts_for(HAL_ADC_P_SPRING, p_spring_pa));
    fake_hal_set_adc(HAL_ADC_P_PIPE, counts_for(HAL_ADC_P_PIPE, p_pipe_pa));
    fake_hal_set_adc(HAL_ADC_P_ACC, counts_for(HAL_ADC_P_ACC, p_acc_pa));
}

void run_ticks(unsigned n)
{
    for (unsigned i = 0; i < n; i++) {
        fake_hal_advance_ms(LEVELER_TICK_MS);
        leveler_app_tick();
    }
}

void boot_valid(void)
{
    fake_hal_reset();
    fake_hal_set_time_ms(1000);
    leveler_app_init();
    set_sensors(MID_BAND_UM, P_NOMINAL_PA, P_NOMINAL_PA, P_NOMINAL_PA);
    run_ticks(leveler_settings_current()->sensor_good_samples);
}

int write_hr_u16(uint16_t addr, uint16_t value, uint16_t *reason)
{
    return (int)leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, addr, 1, &value, reason);
}

int write_hr_i32(uint16_t addr, int32_t value, uint16_t *reason)
{
    uint32_t u = (uint32_t)value;
    uint16_t w[2] = {(uint16_t)(u >> 16), (uint16_t)(u & 0xFFFFu)};
    return (int)leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, addr, 2, w, reason);
}

int32_t read_hr_i32(uint16_t addr)
{
    uint16_t w[2] = {0, 0};
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, addr, 2, w), LEVELER_REG_OK);
    return (int32_t)(((uint32_t)w[0] << 16) | w[1]);
}

uint16_t read_ir_u16(uint16_t addr)
{
    uint16_t w = 0xFFFFu;
    assert_int_equal(leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, addr, 1, &w), LEVELER_REG_OK);
    return w;
}

int write_coil(uint16_t addr, uint16_t value)
{
    return (int)leveler_regs_write(LEVELER_TABLE_COIL, addr, 1, &value, NULL);
}
