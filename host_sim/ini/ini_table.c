/* The table-driven INI reader (ini_table.h): one handler for every config. */
#define _POSIX_C_SOURCE 200809L
#include "ini_table.h"
#include "ini_values.h"

#include <ini.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int ini_file_fail(ini_file *r, const char *section, const char *key, const char *value, const char *fmt, ...)
{
    ini_load *l = r->load;
    if (l->failed)
        return 0;
    l->failed = 1;
    char reason[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    const char *path = r->guard.path;
    if (!key)
        snprintf(l->err, l->err_len, "%s:%u: %s", path, r->guard.line, reason);
    else if (!value)
        snprintf(l->err, l->err_len, "%s:%u: [%s] %s: %s", path, r->guard.line, section, key, reason);
    else
        snprintf(l->err, l->err_len, "%s:%u: [%s] %s = %s: %s", path, r->guard.line, section, key, value, reason);
    return 0;
}

void ini_table_unit_list(const ini_table *t, int kind, char *buf, size_t len)
{
    buf[0] = 0;
    for (size_t i = 0; i < t->unit_count; i++)
        if (t->units[i].kind == kind) {
            size_t used = strlen(buf);
            snprintf(buf + used, len - used, "%s_%s", used ? ", " : "", t->units[i].suffix);
        }
}

static bool has_units(const ini_table *t, int kind)
{
    for (size_t i = 0; i < t->unit_count; i++)
        if (t->units[i].kind == kind)
            return true;
    return false;
}

/* ---- the handler ---- */

/* The table's name for section's fields ("name" or "name."), NULL if none. */
static const char *section_group(const ini_table *t, const char *section)
{
    const char *prefix = NULL;
    for (size_t i = 0; i < t->field_count; i++) {
        const char *s = t->fields[i].section;
        size_t n = strlen(s);
        if (!strcmp(s, section))
            return s;
        if (n && s[n - 1] == '.' && !strncmp(s, section, n) && section[n])
            prefix = s;
    }
    return prefix;
}

/* Does key name field f (with one of its units)? 1 (*u the unit, NULL for a plain key),
 * 0 if not, -1 if the base matches but the suffix is no unit of f's. */
static int match_key(const ini_table *t, const ini_field *f, const char *key, const ini_unit **u)
{
    size_t bl = strlen(f->key);
    *u = NULL;
    if (strncmp(key, f->key, bl) != 0)
        return 0;
    if (f->type != INI_REAL || !has_units(t, f->unit))
        return key[bl] == 0;
    if (key[bl] != '_')
        return 0;
    for (size_t j = 0; j < t->unit_count; j++)
        if (t->units[j].kind == f->unit && strcmp(t->units[j].suffix, key + bl + 1) == 0)
            *u = &t->units[j];
    return *u ? 1 : -1;
}

/* Field i of instance index in obj, given as key = value in unit u. */
static int read_field(ini_file *r, size_t i, int index, void *obj, const ini_unit *u, const char *section,
                      const char *key, const char *value)
{
    const ini_table *t = r->load->table;
    const ini_field *f = &t->fields[i];
    unsigned *given = &r->given_line[i * (size_t)t->max_instances + (size_t)index];
    if (*given)
        return ini_file_fail(r, section, key, value, "%s given twice in this file (first at line %u%s)", f->key,
                             *given, has_units(t, f->unit) ? ", possibly under another unit" : "");
    *given = r->guard.line;
    if (!ini_table_value(r, f, u, obj, section, key, value) || r->load->failed)
        return 0;
    if (t->stored)
        t->stored(r, f, index, u);
    return 1;
}

static int unknown_key(ini_file *r, const char *group, const char *section, const char *key)
{
    const ini_table *t = r->load->table;
    if (t->see)
        return ini_file_fail(r, section, key, NULL, "unknown key (see %s)", t->see);
    char list[512] = "";
    for (size_t i = 0; i < t->field_count; i++)
        if (!strcmp(t->fields[i].section, group)) {
            size_t used = strlen(list);
            snprintf(list + used, sizeof list - used, "%s%s", used ? ", " : "", t->fields[i].key);
        }
    return ini_file_fail(r, section, key, NULL, "unknown key (allowed %s)", list);
}

/* key = value of a [section] the table has fields for (group: their section). */
static int read_key(ini_file *r, const char *group, const char *section, const char *key, const char *value)
{
    const ini_table *t = r->load->table;
    int index = 0;
    void *obj = r->load->config;
    if (strchr(group, '.') && (obj = t->instance(r, section, group, key, &index)) == NULL)
        return 0;
    long base_matched = -1;
    for (size_t i = 0; i < t->field_count; i++) {
        const ini_unit *u;
        int m = strcmp(t->fields[i].section, group) == 0 ? match_key(t, &t->fields[i], key, &u) : 0;
        if (m > 0)
            return read_field(r, i, index, obj, u, section, key, value);
        if (m < 0)
            base_matched = (long)i;
    }
    if (base_matched < 0)
        return unknown_key(r, group, section, key);
    const ini_field *f = &t->fields[base_matched];
    char list[256];
    ini_table_unit_list(t, f->unit, list, sizeof list);
    return ini_file_fail(r, section, key, value, "unit suffix not allowed for %s; use %s%s", f->key, f->key, list);
}

static int handler(void *user, const char *section, const char *key, const char *value)
{
    ini_file *r = user;
    ini_load *l = r->load;
    if (l->failed)
        return 0;
    if (ini_guard_key(&r->guard, section, key, l->err, l->err_len) != 0) {
        l->failed = 1;
        return 0;
    }
    r->keys_seen++;
    if (l->table->other) {
        int rc = l->table->other(r, section, key, value);
        if (rc >= 0)
            return rc && !l->failed;
    }
    const char *group = section_group(l->table, section);
    if (!group) {
        const char *see = l->table->see;
        return ini_file_fail(r, section, key, NULL, "unknown section [%s]%s%s%s", section, see ? " (see " : "",
                             see ? see : "", see ? ")" : "");
    }
    return read_key(r, group, section, key, value);
}

/* Parses the opened guard into the load. */
static int read_guarded(ini_load *load, ini_file *r)
{
    const ini_table *t = load->table;
    r->load = load;
    r->given_line = calloc(t->field_count * (size_t)t->max_instances, sizeof *r->given_line);
    if (!r->given_line) {
        ini_guard_close(&r->guard);
        snprintf(load->err, load->err_len, "%s: out of memory", r->guard.path);
        load->failed = 1;
        return -1;
    }
    int rc = ini_parse_stream(ini_guard_reader, &r->guard, handler, r);
    if (!load->failed && ini_guard_finish(&r->guard, rc, load->err, load->err_len) != 0)
        load->failed = 1;
    ini_guard_close(&r->guard);
    free(r->given_line);
    return load->failed ? -1 : 0;
}

/* path, or text standing for a file named path, into the load. */
static int read_source(ini_load *load, const char *path, const char *text)
{
    ini_file *r = calloc(1, sizeof *r);
    char err[512];
    int opened = !r     ? -1
                 : text ? ini_guard_open_text(&r->guard, path, text, err, sizeof err)
                        : ini_guard_open(&r->guard, path, err, sizeof err);
    if (opened != 0) {
        if (!load->failed)
            snprintf(load->err, load->err_len, "%s", r ? err : "out of memory");
        load->failed = 1;
        free(r);
        return -1;
    }
    int rc = read_guarded(load, r);
    free(r);
    return rc;
}

int ini_table_read(ini_load *load, const char *path)
{
    return read_source(load, path, NULL);
}

int ini_table_read_text(ini_load *load, const char *name, const char *text)
{
    return read_source(load, name, text);
}
