/*
 * Simulator speed with the firmware in the loop, no CSV in the timed part:
 * simulated seconds per wall second for the 55 s thesis case, and how the cost
 * grows with simulated time (55, 550, 5500 s: the last load is held).
 * Target (brief): >= 20,000x real time on one core (55 s in <= 2.75 ms).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <time.h>

#include "simloop.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "host_sim/configs/thesis-900lb.ini";
    static plant_config cfg;
    char err[1024];
    if (plant_config_load(path, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "leveler-sim-bench: %s\n", err);
        return 2;
    }
    static const double ends[] = {55.0, 550.0, 5500.0};
    printf("leveler-sim speed, %s, %d RK4 sub-steps per 10 ms tick, firmware in the loop, no log\n", cfg.name,
           cfg.substeps_per_tick);
    printf("%10s %8s %14s %16s %14s\n", "sim_s", "repeats", "wall_ms/run", "x real time", "us/tick");
    double base_ms = 0.0;
    for (size_t i = 0; i < sizeof ends / sizeof ends[0]; i++) {
        int reps = ends[i] <= 55.0 ? 50 : (ends[i] <= 550.0 ? 5 : 1);
        sim_options so = {.config = &cfg, .end_s = ends[i]};
        static sim_result res;
        double best = 1e9;
        for (int r = 0; r < reps; r++) {
            double t0 = now_s();
            if (sim_run(&so, &res, err, sizeof err) != 0) {
                fprintf(stderr, "leveler-sim-bench: %s\n", err);
                return 1;
            }
            double dt = now_s() - t0;
            if (dt < best)
                best = dt;
        }
        if (i == 0)
            base_ms = best * 1e3;
        printf("%10.0f %8d %14.3f %16.0f %14.3f\n", ends[i], reps, best * 1e3, ends[i] / best,
               best * 1e6 / (double)res.ticks);
    }
    printf("55 s thesis case: %.3f ms (target <= 2.75 ms, i.e. >= 20000x)\n", base_ms);
    return 0;
}
