/* CRC-32 of the flash store against the catalogue check value and zlib. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "crc32.h"
#ifdef BOARD_TEST_HAVE_ZLIB
#include <zlib.h>
#endif

static void check_value_from_the_catalogue(void **state)
{
    (void)state;
    /* CRC-32/ISO-HDLC (zlib, IEEE 802.3): check = 0xCBF43926 (Williams / reveng catalogue). */
    assert_int_equal(crc32_update(0, "123456789", 9), 0xCBF43926u);
    assert_int_equal(crc32_update(0, "", 0), 0u);
}

static void incremental_equals_one_shot(void **state)
{
    (void)state;
    const char *text = "leveler settings record";
    uint32_t whole = crc32_update(0, text, 23);
    for (size_t split = 0; split <= 23; split++) {
        assert_int_equal(crc32_update(crc32_update(0, text, split), text + split, 23 - split), whole);
    }
}

static void matches_zlib_on_random_buffers(void **state)
{
    (void)state;
#ifdef BOARD_TEST_HAVE_ZLIB
    uint8_t buf[600];
    srand(12345);
    for (size_t len = 0; len < sizeof buf; len += 37) {
        for (size_t i = 0; i < len; i++) {
            buf[i] = (uint8_t)rand();
        }
        assert_int_equal(crc32_update(0, buf, len), (uint32_t)crc32(0L, buf, (uInt)len));
    }
#else
    skip(); /* zlib1g-dev not installed: the catalogue check value still runs */
#endif
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(check_value_from_the_catalogue),
        cmocka_unit_test(incremental_equals_one_shot),
        cmocka_unit_test(matches_zlib_on_random_buffers),
    };
    return cmocka_run_group_tests_name("board_crc32", tests, NULL, NULL);
}
