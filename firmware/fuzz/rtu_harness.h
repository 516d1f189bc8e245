/* One input of the frame-parser harness, shared by the libFuzzer target and
 * the plain corpus replay. Aborts (with a message naming the invariant) when
 * the firmware misbehaves. */
#ifndef LEVELER_TEST_RTU_HARNESS_H
#define LEVELER_TEST_RTU_HARNESS_H

#include <stddef.h>
#include <stdint.h>

/* Reference CRC-16/MODBUS of the test side, written from the serial-line
 * specification (appendix B) independently of the firmware's. */
uint16_t rtu_test_crc16(const uint8_t *data, size_t len);

/* Append the CRC (low byte first) to body[0..len); body needs len + 2 bytes. */
size_t rtu_test_frame(uint8_t *body, size_t len);

/*
 * Run one input: data is an ADU without its CRC (address, function code, data).
 *  1. leveler_modbus_rtu_handle() on the bytes as they are (mostly a bad CRC);
 *  2. on the bytes with their CRC appended, with a full response buffer;
 *  3. again with a small response buffer (last byte % 12 bytes, NULL when 0);
 *  4. the framed bytes twice through leveler_modbus_rtu_poll() on the scripted
 *     HAL (chunked reads, 8-byte writes, a millisecond clock that wraps).
 * After each step: settings still valid, a refused or ignored request changed
 * no setting, every reply well formed.
 */
void rtu_harness_run(const uint8_t *data, size_t size);

#endif
