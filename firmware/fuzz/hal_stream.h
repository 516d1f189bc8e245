/* Scripted HAL for the frame-parser harness (fuzz target and corpus replay):
 * serial input from a buffer handed out in chunks, serial output captured,
 * time advanced by the harness, ADC fixed. Single-threaded. */
#ifndef LEVELER_TEST_HAL_STREAM_H
#define LEVELER_TEST_HAL_STREAM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "leveler/hal.h"

#define HAL_STREAM_TX_CAP 4096u

typedef struct {
    uint32_t now_ms;
    const uint8_t *rx;      /* bytes still to hand out */
    size_t rx_left;
    size_t rx_chunk;        /* at most this many per hal_serial_read() */
    size_t tx_chunk;        /* at most this many accepted per hal_serial_write() */
    bool overstate;         /* a faulty HAL: report one byte more than it moved */
    uint8_t tx[HAL_STREAM_TX_CAP];
    size_t tx_len;
} hal_stream_state;

extern hal_stream_state hal_stream;

void hal_stream_reset(uint32_t now_ms, size_t rx_chunk, size_t tx_chunk, bool overstate);
void hal_stream_feed(const uint8_t *bytes, size_t len);

#endif
