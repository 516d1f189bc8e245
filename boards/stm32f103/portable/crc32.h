/*
 * CRC-32 as in IEEE 802.3 / zlib (reflected polynomial 0xEDB88320, initial
 * value and final XOR 0xFFFFFFFF); check value crc32("123456789") = 0xCBF43926.
 * Portable: used by the flash settings store on the board, tested on the host
 * against zlib.
 */
#ifndef BOARD_CRC32_H
#define BOARD_CRC32_H

#include <stddef.h>
#include <stdint.h>

/* Continue a CRC over len more bytes: start with crc = 0 for a fresh CRC;
 * crc32_update(crc32_update(0, a, n), b, m) == CRC of a followed by b. */
uint32_t crc32_update(uint32_t crc, const void *data, size_t len);

#endif
