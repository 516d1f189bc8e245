#include "leveler/fixed_point.h"

int32_t leveler_sat_i32(int64_t v)
{
    if (v > INT32_MAX) {
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)v;
}

uint32_t leveler_sat_add_u32(uint32_t a, uint32_t b)
{
    return (a > UINT32_MAX - b) ? UINT32_MAX : a + b;
}

uint32_t leveler_sat_sub_u32(uint32_t a, uint32_t b)
{
    return (a > b) ? a - b : 0u;
}

uint16_t leveler_sat_inc_u16(uint16_t a)
{
    return (a == UINT16_MAX) ? a : (uint16_t)(a + 1u);
}

int64_t leveler_div_round_i64(int64_t n, int64_t d)
{
    /* Work on the magnitude so the rounding is symmetric about zero. n is far
     * from INT64_MIN in every caller (see leveler_cal_convert). */
    int64_t mag = (n < 0) ? -n : n;
    int64_t q = (mag + d / 2) / d;
    return (n < 0) ? -q : q;
}

int32_t leveler_cal_convert(const leveler_calibration *cal, uint32_t counts_sum, uint16_t n)
{
    int64_t den = (int64_t)n * ((int64_t)cal->raw_hi - (int64_t)cal->raw_lo);
    int64_t span = (int64_t)cal->eng_hi - (int64_t)cal->eng_lo;
    int64_t offset = (int64_t)counts_sum - (int64_t)n * (int64_t)cal->raw_lo;
    if (den == 0) {
        return cal->eng_lo;
    }
    if (den < 0) { /* keep the divisor positive: negative slopes flip the numerator */
        den = -den;
        span = -span;
    }
    return leveler_sat_i32((int64_t)cal->eng_lo + leveler_div_round_i64(offset * span, den));
}
