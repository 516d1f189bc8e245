/*
 * leveler-rig: the unchanged firmware on a Linux computer driving a real rig.
 *
 *   leveler-rig --config rig.ini [--check]
 *
 * Exit status: 0 done (stopped by a signal or [rig] run_seconds), 1 the rig could
 * not start or the log could not be closed, 2 bad input (an option, the config).
 *
 * Every 10 ms on absolute deadlines (clock_nanosleep TIMER_ABSTIME on
 * CLOCK_MONOTONIC): scan the Modbus sensor module, leveler_app_tick(), apply
 * the outputs, write a run-log line; the time left before the next deadline
 * serves the Modbus TCP clients. A missed deadline is counted through
 * leveler_app_report_tick_overrun() and the schedule skips ahead.
 *
 * clock = lockstep (tests against leveler-plant-server): no sleeping; after
 * each tick the module is asked to advance 10 ms, and hal_now_ms() is the
 * module's clock. The loop body is the same.
 *
 * SIGINT/SIGTERM set a flag: the tick in progress finishes, outputs go safe,
 * the log is fsync'ed and closed, exit status 0.
 *
 * When the process cannot do that (SIGKILL, a crash, a hang), two watchdogs
 * outside it act: the output module's communication watchdog ([outputs]
 * watchdog_ms, armed at start and again whenever the module reconnects, read
 * back; the module drives its outputs safe when the rig stops writing) and
 * systemd's (WatchdogSec= in the unit: the tick loop sends WATCHDOG=1; a
 * silent rig is killed and restarted, and a start drives every output safe
 * first). Whatever ended the process, the unit's ExecStopPost= runs
 * `leveler-rig --safe-outputs` (GPIO lines have no watchdog of their own).
 *
 * The run log never stops control: a row the disk refuses is dropped whole
 * (log_fault, log_rows_dropped in the register map) and SIGXFSZ is ignored,
 * so a file-size limit is an error return, not a death.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <systemd/sd-daemon.h>

#include "cli.h"
#include "leveler/app.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "leveler/status.h"
#include "auto_clear.h"
#include "output_backend.h"
#include "rig_config.h"
#include "rig_hal.h"
#include "runlog.h"
#include "runlog_firmware.h"
#include "modbus_link.h"
#include "sensor_module.h"
#include "modbus_tcp_server.h"

/* The measurements block of the input registers: height, P2, P1, P3 (int32,
 * high word first) then sensor_fault_bits; one read per logged tick. */
#define REG_MEASUREMENTS LEVELER_IR_HEIGHT_UM
#define REG_MEASUREMENT_COUNT (LEVELER_IR_SENSOR_FAULT_BITS - LEVELER_IR_HEIGHT_UM + 1u)
_Static_assert(LEVELER_IR_P_SPRING_PA == LEVELER_IR_HEIGHT_UM + 2 && LEVELER_IR_P_PIPE_PA == LEVELER_IR_HEIGHT_UM + 4 &&
                   LEVELER_IR_P_ACC_PA == LEVELER_IR_HEIGHT_UM + 6,
               "log_tick() expects height, P2, P1, P3 in consecutive int32 pairs");

#define NS_PER_MS 1000000LL
#define TICK_NS ((long long)LEVELER_TICK_MS * NS_PER_MS)

static volatile sig_atomic_t stop_requested;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static long long ns_of(const struct timespec *t)
{
    return (long long)t->tv_sec * 1000000000LL + t->tv_nsec;
}

static struct timespec ts_of(long long ns)
{
    struct timespec t = {.tv_sec = (time_t)(ns / 1000000000LL), .tv_nsec = (long)(ns % 1000000000LL)};
    return t;
}

static long long mono_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return ns_of(&t);
}

static int32_t reg32(const uint16_t *r)
{
    return (int32_t)(((uint32_t)r[0] << 16) | r[1]);
}

/* Everything the rig holds open. */
typedef struct {
    rig_config cfg;
    const char *config_path;
    rig_link *link;
    rig_sensors *sensors;
    rig_output_backend outputs;
    bool outputs_open;
    rig_modbus_tcp_server *tcp_server;
    runlog *log;
    double last_load_n;
    double last_t_s;           /* time of the last logged row: the log's time must increase */
    bool log_fault_reported;
    uint64_t ticks, overruns;
    long long notify_every_ns; /* systemd watchdog: 0 = not asked for */
    long long next_notify_ns;
    rig_auto_clear auto_clear;
    long long next_output_error_ns; /* stderr during an outage: one line per RIG_SAY_EVERY_NS */
    unsigned output_errors_unsaid;
} rig;

#define RIG_SAY_EVERY_NS (10 * 1000 * NS_PER_MS)

static void log_tick(rig *r, const bool out[HAL_OUT_COUNT])
{
    const rig_config *cfg = &r->cfg;
    uint16_t m[REG_MEASUREMENT_COUNT];
    if (leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, REG_MEASUREMENTS, REG_MEASUREMENT_COUNT, m) != LEVELER_REG_OK)
        return;
    uint16_t faulty = m[LEVELER_IR_SENSOR_FAULT_BITS - REG_MEASUREMENTS];
    double p[3];
    for (int i = 0; i < 3; i++) {
        int ch = HAL_ADC_P_SPRING + i;
        p[i] = (cfg->channel[ch].enabled && !(faulty & (1u << ch))) ? (double)reg32(m + 2 + 2 * i) : NAN;
    }
    double load_n;
    if (cfg->load.enabled) {
        if (rig_sensors_load_n(r->sensors, &load_n))
            r->last_load_n = load_n;
        load_n = r->last_load_n; /* the log needs a load in every row: hold the last good one */
    } else {
        load_n = cfg->log_load_n;
    }
    runlog_row row = runlog_row_empty();
    row.t_s = rig_hal_now_s();
    row.height_m = reg32(m) * 1e-6;
    row.p_spring_pa = p[0];
    row.p_pipe_pa = p[1];
    row.p_acc_pa = p[2];
    row.load_n = load_n;
    row.compressor = out[HAL_OUT_COMPRESSOR];
    row.spring_valve = out[HAL_OUT_SPRING_VALVE];
    row.vent_valve = out[HAL_OUT_VENT_VALVE];
    row.acc_valve = cfg->pin[HAL_OUT_ACC_VALVE].configured ? out[HAL_OUT_ACC_VALVE] : -1;
    runlog_row_firmware_state(&row);
    /* No load yet, or lockstep time that did not advance (a failed step): nothing new to log. */
    if (!isfinite(row.load_n) || row.t_s <= r->last_t_s)
        return;
    r->last_t_s = row.t_s;
    if (runlog_write(r->log, &row) != 0 && !r->log_fault_reported)
        fprintf(stderr, "leveler-rig: run log %s: %s: dropping rows until it can be written (control goes on)\n",
                cfg->log_path, strerror(errno));
    runlog_stats st = runlog_get_stats(r->log);
    if (!st.fault && r->log_fault_reported)
        fprintf(stderr, "leveler-rig: run log %s: writing again after %llu dropped rows\n", cfg->log_path,
                st.rows_dropped);
    r->log_fault_reported = st.fault;
    leveler_app_report_log(st.fault, st.rows_dropped > UINT32_MAX ? UINT32_MAX : (uint32_t)st.rows_dropped);
}

enum { OPT_CONFIG = 0x100, OPT_CHECK, OPT_SAFE_OUTPUTS };

static const cli_option rig_options[] = {
    {"config", OPT_CONFIG, "FILE", "the rig's INI file (boards/linux-rig/rig.ini)", 1},
    {"check", OPT_CHECK, NULL, "parse the config, print the result and exit", 0},
    {"safe-outputs", OPT_SAFE_OUTPUTS, NULL, "drive every output safe (de-energised) and exit: the unit's ExecStopPost=", 0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec rig_cli = {
    .prog = "leveler-rig",
    .usage = "--config FILE [--check | --safe-outputs]",
    .about = "The unchanged firmware on a Linux computer driving a real rig (SIGINT/SIGTERM: outputs safe, exit 0).",
    .opts = rig_options,
};

typedef struct {
    const char *config_path;
    bool check_only;
    bool safe_only;
} rig_args;

static int rig_option(void *user, int key, const char *v)
{
    rig_args *a = user;
    if (key == OPT_CONFIG)
        a->config_path = v;
    else if (key == OPT_CHECK)
        a->check_only = true;
    else
        a->safe_only = true;
    return 0;
}

/* CLI_CONTINUE to run, else the exit status (0 after --help/--version, 2 bad usage). */
static int parse_args(int argc, char **argv, rig_args *a)
{
    *a = (rig_args){0};
    return cli_parse(&rig_cli, argc, argv, rig_option, a, NULL);
}

static void install_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN); /* a vanished client is an error return, not a death */
    signal(SIGXFSZ, SIG_IGN); /* a file-size limit is EFBIG on the log, not a death with the compressor on */
}

/* Written whole then renamed, so a reader never sees half a number. */
static void write_port_file(const rig *r)
{
    char tmp[RIG_TEXT_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", r->cfg.supervision_port_file);
    FILE *f = fopen(tmp, "w");
    if (f == NULL || fprintf(f, "%u\n", rig_modbus_tcp_server_port(r->tcp_server)) < 0 || fclose(f) != 0 ||
        rename(tmp, r->cfg.supervision_port_file) != 0)
        fprintf(stderr, "leveler-rig: [supervision] port_file %s: %s\n", r->cfg.supervision_port_file, strerror(errno));
}

static int open_tcp_server_and_log(rig *r, char *err, size_t err_len)
{
    const rig_config *cfg = &r->cfg;
    if (cfg->supervision_enabled) {
        r->tcp_server = rig_modbus_tcp_server_open(cfg, err, err_len);
        if (r->tcp_server == NULL)
            return -1;
        if (cfg->supervision_port_file[0])
            write_port_file(r);
        fprintf(stderr, "leveler-rig: Modbus TCP server on %s port %u%s\n", cfg->supervision_address,
                rig_modbus_tcp_server_port(r->tcp_server), cfg->read_only ? " (read-only)" : "");
    }
    if (cfg->log_path[0]) {
        runlog_options lo = {.path = cfg->log_path, .config_name = cfg->name, .source = "rig",
                             .rotate_bytes = (size_t)cfg->log_rotate_bytes, .keep_files = cfg->log_keep_files,
                             .keep_previous = 1};
        char lerr[400];
        r->log = runlog_open(&lo, lerr, sizeof lerr);
        if (r->log == NULL) {
            snprintf(err, err_len, "[log] path: %s", lerr);
            return -1;
        }
    }
    return 0;
}

/* The module link, outputs driven safe, the firmware, the Modbus TCP server, the log. 0 or 1 (message printed). */
static int rig_open(rig *r)
{
    char err[512];
    r->last_load_n = NAN;
    r->last_t_s = -1.0;
    r->link = rig_link_open(&r->cfg, err, sizeof err);
    if (r->link != NULL)
        r->sensors = rig_sensors_open(&r->cfg, r->link, err, sizeof err);
    if (r->sensors != NULL) {
        int orc = r->cfg.outputs == RIG_OUTPUTS_GPIOD
                      ? rig_gpiod_open(&r->cfg, &r->outputs, err, sizeof err)
                      : rig_modbus_outputs_open(&r->cfg, r->link, &r->outputs, err, sizeof err);
        r->outputs_open = orc == 0;
    }
    if (r->outputs_open) {
        rig_hal_bind(r->sensors, r->cfg.clock);
        leveler_app_init();
    }
    if (!r->outputs_open || open_tcp_server_and_log(r, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-rig: %s: %s\n", r->config_path, err);
        return 1;
    }
    uint64_t usec = 0;
    if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0)
        r->notify_every_ns = (long long)usec * 1000 / 4; /* well inside WatchdogSec */
    sd_notify(0, "READY=1");
    return 0;
}

static void notify_alive(rig *r)
{
    if (r->notify_every_ns == 0)
        return;
    long long now = mono_ns();
    if (now >= r->next_notify_ns) {
        sd_notify(0, "WATCHDOG=1");
        r->next_notify_ns = now + r->notify_every_ns;
    }
}

/* Unchanged outputs are re-sent once a second, or often enough to feed the
 * output module's watchdog (four times per watchdog time). */
static uint64_t refresh_ticks(const rig_config *cfg)
{
    uint64_t t = 100;
    if (cfg->outputs == RIG_OUTPUTS_MODBUS && cfg->output_watchdog_ms > 0)
        t = cfg->output_watchdog_ms / 4u / LEVELER_TICK_MS;
    return t < 1 ? 1 : t > 100 ? 100 : t;
}

/* Sleeps to the next deadline (serving Modbus TCP clients meanwhile); counts missed ones. */
static void wait_for_tick(rig *r, long long *deadline)
{
    if (r->cfg.clock == RIG_CLOCK_LOCKSTEP) {
        if (r->tcp_server)
            rig_modbus_tcp_server_serve(r->tcp_server, 0);
        if (rig_sensors_step(r->sensors, LEVELER_TICK_MS) != 0) {
            /* The module did not advance: wait a little instead of spinning. */
            struct timespec pause = {0, 2 * NS_PER_MS};
            nanosleep(&pause, NULL);
        }
        return;
    }
    /* Serve Modbus TCP clients until ~1 ms before the deadline, then sleep to it exactly. */
    if (r->tcp_server) {
        long long left_ms = (*deadline - mono_ns()) / NS_PER_MS - 1;
        rig_modbus_tcp_server_serve(r->tcp_server, left_ms > 0 ? (int)left_ms : 0);
    }
    struct timespec when = ts_of(*deadline);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &when, NULL) == EINTR && !stop_requested) {
    }
    *deadline += TICK_NS;
    long long now = mono_ns();
    while (now >= *deadline) { /* this tick's deadline already passed: count and skip it */
        leveler_app_report_tick_overrun();
        r->overruns++;
        *deadline += TICK_NS;
    }
}

/* A failed output write, said at once and then at most every 10 s with the
 * count of those not said: an outage is a few lines, not one per tick. */
static void say_output_error(rig *r, const char *err)
{
    long long now = mono_ns();
    if (now < r->next_output_error_ns) {
        r->output_errors_unsaid++;
        return;
    }
    if (r->output_errors_unsaid > 0)
        fprintf(stderr, "leveler-rig: %s (and %u more failed output writes in the last %lld s)\n", err,
                r->output_errors_unsaid, RIG_SAY_EVERY_NS / 1000 / NS_PER_MS);
    else
        fprintf(stderr, "leveler-rig: %s\n", err);
    r->output_errors_unsaid = 0;
    r->next_output_error_ns = now + RIG_SAY_EVERY_NS;
}

/* [faults] auto-clear of link faults (auto_clear.h), after the tick. */
static void auto_clear_link_faults(rig *r, bool scan_failed)
{
    const leveler_status *st = leveler_app_status();
    uint16_t latched = st->latched_fault_bits;
    switch (rig_auto_clear_step(&r->auto_clear, hal_now_ms(), latched, st->sensors_valid, scan_failed)) {
    case RIG_AUTO_CLEAR_NOW: {
        const uint16_t one = 1; /* the clear_faults coil, as an operator's write */
        (void)leveler_regs_write(LEVELER_TABLE_COIL, LEVELER_COIL_CLEAR_FAULTS, 1, &one, NULL);
        leveler_app_report_link_faults_auto_cleared(r->auto_clear.count);
        fprintf(stderr,
                "leveler-rig: link faults 0x%04x cleared after %u s of valid sensors (auto-clear %u, %u in the last "
                "hour of at most %u)\n",
                latched, r->cfg.auto_clear_after_s, r->auto_clear.count, r->auto_clear.recent,
                r->auto_clear.max_per_hour);
        break;
    }
    case RIG_AUTO_CLEAR_LIMIT:
        fprintf(stderr, "leveler-rig: link faults 0x%04x stay latched: %u auto-clears in the last hour already "
                        "(clear_faults to go on)\n", latched, r->auto_clear.max_per_hour);
        break;
    case RIG_AUTO_CLEAR_NO:
        break;
    }
}

static void rig_loop(rig *r)
{
    bool out[HAL_OUT_COUNT], applied[HAL_OUT_COUNT];
    bool have_applied = false;
    char err[512];
    const uint64_t refresh = refresh_ticks(&r->cfg);
    long long deadline = mono_ns() + TICK_NS;
    rig_auto_clear_init(&r->auto_clear, r->cfg.auto_clear_after_s * 1000u, r->cfg.auto_clear_max_per_hour);
    while (!stop_requested) {
        uint32_t failed_before = rig_sensors_failed_scans(r->sensors);
        rig_sensors_scan(r->sensors);
        bool scan_failed = rig_sensors_failed_scans(r->sensors) != failed_before;
        if (r->cfg.run_seconds > 0 && hal_now_ms() > r->cfg.run_seconds * 1000.0)
            break;
        leveler_app_report_sensor_scans_failed(rig_sensors_failed_scans(r->sensors));
        leveler_app_tick();
        auto_clear_link_faults(r, scan_failed);
        notify_alive(r);
        rig_hal_wanted_outputs(out);
        if (!have_applied || memcmp(out, applied, sizeof out) != 0 || r->ticks % refresh == 0) {
            /* A failed write is tried again next tick. */
            have_applied = r->outputs.apply(r->outputs.impl, out, err, sizeof err) == 0;
            if (!have_applied)
                say_output_error(r, err);
            memcpy(applied, out, sizeof out);
        }
        if (r->log)
            log_tick(r, out);
        r->ticks++;
        wait_for_tick(r, &deadline);
    }
}

/* Outputs safe first, then the log. Returns the exit status. */
static int rig_close(rig *r)
{
    sd_notify(0, "STOPPING=1");
    if (r->outputs_open)
        r->outputs.close(r->outputs.impl);
    int rc = 0;
    runlog_stats ls_log = r->log ? runlog_get_stats(r->log) : (runlog_stats){0, 0, 0};
    if (r->log && runlog_close(r->log) != 0) {
        fprintf(stderr, "leveler-rig: closing run log %s: %s\n", r->cfg.log_path, strerror(errno));
        rc = 1;
    }
    uint32_t failed_scans = r->sensors ? rig_sensors_failed_scans(r->sensors) : 0;
    rig_link_stats ls = r->link ? rig_link_get_stats(r->link) : (rig_link_stats){0};
    rig_modbus_tcp_server_close(r->tcp_server);
    rig_sensors_close(r->sensors);
    rig_link_close(r->link);
    fprintf(stderr,
            "leveler-rig: stopped after %llu ticks, %llu overruns, %u failed sensor scans, %u failed module requests, "
            "%u reconnects, %llu log rows written, %llu dropped\n",
            (unsigned long long)r->ticks, (unsigned long long)r->overruns, failed_scans, ls.failed_requests,
            ls.reconnects, ls_log.rows_written, ls_log.rows_dropped);
    return rc;
}

/* --safe-outputs: after the service's process is gone (ExecStopPost=, also
 * after a SIGKILL, a crash, a watchdog kill or a failed ExecStartPre=), the
 * lines are free: take them, drive every output de-energised, release them.
 * 0 when the outputs were driven safe, 1 otherwise. */
static int safe_outputs(rig *r)
{
    char err[512];
    int rc;
    if (r->cfg.outputs == RIG_OUTPUTS_GPIOD) {
        rc = rig_gpiod_open(&r->cfg, &r->outputs, err, sizeof err); /* requested de-energised */
    } else {
        r->cfg.output_watchdog_ms = 0; /* coils only: nothing is left to feed it */
        r->link = rig_link_open(&r->cfg, err, sizeof err);
        rc = r->link ? rig_modbus_outputs_open(&r->cfg, r->link, &r->outputs, err, sizeof err) : -1;
    }
    if (rc == 0)
        r->outputs.close(r->outputs.impl); /* every output off, then released */
    rig_link_close(r->link);
    if (rc != 0) {
        fprintf(stderr, "leveler-rig: --safe-outputs: %s: %s\n", r->config_path, err);
        return 1;
    }
    fprintf(stderr, "leveler-rig: --safe-outputs: every output driven safe\n");
    return 0;
}

int main(int argc, char **argv)
{
    static rig r;
    rig_args args;
    int prc = parse_args(argc, argv, &args);
    if (prc != CLI_CONTINUE)
        return prc;
    r.config_path = args.config_path;
    char err[512];
    rig_config_defaults(&r.cfg);
    if (rig_config_load(r.config_path, &r.cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-rig: %s\n", err);
        return 2;
    }
    if (args.check_only) {
        printf("%s: ok\n", r.config_path);
        return 0;
    }
    if (args.safe_only)
        return safe_outputs(&r);
    install_signals();
    if (rig_open(&r) != 0) {
        rig_close(&r);
        return 1;
    }
    rig_loop(&r);
    return rig_close(&r);
}
