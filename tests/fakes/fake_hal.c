#include "fake_hal.h"

#include <string.h>

static struct {
    uint16_t counts[HAL_ADC_COUNT];
    bool fail[HAL_ADC_COUNT];
    uint32_t reads[HAL_ADC_COUNT];
    uint16_t script[HAL_ADC_COUNT][FAKE_HAL_ADC_SCRIPT_CAP];
    size_t script_len[HAL_ADC_COUNT];
    size_t script_pos[HAL_ADC_COUNT];
    uint32_t now_ms;
    bool out[HAL_OUT_COUNT];
    uint32_t out_writes[HAL_OUT_COUNT];
    uint8_t rx[FAKE_HAL_SERIAL_CAP];
    size_t rx_head, rx_len;
    uint8_t tx[FAKE_HAL_SERIAL_CAP];
    size_t tx_len;
    size_t tx_limit;
} fake;

void fake_hal_reset(void)
{
    memset(&fake, 0, sizeof(fake));
    for (unsigned c = 0; c < HAL_ADC_COUNT; c++) {
        fake.counts[c] = 2048u;
    }
    fake.tx_limit = FAKE_HAL_SERIAL_CAP;
}

void fake_hal_set_adc(hal_adc_channel channel, uint16_t counts)
{
    fake.counts[channel] = counts;
}

void fake_hal_script_adc(hal_adc_channel channel, const uint16_t *values, size_t n)
{
    if (n > FAKE_HAL_ADC_SCRIPT_CAP) {
        n = FAKE_HAL_ADC_SCRIPT_CAP;
    }
    memcpy(fake.script[channel], values, n * sizeof(values[0]));
    fake.script_len[channel] = n;
    fake.script_pos[channel] = 0;
}

void fake_hal_set_adc_fail(hal_adc_channel channel, bool fail)
{
    fake.fail[channel] = fail;
}

uint32_t fake_hal_adc_reads(hal_adc_channel channel)
{
    return fake.reads[channel];
}

void fake_hal_set_time_ms(uint32_t now_ms)
{
    fake.now_ms = now_ms;
}

void fake_hal_advance_ms(uint32_t dt_ms)
{
    fake.now_ms += dt_ms;
}

bool fake_hal_output(hal_output output)
{
    return fake.out[output];
}

uint32_t fake_hal_output_writes(hal_output output)
{
    return fake.out_writes[output];
}

void fake_hal_serial_push_rx(const uint8_t *bytes, size_t n)
{
    for (size_t i = 0; i < n && fake.rx_len < FAKE_HAL_SERIAL_CAP; i++) {
        fake.rx[(fake.rx_head + fake.rx_len) % FAKE_HAL_SERIAL_CAP] = bytes[i];
        fake.rx_len++;
    }
}

size_t fake_hal_serial_take_tx(uint8_t *out, size_t cap)
{
    size_t n = (fake.tx_len < cap) ? fake.tx_len : cap;
    memcpy(out, fake.tx, n);
    memmove(fake.tx, fake.tx + n, fake.tx_len - n);
    fake.tx_len -= n;
    return n;
}

void fake_hal_serial_set_tx_limit(size_t max_per_call)
{
    fake.tx_limit = max_per_call;
}

/* --- hal.h --- */

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    if ((unsigned)channel >= HAL_ADC_COUNT) {
        return false;
    }
    fake.reads[channel]++;
    if (fake.fail[channel]) {
        return false;
    }
    if (fake.script_pos[channel] < fake.script_len[channel]) {
        *counts = fake.script[channel][fake.script_pos[channel]++];
    } else {
        *counts = fake.counts[channel];
    }
    return true;
}

void hal_output_set(hal_output output, bool on)
{
    if ((unsigned)output < HAL_OUT_COUNT) {
        fake.out[output] = on;
        fake.out_writes[output]++;
    }
}

uint32_t hal_now_ms(void)
{
    return fake.now_ms;
}

size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    size_t n = 0;
    while (n < max_len && fake.rx_len > 0u) {
        buf[n++] = fake.rx[fake.rx_head];
        fake.rx_head = (fake.rx_head + 1u) % FAKE_HAL_SERIAL_CAP;
        fake.rx_len--;
    }
    return n;
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    size_t room = FAKE_HAL_SERIAL_CAP - fake.tx_len;
    size_t n = len;
    if (n > fake.tx_limit) {
        n = fake.tx_limit;
    }
    if (n > room) {
        n = room;
    }
    memcpy(fake.tx + fake.tx_len, buf, n);
    fake.tx_len += n;
    return n;
}
