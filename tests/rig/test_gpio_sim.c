/*
 * The libgpiod output backend against the kernel's gpio-sim (configfs):
 * real character-device lines, levels read back from sysfs. Where gpio-sim
 * is not available (no configfs, module not loaded, not root) the test
 * reports itself skipped (exit 77, CTest SKIP_RETURN_CODE).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "output_backend.h"

#define GPIO_SIM "/sys/kernel/config/gpio-sim"
#define SKIP 77

static char dev_dir[256];

static int write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    int ok = fputs(text, f) >= 0;
    return (fclose(f) == 0 && ok) ? 0 : -1;
}

static int read_text(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    char *r = fgets(buf, (int)cap, f);
    fclose(f);
    if (!r)
        return -1;
    buf[strcspn(buf, "\n")] = '\0';
    return 0;
}

static void cleanup(void)
{
    char p[300];
    snprintf(p, sizeof p, "%s/live", dev_dir);
    write_text(p, "0");
    snprintf(p, sizeof p, "%s/bank0", dev_dir);
    rmdir(p);
    rmdir(dev_dir);
}

static int level(const char *dev_name, const char *chip_name, int line)
{
    char p[300], v[16];
    snprintf(p, sizeof p, "/sys/devices/platform/%s/%s/sim_gpio%d/value", dev_name, chip_name, line);
    if (read_text(p, v, sizeof v) != 0)
        return -1;
    return atoi(v);
}

int main(void)
{
    if (access(GPIO_SIM, W_OK) != 0) {
        printf("SKIP: %s not available (%s): needs configfs, the gpio-sim module and root\n", GPIO_SIM,
               strerror(errno));
        return SKIP;
    }
    snprintf(dev_dir, sizeof dev_dir, GPIO_SIM "/leveler-test-%d", (int)getpid());
    char p[300], chip_name[64], dev_name[64];
    if (mkdir(dev_dir, 0755) != 0) {
        printf("SKIP: cannot create %s: %s\n", dev_dir, strerror(errno));
        return SKIP;
    }
    snprintf(p, sizeof p, "%s/bank0", dev_dir);
    mkdir(p, 0755);
    snprintf(p, sizeof p, "%s/bank0/num_lines", dev_dir);
    write_text(p, "8");
    snprintf(p, sizeof p, "%s/live", dev_dir);
    if (write_text(p, "1") != 0) {
        printf("SKIP: cannot bring the simulated chip live\n");
        cleanup();
        return SKIP;
    }
    snprintf(p, sizeof p, "%s/bank0/chip_name", dev_dir);
    int ok = read_text(p, chip_name, sizeof chip_name) == 0;
    snprintf(p, sizeof p, "%s/dev_name", dev_dir);
    ok = ok && read_text(p, dev_name, sizeof dev_name) == 0;
    if (!ok) {
        printf("FAIL: no chip_name/dev_name for the live gpio-sim chip\n");
        cleanup();
        return 1;
    }

    rig_config cfg;
    rig_config_defaults(&cfg);
    for (int o = 0; o < HAL_OUT_COUNT; o++) {
        cfg.pin[o].configured = true;
        snprintf(cfg.pin[o].chip, sizeof cfg.pin[o].chip, "%s", chip_name);
        cfg.pin[o].line = (uint32_t)o;
        cfg.pin[o].active_low = (o % 2) == 1;
    }
    rig_output_backend out;
    char err[256];
    int failures = 0;
    if (rig_gpiod_open(&cfg, &out, err, sizeof err) != 0) {
        printf("FAIL: %s\n", err);
        cleanup();
        return 1;
    }
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        if (level(dev_name, chip_name, o) != (cfg.pin[o].active_low ? 1 : 0)) {
            printf("FAIL: line %d not de-energised at start\n", o);
            failures++;
        }
    bool on[HAL_OUT_COUNT] = {true, true, false, false, true};
    if (out.apply(out.impl, on, err, sizeof err) != 0) {
        printf("FAIL: %s\n", err);
        failures++;
    }
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        if (level(dev_name, chip_name, o) != (on[o] ^ cfg.pin[o].active_low)) {
            printf("FAIL: line %d reads %d\n", o, level(dev_name, chip_name, o));
            failures++;
        }
    out.close(out.impl);
    /* Released lines keep their last driven level on gpio-sim: the safe one. */
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        if (!cfg.pin[o].active_low && level(dev_name, chip_name, o) != 0) {
            printf("FAIL: line %d not safe after close\n", o);
            failures++;
        }
    cleanup();
    printf("%s\n", failures ? "FAILED" : "OK: gpio-sim lines followed the backend");
    return failures ? 1 : 0;
}
