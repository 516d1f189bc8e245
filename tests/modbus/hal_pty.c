#define _POSIX_C_SOURCE 200809L
#include "hal_pty.h"

#include <errno.h>
#include <stdatomic.h>
#include <time.h>
#include <unistd.h>

const uint16_t hal_pty_adc_counts[HAL_ADC_COUNT] = {2048, 1500, 1600, 1700};

static int serial_fd = -1;
static atomic_bool outputs[HAL_OUT_COUNT];

void hal_pty_attach(int master_fd) { serial_fd = master_fd; }

bool hal_pty_output(hal_output output) { return atomic_load(&outputs[output]); }

bool hal_adc_read(hal_adc_channel channel, uint16_t *counts)
{
    if ((unsigned)channel >= HAL_ADC_COUNT) {
        return false;
    }
    *counts = hal_pty_adc_counts[channel];
    return true;
}

void hal_output_set(hal_output output, bool on)
{
    if ((unsigned)output < HAL_OUT_COUNT) {
        atomic_store(&outputs[output], on);
    }
}

uint32_t hal_now_ms(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (uint32_t)((uint64_t)now.tv_sec * 1000u + (uint64_t)now.tv_nsec / 1000000u);
}

size_t hal_serial_read(uint8_t *buf, size_t max_len)
{
    const ssize_t n = read(serial_fd, buf, max_len);
    return n > 0 ? (size_t)n : 0; /* EAGAIN: nothing yet; EIO: peer closed */
}

size_t hal_serial_write(const uint8_t *buf, size_t len)
{
    const ssize_t n = write(serial_fd, buf, len);
    return n > 0 ? (size_t)n : 0;
}
