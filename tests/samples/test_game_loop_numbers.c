/* The game-loop sample takes --frames and --grid only as whole numbers in their ranges (1..100000
 * and 2..512): anything else is refused with exit status 2 and a message naming the option,
 * before weft is set up; a small good run passes. argv: game_loop binary, output folder. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, mkdir */
#include "test.h"

#include "tools/tool_run.h"

#include <sys/stat.h>

static const char *g_exe;
static char g_stdout[1100], g_stderr[1100];

static void refused(const char *option, const char *value)
{
    const char *argv[] = {g_exe, option, value, "--quiet", NULL};
    const int rc = tool_run_err(argv, g_stdout, g_stderr);
    static char text[4096];
    tool_slurp(g_stderr, text, sizeof text);
    CHECK_MSG(rc == 2 && strstr(text, option) != NULL, "%s '%s': exit %d, stderr: %.300s", option, value, rc, text);
}

static void bad_numbers_refused(void)
{
    static const char *const bad[] = {"abc", "2x", "3.7", "-1", "99999999999999999999", "nan", "", " 5", "+5",
                                      "0x10", "1e3", "5 ", "4294967297"};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        refused("--frames", bad[k]);
        refused("--grid", bad[k]);
    }
    refused("--frames", "0");
    refused("--frames", "100001");
    refused("--grid", "1");
    refused("--grid", "513");
}

static void good_numbers_run(void)
{
    const char *argv[] = {g_exe, "--frames", "2", "--grid", "4", "--quiet", NULL};
    CHECK_EQ_INT(tool_run_err(argv, g_stdout, g_stderr), 0);
    static char text[4096];
    tool_slurp(g_stdout, text, sizeof text);
    CHECK_MSG(strstr(text, "2 frames") != NULL, "%s", text);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s GAME_LOOP OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    mkdir(argv[2], 0777);
    snprintf(g_stdout, sizeof g_stdout, "%s/stdout.txt", argv[2]);
    snprintf(g_stderr, sizeof g_stderr, "%s/stderr.txt", argv[2]);
    static const test_case_ cases[] = {TEST_CASE(bad_numbers_refused), TEST_CASE(good_numbers_run)};
    return test_run_(cases, sizeof cases / sizeof cases[0], argc - 2, argv + 2);
}
