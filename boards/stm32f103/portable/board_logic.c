#include "board_logic.h"

uint16_t adc_oversample_mean(const volatile uint16_t *buffer, uint32_t channel,
                             uint32_t channel_count, uint32_t samples_per_channel)
{
    if (samples_per_channel == 0u || channel >= channel_count) {
        return 0u;
    }
    uint32_t sum = 0;
    for (uint32_t i = 0; i < samples_per_channel; i++) {
        sum += buffer[i * channel_count + channel] & 0x0FFFu; /* right-aligned 12-bit */
    }
    return (uint16_t)((sum + samples_per_channel / 2u) / samples_per_channel);
}

uint16_t usart_brr(uint32_t pclk_hz, uint32_t baud)
{
    if (baud == 0u) {
        return 0u;
    }
    /* Round to nearest without overflow or 64-bit division (which would pull
     * in libgcc's __udivmoddi4): bump the quotient when 2*r >= baud. */
    uint32_t brr = pclk_hz / baud;
    uint32_t r = pclk_hz % baud;
    if (r >= baud - r) {
        brr++;
    }
    if (brr < 16u || brr > 0xFFFFu) {
        return 0u;
    }
    return (uint16_t)brr;
}

uint32_t usart_baud_from_brr(uint32_t pclk_hz, uint16_t brr)
{
    if (brr == 0u) {
        return 0u;
    }
    uint32_t baud = pclk_hz / brr;
    uint32_t r = pclk_hz % brr;
    return r >= (uint32_t)brr - r ? baud + 1u : baud;
}

uint32_t blink_code_period_ms(uint16_t code)
{
    if (code == 0u) {
        return 0u;
    }
    uint32_t n = code > BLINK_MAX_CODE ? BLINK_MAX_CODE : code;
    return n * (BLINK_ON_MS + BLINK_OFF_MS) + BLINK_PAUSE_MS;
}

bool blink_code_led_on(uint16_t code, uint32_t now_ms)
{
    if (code == 0u) {
        return true;
    }
    uint32_t n = code > BLINK_MAX_CODE ? BLINK_MAX_CODE : code;
    uint32_t phase = now_ms % blink_code_period_ms(code);
    if (phase >= n * (BLINK_ON_MS + BLINK_OFF_MS)) {
        return false; /* the pause */
    }
    return phase % (BLINK_ON_MS + BLINK_OFF_MS) < BLINK_ON_MS;
}

void persist_policy_init(persist_policy *p, uint32_t generation, uint32_t now_ms)
{
    p->persisted_generation = generation;
    p->seen_generation = generation;
    p->seen_at_ms = now_ms;
}

bool persist_policy_due(persist_policy *p, uint32_t generation, uint32_t now_ms, uint32_t settle_ms)
{
    if (generation != p->seen_generation) {
        p->seen_generation = generation;
        p->seen_at_ms = now_ms;
        return false;
    }
    /* Unsigned difference: correct across the 2^32 ms wrap. */
    return generation != p->persisted_generation && (uint32_t)(now_ms - p->seen_at_ms) >= settle_ms;
}

void persist_policy_saved(persist_policy *p, uint32_t generation)
{
    p->persisted_generation = generation;
}
