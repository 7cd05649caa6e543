/* The commands' option parsing: a table of options per command, read by getopt_long, with the
 * --help text generated from the same table; and numeric option values, parsed whole: the entire string is the number (no sign unless the
 * range allows negatives, no spaces, no trailing text, no overflow, nothing but finite numbers)
 * and it lies in [lo, hi]. On failure each prints "<tool>: <option> wants <what> in [lo, hi],
 * got '<value>'" to stderr and returns false, leaving *out unchanged. Commands exit with status 2
 * (a usage error) when one fails, before doing any work. */
#ifndef WEFT_SUPPORT_CLI_H
#define WEFT_SUPPORT_CLI_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <getopt.h>
#include <stdio.h>

/* ---- Options ---------------------------------------------------------------------------------
 * A command lists its options once, as a table ending in {0}; cli_next walks argv with
 * getopt_long (so `--name value`, `--name=value`, unambiguous prefixes, and positional arguments
 * anywhere all work) and cli_usage prints the help from the same table. -h and --help are
 * built in: they print the help and stop. Every message names the tool and the option; a usage
 * error prints one line and a pointer to --help and stops with 2, before the command does any
 * work. The loop of every command:
 *
 *   cli_parser cli;
 *   cli_start(&cli, &k_command, argc, argv);
 *   for (int id; (id = cli_next(&cli, &value)) != CLI_END;) {
 *       switch (id) {
 *       case CLI_STOP: return cli.exit;
 *       case OPT_FRAMES: ... cli_u32(...) ...; break;
 *       }
 *   }
 */

enum {
    CLI_END = -1,   /* no options left: positional arguments are cli_rest() */
    CLI_STOP = -2,  /* stop with exit status parser.exit: 0 after printing --help, 2 after reporting
                     * a usage error (unknown option, missing value, ambiguous prefix) */
    CLI_MAX_OPTIONS = 96,
};

typedef struct cli_option {
    const char *name;   /* the long name without "--" */
    const char *value;  /* the value's name in the help ("N", "on|off"); NULL: a flag without one */
    int id;             /* what cli_next returns for this option; >= 1 */
    const char *help;   /* its help, lines separated by '\n'; NULL: accepted but not listed (an alias) */
} cli_option;

typedef struct cli_command {
    const char *tool;             /* "weft quantize": the prefix of every message */
    const char *synopsis;         /* printed after "usage: "; may span lines */
    const char *about;            /* printed between the synopsis and the options; may be NULL */
    const cli_option *options;    /* ends with an entry whose name is NULL */
    void (*notes)(FILE *out);     /* optional text after the options (defaults known at run time) */
} cli_command;

typedef struct cli_parser {
    const cli_command *cmd;
    int argc;
    char **argv;
    int count;                    /* options in the table */
    int exit;                     /* with CLI_STOP: the command's exit status */
    bool done;
    bool malformed;               /* the table failed cli_start's checks */
    int first_positional;         /* argv index of the first positional argument, after CLI_END */
    char short_opts[4];
    struct option table[CLI_MAX_OPTIONS + 2]; /* getopt_long's view of the options */
} cli_parser;

/* Prepares to read argv[1..argc) (argv[0] is the command's name). A malformed table (too many
 * options, a duplicate name or id, an id below 1) is reported by the first cli_next, which then
 * stops with 2. */
void cli_start(cli_parser *p, const cli_command *cmd, int argc, char **argv);
/* The next option: its id with *value set (NULL for a flag), CLI_END, or CLI_STOP. */
int cli_next(cli_parser *p, const char **value);
/* After CLI_END: the positional arguments, in their order on the command line. */
int cli_rest(const cli_parser *p, char ***rest);
/* After CLI_END, for a command that takes no positional argument: 0, or 2 after reporting the
 * first one as unexpected. */
int cli_no_rest(const cli_parser *p);
/* "--name" of an option id, for messages ("?" if unknown). */
const char *cli_name(const cli_command *cmd, int id);
/* The help: usage line, about, the options with their help, the notes. */
void cli_usage(const cli_command *cmd, FILE *out);
/* Reports "<tool>: <what>" and the pointer to --help on stderr; returns 2 (the usage exit). */
int cli_fail(const cli_command *cmd, const char *what);

bool cli_u32(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out);
bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out);
bool cli_float(const char *tool, const char *option, const char *value, float lo, float hi, float *out);
bool cli_double(const char *tool, const char *option, const char *value, double lo, double hi, double *out);

/* One of two words: *out false for `no`, true for `yes`; anything else is reported ("<tool>: <option>
 * takes <no> or <yes>") and leaves *out untouched. */
bool cli_either(const char *tool, const char *option, const char *value, const char *no, const char *yes, bool *out);

/* "5,10,20": one to cap comma-separated whole numbers, each in [lo, hi] (no empty items). Writes
 * out[0 .. *count) only on success. */
bool cli_u32_list(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out,
                  size_t cap, size_t *count);

/* "1000,8,0.5": exactly n comma-separated numbers, each in [lo, hi]. Writes out[0 .. n) only on
 * success. */
bool cli_floats(const char *tool, const char *option, const char *value, float lo, float hi, float *out, size_t n);

#endif
