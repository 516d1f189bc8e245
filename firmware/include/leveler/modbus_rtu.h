/*
 * Portable Modbus RTU slave over the HAL serial bytes and the register map.
 * The board calls leveler_modbus_rtu_poll() from its main loop between ticks;
 * it never blocks and handles at most one frame per call.
 */
#ifndef LEVELER_MODBUS_RTU_H
#define LEVELER_MODBUS_RTU_H

#include <stddef.h>
#include <stdint.h>

#define LEVELER_RTU_MAX_ADU 256u

/* Reset the receiver; address and baud come from the settings in force. */
void leveler_modbus_rtu_init(void);

/* Move received bytes in, close a frame after the 3.5-character gap,
 * answer it through hal_serial_write(). */
void leveler_modbus_rtu_poll(void);

/* One complete request ADU (address..CRC) -> response ADU. Returns the
 * response length, 0 for no reply (bad CRC, other address, broadcast).
 * Pure apart from the register map: the fuzz target and tests call it. */
size_t leveler_modbus_rtu_handle(const uint8_t *req, size_t req_len, uint8_t *resp, size_t resp_cap);

#endif /* LEVELER_MODBUS_RTU_H */
