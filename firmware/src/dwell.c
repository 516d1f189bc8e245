#include "leveler/dwell.h"

static void set_bits(leveler_outputs *o, uint8_t bits)
{
    o->compressor = (bits & 1u) != 0u;
    o->spring_valve = (bits & 2u) != 0u;
    o->vent_valve = (bits & 4u) != 0u;
    o->acc_valve = (bits & 8u) != 0u;
}

void leveler_dwell_init(leveler_dwell *d, uint32_t now_ms, uint16_t longest_ms)
{
    d->on_bits = 0;
    for (unsigned i = 0; i < 4u; i++) {
        d->since_ms[i] = now_ms - longest_ms; /* wraps harmlessly: only differences are used */
    }
}

void leveler_dwell_apply(const leveler_dwell *d, uint16_t min_on_ms, uint16_t min_off_ms, uint32_t now_ms,
                         leveler_outputs *req)
{
    uint8_t want = leveler_outputs_bits(req);
    uint8_t got = d->on_bits;
    for (unsigned i = 0; i < 4u; i++) {
        uint8_t bit = (uint8_t)(1u << i);
        if (((want ^ d->on_bits) & bit) == 0u) {
            continue;
        }
        uint32_t held_ms = now_ms - d->since_ms[i];
        uint16_t need = ((d->on_bits & bit) != 0u) ? min_on_ms : min_off_ms;
        if (held_ms >= need) {
            got = (uint8_t)(got ^ bit);
        }
    }
    set_bits(req, got);
}

void leveler_dwell_note(leveler_dwell *d, const leveler_outputs *driven, uint32_t now_ms)
{
    uint8_t now_bits = leveler_outputs_bits(driven);
    for (unsigned i = 0; i < 4u; i++) {
        if (((now_bits ^ d->on_bits) & (1u << i)) != 0u) {
            d->since_ms[i] = now_ms;
        }
    }
    d->on_bits = now_bits;
}
