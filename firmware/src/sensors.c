#include "leveler/sensors.h"

#include <string.h>

#include "leveler/fixed_point.h"

void leveler_sensors_init(leveler_sensors *s, uint32_t now_ms)
{
    memset(s, 0, sizeof(*s));
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        s->ch[c].last_fresh_ms = now_ms;
        s->ch[c].stuck_since_ms = now_ms;
    }
}

/* Sum of this tick's conversions, rescaled to LEVELER_OVERSAMPLE readings.
 * Max 4 * 4095 * 4 < 2^17: no overflow. Returns false when no read succeeded. */
static bool read_channel(hal_adc_channel channel, uint32_t *sum_out)
{
    uint32_t sum = 0;
    uint32_t got = 0;
    for (unsigned i = 0; i < LEVELER_OVERSAMPLE; i++) {
        uint16_t counts = 0;
        if (hal_adc_read(channel, &counts)) {
            sum += (counts > HAL_ADC_MAX_COUNTS) ? HAL_ADC_MAX_COUNTS : counts;
            got++;
        }
    }
    if (got == 0u) {
        return false;
    }
    *sum_out = (sum * LEVELER_OVERSAMPLE + got / 2u) / got;
    return true;
}

static uint32_t abs_diff_u32(uint32_t a, uint32_t b)
{
    return (a > b) ? a - b : b - a;
}

static void debounce(leveler_sensor_channel *ch, const leveler_settings *set, bool bad, bool stale)
{
    if (bad) {
        ch->good_run = 0;
        ch->bad_run = leveler_sat_inc_u16(ch->bad_run);
        if (stale || ch->bad_run >= set->sensor_bad_samples) {
            ch->faulty = true;
            ch->valid = false;
        }
    } else {
        ch->bad_run = 0;
        ch->good_run = leveler_sat_inc_u16(ch->good_run);
        if (ch->good_run >= set->sensor_good_samples) {
            ch->faulty = false;
            ch->valid = true;
        }
    }
}

static void sample_channel(leveler_sensor_channel *ch, hal_adc_channel channel, const leveler_settings *set,
                           uint32_t now_ms)
{
    uint32_t sum = 0;
    uint8_t bad = 0;
    bool fresh = read_channel(channel, &sum);

    if (fresh) {
        ch->last_fresh_ms = now_ms;
        ch->raw_counts = (uint16_t)((sum + LEVELER_OVERSAMPLE / 2u) / LEVELER_OVERSAMPLE);
        if (!ch->have_fresh || sum != ch->last_sum) {
            ch->stuck_since_ms = now_ms;
        }
        ch->last_sum = sum;
        ch->have_fresh = true;
        if (sum < LEVELER_ADC_OPEN_BELOW_COUNTS * LEVELER_OVERSAMPLE ||
            sum > LEVELER_ADC_SHORT_ABOVE_COUNTS * LEVELER_OVERSAMPLE) {
            bad |= LEVELER_SENSOR_BAD_RANGE;
        }
        if (set->sensor_stuck_s != 0u &&
            now_ms - ch->stuck_since_ms >= (uint32_t)set->sensor_stuck_s * 1000u) {
            bad |= LEVELER_SENSOR_BAD_STUCK;
        }
    } else {
        bad |= LEVELER_SENSOR_BAD_NO_READING;
        if (now_ms - ch->last_fresh_ms >= set->sensor_stale_ms) {
            bad |= LEVELER_SENSOR_BAD_STALE;
        }
    }
    ch->bad_reasons = bad;

    if (bad == 0u) {
        bool jump = ch->have_accepted &&
                    abs_diff_u32(sum, ch->accepted_sum) > LEVELER_SPIKE_LIMIT_COUNTS * LEVELER_OVERSAMPLE;
        if (jump && !ch->spike_held) {
            ch->spike_held = true; /* hold once: a lone spike never reaches the controller */
        } else {
            ch->spike_held = false;
            ch->accepted_sum = sum;
            ch->have_accepted = true;
            ch->value = leveler_cal_convert(&set->calibration[channel], sum, LEVELER_OVERSAMPLE);
        }
    }
    debounce(ch, set, bad != 0u, (bad & LEVELER_SENSOR_BAD_STALE) != 0u);
}

void leveler_sensors_sample(leveler_sensors *s, const leveler_settings *set, uint32_t now_ms)
{
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        sample_channel(&s->ch[c], (hal_adc_channel)c, set, now_ms);
    }
}

bool leveler_sensors_valid(const leveler_sensors *s, uint16_t channel_mask)
{
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        if ((channel_mask & (1u << c)) != 0u && !s->ch[c].valid) {
            return false;
        }
    }
    return true;
}

bool leveler_sensors_all_valid(const leveler_sensors *s)
{
    return leveler_sensors_valid(s, (uint16_t)((1u << HAL_ADC_COUNT) - 1u));
}

uint16_t leveler_sensors_fault_bits(const leveler_sensors *s)
{
    uint16_t bits = 0;
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        if (s->ch[c].faulty) {
            bits = (uint16_t)(bits | (1u << c));
        }
    }
    return bits;
}
