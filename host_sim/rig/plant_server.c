/*
 * leveler-plant-server: the plant model served as a Modbus TCP analog-input
 * module, so leveler-rig can run unchanged, closed loop, without hardware.
 *
 *   leveler-plant-server --config host_sim/configs/thesis-900lb.ini
 *       [--address 127.0.0.1] [--port 0] [--port-file F] [--clock lockstep|realtime]
 *       [--max-seconds S]
 *
 * Module map (0-based):
 *   input registers 0..3   ADC counts of height, P2, P1, P3 (plant_sensor_counts, 12-bit)
 *   input register  4      load, N (rounded, the scenario's load: a load cell)
 *   input registers 16,17  module clock, ms (uint32, high word first)
 *   holding register 0     lockstep: writing N advances the plant N ms (multiple
 *                          of 10) before the reply; ignored with --clock realtime
 *   coils 0..3             compressor, spring valve, vent valve, accumulator valve
 *
 * Start: the coils hold the config's [initial] actuators and the module clock
 * starts at 10 ms, the first tick already run under them (the rig was running
 * when the controller took over; leveler-sim does the same).
 *
 * Load schedule: the config's [scenario]; the load in force over each 10 ms
 * step is the one at the start of that step. --clock realtime advances 10 ms
 * per 10 ms of CLOCK_MONOTONIC. The process ends on SIGINT/SIGTERM, or after
 * --max-seconds of wall time (a guard for tests).
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

#include "plant.h"

#define REG_COUNTS 0
#define REG_LOAD_N 4
#define REG_TIME_MS 16
#define REG_STEP 0
#define TICK_MS 10
#define MAX_CLIENTS 16

static volatile sig_atomic_t stop_requested;
static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

typedef struct {
    plant_config cfg;
    plant pl;
    plant_rng rng;
    uint64_t time_ms;
    modbus_mapping_t *map;
} served_plant;

/* The scenario load over the interval starting at t_s; half a tick of slack
 * against rounding, as leveler-sim does. */
static double load_at(const plant_config *c, double t_s)
{
    double t = t_s + 0.5 * TICK_MS / 1000.0;
    return c->base_load_n + ((t >= c->step_on_s && t < c->step_off_s) ? c->step_load_n : 0.0);
}

static void read_coils(served_plant *sp)
{
    plant_inputs in = {
        .compressor = sp->map->tab_bits[0] != 0,
        .spring_valve = sp->map->tab_bits[1] != 0,
        .vent_valve = sp->map->tab_bits[2] != 0,
        .acc_valve = sp->map->tab_bits[3] != 0,
        .load_n = load_at(&sp->cfg, sp->time_ms / 1000.0),
    };
    plant_set_inputs(&sp->pl, &in);
}

static void publish(served_plant *sp)
{
    uint16_t counts[4];
    plant_sensor_counts(&sp->pl, &sp->cfg.sensors, &sp->rng, counts);
    for (int i = 0; i < 4; i++)
        sp->map->tab_input_registers[REG_COUNTS + i] = counts[i];
    double load = rint(load_at(&sp->cfg, sp->time_ms / 1000.0)); /* the load cell reads the load now */
    sp->map->tab_input_registers[REG_LOAD_N] = (uint16_t)(load < 0 ? 0 : load > 65535 ? 65535 : load);
    uint32_t t = (uint32_t)sp->time_ms;
    sp->map->tab_input_registers[REG_TIME_MS] = (uint16_t)(t >> 16);
    sp->map->tab_input_registers[REG_TIME_MS + 1] = (uint16_t)(t & 0xFFFFu);
}

static void advance_one_tick(served_plant *sp)
{
    read_coils(sp); /* valves as the controller last set them, load for this step */
    plant_advance(&sp->pl, TICK_MS / 1000.0, sp->cfg.substeps_per_tick);
    sp->time_ms += TICK_MS;
}

static double mono_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    const char *config = NULL, *address = "127.0.0.1", *port_file = NULL;
    int port = 0, lockstep = 1;
    double max_seconds = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--config") && i + 1 < argc)
            config = argv[++i];
        else if (!strcmp(argv[i], "--address") && i + 1 < argc)
            address = argv[++i];
        else if (!strcmp(argv[i], "--port") && i + 1 < argc)
            port = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--port-file") && i + 1 < argc)
            port_file = argv[++i];
        else if (!strcmp(argv[i], "--clock") && i + 1 < argc) {
            const char *c = argv[++i];
            if (strcmp(c, "lockstep") && strcmp(c, "realtime")) {
                fprintf(stderr, "leveler-plant-server: --clock: '%s' is not one of lockstep, realtime\n", c);
                return 2;
            }
            lockstep = !strcmp(c, "lockstep");
        } else if (!strcmp(argv[i], "--max-seconds") && i + 1 < argc)
            max_seconds = atof(argv[++i]);
        else {
            fprintf(stderr, "usage: leveler-plant-server --config FILE [--address A] [--port P] [--port-file F]"
                            " [--clock lockstep|realtime] [--max-seconds S]\n");
            return 2;
        }
    }
    if (config == NULL || port < 0 || port > 65535) {
        fprintf(stderr, "leveler-plant-server: --config FILE is required (and --port 0..65535)\n");
        return 2;
    }

    static served_plant sp;
    char err[512];
    if (plant_config_load(config, &sp.cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-plant-server: %s\n", err);
        return 2;
    }
    plant_init(&sp.pl, &sp.cfg.plant);
    plant_rng_seed(&sp.rng, sp.cfg.sensors.noise_seed);
    sp.map = modbus_mapping_new(8, 0, 8, 32);
    modbus_t *ctx = modbus_new_tcp(address, port);
    if (sp.map == NULL || ctx == NULL) {
        fprintf(stderr, "leveler-plant-server: %s\n", modbus_strerror(errno));
        return 1;
    }
    /* The rig is already running when the controller takes over: the coils
     * start as the config's [initial] actuators and the first tick runs under
     * them, so the controller's first scan is at 10 ms (as leveler-sim). */
    sp.map->tab_bits[0] = (uint8_t)sp.cfg.init_compressor;
    sp.map->tab_bits[1] = (uint8_t)sp.cfg.init_spring_valve;
    sp.map->tab_bits[2] = (uint8_t)sp.cfg.init_vent_valve;
    sp.map->tab_bits[3] = (uint8_t)sp.cfg.init_acc_valve;
    advance_one_tick(&sp);
    publish(&sp);

    int listen_fd = modbus_tcp_listen(ctx, MAX_CLIENTS);
    if (listen_fd < 0) {
        fprintf(stderr, "leveler-plant-server: cannot listen on %s:%d: %s\n", address, port, modbus_strerror(errno));
        return 1;
    }
    struct sockaddr_in sa;
    socklen_t slen = sizeof sa;
    getsockname(listen_fd, (struct sockaddr *)&sa, &slen);
    if (port_file) {
        char tmp[1024];
        snprintf(tmp, sizeof tmp, "%s.tmp", port_file);
        FILE *f = fopen(tmp, "w");
        if (f == NULL || fprintf(f, "%u\n", ntohs(sa.sin_port)) < 0 || fclose(f) != 0 || rename(tmp, port_file) != 0) {
            fprintf(stderr, "leveler-plant-server: --port-file %s: %s\n", port_file, strerror(errno));
            return 1;
        }
    }

    struct sigaction act;
    memset(&act, 0, sizeof act);
    act.sa_handler = on_signal;
    sigaction(SIGINT, &act, NULL);
    sigaction(SIGTERM, &act, NULL);
    signal(SIGPIPE, SIG_IGN);

    int clients[MAX_CLIENTS];
    for (int i = 0; i < MAX_CLIENTS; i++)
        clients[i] = -1;
    const double started = mono_s();
    double next_tick = started + TICK_MS / 1000.0;
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    const int header = modbus_get_header_length(ctx);

    while (!stop_requested) {
        double now = mono_s();
        if (max_seconds > 0 && now - started > max_seconds) {
            fprintf(stderr, "leveler-plant-server: --max-seconds %g reached\n", max_seconds);
            break;
        }
        if (!lockstep) {
            while (now >= next_tick) {
                advance_one_tick(&sp);
                next_tick += TICK_MS / 1000.0;
            }
            publish(&sp);
        }
        fd_set rd;
        FD_ZERO(&rd);
        FD_SET(listen_fd, &rd);
        int maxfd = listen_fd;
        for (int i = 0; i < MAX_CLIENTS; i++)
            if (clients[i] >= 0) {
                FD_SET(clients[i], &rd);
                maxfd = clients[i] > maxfd ? clients[i] : maxfd;
            }
        double wait_s = lockstep ? 0.1 : next_tick - mono_s();
        if (wait_s < 0)
            wait_s = 0;
        struct timeval tv = {.tv_sec = (time_t)wait_s, .tv_usec = (suseconds_t)((wait_s - (double)(time_t)wait_s) * 1e6)};
        int ready = select(maxfd + 1, &rd, NULL, NULL, &tv);
        if (ready <= 0)
            continue;
        if (FD_ISSET(listen_fd, &rd)) {
            int fd = accept(listen_fd, NULL, NULL);
            int slot = -1;
            for (int i = 0; i < MAX_CLIENTS && fd >= 0; i++)
                if (clients[i] < 0) {
                    slot = i;
                    break;
                }
            if (slot >= 0)
                clients[slot] = fd;
            else if (fd >= 0)
                close(fd);
        }
        for (int i = 0; i < MAX_CLIENTS; i++) {
            if (clients[i] < 0 || !FD_ISSET(clients[i], &rd))
                continue;
            modbus_set_socket(ctx, clients[i]);
            int len = modbus_receive(ctx, query);
            if (len < 0) {
                close(clients[i]);
                clients[i] = -1;
                continue;
            }
            if (len == 0)
                continue;
            int function = query[header];
            int addr = (query[header + 1] << 8) | query[header + 2];
            if (function == MODBUS_FC_WRITE_SINGLE_REGISTER && addr == REG_STEP && lockstep) {
                int step_ms = (query[header + 3] << 8) | query[header + 4];
                for (int k = 0; k < step_ms / TICK_MS; k++)
                    advance_one_tick(&sp);
            }
            publish(&sp);
            if (modbus_reply(ctx, query, len, sp.map) < 0) {
                close(clients[i]);
                clients[i] = -1;
                continue;
            }
            if (function == MODBUS_FC_WRITE_SINGLE_COIL || function == MODBUS_FC_WRITE_MULTIPLE_COILS)
                read_coils(&sp); /* a real-time plant sees the valves at once */
        }
    }
    for (int i = 0; i < MAX_CLIENTS; i++)
        if (clients[i] >= 0)
            close(clients[i]);
    close(listen_fd);
    modbus_free(ctx);
    modbus_mapping_free(sp.map);
    return 0;
}
