#include "flash_store.h"

#include <string.h>

#include "crc32.h"

static void put_u16_le(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put_u32_le(uint8_t *p, uint32_t v)
{
    put_u16_le(p, (uint16_t)v);
    put_u16_le(p + 2, (uint16_t)(v >> 16));
}
static uint16_t get_u16_le(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t get_u32_le(const uint8_t *p)
{
    return (uint32_t)get_u16_le(p) | ((uint32_t)get_u16_le(p + 2) << 16);
}

uint32_t flash_store_slot_bytes(uint16_t payload_len)
{
    uint32_t padded = ((uint32_t)payload_len + 3u) & ~3u;
    return FLASH_STORE_HEADER_BYTES + padded + FLASH_STORE_CRC_BYTES;
}

static uint32_t slot_offset(const flash_store *s, uint32_t page, uint32_t slot)
{
    return page * s->driver->page_bytes + slot * s->slot_bytes;
}

static bool slot_is_erased(const flash_store *s, const uint8_t *slot)
{
    for (uint32_t i = 0; i < s->slot_bytes; i++) {
        if (slot[i] != 0xFFu) {
            return false;
        }
    }
    return true;
}

/* A slot is valid when magic, length, format and CRC all match. */
static bool slot_is_valid(const flash_store *s, const uint8_t *slot, uint32_t *sequence)
{
    if (get_u32_le(slot) != FLASH_STORE_MAGIC || get_u16_le(slot + 8) != s->payload_len ||
        get_u16_le(slot + 10) != s->format) {
        return false;
    }
    uint32_t crc_at = s->slot_bytes - FLASH_STORE_CRC_BYTES;
    if (crc32_update(0, slot, crc_at) != get_u32_le(slot + crc_at)) {
        return false;
    }
    *sequence = get_u32_le(slot + 4);
    return true;
}

flash_store_status flash_store_open(flash_store *store, const flash_store_driver *driver,
                                    uint16_t payload_len, uint16_t format)
{
    memset(store, 0, sizeof *store);
    if (driver == NULL || driver->page_bytes == 0u || (driver->page_bytes & 3u) != 0u) {
        return FLASH_STORE_BAD_SIZE;
    }
    uint32_t slot_bytes = flash_store_slot_bytes(payload_len);
    if (payload_len == 0u || slot_bytes > FLASH_STORE_MAX_SLOT_BYTES || slot_bytes > driver->page_bytes) {
        return FLASH_STORE_BAD_SIZE; /* store->driver stays NULL: load/save refuse */
    }
    store->driver = driver;
    store->payload_len = payload_len;
    store->format = format;
    store->slot_bytes = slot_bytes;
    store->slots_per_page = driver->page_bytes / store->slot_bytes;

    uint8_t slot[FLASH_STORE_MAX_SLOT_BYTES];
    for (uint32_t page = 0; page < FLASH_STORE_PAGES; page++) {
        for (uint32_t i = 0; i < store->slots_per_page; i++) {
            driver->read(driver->ctx, slot_offset(store, page, i), slot, store->slot_bytes);
            uint32_t sequence;
            if (slot_is_valid(store, slot, &sequence) &&
                (!store->have_newest || sequence > store->newest_sequence)) {
                store->have_newest = true;
                store->newest_sequence = sequence;
                store->newest_page = page;
                store->newest_slot = i;
            }
        }
    }
    return store->have_newest ? FLASH_STORE_OK : FLASH_STORE_EMPTY;
}

flash_store_status flash_store_load(const flash_store *store, void *payload)
{
    if (store->driver == NULL) {
        return FLASH_STORE_BAD_SIZE;
    }
    if (!store->have_newest) {
        return FLASH_STORE_EMPTY;
    }
    store->driver->read(store->driver->ctx,
                        slot_offset(store, store->newest_page, store->newest_slot) +
                            FLASH_STORE_HEADER_BYTES,
                        payload, store->payload_len);
    return FLASH_STORE_OK;
}

/* First fully erased slot of a page after its last used one, or slots_per_page. */
static uint32_t first_free_slot(const flash_store *s, uint32_t page, uint8_t *scratch)
{
    uint32_t free_slot = s->slots_per_page;
    for (uint32_t i = s->slots_per_page; i-- > 0;) {
        s->driver->read(s->driver->ctx, slot_offset(s, page, i), scratch, s->slot_bytes);
        if (!slot_is_erased(s, scratch)) {
            break;
        }
        free_slot = i;
    }
    return free_slot;
}

flash_store_status flash_store_save(flash_store *store, const void *payload)
{
    const flash_store_driver *d = store->driver;
    if (d == NULL) {
        return FLASH_STORE_BAD_SIZE;
    }
    uint8_t record[FLASH_STORE_MAX_SLOT_BYTES];

    /* Where: after the newest record in its page, else start the other page. */
    uint32_t page = store->have_newest ? store->newest_page : 0u;
    uint32_t slot = first_free_slot(store, page, record);
    if (slot >= store->slots_per_page) {
        page = store->have_newest ? 1u - store->newest_page : 0u;
        if (!d->erase_page(d->ctx, page)) {
            return FLASH_STORE_FLASH_ERROR;
        }
        slot = 0;
    }

    /* Wrapping the sequence would make this record look oldest: saturate
     * (2^32 saves is far beyond the flash's endurance anyway). */
    uint32_t sequence = store->have_newest ? store->newest_sequence + 1u : 1u;
    if (sequence == 0u) {
        sequence = UINT32_MAX;
    }
    memset(record, 0xFF, store->slot_bytes);
    put_u32_le(record, FLASH_STORE_MAGIC);
    put_u32_le(record + 4, sequence);
    put_u16_le(record + 8, store->payload_len);
    put_u16_le(record + 10, store->format);
    memcpy(record + FLASH_STORE_HEADER_BYTES, payload, store->payload_len);
    uint32_t crc_at = store->slot_bytes - FLASH_STORE_CRC_BYTES;
    put_u32_le(record + crc_at, crc32_update(0, record, crc_at));

    /* Body first, CRC last: a cut anywhere leaves an invalid record. */
    uint32_t base = slot_offset(store, page, slot);
    if (!d->program(d->ctx, base, record, crc_at) ||
        !d->program(d->ctx, base + crc_at, record + crc_at, FLASH_STORE_CRC_BYTES)) {
        return FLASH_STORE_FLASH_ERROR;
    }
    /* Read back: only a record that validates in flash becomes the newest. */
    uint32_t check_sequence;
    d->read(d->ctx, base, record, store->slot_bytes);
    if (!slot_is_valid(store, record, &check_sequence) || check_sequence != sequence) {
        return FLASH_STORE_FLASH_ERROR;
    }
    store->have_newest = true;
    store->newest_sequence = sequence;
    store->newest_page = page;
    store->newest_slot = slot;
    return FLASH_STORE_OK;
}
