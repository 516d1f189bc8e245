/*
 * The application loop every target runs.
 *
 *   leveler_app_init();                  once: outputs to safe state, defaults loaded
 *   every LEVELER_TICK_MS:  leveler_app_tick();   sample -> supervise + control -> actuate
 *
 * The target owns the clock: the board calls tick from its main loop when
 * SysTick says 10 ms have passed, the simulator after advancing its plant by
 * 10 ms, the Linux rig on absolute deadlines. The firmware only reads
 * hal_now_ms() for its own timers (run time, cool-down, stall, stale).
 */
#ifndef LEVELER_APP_H
#define LEVELER_APP_H

#include <stdbool.h>
#include <stdint.h>

#define LEVELER_TICK_MS 10u /* the thesis time step, 0.01 s */

/* Reset all firmware state to power-up: outputs safe, settings = defaults,
 * faults cleared, sensors not yet valid. */
void leveler_app_init(void);

/* One control tick. Never blocks. */
void leveler_app_tick(void);

/* Target-side diagnostics the register map exposes (written by the target). */
void leveler_app_report_tick_overrun(void);            /* rig: a deadline was missed */
void leveler_app_report_tick_cycles(uint32_t cycles);  /* board: DWT cycles of one tick; worst kept */
void leveler_app_report_clock_fault(bool hse_failed);  /* board: fell back to HSI */
void leveler_app_report_reset_cause(bool watchdog);     /* board: the last reset came from the watchdog */
void leveler_app_report_log(bool fault, uint32_t rows_dropped); /* rig: run-log health */
void leveler_app_report_sensor_scans_failed(uint32_t failed);   /* rig: sensor-module link health */
void leveler_app_report_link_faults_auto_cleared(uint32_t count); /* rig: [faults] auto-clears so far */

#endif /* LEVELER_APP_H */
