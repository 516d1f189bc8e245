#include "hal_stream.h"

#include <string.h>

hal_stream_state hal_stream;

void hal_stream_reset(uint32_t now_ms, size_t rx_chunk, size_t tx_chunk, bool overstate)
{
    memset(&hal_stream, 0, sizeof hal_stream);
    hal_stream.now_ms = now_ms;
    hal_stream.rx_chunk = rx_chunk;
    hal_stream.tx_chunk = tx_chunk;
    hal_stream.overstate = overstate;
}

void hal_stream_feed(const uint8_t *bytes, size_t len)
{
    hal_stream.rx = bytes;
    hal_stream.rx_left = len;
}

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    *counts = (uint16_t)(1000u + 100u * (unsigned)channel);
    return true;
}

void hal_output_set(hal_output output, bool on)
{
    (void)output;
    (void)on;
}

uint32_t hal_now_ms(void) { return hal_stream.now_ms; }

size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    size_t n = hal_stream.rx_left < hal_stream.rx_chunk ? hal_stream.rx_left : hal_stream.rx_chunk;
    n = n < max_len ? n : max_len;
    if (n == 0) {
        return 0;
    }
    memcpy(buf, hal_stream.rx, n);
    hal_stream.rx += n;
    hal_stream.rx_left -= n;
    return hal_stream.overstate ? n + 1u : n;
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    size_t n = len < hal_stream.tx_chunk ? len : hal_stream.tx_chunk;
    if (n > HAL_STREAM_TX_CAP - hal_stream.tx_len) {
        n = HAL_STREAM_TX_CAP - hal_stream.tx_len;
    }
    memcpy(&hal_stream.tx[hal_stream.tx_len], buf, n);
    hal_stream.tx_len += n;
    return hal_stream.overstate && n > 0 ? n + 1u : n;
}
