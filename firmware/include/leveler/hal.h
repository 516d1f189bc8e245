/*
 * The one seam between the portable firmware and a target.
 *
 * Exactly one implementation of these functions is linked into each target,
 * chosen in CMake (link-time substitution, as in Grenning's TDD for Embedded C):
 *   boards/stm32f103/hal_stm32f103.c   the flashable board
 *   host_sim/sim/hal_sim.c             the plant model (simulator owns time)
 *   host_sim/rig/hal_rig.c             a Linux computer on a real rig
 *   tests/fakes/fake_hal.c             unit tests
 * Nothing in firmware/ may test which one it is.
 */
#ifndef LEVELER_HAL_H
#define LEVELER_HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Sensor inputs, in the order of the ADC scan. */
typedef enum {
    HAL_ADC_HEIGHT = 0,   /* LVDT on the platform */
    HAL_ADC_P_SPRING = 1, /* P2, air-spring pressure */
    HAL_ADC_P_PIPE = 2,   /* P1, pipe / junction pressure */
    HAL_ADC_P_ACC = 3,    /* P3, accumulator pressure */
    HAL_ADC_COUNT = 4
} hal_adc_channel;

/* Full scale of every ADC channel: 12-bit counts 0..4095. */
#define HAL_ADC_MAX_COUNTS 4095u

/* Digital outputs. true = energised (compressor running, valve open, LED lit). */
typedef enum {
    HAL_OUT_COMPRESSOR = 0,
    HAL_OUT_SPRING_VALVE = 1, /* solenoid valve between pipe and spring */
    HAL_OUT_VENT_VALVE = 2,
    HAL_OUT_ACC_VALVE = 3,
    HAL_OUT_STATUS_LED = 4,
    HAL_OUT_COUNT = 5
} hal_output;

/*
 * One conversion of a channel, in counts 0..HAL_ADC_MAX_COUNTS.
 * Returns false when no fresh reading could be had (a rig's Modbus read timed
 * out, a DMA scan did not complete): the firmware counts that as a bad sample
 * for the channel's debounce. *counts is left unchanged then.
 */
bool hal_adc_read(hal_adc_channel channel, uint16_t *counts);

/* Drive one output. Must be safe to call at any time, including before
 * hal_init() has finished and from the fault path. */
void hal_output_set(hal_output output, bool on);

/* Monotonic milliseconds since start; wraps at 2^32 (use unsigned differences). */
uint32_t hal_now_ms(void);

/* Serial bytes for the Modbus RTU link on the board.
 * Non-blocking: return how many bytes were moved (0 when none). */
size_t hal_serial_read(uint8_t *buf, size_t max_len);
size_t hal_serial_write(const uint8_t *buf, size_t len);

#endif /* LEVELER_HAL_H */
