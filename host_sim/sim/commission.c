/* Commissioning the firmware for a simulated run (commission.h). */
#include "commission.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

static int write_u16(uint16_t addr, uint16_t v, const char *what, char *err, size_t len)
{
    uint16_t reason = 0;
    if (leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, addr, 1, &v, &reason) != LEVELER_REG_OK) {
        snprintf(err, len, "firmware refused %s = %u (holding %u, reason %u)", what, v, addr, reason);
        return -1;
    }
    return 0;
}

static int32_t round_i32(double v)
{
    if (v > 2147483647.0)
        return 2147483647;
    if (v < -2147483648.0)
        return (-2147483647 - 1);
    return (int32_t)lround(v);
}

static void put_i32(uint16_t *w, int32_t v)
{
    uint32_t u = (uint32_t)v;
    w[0] = (uint16_t)(u >> 16); /* high word first */
    w[1] = (uint16_t)(u & 0xFFFFu);
}

static int write_block(uint16_t addr, const uint16_t *w, uint16_t n, const char *what, char *err, size_t len)
{
    uint16_t reason = 0;
    if (leveler_regs_write(LEVELER_TABLE_HOLDING_REGISTER, addr, n, w, &reason) != LEVELER_REG_OK) {
        snprintf(err, len, "firmware refused %s (holding %u..%u, reason %u)", what, addr, addr + n - 1u, reason);
        return -1;
    }
    return 0;
}

/* What a commissioning engineer writes: calibration, band, algorithm (and for algorithm 3 whether an
 * accumulator is fitted), the chatter limit when the config gives one, accumulator charge. */
int sim_commission(const plant_config *cfg, int algorithm, char *err, size_t len)
{
    const plant_sensor_params *s = &cfg->sensors;
    static const uint16_t cal_addr[4] = {LEVELER_HR_CAL_HEIGHT_RAW_LO, LEVELER_HR_CAL_P_SPRING_RAW_LO,
                                         LEVELER_HR_CAL_P_PIPE_RAW_LO, LEVELER_HR_CAL_P_ACC_RAW_LO};
    for (int ch = 0; ch < 4; ch++) {
        uint16_t w[6];
        double raw_lo = ch == 0 ? s->height_lo_counts : s->pressure_lo_counts;
        double raw_hi = ch == 0 ? s->height_hi_counts : s->pressure_hi_counts;
        double eng_lo = ch == 0 ? s->height_lo_m * 1e6 : s->pressure_lo_pa;
        double eng_hi = ch == 0 ? s->height_hi_m * 1e6 : s->pressure_hi_pa;
        w[0] = (uint16_t)lround(raw_lo);
        w[1] = (uint16_t)lround(raw_hi);
        put_i32(&w[2], round_i32(eng_lo));
        put_i32(&w[4], round_i32(eng_hi));
        if (write_block(cal_addr[ch], w, 6, "calibration", err, len) != 0)
            return -1;
    }
    uint16_t band[4];
    put_i32(&band[0], round_i32(cfg->band_lower_m * 1e6));
    put_i32(&band[2], round_i32(cfg->band_upper_m * 1e6));
    if (write_block(LEVELER_HR_BAND_LOWER_UM, band, 4, "band", err, len) != 0)
        return -1;
    if (write_u16(LEVELER_HR_ALGORITHM, (uint16_t)algorithm, "algorithm", err, len) != 0)
        return -1;
    /* Algorithm 3 is told whether the rig has an accumulator (the others know by their number). */
    if (write_u16(LEVELER_HR_ALG3_ACCUMULATOR, cfg->plant.acc_type != PLANT_ACC_NONE, "alg3_accumulator", err, len) != 0)
        return -1;
    if (cfg->chatter_max_per_min >= 0 &&
        write_u16(LEVELER_HR_CHATTER_MAX_PER_MIN, (uint16_t)cfg->chatter_max_per_min, "chatter_max_per_min", err,
                  len) != 0)
        return -1;
    uint16_t charge[2];
    put_i32(charge, round_i32(cfg->plant.acc_charge_pa));
    return write_block(LEVELER_HR_ACC_CHARGE_MAX_PA, charge, 2, "accumulator charge", err, len);
}
