/*
 * Single-producer single-consumer byte ring for the USART: the interrupt
 * handler is one side, the main loop the other. Capacity is a power of two;
 * head and tail are free-running 16-bit counters (used = head - tail, modulo
 * 2^16), each written by one side only, so no lock is needed on a Cortex-M3
 * (aligned 16-bit stores are atomic). One side must not call the other's
 * functions.
 */
#ifndef BOARD_BYTE_RING_H
#define BOARD_BYTE_RING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define BYTE_RING_CAPACITY 256u /* >= one Modbus RTU ADU; power of two, <= 32768 */

typedef struct {
    volatile uint16_t head; /* written by the producer */
    volatile uint16_t tail; /* written by the consumer */
    uint8_t data[BYTE_RING_CAPACITY];
} byte_ring;

void byte_ring_init(byte_ring *ring);
size_t byte_ring_used(const byte_ring *ring);
/* Producer: false when full (the byte is dropped, the caller counts it). */
bool byte_ring_put(byte_ring *ring, uint8_t byte);
/* Producer: as many of len bytes as fit; returns how many. */
size_t byte_ring_write(byte_ring *ring, const uint8_t *src, size_t len);
/* Consumer: false when empty. */
bool byte_ring_get(byte_ring *ring, uint8_t *byte);
/* Consumer: up to max_len bytes; returns how many. */
size_t byte_ring_read(byte_ring *ring, uint8_t *dst, size_t max_len);

#endif
