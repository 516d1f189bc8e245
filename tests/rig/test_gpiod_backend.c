/* The libgpiod output backend at its seam: gpio_gpiod_v1.c against a fake
 * libgpiod that records pin levels. Active-low lines must be driven inverted,
 * every line de-energised from the moment it is requested and again at close. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <string.h>

#include "fake_gpiod_v1.h"
#include "output_backend.h"

static void pin_map(rig_config *cfg)
{
    rig_config_defaults(cfg);
    const struct { const char *chip; unsigned line; bool active_low; } pins[HAL_OUT_COUNT] = {
        {"gpiochip0", 17, false}, {"gpiochip0", 27, true}, {"/dev/gpiochip1", 5, false}, {"1", 6, true},
        {"gpiochip0", 4, false}};
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        cfg->pin[o].configured = true;
        strcpy(cfg->pin[o].chip, pins[o].chip);
        cfg->pin[o].line = pins[o].line;
        cfg->pin[o].active_low = pins[o].active_low;
    }
}

static const int chip_of[HAL_OUT_COUNT] = {0, 0, 1, 1, 0};
static const int line_of[HAL_OUT_COUNT] = {17, 27, 5, 6, 4};

static void safe_at_request_follows_at_apply_safe_at_close(void **state)
{
    (void)state;
    fake_gpiod_reset();
    rig_config cfg;
    pin_map(&cfg);
    rig_output_backend out;
    char err[256];
    assert_int_equal(rig_gpiod_open(&cfg, &out, err, sizeof err), 0);
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        const fake_line *l = fake_gpiod_line(chip_of[o], line_of[o]);
        assert_true(l->requested);
        assert_string_equal(l->consumer, "leveler-rig");
        assert_int_equal(l->active_low, cfg.pin[o].active_low);
        /* de-energised: an active-low pin sits high */
        assert_int_equal(l->physical, cfg.pin[o].active_low ? 1 : 0);
    }

    bool on[HAL_OUT_COUNT] = {true, true, false, true, false};
    assert_int_equal(out.apply(out.impl, on, err, sizeof err), 0);
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        assert_int_equal(fake_gpiod_line(chip_of[o], line_of[o])->physical, on[o] ^ cfg.pin[o].active_low);

    out.close(out.impl);
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        const fake_line *l = fake_gpiod_line(chip_of[o], line_of[o]);
        assert_int_equal(l->physical, cfg.pin[o].active_low ? 1 : 0);
        assert_false(l->requested);
        assert_int_equal(l->released, 1);
    }
    assert_int_equal(fake_gpiod_open_chips(), 0);
}

static void unknown_chip_names_output_and_leaves_nothing_requested(void **state)
{
    (void)state;
    fake_gpiod_reset();
    rig_config cfg;
    pin_map(&cfg);
    strcpy(cfg.pin[HAL_OUT_VENT_VALVE].chip, "gpiochip7");
    rig_output_backend out;
    char err[256] = "";
    assert_int_equal(rig_gpiod_open(&cfg, &out, err, sizeof err), -1);
    assert_non_null(strstr(err, "[output.vent_valve]"));
    assert_non_null(strstr(err, "gpiochip7"));
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        assert_false(fake_gpiod_line(chip_of[o], line_of[o])->requested);
    /* the lines already taken were left de-energised */
    assert_int_equal(fake_gpiod_line(0, 27)->physical, 1);
    assert_int_equal(fake_gpiod_open_chips(), 0);
}

static void busy_line_is_an_error(void **state)
{
    (void)state;
    fake_gpiod_reset();
    rig_config cfg;
    pin_map(&cfg);
    cfg.pin[HAL_OUT_ACC_VALVE].line = 5; /* same as the vent valve on chip 1 */
    strcpy(cfg.pin[HAL_OUT_ACC_VALVE].chip, "gpiochip1");
    rig_output_backend out;
    char err[256] = "";
    assert_int_equal(rig_gpiod_open(&cfg, &out, err, sizeof err), -1);
    assert_non_null(strstr(err, "[output.acc_valve]"));
    assert_int_equal(fake_gpiod_open_chips(), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(safe_at_request_follows_at_apply_safe_at_close),
        cmocka_unit_test(unknown_chip_names_output_and_leaves_nothing_requested),
        cmocka_unit_test(busy_line_is_an_error),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
