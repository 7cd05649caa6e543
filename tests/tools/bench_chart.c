/* `weft bench chart --quick` on the committed sample sequence: the run succeeds, and chart.csv
 * (beside CHART.md, which links it) holds an LBS row and an XPBD row with finite, plausible
 * numbers for the frames asked for, the real-motion panel's LBS row (one library walk) and the cape
 * panel's FNOpt and fast XPBD-10 rows (the render sample's cape on the walk), none lost; the
 * FNOpt grid scene's learned row (xy, read from `weft fnopt run`'s CSV by its column names). A
 * run that fails writes nothing.
 * argv: weft binary, data folder, output folder, FNOpt weights. Exits 77 (skipped) without a sample sequence. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, stat */
#include "test.h"

#include "tool_run.h"

#include <stdbool.h>
#include <sys/stat.h>

static const char *g_exe, *g_data, *g_out, *g_fnopt;

/* Field `col` (0-based) of a CSV line into out. */
static void field(const char *line, int col, char *out, size_t cap)
{
    for (int c = 0; c < col && line; ++c) {
        line = strchr(line, ',');
        line = line ? line + 1 : NULL;
    }
    size_t n = 0;
    while (line && line[n] && line[n] != ',' && line[n] != '\n' && n + 1 < cap) {
        out[n] = line[n];
        n++;
    }
    out[n] = '\0';
}

/* Runs the chart (argv), which must succeed, and opens the chart.csv it wrote into `out`; NULL
 * after a failed check. */
static FILE *run_chart(const char *const *argv, const char *out)
{
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    char path[1100];
    snprintf(path, sizeof path, "%s/chart.csv", out);
    FILE *f = fopen(path, "r");
    CHECK_MSG(f != NULL, "cannot open %s", path);
    return f;
}

static void chart_quick_rows(void)
{
    const char *argv[] = {g_exe, "bench", "chart", "--data", g_data, "--split", "all", "--quick", "--frames", "4",
                          "--xpbd", "5", "--no-fnopt", "--no-plot", "--fnopt-model", g_fnopt, "--out", g_out, NULL};
    FILE *f = run_chart(argv, g_out);
    if (!f) {
        return;
    }
    char line[2048];
    CHECK(fgets(line, sizeof line, f) != NULL);
    static const char header[] = "scenario,method,family,precision,ccd,sequences,frames,mve_cm,";
    CHECK(strncmp(line, header, sizeof header - 1) == 0);
    int lbs = 0, xpbd = 0, mocap = 0, cape = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "cape,FNOpt fp32,fnopt,", 22) == 0 || strncmp(line, "cape,XPBD-fast-10,", 18) == 0) {
            /* the cape's panel: FNOpt and the fast XPBD on the same cape, scored like real motion */
            char inside[64], lost[16], ms[64];
            field(line, 9, ms, sizeof ms);
            field(line, 17, inside, sizeof inside);
            field(line, 18, lost, sizeof lost);
            const double x = strtod(inside, NULL), t = strtod(ms, NULL);
            CHECK_MSG(inside[0] && isfinite(x) && x >= 0.0 && x <= 100.0, "cape inside_body '%s'", inside);
            CHECK_MSG(isfinite(t) && t > 0.0, "cape ms/frame '%s'", ms);
            CHECK_MSG(strcmp(lost, "0") == 0, "cape lost on the walk: '%s'", lost);
            ++cape;
            continue;
        }
        if (strncmp(line, "mocap,LBS,", 10) == 0) {
            /* the real-motion panel: no MVE, the share of cloth inside the body (column 17) */
            char inside[64], lost[16];
            field(line, 17, inside, sizeof inside);
            field(line, 18, lost, sizeof lost);
            const double x = strtod(inside, NULL);
            CHECK_MSG(inside[0] && isfinite(x) && x >= 0.0 && x <= 100.0, "mocap LBS inside_body '%s'", inside);
            CHECK_MSG(strcmp(lost, "0") == 0, "mocap LBS lost '%s' garments on the walk", lost);
            ++mocap;
            continue;
        }
        char method[128], family[32], frames[32], mve[64], ms[64];
        field(line, 1, method, sizeof method);
        field(line, 2, family, sizeof family);
        field(line, 6, frames, sizeof frames);
        field(line, 7, mve, sizeof mve);
        field(line, 9, ms, sizeof ms);
        double e = strtod(mve, NULL), t = strtod(ms, NULL);
        bool is_lbs = strcmp(method, "LBS") == 0, is_xpbd = strcmp(method, "XPBD-5") == 0;
        if (!is_lbs && !is_xpbd) {
            continue;
        }
        lbs += is_lbs;
        xpbd += is_xpbd;
        CHECK_MSG(mve[0] && isfinite(e) && e >= 0.0 && e < 1000.0, "%s: MVE '%s'", method, mve);
        CHECK_MSG(isfinite(t) && t > 0.0, "%s: ms/frame '%s'", method, ms);
        CHECK_MSG(strcmp(frames, "4") == 0, "%s: %s frames scored, asked for 4", method, frames);
        CHECK(strcmp(family, is_lbs ? "lbs" : "xpbd") == 0);
    }
    fclose(f);
    CHECK_EQ_INT(lbs, 1);
    CHECK_EQ_INT(xpbd, 1);
    CHECK_EQ_INT(mocap, 1);
    CHECK_EQ_INT(cape, 2);
    char path[1100];
    snprintf(path, sizeof path, "%s/CHART.md", g_out);
    f = fopen(path, "r");
    CHECK_MSG(f != NULL, "cannot open %s", path);
    if (f) {
        static char text[1 << 16];
        size_t n = fread(text, 1, sizeof text - 1, f);
        text[n] = '\0';
        fclose(f);
        CHECK_MSG(n > 0, "%s is empty", path);
        /* With --out other than docs the CSV stays beside the page, which links it. */
        CHECK_MSG(strstr(text, "Raw numbers: [chart.csv](chart.csv).") != NULL, "%s does not link chart.csv", path);
        CHECK_MSG(strstr(text, "## cape (real motion)") != NULL, "%s has no cape panel", path);
    }
}

/* The FNOpt grid scene alone (no real motion): its learned row has the frames asked for, a
 * finite e3D and a time. */
static void chart_fnopt_rows(void)
{
    char out[1024];
    snprintf(out, sizeof out, "%s/fnopt", g_out);
    mkdir(out, 0777);
    const char *argv[] = {g_exe,  "bench", "chart", "--data", g_data, "--split", "all", "--quick", "--frames", "3",
                          "--xpbd", "5", "--xpbd-fast", "5", "--no-mocap", "--no-plot", "--fnopt-model", g_fnopt,
                          "--out", out, NULL};
    FILE *f = run_chart(argv, out);
    if (!f) {
        return;
    }
    char line[2048];
    int learned = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "fnopt-grid,FNOpt,fnopt,", 23) != 0) {
            continue;
        }
        char frames[32], e3d[64], ms[64];
        field(line, 6, frames, sizeof frames);
        field(line, 8, e3d, sizeof e3d);
        field(line, 9, ms, sizeof ms);
        const double e = strtod(e3d, NULL), t = strtod(ms, NULL);
        CHECK_MSG(strcmp(frames, "3") == 0, "FNOpt frames '%s', want 3", frames);
        CHECK_MSG(e3d[0] && isfinite(e) && e > 0.0 && e < 1.0, "FNOpt e3d '%s'", e3d);
        CHECK_MSG(isfinite(t) && t > 0.0, "FNOpt ms/frame '%s'", ms);
        ++learned;
    }
    fclose(f);
    CHECK_EQ_INT(learned, 1);
}

/* A run that fails (here a model file that does not load) fails the benchmark, and nothing is
 * written from the partial results: no CSV, no page, no figure. */
static void chart_refuses_partial_results(void)
{
    char models[1024], bad_model[1100], out[1024], path[1200];
    snprintf(models, sizeof models, "%s/broken_models", g_out);
    snprintf(out, sizeof out, "%s/partial", g_out);
    mkdir(models, 0777);
    mkdir(out, 0777);
    snprintf(bad_model, sizeof bad_model, "%s/broken.safetensors", models);
    FILE *f = fopen(bad_model, "w");
    CHECK(f != NULL);
    if (f) {
        fputs("not a safetensors file", f);
        fclose(f);
    }
    const char *argv[] = {g_exe,  "bench", "chart",  "--data",     g_data,      "--split",   "all",
                          "--quick", "--frames", "2", "--xpbd", "5", "--xpbd-fast", "5", "--no-fnopt",
                          "--no-plot", "--models", models, "--out", out, NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 1);
    static const char *const written[] = {"chart.csv", "CHART.md", "img/chart.png"};
    for (size_t k = 0; k < sizeof written / sizeof written[0]; ++k) {
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", out, written[k]);
        CHECK_MSG(stat(path, &st) != 0, "%s was written from a failed run", path);
    }
}

static void chart_rejects_bad_input(void)
{
    /* A folder without sequences and an unknown option both fail cleanly. */
    const char *none[] = {g_exe, "bench", "chart", "--data", g_out, "--no-fnopt", "--no-plot", "--out", g_out, NULL};
    CHECK_EQ_INT(tool_run(none, NULL), 1);
    const char *bad[] = {g_exe, "bench", "chart", "--data", g_data, "--xpbd", "0", NULL};
    CHECK_EQ_INT(tool_run(bad, NULL), 2);
}

int main(int argc, char **argv)
{
    if (argc < 5) {
        fprintf(stderr, "usage: %s WEFT DATA OUT FNOPT_WEIGHTS\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_data = argv[2];
    g_out = argv[3];
    g_fnopt = argv[4];
    char meta[1024];
    struct stat st;
    snprintf(meta, sizeof meta, "%s/sample_seq/meta.json", g_data);
    if (stat(meta, &st) != 0) {
        printf("no sample sequence at %s: skipped\n", meta);
        return 77;
    }
    mkdir(g_out, 0777);
    static const test_case_ cases[] = {TEST_CASE(chart_quick_rows), TEST_CASE(chart_fnopt_rows),
                                       TEST_CASE(chart_refuses_partial_results), TEST_CASE(chart_rejects_bad_input)};
    return test_run_(cases, sizeof cases / sizeof cases[0], 1, argv);
}
