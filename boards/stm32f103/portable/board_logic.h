/*
 * Board arithmetic and policies that need no hardware, kept here so the host
 * tests exercise exactly the code the STM32 runs.
 */
#ifndef BOARD_LOGIC_H
#define BOARD_LOGIC_H

#include <stdbool.h>
#include <stdint.h>

/* ---- ADC oversampling ----
 * The DMA buffer holds samples_per_channel scans of channel_count channels,
 * interleaved: buffer[scan * channel_count + channel]. Returns the rounded mean
 * of one channel in 12-bit counts.
 * Scaling: each sample <= 4095, samples_per_channel <= 2^20, so the uint32_t
 * sum < 2^32; the mean rounds half up and stays within 0..4095. */
uint16_t adc_oversample_mean(const volatile uint16_t *buffer, uint32_t channel,
                             uint32_t channel_count, uint32_t samples_per_channel);

/* ---- USART baud rate ----
 * BRR for 16x oversampling: USARTDIV*16 = pclk/baud, rounded to nearest
 * (RM0008 27.3.4). Returns 0 when baud is 0 or the divider is outside
 * 16..0xFFFF (the rate cannot be made on this clock). */
uint16_t usart_brr(uint32_t pclk_hz, uint32_t baud);

/* The baud rate a BRR value really gives: pclk/brr, rounded. */
uint32_t usart_baud_from_brr(uint32_t pclk_hz, uint16_t brr);

/* ---- Status LED blink codes ----
 * code 0: steady on (running, no fault). code N >= 1: N flashes of
 * BLINK_ON_MS on / BLINK_OFF_MS off, then BLINK_PAUSE_MS dark, repeating.
 * Codes above BLINK_MAX_CODE show as BLINK_MAX_CODE. Pure function of time. */
#define BLINK_ON_MS 200u
#define BLINK_OFF_MS 300u
#define BLINK_PAUSE_MS 1500u
#define BLINK_MAX_CODE 15u
bool blink_code_led_on(uint16_t code, uint32_t now_ms);
uint32_t blink_code_period_ms(uint16_t code);

/* ---- Settings persistence policy ----
 * Persist when the settings generation has changed and then stayed the same
 * for settle_ms (a burst of Modbus writes becomes one flash record: every
 * page erase stalls the CPU ~20-40 ms). */
typedef struct {
    uint32_t persisted_generation;
    uint32_t seen_generation;
    uint32_t seen_at_ms;
} persist_policy;
void persist_policy_init(persist_policy *p, uint32_t generation, uint32_t now_ms);
/* True when a save is due now; call persist_policy_saved() after saving. */
bool persist_policy_due(persist_policy *p, uint32_t generation, uint32_t now_ms, uint32_t settle_ms);
void persist_policy_saved(persist_policy *p, uint32_t generation);

#endif
