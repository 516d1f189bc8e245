/*
 * Switching-rate counter behind the supervisor's chatter fault: a relay or a
 * solenoid switched every second dies in days, whatever algorithm asks for it.
 * A "switching" is a tick on which any driven output changed. The count covers
 * the current 10 s bucket and the five before it (50..60 s).
 */
#ifndef LEVELER_CHATTER_H
#define LEVELER_CHATTER_H

#include <stdbool.h>
#include <stdint.h>

#define LEVELER_CHATTER_BUCKETS 6u
#define LEVELER_CHATTER_BUCKET_MS 10000u

typedef struct {
    uint16_t bucket[LEVELER_CHATTER_BUCKETS];
    uint32_t bucket_start_ms; /* start of bucket[head] */
    uint8_t head;
    uint8_t last_bits;        /* outputs of the previous tick, bit n = hal_output n */
    bool started;
} leveler_chatter;

void leveler_chatter_init(leveler_chatter *c);

/* Note this tick's driven outputs (bit n = output n); returns the switchings
 * in the window, the current tick's included (saturates at UINT16_MAX). */
uint16_t leveler_chatter_step(leveler_chatter *c, uint8_t out_bits, uint32_t now_ms);

#endif /* LEVELER_CHATTER_H */
