/*
 * leveler-plant-server: the plant model served as a Modbus TCP analog-input
 * module, so leveler-rig can run unchanged, closed loop, without hardware.
 *
 *   leveler-plant-server --config host_sim/configs/thesis-900lb.ini
 *       [--address 127.0.0.1] [--port 0] [--port-file F] [--clock lockstep|realtime]
 *       [--max-seconds S] [--schedule FILE]
 *
 * Module map (0-based):
 *   input registers 0..3   ADC counts of height, P2, P1, P3 (plant_sensor_counts, 12-bit)
 *   input register  4      load, N (rounded, the scenario's load: a load cell)
 *   input registers 16,17  module clock, ms (uint32, high word first)
 *   holding register 0     lockstep: writing N advances the plant N ms (multiple
 *                          of 10) before the reply; ignored with --clock realtime
 *   coils 0..3             compressor, spring valve, vent valve, accumulator valve
 *   holding register 2     communication watchdog, ms (0 = off; output_watchdog.h)
 *   input register  5      watchdog trips
 *
 * The plant steps on the simulator's one stepper (host_sim/sim/stepper.h) with
 * the coils as its commands: the first tick runs under the config's
 * [initial] actuators (the coils start as them) and the module clock starts
 * at 10 ms (the rig was running when the controller took over; leveler-sim
 * does the same). Load: the config's [scenario] by the stepper's one rule.
 * --clock realtime advances 10 ms
 * per 10 ms of CLOCK_MONOTONIC. The process ends on SIGINT/SIGTERM, or after
 * --max-seconds of wall time (a guard for tests).
 * Exit status: 0 done, 1 the server could not start, 2 bad input (an option, the config).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <modbus.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "output_watchdog.h"
#include "plant.h"
#include "stepper.h"

#define REG_COUNTS 0
#define REG_LOAD_N 4
#define REG_TIME_MS 16
#define REG_STEP 0
#define MAX_CLIENTS 16

static volatile sig_atomic_t stop_requested;
static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

typedef struct {
    const char *config, *address, *port_file, *schedule;
    int port;
    int lockstep;
    double max_seconds;
} server_options;

typedef struct {
    plant_config cfg;
    plant_fx pl; /* with the config's effects */
    plant_rng rng;
    sim_load_step steps[4];
    sim_load_step *file_steps; /* --schedule: loads from a schedule file (its register columns are not served) */
    sim_schedule_cursor cursor;
    sim_stepper st;
    modbus_mapping_t *map;
    modbus_t *ctx;
    int listen_fd;
    int clients[MAX_CLIENTS];
} served_plant;

/* Coils 0..3 in the order of the module map. */
static const hal_output coil_output[4] = {HAL_OUT_COMPRESSOR, HAL_OUT_SPRING_VALVE, HAL_OUT_VENT_VALVE,
                                          HAL_OUT_ACC_VALVE};

/* The stepper's commands: the coils as the controller last wrote them. */
static void coil_commands(sim_stepper *s, void *user, bool out[HAL_OUT_COUNT])
{
    (void)s;
    const uint8_t *bits = ((modbus_mapping_t *)user)->tab_bits;
    memset(out, 0, HAL_OUT_COUNT * sizeof out[0]);
    for (int i = 0; i < 4; i++)
        out[coil_output[i]] = bits[i] != 0;
}

static uint64_t time_ms(const served_plant *sp)
{
    return (uint64_t)sp->st.k * LEVELER_TICK_MS;
}

static void publish(served_plant *sp)
{
    uint16_t counts[4];
    double sensed[4];
    plant_fx_sensed(&sp->pl, sensed);
    plant_counts(&sp->cfg.sensors, sensed, &sp->rng, counts);
    for (int i = 0; i < 4; i++)
        sp->map->tab_input_registers[REG_COUNTS + i] = counts[i];
    /* the load cell reads the load now */
    double load = rint(sim_schedule_load_at(&sp->cursor, (double)time_ms(sp) / 1000.0));
    sp->map->tab_input_registers[REG_LOAD_N] = (uint16_t)(load < 0 ? 0 : load > 65535 ? 65535 : load);
    uint32_t t = (uint32_t)time_ms(sp);
    sp->map->tab_input_registers[REG_TIME_MS] = (uint16_t)(t >> 16);
    sp->map->tab_input_registers[REG_TIME_MS + 1] = (uint16_t)(t & 0xFFFFu);
}

static void advance_one_tick(served_plant *sp)
{
    sim_stepper_decide(&sp->st); /* valves as the controller last set them, load for this step */
    sim_stepper_advance(&sp->st);
}

static double mono_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

enum { OPT_CONFIG = 0x100, OPT_ADDRESS, OPT_PORT, OPT_PORT_FILE, OPT_CLOCK, OPT_MAX_SECONDS, OPT_SCHEDULE };

static const cli_option server_options_list[] = {
    {"config", OPT_CONFIG, "FILE", "the plant, sensors and scenario (the simulator's INI, docs/config-format.md)", 1},
    {"address", OPT_ADDRESS, "A", "listen address (default 127.0.0.1)", 0},
    {"port", OPT_PORT, "P", "TCP port, 0 = any free one (default 0; see --port-file)", 0},
    {"port-file", OPT_PORT_FILE, "F", "write the port it listens on to F (for tests and scripts)", 0},
    {"clock", OPT_CLOCK, "lockstep|realtime",
     "lockstep: the plant advances when the client writes holding register 0\n"
     "(default); realtime: 10 ms per 10 ms of the monotonic clock", 0},
    {"max-seconds", OPT_MAX_SECONDS, "S", "stop after S seconds of wall time (a guard for tests; 0 = never)", 0},
    {"schedule", OPT_SCHEDULE, "FILE", "loads over time (the simulator's schedule CSV) in place of the config's scenario", 0},
    {NULL, 0, NULL, NULL, 0},
};

static const cli_spec server_cli = {
    .prog = "leveler-plant-server",
    .usage = "--config FILE [--address A] [--port P] [--port-file F]\n[--clock lockstep|realtime] [--max-seconds S] [--schedule FILE]",
    .about = "The plant model served as a Modbus TCP analog-input module for leveler-rig (ends on SIGINT/SIGTERM).",
    .opts = server_options_list,
};

static int server_option(void *user, int key, const char *v)
{
    server_options *o = user;
    switch (key) {
    case OPT_CONFIG: o->config = v; return 0;
    case OPT_ADDRESS: o->address = v; return 0;
    case OPT_PORT_FILE: o->port_file = v; return 0;
    case OPT_SCHEDULE: o->schedule = v; return 0;
    case OPT_PORT: return cli_int(&server_cli, "port", v, 0, 65535, &o->port);
    case OPT_MAX_SECONDS: return cli_double(&server_cli, "max-seconds", v, 0.0, 1e9, &o->max_seconds);
    case OPT_CLOCK:
        if (strcmp(v, "lockstep") && strcmp(v, "realtime"))
            return cli_bad_value(&server_cli, "clock", v, "one of lockstep, realtime");
        o->lockstep = !strcmp(v, "lockstep");
        return 0;
    }
    return CLI_EXIT_BAD_INPUT;
}

/* CLI_CONTINUE, or the exit status (0 after --help/--version, 2 after a message). */
static int parse_args(int argc, char **argv, server_options *o)
{
    *o = (server_options){.address = "127.0.0.1", .lockstep = 1};
    return cli_parse(&server_cli, argc, argv, server_option, o, NULL);
}

/* The plant at 10 ms: the first tick ran under the [initial] actuators, which
 * the coils now hold. 0, or the exit status after a message. */
static int start_plant(served_plant *sp, const char *config, const char *schedule)
{
    char err[512];
    if (plant_config_load(config, &sp->cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-plant-server: %s\n", err);
        return 2;
    }
    sp->map = modbus_mapping_new(8, 0, 8, 32);
    if (sp->map == NULL) {
        fprintf(stderr, "leveler-plant-server: %s\n", modbus_strerror(errno));
        return 1;
    }
    if (sim_plant_open(&sp->pl, &sp->cfg, NULL, 0, NULL, NULL) != 0) {
        fprintf(stderr, "leveler-plant-server: %s: the config's effects cannot run\n", config);
        return 2;
    }
    plant_rng_seed(&sp->rng, sp->cfg.sensors.noise_seed);
    double end_s;
    sp->cursor = (sim_schedule_cursor){sp->steps, sim_schedule_from_config(&sp->cfg, sp->steps, &end_s), 0};
    size_t count = 0;
    if (schedule && sim_schedule_load(schedule, &sp->file_steps, &count, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-plant-server: --schedule %s\n", err);
        return 2;
    }
    if (schedule)
        sp->cursor = (sim_schedule_cursor){sp->file_steps, count, 0}; /* the last load holds past its end */
    sp->st = (sim_stepper){.cfg = &sp->cfg, .plant = &sp->pl, .ops = &sim_fx_plant,
                           .commands = coil_commands, .commands_user = sp->map,
                           .load = sim_load_from_schedule, .load_user = &sp->cursor, .initial_outputs = true};
    sim_stepper_start(&sp->st);
    sim_stepper_decide(&sp->st);
    for (int i = 0; i < 4; i++)
        sp->map->tab_bits[i] = sp->st.out[coil_output[i]];
    sim_stepper_advance(&sp->st);
    publish(sp);
    return 0;
}

/* Listen (and write the port file). 0, or the exit status after a message. */
static int open_server(served_plant *sp, const server_options *o)
{
    sp->ctx = modbus_new_tcp(o->address, o->port);
    if (sp->ctx == NULL) {
        fprintf(stderr, "leveler-plant-server: %s\n", modbus_strerror(errno));
        return 1;
    }
    sp->listen_fd = modbus_tcp_listen(sp->ctx, MAX_CLIENTS);
    if (sp->listen_fd < 0) {
        fprintf(stderr, "leveler-plant-server: cannot listen on %s:%d: %s\n", o->address, o->port,
                modbus_strerror(errno));
        return 1;
    }
    for (int i = 0; i < MAX_CLIENTS; i++)
        sp->clients[i] = -1;
    struct sockaddr_in sa;
    socklen_t slen = sizeof sa;
    getsockname(sp->listen_fd, (struct sockaddr *)&sa, &slen);
    if (o->port_file) {
        char tmp[1024];
        snprintf(tmp, sizeof tmp, "%s.tmp", o->port_file);
        FILE *f = fopen(tmp, "w");
        if (f == NULL || fprintf(f, "%u\n", ntohs(sa.sin_port)) < 0 || fclose(f) != 0 ||
            rename(tmp, o->port_file) != 0) {
            fprintf(stderr, "leveler-plant-server: --port-file %s: %s\n", o->port_file, strerror(errno));
            return 1;
        }
    }
    struct sigaction act;
    memset(&act, 0, sizeof act);
    act.sa_handler = on_signal;
    sigaction(SIGINT, &act, NULL);
    sigaction(SIGTERM, &act, NULL);
    signal(SIGPIPE, SIG_IGN);
    return 0;
}

static void accept_client(served_plant *sp)
{
    int fd = accept(sp->listen_fd, NULL, NULL);
    if (fd < 0)
        return;
    for (int i = 0; i < MAX_CLIENTS; i++)
        if (sp->clients[i] < 0) {
            sp->clients[i] = fd;
            return;
        }
    close(fd);
}

/* One request of client i: lockstep steps, then the reply from the fresh map. */
static void serve_client(served_plant *sp, int i, int lockstep)
{
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    const int header = modbus_get_header_length(sp->ctx);
    modbus_set_socket(sp->ctx, sp->clients[i]);
    int len = modbus_receive(sp->ctx, query);
    if (len == 0)
        return;
    int function = len > 0 ? query[header] : -1;
    if (function == MODBUS_FC_WRITE_SINGLE_REGISTER && lockstep &&
        ((query[header + 1] << 8) | query[header + 2]) == REG_STEP) {
        int step_ms = (query[header + 3] << 8) | query[header + 4];
        for (int k = 0; k < step_ms / (int)LEVELER_TICK_MS; k++)
            advance_one_tick(sp);
    }
    if (len > 0)
        publish(sp);
    if (len < 0 || modbus_reply(sp->ctx, query, len, sp->map) < 0) {
        close(sp->clients[i]);
        sp->clients[i] = -1;
        return;
    }
    output_watchdog_after_request(sp->map, query, header);
    if (function == MODBUS_FC_WRITE_SINGLE_COIL || function == MODBUS_FC_WRITE_MULTIPLE_COILS)
        sim_stepper_decide(&sp->st); /* a real-time plant sees the valves at once */
}

/* Wait for requests (and, in real time, for the next tick) at most until the next tick. */
static void serve(served_plant *sp, const server_options *o)
{
    const double started = mono_s();
    const double tick_s = LEVELER_TICK_MS / 1000.0;
    double next_tick = started + tick_s;
    while (!stop_requested) {
        double now = mono_s();
        if (o->max_seconds > 0 && now - started > o->max_seconds) {
            fprintf(stderr, "leveler-plant-server: --max-seconds %g reached\n", o->max_seconds);
            return;
        }
        if (!o->lockstep) {
            for (; now >= next_tick; next_tick += tick_s)
                advance_one_tick(sp);
            publish(sp);
        }
        fd_set rd;
        FD_ZERO(&rd);
        FD_SET(sp->listen_fd, &rd);
        int maxfd = sp->listen_fd;
        for (int i = 0; i < MAX_CLIENTS; i++)
            if (sp->clients[i] >= 0) {
                FD_SET(sp->clients[i], &rd);
                maxfd = sp->clients[i] > maxfd ? sp->clients[i] : maxfd;
            }
        if (output_watchdog_check(sp->map, 4))
            sim_stepper_decide(&sp->st); /* the module drove its outputs safe by itself */
        double wait_s = o->lockstep ? 0.1 : fmax(0.0, next_tick - mono_s());
        int wd_left_ms = output_watchdog_ms_left(sp->map);
        if (wd_left_ms >= 0 && wait_s > wd_left_ms / 1000.0)
            wait_s = wd_left_ms / 1000.0;
        struct timeval tv = {.tv_sec = (time_t)wait_s,
                             .tv_usec = (suseconds_t)((wait_s - (double)(time_t)wait_s) * 1e6)};
        if (select(maxfd + 1, &rd, NULL, NULL, &tv) <= 0)
            continue;
        if (FD_ISSET(sp->listen_fd, &rd))
            accept_client(sp);
        for (int i = 0; i < MAX_CLIENTS; i++)
            if (sp->clients[i] >= 0 && FD_ISSET(sp->clients[i], &rd))
                serve_client(sp, i, o->lockstep);
    }
}

static void close_server(served_plant *sp)
{
    free(sp->file_steps);
    for (int i = 0; i < MAX_CLIENTS; i++)
        if (sp->clients[i] >= 0)
            close(sp->clients[i]);
    if (sp->listen_fd >= 0)
        close(sp->listen_fd);
    if (sp->ctx)
        modbus_free(sp->ctx);
    if (sp->map)
        modbus_mapping_free(sp->map);
}

int main(int argc, char **argv)
{
    server_options o;
    static served_plant sp;
    sp.listen_fd = -1;
    int rc = parse_args(argc, argv, &o);
    if (rc != CLI_CONTINUE)
        return rc;
    rc = start_plant(&sp, o.config, o.schedule);
    if (rc == 0)
        rc = open_server(&sp, &o);
    if (rc == 0)
        serve(&sp, &o);
    close_server(&sp);
    return rc;
}
