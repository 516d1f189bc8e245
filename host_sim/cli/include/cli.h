/*
 * The one command style of the leveler programs (issue 22): getopt_long with
 * --opt=value and --opt value alike, --help (exit 0) and --version on every
 * program, one help layout (usage line, one line per option, exit codes) and
 * one set of exit codes.
 *
 * A program lists its options once (cli_option), cli_parse() runs getopt_long
 * over them and hands each to the program's callback; the help text is made
 * from the same list, so the two cannot drift.
 */
#ifndef LEVELER_CLI_H
#define LEVELER_CLI_H

#include <stdio.h>

/* Exit codes of every leveler program. */
enum {
    CLI_EXIT_OK = 0,        /* done */
    CLI_EXIT_FAILED = 1,    /* the job failed (a run, a connection, a write) */
    CLI_EXIT_BAD_INPUT = 2, /* bad input: an option, a config, a file that cannot be read */
    CLI_CONTINUE = -1       /* cli_parse(): go on and do the job */
};

typedef struct {
    const char *name; /* long name without "--"; NULL ends the list */
    int key;          /* handed to the callback; a letter gives the short option -<letter> too */
    const char *arg;  /* the value's name in the help (FILE, S, 1|2|3), NULL = a flag */
    const char *help; /* one line; "\n" continues it on the next line, indented */
    int required;     /* 1: cli_parse() refuses to go on without it */
} cli_option;

typedef struct {
    const char *prog;       /* leveler-sim */
    const char *usage;      /* after the program name; "\n" continues on the next line, "\n|" starts another form */
    const char *about;      /* one sentence under the usage line */
    const cli_option *opts; /* --help and --version are added */
    const char *exit_extra; /* extra exit-code lines (e.g. "130 interrupted"), or NULL */
    int max_operands;       /* positional arguments allowed (0 for most programs) */
} cli_spec;

/* One option: 0, or CLI_EXIT_BAD_INPUT after a message (cli_bad_value). */
typedef int (*cli_handler)(void *user, int key, const char *value);

/*
 * getopt_long over spec->opts plus --help/-h and --version. Returns
 * CLI_CONTINUE with *operands set to the index of the first positional
 * argument (if operands is not NULL), 0 after --help or --version (printed on
 * stdout), or CLI_EXIT_BAD_INPUT after a message on stderr.
 */
int cli_parse(const cli_spec *spec, int argc, char **argv, cli_handler on_option, void *user, int *operands);

void cli_help(const cli_spec *spec, FILE *f);
void cli_version(const char *prog, FILE *f);
/* "PROG: --name: 'value' is not <what>": returns CLI_EXIT_BAD_INPUT. */
int cli_bad_value(const cli_spec *spec, const char *name, const char *value, const char *what);
/* A whole-string number in [lo, hi]: 0, or CLI_EXIT_BAD_INPUT after a message naming the option. */
int cli_double(const cli_spec *spec, const char *name, const char *value, double lo, double hi, double *out);
int cli_int(const cli_spec *spec, const char *name, const char *value, long lo, long hi, int *out);
/* The option by key (for messages). */
const char *cli_name_of(const cli_spec *spec, int key);

#endif
