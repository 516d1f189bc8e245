/*
 * The one table-driven INI reader of the project's configs (the plant's,
 * plant_config_schema.c, and the rig's, rig_config_schema.c): a config is a
 * table of fields (section, key, type, unit, range, offset into the config)
 * read with libinih through ini_guard.h by one handler.
 *
 * - [name.X] sections: a field whose section is "name." is read from every
 *   [name.X] the table has no fields of its own for; the table's instance
 *   hook turns X into the object (a band, a channel, an output) and an index;
 * - INI_REAL fields whose unit kind has units take the unit as a key suffix
 *   (volume_in3); the value is converted to SI and its range checked in SI,
 *   the message giving it in the file's unit; a quantity given twice in one
 *   file, even under two units, is an error;
 * - every error has one format, "path:line: [section] key = value: reason";
 *   the "= value" is left out when the reason quotes the value itself.
 */
#ifndef LEVELER_INI_TABLE_H
#define LEVELER_INI_TABLE_H

#include <stdbool.h>
#include <stddef.h>

#include "ini_guard.h"

typedef enum {
    INI_REAL,    /* a number (strtod), in its unit; min..max in SI */
    INI_DECIMAL, /* a decimal integer without leading zeros in min..max */
    INI_BOOL,    /* true/false, yes/no, on/off, 1/0 (bool) */
    INI_TEXT,    /* UTF-8 text shorter than size (char[size]) */
    INI_CHOICE,  /* one of choices -> its index (int, or an enum) */
    INI_CUSTOM,  /* read by fn */
} ini_type;

/* How an INI_REAL or INI_DECIMAL is stored. */
typedef enum { INI_F64, INI_INT, INI_U8, INI_U16, INI_U32, INI_U64 } ini_store;

typedef struct ini_file ini_file;

/* A key read by hand (field f): 1 done, 0 failed (ini_file_fail called). obj as for the table's fields. */
typedef struct ini_field ini_field;
typedef int (*ini_key_fn)(ini_file *r, const ini_field *f, void *obj, const char *section, const char *key,
                          const char *value);

struct ini_field {
    const char *section; /* "name": [name]; "name.": every [name.X] (a more exact [name.X] first) */
    const char *key;     /* INI_REAL with units: the base, written key_SUFFIX */
    ini_type type;
    ini_store store;
    size_t offset;              /* into the config, or into the [name.X] instance */
    double min, max;            /* INI_REAL: SI; INI_DECIMAL: integers */
    int unit;                   /* INI_REAL: unit kind; a kind without units is a plain key */
    size_t size;                /* INI_TEXT: the buffer's size */
    const char *const *choices; /* INI_CHOICE: NULL-terminated */
    ini_key_fn fn;              /* INI_CUSTOM */
};

typedef struct {
    int kind;
    const char *suffix;
    double factor; /* SI = value * factor (+ the table's gauge offset when gauge) */
    bool gauge;    /* stored as value * factor: the caller adds the offset once it is final */
} ini_unit;

typedef struct {
    const ini_field *fields;
    size_t field_count;
    const ini_unit *units;
    size_t unit_count;
    int max_instances; /* of any [name.X] (1 if none) */
    const char *see;   /* unknown keys and sections: "(see SEE)"; NULL: the section's keys are listed */
    /* [name.X] (its fields' section: group) -> the object the fields go into and
     * X's index (< max_instances); NULL after ini_file_fail (key: the key being read). */
    void *(*instance)(ini_file *r, const char *section, const char *group, const char *key, int *index);
    /* Sections read by hand: -1 when section is not one, else 1 read, 0 failed. */
    int (*other)(ini_file *r, const char *section, const char *key, const char *value);
    /* After a field was stored (u: the unit it was given in, NULL for none). */
    void (*stored)(ini_file *r, const ini_field *f, int index, const ini_unit *u);
    /* The SI offset of gauge units at the time a value is read (ambient pressure). */
    double (*gauge_offset)(const void *config);
} ini_table;

/* One load: a file and the files it includes, into one config. */
typedef struct {
    const ini_table *table;
    void *config; /* the fields' offsets are into this */
    void *user;   /* the caller's own state, for its hooks */
    char *err;
    size_t err_len;
    int failed;
} ini_load;

struct ini_file {
    ini_guard guard; /* the file, its real line numbers, repeated keys and sections */
    ini_load *load;
    int keys_seen;         /* keys read so far in this file */
    unsigned *given_line;  /* per field and instance: where it was given in this file; 0 = not yet */
};

/* Reads path into load->config: 0, or -1 with the first error in load->err. */
int ini_table_read(ini_load *load, const char *path);
/* The same for a text compiled into the program; name stands for the file in messages. */
int ini_table_read_text(ini_load *load, const char *name, const char *text);

/* Sets the load's error (the first one wins): "path:line: [section] key = value: reason";
 * value NULL leaves out " = value", key NULL "[section] key". Returns 0. */
__attribute__((format(printf, 5, 6))) int ini_file_fail(ini_file *r, const char *section, const char *key,
                                                        const char *value, const char *fmt, ...);

/* A decimal integer without leading zeros in lo..hi: 1, or 0 after ini_file_fail. */
int ini_file_decimal(ini_file *r, const char *section, const char *key, const char *value, long long lo,
                     long long hi, long long *out);

/* "_pa, _kpa, ..": the key suffixes of a unit kind. */
void ini_table_unit_list(const ini_table *t, int kind, char *buf, size_t len);

/* A number (strtod, trailing blanks allowed): 0, or -1 if value is not one. */
int ini_parse_number(const char *value, double *out);

#endif
