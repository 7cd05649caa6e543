/* weft command-line tool: dispatches `weft <command>` and `weft bench <name>`. */
#include "weft.h"

#include <stdio.h>
#include <string.h>

typedef int weft_command_fn(int argc, char **argv);

#define WEFT_COMMAND(n) weft_command_fn weft_cmd_##n; extern const char weft_cmd_##n##_help[];
#define WEFT_BENCH(n) weft_command_fn weft_bench_##n; extern const char weft_bench_##n##_help[];
#include "registry.inc"
#undef WEFT_COMMAND
#undef WEFT_BENCH

typedef struct entry {
    const char *name;
    weft_command_fn *fn;
    const char *help;
} entry;

#define WEFT_COMMAND(n) {#n, weft_cmd_##n, weft_cmd_##n##_help},
#define WEFT_BENCH(n)
static const entry g_commands[] = {
#include "registry.inc"
    {NULL, NULL, NULL}};
#undef WEFT_COMMAND
#undef WEFT_BENCH

#define WEFT_COMMAND(n)
#define WEFT_BENCH(n) {#n, weft_bench_##n, weft_bench_##n##_help},
static const entry g_benches[] = {
#include "registry.inc"
    {NULL, NULL, NULL}};
#undef WEFT_COMMAND
#undef WEFT_BENCH

static void usage(FILE *out)
{
    fprintf(out, "usage: weft <command> [options]   (weft <command> --help for details)\n\ncommands:\n");
    fprintf(out, "  %-10s %s\n", "bench", "benchmarks: weft bench <name>, see below");
    fprintf(out, "  %-10s %s\n", "version", "print the version and the build/CPU configuration");
    for (const entry *e = g_commands; e->name; ++e) {
        fprintf(out, "  %-10s %s\n", e->name, e->help);
    }
    fprintf(out, "\nbenchmarks:\n");
    for (const entry *e = g_benches; e->name; ++e) {
        fprintf(out, "  bench %-10s %s\n", e->name, e->help);
    }
}

static int dispatch(const entry *table, int argc, char **argv)
{
    for (const entry *e = table; e->name; ++e) {
        if (strcmp(e->name, argv[0]) == 0) {
            return e->fn(argc, argv);
        }
    }
    fprintf(stderr, "weft: unknown command '%s'\n\n", argv[0]);
    usage(stderr);
    return 2;
}

int main(int argc, char **argv)
{
    if (argc < 2 || strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (strcmp(argv[1], "version") == 0 || strcmp(argv[1], "--version") == 0) {
        printf("%s\n", weft_config_string());
        return 0;
    }
    if (strcmp(argv[1], "bench") == 0) {
        if (argc < 3) {
            usage(stderr);
            return 2;
        }
        return dispatch(g_benches, argc - 2, argv + 2);
    }
    return dispatch(g_commands, argc - 1, argv + 1);
}
