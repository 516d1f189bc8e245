/*
 * Run-time settings: everything a supervisor may change through the holding
 * registers, in one plain struct so a board can store it in flash as a blob.
 * Units are in the names; pressures are absolute pascals.
 */
#ifndef LEVELER_SETTINGS_H
#define LEVELER_SETTINGS_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/hal.h"

typedef enum { LEVELER_MODE_OFF = 0, LEVELER_MODE_AUTO = 1, LEVELER_MODE_MANUAL = 2 } leveler_mode;
typedef enum {
    LEVELER_ALGO_NO_ACCUMULATOR = 1,
    LEVELER_ALGO_ACCUMULATOR = 2,
    LEVELER_ALGO_HYSTERESIS_AWARE = 3 /* algorithm 3, alg3.h */
} leveler_algorithm;

/* Two-point calibration of one channel: counts raw_lo -> eng_lo, raw_hi -> eng_hi
 * (eng in um for height, Pa absolute for pressures). */
typedef struct {
    uint16_t raw_lo;
    uint16_t raw_hi;
    int32_t eng_lo;
    int32_t eng_hi;
} leveler_calibration;

typedef struct {
    uint16_t mode;                 /* leveler_mode */
    uint16_t algorithm;            /* leveler_algorithm */
    int32_t band_lower_um;         /* thesis: 15.6 in */
    int32_t band_upper_um;         /* thesis: 15.8 in */
    int32_t acc_charge_max_pa;     /* thesis program: 126.7 psia */
    int32_t overpressure_limit_pa; /* compressor off above this */
    int32_t overpressure_vent_pa;  /* and vent above this */
    uint16_t compressor_max_run_s; /* then a cool-down */
    uint16_t compressor_cooldown_s;
    uint16_t stall_window_s;       /* filling without rise for this long = fault */
    int32_t stall_min_rise_pa;     /* the rise in P1/P2 that counts as progress */
    int32_t stall_min_rise_um;     /* or this rise in height */
    uint16_t sensor_bad_samples;   /* debounce: faulty after N bad samples */
    uint16_t sensor_good_samples;  /* recovers after M good ones */
    uint16_t sensor_stuck_s;       /* raw value frozen this long = stuck; 0 = off */
    uint16_t sensor_stale_ms;      /* no fresh reading this long = stale */
    uint16_t modbus_address;       /* 1..247 */
    uint16_t modbus_baud_div100;   /* 19200 baud = 192 */
    leveler_calibration calibration[HAL_ADC_COUNT];
    uint16_t chatter_max_per_min;  /* supervisor: switchings per 60 s that latch the chatter fault; 0 = off */
    /* algorithm 3 (alg3.h); the learnt values are kept here so they reach flash */
    uint16_t alg3_accumulator;     /* 1 = fitted */
    uint16_t alg3_target_permille; /* target inside the band, from the lower edge */
    uint16_t alg3_persist_ms;
    uint16_t alg3_min_on_ms;
    uint16_t alg3_min_off_ms;
    uint16_t alg3_settle_ms;
    uint16_t alg3_learn;
    uint16_t alg3_coast_up_ms;     /* learnt */
    uint16_t alg3_coast_down_ms;   /* learnt */
    int32_t alg3_confirm_um_s;
    int32_t alg3_line_slope_pa_per_mm;
    int32_t alg3_up_pa;            /* learnt, 0 = not yet */
    int32_t alg3_down_pa;          /* learnt, 0 = not yet */
    int32_t alg3_coast_k_up_pa_per_mm;   /* learnt */
    int32_t alg3_coast_k_down_pa_per_mm; /* learnt */
    int32_t alg3_gap_pa;           /* learnt */
    /* the last commissioning (commission.h), read-only over Modbus, kept in flash with the rest */
    uint16_t commission_result;    /* leveler_commission_result */
    uint16_t commission_ms;        /* its duration, saturated */
    int32_t commission_up_pa;      /* the lines it learnt at the target height, 0 = none */
    int32_t commission_down_pa;
} leveler_settings;

/* Factory defaults (the thesis rig). */
void leveler_settings_defaults(leveler_settings *out);

/* The settings in force. */
const leveler_settings *leveler_settings_current(void);

/* Validate a whole settings struct (ranges and consistency, e.g. band lower < upper).
 * Returns 0 when valid, else a leveler_reg_reason code (see regmap.h). */
uint16_t leveler_settings_check(const leveler_settings *s);

/* Replace the settings in force after leveler_settings_check(); refused
 * settings change nothing. Used by a board restoring its flash copy. */
uint16_t leveler_settings_apply(const leveler_settings *s);

/* Increments on every accepted change, so a board knows when to persist. */
uint32_t leveler_settings_generation(void);

#endif /* LEVELER_SETTINGS_H */
