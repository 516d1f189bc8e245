/*
 * A board for leveler-monitor's RTU test: the firmware as a board runs it
 * (leveler_app_init, leveler_modbus_rtu_poll() in a loop, leveler_app_tick()
 * every 10 ms) on the pty HAL of the Modbus tests (tests/modbus/hal_pty.c:
 * fixed ADC counts), behind a pseudo-terminal. Prints the pty's path, serves
 * until SIGTERM/SIGINT, then prints the settings a master wrote, read inside
 * the firmware through its register map (the test's independent read-back):
 *
 *   pty /dev/pts/N
 *   mode 0 band_lower_um 395000 band_upper_um 402500 latched_fault_bits 0
 */
#define _DEFAULT_SOURCE
#include <fcntl.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "hal_pty.h"
#include "leveler/app.h"
#include "leveler/modbus_rtu.h"
#include "leveler/regmap.h"
#include "leveler/regmap_addr.h"

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
    (void)sig;
    stop = 1;
}

static long read_i32(uint16_t addr)
{
    uint16_t w[2] = {0, 0};
    leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, addr, 2, w);
    return (long)(int32_t)(((uint32_t)w[0] << 16) | w[1]); /* high word first */
}

int main(void)
{
    struct termios raw;
    memset(&raw, 0, sizeof raw);
    cfmakeraw(&raw);
    int master = -1, slave = -1;
    char path[128];
    if (openpty(&master, &slave, path, &raw, NULL) != 0) {
        perror("openpty");
        return 1;
    }
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    hal_pty_attach(master);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    leveler_app_init();
    leveler_modbus_rtu_init();
    printf("pty %s\n", path);
    fflush(stdout);
    uint32_t next_tick_ms = hal_now_ms() + LEVELER_TICK_MS;
    const struct timespec nap = {0, 100000}; /* 0.1 ms: well inside the 3.5-character gap */
    while (!stop) {
        leveler_modbus_rtu_poll();
        if ((int32_t)(hal_now_ms() - next_tick_ms) >= 0) {
            leveler_app_tick();
            next_tick_ms += LEVELER_TICK_MS;
        }
        nanosleep(&nap, NULL);
    }
    uint16_t mode = 0, latched = 0;
    leveler_regs_read(LEVELER_TABLE_HOLDING_REGISTER, LEVELER_HR_MODE, 1, &mode);
    leveler_regs_read(LEVELER_TABLE_INPUT_REGISTER, LEVELER_IR_LATCHED_FAULT_BITS, 1, &latched);
    printf("mode %u band_lower_um %ld band_upper_um %ld latched_fault_bits %u\n", mode,
           read_i32(LEVELER_HR_BAND_LOWER_UM), read_i32(LEVELER_HR_BAND_UPPER_UM), latched);
    close(slave);
    close(master);
    return 0;
}
