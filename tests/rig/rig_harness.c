#define _POSIX_C_SOURCE 200809L
#include "rig_harness.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

double harness_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void harness_sleep_ms(int ms)
{
    struct timespec t = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

static pid_t spawn(char *const argv[], const char *out_path)
{
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, STDOUT_FILENO);
            dup2(fd, STDERR_FILENO);
            close(fd);
        }
        execv(argv[0], argv);
        _exit(127);
    }
    return pid;
}

static int read_port(const char *path, pid_t pid, double timeout_s)
{
    double until = harness_now() + timeout_s;
    while (harness_now() < until) {
        FILE *f = fopen(path, "r");
        if (f) {
            int port = 0;
            int ok = fscanf(f, "%d", &port);
            fclose(f);
            if (ok == 1 && port > 0)
                return port;
        }
        if (waitpid(pid, NULL, WNOHANG) == pid)
            return -1; /* died before listening */
        harness_sleep_ms(10);
    }
    return -1;
}

/* base + extra, where extra's keys for a section base already has go under
 * that section (a repeated [section] is an error in a rig config). */
static void merge_ini(char *base, size_t cap, const char *extra)
{
    while (extra && *extra) {
        const char *next = strstr(extra + 1, "\n[");
        size_t block_len = next ? (size_t)(next + 1 - extra) : strlen(extra);
        const char *eol = memchr(extra, '\n', block_len);
        size_t head_len = eol ? (size_t)(eol + 1 - extra) : block_len;
        char head[128];
        snprintf(head, sizeof head, "%.*s", (int)head_len, extra);
        char *at = extra[0] == '[' ? strstr(base, head) : NULL;
        size_t used = strlen(base);
        if (at != NULL && used + block_len - head_len < cap) {
            char *insert = at + head_len;
            memmove(insert + block_len - head_len, insert, strlen(insert) + 1);
            memcpy(insert, extra + head_len, block_len - head_len);
        } else if (used + block_len + 1 < cap) {
            snprintf(base + used, cap - used, "%.*s", (int)block_len, extra);
        }
        extra += block_len;
    }
}

int harness_start_plant(rig_run *run, const char *plant_server, const char *plant_config, const char *clock,
                        const char *rig_clock, const char *extra_ini)
{
    memset(run, 0, sizeof *run);
    run->plant_pid = run->rig_pid = -1;
    snprintf(run->dir, sizeof run->dir, "/tmp/leveler-rig-test-XXXXXX");
    if (mkdtemp(run->dir) == NULL)
        return -1;
    char port_file[200], out[200];
    snprintf(port_file, sizeof port_file, "%s/plant.port", run->dir);
    snprintf(out, sizeof out, "%s/plant.out", run->dir);
    char *argv[] = {(char *)plant_server, "--config", (char *)plant_config, "--port", "0", "--port-file", port_file,
                    "--clock", (char *)clock, "--max-seconds", "300", NULL};
    run->plant_pid = spawn(argv, out);
    run->plant_port = read_port(port_file, run->plant_pid, 20.0);
    if (run->plant_port < 0)
        return -1;

    snprintf(run->rig_config, sizeof run->rig_config, "%s/rig.ini", run->dir);
    snprintf(run->log_path, sizeof run->log_path, "%s/rig.csv", run->dir);
    FILE *f = fopen(run->rig_config, "w");
    if (f == NULL)
        return -1;
    char text[4096];
    snprintf(text, sizeof text,
            "[rig]\nname = thesis-900lb\nclock = %s\n"
            "[sensors]\ntransport = tcp\nhost = 127.0.0.1\nport = %d\ntimeout_ms = %d\n"
            "[sensor.height]\nregister = 0\n[sensor.p_spring]\nregister = 1\n[sensor.p_pipe]\nregister = 2\n"
            "[sensor.p_acc]\nregister = 3\n"
            "[sensor.load]\nregister = 4\nraw_lo = 0\nraw_hi = 1\nload_n_lo = 0\nload_n_hi = 1\n"
            "[outputs]\nbackend = modbus\n[output.compressor]\ncoil = 0\n[output.spring_valve]\ncoil = 1\n"
            "[output.vent_valve]\ncoil = 2\n[output.acc_valve]\ncoil = 3\n"
            "[supervision]\naddress = 127.0.0.1\nport = 0\nport_file = %s/supervision.port\n"
            "[log]\npath = %s\n",
            rig_clock, run->plant_port, strcmp(rig_clock, "lockstep") ? 5 : 2000, run->dir, run->log_path);
    merge_ini(text, sizeof text, extra_ini);
    fputs(text, f);
    fclose(f);
    return 0;
}

int harness_start_rig(rig_run *run, const char *rig_binary)
{
    char port_file[200], out[200];
    snprintf(port_file, sizeof port_file, "%s/supervision.port", run->dir);
    snprintf(out, sizeof out, "%s/rig.out", run->dir);
    char *argv[] = {(char *)rig_binary, "--config", run->rig_config, NULL};
    run->rig_pid = spawn(argv, out);
    run->supervision_port = read_port(port_file, run->rig_pid, 20.0);
    return run->supervision_port > 0 ? 0 : -1;
}

int harness_wait(pid_t pid, double timeout_s, int *raw_status)
{
    double until = harness_now() + timeout_s;
    int status = 0;
    while (harness_now() < until) {
        pid_t r = waitpid(pid, &status, WNOHANG);
        if (r == pid) {
            if (raw_status)
                *raw_status = status;
            return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        }
        harness_sleep_ms(10);
    }
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    return -1;
}

void harness_stop(rig_run *run)
{
    if (run->rig_pid > 0) {
        kill(run->rig_pid, SIGTERM);
        harness_wait(run->rig_pid, 10.0, NULL);
        run->rig_pid = -1;
    }
    if (run->plant_pid > 0) {
        kill(run->plant_pid, SIGTERM);
        harness_wait(run->plant_pid, 10.0, NULL);
        run->plant_pid = -1;
    }
    if (getenv("LEVELER_KEEP_TEST_DIRS") == NULL && run->dir[0]) {
        char cmd[200];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", run->dir);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", run->dir);
    }
}
