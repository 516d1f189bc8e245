/* The USART's lock-free byte ring: capacity, FIFO order, counter wrap. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "byte_ring.h"

static byte_ring ring;

static void fills_to_capacity_then_refuses(void **state)
{
    (void)state;
    byte_ring_init(&ring);
    for (uint32_t i = 0; i < BYTE_RING_CAPACITY; i++) {
        assert_true(byte_ring_put(&ring, (uint8_t)i));
    }
    assert_int_equal(byte_ring_used(&ring), BYTE_RING_CAPACITY);
    assert_false(byte_ring_put(&ring, 0xAA));
    uint8_t b;
    for (uint32_t i = 0; i < BYTE_RING_CAPACITY; i++) {
        assert_true(byte_ring_get(&ring, &b));
        assert_int_equal(b, (uint8_t)i);
    }
    assert_false(byte_ring_get(&ring, &b));
    assert_int_equal(byte_ring_used(&ring), 0);
}

static void fifo_order_survives_16_bit_counter_wrap(void **state)
{
    (void)state;
    byte_ring_init(&ring);
    /* Push 200 000 bytes through in uneven chunks: head/tail wrap 2^16 three times. */
    uint8_t chunk[97], out[97];
    uint32_t produced = 0, consumed = 0;
    while (consumed < 200000u) {
        for (size_t i = 0; i < sizeof chunk; i++) {
            chunk[i] = (uint8_t)((produced + i) * 13u);
        }
        size_t n = byte_ring_write(&ring, chunk, sizeof chunk);
        produced += (uint32_t)n;
        size_t m = byte_ring_read(&ring, out, 61);
        for (size_t i = 0; i < m; i++) {
            assert_int_equal(out[i], (uint8_t)((consumed + i) * 13u));
        }
        consumed += (uint32_t)m;
        assert_int_equal(byte_ring_used(&ring), produced - consumed);
        assert_true(byte_ring_used(&ring) <= BYTE_RING_CAPACITY);
    }
}

static void partial_write_when_nearly_full(void **state)
{
    (void)state;
    byte_ring_init(&ring);
    uint8_t data[BYTE_RING_CAPACITY];
    for (size_t i = 0; i < sizeof data; i++) {
        data[i] = (uint8_t)i;
    }
    assert_int_equal(byte_ring_write(&ring, data, BYTE_RING_CAPACITY - 10u), BYTE_RING_CAPACITY - 10u);
    assert_int_equal(byte_ring_write(&ring, data, 25), 10);
    uint8_t out[BYTE_RING_CAPACITY];
    assert_int_equal(byte_ring_read(&ring, out, sizeof out), BYTE_RING_CAPACITY);
    assert_int_equal(out[BYTE_RING_CAPACITY - 10u], 0);
    assert_int_equal(out[BYTE_RING_CAPACITY - 1u], 9);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(fills_to_capacity_then_refuses),
        cmocka_unit_test(fifo_order_survives_16_bit_counter_wrap),
        cmocka_unit_test(partial_write_when_nearly_full),
    };
    return cmocka_run_group_tests_name("board_byte_ring", tests, NULL, NULL);
}
