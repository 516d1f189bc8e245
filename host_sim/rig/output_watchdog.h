/*
 * The communication watchdog of a Modbus I/O module, as leveler-plant-server
 * models it (real modules, e.g. WAGO 750-352, Moxa ioLogik, Advantech ADAM,
 * have one): a client writes a time in ms into a holding register (0 = off);
 * every write request (FC 05/06/15/16) feeds it; when none arrives for that
 * long, the module drives its coils to 0 (safe) by itself and counts the
 * trip. Wall time (CLOCK_MONOTONIC), also in lockstep: a dead controller
 * must not keep valves open because the plant's clock stands still.
 */
#ifndef LEVELER_RIG_OUTPUT_WATCHDOG_H
#define LEVELER_RIG_OUTPUT_WATCHDOG_H

#include <stdbool.h>
#include <stdint.h>

#include <modbus.h>

#define OUTPUT_WATCHDOG_REGISTER 2 /* holding: watchdog time, ms (0 = off) */
#define OUTPUT_WATCHDOG_TRIPS 5    /* input: times it drove the coils safe */

/* After each request the module answered (query as modbus_receive gave it). */
void output_watchdog_after_request(modbus_mapping_t *map, const uint8_t *query, int header_length);
/* true when it has just tripped (coils 0..coil_count-1 now 0). */
bool output_watchdog_check(modbus_mapping_t *map, int coil_count);
/* ms until it would trip (for the server's wait), or -1 when disarmed. */
int output_watchdog_ms_left(const modbus_mapping_t *map);

#endif
