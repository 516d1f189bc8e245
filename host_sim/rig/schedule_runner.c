/*
 * leveler-schedule-run: plays a schedule file (the one leveler-sim --schedule
 * runs; docs/config-format.md) on a rig over Modbus TCP, as a SCADA would.
 *
 *   leveler-schedule-run --schedule FILE --host ADDR --port N [--unit ID] [--warn-s S]
 *
 * The rig's own clock is the time base: t = 0 is the rig's uptime_ms when the
 * runner starts, so a lockstep rig (tests) and a real-time one are played
 * alike. At each row's time the register columns (mode, manual_compressor,
 * manual_spring_valve, manual_vent_valve, manual_acc_valve) are written through
 * the rig's Modbus TCP server: the manual requests first (consecutive coils
 * in one FC 15), then the mode (FC 06); the rig validates each request
 * all-or-nothing and a refusal ends the run. The load is weights on a real rig: the runner tells the operator
 * when to change it (--warn-s seconds ahead, then at the time), it does not
 * write it.
 *
 * Each row's writes are printed with the rig time read just after them:
 *   "t 5.000 s (rig 12.345 s): wrote manual_compressor = 1 manual_spring_valve = 0 mode = 2"
 * At the end, and on SIGINT/SIGTERM, the manual requests are written 0 and
 * the mode the rig had at the start is written back (auto when it was in
 * manual). Exit status: 0 done, 2 usage or schedule error, 1 Modbus error or
 * refusal, 130 interrupted (the rig restored).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <modbus.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "stepper.h"

#define LB_N 4.4482216152605

static volatile sig_atomic_t stop_requested;
static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

typedef struct {
    const char *schedule, *host;
    int port, unit;
    double warn_s;
} runner_args;

enum { OPT_SCHEDULE = 0x100, OPT_HOST, OPT_PORT, OPT_UNIT, OPT_WARN_S };

static const cli_option runner_options[] = {
    {"schedule", OPT_SCHEDULE, "FILE", "the schedule (CSV t_s,load_n[,mode,manual_*]; docs/config-format.md)", 1},
    {"host", OPT_HOST, "ADDR", "the rig's Modbus TCP server address (default 127.0.0.1)", 0},
    {"port", OPT_PORT, "N", "its Modbus TCP port (default 502)", 0},
    {"unit", OPT_UNIT, "ID", "Modbus unit id 0..247 (default 1)", 0},
    {"warn-s", OPT_WARN_S, "S", "tell the operator S seconds before a load change (default 5)", 0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec runner_cli = {
    .prog = "leveler-schedule-run",
    .usage = "--schedule FILE --host ADDR --port N [--unit ID] [--warn-s S]",
    .about = "Plays a schedule file's mode and manual rows on a rig over Modbus TCP, as a SCADA would.",
    .opts = runner_options,
    .exit_extra = "130 interrupted (the rig restored)",
};

static int runner_option(void *user, int key, const char *v)
{
    runner_args *a = user;
    switch (key) {
    case OPT_SCHEDULE: a->schedule = v; return 0;
    case OPT_HOST: a->host = v; return 0;
    case OPT_PORT: return cli_int(&runner_cli, "port", v, 1, 65535, &a->port);
    case OPT_UNIT: return cli_int(&runner_cli, "unit", v, 0, 247, &a->unit);
    case OPT_WARN_S: return cli_double(&runner_cli, "warn-s", v, 0.0, 1e6, &a->warn_s);
    }
    return CLI_EXIT_BAD_INPUT;
}

/* CLI_CONTINUE, or the exit status (0 after --help/--version, 2 after a message). */
static int parse_args(int argc, char **argv, runner_args *a)
{
    *a = (runner_args){.host = "127.0.0.1", .port = 502, .unit = 1, .warn_s = 5.0};
    return cli_parse(&runner_cli, argc, argv, runner_option, a, NULL);
}

/* The rig's uptime, s; -1 on a Modbus error. */
static double rig_time_s(modbus_t *mb)
{
    uint16_t w[2];
    if (modbus_read_input_registers(mb, LEVELER_IR_UPTIME_MS, 2, w) != 2)
        return -1.0;
    return (double)(((uint32_t)w[0] << 16) | w[1]) / 1000.0;
}

static int write_reg(modbus_t *mb, const sim_schedule_reg *r, uint16_t v)
{
    if (r->table == LEVELER_TABLE_COIL)
        return modbus_write_bit(mb, r->address, v) == 1 ? 0 : -1;
    return modbus_write_register(mb, r->address, v) == 1 ? 0 : -1;
}

static bool written(const sim_load_step *row, int j) { return (row->writes & (1u << j)) != 0; }

/* Writes the registers sim_schedule_write_order[k0..k1): one register (FC 06), or
 * coils at consecutive addresses in one FC 15 request. */
static int write_run(modbus_t *mb, const sim_load_step *row, int k0, int k1)
{
    const sim_schedule_reg *r = &sim_schedule_regs[sim_schedule_write_order[k0]];
    if (r->table != LEVELER_TABLE_COIL)
        return write_reg(mb, r, row->value[sim_schedule_write_order[k0]]);
    uint8_t bits[SIM_SCHEDULE_REG_COUNT];
    for (int k = k0; k < k1; k++)
        bits[k - k0] = (uint8_t)row->value[sim_schedule_write_order[k]];
    return modbus_write_bits(mb, r->address, k1 - k0, bits) == k1 - k0 ? 0 : -1;
}

/* A row's writes in sim_schedule_write_order (the manual requests, then the
 * mode), each run of coils at consecutive addresses in one request; the rig
 * validates each request all-or-nothing. 0 or -1. */
static int play_row(modbus_t *mb, const sim_load_step *row)
{
    char what[256] = "";
    size_t len = 0;
    for (int k = 0; k < SIM_SCHEDULE_REG_COUNT;) {
        if (!written(row, sim_schedule_write_order[k])) {
            k++;
            continue;
        }
        const sim_schedule_reg *r = &sim_schedule_regs[sim_schedule_write_order[k]];
        int k1 = k + 1;
        while (r->table == LEVELER_TABLE_COIL && k1 < SIM_SCHEDULE_REG_COUNT && written(row, sim_schedule_write_order[k1]) &&
               sim_schedule_regs[sim_schedule_write_order[k1]].table == LEVELER_TABLE_COIL &&
               sim_schedule_regs[sim_schedule_write_order[k1]].address == r->address + (unsigned)(k1 - k))
            k1++;
        if (write_run(mb, row, k, k1) != 0) {
            fprintf(stderr, "leveler-schedule-run: row at %g s: the rig refused %s%s%s: %s\n", row->t_s, r->name,
                    k1 - k > 1 ? ".." : "", k1 - k > 1 ? sim_schedule_regs[sim_schedule_write_order[k1 - 1]].name : "",
                    modbus_strerror(errno));
            return -1;
        }
        for (; k < k1; k++) {
            int j = sim_schedule_write_order[k];
            len += (size_t)snprintf(what + len, sizeof what - len, " %s = %u", sim_schedule_regs[j].name,
                                    row->value[j]);
        }
    }
    if (row->writes)
        printf("t %.3f s (rig %.3f s): wrote%s\n", row->t_s, rig_time_s(mb), what);
    fflush(stdout);
    return 0;
}

/* Back to how the rig was: manual requests 0, then the mode read at the start. */
static int restore(modbus_t *mb, uint16_t mode)
{
    int rc = 0;
    for (int j = 1; j < SIM_SCHEDULE_REG_COUNT; j++)
        rc |= write_reg(mb, &sim_schedule_regs[j], 0);
    rc |= write_reg(mb, &sim_schedule_regs[0], mode == LEVELER_HR_MODE_MANUAL ? LEVELER_HR_MODE_AUTO : mode);
    printf("restored: manual requests 0, mode %u%s\n", mode == LEVELER_HR_MODE_MANUAL ? 1u : mode,
           rc ? " (a write failed)" : "");
    fflush(stdout);
    return rc ? -1 : 0;
}

static void tell_load(const sim_load_step *row, const char *when)
{
    printf("LOAD %s: set the load to %.0f N (%.0f lb) at t %.1f s\n", when, row->load_n, row->load_n / LB_N,
           row->t_s);
    fflush(stdout);
}

/* Plays the rows against the rig's clock; 0 done, 1 Modbus error, 130 interrupted. */
static int play(modbus_t *mb, const sim_load_step *rows, size_t n, double warn_s)
{
    double t0 = rig_time_s(mb);
    if (t0 < 0) {
        fprintf(stderr, "leveler-schedule-run: reading uptime_ms: %s\n", modbus_strerror(errno));
        return 1;
    }
    printf("start at rig time %.3f s: %zu rows over %.1f s\n", t0, n, rows[n - 1].t_s);
    tell_load(&rows[0], "now");
    size_t next = 0, warned = 1;
    const struct timespec poll = {0, 2000000}; /* 2 ms */
    while (next < n && !stop_requested) {
        double t = rig_time_s(mb);
        if (t < 0) {
            fprintf(stderr, "leveler-schedule-run: reading uptime_ms: %s\n", modbus_strerror(errno));
            return 1;
        }
        t -= t0;
        while (warned < n && rows[warned].t_s - warn_s <= t) {
            if (rows[warned].load_n != rows[warned - 1].load_n && rows[warned].t_s > t)
                tell_load(&rows[warned], "soon");
            warned++;
        }
        while (next < n && rows[next].t_s <= t) {
            if (next > 0 && rows[next].load_n != rows[next - 1].load_n)
                tell_load(&rows[next], "NOW");
            if (play_row(mb, &rows[next]) != 0)
                return 1;
            next++;
        }
        nanosleep(&poll, NULL);
    }
    return stop_requested ? 130 : 0;
}

int main(int argc, char **argv)
{
    runner_args a;
    int prc = parse_args(argc, argv, &a);
    if (prc != CLI_CONTINUE)
        return prc;
    char err[512];
    sim_load_step *rows = NULL;
    size_t n = 0;
    if (sim_schedule_load(a.schedule, &rows, &n, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-schedule-run: %s\n", err);
        return 2;
    }
    modbus_t *mb = modbus_new_tcp(a.host, a.port);
    if (!mb || modbus_set_slave(mb, a.unit) != 0 || modbus_connect(mb) != 0) {
        fprintf(stderr, "leveler-schedule-run: cannot connect to %s:%d: %s\n", a.host, a.port,
                modbus_strerror(errno));
        if (mb)
            modbus_free(mb);
        free(rows);
        return 1;
    }
    struct sigaction sa = {.sa_handler = on_signal};
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    uint16_t mode = LEVELER_HR_MODE_AUTO;
    if (modbus_read_registers(mb, LEVELER_HR_MODE, 1, &mode) != 1) {
        fprintf(stderr, "leveler-schedule-run: reading mode: %s\n", modbus_strerror(errno));
        modbus_free(mb);
        free(rows);
        return 1;
    }
    int rc = play(mb, rows, n, a.warn_s);
    if (restore(mb, mode) != 0 && rc == 0)
        rc = 1;
    modbus_close(mb);
    modbus_free(mb);
    free(rows);
    return rc;
}
