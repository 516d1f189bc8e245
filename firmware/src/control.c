#include "leveler/control.h"

#include <string.h>

/*
 * Algorithm 1 (no accumulator), Chapter IV part one: strict comparisons as in
 * Appendix B (y < Lower_band, y > Upper_band); on an edge the height is in band.
 */
static leveler_control_state no_accumulator(int32_t lower_um, int32_t upper_um, int32_t height_um,
                                            leveler_outputs *out)
{
    out->acc_valve = false; /* "the accumulator valve is simply closed for the duration" */
    if (height_um < lower_um) {
        out->compressor = true;
        out->spring_valve = true;
        out->vent_valve = false;
        return LEVELER_STATE_CHARGING;
    }
    if (height_um > upper_um) {
        out->compressor = false;
        out->spring_valve = true;
        out->vent_valve = true;
        return LEVELER_STATE_DISCHARGING;
    }
    out->compressor = false;
    out->spring_valve = false;
    out->vent_valve = false;
    return LEVELER_STATE_IN_BAND;
}

/*
 * Algorithm 2 (accumulator): Appendix B's on_off, which settles what the text
 * (Chapter III "Accumulator" and Chapter IV part two) leaves open. Differences
 * from the Chapter IV table, each following the program:
 *  - above band: the text opens the accumulator whenever P3 <= P1; the program
 *    only while P3 < P1 (strict) AND P3 < Charged_pressure (no charging past
 *    the maximum while discharging).
 *  - in band: the text runs the compressor with the accumulator valve open when
 *    P3 <= P1 whatever P3 is; the program first checks P3 >= Charged_pressure
 *    (compressor off, valve closed), else runs the compressor and opens the
 *    valve only while P3 < P1 (strict).
 *  - the text's in-band limit "not over 120 psig" is the program's
 *    Charged_pressure (126.7 psia = settings.acc_charge_max_pa), compared as
 *    P3 >= max -> stop.
 *  - below band: identical (valve open only while P3 > P1, strict).
 */
static leveler_control_state accumulator(int32_t lower_um, int32_t upper_um, int32_t acc_max_pa, int32_t height_um,
                                         int32_t p1_pa, int32_t p3_pa, leveler_outputs *out)
{
    if (height_um < lower_um) {
        out->compressor = true;
        out->spring_valve = true;
        out->vent_valve = false;
        out->acc_valve = p3_pa > p1_pa; /* the charged accumulator helps lift */
        return LEVELER_STATE_CHARGING;
    }
    if (height_um > upper_um) {
        out->compressor = false;
        out->spring_valve = true;
        out->vent_valve = true;
        out->acc_valve = (p3_pa < acc_max_pa) && (p3_pa < p1_pa); /* surplus air charges it */
        return LEVELER_STATE_DISCHARGING;
    }
    out->spring_valve = false;
    out->vent_valve = false;
    if (p3_pa >= acc_max_pa) {
        out->compressor = false;
        out->acc_valve = false;
    } else {
        out->compressor = true; /* in band: time to charge the accumulator */
        out->acc_valve = p3_pa < p1_pa;
    }
    return LEVELER_STATE_IN_BAND;
}

uint8_t leveler_outputs_bits(const leveler_outputs *o)
{
    return (uint8_t)((o->compressor ? 1u : 0u) | (o->spring_valve ? 2u : 0u) | (o->vent_valve ? 4u : 0u) |
                     (o->acc_valve ? 8u : 0u));
}

uint16_t leveler_control_channels_used(uint16_t algorithm, bool acc_fitted)
{
    const uint16_t all = (uint16_t)((1u << HAL_ADC_COUNT) - 1u);
    if (algorithm == (uint16_t)LEVELER_ALGO_NO_ACCUMULATOR ||
        (algorithm == (uint16_t)LEVELER_ALGO_HYSTERESIS_AWARE && !acc_fitted)) {
        return (uint16_t)(all & ~(1u << HAL_ADC_P_ACC));
    }
    return all;
}

leveler_control_state leveler_control_decide(uint16_t algorithm, int32_t band_lower_um, int32_t band_upper_um,
                                             int32_t acc_charge_max_pa, int32_t height_um, int32_t p_pipe_pa,
                                             int32_t p_acc_pa, leveler_outputs *out)
{
    switch (algorithm) {
    case LEVELER_ALGO_NO_ACCUMULATOR:
        return no_accumulator(band_lower_um, band_upper_um, height_um, out);
    case LEVELER_ALGO_ACCUMULATOR:
        return accumulator(band_lower_um, band_upper_um, acc_charge_max_pa, height_um, p_pipe_pa, p_acc_pa, out);
    default:
        memset(out, 0, sizeof(*out));
        return LEVELER_STATE_SAFE;
    }
}
