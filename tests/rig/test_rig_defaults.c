/* The rig's defaults come from boards/linux-rig/rig-defaults.ini, compiled in:
 * the built-in text loads (rig_config_defaults aborts otherwise), and every
 * config gives, field by field, the struct it gave when the defaults were
 * written in C (old_c_rig_config_defaults below, the expectation: a copy of
 * the C defaults as they were before rig-defaults.ini, kept only here). */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "rig_config.h"

static char **config_paths; /* the INI files of boards/linux-rig, from the command line */
static int config_count;

/* The expectation: host_sim/rig/rig_config.c's rig_config_defaults() before
 * the defaults moved into rig-defaults.ini. Not to be changed with the INI file. */
static void old_c_rig_config_defaults(rig_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    snprintf(cfg->name, sizeof cfg->name, "rig");
    cfg->clock = RIG_CLOCK_MONOTONIC;
    cfg->lockstep_time_register = 16;
    cfg->lockstep_step_register = 0;
    cfg->transport = RIG_TRANSPORT_RTU;
    snprintf(cfg->device, sizeof cfg->device, "/dev/ttyUSB0");
    cfg->baud = 19200;
    cfg->parity = 'N';
    cfg->data_bits = 8;
    cfg->stop_bits = 1;
    snprintf(cfg->host, sizeof cfg->host, "127.0.0.1");
    cfg->port = 502;
    cfg->slave = 1;
    cfg->timeout_ms = 5;
    for (int c = 0; c < HAL_ADC_COUNT; c++) {
        rig_channel *ch = &cfg->channel[c];
        ch->enabled = c != HAL_ADC_P_ACC; /* the accumulator is optional */
        ch->table = RIG_TABLE_INPUT;
        ch->address = (uint16_t)c;
        ch->raw_lo = 0;
        ch->raw_hi = HAL_ADC_MAX_COUNTS;
        ch->out_lo = 0;
        ch->out_hi = HAL_ADC_MAX_COUNTS;
    }
    cfg->load.enabled = false;
    cfg->load.table = RIG_TABLE_INPUT;
    cfg->load.address = 4;
    cfg->load.raw_lo = 0;
    cfg->load.raw_hi = 1;
    cfg->load.out_lo = 0;
    cfg->load.out_hi = 1;
    cfg->outputs = RIG_OUTPUTS_GPIOD;
    snprintf(cfg->consumer, sizeof cfg->consumer, "leveler-rig");
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        snprintf(cfg->pin[o].chip, sizeof cfg->pin[o].chip, "gpiochip0");
        cfg->pin[o].coil = (uint16_t)o;
    }
    cfg->supervision_enabled = true;
    snprintf(cfg->supervision_address, sizeof cfg->supervision_address, "127.0.0.1");
    cfg->supervision_port = 1502;
    cfg->read_only = false;
    cfg->idle_timeout_ms = 60000;
    cfg->request_timeout_ms = 1000;
    cfg->max_clients = 4;
    cfg->log_rotate_bytes = 0;
    cfg->log_keep_files = 5;
    cfg->log_load_n = NAN;
    snprintf(cfg->mbaps_address, sizeof cfg->mbaps_address, "0.0.0.0");
    cfg->mbaps_port = 802;
    cfg->mbaps_write_role_count = 1;
    snprintf(cfg->mbaps_write_roles[0], sizeof cfg->mbaps_write_roles[0], "Operator");
    cfg->auto_clear_after_s = 0;
    cfg->auto_clear_max_per_hour = 6;
}

/* One field differs: its name, both values (as doubles; text fields compared apart). */
static int differences;
static void differ(const char *what, const char *field, double want, double got)
{
    print_error("%s: %s: want %.17g, got %.17g\n", what, field, want, got);
    differences++;
}
#define SAME_NUM(field)                                                                                             \
    do {                                                                                                            \
        double w_ = (double)want->field, g_ = (double)got->field;                                                   \
        if (!(w_ == g_ || (isnan(w_) && isnan(g_))))                                                                \
            differ(what, #field, w_, g_);                                                                           \
    } while (0)
#define SAME_TEXT(field)                                                                                            \
    do {                                                                                                            \
        if (strcmp(want->field, got->field) != 0) {                                                                 \
            print_error("%s: %s: want '%s', got '%s'\n", what, #field, want->field, got->field);                    \
            differences++;                                                                                          \
        }                                                                                                           \
    } while (0)

static void same_channel(const char *what, const rig_channel *want, const rig_channel *got)
{
    SAME_NUM(enabled);
    SAME_NUM(table);
    SAME_NUM(address);
    SAME_NUM(is_signed);
    SAME_NUM(raw_lo);
    SAME_NUM(raw_hi);
    SAME_NUM(out_lo);
    SAME_NUM(out_hi);
}

static void same_pin(const char *what, const rig_output_pin *want, const rig_output_pin *got)
{
    SAME_NUM(configured);
    SAME_TEXT(chip);
    SAME_NUM(line);
    SAME_NUM(active_low);
    SAME_NUM(coil);
}

static void same_lists(const char *what, const rig_config *want, const rig_config *got)
{
    SAME_NUM(writer_count);
    for (int i = 0; i < RIG_MAX_WRITERS; i++)
        SAME_TEXT(writers[i]);
    SAME_NUM(mbaps_write_role_count);
    for (int i = 0; i < RIG_MAX_WRITERS; i++)
        SAME_TEXT(mbaps_write_roles[i]);
}

/* Every field of rig_config, in its order in rig_config.h. */
static void same_config(const char *what, const rig_config *want, const rig_config *got)
{
    differences = 0;
    SAME_TEXT(name);
    SAME_NUM(clock);
    SAME_NUM(run_seconds);
    SAME_NUM(lockstep_time_register);
    SAME_NUM(lockstep_step_register);
    SAME_NUM(transport);
    SAME_TEXT(device);
    SAME_NUM(baud);
    SAME_NUM(parity);
    SAME_NUM(data_bits);
    SAME_NUM(stop_bits);
    SAME_TEXT(host);
    SAME_NUM(port);
    SAME_NUM(slave);
    SAME_NUM(timeout_ms);
    for (int c = 0; c < HAL_ADC_COUNT; c++)
        same_channel(what, &want->channel[c], &got->channel[c]);
    same_channel(what, &want->load, &got->load);
    SAME_NUM(outputs);
    SAME_TEXT(consumer);
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        same_pin(what, &want->pin[o], &got->pin[o]);
    SAME_NUM(output_watchdog_ms);
    SAME_NUM(output_watchdog_register);
    SAME_NUM(supervision_enabled);
    SAME_TEXT(supervision_address);
    SAME_NUM(supervision_port);
    SAME_TEXT(supervision_port_file);
    SAME_NUM(read_only);
    SAME_NUM(idle_timeout_ms);
    SAME_NUM(request_timeout_ms);
    SAME_NUM(max_clients);
    SAME_TEXT(write_socket);
    SAME_TEXT(mbaps_address);
    SAME_NUM(mbaps_port);
    SAME_TEXT(mbaps_port_file);
    SAME_TEXT(mbaps_cert);
    SAME_TEXT(mbaps_key);
    SAME_TEXT(mbaps_ca);
    SAME_TEXT(mbaps_crl);
    same_lists(what, want, got);
    SAME_TEXT(log_path);
    SAME_NUM(log_rotate_bytes);
    SAME_NUM(log_keep_files);
    SAME_NUM(log_load_n);
    SAME_NUM(auto_clear_after_s);
    SAME_NUM(auto_clear_max_per_hour);
    /* A field added to rig_config.h but not above still shows here (both start from zeroed memory). */
    if (memcmp(want, got, sizeof *want) != 0 && differences == 0)
        fail_msg("%s: the structs differ in a field same_config does not compare", what);
    if (differences)
        fail_msg("%s: %d fields differ from the old C defaults", what, differences);
}

/* path loaded over the old C defaults and over the INI defaults: the same result,
 * the same error (a file that fails, e.g. rig-defaults.ini itself with no outputs), the same struct. */
static void same_load(const char *what, const char *path)
{
    static rig_config want, got;
    char want_err[512] = "", got_err[512] = "";
    old_c_rig_config_defaults(&want);
    int want_rc = rig_config_load(path, &want, want_err, sizeof want_err);
    rig_config_defaults(&got);
    int got_rc = rig_config_load(path, &got, got_err, sizeof got_err);
    assert_int_equal(got_rc, want_rc);
    assert_string_equal(got_err, want_err);
    same_config(what, &want, &got);
}

static void builtin_defaults_load_and_match(void **state)
{
    (void)state;
    static rig_config want, got;
    old_c_rig_config_defaults(&want);
    rig_config_defaults(&got); /* aborts if the built-in text does not load */
    same_config("the defaults alone", &want, &got);
}

static void board_configs_match(void **state)
{
    (void)state;
    assert_true(config_count >= 3); /* rig.ini, rig-loopback.ini, rig-defaults.ini at least */
    for (int i = 0; i < config_count; i++)
        same_load(config_paths[i], config_paths[i]);
}

/* The configs the rig tests write (rig_harness.c, py/rigproc.py, rig_vs_sim.py;
 * test_rig_config.c's outputs with a few keys), with their placeholders filled. */
static const char *const test_configs[] = {
    "[rig]\nname = thesis-900lb\nclock = lockstep\n[sensors]\ntransport = tcp\nhost = 127.0.0.1\nport = 5020\n"
    "timeout_ms = 2000\n[sensor.height]\nregister = 0\n[sensor.p_spring]\nregister = 1\n[sensor.p_pipe]\n"
    "register = 2\n[sensor.p_acc]\nregister = 3\n[sensor.load]\nregister = 4\nraw_lo = 0\nraw_hi = 1\n"
    "load_n_lo = 0\nload_n_hi = 1\n[outputs]\nbackend = modbus\n[output.compressor]\ncoil = 0\n"
    "[output.spring_valve]\ncoil = 1\n[output.vent_valve]\ncoil = 2\n[output.acc_valve]\ncoil = 3\n"
    "[supervision]\naddress = 127.0.0.1\nport = 0\nport_file = /tmp/x/supervision.port\n[log]\npath = /tmp/x/rig.csv\n",
    "[rig]\nrun_seconds = 30\n[sensors]\ntransport = tcp\nport = 5020\n[sensor.load]\nenabled = false\n"
    "[output.compressor]\nline = 1\n[output.spring_valve]\nline = 2\n[output.vent_valve]\nline = 3\n"
    "[output.acc_valve]\nline = 4\n[supervision]\nenabled = false\n[log]\nload_n = 4000\n",
    "[output.compressor]\nline = 1\n[output.spring_valve]\nline = 2\n[output.vent_valve]\nline = 3\n"
    "[output.acc_valve]\nline = 4\n[log]\nload_n = 4000\n[supervision]\naddress = localhost\n"
    "writers = ::1, 127.0.0.2\nidle_timeout_ms = 500\n[mbaps]\nwrite_roles = Operator, Engineer\n",
    "[sensor.p_acc]\nenabled = false\nraw_lo = 2000\n[outputs]\nbackend = modbus\nwatchdog_ms = 200\n"
    "watchdog_register = 2\n[output.compressor]\ncoil = 7\n[output.spring_valve]\nline = 2\n"
    "[output.vent_valve]\nline = 3\n[output.acc_valve]\nline = 4\n[faults]\nauto_clear_after_s = 10\n",
};

static void test_configs_match(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof test_configs / sizeof test_configs[0]; i++) {
        char path[64] = "/tmp/leveler-rig-defaults-XXXXXX";
        int fd = mkstemp(path);
        assert_true(fd >= 0);
        size_t n = strlen(test_configs[i]);
        assert_int_equal(write(fd, test_configs[i], n), (ssize_t)n);
        close(fd);
        char what[32];
        snprintf(what, sizeof what, "test config %zu", i);
        same_load(what, path);
        unlink(path);
    }
}

int main(int argc, char **argv)
{
    config_paths = argv + 1;
    config_count = argc - 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(builtin_defaults_load_and_match),
        cmocka_unit_test(board_configs_match),
        cmocka_unit_test(test_configs_match),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
