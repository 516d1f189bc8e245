/* The value types of the one INI reader (ini_table.h): numbers with units and
 * ranges, strict decimals, booleans, texts, choices. */
#define _POSIX_C_SOURCE 200809L
#include "ini_table.h"
#include "ini_values.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

int ini_parse_number(const char *value, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(value, &end);
    if (end == value || errno == ERANGE || !isfinite(v))
        return -1;
    while (*end == ' ' || *end == '\t')
        end++;
    if (*end)
        return -1;
    *out = v;
    return 0;
}

static void put_number(void *dst, ini_store store, double v)
{
    switch (store) {
    case INI_F64: *(double *)dst = v; break;
    case INI_INT: *(int *)dst = (int)v; break;
    case INI_U8: *(uint8_t *)dst = (uint8_t)v; break;
    case INI_U16: *(uint16_t *)dst = (uint16_t)v; break;
    case INI_U32: *(uint32_t *)dst = (uint32_t)v; break;
    case INI_U64: *(uint64_t *)dst = (uint64_t)v; break;
    }
}

/* A quantity in unit u (NULL: a plain number), converted, range-checked in SI. */
static int read_real(ini_file *r, const ini_field *f, const ini_unit *u, void *dst, const char *section,
                     const char *key, const char *value)
{
    double v;
    if (ini_parse_number(value, &v) != 0)
        return ini_file_fail(r, section, key, value, "not a number");
    const ini_table *t = r->load->table;
    double factor = u ? u->factor : 1.0;
    double off = u && u->gauge && t->gauge_offset ? t->gauge_offset(r->load->config) : 0.0;
    double si = v * factor + off;
    if (si < f->min || si > f->max)
        return ini_file_fail(r, section, key, value, "out of range [%.6g, %.6g]%s%s", (f->min - off) / factor,
                             (f->max - off) / factor, u ? " " : "", u ? u->suffix : "");
    if (f->store != INI_F64 && v != floor(v))
        return ini_file_fail(r, section, key, value, "must be a whole number in [%.10g, %.10g]", f->min, f->max);
    put_number(dst, f->store, v * factor); /* gauge: the caller adds the offset at the end (it may come later) */
    return 1;
}

/* Decimal only (a leading 0 is refused: 0777 is neither 777 nor octal 511 here). */
int ini_file_decimal(ini_file *r, const char *section, const char *key, const char *value, long long lo,
                     long long hi, long long *out)
{
    char *end;
    errno = 0;
    const char *digits = value + (value[0] == '-' || value[0] == '+');
    long long v = strtoll(value, &end, 10);
    if (end == value || *end != '\0' || errno == ERANGE || !(digits[0] >= '0' && digits[0] <= '9'))
        return ini_file_fail(r, section, key, NULL, "'%s' is not an integer (decimal, allowed %lld..%lld)", value,
                             lo, hi);
    if (digits[0] == '0' && digits[1] != '\0')
        return ini_file_fail(r, section, key, NULL, "'%s': leading zeros are not allowed (decimal only)", value);
    if (v < lo || v > hi)
        return ini_file_fail(r, section, key, NULL, "%lld is out of range (allowed %lld..%lld)", v, lo, hi);
    *out = v;
    return 1;
}

static int read_decimal(ini_file *r, const ini_field *f, void *dst, const char *section, const char *key,
                        const char *value)
{
    long long v;
    if (!ini_file_decimal(r, section, key, value, (long long)f->min, (long long)f->max, &v))
        return 0;
    put_number(dst, f->store, (double)v);
    return 1;
}

static int read_bool(ini_file *r, bool *dst, const char *section, const char *key, const char *value)
{
    if (!strcasecmp(value, "true") || !strcasecmp(value, "yes") || !strcmp(value, "1") || !strcasecmp(value, "on"))
        *dst = true;
    else if (!strcasecmp(value, "false") || !strcasecmp(value, "no") || !strcmp(value, "0") ||
             !strcasecmp(value, "off"))
        *dst = false;
    else
        return ini_file_fail(r, section, key, NULL, "'%s' is not a boolean (allowed true/false)", value);
    return 1;
}

static int read_text(ini_file *r, const ini_field *f, char *dst, const char *section, const char *key,
                     const char *value)
{
    if (strlen(value) >= f->size)
        return ini_file_fail(r, section, key, NULL, "longer than %zu characters", f->size - 1);
    if (!ini_utf8_valid(value))
        return ini_file_fail(r, section, key, NULL, "not valid UTF-8");
    memcpy(dst, value, strlen(value) + 1);
    return 1;
}

static int read_choice(ini_file *r, const ini_field *f, int *dst, const char *section, const char *key,
                       const char *value)
{
    char allowed[128] = "";
    for (int i = 0; f->choices[i]; i++) {
        if (!strcmp(value, f->choices[i])) {
            *dst = i;
            return 1;
        }
        size_t used = strlen(allowed);
        snprintf(allowed + used, sizeof allowed - used, "%s%s", i ? ", " : "", f->choices[i]);
    }
    return ini_file_fail(r, section, key, NULL, "'%s' is not one of %s", value, allowed);
}

int ini_table_value(ini_file *r, const ini_field *f, const ini_unit *u, void *obj, const char *section,
                    const char *key, const char *value)
{
    void *dst = (char *)obj + f->offset;
    switch (f->type) {
    case INI_REAL: return read_real(r, f, u, dst, section, key, value);
    case INI_DECIMAL: return read_decimal(r, f, dst, section, key, value);
    case INI_BOOL: return read_bool(r, dst, section, key, value);
    case INI_TEXT: return read_text(r, f, dst, section, key, value);
    case INI_CHOICE: return read_choice(r, f, dst, section, key, value);
    case INI_CUSTOM: return f->fn(r, f, obj, section, key, value);
    }
    return 0;
}

