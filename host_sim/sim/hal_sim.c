/*
 * hal.h over the plant simulator, and the firmware as the stepper's commands
 * hook (simloop.h). The simulator owns time and the sensor counts; the
 * firmware's outputs are read back after each tick. The serial link is silent
 * (no supervisor attached in the simulator).
 */
#include "leveler/hal.h"
#include "simloop.h"

#include <stdio.h>
#include <string.h>

#include "commission.h"
#include "leveler/app.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

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

int sim_firmware_commission(char *err, size_t err_len)
{
    uint16_t one = 1, reason = 0;
    if (leveler_regs_write(LEVELER_TABLE_COIL, LEVELER_COIL_COMMISSION, 1, &one, &reason) == LEVELER_REG_OK)
        return 0;
    snprintf(err, err_len, "firmware refused commission = 1 (reason %u)", reason);
    return -1;
}

/* One register write of a schedule row; 0 or -1 with the refusal in w->err. */
static int write_reg(sim_schedule_writer *w, const sim_load_step *row, int j)
{
    const sim_schedule_reg *r = &sim_schedule_regs[j];
    uint16_t v = row->value[j], reason = 0;
    if (leveler_regs_write((leveler_table)r->table, r->address, 1, &v, &reason) == LEVELER_REG_OK)
        return 0;
    snprintf(w->err, sizeof w->err, "schedule row at %g s: firmware refused %s = %u (reason %u)", row->t_s,
             r->name, v, reason);
    w->failed = 1;
    return -1;
}

void sim_schedule_write_due(sim_schedule_writer *w, double t_s)
{
    while (!w->failed && w->next < w->count && sim_schedule_due(w->steps[w->next].t_s, t_s)) {
        const sim_load_step *row = &w->steps[w->next++];
        for (int k = 0; k < SIM_SCHEDULE_REG_COUNT && !w->failed; k++) {
            int j = sim_schedule_write_order[k];
            if (row->writes & (1u << j))
                (void)write_reg(w, row, j);
        }
    }
}

void sim_firmware_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT])
{
    if (user)
        sim_schedule_write_due(user, s->t_s_now);
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
