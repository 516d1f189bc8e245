/* INI checks libinih leaves to its caller (ini_guard.h). */
#define _POSIX_C_SOURCE 200809L
#include "ini_guard.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

struct ini_guard_entry {
    char *section;
    char *key; /* NULL for the section itself */
    unsigned line;
};

int ini_guard_open(ini_guard *g, const char *path, char *err, size_t err_len)
{
    memset(g, 0, sizeof *g);
    g->path = path;
    g->file = fopen(path, "r");
    if (g->file == NULL) {
        snprintf(err, err_len, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    struct stat st;
    if (fstat(fileno(g->file), &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(err, err_len, "%s: not a regular file (%s)", path,
                 S_ISDIR(st.st_mode) ? "a directory" : "a device, pipe or socket");
        fclose(g->file);
        g->file = NULL;
        return -1;
    }
    return 0;
}

int ini_guard_open_text(ini_guard *g, const char *name, const char *text, char *err, size_t err_len)
{
    memset(g, 0, sizeof *g);
    g->path = name;
    g->file = fmemopen((void *)text, strlen(text), "r");
    if (g->file == NULL) {
        snprintf(err, err_len, "%s: cannot open: %s", name, strerror(errno));
        return -1;
    }
    return 0;
}

static ini_guard_entry *find(ini_guard *g, const char *section, const char *key)
{
    for (size_t i = 0; i < g->n_seen; i++) {
        ini_guard_entry *e = &g->seen[i];
        if (!strcmp(e->section, section) && ((key == NULL && e->key == NULL) || (key && e->key && !strcmp(e->key, key))))
            return e;
    }
    return NULL;
}

static int remember(ini_guard *g, const char *section, const char *key)
{
    if (g->n_seen == g->cap_seen) {
        size_t cap = g->cap_seen ? 2 * g->cap_seen : 32;
        ini_guard_entry *n = realloc(g->seen, cap * sizeof *n);
        if (n == NULL)
            return -1;
        g->seen = n;
        g->cap_seen = cap;
    }
    ini_guard_entry *e = &g->seen[g->n_seen];
    e->section = strdup(section);
    e->key = key ? strdup(key) : NULL;
    e->line = g->line;
    if (e->section == NULL || (key && e->key == NULL)) {
        free(e->section);
        free(e->key);
        return -1;
    }
    g->n_seen++;
    return 0;
}

/* A "[name]" line (as inih reads it: the name runs to the first ']'): checks it is new. */
static bool section_line_ok(ini_guard *g, const char *line)
{
    const char *p = line;
    if (g->line == 1 && !strncmp(p, "\xEF\xBB\xBF", 3))
        p += 3;
    while (*p == ' ' || *p == '\t')
        p++;
    if (*p != '[')
        return true;
    const char *end = strchr(p + 1, ']');
    if (end == NULL)
        return true; /* inih reports the syntax error */
    char name[256];
    snprintf(name, sizeof name, "%.*s", (int)(end - p - 1), p + 1);
    ini_guard_entry *e = find(g, name, NULL);
    if (e != NULL) {
        snprintf(g->failure, sizeof g->failure, "%s:%u: [%s]: section repeated (first at line %u); keep one",
                 g->path, g->line, name, e->line);
        return false;
    }
    if (remember(g, name, NULL) != 0) {
        snprintf(g->failure, sizeof g->failure, "%s:%u: out of memory", g->path, g->line);
        return false;
    }
    return true;
}

char *ini_guard_reader(char *str, int num, void *guard)
{
    ini_guard *g = guard;
    if (g->failure[0] || fgets(str, num, g->file) == NULL)
        return NULL;
    g->line++;
    size_t len = strlen(str);
    if (len > 0 && str[len - 1] != '\n') {
        int c = fgetc(g->file);
        if (c != EOF) {
            snprintf(g->failure, sizeof g->failure, "%s:%u: line longer than %d characters", g->path, g->line,
                     num - 2);
            return NULL;
        }
    }
    const char *p = str;
    g->continuation = (*p == ' ' || *p == '\t');
    while (*p == ' ' || *p == '\t')
        p++;
    if (*p == '\n' || *p == '\r' || *p == ';' || *p == '#' || *p == '\0' || *p == '[')
        g->continuation = false;
    if (!section_line_ok(g, str))
        return NULL;
    return str;
}

int ini_guard_key(ini_guard *g, const char *section, const char *key, char *err, size_t err_len)
{
    if (g->continuation)
        return 0;
    ini_guard_entry *e = find(g, section, key);
    if (e != NULL) {
        snprintf(err, err_len, "%s:%u: [%s] %s: repeated (first at line %u); keep one", g->path, g->line, section, key,
                 e->line);
        return -1;
    }
    if (remember(g, section, key) != 0) {
        snprintf(err, err_len, "%s:%u: out of memory", g->path, g->line);
        return -1;
    }
    return 0;
}

int ini_guard_finish(ini_guard *g, int rc, char *err, size_t err_len)
{
    if (g->failure[0]) {
        snprintf(err, err_len, "%s", g->failure);
        return -1;
    }
    if (rc > 0) {
        snprintf(err, err_len, "%s:%d: syntax error (expected [section] or key = value)", g->path, rc);
        return -1;
    }
    if (rc < 0 || ferror(g->file)) {
        snprintf(err, err_len, "%s: cannot read", g->path);
        return -1;
    }
    return 0;
}

void ini_guard_close(ini_guard *g)
{
    if (g->file)
        fclose(g->file);
    for (size_t i = 0; i < g->n_seen; i++) {
        free(g->seen[i].section);
        free(g->seen[i].key);
    }
    free(g->seen);
    memset(g, 0, sizeof *g);
}

bool ini_utf8_valid(const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    while (*p) {
        unsigned c = *p, n;
        uint32_t cp;
        if (c < 0x80) {
            p++;
            continue;
        } else if (c >= 0xC2 && c <= 0xDF) {
            n = 1, cp = c & 0x1F;
        } else if (c >= 0xE0 && c <= 0xEF) {
            n = 2, cp = c & 0x0F;
        } else if (c >= 0xF0 && c <= 0xF4) {
            n = 3, cp = c & 0x07;
        } else {
            return false;
        }
        for (unsigned i = 1; i <= n; i++) {
            if ((p[i] & 0xC0) != 0x80)
                return false;
            cp = (cp << 6) | (p[i] & 0x3F);
        }
        if ((n == 2 && cp < 0x800) || (n == 3 && cp < 0x10000) || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
            return false;
        p += n + 1;
    }
    return true;
}
