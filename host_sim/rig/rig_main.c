/*
 * leveler-rig: the unchanged firmware on a Linux computer driving a real rig.
 *
 *   leveler-rig --config rig.ini [--check]
 *
 * Every 10 ms on absolute deadlines (clock_nanosleep TIMER_ABSTIME on
 * CLOCK_MONOTONIC): scan the Modbus sensor module, leveler_app_tick(), apply
 * the outputs, write a run-log line; the time left before the next deadline
 * serves the supervision clients. A missed deadline is counted through
 * leveler_app_report_tick_overrun() and the schedule skips ahead.
 *
 * clock = lockstep (tests against leveler-plant-server): no sleeping; after
 * each tick the module is asked to advance 10 ms, and hal_now_ms() is the
 * module's clock. The loop body is the same.
 *
 * SIGINT/SIGTERM set a flag: the tick in progress finishes, outputs go safe,
 * the log is fsync'ed and closed, exit status 0.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "leveler/app.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"
#include "output_backend.h"
#include "rig_config.h"
#include "rig_hal.h"
#include "runlog.h"
#include "sensor_module.h"
#include "supervision.h"

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

static void log_tick(runlog *log, const rig_config *cfg, rig_sensors *sensors, const bool out[HAL_OUT_COUNT],
                     double *last_load_n)
{
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
        if (rig_sensors_load_n(sensors, &load_n))
            *last_load_n = load_n;
        load_n = *last_load_n; /* the log needs a load in every row: hold the last good one */
    } else {
        load_n = cfg->log_load_n;
    }
    runlog_row row = {
        .t_s = hal_now_ms() / 1000.0,
        .height_m = reg32(m) * 1e-6,
        .p_spring_pa = p[0],
        .p_pipe_pa = p[1],
        .p_acc_pa = p[2],
        .load_n = load_n,
        .compressor = out[HAL_OUT_COMPRESSOR],
        .spring_valve = out[HAL_OUT_SPRING_VALVE],
        .vent_valve = out[HAL_OUT_VENT_VALVE],
        .acc_valve = cfg->pin[HAL_OUT_ACC_VALVE].configured ? out[HAL_OUT_ACC_VALVE] : -1,
    };
    if (isfinite(row.load_n) && runlog_write(log, &row) != 0)
        fprintf(stderr, "leveler-rig: run log %s: %s\n", cfg->log_path, strerror(errno));
}

static void usage(void)
{
    fprintf(stderr, "usage: leveler-rig --config FILE [--check]\n"
                    "  --check   parse the config, print the result and exit\n");
}

int main(int argc, char **argv)
{
    const char *config_path = NULL;
    int check_only = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--config") && i + 1 < argc)
            config_path = argv[++i];
        else if (!strcmp(argv[i], "--check"))
            check_only = 1;
        else {
            usage();
            return 2;
        }
    }
    if (config_path == NULL) {
        usage();
        return 2;
    }

    static rig_config cfg;
    char err[512];
    rig_config_defaults(&cfg);
    if (rig_config_load(config_path, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-rig: %s\n", err);
        return 2;
    }
    if (check_only) {
        printf("%s: ok\n", config_path);
        return 0;
    }

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN); /* a vanished client is an error return, not a death */

    rig_sensors *sensors = rig_sensors_open(&cfg, err, sizeof err);
    if (sensors == NULL) {
        fprintf(stderr, "leveler-rig: %s: %s\n", config_path, err);
        return 1;
    }
    rig_output_backend outputs;
    int orc = cfg.outputs == RIG_OUTPUTS_GPIOD
                  ? rig_gpiod_open(&cfg, &outputs, err, sizeof err)
                  : rig_modbus_outputs_open(&cfg, rig_sensors_modbus(sensors), &outputs, err, sizeof err);
    if (orc != 0) {
        fprintf(stderr, "leveler-rig: %s: %s\n", config_path, err);
        rig_sensors_close(sensors);
        return 1;
    }

    rig_hal_bind(sensors, cfg.clock);
    leveler_app_init();

    rig_supervision *sv = NULL;
    if (cfg.supervision_enabled) {
        sv = rig_supervision_open(&cfg, err, sizeof err);
        if (sv == NULL) {
            fprintf(stderr, "leveler-rig: %s: %s\n", config_path, err);
            outputs.close(outputs.impl);
            rig_sensors_close(sensors);
            return 1;
        }
        if (cfg.supervision_port_file[0]) {
            /* Written whole then renamed, so a reader never sees half a number. */
            char tmp[RIG_TEXT_MAX + 8];
            snprintf(tmp, sizeof tmp, "%s.tmp", cfg.supervision_port_file);
            FILE *f = fopen(tmp, "w");
            if (f == NULL || fprintf(f, "%u\n", rig_supervision_port(sv)) < 0 || fclose(f) != 0 ||
                rename(tmp, cfg.supervision_port_file) != 0)
                fprintf(stderr, "leveler-rig: [supervision] port_file %s: %s\n", cfg.supervision_port_file,
                        strerror(errno));
        }
        fprintf(stderr, "leveler-rig: supervision on %s:%u%s\n", cfg.supervision_address,
                rig_supervision_port(sv), cfg.read_only ? " (read-only)" : "");
    }

    runlog *log = NULL;
    if (cfg.log_path[0]) {
        runlog_options lo = {.path = cfg.log_path, .config_name = cfg.name, .source = "rig",
                             .rotate_bytes = (size_t)cfg.log_rotate_bytes, .keep_files = cfg.log_keep_files};
        log = runlog_open(&lo, err, sizeof err);
        if (log == NULL) {
            fprintf(stderr, "leveler-rig: %s: [log] path: %s\n", config_path, err);
            rig_supervision_close(sv);
            outputs.close(outputs.impl);
            rig_sensors_close(sensors);
            return 1;
        }
    }

    bool out[HAL_OUT_COUNT], applied[HAL_OUT_COUNT];
    bool have_applied = false;
    double last_load_n = NAN;
    uint64_t ticks = 0, overruns = 0;
    const uint64_t refresh_ticks = 100; /* re-send unchanged outputs once a second */
    long long deadline = mono_ns() + TICK_NS;

    while (!stop_requested) {
        rig_sensors_scan(sensors);
        if (cfg.run_seconds > 0 && hal_now_ms() > cfg.run_seconds * 1000.0)
            break;
        leveler_app_tick();
        rig_hal_wanted_outputs(out);
        if (!have_applied || memcmp(out, applied, sizeof out) != 0 || ticks % refresh_ticks == 0) {
            if (outputs.apply(outputs.impl, out, err, sizeof err) != 0)
                fprintf(stderr, "leveler-rig: %s\n", err);
            memcpy(applied, out, sizeof out);
            have_applied = true;
        }
        if (log)
            log_tick(log, &cfg, sensors, out, &last_load_n);
        ticks++;

        if (cfg.clock == RIG_CLOCK_LOCKSTEP) {
            if (sv)
                rig_supervision_serve(sv, 0);
            if (rig_sensors_step(sensors, LEVELER_TICK_MS) != 0) {
                /* The module did not advance: wait a little instead of spinning. */
                struct timespec pause = {0, 2 * NS_PER_MS};
                nanosleep(&pause, NULL);
            }
            continue;
        }

        /* Serve supervision until ~1 ms before the deadline, then sleep to it exactly. */
        if (sv) {
            long long left_ms = (deadline - mono_ns()) / NS_PER_MS - 1;
            rig_supervision_serve(sv, left_ms > 0 ? (int)left_ms : 0);
        }
        struct timespec when = ts_of(deadline);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &when, NULL) == EINTR && !stop_requested) {
        }
        deadline += TICK_NS;
        long long now = mono_ns();
        while (now >= deadline) { /* this tick's deadline already passed: count and skip it */
            leveler_app_report_tick_overrun();
            overruns++;
            deadline += TICK_NS;
        }
    }

    /* Shutdown: outputs safe first, then the log. */
    outputs.close(outputs.impl);
    int rc = 0;
    if (log && runlog_close(log) != 0) {
        fprintf(stderr, "leveler-rig: closing run log %s: %s\n", cfg.log_path, strerror(errno));
        rc = 1;
    }
    uint32_t failed_scans = rig_sensors_failed_scans(sensors);
    rig_supervision_close(sv);
    rig_sensors_close(sensors);
    fprintf(stderr, "leveler-rig: stopped after %llu ticks, %llu overruns, %u failed sensor scans\n",
            (unsigned long long)ticks, (unsigned long long)overruns, failed_scans);
    return rc;
}
