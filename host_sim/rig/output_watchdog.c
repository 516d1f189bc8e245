/* Communication watchdog of the served I/O module (output_watchdog.h). */
#define _POSIX_C_SOURCE 200809L
#include "output_watchdog.h"

#include <string.h>
#include <time.h>

static uint64_t last_write_ms;

static uint64_t mono_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

void output_watchdog_after_request(modbus_mapping_t *map, const uint8_t *query, int header_length)
{
    (void)map;
    int function = query[header_length];
    if (function == MODBUS_FC_WRITE_SINGLE_COIL || function == MODBUS_FC_WRITE_SINGLE_REGISTER ||
        function == MODBUS_FC_WRITE_MULTIPLE_COILS || function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS)
        last_write_ms = mono_ms();
}

int output_watchdog_ms_left(const modbus_mapping_t *map)
{
    uint16_t period = map->tab_registers[OUTPUT_WATCHDOG_REGISTER];
    if (period == 0)
        return -1;
    uint64_t now = mono_ms(), due = last_write_ms + period;
    return now >= due ? 0 : (int)(due - now);
}

bool output_watchdog_check(modbus_mapping_t *map, int coil_count)
{
    if (output_watchdog_ms_left(map) != 0)
        return false;
    bool any_on = false;
    for (int i = 0; i < coil_count; i++)
        any_on = any_on || map->tab_bits[i];
    last_write_ms = mono_ms(); /* re-armed: trips again only after another silent period */
    if (!any_on)
        return false;
    memset(map->tab_bits, 0, (size_t)coil_count);
    map->tab_input_registers[OUTPUT_WATCHDOG_TRIPS]++;
    return true;
}
