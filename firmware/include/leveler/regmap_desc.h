/*
 * Descriptor table behind the register map (internal to the firmware and its tests).
 * scripts/gen_regmap.py writes the table (regmap_table.c in the build tree) from
 * firmware/regmap/registers.json; regmap.c and settings.c walk it.
 */
#ifndef LEVELER_REGMAP_DESC_H
#define LEVELER_REGMAP_DESC_H

#include <stdint.h>
#include "leveler/regmap.h"
#include "leveler/settings.h"
#include "leveler/status.h"

typedef enum {
    LEVELER_REGTYPE_BIT = 0, /* bool field, one coil / discrete input */
    LEVELER_REGTYPE_U16 = 1, /* uint16_t field, one register */
    LEVELER_REGTYPE_I32 = 2, /* int32_t field, two registers, high word first */
    LEVELER_REGTYPE_U32 = 3  /* uint32_t field, two registers, high word first */
} leveler_regtype;

typedef enum { LEVELER_ACCESS_R = 0, LEVELER_ACCESS_RW = 1 } leveler_access;

/* Which struct a bind points into. */
typedef enum {
    LEVELER_REGION_STATUS = 0,   /* leveler_status (read-only, the app's outputs) */
    LEVELER_REGION_SETTINGS = 1, /* leveler_settings (validated as a whole) */
    LEVELER_REGION_COMMAND = 2   /* leveler_command (coils) */
} leveler_region;

#define LEVELER_REGFLAG_ENUM 0x01u /* out-of-range values are refused as BAD_ENUM */

typedef struct {
    int64_t min; /* inclusive range of the value (int64 holds every int32 and uint32) */
    int64_t max;
    int64_t default_value; /* meaningful when has_default */
    uint16_t offset;       /* offsetof the bound field in its region's struct */
    uint16_t address;      /* 0-based, first register of the value */
    uint8_t table;         /* leveler_table */
    uint8_t type;          /* leveler_regtype */
    uint8_t access;        /* leveler_access */
    uint8_t region;        /* leveler_region */
    uint8_t flags;         /* LEVELER_REGFLAG_* */
    uint8_t has_default;
} leveler_reg_desc;

/* Number of entries: LEVELER_REGMAP_ENTRY_COUNT in the generated leveler/regmap_addr.h. */
extern const leveler_reg_desc leveler_reg_table[];
uint16_t leveler_reg_table_count(void);

/* Registers (or bits) one descriptor occupies: 2 for 32-bit types, else 1. */
uint16_t leveler_reg_words(const leveler_reg_desc *d);

/* Load / store the bound field of d inside the struct at base, widened to int64. */
int64_t leveler_reg_field_get(const leveler_reg_desc *d, const void *base);
void leveler_reg_field_set(const leveler_reg_desc *d, void *base, int64_t value);

#endif /* LEVELER_REGMAP_DESC_H */
