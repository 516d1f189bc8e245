/* The command style every leveler program shares: see cli.h. */
#define _GNU_SOURCE /* getopt_long */
#include "cli.h"

#include <ctype.h>
#include <stdbool.h>
#include <errno.h>
#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#include "leveler/version.h"

#define CLI_MAX_OPTIONS 40
#define CLI_KEY_HELP 'h'
#define CLI_KEY_VERSION 0x7f01
#define CLI_HELP_COLUMN 26

void cli_version(const char *prog, FILE *f)
{
    fprintf(f, "%s %s\n", prog, LEVELER_VERSION);
}

/* One help line per option: "  -k, --name ARG   text", continued lines indented to the text. */
static void help_line(FILE *f, int key, const char *name, const char *arg, const char *help)
{
    char left[96];
    bool letter = key < 128 && isalpha(key);
    int n = letter ? snprintf(left, sizeof left, "  -%c, --%s%s%s", key, name, arg ? " " : "", arg ? arg : "")
                   : snprintf(left, sizeof left, "  --%s%s%s", name, arg ? " " : "", arg ? arg : "");
    fputs(left, f);
    if (n >= CLI_HELP_COLUMN) { /* a long option name: its text starts on the next line */
        fputc('\n', f);
        n = 0;
    }
    for (const char *p = help; *p;) {
        const char *nl = strchr(p, '\n');
        size_t len = nl ? (size_t)(nl - p) : strlen(p);
        fprintf(f, "%*s%.*s\n", n < CLI_HELP_COLUMN ? CLI_HELP_COLUMN - n : 1, "", (int)len, p);
        n = 0;
        p += len + (nl != NULL);
    }
}

void cli_help(const cli_spec *spec, FILE *f)
{
    /* usage lines: "\n" continues the form, "\n|" starts another form of the command */
    const char *u = spec->usage;
    fprintf(f, "usage: %s ", spec->prog);
    for (const char *nl; (nl = strchr(u, '\n')) != NULL; u = nl + 1) {
        fprintf(f, "%.*s\n", (int)(nl - u), u);
        if (nl[1] == '|') {
            fprintf(f, "       %s ", spec->prog);
            nl++;
        } else
            fprintf(f, "%*s", (int)strlen(spec->prog) + 8, "");
    }
    fprintf(f, "%s\n       %s --help | --version\n", u, spec->prog);
    if (spec->about)
        fprintf(f, "%s\n", spec->about);
    fprintf(f, "\noptions (--opt VALUE or --opt=VALUE):\n");
    for (const cli_option *o = spec->opts; o && o->name; o++)
        help_line(f, o->key, o->name, o->arg, o->help);
    help_line(f, CLI_KEY_HELP, "help", NULL, "this help, exit 0");
    help_line(f, CLI_KEY_VERSION, "version", NULL, "print the program's version, exit 0");
    fprintf(f, "\nexit codes: 0 done, 1 the job failed, 2 bad input (an option, a config, a file)%s%s\n",
            spec->exit_extra ? ", " : "", spec->exit_extra ? spec->exit_extra : "");
}

const char *cli_name_of(const cli_spec *spec, int key)
{
    for (const cli_option *o = spec->opts; o && o->name; o++)
        if (o->key == key)
            return o->name;
    return "?";
}

int cli_bad_value(const cli_spec *spec, const char *name, const char *value, const char *what)
{
    fprintf(stderr, "%s: --%s: '%s' is not %s\n", spec->prog, name, value, what);
    return CLI_EXIT_BAD_INPUT;
}

int cli_double(const cli_spec *spec, const char *name, const char *value, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(value, &end);
    if (end == value || *end || errno || !(v >= lo && v <= hi)) {
        char what[96];
        snprintf(what, sizeof what, "a number in [%g, %g]", lo, hi);
        return cli_bad_value(spec, name, value, what);
    }
    *out = v;
    return 0;
}

int cli_int(const cli_spec *spec, const char *name, const char *value, long lo, long hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(value, &end, 10);
    if (end == value || *end || errno || v < lo || v > hi) {
        char what[96];
        snprintf(what, sizeof what, "a whole number in [%ld, %ld]", lo, hi);
        return cli_bad_value(spec, name, value, what);
    }
    *out = (int)v;
    return 0;
}

/* getopt_long's table and short-option string from the program's list. */
static int build_table(const cli_spec *spec, struct option *lo, char *shorts)
{
    int n = 0, s = 0;
    shorts[s++] = ':'; /* a missing value returns ':' (our message, not getopt's) */
    for (const cli_option *o = spec->opts; o && o->name && n < CLI_MAX_OPTIONS - 3; o++, n++) {
        lo[n] = (struct option){o->name, o->arg ? required_argument : no_argument, NULL, o->key};
        if (o->key < 128 && isalpha(o->key)) {
            shorts[s++] = (char)o->key;
            if (o->arg)
                shorts[s++] = ':';
        }
    }
    lo[n++] = (struct option){"help", no_argument, NULL, CLI_KEY_HELP};
    lo[n++] = (struct option){"version", no_argument, NULL, CLI_KEY_VERSION};
    lo[n] = (struct option){0, 0, 0, 0};
    shorts[s++] = 'h';
    shorts[s] = '\0';
    return n;
}

static int bad_usage(const cli_spec *spec, const char *what, const char *arg)
{
    fprintf(stderr, "%s: %s '%s' (see %s --help)\n", spec->prog, what, arg, spec->prog);
    return CLI_EXIT_BAD_INPUT;
}

/* The first required option not given: exit 2 with its name, else CLI_CONTINUE. */
static int check_required(const cli_spec *spec, const unsigned char *seen)
{
    int i = 0;
    for (const cli_option *o = spec->opts; o && o->name && i < CLI_MAX_OPTIONS; o++, i++)
        if (o->required && !seen[i]) {
            fprintf(stderr, "%s: --%s%s%s is required (see %s --help)\n", spec->prog, o->name, o->arg ? " " : "",
                    o->arg ? o->arg : "", spec->prog);
            return CLI_EXIT_BAD_INPUT;
        }
    return CLI_CONTINUE;
}

static void mark_seen(const cli_spec *spec, int key, unsigned char *seen)
{
    int i = 0;
    for (const cli_option *o = spec->opts; o && o->name && i < CLI_MAX_OPTIONS; o++, i++)
        if (o->key == key)
            seen[i] = 1;
}

int cli_parse(const cli_spec *spec, int argc, char **argv, cli_handler on_option, void *user, int *operands)
{
    unsigned char seen[CLI_MAX_OPTIONS] = {0};
    struct option lo[CLI_MAX_OPTIONS];
    char shorts[2 * CLI_MAX_OPTIONS + 4];
    build_table(spec, lo, shorts);
    opterr = 0;
    optind = 0; /* glibc: start afresh */
    for (;;) {
        int prev = optind ? optind : 1;
        int key = getopt_long(argc, argv, shorts, lo, NULL);
        if (key == -1)
            break;
        if (key == CLI_KEY_HELP) {
            cli_help(spec, stdout);
            return CLI_EXIT_OK;
        }
        if (key == CLI_KEY_VERSION) {
            cli_version(spec->prog, stdout);
            return CLI_EXIT_OK;
        }
        if (key == ':')
            return bad_usage(spec, "this option needs a value:", argv[prev]);
        if (key == '?')
            return bad_usage(spec, "unknown option", argv[prev]);
        int rc = on_option(user, key, optarg);
        if (rc != 0)
            return rc;
        mark_seen(spec, key, seen);
    }
    if (argc - optind > spec->max_operands)
        return bad_usage(spec, "unexpected argument", argv[optind]);
    if (operands)
        *operands = optind;
    return check_required(spec, seen);
}
