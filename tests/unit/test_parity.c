/*
 * Parity: a double-precision reference (calibration + controller written here
 * from the thesis rules and Appendix B's on_off) against the fixed-point
 * firmware, over >= 100,000 seeded random sensor states. Outputs must agree,
 * except where a reference value lies within one quantisation step (1 um or
 * 1 Pa: the firmware rounds each value to the unit) of a threshold.
 */
#include "test_support.h"

#include <math.h>
#include <stdio.h>

#include "leveler/control.h"
#include "leveler/fixed_point.h"

#define STATES 200000u

static uint64_t rng_state = 0x2545F4914F6CDD1DULL; /* fixed seed: reproducible */

static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 11);
}

static int32_t rnd_range(int32_t lo, int32_t hi)
{
    return lo + (int32_t)(rnd() % (uint32_t)(hi - lo + 1));
}

static double ref_convert(const leveler_calibration *c, uint32_t sum)
{
    return c->eng_lo + (sum / 4.0 - c->raw_lo) * ((double)c->eng_hi - c->eng_lo) / ((double)c->raw_hi - c->raw_lo);
}

/* Sum of four readings whose reference value is nearest v, nudged by +-jitter quarter counts. */
static uint32_t sum_near(const leveler_calibration *c, double v, int jitter)
{
    double counts = c->raw_lo + (v - c->eng_lo) * ((double)c->raw_hi - c->raw_lo) / ((double)c->eng_hi - c->eng_lo);
    long s = lround(counts * 4.0) + rnd_range(-jitter, jitter);
    return (uint32_t)(s < 0 ? 0 : s > 16380 ? 16380 : s);
}

typedef struct {
    bool c, s, v, a;
} ref_out;

/* The rules, straight from the thesis (Chapter IV) and Appendix B on_off, in doubles. */
static ref_out reference_controller(int algo, double lower, double upper, double acc_max, double y, double p1,
                                    double p3)
{
    ref_out o = {0, 0, 0, 0};
    if (y < lower) {
        o.c = 1, o.s = 1, o.v = 0;
        o.a = (algo == 2) && (p3 > p1);
    } else if (y > upper) {
        o.c = 0, o.s = 1, o.v = 1;
        o.a = (algo == 2) && (p3 < acc_max) && (p3 < p1);
    } else {
        o.s = 0, o.v = 0;
        if (algo == 1) {
            o.c = 0, o.a = 0;
        } else if (p3 >= acc_max) {
            o.c = 0, o.a = 0;
        } else {
            o.c = 1;
            o.a = p3 < p1;
        }
    }
    return o;
}

static void random_cal(leveler_calibration *c, int32_t eng_a, int32_t eng_b)
{
    c->raw_lo = (uint16_t)rnd_range(0, 1000);
    c->raw_hi = (uint16_t)rnd_range(3000, 4095);
    c->eng_lo = eng_a + rnd_range(-20000, 20000);
    c->eng_hi = eng_b + rnd_range(-20000, 20000);
    if (rnd() % 4u == 0u) { /* a quarter with negative slope */
        uint16_t t = c->raw_lo;
        c->raw_lo = c->raw_hi;
        c->raw_hi = t;
    }
}

static void test_parity_with_double_reference(void **state)
{
    (void)state;
    unsigned mismatches = 0, excused = 0, near_threshold = 0;
    for (unsigned i = 0; i < STATES; i++) {
        leveler_calibration cal_h, cal_p1, cal_p3;
        random_cal(&cal_h, 250000, 500000);
        random_cal(&cal_p1, 101325, 1480276);
        cal_p3 = cal_p1; /* same transducer type: P3 vs P1 ties are reachable */
        if (rnd() % 3u == 0u) {
            random_cal(&cal_p3, 101325, 1480276);
        }
        int algo = 1 + (int)(rnd() % 2u);
        int32_t lower = rnd_range(300000, 450000);
        int32_t upper = lower + rnd_range(1, 20000);
        int32_t acc_max = rnd_range(300000, 1100000);

        uint32_t sh, s1, s3;
        unsigned pick = rnd() % 6u;
        sh = pick == 0 ? sum_near(&cal_h, lower, 3) : pick == 1 ? sum_near(&cal_h, upper, 3) : rnd() % 16381u;
        s1 = rnd() % 16381u;
        unsigned pick3 = rnd() % 4u;
        s3 = pick3 == 0 ? sum_near(&cal_p3, ref_convert(&cal_p1, s1), 2)
             : pick3 == 1 ? sum_near(&cal_p3, acc_max, 2)
                          : rnd() % 16381u;

        leveler_outputs fw;
        leveler_control_decide((uint16_t)algo, lower, upper, acc_max, leveler_cal_convert(&cal_h, sh, 4),
                               leveler_cal_convert(&cal_p1, s1, 4), leveler_cal_convert(&cal_p3, s3, 4), &fw);
        double y = ref_convert(&cal_h, sh), p1 = ref_convert(&cal_p1, s1), p3 = ref_convert(&cal_p3, s3);
        ref_out r = reference_controller(algo, lower, upper, acc_max, y, p1, p3);

        bool near = fabs(y - lower) <= 1.0 || fabs(y - upper) <= 1.0 ||
                    (algo == 2 && (fabs(p3 - p1) <= 1.0 || fabs(p3 - acc_max) <= 1.0));
        near_threshold += near;
        if (fw.compressor != r.c || fw.spring_valve != r.s || fw.vent_valve != r.v || fw.acc_valve != r.a) {
            mismatches++;
            if (!near) {
                fail_msg("state %u: algo %d y=%.3f p1=%.3f p3=%.3f -> fw %d%d%d%d ref %d%d%d%d", i, algo, y, p1, p3,
                         fw.compressor, fw.spring_valve, fw.vent_valve, fw.acc_valve, r.c, r.s, r.v, r.a);
            }
            excused++;
        }
    }
    printf("parity: %u random states, %u within one step of a threshold, %u differ (all %u within one step)\n",
           STATES, near_threshold, mismatches, excused);
    assert_true(near_threshold > 1000u); /* the edges really were exercised */
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_parity_with_double_reference)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
