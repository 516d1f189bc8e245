/*
 * What libinih leaves to its caller, done once for every INI file the
 * project reads (the rig config and the simulator's plant config):
 *
 * - a directory (or anything but a regular file) is refused at open;
 * - the line number the handler sees is the file's real line, and a line
 *   longer than inih's buffer is an error at that line (inih would cut it
 *   into several lines, each parsed on its own);
 * - a repeated [section] or a repeated key within one file is an error
 *   naming both lines (last-value-wins would let a second `read_only = false`
 *   undo the first silently).
 * Multi-line values (an indented line continuing a key) are not repeats.
 *
 * Use: ini_guard_open(), ini_parse_stream(ini_guard_reader, guard, handler, ..),
 * ini_guard_key() from the handler, ini_guard_finish(), ini_guard_close().
 */
#ifndef LEVELER_INI_GUARD_H
#define LEVELER_INI_GUARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

typedef struct ini_guard_entry ini_guard_entry;

typedef struct {
    FILE *file;
    const char *path;
    unsigned line;         /* the line the handler is looking at */
    bool continuation;     /* that line continues the previous key's value */
    char failure[320];     /* set by the reader: why parsing stopped */
    ini_guard_entry *seen; /* sections and keys with their first line */
    size_t n_seen, cap_seen;
} ini_guard;

/* 0, or -1 with "path: reason" in err (missing, unreadable, a directory). */
int ini_guard_open(ini_guard *g, const char *path, char *err, size_t err_len);
/* The same for a text compiled into the program; name stands for its file in messages. */
int ini_guard_open_text(ini_guard *g, const char *name, const char *text, char *err, size_t err_len);
char *ini_guard_reader(char *str, int num, void *guard);
/* 0 the first time a key is seen in its section; -1 with
 * "path:line: [section] key: repeated (first at line N)" in err. */
int ini_guard_key(ini_guard *g, const char *section, const char *key, char *err, size_t err_len);
/* After ini_parse_stream returned rc: 0, or -1 with the reader's failure or
 * inih's syntax error ("path:line: ...") in err. */
int ini_guard_finish(ini_guard *g, int rc, char *err, size_t err_len);
void ini_guard_close(ini_guard *g);

/* true when s is well-formed UTF-8 (no overlongs, surrogates or > U+10FFFF). */
bool ini_utf8_valid(const char *s);

#endif
