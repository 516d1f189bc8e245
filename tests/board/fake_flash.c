#include "fake_flash.h"

#include <string.h>

static void fake_read(void *ctx, uint32_t offset, void *out, uint32_t len)
{
    fake_flash *f = ctx;
    memcpy(out, f->mem + offset, len);
}

static bool fake_program(void *ctx, uint32_t offset, const void *data, uint32_t len)
{
    fake_flash *f = ctx;
    const uint8_t *bytes = data;
    if (!f->powered || (offset & 1u) || (len & 1u) || offset + len > sizeof f->mem) {
        return false;
    }
    for (uint32_t i = 0; i < len; i += 2u) {
        uint8_t *cell = f->mem + offset + i;
        if (f->halfwords_until_power_loss == 0) {
            /* Cut mid-programming: some bits of the halfword already went to 0. */
            cell[0] &= (uint8_t)(bytes[i] | 0x5Au);
            cell[1] &= (uint8_t)(bytes[i + 1u] | 0xA5u);
            f->powered = false;
            return false;
        }
        if (f->halfwords_until_power_loss > 0) {
            f->halfwords_until_power_loss--;
        }
        if (cell[0] != 0xFFu || cell[1] != 0xFFu) {
            return false; /* PGERR: the halfword was not erased */
        }
        cell[0] = bytes[i];
        cell[1] = bytes[i + 1u];
        if (f->corrupt_next_program) {
            cell[0] ^= 0x01u; /* a weak cell: the driver's read-back would catch it */
        }
        f->halfwords_programmed++;
    }
    if (f->corrupt_next_program) {
        f->corrupt_next_program = false;
        return true; /* the write "succeeded"; only the store's read-back can notice */
    }
    return true;
}

static bool fake_erase(void *ctx, uint32_t page_index)
{
    fake_flash *f = ctx;
    if (!f->powered || page_index > 1u) {
        return false;
    }
    uint8_t *page = f->mem + page_index * FAKE_FLASH_PAGE_BYTES;
    if (f->erases_until_power_loss == 0) {
        memset(page, 0xFF, FAKE_FLASH_PAGE_BYTES / 2u); /* half done */
        for (uint32_t i = FAKE_FLASH_PAGE_BYTES / 2u; i < FAKE_FLASH_PAGE_BYTES; i += 7u) {
            page[i] = 0x3Cu; /* and the rest in an undefined state */
        }
        f->powered = false;
        return false;
    }
    if (f->erases_until_power_loss > 0) {
        f->erases_until_power_loss--;
    }
    memset(page, 0xFF, FAKE_FLASH_PAGE_BYTES);
    f->erase_count[page_index]++;
    return true;
}

void fake_flash_init(fake_flash *f)
{
    memset(f, 0, sizeof *f);
    memset(f->mem, 0xFF, sizeof f->mem);
    f->driver = (flash_store_driver){.ctx = f,
                                     .page_bytes = FAKE_FLASH_PAGE_BYTES,
                                     .read = fake_read,
                                     .program = fake_program,
                                     .erase_page = fake_erase};
    fake_flash_reboot(f);
}

void fake_flash_reboot(fake_flash *f)
{
    f->powered = true;
    f->halfwords_until_power_loss = -1;
    f->erases_until_power_loss = -1;
    f->corrupt_next_program = false;
}
