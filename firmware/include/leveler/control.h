/*
 * The on-off leveling controller of the thesis (Chapter III "Control Algorithm",
 * Chapter IV "Experiment Procedure", Appendix B procedure on_off). Pure: the
 * same inputs give the same outputs; the safety supervisor overrides it.
 */
#ifndef LEVELER_CONTROL_H
#define LEVELER_CONTROL_H

#include <stdbool.h>
#include <stdint.h>
#include "leveler/settings.h"
#include "leveler/status.h"

typedef struct {
    bool compressor;
    bool spring_valve;
    bool vent_valve;
    bool acc_valve;
} leveler_outputs;

/*
 * Decide the outputs from the height and the pipe (P1, "system pressure") and
 * accumulator (P3) pressures. algorithm is a leveler_algorithm; any other
 * value gives the safe outputs and LEVELER_STATE_SAFE. Returns the band state.
 */
leveler_control_state leveler_control_decide(uint16_t algorithm, int32_t band_lower_um, int32_t band_upper_um,
                                             int32_t acc_charge_max_pa, int32_t height_um, int32_t p_pipe_pa,
                                             int32_t p_acc_pa, leveler_outputs *out);

/*
 * The sensor channels an algorithm depends on, bit n = hal_adc_channel n.
 * Algorithm 1 leaves out P3: the thesis rig without an accumulator had only
 * the LVDT and the spring and pipe transducers (Chapter III, "System
 * Modelling"), so a rig without one must not fault on a missing P3.
 * Algorithm 3 uses P3 only when an accumulator is fitted (alg3_accumulator).
 * An unknown algorithm needs every channel.
 */
uint16_t leveler_control_channels_used(uint16_t algorithm, bool acc_fitted);

/* The outputs as bits: 1 compressor, 2 spring valve, 4 vent valve, 8 accumulator valve. */
uint8_t leveler_outputs_bits(const leveler_outputs *o);

#endif /* LEVELER_CONTROL_H */
