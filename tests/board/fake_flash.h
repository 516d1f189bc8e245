/*
 * RAM-backed stand-in for two STM32F1 flash pages behind flash_store's seam,
 * with the F1 rules that matter: erased = 0xFF, programming only into erased
 * halfwords (else PGERR), and injectable power loss / programming errors.
 */
#ifndef FAKE_FLASH_H
#define FAKE_FLASH_H

#include <stdbool.h>
#include <stdint.h>

#include "flash_store.h"

#define FAKE_FLASH_PAGE_BYTES 1024u

typedef struct {
    uint8_t mem[2u * FAKE_FLASH_PAGE_BYTES];
    bool powered;
    /* Power is lost when programming the halfword after this many more (-1 never). */
    int32_t halfwords_until_power_loss;
    /* Power is lost in the middle of the next erase when 0 (-1 never). */
    int32_t erases_until_power_loss;
    /* Next program call fails verification after writing wrong data (not a power loss). */
    bool corrupt_next_program;
    uint32_t erase_count[2];
    uint32_t halfwords_programmed;
    flash_store_driver driver;
} fake_flash;

/* Fresh, fully erased, powered. */
void fake_flash_init(fake_flash *f);
/* Power back on after a loss: injections cleared, contents kept. */
void fake_flash_reboot(fake_flash *f);

#endif
