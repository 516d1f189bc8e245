/*
 * The Modbus register map: the access functions the PDU server calls
 * (modbus_pdu.c, behind the RTU slave in firmware/ and the rig's Modbus TCP server).
 *
 * The table itself is generated at build time from firmware/regmap/registers.json
 * (C table: regmap_table.c / leveler/regmap_addr.h in the build tree; docs/registers.md).
 * Addresses are 0-based. 32-bit values take two registers, high word first.
 */
#ifndef LEVELER_REGMAP_H
#define LEVELER_REGMAP_H

#include <stdbool.h>
#include <stdint.h>

typedef enum {
    LEVELER_TABLE_COIL = 0,             /* R/W bits  (FC 01, 05, 15) */
    LEVELER_TABLE_DISCRETE_INPUT = 1,   /* R bits    (FC 02) */
    LEVELER_TABLE_HOLDING_REGISTER = 2, /* R/W words (FC 03, 06, 16) */
    LEVELER_TABLE_INPUT_REGISTER = 3    /* R words   (FC 04) */
} leveler_table;

/* Outcome of an access; maps onto Modbus exceptions as noted. */
typedef enum {
    LEVELER_REG_OK = 0,
    LEVELER_REG_ILLEGAL_ADDRESS = 2, /* exception 02: address/count outside the table, or splits a 32-bit value */
    LEVELER_REG_ILLEGAL_VALUE = 3    /* exception 03: the write was refused; see the reason */
} leveler_reg_status;

/* Why a write was refused. The last one is readable in an input register. */
typedef enum {
    LEVELER_REASON_NONE = 0,
    LEVELER_REASON_READ_ONLY = 1,
    LEVELER_REASON_OUT_OF_RANGE = 2,
    LEVELER_REASON_BAND_ORDER = 3,      /* band lower edge at or above the upper */
    LEVELER_REASON_LIMIT_ORDER = 4,     /* e.g. vent limit below the compressor cut-off */
    LEVELER_REASON_CALIBRATION = 5,     /* raw_lo == raw_hi, or eng span of zero */
    LEVELER_REASON_BAD_ENUM = 6,        /* mode / algorithm / baud not one of the listed values */
    LEVELER_REASON_SPLIT_VALUE = 7      /* only half of a 32-bit value written */
} leveler_reg_reason;

/* Read count consecutive items. Bits come back as 0/1, one per element. */
leveler_reg_status leveler_regs_read(leveler_table table, uint16_t addr, uint16_t count, uint16_t *out);

/* Write count consecutive items, all or nothing: the whole request is validated
 * (each field's range, then the settings' consistency) before anything changes.
 * On refusal *reason (may be NULL) says why and the register map's
 * last_refusal_reason register holds it too. */
leveler_reg_status leveler_regs_write(leveler_table table, uint16_t addr, uint16_t count,
                                      const uint16_t *values, uint16_t *reason);

/* Size of each table (one past the highest address). */
uint16_t leveler_regs_table_size(leveler_table table);

#endif /* LEVELER_REGMAP_H */
