/*
 * Minimum on and off times of the four outputs (algorithm 3): a request to
 * switch an output is held back until the output has been in its present
 * state for the minimum. The supervisor acts after this and may switch at
 * once (safety first); leveler_dwell_note() then records what was driven.
 */
#ifndef LEVELER_DWELL_H
#define LEVELER_DWELL_H

#include <stdbool.h>
#include <stdint.h>

#include "leveler/control.h"

typedef struct {
    uint8_t on_bits;        /* bit n: output n driven on (compressor, spring, vent, acc) */
    uint32_t since_ms[4];   /* when each output last changed */
} leveler_dwell;

/* All off, and free to switch at once. */
void leveler_dwell_init(leveler_dwell *d, uint32_t now_ms, uint16_t longest_ms);

/* Hold back switches that come too early (req is changed in place). */
void leveler_dwell_apply(const leveler_dwell *d, uint16_t min_on_ms, uint16_t min_off_ms, uint32_t now_ms,
                         leveler_outputs *req);

/* What was actually driven this tick. */
void leveler_dwell_note(leveler_dwell *d, const leveler_outputs *driven, uint32_t now_ms);

#endif /* LEVELER_DWELL_H */
