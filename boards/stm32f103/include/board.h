/*
 * STM32F103C8 board internals shared by startup, HAL and main loop.
 * Pin map (see README.md for the wiring):
 *   PA0..PA3  ADC12_IN0..3   height, P2 spring, P1 pipe, P3 accumulator
 *   PA8       RS-485 DE + /RE (high = transmit)
 *   PA9/PA10  USART1 TX/RX   Modbus RTU
 *   PB12..15  compressor, spring valve, vent valve, accumulator valve (high = on)
 *   PC13      status LED (active low, on the Blue Pill)
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdbool.h>
#include <stdint.h>

#include "flash_store.h"

#define BOARD_OUT_PORT_PINS_FIRST 12u /* PB12..PB15, in hal_output order */
#define BOARD_LED_PIN 13u             /* PC13 */
#define BOARD_DE_PIN 8u               /* PA8 */

#define BOARD_HSE_HZ 8000000u
#define BOARD_HSI_HZ 8000000u

typedef struct {
    uint32_t sysclk_hz;
    uint32_t pclk1_hz;
    uint32_t pclk2_hz;
    bool hse_failed; /* running from HSI (PLL x16 from HSI/2 = 64 MHz, or 8 MHz) */
} board_clocks;

/* startup.c -> board.c: before RAM is initialised, so no globals used. */
void board_outputs_safe_early(void);
/* After .data/.bss: HSE+PLL to 72 MHz, or HSI fallback. */
void board_clock_init(void);
const board_clocks *board_clock(void);
/* True once after the clock security system moved us to HSI at run time. */
bool board_take_clock_fault_event(void);
/* NMI: true (and running from HSI) when the clock security system fired. */
bool board_clock_recover_after_css(void);
void Default_Handler(void); /* startup.c */

void board_systick_init(void); /* hal_stm32f103.c: the 1 ms time base */
void board_cycle_counter_init(void);
uint32_t board_cycles(void);
void board_watchdog_start(void);
void board_watchdog_refresh(void);
bool board_reset_was_watchdog(void); /* read once at boot, flags then cleared */

/* hal_stm32f103.c */
void board_hal_init(void);                 /* GPIO, ADC+DMA, USART at 19200 8E1 */
bool board_serial_set_baud(uint32_t baud); /* false when the clock cannot make it */
void board_serial_reclock(void);           /* re-derive the divider after a clock change */
bool board_serial_idle(void);              /* nothing queued or on the wire */
void board_led_set(bool lit);              /* the pin itself, owned by main.c */
bool board_firmware_led_request(void);     /* last hal_output_set(HAL_OUT_STATUS_LED, ..) */

/* flash_stm32f103.c: the settings store's flash seam over the last two pages. */
const flash_store_driver *board_flash_driver(void);

#endif
