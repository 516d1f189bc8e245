/*
 * Sensor sampling: four ADC channels -> filtered engineering values + validity.
 *
 * Per tick and channel:
 *  1. oversample: LEVELER_OVERSAMPLE conversions, summed (the reads that
 *     succeeded, rescaled to LEVELER_OVERSAMPLE); all samples are of this tick,
 *     so the average adds no lag beyond the tick itself;
 *  2. classify: out of range (open wire / short: mean below 5 % or above 95 %
 *     of full scale; the transducers' live span is 10 %..90 %, 410..3686
 *     counts), stuck (sum unchanged for settings.sensor_stuck_s; 0 = off),
 *     no reading (every hal_adc_read() failed), stale (no reading for
 *     settings.sensor_stale_ms);
 *  3. spike filter on a good sample: a jump of more than LEVELER_SPIKE_LIMIT_COUNTS
 *     from the last accepted value is held for one tick and taken on the next
 *     tick whatever it is (added lag at most one tick, on jumps only);
 *  4. convert the accepted sum with the channel's two-point calibration;
 *  5. debounce: faulty after settings.sensor_bad_samples consecutive bad samples
 *     (stale is faulty at once), valid again after settings.sensor_good_samples
 *     consecutive good ones. A channel starts neither valid nor faulty.
 */
#ifndef LEVELER_SENSORS_H
#define LEVELER_SENSORS_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/hal.h"
#include "leveler/settings.h"

#define LEVELER_OVERSAMPLE 4u
/* 5 % and 95 % of 4095 counts: below / above is an open wire or a short. */
#define LEVELER_ADC_OPEN_BELOW_COUNTS 205u
#define LEVELER_ADC_SHORT_ABOVE_COUNTS 3890u
/* 10 % of full scale in one tick is a spike unless the next tick confirms it. */
#define LEVELER_SPIKE_LIMIT_COUNTS 410u

/* Why the last sample of a channel was bad (bit set). */
#define LEVELER_SENSOR_BAD_RANGE 0x01u
#define LEVELER_SENSOR_BAD_STUCK 0x02u
#define LEVELER_SENSOR_BAD_NO_READING 0x04u
#define LEVELER_SENSOR_BAD_STALE 0x08u

typedef struct {
    int32_t value;             /* last accepted value, um or Pa absolute */
    uint32_t accepted_sum;     /* its counts sum (x LEVELER_OVERSAMPLE) */
    uint32_t last_sum;         /* counts sum of the last fresh reading */
    uint32_t last_fresh_ms;    /* time of the last fresh reading */
    uint32_t stuck_since_ms;   /* since when last_sum has not changed */
    uint16_t raw_counts;       /* mean counts of the last fresh reading */
    uint16_t bad_run;          /* consecutive bad samples (saturates) */
    uint16_t good_run;         /* consecutive good samples (saturates) */
    uint8_t bad_reasons;       /* LEVELER_SENSOR_BAD_* of the last sample */
    bool have_accepted;        /* value holds a real reading */
    bool have_fresh;           /* last_sum holds a real reading */
    bool spike_held;           /* last tick's sample was held as a spike */
    bool valid;
    bool faulty;
} leveler_sensor_channel;

typedef struct {
    leveler_sensor_channel ch[HAL_ADC_COUNT];
} leveler_sensors;

void leveler_sensors_init(leveler_sensors *s, uint32_t now_ms);
void leveler_sensors_sample(leveler_sensors *s, const leveler_settings *set, uint32_t now_ms);
bool leveler_sensors_all_valid(const leveler_sensors *s);
/* Every channel in channel_mask (bit n = channel n) valid. */
bool leveler_sensors_valid(const leveler_sensors *s, uint16_t channel_mask);
uint16_t leveler_sensors_fault_bits(const leveler_sensors *s); /* bit n = channel n faulty */

#endif /* LEVELER_SENSORS_H */
