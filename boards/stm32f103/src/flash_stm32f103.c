/*
 * The settings store's flash seam on the STM32F103C8: the last two 1 KB pages
 * (0x0800F800, 0x0800FC00; reserved as SETTINGS in the linker script).
 * Sequences from PM0075 2.3: unlock with KEY1/KEY2, PER+AR+STRT for a page
 * erase, PG + 16-bit writes for programming, wait BSY, check EOP/PGERR/WRPRTERR.
 * The CPU stalls on flash fetches while BSY (erase ~20-40 ms, halfword ~52 us).
 */
#include <string.h>

#include "board.h"
#include "flash_store.h"
#include "stm32f103_regs.h"

extern const uint8_t __settings_start[];

static void flash_unlock(void)
{
    if (FLASH_IF->CR & FLASH_CR_LOCK) {
        FLASH_IF->KEYR = FLASH_KEY1;
        FLASH_IF->KEYR = FLASH_KEY2;
    }
}

static void flash_lock(void) { FLASH_IF->CR |= FLASH_CR_LOCK; }

/* Wait for the operation, then report and clear its status flags. */
static bool flash_wait_ok(void)
{
    while (FLASH_IF->SR & FLASH_SR_BSY) {
    }
    uint32_t sr = FLASH_IF->SR;
    FLASH_IF->SR = FLASH_SR_EOP | FLASH_SR_PGERR | FLASH_SR_WRPRTERR; /* write 1 to clear */
    return (sr & (FLASH_SR_PGERR | FLASH_SR_WRPRTERR)) == 0u;
}

static void store_read(void *ctx, uint32_t offset, void *out, uint32_t len)
{
    (void)ctx;
    memcpy(out, __settings_start + offset, len); /* flash is memory-mapped */
}

static bool store_erase_page(void *ctx, uint32_t page_index)
{
    (void)ctx;
    flash_unlock();
    (void)flash_wait_ok();
    FLASH_IF->CR = FLASH_CR_PER;
    FLASH_IF->AR = (uint32_t)(uintptr_t)__settings_start + page_index * FLASH_PAGE_BYTES;
    FLASH_IF->CR = FLASH_CR_PER | FLASH_CR_STRT;
    bool ok = flash_wait_ok();
    FLASH_IF->CR = 0;
    flash_lock();
    /* Verify: an erased page reads all 0xFF. */
    const volatile uint32_t *word =
        (const volatile uint32_t *)(uintptr_t)(__settings_start + page_index * FLASH_PAGE_BYTES);
    for (uint32_t i = 0; ok && i < FLASH_PAGE_BYTES / 4u; i++) {
        ok = word[i] == 0xFFFFFFFFu;
    }
    return ok;
}

static bool store_program(void *ctx, uint32_t offset, const void *data, uint32_t len)
{
    (void)ctx;
    if ((offset & 1u) != 0u || (len & 1u) != 0u) {
        return false;
    }
    const uint8_t *bytes = (const uint8_t *)data;
    volatile uint16_t *dst = (volatile uint16_t *)(uintptr_t)(__settings_start + offset);
    bool ok = true;
    flash_unlock();
    (void)flash_wait_ok();
    FLASH_IF->CR = FLASH_CR_PG;
    for (uint32_t i = 0; ok && i < len / 2u; i++) {
        uint16_t halfword = (uint16_t)(bytes[2u * i] | (bytes[2u * i + 1u] << 8)); /* little-endian */
        dst[i] = halfword;
        ok = flash_wait_ok() && dst[i] == halfword;
    }
    FLASH_IF->CR = 0;
    flash_lock();
    return ok;
}

static const flash_store_driver s_driver = {
    .ctx = NULL,
    .page_bytes = FLASH_PAGE_BYTES,
    .read = store_read,
    .program = store_program,
    .erase_page = store_erase_page,
};

const flash_store_driver *board_flash_driver(void) { return &s_driver; }
