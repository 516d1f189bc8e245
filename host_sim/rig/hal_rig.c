/* HAL for a Linux computer on a real rig (see rig_hal.h). */
#define _POSIX_C_SOURCE 200809L
#include "rig_hal.h"

#include <signal.h>
#include <time.h>

static rig_sensors *bound_sensors;
static rig_clock bound_clock = RIG_CLOCK_MONOTONIC;
static volatile sig_atomic_t wanted[HAL_OUT_COUNT];
static struct timespec start;
static uint32_t last_module_ms;

void rig_hal_bind(rig_sensors *sensors, rig_clock clock)
{
    bound_sensors = sensors;
    bound_clock = clock;
    clock_gettime(CLOCK_MONOTONIC, &start);
}

void rig_hal_wanted_outputs(bool out[HAL_OUT_COUNT])
{
    for (int o = 0; o < HAL_OUT_COUNT; o++)
        out[o] = wanted[o] != 0;
}

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    return rig_sensors_counts(bound_sensors, channel, counts);
}

void hal_output_set(hal_output output, bool on)
{
    if ((unsigned)output < HAL_OUT_COUNT)
        wanted[output] = on ? 1 : 0;
}

uint32_t hal_now_ms(void)
{
    if (bound_clock == RIG_CLOCK_LOCKSTEP) {
        /* The module's clock; if a scan failed, time holds (the firmware's
         * stale-sensor timer then cannot run either: documented in the README). */
        rig_sensors_module_time_ms(bound_sensors, &last_module_ms);
        return last_module_ms;
    }
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    int64_t ms = (int64_t)(now.tv_sec - start.tv_sec) * 1000 + (now.tv_nsec - start.tv_nsec) / 1000000;
    return (uint32_t)ms; /* wraps at 2^32 as the contract says */
}

double rig_hal_now_s(void)
{
    if (bound_clock == RIG_CLOCK_LOCKSTEP)
        return hal_now_ms() / 1000.0;
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)(now.tv_sec - start.tv_sec) + 1e-9 * (double)(now.tv_nsec - start.tv_nsec);
}

/* No serial link on the rig: its Modbus TCP server serves the register map. */
size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    (void)buf;
    (void)max_len;
    return 0;
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    (void)buf;
    return len; /* discarded */
}
