/*
 * Field accessors of the generated register table (regmap_desc.h): how many
 * descriptors, how many words a value takes, and a field's value read from or
 * written into its struct. Used by the access layer (regmap.c) and by
 * settings.c (defaults, validation, comparison).
 */
#include "leveler/regmap_desc.h"

#include <stdbool.h>
#include <string.h>

#include "leveler/regmap_addr.h"

uint16_t leveler_reg_table_count(void)
{
    return (uint16_t)LEVELER_REGMAP_ENTRY_COUNT;
}

uint16_t leveler_reg_words(const leveler_reg_desc *d)
{
    return (d->type == LEVELER_REGTYPE_I32 || d->type == LEVELER_REGTYPE_U32) ? 2u : 1u;
}

int64_t leveler_reg_field_get(const leveler_reg_desc *d, const void *base)
{
    const uint8_t *p = (const uint8_t *)base + d->offset;
    switch (d->type) {
    case LEVELER_REGTYPE_BIT: {
        bool b;
        memcpy(&b, p, sizeof(b));
        return b ? 1 : 0;
    }
    case LEVELER_REGTYPE_U16: {
        uint16_t v;
        memcpy(&v, p, sizeof(v));
        return v;
    }
    case LEVELER_REGTYPE_I32: {
        int32_t v;
        memcpy(&v, p, sizeof(v));
        return v;
    }
    default: {
        uint32_t v;
        memcpy(&v, p, sizeof(v));
        return v;
    }
    }
}

/* value must already be inside the field's range (callers check). */
void leveler_reg_field_set(const leveler_reg_desc *d, void *base, int64_t value)
{
    uint8_t *p = (uint8_t *)base + d->offset;
    switch (d->type) {
    case LEVELER_REGTYPE_BIT: {
        bool b = value != 0;
        memcpy(p, &b, sizeof(b));
        break;
    }
    case LEVELER_REGTYPE_U16: {
        uint16_t v = (uint16_t)value;
        memcpy(p, &v, sizeof(v));
        break;
    }
    case LEVELER_REGTYPE_I32: {
        int32_t v = (int32_t)value;
        memcpy(p, &v, sizeof(v));
        break;
    }
    default: {
        uint32_t v = (uint32_t)value;
        memcpy(p, &v, sizeof(v));
        break;
    }
    }
}
