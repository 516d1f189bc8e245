#include "rtu_harness.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_stream.h"
#include "leveler/app.h"
#include "leveler/modbus_rtu.h"
#include "leveler/settings.h"

#define HARNESS_MAX_INPUT 600u /* longer inputs add nothing: frames stop at 256 */
#define STREAM_START_MS 0xFFFFFFF0u /* the millisecond counter wraps mid-stream */
#define WORST_GAP_MS 40u /* 3.5 characters at 1200 baud = 33 ms */

#define REQUIRE(cond)                                                                      \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "%s:%d: invariant failed: %s\n", __FILE__, __LINE__, #cond);  \
            abort();                                                                       \
        }                                                                                  \
    } while (0)

uint16_t rtu_test_crc16(const uint8_t *data, size_t len)
{
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < len; i++) {
        crc = (uint16_t)(crc ^ data[i]);
        for (int k = 0; k < 8; k++) {
            const bool lsb = (crc & 1u) != 0;
            crc = (uint16_t)(crc >> 1);
            if (lsb) {
                crc = (uint16_t)(crc ^ 0xA001u);
            }
        }
    }
    return crc;
}

size_t rtu_test_frame(uint8_t *body, size_t len)
{
    const uint16_t crc = rtu_test_crc16(body, len);
    body[len] = (uint8_t)(crc & 0xFFu);
    body[len + 1] = (uint8_t)(crc >> 8);
    return len + 2;
}

static bool crc_ok(const uint8_t *adu, size_t len)
{
    return len >= 4 && rtu_test_crc16(adu, len - 2) == (uint16_t)(adu[len - 2] | (adu[len - 1] << 8));
}

static void require_settings_valid(void)
{
    const leveler_settings *s = leveler_settings_current();
    REQUIRE(leveler_settings_check(s) == 0);
    REQUIRE(s->modbus_address >= 1 && s->modbus_address <= 247);
}

static void check_one(const uint8_t *req, size_t req_len, size_t cap)
{
    static uint8_t resp[LEVELER_RTU_MAX_ADU];
    REQUIRE(cap <= sizeof resp);
    const leveler_settings before = *leveler_settings_current();
    const uint32_t generation_before = leveler_settings_generation();

    const size_t n = leveler_modbus_rtu_handle(req, req_len, cap > 0 ? resp : NULL, cap);

    require_settings_valid();
    const bool unchanged = leveler_settings_generation() == generation_before &&
                           memcmp(&before, leveler_settings_current(), sizeof before) == 0;
    REQUIRE(n <= cap);
    const bool for_us = req_len >= 4 && req_len <= LEVELER_RTU_MAX_ADU && crc_ok(req, req_len) &&
                        (req[0] == 0 || req[0] == before.modbus_address);
    if (!for_us) {
        REQUIRE(n == 0);
        REQUIRE(unchanged);
        return;
    }
    const uint8_t fc = req[1];
    if (fc >= 1 && fc <= 4) {
        REQUIRE(unchanged); /* reads never change settings */
    }
    if (req[0] == 0) {
        REQUIRE(n == 0); /* broadcasts are never answered */
        return;
    }
    if (n == 0) {
        /* only silence when not even an exception fits, or for codes 0 and
         * 0x80, which have no exception code in 0x81..0xFF */
        REQUIRE(cap < 5 || (fc & 0x7Fu) == 0);
        REQUIRE(unchanged);
        return;
    }
    REQUIRE(n >= 5);
    REQUIRE(crc_ok(resp, n));
    REQUIRE(resp[0] == req[0]);
    if ((resp[1] & 0x80u) != 0) {
        /* exception reply (a function code >= 0x80 can only get one) */
        REQUIRE(resp[1] == (uint8_t)(fc | 0x80u));
        REQUIRE(resp[1] >= 0x81u);
        REQUIRE(n == 5);
        REQUIRE(resp[2] >= 1 && resp[2] <= 4);
        REQUIRE(unchanged); /* a refused request changes nothing */
        return;
    }
    REQUIRE(resp[1] == fc);
    switch (fc) {
    case 1: case 2: case 3: case 4:
        REQUIRE(resp[2] == n - 5); /* byte count */
        break;
    case 5: case 6:
        REQUIRE(n == req_len && memcmp(resp, req, n - 2) == 0); /* echo */
        break;
    case 15: case 16:
        REQUIRE(n == 8 && memcmp(resp, req, 6) == 0);
        break;
    default:
        REQUIRE(!"a normal reply to a function the slave does not serve");
    }
}

static void poll_for(uint32_t ms)
{
    for (uint32_t i = 0; i < ms; i++) {
        hal_stream.now_ms++;
        leveler_modbus_rtu_poll();
    }
}

static void stream_twice(const uint8_t *framed, size_t len, bool overstate)
{
    const size_t rx_chunk = 1u + len % 9u;
    hal_stream_reset(STREAM_START_MS, rx_chunk, 8u, overstate);
    leveler_modbus_rtu_init();
    for (int copy = 0; copy < 2; copy++) {
        hal_stream_feed(framed, len);
        /* one poll per ms: the gap (>= 2 ms) cannot pass while bytes flow */
        while (hal_stream.rx_left > 0) {
            poll_for(1);
        }
        /* wait for the first reply to start; the second copy then arrives while
         * a long reply is still going out (a request over our own reply) */
        for (uint32_t ms = 0; ms < WORST_GAP_MS && hal_stream.tx_len == 0; ms++) {
            poll_for(1);
        }
    }
    poll_for(2u * WORST_GAP_MS); /* close the last frame, drain the last reply */
    require_settings_valid();
    REQUIRE(hal_stream.tx_len <= 2u * LEVELER_RTU_MAX_ADU + 2u);
    if (hal_stream.tx_len > 0 && !overstate) {
        REQUIRE(hal_stream.tx[0] == framed[0]);
    }
}

void rtu_harness_run(const uint8_t *data, size_t size)
{
    static uint8_t framed[HARNESS_MAX_INPUT + 2];
    if (size > HARNESS_MAX_INPUT) {
        size = HARNESS_MAX_INPUT;
    }
    hal_stream_reset(0, 64, 64, false);
    leveler_app_init();
    leveler_modbus_rtu_init();
    require_settings_valid();
    if (size == 0) {
        REQUIRE(leveler_modbus_rtu_handle(NULL, 0, NULL, 0) == 0);
        return;
    }
    check_one(data, size, LEVELER_RTU_MAX_ADU);

    memcpy(framed, data, size);
    const size_t framed_len = rtu_test_frame(framed, size);
    check_one(framed, framed_len, LEVELER_RTU_MAX_ADU);
    check_one(framed, framed_len, data[size - 1] % 12u);

    stream_twice(framed, framed_len, (data[0] & 0x80u) != 0);
}
