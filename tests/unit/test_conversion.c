/* Sensor conversion against a double-precision reference over the whole ADC range. */
#include "test_support.h"

#include <math.h>
#include <stdio.h>

#include "leveler/fixed_point.h"

static double reference(const leveler_calibration *c, double counts_sum, unsigned n)
{
    double v = c->eng_lo + (counts_sum - n * (double)c->raw_lo) * ((double)c->eng_hi - c->eng_lo) /
                               (n * ((double)c->raw_hi - c->raw_lo));
    if (v > INT32_MAX) {
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        return INT32_MIN;
    }
    return v;
}

static const leveler_calibration calibrations[] = {
    {410, 3686, 250000, 500000},        /* default height, um */
    {410, 3686, 101325, 1480276},       /* default pressure, Pa */
    {3686, 410, 250000, 500000},        /* negative slope: points swapped */
    {410, 3686, 500000, 250000},        /* negative slope: eng swapped */
    {0, 4095, -2000000, 2000000},       /* widest register range */
    {0, 4095, 0, 1},                    /* tiny span: mostly rounding */
    {2047, 2048, -2000000, 2000000},    /* one count = 4e6 units, saturates */
    {100, 101, INT32_MIN, INT32_MAX},   /* extreme: full int32 span per count */
    {4095, 0, INT32_MAX, INT32_MIN + 1},
    {1, 4094, 7, -13},
};

static void test_every_count_within_half_lsb(void **state)
{
    (void)state;
    double worst = 0.0;
    for (size_t k = 0; k < sizeof(calibrations) / sizeof(calibrations[0]); k++) {
        const leveler_calibration *c = &calibrations[k];
        double worst_cal = 0.0;
        for (uint32_t counts = 0; counts <= 4095u; counts++) {
            double err = fabs((double)leveler_cal_convert(c, counts, 1) - reference(c, counts, 1));
            if (err > worst_cal) {
                worst_cal = err;
            }
        }
        /* The oversampled path: sums of four readings keep quarter counts. */
        for (uint32_t sum = 0; sum <= 4u * 4095u; sum++) {
            double err = fabs((double)leveler_cal_convert(c, sum, 4) - reference(c, sum, 4));
            if (err > worst_cal) {
                worst_cal = err;
            }
        }
        printf("calibration %zu (%u..%u -> %d..%d): max error %.6f LSB\n", k, c->raw_lo, c->raw_hi, c->eng_lo,
               c->eng_hi, worst_cal);
        assert_true(worst_cal <= 0.5 + 1e-9);
        if (worst_cal > worst) {
            worst = worst_cal;
        }
    }
    printf("conversion: largest error over all calibrations and counts: %.6f LSB of the output unit\n", worst);
}

static void test_rounds_half_away_from_zero(void **state)
{
    (void)state;
    leveler_calibration up = {0, 2, 0, 1};   /* count 1 -> +0.5 */
    leveler_calibration down = {0, 2, 0, -1}; /* count 1 -> -0.5 */
    assert_int_equal(leveler_cal_convert(&up, 1, 1), 1);
    assert_int_equal(leveler_cal_convert(&down, 1, 1), -1);
    leveler_calibration third = {0, 3, 0, 1}; /* 1/3 -> 0, 2/3 -> 1 */
    assert_int_equal(leveler_cal_convert(&third, 1, 1), 0);
    assert_int_equal(leveler_cal_convert(&third, 2, 1), 1);
}

static void test_saturates(void **state)
{
    (void)state;
    leveler_calibration steep = {100, 101, 0, INT32_MAX};
    assert_int_equal(leveler_cal_convert(&steep, 4095, 1), INT32_MAX);
    assert_int_equal(leveler_cal_convert(&steep, 0, 1), INT32_MIN);
    leveler_calibration flat = {7, 7, 1234, 99};
    assert_int_equal(leveler_cal_convert(&flat, 3000, 1), 1234); /* refused by settings; defined anyway */
    assert_int_equal(leveler_sat_i32((int64_t)INT32_MAX + 5), INT32_MAX);
    assert_int_equal(leveler_sat_i32((int64_t)INT32_MIN - 5), INT32_MIN);
    assert_int_equal(leveler_sat_add_u32(UINT32_MAX - 1u, 5u), UINT32_MAX);
    assert_int_equal(leveler_sat_add_u32(1u, 2u), 3u);
    assert_int_equal(leveler_sat_sub_u32(3u, 5u), 0u);
    assert_int_equal(leveler_sat_inc_u16(UINT16_MAX), UINT16_MAX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_count_within_half_lsb),
        cmocka_unit_test(test_rounds_half_away_from_zero),
        cmocka_unit_test(test_saturates),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
