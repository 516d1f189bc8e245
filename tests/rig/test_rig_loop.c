/*
 * leveler-rig, unchanged, closed loop against leveler-plant-server over real
 * Modbus TCP (lockstep: the plant advances 10 ms per rig tick), supervised by
 * libmodbus clients.
 *   argv: leveler-rig leveler-plant-server plant-config.ini steady-plant-config.ini
 */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <arpa/inet.h>
#include <errno.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "rig_harness.h"

#include "leveler/regmap.h"
#include "leveler/regmap_addr.h" /* generated from firmware/regmap/registers.json */

#define IR_HEIGHT_UM LEVELER_IR_HEIGHT_UM
#define IR_CONTROL_STATE LEVELER_IR_CONTROL_STATE
#define IR_LAST_REFUSAL LEVELER_IR_LAST_REFUSAL_REASON
#define IR_UPTIME_MS LEVELER_IR_UPTIME_MS
#define IR_TICK_OVERRUNS LEVELER_IR_TICK_OVERRUNS
#define HR_BAND_LOWER_UM LEVELER_HR_BAND_LOWER_UM
#define HR_BAND_UPPER_UM LEVELER_HR_BAND_UPPER_UM
#define REASON_BAND_ORDER LEVELER_REASON_BAND_ORDER
#define UM_PER_IN 25400

static const char *rig_binary, *plant_binary, *plant_config, *steady_config;

static modbus_t *client(int port)
{
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", port);
    assert_non_null(ctx);
    modbus_set_response_timeout(ctx, 2, 0);
    assert_int_equal(modbus_connect(ctx), 0);
    return ctx;
}

static int32_t read_i32(modbus_t *ctx, int input, int addr)
{
    uint16_t r[2];
    int n = input ? modbus_read_input_registers(ctx, addr, 2, r) : modbus_read_registers(ctx, addr, 2, r);
    assert_int_equal(n, 2);
    return (int32_t)(((uint32_t)r[0] << 16) | r[1]);
}

static void write_band(modbus_t *ctx, int32_t lo_um, int32_t hi_um, int expect_ok)
{
    uint16_t v[4] = {(uint16_t)((uint32_t)lo_um >> 16), (uint16_t)lo_um, (uint16_t)((uint32_t)hi_um >> 16),
                     (uint16_t)hi_um};
    int rc = modbus_write_registers(ctx, HR_BAND_LOWER_UM, 4, v);
    if (expect_ok)
        assert_int_equal(rc, 4);
    else {
        assert_int_equal(rc, -1);
        assert_int_equal(errno, EMBXILVAL); /* exception 03 */
    }
}

/* true once the peer has closed the connection (recv gives 0 or an error). */
static int closed_by_peer(int fd, double timeout_s)
{
    double until = harness_now() + timeout_s;
    char buf[64];
    while (harness_now() < until) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, 50) > 0) {
            ssize_t n = recv(fd, buf, sizeof buf, 0);
            if (n <= 0)
                return 1;
        }
    }
    return 0;
}

static int raw_connect(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(connect(fd, (struct sockaddr *)&a, sizeof a), 0);
    return fd;
}

static void modbus_tcp_server_serves_the_register_map(void **state)
{
    (void)state;
    rig_run run;
    assert_int_equal(harness_start_plant(&run, plant_binary, steady_config, "lockstep", "lockstep",
                                         "[supervision]\nidle_timeout_ms = 3000\n"), 0);
    assert_int_equal(harness_start_rig(&run, rig_binary), 0);

    modbus_t *a = client(run.supervision_port);
    modbus_t *b = client(run.supervision_port); /* two clients at once */

    /* Measurements: the thesis start, 15.65 in, within a few hundredths. */
    harness_sleep_ms(200);
    int32_t h0 = read_i32(a, 1, IR_HEIGHT_UM);
    assert_true(h0 > 14 * UM_PER_IN && h0 < 17 * UM_PER_IN);
    uint32_t up_a = (uint32_t)read_i32(a, 1, IR_UPTIME_MS);
    uint32_t up_b = (uint32_t)read_i32(b, 1, IR_UPTIME_MS);
    assert_true(up_b >= up_a);
    assert_int_equal(read_i32(b, 0, HR_BAND_LOWER_UM), 396240); /* 15.6 in default */

    /* An invalid write (lower edge above the upper) is refused with
     * exception 03 and changes nothing. */
    write_band(a, 17 * UM_PER_IN, 16 * UM_PER_IN, 0);
    assert_int_equal(read_i32(b, 0, HR_BAND_LOWER_UM), 396240);
    assert_int_equal(read_i32(b, 0, HR_BAND_UPPER_UM), 401320);
    uint16_t reason;
    assert_int_equal(modbus_read_input_registers(b, IR_LAST_REFUSAL, 1, &reason), 1);
    assert_int_equal(reason, REASON_BAND_ORDER);

    /* A client that sends garbage is dropped; control and the others go on. */
    int junk = raw_connect(run.supervision_port);
    const char garbage[] = "GET / HTTP/1.0\r\n\r\n";
    assert_int_equal(send(junk, garbage, sizeof garbage - 1, 0), (ssize_t)(sizeof garbage - 1));
    assert_true(closed_by_peer(junk, 3.0));
    close(junk);
    uint32_t up_after = (uint32_t)read_i32(a, 1, IR_UPTIME_MS);
    assert_true(up_after > up_b);

    /* Raise the band to 16.4 .. 16.6 in: the platform follows up into it and
     * the controller reports "in band" (state 0) there. */
    const int32_t lo = (int32_t)(16.4 * UM_PER_IN), hi = (int32_t)(16.6 * UM_PER_IN);
    const int32_t slack = UM_PER_IN / 20; /* 0.05 in: filter and quantisation */
    write_band(a, lo, hi, 1);
    assert_int_equal(read_i32(b, 0, HR_BAND_LOWER_UM), lo);
    int32_t h = 0, highest = 0;
    uint16_t control_state = 99;
    int in_band_ticks = 0;
    double until = harness_now() + 60.0;
    while (harness_now() < until && in_band_ticks < 20) {
        h = read_i32(a, 1, IR_HEIGHT_UM);
        highest = h > highest ? h : highest;
        assert_int_equal(modbus_read_input_registers(b, IR_CONTROL_STATE, 1, &control_state), 1);
        in_band_ticks = (control_state == LEVELER_IR_CONTROL_STATE_IN_BAND && h >= lo - slack && h <= hi + slack) ? in_band_ticks + 1 : 0;
        harness_sleep_ms(20);
    }
    uint32_t up_end = (uint32_t)read_i32(a, 1, IR_UPTIME_MS);
    print_message("platform %.3f in -> %.3f in (highest %.3f in) after %.1f s of plant time\n", h0 / 25400.0,
                  h / 25400.0, highest / 25400.0, (up_end - up_after) / 1000.0);
    assert_true(h0 < lo - UM_PER_IN / 2); /* it really had to move */
    assert_int_equal(in_band_ticks, 20);

    /* An idle client is dropped after the idle timeout (3 s here). */
    int idle = raw_connect(run.supervision_port);
    assert_true(closed_by_peer(idle, 8.0));
    close(idle);

    modbus_close(a);
    modbus_free(a);
    modbus_close(b);
    modbus_free(b);
    harness_stop(&run);
}

static void read_only_refuses_writes(void **state)
{
    (void)state;
    rig_run run;
    assert_int_equal(harness_start_plant(&run, plant_binary, plant_config, "lockstep", "lockstep",
                                         "[supervision]\nread_only = true\n"), 0);
    assert_int_equal(harness_start_rig(&run, rig_binary), 0);
    modbus_t *a = client(run.supervision_port);
    assert_true(read_i32(a, 1, IR_HEIGHT_UM) > 0);
    uint16_t v = 2;
    assert_int_equal(modbus_write_register(a, 0, v), -1);
    assert_int_equal(errno, EMBXILFUN); /* exception 01: no write functions */
    assert_int_equal(modbus_write_bit(a, 0, 1), -1);
    assert_int_equal(errno, EMBXILFUN);
    uint16_t mode;
    assert_int_equal(modbus_read_registers(a, 0, 1, &mode), 1);
    assert_int_equal(mode, 1); /* still auto */
    modbus_close(a);
    modbus_free(a);
    harness_stop(&run);
}

static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    *len = fread(buf, 1, (size_t)n, f);
    buf[*len] = '\0';
    fclose(f);
    return buf;
}

static void sigterm_leaves_outputs_safe_and_log_whole(void **state)
{
    (void)state;
    rig_run run;
    assert_int_equal(harness_start_plant(&run, plant_binary, plant_config, "lockstep", "lockstep", NULL), 0);
    assert_int_equal(harness_start_rig(&run, rig_binary), 0);
    modbus_t *module = client(run.plant_port);

    /* Wait until the controller is charging after the +200 lb step (an output on). */
    uint8_t coils[4] = {0};
    double until = harness_now() + 60.0;
    int any_on = 0;
    while (!any_on && harness_now() < until) {
        assert_int_equal(modbus_read_bits(module, 0, 4, coils), 4);
        any_on = coils[0] | coils[1] | coils[2] | coils[3];
        if (!any_on)
            harness_sleep_ms(5);
    }
    assert_true(any_on);

    assert_int_equal(kill(run.rig_pid, SIGTERM), 0);
    int status = harness_wait(run.rig_pid, 10.0, NULL);
    run.rig_pid = -1;
    assert_int_equal(status, 0); /* finished the tick, closed the log, exit 0 */

    assert_int_equal(modbus_read_bits(module, 0, 4, coils), 4);
    assert_int_equal(coils[0] | coils[1] | coils[2] | coils[3], 0);

    size_t len;
    char *text = slurp(run.log_path, &len);
    assert_non_null(text);
    assert_true(len > 100);
    assert_int_equal(text[len - 1], '\n');
    text[len - 1] = '\0';
    const char *last = strrchr(text, '\n') + 1;
    const char *header = strstr(text, "\nt_s,");
    assert_non_null(header);
    int commas = 0, header_commas = 0;
    for (const char *c = last; *c; c++)
        commas += *c == ',';
    for (const char *c = header + 1; *c && *c != '\n'; c++)
        header_commas += *c == ',';
    assert_int_equal(header_commas, 17); /* format 3: 18 columns */
    assert_int_equal(commas, header_commas); /* the last row is whole */
    free(text);
    modbus_close(module);
    modbus_free(module);
    harness_stop(&run);
}

/* Real time: the rig on CLOCK_MONOTONIC deadlines against a plant advancing
 * with the wall clock. Ticks are 10 ms apart; a process held up for 200 ms
 * counts the missed deadlines in tick_overruns and skips ahead (no burst). */
static void realtime_ticks_and_overruns(void **state)
{
    (void)state;
    rig_run run;
    assert_int_equal(harness_start_plant(&run, plant_binary, steady_config, "realtime", "monotonic", NULL), 0);
    assert_int_equal(harness_start_rig(&run, rig_binary), 0);
    modbus_t *a = client(run.supervision_port);
    harness_sleep_ms(1000);
    uint32_t before = (uint32_t)read_i32(a, 1, IR_TICK_OVERRUNS);
    assert_int_equal(kill(run.rig_pid, SIGSTOP), 0);
    harness_sleep_ms(200);
    assert_int_equal(kill(run.rig_pid, SIGCONT), 0);
    harness_sleep_ms(300);
    uint32_t after = (uint32_t)read_i32(a, 1, IR_TICK_OVERRUNS);
    print_message("tick_overruns %u -> %u across a 200 ms stop\n", before, after);
    assert_true(after - before >= 15 && after - before <= 40);
    modbus_close(a);
    modbus_free(a);

    assert_int_equal(kill(run.rig_pid, SIGTERM), 0);
    assert_int_equal(harness_wait(run.rig_pid, 10.0, NULL), 0);
    run.rig_pid = -1;

    /* The log's rows: 10 ms apart (median), one gap for the stop, no burst after it. */
    FILE *f = fopen(run.log_path, "r");
    assert_non_null(f);
    char line[256];
    double prev = -1, deltas[4096];
    int n = 0, short_gaps = 0;
    while (fgets(line, sizeof line, f) && n < 4096) {
        if (line[0] < '0' || line[0] > '9')
            continue;
        double t = atof(line);
        if (prev >= 0) {
            deltas[n++] = t - prev;
            short_gaps += (t - prev) < 0.005;
        }
        prev = t;
    }
    fclose(f);
    assert_true(n > 100);
    int near_10ms = 0;
    for (int i = 0; i < n; i++)
        near_10ms += deltas[i] > 0.0085 && deltas[i] < 0.0115;
    print_message("%d intervals, %d within 10 +- 1.5 ms, %d under 5 ms\n", n, near_10ms, short_gaps);
    assert_true(near_10ms > n / 2);
    assert_true(short_gaps < n / 10);
    harness_stop(&run);
}

int main(int argc, char **argv)
{
    if (argc != 5) {
        fprintf(stderr, "usage: %s leveler-rig leveler-plant-server plant.ini steady-plant.ini\n", argv[0]);
        return 2;
    }
    rig_binary = argv[1];
    plant_binary = argv[2];
    plant_config = argv[3];
    steady_config = argv[4];
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(modbus_tcp_server_serves_the_register_map),
        cmocka_unit_test(read_only_refuses_writes),
        cmocka_unit_test(sigterm_leaves_outputs_safe_and_log_whole),
        cmocka_unit_test(realtime_ticks_and_overruns),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
