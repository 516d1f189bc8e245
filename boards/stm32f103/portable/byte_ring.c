#include "byte_ring.h"

#define RING_MASK (BYTE_RING_CAPACITY - 1u)
_Static_assert((BYTE_RING_CAPACITY & RING_MASK) == 0u, "ring capacity must be a power of two");
_Static_assert(BYTE_RING_CAPACITY <= 32768u, "16-bit counters need capacity <= 2^15");

void byte_ring_init(byte_ring *ring)
{
    ring->head = 0;
    ring->tail = 0;
}

size_t byte_ring_used(const byte_ring *ring)
{
    return (uint16_t)(ring->head - ring->tail);
}

bool byte_ring_put(byte_ring *ring, uint8_t byte)
{
    uint16_t head = ring->head;
    if ((uint16_t)(head - ring->tail) >= BYTE_RING_CAPACITY) {
        return false;
    }
    ring->data[head & RING_MASK] = byte;
    ring->head = (uint16_t)(head + 1u); /* publish after the byte is stored */
    return true;
}

size_t byte_ring_write(byte_ring *ring, const uint8_t *src, size_t len)
{
    size_t n = 0;
    while (n < len && byte_ring_put(ring, src[n])) {
        n++;
    }
    return n;
}

bool byte_ring_get(byte_ring *ring, uint8_t *byte)
{
    uint16_t tail = ring->tail;
    if (ring->head == tail) {
        return false;
    }
    *byte = ring->data[tail & RING_MASK];
    ring->tail = (uint16_t)(tail + 1u);
    return true;
}

size_t byte_ring_read(byte_ring *ring, uint8_t *dst, size_t max_len)
{
    size_t n = 0;
    while (n < max_len && byte_ring_get(ring, &dst[n])) {
        n++;
    }
    return n;
}
