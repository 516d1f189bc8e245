/*
 * The register map's Modbus access layer: reads and writes by table and
 * address over the app's status, settings and commands. The field accessors
 * it shares with settings.c are in regmap_fields.c (no app dependency there,
 * so settings.c does not reach back into the app).
 */
#include "leveler/regmap.h"

#include <stddef.h>
#include <string.h>

#include "internal.h"
#include "leveler/regmap_addr.h"
#include "leveler/regmap_desc.h"
#include "leveler/settings.h"

/* The names registers.json gives the fault codes and refusal reasons (read by
 * supervision tools such as leveler-monitor) must be the firmware's own codes. */
_Static_assert(LEVELER_IR_LAST_FAULT_CODE_OVERPRESSURE == LEVELER_FAULT_OVERPRESSURE &&
                   LEVELER_IR_LAST_FAULT_CODE_RUN_TIME == LEVELER_FAULT_RUN_TIME &&
                   LEVELER_IR_LAST_FAULT_CODE_STALL == LEVELER_FAULT_STALL &&
                   LEVELER_IR_LAST_FAULT_CODE_SENSOR_HEIGHT == LEVELER_FAULT_SENSOR_HEIGHT &&
                   LEVELER_IR_LAST_FAULT_CODE_SENSOR_P_SPRING == LEVELER_FAULT_SENSOR_P_SPRING &&
                   LEVELER_IR_LAST_FAULT_CODE_SENSOR_P_PIPE == LEVELER_FAULT_SENSOR_P_PIPE &&
                   LEVELER_IR_LAST_FAULT_CODE_SENSOR_P_ACC == LEVELER_FAULT_SENSOR_P_ACC &&
                   LEVELER_IR_LAST_FAULT_CODE_CHATTER == LEVELER_FAULT_CHATTER,
               "registers.json: last_fault_code's enum differs from leveler_fault_code (status.h)");
_Static_assert(LEVELER_IR_LAST_REFUSAL_REASON_READ_ONLY == LEVELER_REASON_READ_ONLY &&
                   LEVELER_IR_LAST_REFUSAL_REASON_OUT_OF_RANGE == LEVELER_REASON_OUT_OF_RANGE &&
                   LEVELER_IR_LAST_REFUSAL_REASON_BAND_ORDER == LEVELER_REASON_BAND_ORDER &&
                   LEVELER_IR_LAST_REFUSAL_REASON_LIMIT_ORDER == LEVELER_REASON_LIMIT_ORDER &&
                   LEVELER_IR_LAST_REFUSAL_REASON_CALIBRATION == LEVELER_REASON_CALIBRATION &&
                   LEVELER_IR_LAST_REFUSAL_REASON_BAD_ENUM == LEVELER_REASON_BAD_ENUM &&
                   LEVELER_IR_LAST_REFUSAL_REASON_SPLIT_VALUE == LEVELER_REASON_SPLIT_VALUE,
               "registers.json: last_refusal_reason's enum differs from leveler_reg_reason (regmap.h)");

uint16_t leveler_regs_table_size(leveler_table table)
{
    switch (table) {
    case LEVELER_TABLE_COIL:
        return LEVELER_COIL_TABLE_SIZE;
    case LEVELER_TABLE_DISCRETE_INPUT:
        return LEVELER_DI_TABLE_SIZE;
    case LEVELER_TABLE_HOLDING_REGISTER:
        return LEVELER_HR_TABLE_SIZE;
    case LEVELER_TABLE_INPUT_REGISTER:
        return LEVELER_IR_TABLE_SIZE;
    default:
        return 0;
    }
}

/* The descriptor whose value covers addr, or NULL for a gap. */
static const leveler_reg_desc *find(leveler_table table, uint16_t addr)
{
    for (uint16_t i = 0; i < leveler_reg_table_count(); i++) {
        const leveler_reg_desc *d = &leveler_reg_table[i];
        if (d->table == (uint8_t)table && addr >= d->address && addr < d->address + leveler_reg_words(d)) {
            return d;
        }
    }
    return NULL;
}

static const void *region_base(uint8_t region)
{
    switch (region) {
    case LEVELER_REGION_STATUS:
        return leveler_app_status();
    case LEVELER_REGION_SETTINGS:
        return leveler_settings_current();
    default:
        return leveler_app_command();
    }
}

/* Word (or bit) `addr` of the value d describes: high word first. */
static uint16_t word_of(const leveler_reg_desc *d, int64_t value, uint16_t addr)
{
    if (leveler_reg_words(d) == 1u) {
        return (uint16_t)((uint64_t)value & 0xFFFFu);
    }
    uint32_t u = (uint32_t)((uint64_t)value & 0xFFFFFFFFu);
    return (addr == d->address) ? (uint16_t)(u >> 16) : (uint16_t)(u & 0xFFFFu);
}

/* A request [addr, addr+count) that cuts through a 32-bit value. */
static bool splits(const leveler_reg_desc *d, uint16_t addr, uint16_t count)
{
    uint32_t first = d->address;
    uint32_t last = (uint32_t)d->address + leveler_reg_words(d) - 1u;
    return first < addr || last >= (uint32_t)addr + count;
}

static bool bounds_ok(leveler_table table, uint16_t addr, uint16_t count)
{
    return count > 0u && (uint32_t)addr + count <= leveler_regs_table_size(table);
}

leveler_reg_status leveler_regs_read(leveler_table table, uint16_t addr, uint16_t count, uint16_t *out)
{
    if (!bounds_ok(table, addr, count)) {
        return LEVELER_REG_ILLEGAL_ADDRESS;
    }
    for (uint16_t i = 0; i < count; i++) {
        const leveler_reg_desc *d = find(table, (uint16_t)(addr + i));
        if (d != NULL && splits(d, addr, count)) {
            return LEVELER_REG_ILLEGAL_ADDRESS;
        }
    }
    for (uint16_t i = 0; i < count; i++) {
        uint16_t a = (uint16_t)(addr + i);
        const leveler_reg_desc *d = find(table, a);
        out[i] = (d == NULL) ? 0u : word_of(d, leveler_reg_field_get(d, region_base(d->region)), a);
    }
    return LEVELER_REG_OK;
}

static leveler_reg_status refuse(leveler_reg_status st, uint16_t why, uint16_t *reason)
{
    if (reason != NULL) {
        *reason = why;
    }
    leveler_app_note_refusal(why);
    return st;
}

/* Value of d assembled from the request's words, sign-extended for int32. */
static int64_t assemble(const leveler_reg_desc *d, uint16_t addr, const uint16_t *values)
{
    const uint16_t *w = &values[d->address - addr];
    switch (d->type) {
    case LEVELER_REGTYPE_I32:
        return (int32_t)(((uint32_t)w[0] << 16) | w[1]);
    case LEVELER_REGTYPE_U32:
        return (int64_t)(((uint32_t)w[0] << 16) | w[1]);
    default:
        return w[0];
    }
}

leveler_reg_status leveler_regs_write(leveler_table table, uint16_t addr, uint16_t count, const uint16_t *values,
                                      uint16_t *reason)
{
    if (reason != NULL) {
        *reason = LEVELER_REASON_NONE;
    }
    if (table == LEVELER_TABLE_INPUT_REGISTER || table == LEVELER_TABLE_DISCRETE_INPUT) {
        return refuse(LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_READ_ONLY, reason);
    }
    if (!bounds_ok(table, addr, count)) {
        return LEVELER_REG_ILLEGAL_ADDRESS;
    }
    leveler_settings next = *leveler_settings_current();
    leveler_command cmd = *leveler_app_command();
    bool clear = false;

    /* Validate every item into copies; nothing in force changes before the end. */
    for (uint16_t i = 0; i < count;) {
        const leveler_reg_desc *d = find(table, (uint16_t)(addr + i));
        if (d == NULL) {
            return refuse(LEVELER_REG_ILLEGAL_ADDRESS, LEVELER_REASON_READ_ONLY, reason); /* a gap */
        }
        if (splits(d, addr, count)) {
            return refuse(LEVELER_REG_ILLEGAL_ADDRESS, LEVELER_REASON_SPLIT_VALUE, reason);
        }
        if (d->access != LEVELER_ACCESS_RW || d->region == LEVELER_REGION_STATUS) {
            return refuse(LEVELER_REG_ILLEGAL_VALUE, LEVELER_REASON_READ_ONLY, reason);
        }
        int64_t v = assemble(d, addr, values);
        if (v < d->min || v > d->max) {
            uint16_t why = ((d->flags & LEVELER_REGFLAG_ENUM) != 0u) ? LEVELER_REASON_BAD_ENUM
                                                                       : LEVELER_REASON_OUT_OF_RANGE;
            return refuse(LEVELER_REG_ILLEGAL_VALUE, why, reason);
        }
        if (d->region == LEVELER_REGION_SETTINGS) {
            leveler_reg_field_set(d, &next, v);
        } else if (d->offset == offsetof(leveler_command, clear_faults)) {
            clear = clear || v != 0; /* an action, never stored */
        } else {
            leveler_reg_field_set(d, &cmd, v);
        }
        i = (uint16_t)(i + leveler_reg_words(d));
    }
    uint16_t why = leveler_settings_check(&next);
    if (why != LEVELER_REASON_NONE) {
        return refuse(LEVELER_REG_ILLEGAL_VALUE, why, reason);
    }
    (void)leveler_settings_apply(&next); /* checked above: cannot be refused */
    *leveler_app_command_mut() = cmd;
    if (clear) {
        leveler_app_clear_faults();
    }
    return LEVELER_REG_OK;
}
