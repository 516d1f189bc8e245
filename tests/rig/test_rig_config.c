/* leveler-rig configuration: the shipped example parses to what it says, and
 * every error names the file, the line, the [section] key and the range. */
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

static const char *example_path;
static char tmp_path[64];

static int load_text(const char *text, rig_config *cfg, char *err, size_t len)
{
    snprintf(tmp_path, sizeof tmp_path, "/tmp/leveler-rig-config-XXXXXX");
    int fd = mkstemp(tmp_path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    rig_config_defaults(cfg);
    int rc = rig_config_load(tmp_path, cfg, err, len);
    unlink(tmp_path);
    return rc;
}

#define OUTPUTS "[output.compressor]\nline = 1\n[output.spring_valve]\nline = 2\n" \
                "[output.vent_valve]\nline = 3\n[output.acc_valve]\nline = 4\n[log]\nload_n = 4000\n"

static void example_config_parses(void **state)
{
    (void)state;
    rig_config cfg;
    char err[512] = "";
    rig_config_defaults(&cfg);
    int rc = rig_config_load(example_path, &cfg, err, sizeof err);
    if (rc != 0)
        print_error("%s\n", err);
    assert_int_equal(rc, 0);
    assert_int_equal(cfg.clock, RIG_CLOCK_MONOTONIC);
    assert_int_equal(cfg.transport, RIG_TRANSPORT_RTU);
    assert_int_equal(cfg.baud, 115200);
    assert_int_equal(cfg.outputs, RIG_OUTPUTS_GPIOD);
    assert_int_equal(cfg.pin[HAL_OUT_COMPRESSOR].line, 17);
    assert_true(cfg.pin[HAL_OUT_COMPRESSOR].active_low);
    assert_true(cfg.pin[HAL_OUT_STATUS_LED].configured);
    assert_string_equal(cfg.supervision_address, "127.0.0.1");
    assert_true(fabs(cfg.log_load_n - 4003.4) < 1e-9);
    /* 4-20 mA line: raw 2000 -> 0 counts, 10000 -> 4095, midway -> 2048 (rounded) */
    assert_true(cfg.channel[HAL_ADC_HEIGHT].enabled);
    assert_int_equal(cfg.channel[HAL_ADC_HEIGHT].raw_lo, 2000);
    /* Issue 23: the module watchdog is on out of the box. */
    assert_int_equal(cfg.output_watchdog_ms, 200);
    assert_int_equal(cfg.auto_clear_after_s, 10);
    assert_int_equal(cfg.auto_clear_max_per_hour, 6);
}


static void expect_error(const char *text, const char *want)
{
    rig_config cfg;
    char err[512] = "";
    assert_int_equal(load_text(text, &cfg, err, sizeof err), -1);
    char full[600];
    snprintf(full, sizeof full, "%s:%s", tmp_path, want);
    if (strstr(err, want) == NULL || strncmp(err, tmp_path, strlen(tmp_path)) != 0)
        fail_msg("got '%s', want '%s'", err, full);
}

static void errors_name_file_line_key_and_range(void **state)
{
    (void)state;
    expect_error("[sensors]\ntransport = tcp\nbaud = 50\n" OUTPUTS,
                 ":3: [sensors] baud: 50 is out of range (allowed 300..4000000)");
    expect_error("[sensors]\nparity = X\n" OUTPUTS, ":2: [sensors] parity: 'X' is not one of N, E, O");
    expect_error("; comment\n\n[sensor.height]\nregister = 70000\n" OUTPUTS,
                 ":4: [sensor.height] register: 70000 is out of range (allowed 0..65535)");
    expect_error("[sensor.p_spring]\ncounts_hi = 5000\n" OUTPUTS,
                 ":2: [sensor.p_spring] counts_hi = 5000: out of range [0, 4095]");
    expect_error("[sensor.load]\ncounts_lo = 3\n" OUTPUTS,
                 ":2: [sensor.load] counts_lo: unknown key (allowed enabled, table, register, signed, raw_lo, raw_hi, "
                 "load_n_lo, load_n_hi)");
    expect_error(OUTPUTS "[supervision]\nread_only = maybe\n",
                 ":12: [supervision] read_only: 'maybe' is not a boolean");
    expect_error("[rig]\ncolour = blue\n" OUTPUTS, ":2: [rig] colour: unknown key");
    expect_error("[pump]\nspeed = 3\n" OUTPUTS, ":2: [pump] speed: unknown section");
    expect_error("[output.heater]\nline = 3\n" OUTPUTS, ":2: [output.heater] line: unknown output");
    expect_error("[sensors]\ntimeout_ms = 12x\n" OUTPUTS, ":2: [sensors] timeout_ms: '12x' is not an integer");
    expect_error("[rig]\nthis line is not ini\n" OUTPUTS, ":2: syntax error");
}

static void whole_file_checks(void **state)
{
    (void)state;
    expect_error("[output.compressor]\nline = 1\n[log]\nload_n = 1\n", " [output.spring_valve]: missing");
    expect_error("[rig]\nclock = lockstep\n" OUTPUTS, " [rig] clock: lockstep needs [outputs] backend = modbus");
    expect_error("[sensor.height]\nraw_lo = 5\nraw_hi = 5\n" OUTPUTS, " [sensor.height] raw_lo, raw_hi: must differ");
    expect_error("[log]\npath = /tmp/x.csv\n[output.compressor]\nline = 1\n[output.spring_valve]\nline = 2\n"
                 "[output.vent_valve]\nline = 3\n[output.acc_valve]\nline = 4\n",
                 " [log] load_n: required when there is no [sensor.load]");
}

/* Issue 13: addresses, repeated keys and sections, decimal ports, long lines,
 * directories and names. */
static void hardening_errors(void **state)
{
    (void)state;
    expect_error(OUTPUTS "[supervision]\nread_only = true\n\nread_only = false\n",
                 ":14: [supervision] read_only: repeated (first at line 12)");
    expect_error("[sensors]\nport = 502\n[rig]\nname = a\n[sensors]\nslave = 2\n" OUTPUTS,
                 ":5: [sensors]: section repeated (first at line 1)");
    expect_error("[sensors]\nport = 0777\n" OUTPUTS, ":2: [sensors] port: '0777': leading zeros are not allowed");
    expect_error("[sensors]\nport = 0x1F6\n" OUTPUTS, ":2: [sensors] port: '0x1F6' is not an integer");
    expect_error(OUTPUTS "[supervision]\naddress = 0127.0.0.1\n",
                 ":12: [supervision] address: '0127.0.0.1' is not a numeric IPv4 or IPv6 address");
    expect_error(OUTPUTS "[supervision]\naddress = example.org\n", ":12: [supervision] address: 'example.org' is not");
    expect_error(OUTPUTS "[supervision]\nwriters = 127.0.0.1, 10.0.0.01\n",
                 ":12: [supervision] writers: '10.0.0.01' is not a numeric");
    expect_error("[sensors]\nhost = 192.168.001.2\n" OUTPUTS, ":2: [sensors] host: '192.168.001.2' is neither");
    expect_error("[rig]\nname = caf\xc3(\n" OUTPUTS, ":2: [rig] name: not valid UTF-8");
    static char long_text[6000];
    snprintf(long_text, sizeof long_text, "; one\n[rig]\nname = %05000d\n" OUTPUTS, 0);
    expect_error(long_text, ":3: line longer than");
    expect_error("[outputs]\nbackend = modbus\nwatchdog_ms = 200\n" OUTPUTS, " [outputs] watchdog_ms: needs");

    rig_config cfg;
    char err[512];
    rig_config_defaults(&cfg);
    assert_int_equal(rig_config_load("/tmp", &cfg, err, sizeof err), -1);
    assert_non_null(strstr(err, "/tmp: not a regular file (a directory)"));

    /* What resolves: IPv6, localhost = loopback, canonical text, a writers list. */
    assert_int_equal(load_text(OUTPUTS "[supervision]\naddress = localhost\nwriters = ::1, 127.0.0.2\n"
                               "[sensors]\nhost = ::1\nport = 1502\n", &cfg, err, sizeof err), 0);
    assert_string_equal(cfg.supervision_address, "127.0.0.1");
    assert_int_equal(cfg.writer_count, 2);
    assert_string_equal(cfg.writers[0], "::1");
    assert_string_equal(cfg.host, "::1");
    assert_int_equal(cfg.port, 1502);
    assert_int_equal(load_text(OUTPUTS "[supervision]\naddress = 0:0:0:0:0:0:0:1\n", &cfg, err, sizeof err), 0);
    assert_string_equal(cfg.supervision_address, "::1");
    char out[64];
    assert_int_equal(rig_config_parse_address("255.255.255.255", out, sizeof out), 0);
    assert_int_equal(rig_config_parse_address("127.1", out, sizeof out), -1);
}

/* Issue 23: a watchdog no module can honour (it trips between the rig's
 * writes) is refused with file:line; 0 (off) and 100 ms are accepted. */
static void watchdog_bounded(void **state)
{
    (void)state;
    expect_error("[outputs]\nbackend = modbus\nwatchdog_register = 2\nwatchdog_ms = 5\n" OUTPUTS,
                 ":4: [outputs] watchdog_ms: 5 ms is shorter than a module can honour (0 = off, or 100..65535)");
    expect_error("[outputs]\nbackend = modbus\nwatchdog_ms = 10\nwatchdog_register = 2\n" OUTPUTS,
                 ":3: [outputs] watchdog_ms: 10 ms is shorter");
    expect_error("[outputs]\nbackend = modbus\nwatchdog_ms = 99\nwatchdog_register = 2\n" OUTPUTS,
                 ":3: [outputs] watchdog_ms: 99 ms is shorter");
    rig_config cfg;
    char err[512];
    assert_int_equal(load_text("[outputs]\nbackend = modbus\nwatchdog_ms = 100\nwatchdog_register = 2\n" OUTPUTS,
                               &cfg, err, sizeof err), 0);
    assert_int_equal(cfg.output_watchdog_ms, 100);
    assert_int_equal(load_text("[outputs]\nbackend = modbus\nwatchdog_ms = 0\n" OUTPUTS, &cfg, err, sizeof err), 0);
    assert_int_equal(cfg.auto_clear_after_s, 0); /* off unless configured */
    expect_error(OUTPUTS "[faults]\nauto_clear_max_per_hour = 0\n", ":12: [faults] auto_clear_max_per_hour:");
}

/* A [sensor.X] section turns its channel on, the load's too, unless it says
 * enabled = false, wherever in the section that is. */
static void channel_sections_turn_on(void **state)
{
    (void)state;
    rig_config cfg;
    char err[512];
    assert_int_equal(load_text("[sensor.load]\nenabled = false\nregister = 5\n[sensor.p_acc]\nregister = 3\n"
                               "enabled = false\n" OUTPUTS, &cfg, err, sizeof err), 0);
    assert_false(cfg.load.enabled);
    assert_int_equal(cfg.load.address, 5);
    assert_false(cfg.channel[HAL_ADC_P_ACC].enabled);
    assert_int_equal(load_text("[sensor.load]\nregister = 5\n[sensor.p_acc]\nregister = 3\n" OUTPUTS, &cfg, err,
                               sizeof err), 0);
    assert_true(cfg.load.enabled);
    assert_true(cfg.channel[HAL_ADC_P_ACC].enabled);
    assert_int_equal(load_text(OUTPUTS, &cfg, err, sizeof err), 0); /* the defaults: no load, no accumulator */
    assert_false(cfg.load.enabled);
    assert_false(cfg.channel[HAL_ADC_P_ACC].enabled);
    assert_true(cfg.channel[HAL_ADC_HEIGHT].enabled);
}

static void missing_file_is_named(void **state)
{
    (void)state;
    rig_config cfg;
    char err[512];
    rig_config_defaults(&cfg);
    assert_int_equal(rig_config_load("/nonexistent/rig.ini", &cfg, err, sizeof err), -1);
    assert_non_null(strstr(err, "/nonexistent/rig.ini"));
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s boards/linux-rig/rig.ini\n", argv[0]);
        return 2;
    }
    example_path = argv[1];
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(example_config_parses),
        cmocka_unit_test(errors_name_file_line_key_and_range),
        cmocka_unit_test(whole_file_checks),
        cmocka_unit_test(hardening_errors),
        cmocka_unit_test(watchdog_bounded),
        cmocka_unit_test(channel_sections_turn_on),
        cmocka_unit_test(missing_file_is_named),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
