/* `weft bench xpbd`: the sheet scene's --only run prints a trajectory hash that repeats; the
 * T-shirt scene drapes a small T-shirt on the avatar and prints the substeps table, S = 40 at
 * zero error against itself and the fast method's rows scored against it; a bad --scene fails
 * with a usage exit. argv: weft binary, output folder. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, mkdir */
#include "test.h"

#include "tool_run.h"

#include <stdbool.h>
#include <sys/stat.h>

static const char *g_exe, *g_out;

static void sheet_hash_repeats(void)
{
    char out1[1024], out2[1024];
    snprintf(out1, sizeof out1, "%s/sheet1.txt", g_out);
    snprintf(out2, sizeof out2, "%s/sheet2.txt", g_out);
    const char *argv[] = {g_exe, "bench", "xpbd", "--vertices", "100", "--frames", "4", "--only", "5", NULL};
    CHECK_EQ_INT(tool_run(argv, out1), 0);
    CHECK_EQ_INT(tool_run(argv, out2), 0);
    static char a[8192], b[8192];
    tool_slurp(out1, a, sizeof a);
    tool_slurp(out2, b, sizeof b);
    const char *ha = strstr(a, "trajectory hash "), *hb = strstr(b, "trajectory hash ");
    CHECK_MSG(ha && hb && strncmp(ha, hb, 32) == 0, "hashes differ or are missing: %.200s", a);
}

/* The RMSE-vs-S=40 cell (the sixth) of the row that starts with `row`. */
static double rmse_cell(const char *t, const char *row, bool *found)
{
    const char *r = strstr(t, row), *p = r ? r + 1 : NULL;
    for (int bar = 0; bar < 5 && p; ++bar) {
        p = strchr(p + 1, '|');
    }
    char *end = NULL;
    const double v = p ? strtod(p + 1, &end) : -1.0;
    *found = p && end != p + 1;
    return v;
}

static void tshirt_table(void)
{
    char out[1024];
    snprintf(out, sizeof out, "%s/tshirt.txt", g_out);
    const char *argv[] = {g_exe, "bench", "xpbd", "--scene", "tshirt", "--vertices", "256", "--frames", "3", "--no-80",
                          "--fast", NULL};
    CHECK_EQ_INT(tool_run(argv, out), 0);
    static char t[8192];
    tool_slurp(out, t, sizeof t);
    CHECK_MSG(strstr(t, "garment: tshirt on avatar") != NULL, "not a T-shirt: %.200s", t);
    /* rows for S = 5, 10, 20 and 40 of both methods; the reference's S = 40 is at zero error */
    CHECK(strstr(t, "\n| xpbd | 5 |") && strstr(t, "\n| xpbd | 10 |") && strstr(t, "\n| xpbd | 20 |"));
    CHECK(strstr(t, "\n| xpbd-fast | 5 |") && strstr(t, "\n| xpbd-fast | 40 |"));
    bool found = false;
    const double rmse40 = rmse_cell(t, "\n| xpbd | 40 |", &found);
    CHECK_MSG(found && rmse40 == 0.0, "S = 40 row: %.300s", t);
    /* S = 5 is somewhere else, and so is the fast method at S = 40 */
    CHECK(rmse_cell(t, "\n| xpbd | 5 |", &found) > 0.0 && found);
    CHECK(rmse_cell(t, "\n| xpbd-fast | 40 |", &found) > 0.0 && found);
    /* every row counts its frames with intersecting triangles, out of 3 */
    CHECK(strstr(t, " of 3 |\n") != NULL);
}

static void bad_scene_fails(void)
{
    const char *argv[] = {g_exe, "bench", "xpbd", "--scene", "hat", NULL};
    CHECK_EQ_INT(tool_run(argv, "/dev/null"), 2);
    const char *frames[] = {g_exe, "bench", "xpbd", "--frames", "0", NULL};
    CHECK_EQ_INT(tool_run(frames, "/dev/null"), 2);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s WEFT OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_out = argv[2];
    mkdir(g_out, 0777);
    static const test_case_ cases[] = {TEST_CASE(sheet_hash_repeats), TEST_CASE(tshirt_table),
                                         TEST_CASE(bad_scene_fails)};
    return test_run_(cases, sizeof cases / sizeof cases[0], argc - 2, argv + 2);
}
