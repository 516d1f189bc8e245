/*
 * Wear-levelled, power-loss-safe store for one fixed-size blob (the board's
 * leveler_settings) in two flash pages.
 *
 * Layout: each page is an array of fixed-size slots; a slot holds one record
 *   magic u32 | sequence u32 | payload_len u16 | format u16 | payload | pad to 4 | crc32 u32
 * (little-endian; CRC-32/zlib over everything before it). The CRC is programmed
 * last, so a record cut short by a power loss never validates.
 *   - load: the valid record (magic, length, format, CRC) with the highest
 *     sequence number wins; none -> FLASH_STORE_EMPTY (caller keeps defaults).
 *   - save: append into the next erased slot of the page holding the newest
 *     record; when that page is full, erase the OTHER page and start it. The page
 *     with the newest valid record is never erased, so a power loss at any point
 *     leaves either the old or the new blob loadable.
 * Erases alternate between the two pages: with 1 KB pages and the 100-byte
 * settings blob (116-byte slot) that is one erase per 8 saves.
 *
 * Flash semantics assumed (STM32F1, PM0075): erased bytes read 0xFF, programming
 * is in 16-bit halfwords and only into erased halfwords, page erase only.
 */
#ifndef BOARD_FLASH_STORE_H
#define BOARD_FLASH_STORE_H

#include <stdbool.h>
#include <stdint.h>

/* The seam to the flash hardware (STM32 driver on the board, RAM fake in tests).
 * Offsets are bytes from the start of the two-page store area. */
typedef struct {
    void *ctx;
    uint32_t page_bytes; /* multiple of 4 */
    void (*read)(void *ctx, uint32_t offset, void *out, uint32_t len);
    /* offset and len even; returns false on a programming/verify error. */
    bool (*program)(void *ctx, uint32_t offset, const void *data, uint32_t len);
    bool (*erase_page)(void *ctx, uint32_t page_index); /* 0 or 1 */
} flash_store_driver;

typedef enum {
    FLASH_STORE_OK = 0,
    FLASH_STORE_EMPTY = 1,      /* no valid record: use defaults */
    FLASH_STORE_FLASH_ERROR = 2, /* erase/program failed; the old record is intact */
    FLASH_STORE_BAD_SIZE = 3    /* payload does not fit a page / bad driver */
} flash_store_status;

#define FLASH_STORE_PAGES 2u
#define FLASH_STORE_MAGIC 0x3153564Cu /* "LVS1" */
#define FLASH_STORE_HEADER_BYTES 12u
#define FLASH_STORE_CRC_BYTES 4u
/* Largest slot: staged on the stack (open and save each use this much). */
#define FLASH_STORE_MAX_SLOT_BYTES 512u

typedef struct {
    const flash_store_driver *driver;
    uint16_t payload_len;
    uint16_t format;          /* caller's layout version; other formats are ignored */
    uint32_t slot_bytes;
    uint32_t slots_per_page;
    bool have_newest;
    uint32_t newest_sequence;
    uint32_t newest_page;
    uint32_t newest_slot;
} flash_store;

/* Scan both pages. payload_len must fit one slot per page. */
flash_store_status flash_store_open(flash_store *store, const flash_store_driver *driver,
                                    uint16_t payload_len, uint16_t format);

/* Copy the newest valid payload out (payload_len bytes). */
flash_store_status flash_store_load(const flash_store *store, void *payload);

/* Append a new record holding payload (payload_len bytes). */
flash_store_status flash_store_save(flash_store *store, const void *payload);

/* Slot size for a payload: header + payload rounded up to 4 + CRC. */
uint32_t flash_store_slot_bytes(uint16_t payload_len);

#endif
