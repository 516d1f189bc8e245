/*
 * The board's wear-levelled settings store (boards/stm32f103/portable/flash_store.c)
 * over a RAM fake of two STM32F1 flash pages: round trip, page roll-over and
 * wear, power loss at every halfword and mid-erase, corrupt records, CRC.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "fake_flash.h"
#include "flash_store.h"
#include "leveler/settings.h"

/* The real blob the board stores. */
#define PAYLOAD_LEN ((uint16_t)sizeof(leveler_settings))
#define FORMAT 0x0101u

typedef struct {
    uint8_t bytes[sizeof(leveler_settings)];
} payload;

static payload make_payload(uint32_t seed)
{
    payload p;
    for (size_t i = 0; i < sizeof p.bytes; i++) {
        p.bytes[i] = (uint8_t)(seed * 131u + i * 7u + (seed >> 8));
    }
    return p;
}

static uint32_t slots_per_page(void)
{
    return FAKE_FLASH_PAGE_BYTES / flash_store_slot_bytes(PAYLOAD_LEN);
}

/* Boot: open a fresh store on the fake, as the board does after reset. */
static flash_store_status boot_and_load(fake_flash *f, payload *out)
{
    flash_store store;
    fake_flash_reboot(f);
    flash_store_status st = flash_store_open(&store, &f->driver, PAYLOAD_LEN, FORMAT);
    if (st != FLASH_STORE_OK) {
        return st;
    }
    return flash_store_load(&store, out);
}

static void save_n(fake_flash *f, uint32_t first_seed, uint32_t n)
{
    flash_store store;
    flash_store_status st = flash_store_open(&store, &f->driver, PAYLOAD_LEN, FORMAT);
    assert_true(st == FLASH_STORE_OK || st == FLASH_STORE_EMPTY);
    for (uint32_t i = 0; i < n; i++) {
        payload p = make_payload(first_seed + i);
        assert_int_equal(flash_store_save(&store, &p), FLASH_STORE_OK);
    }
}

static void erased_flash_is_empty(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    payload out;
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_EMPTY);
}

static void saved_blob_survives_reboot(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    save_n(&f, 42, 1);
    payload expect = make_payload(42), out;
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, expect.bytes, sizeof out.bytes);
    /* The settings blob fits several records per 1 KB page (wear levelling works). */
    assert_true(slots_per_page() >= 4u);
}

static void newest_wins_across_page_rollover_and_wear_alternates(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    const uint32_t saves = 10u * 2u * slots_per_page() + 3u;
    for (uint32_t i = 0; i < saves; i++) {
        save_n(&f, 1000u + i, 1); /* reboot between saves: the scan must find the newest */
        payload expect = make_payload(1000u + i), out;
        assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
        assert_memory_equal(out.bytes, expect.bytes, sizeof out.bytes);
    }
    /* One erase per page-full of records, alternating between the two pages.
     * Page 0 starts erased, so the first erase comes when it is full. */
    uint32_t erases = f.erase_count[0] + f.erase_count[1];
    assert_int_equal(erases, (saves - 1u) / slots_per_page());
    assert_true(f.erase_count[0] + 1u >= f.erase_count[1] && f.erase_count[1] + 1u >= f.erase_count[0]);
    /* Every save programs exactly one slot's halfwords. */
    assert_int_equal(f.halfwords_programmed, saves * flash_store_slot_bytes(PAYLOAD_LEN) / 2u);
}

/* Cut the power at every halfword of one save, starting from `already` saved
 * records (1: plain append; slots_per_page: the save must erase the other page).
 * After the reboot the old or the new blob loads, never garbage or nothing;
 * and the store keeps working. */
static void power_loss_at_every_halfword(uint32_t already)
{
    const uint32_t slot_halfwords = flash_store_slot_bytes(PAYLOAD_LEN) / 2u;
    payload old_p = make_payload(already - 1u), new_p = make_payload(777), after = make_payload(888), out;
    for (uint32_t cut = 0; cut <= slot_halfwords; cut++) {
        fake_flash f;
        fake_flash_init(&f);
        save_n(&f, 0, already);

        flash_store store;
        assert_int_equal(flash_store_open(&store, &f.driver, PAYLOAD_LEN, FORMAT), FLASH_STORE_OK);
        f.halfwords_until_power_loss = (int32_t)cut;
        flash_store_status st = flash_store_save(&store, &new_p);
        assert_int_equal(st, cut < slot_halfwords ? FLASH_STORE_FLASH_ERROR : FLASH_STORE_OK);

        assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
        assert_memory_equal(out.bytes, (st == FLASH_STORE_OK ? new_p : old_p).bytes, sizeof out.bytes);

        save_n(&f, 888, 1);
        assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
        assert_memory_equal(out.bytes, after.bytes, sizeof out.bytes);
    }
}

static void power_loss_while_appending(void **state)
{
    (void)state;
    power_loss_at_every_halfword(1);
}

static void power_loss_while_starting_the_other_page(void **state)
{
    (void)state;
    power_loss_at_every_halfword(slots_per_page());
}

static void power_loss_mid_erase_keeps_the_old_blob(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    save_n(&f, 0, 2u * slots_per_page()); /* page 1 full and newest, page 0 full and older */
    payload old_p = make_payload(2u * slots_per_page() - 1u), new_p = make_payload(5), out;

    flash_store store;
    assert_int_equal(flash_store_open(&store, &f.driver, PAYLOAD_LEN, FORMAT), FLASH_STORE_OK);
    f.erases_until_power_loss = 0;
    assert_int_equal(flash_store_save(&store, &new_p), FLASH_STORE_FLASH_ERROR);

    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, old_p.bytes, sizeof out.bytes);
    save_n(&f, 5, 1);
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, new_p.bytes, sizeof out.bytes);
}

/* Offset of slot n of page 0. */
static uint32_t slot_at(uint32_t n) { return n * flash_store_slot_bytes(PAYLOAD_LEN); }

static void corrupt_newest_record_falls_back_to_previous(void **state)
{
    (void)state;
    const uint32_t header = FLASH_STORE_HEADER_BYTES;
    const uint32_t crc_at = flash_store_slot_bytes(PAYLOAD_LEN) - FLASH_STORE_CRC_BYTES;
    const uint32_t spots[] = {0u, 4u, 8u, header, header + PAYLOAD_LEN / 2u, crc_at, crc_at + 3u};
    payload previous = make_payload(1), out;
    for (size_t k = 0; k < sizeof spots / sizeof spots[0]; k++) {
        for (uint8_t bit = 0; bit < 8u; bit++) {
            fake_flash f;
            fake_flash_init(&f);
            save_n(&f, 1, 2); /* slots 0 (seed 1) and 1 (seed 2) */
            f.mem[slot_at(1) + spots[k]] ^= (uint8_t)(1u << bit);
            assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
            assert_memory_equal(out.bytes, previous.bytes, sizeof out.bytes);
        }
    }
}

static void all_records_corrupt_is_empty(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    save_n(&f, 1, 2);
    f.mem[slot_at(0) + FLASH_STORE_HEADER_BYTES] ^= 0x80u;
    f.mem[slot_at(1) + FLASH_STORE_HEADER_BYTES + 1u] ^= 0x01u;
    payload out;
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_EMPTY);
    /* And a save after that still works (appends after the corrupt slots). */
    save_n(&f, 9, 1);
    payload expect = make_payload(9);
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, expect.bytes, sizeof out.bytes);
}

static void records_of_another_layout_are_ignored(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    save_n(&f, 1, 1);
    flash_store store;
    assert_int_equal(flash_store_open(&store, &f.driver, PAYLOAD_LEN, FORMAT + 1u), FLASH_STORE_EMPTY);
    assert_int_equal(flash_store_open(&store, &f.driver, (uint16_t)(PAYLOAD_LEN - 4u), FORMAT),
                     FLASH_STORE_EMPTY);
}

static void failed_verify_keeps_old_blob_and_next_save_uses_next_slot(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    save_n(&f, 1, 1);
    flash_store store;
    assert_int_equal(flash_store_open(&store, &f.driver, PAYLOAD_LEN, FORMAT), FLASH_STORE_OK);
    payload bad = make_payload(2), good = make_payload(3), out;
    f.corrupt_next_program = true;
    assert_int_equal(flash_store_save(&store, &bad), FLASH_STORE_FLASH_ERROR);
    payload old_p = make_payload(1);
    assert_int_equal(flash_store_load(&store, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, old_p.bytes, sizeof out.bytes);
    assert_int_equal(flash_store_save(&store, &good), FLASH_STORE_OK);
    assert_int_equal(boot_and_load(&f, &out), FLASH_STORE_OK);
    assert_memory_equal(out.bytes, good.bytes, sizeof out.bytes);
}

static void payload_that_cannot_fit_is_refused(void **state)
{
    (void)state;
    fake_flash f;
    fake_flash_init(&f);
    flash_store store;
    assert_int_equal(flash_store_open(&store, &f.driver, 0u, FORMAT), FLASH_STORE_BAD_SIZE);
    assert_int_equal(flash_store_open(&store, &f.driver, 1000u, FORMAT), FLASH_STORE_BAD_SIZE); /* > staging buffer */
    assert_int_equal(flash_store_open(&store, &f.driver, 2000u, FORMAT), FLASH_STORE_BAD_SIZE); /* > page */
    payload p = make_payload(1);
    assert_int_equal(flash_store_save(&store, &p), FLASH_STORE_BAD_SIZE);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(erased_flash_is_empty),
        cmocka_unit_test(saved_blob_survives_reboot),
        cmocka_unit_test(newest_wins_across_page_rollover_and_wear_alternates),
        cmocka_unit_test(power_loss_while_appending),
        cmocka_unit_test(power_loss_while_starting_the_other_page),
        cmocka_unit_test(power_loss_mid_erase_keeps_the_old_blob),
        cmocka_unit_test(corrupt_newest_record_falls_back_to_previous),
        cmocka_unit_test(all_records_corrupt_is_empty),
        cmocka_unit_test(records_of_another_layout_are_ignored),
        cmocka_unit_test(failed_verify_keeps_old_blob_and_next_save_uses_next_slot),
        cmocka_unit_test(payload_that_cannot_fit_is_refused),
    };
    return cmocka_run_group_tests_name("board_flash_store", tests, NULL, NULL);
}
