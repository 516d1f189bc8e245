/* Test harness: run leveler-plant-server and leveler-rig as child processes
 * on 127.0.0.1 with kernel-chosen ports, with bounded waits everywhere. */
#ifndef LEVELER_RIG_HARNESS_H
#define LEVELER_RIG_HARNESS_H

#include <stdbool.h>
#include <sys/types.h>

typedef struct {
    char dir[128];        /* private temp folder */
    pid_t plant_pid;
    pid_t rig_pid;
    int plant_port;
    int supervision_port;
    char rig_config[256];
    char log_path[256];
} rig_run;

/* Starts the plant server (lockstep or realtime) and writes a rig config
 * (extra_ini appended) that talks to it; does not start the rig yet. */
int harness_start_plant(rig_run *run, const char *plant_server, const char *plant_config, const char *clock,
                        const char *rig_clock, const char *extra_ini);
int harness_start_rig(rig_run *run, const char *rig_binary);
/* Waits for a child; returns its exit status, or -1 on timeout (then kills it). */
int harness_wait(pid_t pid, double timeout_s, int *raw_status);
void harness_stop(rig_run *run);
double harness_now(void);
void harness_sleep_ms(int ms);

#endif
