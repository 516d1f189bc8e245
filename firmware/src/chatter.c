#include "leveler/chatter.h"

#include <string.h>

#include "leveler/fixed_point.h"

void leveler_chatter_init(leveler_chatter *c)
{
    memset(c, 0, sizeof(*c));
}

/* Move the head to the bucket holding now_ms, emptying the buckets passed. */
static void advance(leveler_chatter *c, uint32_t now_ms)
{
    unsigned passed = 0;
    while (now_ms - c->bucket_start_ms >= LEVELER_CHATTER_BUCKET_MS && passed < LEVELER_CHATTER_BUCKETS) {
        c->head = (uint8_t)((c->head + 1u) % LEVELER_CHATTER_BUCKETS);
        c->bucket[c->head] = 0;
        c->bucket_start_ms += LEVELER_CHATTER_BUCKET_MS;
        passed++;
    }
    if (now_ms - c->bucket_start_ms >= LEVELER_CHATTER_BUCKET_MS) { /* a long gap: all emptied */
        c->bucket_start_ms = now_ms;
    }
}

uint16_t leveler_chatter_step(leveler_chatter *c, uint8_t out_bits, uint32_t now_ms)
{
    if (!c->started) {
        c->started = true;
        c->bucket_start_ms = now_ms;
        c->last_bits = out_bits;
    }
    advance(c, now_ms);
    if (out_bits != c->last_bits) {
        c->bucket[c->head] = leveler_sat_inc_u16(c->bucket[c->head]);
    }
    c->last_bits = out_bits;
    uint32_t sum = 0;
    for (unsigned i = 0; i < LEVELER_CHATTER_BUCKETS; i++) {
        sum += c->bucket[i];
    }
    return (sum > UINT16_MAX) ? (uint16_t)UINT16_MAX : (uint16_t)sum;
}
