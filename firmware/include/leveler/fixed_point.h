/*
 * Fixed-point helpers (integer only; see each function for scaling and overflow).
 */
#ifndef LEVELER_FIXED_POINT_H
#define LEVELER_FIXED_POINT_H

#include <stdint.h>
#include "leveler/settings.h"

/* Saturate an int64 to int32. */
int32_t leveler_sat_i32(int64_t v);

/* a + b and a - b for uint32, saturating at 0 and UINT32_MAX. */
uint32_t leveler_sat_add_u32(uint32_t a, uint32_t b);
uint32_t leveler_sat_sub_u32(uint32_t a, uint32_t b);

/* a + 1 for uint16, saturating at UINT16_MAX. */
uint16_t leveler_sat_inc_u16(uint16_t a);

/* n / d rounded half away from zero; d > 0. */
int64_t leveler_div_round_i64(int64_t n, int64_t d);

/*
 * Two-point calibration: counts -> engineering unit (um or Pa).
 *
 *   eng = eng_lo + (counts_sum - n*raw_lo) * (eng_hi - eng_lo) / (n * (raw_hi - raw_lo))
 *
 * counts_sum is the sum of n conversions (n = 1 for one reading, 4 for the
 * oversampled tick), so averaging keeps the fraction of a count.
 * Scaling: inputs are integer counts and integer um/Pa; the result is in the
 * unit of eng_lo/eng_hi, rounded half away from zero (error <= 0.5 LSB of the
 * output unit against the exact line).
 * Overflow: |counts_sum - n*raw_lo| <= n*4095 <= 2^28 for n <= 65535 and
 * |eng_hi - eng_lo| < 2^33, so the int64 product stays below 2^61; the result
 * is saturated to int32. raw_lo == raw_hi (refused by settings) returns eng_lo.
 */
int32_t leveler_cal_convert(const leveler_calibration *cal, uint32_t counts_sum, uint16_t n);

#endif /* LEVELER_FIXED_POINT_H */
