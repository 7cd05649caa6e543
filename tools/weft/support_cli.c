/* Whole-string numeric option values (support_cli.h). */
#include "support_cli.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static bool digits_first(const char *v) { return v && v[0] >= '0' && v[0] <= '9'; }

/* A real number may start with a digit, or with '-' or '.' followed by something (strtod alone
 * skips spaces and takes "+5", "inf" and "nan"). */
static bool real_first(const char *v)
{
    return v && (digits_first(v) || ((v[0] == '-' || v[0] == '.') && v[1]));
}

/* The silent parsers: true with *out set, or false. */
static bool parse_whole(const char *v, uint64_t lo, uint64_t hi, uint64_t *out)
{
    if (!digits_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const unsigned long long n = strtoull(v, &end, 10);
    if (!end || *end || errno == ERANGE || n < lo || n > hi) {
        return false;
    }
    *out = (uint64_t)n;
    return true;
}

static bool parse_double(const char *v, double lo, double hi, double *out)
{
    if (!real_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const double x = strtod(v, &end);
    if (!end || *end || errno == ERANGE || !isfinite(x) || x < lo || x > hi) {
        return false;
    }
    *out = x;
    return true;
}

static bool parse_float(const char *v, float lo, float hi, float *out)
{
    if (!real_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const float x = strtof(v, &end);
    if (!end || *end || errno == ERANGE || !isfinite(x) || x < lo || x > hi) {
        return false;
    }
    *out = x;
    return true;
}

/* The next item of a comma-separated list into buf (cap bytes); false when it is too long. *p
 * moves past the item and its comma; *last tells whether it was the final item. */
static bool next_item(const char **p, char *buf, size_t cap, bool *last)
{
    const size_t len = strcspn(*p, ",");
    if (len >= cap) {
        return false;
    }
    memcpy(buf, *p, len);
    buf[len] = '\0';
    *last = (*p)[len] == '\0';
    *p += len + !*last;
    return true;
}

bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out)
{
    if (!parse_whole(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a whole number in [%llu, %llu], got '%s'\n", tool, option, (unsigned long long)lo,
                (unsigned long long)hi, value ? value : "");
        return false;
    }
    return true;
}

bool cli_u32(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out)
{
    uint64_t n = 0;
    if (!cli_u64(tool, option, value, lo, hi, &n)) {
        return false;
    }
    *out = (uint32_t)n;
    return true;
}

bool cli_float(const char *tool, const char *option, const char *value, float lo, float hi, float *out)
{
    if (!parse_float(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a number in [%g, %g], got '%s'\n", tool, option, (double)lo, (double)hi,
                value ? value : "");
        return false;
    }
    return true;
}

bool cli_double(const char *tool, const char *option, const char *value, double lo, double hi, double *out)
{
    if (!parse_double(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a number in [%g, %g], got '%s'\n", tool, option, lo, hi, value ? value : "");
        return false;
    }
    return true;
}

bool cli_either(const char *tool, const char *option, const char *value, const char *no, const char *yes, bool *out)
{
    if (!value || (strcmp(value, no) != 0 && strcmp(value, yes) != 0)) {
        fprintf(stderr, "%s: %s takes %s or %s\n", tool, option, no, yes);
        return false;
    }
    *out = strcmp(value, yes) == 0;
    return true;
}

bool cli_u32_list(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out,
                  size_t cap, size_t *count)
{
    uint32_t got[64];
    size_t n = 0;
    bool ok = value && *value && cap > 0 && cap <= sizeof got / sizeof got[0];
    for (const char *p = value; ok;) {
        char item[32];
        bool last = false;
        uint64_t x = 0;
        ok = n < cap && next_item(&p, item, sizeof item, &last) && parse_whole(item, lo, hi, &x);
        if (ok) {
            got[n++] = (uint32_t)x;
        }
        if (last) {
            break;
        }
    }
    if (!ok) {
        fprintf(stderr, "%s: %s wants 1 to %zu comma-separated whole numbers in [%lu, %lu], got '%s'\n", tool, option,
                cap, (unsigned long)lo, (unsigned long)hi, value ? value : "");
        return false;
    }
    memcpy(out, got, n * sizeof got[0]);
    *count = n;
    return true;
}

bool cli_floats(const char *tool, const char *option, const char *value, float lo, float hi, float *out, size_t n)
{
    float got[16];
    size_t k = 0;
    bool ok = value && n > 0 && n <= sizeof got / sizeof got[0];
    for (const char *p = value; ok;) {
        char item[64];
        bool last = false;
        ok = k < n && next_item(&p, item, sizeof item, &last) && parse_float(item, lo, hi, &got[k]);
        k += ok;
        if (last) {
            break;
        }
    }
    if (!ok || k != n) {
        fprintf(stderr, "%s: %s wants %zu comma-separated numbers in [%g, %g], got '%s'\n", tool, option, n, (double)lo,
                (double)hi, value ? value : "");
        return false;
    }
    memcpy(out, got, n * sizeof got[0]);
    return true;
}

/* ---- Options ------------------------------------------------------------------------------- */

enum { CLI_VAL_BASE = 1000, CLI_VAL_HELP = 999 };

/* The table entry getopt_long reported as c (or as optopt), or NULL. */
static const cli_option *option_of(const cli_parser *p, int c)
{
    return c >= CLI_VAL_BASE && c < CLI_VAL_BASE + p->count ? &p->cmd->options[c - CLI_VAL_BASE] : NULL;
}

void cli_start(cli_parser *p, const cli_command *cmd, int argc, char **argv)
{
    memset(p, 0, sizeof *p);
    p->cmd = cmd;
    p->argc = argc;
    p->argv = argv;
    int n = 0;
    for (const cli_option *o = cmd->options; o && o->name; ++o, ++n) {
        bool bad = n >= CLI_MAX_OPTIONS || o->id < 1 || o->name[0] == '\0' || strcmp(o->name, "help") == 0;
        for (const cli_option *q = cmd->options; !bad && q != o; ++q) {
            bad = strcmp(q->name, o->name) == 0 || q->id == o->id;
        }
        if (bad) {
            fprintf(stderr, "%s: internal error: option table entry '--%s' (id %d) is malformed\n", cmd->tool,
                    o->name ? o->name : "", o->id);
            p->malformed = true;
            return;
        }
        /* getopt_long returns 1000 + the option's index: no clash with its own ':', '?', 'h' */
        p->table[n] = (struct option){o->name, o->value ? required_argument : no_argument, NULL, CLI_VAL_BASE + n};
    }
    p->table[n] = (struct option){"help", no_argument, NULL, CLI_VAL_HELP};
    p->table[n + 1] = (struct option){NULL, 0, NULL, 0};
    p->count = n;
    /* ':' first: a missing value is told apart from an unknown option; "h": -h. */
    memcpy(p->short_opts, ":h", 3);
    /* getopt keeps its position in globals: start over (0 also resets GNU getopt's permutation). */
#ifdef __GLIBC__
    optind = 0;
#else
    optind = 1;
#endif
    opterr = 0;
}

int cli_next(cli_parser *p, const char **value)
{
    *value = NULL;
    if (p->malformed) {
        p->exit = 2;
        return CLI_STOP;
    }
    if (p->done) {
        return CLI_END;
    }
    const int before = optind;
    const int c = getopt_long(p->argc, p->argv, p->short_opts, p->table, NULL);
    if (c == -1) {
        p->done = true;
        p->first_positional = optind;
        return CLI_END;
    }
    if (c == 'h' || c == CLI_VAL_HELP) {
        cli_usage(p->cmd, stdout);
        p->exit = 0;
        return CLI_STOP;
    }
    p->exit = 2; /* any return below but the last is a usage error */
    /* the argument just read: getopt_long has moved optind past it (and its value) */
    const int at = optind - 1 >= 1 ? optind - 1 : before;
    const char *arg = at < p->argc ? p->argv[at] : "";
    char what[512];
    const cli_option *bad = option_of(p, optopt);
    if (c == ':') {
        if (bad) {
            snprintf(what, sizeof what, "--%s needs a value", bad->name);
        } else {
            snprintf(what, sizeof what, "%s needs a value", arg);
        }
        return cli_fail(p->cmd, what), CLI_STOP;
    }
    if (c == '?') {
        const bool is_long = strncmp(arg, "--", 2) == 0;
        const bool prefix = optopt == 0 && is_long;
        if (bad && is_long) {
            /* a value given to a flag (--flag=x) */
            snprintf(what, sizeof what, "--%s takes no value", bad->name);
        } else if (prefix) {
            size_t len = strcspn(arg + 2, "=");
            int matches = 0;
            for (int k = 0; k < p->count; ++k) {
                matches += strncmp(p->table[k].name, arg + 2, len) == 0;
            }
            snprintf(what, sizeof what, "%s option '%.*s'", matches > 1 ? "ambiguous" : "unknown", (int)(len + 2), arg);
        } else {
            snprintf(what, sizeof what, "unknown option '%s'", arg);
        }
        return cli_fail(p->cmd, what), CLI_STOP;
    }
    const cli_option *o = option_of(p, c);
    if (!o) {
        return cli_fail(p->cmd, "internal error: getopt_long returned an unknown option"), CLI_STOP;
    }
    *value = optarg;
    return o->id;
}

int cli_rest(const cli_parser *p, char ***rest)
{
    const int first = p->done ? p->first_positional : p->argc;
    *rest = p->argv + first;
    return p->argc - first;
}

int cli_no_rest(const cli_parser *p)
{
    char **rest;
    if (cli_rest(p, &rest) == 0) {
        return 0;
    }
    char what[300];
    snprintf(what, sizeof what, "unexpected argument '%.200s'", rest[0]);
    return cli_fail(p->cmd, what);
}

const char *cli_name(const cli_command *cmd, int id)
{
    static char name[96];
    for (const cli_option *o = cmd->options; o && o->name; ++o) {
        if (o->id == id) {
            snprintf(name, sizeof name, "--%s", o->name);
            return name;
        }
    }
    return "?";
}

int cli_fail(const cli_command *cmd, const char *what)
{
    fprintf(stderr, "%s: %s (%s --help lists the options)\n", cmd->tool, what, cmd->tool);
    return 2;
}

/* Prints text with every line after the first indented by `indent` spaces. */
static void print_indented(FILE *out, const char *text, int indent)
{
    for (const char *s = text; *s;) {
        const size_t len = strcspn(s, "\n");
        fprintf(out, "%.*s\n", (int)len, s);
        s += len + (s[len] == '\n');
        if (*s) {
            fprintf(out, "%*s", indent, "");
        }
    }
}

void cli_usage(const cli_command *cmd, FILE *out)
{
    enum { column = 28 };
    fprintf(out, "usage: ");
    print_indented(out, cmd->synopsis, 7);
    if (cmd->about && cmd->about[0]) {
        fprintf(out, "\n%s%s", cmd->about, cmd->about[strlen(cmd->about) - 1] == '\n' ? "" : "\n");
    }
    fprintf(out, "\noptions:\n");
    for (const cli_option *o = cmd->options; o && o->name; ++o) {
        if (!o->help) {
            continue;
        }
        char head[128];
        const int w = snprintf(head, sizeof head, "  --%s%s%s", o->name, o->value ? " " : "", o->value ? o->value : "");
        if (w + 2 > column) {
            fprintf(out, "%s\n%*s", head, column, "");
        } else {
            fprintf(out, "%-*s", column, head);
        }
        print_indented(out, o->help, column);
    }
    fprintf(out, "  %-*s%s\n", column - 2, "-h, --help", "this help");
    if (cmd->notes) {
        fprintf(out, "\n");
        cmd->notes(out);
    }
}
