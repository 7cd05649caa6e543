/* `weft bench lod` end to end on the committed sample sequence: the run writes a lod.csv that
 * weft_lod_table_load_file accepts, with one level per candidate (LBS with and without CCD,
 * XPBD at the substeps asked for, the `game` model at three precisions with and without CCD),
 * finite measured numbers, and a LOD.md with the generated table between its markers;
 * --strain-limit and --push-cm add deployed levels; --max-seqs counts per scenario; --sim-data adds resolution levels simulated on a coarser mesh.
 * The table goes beside LOD.md, or to --csv-dir, and the page links it either way.
 * argv: weft binary, data folder, models folder, output folder. Exits 77 (skipped) without a
 * sample sequence. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, symlink */
#include "test.h"
#include "weft/lod.h"

#include <errno.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

static const char *g_exe, *g_data, *g_models, *g_out;

static int run(const char *const argv[])
{
    pid_t pid;
    if (posix_spawn(&pid, argv[0], NULL, NULL, (char *const *)argv, environ) != 0) {
        return -1;
    }
    int status = 0;
    if (waitpid(pid, &status, 0) < 0) {
        return -1;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* Runs `weft bench lod` (argv) and loads the lod.csv it wrote (NULL, with a failed check, when
 * either fails); *ctx is the context it lives in, for the caller to destroy. */
static weft_lod_table *bench_table(const char *const argv[], const char *csv, weft_context **ctx)
{
    CHECK_EQ_INT(run(argv), 0);
    weft_context_def cd = weft_default_context_def();
    *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, ctx), WEFT_OK);
    weft_lod_table *t = NULL;
    if (*ctx) {
        CHECK_RESULT(weft_lod_table_load_file(*ctx, csv, &t), WEFT_OK);
    }
    return t;
}

static void bench_writes_loadable_table(void)
{
    /* Only the `game` model (linked into a folder of its own) keeps the run short. */
    char models[1024], link_path[1200], target[1200];
    snprintf(models, sizeof models, "%s/models", g_out);
    mkdir(g_out, 0755);
    mkdir(models, 0755);
    static const char *const files[] = {"game.safetensors", "game.int8.safetensors", "game.fp16.safetensors"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; ++i) {
        snprintf(link_path, sizeof link_path, "%s/%s", models, files[i]);
        snprintf(target, sizeof target, "%s/%s", g_models, files[i]);
        unlink(link_path);
        CHECK_MSG(symlink(target, link_path) == 0, "symlink %s: %s", link_path, strerror(errno));
    }
    char md[1200], csv[1200];
    snprintf(md, sizeof md, "%s/LOD.md", g_out);
    snprintf(csv, sizeof csv, "%s/lod.csv", g_out);
    unlink(md);
    unlink(csv);
    const char *argv[] = {g_exe,  "bench", "lod",      "--data", g_data,  "--split", "all", "--frames", "3",
                          "--xpbd", "1",   "--models", models,   "--out", g_out,     "--no-scale", NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        CHECK_EQ_INT(weft_lod_table_count(t), 9);
        static const char *const names[] = {"lbs",           "lbs-noccd",     "xpbd-1",
                                            "game-fp32",     "game-fp32-noccd", "game-fp16",
                                            "game-fp16-noccd", "game-int8",   "game-int8-noccd"};
        for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
            uint32_t idx = 0;
            CHECK_RESULT(weft_lod_table_find(t, names[i], &idx), WEFT_OK);
            const weft_lod_level *l = weft_lod_table_level(t, idx);
            CHECK(l && l->frames == 3 && l->sequences == 1 && l->ms_per_frame > 0.0 && isfinite(l->mve_cm));
        }
        uint32_t lv = 0;
        CHECK(weft_lod_pick(t, INFINITY, 1e6, &lv) == WEFT_LOD_PICK_OK);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
    FILE *f = fopen(md, "r");
    CHECK_MSG(f != NULL, "cannot open %s", md);
    if (f) {
        static char text[65536];
        size_t n = fread(text, 1, sizeof text - 1, f);
        text[n] = '\0';
        fclose(f);
        CHECK(strstr(text, "<!-- lod:table -->") != NULL && strstr(text, "<!-- /lod:table -->") != NULL);
        CHECK(strstr(text, "| game-int8 | model game | int8 |") != NULL);
        CHECK_MSG(strstr(text, "The table: [lod.csv](lod.csv).") != NULL, "LOD.md does not link lod.csv beside it");
    }
}

/* Slurps path into buf (cap bytes); false when it cannot be read. */
static bool read_text(const char *path, char *buf, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        return false;
    }
    size_t n = fread(buf, 1, cap - 1, f);
    buf[n] = '\0';
    fclose(f);
    return true;
}

/* --csv-dir: the table goes there, named by --name, not beside the page, and the page's generated
 * block links it by a path relative to the page. */
static void csv_dir_holds_the_table(void)
{
    char empty[1100], page[1100], tables[1100], csv[1200], beside[1200], md[1200];
    snprintf(empty, sizeof empty, "%s/no_models", g_out);
    snprintf(page, sizeof page, "%s/csv_dir/page", g_out);
    snprintf(tables, sizeof tables, "%s/csv_dir/tables/lod", g_out); /* created by the run */
    mkdir(empty, 0755);
    snprintf(csv, sizeof csv, "%s/mine.csv", tables);
    snprintf(beside, sizeof beside, "%s/mine.csv", page);
    snprintf(md, sizeof md, "%s/LOD.md", page);
    unlink(csv);
    unlink(beside);
    unlink(md);
    const char *argv[] = {g_exe,   "bench", "lod",      "--data",    g_data, "--split",    "all",  "--frames", "2",
                          "--xpbd", "1",    "--models", empty,       "--out", page,        "--csv-dir", tables,
                          "--name", "mine", "--no-scale", NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        uint32_t idx = 0;
        CHECK_RESULT(weft_lod_table_find(t, "lbs", &idx), WEFT_OK);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
    struct stat st;
    CHECK_MSG(stat(beside, &st) != 0, "%s written beside the page as well", beside);
    static char text[65536];
    CHECK_MSG(read_text(md, text, sizeof text), "cannot read %s", md);
    CHECK_MSG(strstr(text, "The table: [mine.csv](../tables/lod/mine.csv).") != NULL,
              "LOD.md does not link ../tables/lod/mine.csv");
    CHECK(strstr(text, "<!-- lod:table-mine -->") != NULL);
}

/* --crops: every model level again at each crop, named by it, and the crop in the CSV. */
static void bench_measures_crop_levels(void)
{
    char models[1024], out[1100];
    snprintf(models, sizeof models, "%s/models", g_out); /* linked by the case above */
    snprintf(out, sizeof out, "%s/crops", g_out);
    mkdir(out, 0755);
    char csv[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", out);
    unlink(csv);
    const char *argv[] = {g_exe,    "bench", "lod",   "--data", g_data,       "--split",  "all",
                          "--frames", "3",   "--xpbd", "1",     "--models",   models,     "--out",
                          out,      "--no-scale", "--crops", "model,6:cells@40", NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        CHECK_EQ_INT(weft_lod_table_count(t), 15); /* lbs x2, xpbd-1, game: 3 precisions x CCD x 2 crops */
        static const struct {
            const char *name;
            double cm;
            weft_collider_crop rule;
        } want[] = {{"game-fp32", 0.0, WEFT_COLLIDER_CROP_BOX},
                    {"game-int8-noccd", 0.0, WEFT_COLLIDER_CROP_BOX},
                    {"game-fp32-cells6-cap40", 6.0, WEFT_COLLIDER_CROP_CELLS},
                    {"game-fp16-noccd-cells6-cap40", 6.0, WEFT_COLLIDER_CROP_CELLS},
                    {"game-int8-cells6-cap40", 6.0, WEFT_COLLIDER_CROP_CELLS},
                    {"lbs", 0.0, WEFT_COLLIDER_CROP_BOX}};
        for (size_t i = 0; i < sizeof want / sizeof want[0]; ++i) {
            uint32_t idx = 0;
            CHECK_RESULT(weft_lod_table_find(t, want[i].name, &idx), WEFT_OK);
            const weft_lod_level *l = weft_lod_table_level(t, idx);
            const uint32_t cap = want[i].cm > 0.0 ? 40 : 0;
            CHECK_MSG(l && l->crop_cm == want[i].cm && l->collider_crop == want[i].rule && l->max_collider_tokens == cap &&
                          l->frames == 3 && isfinite(l->mve_cm),
                      "%s", want[i].name);
        }
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
    /* A malformed list is refused before anything runs. */
    const char *bad[] = {g_exe, "bench", "lod", "--data", g_data, "--crops", "6,-2", "--out", out, NULL};
    CHECK_EQ_INT(run(bad), 2);
}

/* --strain-limit and --push-cm: LBS, the first XPBD and each model's int8, with and without
 * CCD, again with both (named ...-sP-pX), the settings in the CSV's columns. */
static void bench_measures_deployed_levels(void)
{
    char models[1024], out[1100];
    snprintf(models, sizeof models, "%s/models", g_out); /* linked by the first case */
    snprintf(out, sizeof out, "%s/deployed", g_out);
    mkdir(out, 0755);
    char csv[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", out);
    unlink(csv);
    const char *argv[] = {g_exe,      "bench", "lod",     "--data",     g_data,      "--split", "all",
                          "--frames", "3",     "--xpbd",  "1",          "--models",  models,    "--out",
                          out,        "--no-scale", "--strain-limit", "10", "--push-cm", "1", NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        CHECK_EQ_INT(weft_lod_table_count(t), 14); /* 9 plain + lbs x2, xpbd-1, game-int8 x2 deployed */
        static const char *const deployed[] = {"lbs-s10-p1", "lbs-noccd-s10-p1", "xpbd-1-s10-p1", "game-int8-s10-p1",
                                               "game-int8-noccd-s10-p1"};
        for (size_t i = 0; i < sizeof deployed / sizeof deployed[0]; ++i) {
            uint32_t idx = 0;
            CHECK_RESULT(weft_lod_table_find(t, deployed[i], &idx), WEFT_OK);
            const weft_lod_level *l = weft_lod_table_level(t, idx);
            CHECK_MSG(l && l->push_cm == 1.0 && l->strain_limit_pct == 10.0 && l->tether_cm == 0.0 && l->frames == 3 &&
                          isfinite(l->mve_cm),
                      "%s", deployed[i]);
        }
        uint32_t idx = 0;
        CHECK_RESULT(weft_lod_table_find(t, "game-int8", &idx), WEFT_OK);
        CHECK(weft_lod_table_level(t, idx)->push_cm == 0.0);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
    const char *bad[] = {g_exe, "bench", "lod", "--data", g_data, "--push-cm", "11", "--out", out, NULL};
    CHECK_EQ_INT(run(bad), 2);
}

/* --max-seqs N keeps N sequences of each scenario (as bench chart), not N of the whole split:
 * two drops (the sample, linked twice) and a garment with --max-seqs 1 measure one of each. */
static void max_seqs_counts_per_scenario(void)
{
    char data[1100], empty[1100], out[1100], link_path[1300], target[1300];
    snprintf(data, sizeof data, "%s/two_scenarios", g_out);
    snprintf(empty, sizeof empty, "%s/no_models", g_out);
    snprintf(out, sizeof out, "%s/max_seqs", g_out);
    mkdir(data, 0755);
    mkdir(empty, 0755);
    mkdir(out, 0755);
    static const char *const names[] = {"drop_a", "drop_b", "garment_a"};
    for (int i = 0; i < 3; ++i) {
        snprintf(link_path, sizeof link_path, "%s/%s", data, names[i]);
        if (i < 2) {
            snprintf(target, sizeof target, "%s/sample_seq", g_data);
        } else {
            snprintf(target, sizeof target, "%s/tests/model/data/garment_seq", WEFT_SOURCE_DIR);
        }
        unlink(link_path);
        CHECK_MSG(symlink(target, link_path) == 0, "symlink %s: %s", link_path, strerror(errno));
    }
    char csv[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", out);
    unlink(csv);
    const char *argv[] = {g_exe,    "bench",  "lod",    "--data", data,  "--split", "all",       "--frames",
                          "2",      "--xpbd", "1",      "--models", empty, "--out",   out,         "--no-scale",
                          "--max-seqs", "1", NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        uint32_t idx = 0;
        CHECK_RESULT(weft_lod_table_find(t, "lbs-noccd", &idx), WEFT_OK);
        const weft_lod_level *l = weft_lod_table_level(t, idx);
        CHECK_MSG(l && l->sequences == 2, "lbs-noccd measured %u sequences, want 2", l ? l->sequences : 0);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
}

/* --sim-data: a 256-vertex drop and its 64-vertex twin (`weft simgen --resolution-series`, same
 * scene) give LBS and XPBD levels at resolution 64/256-ish that the table loader accepts; a folder
 * with no coarser twin is refused before anything runs. */
static void sim_data_adds_resolution_levels(void)
{
    char fine[1100], coarse[1100], empty[1100], out[1100], csv[1200];
    snprintf(fine, sizeof fine, "%s/res_v256", g_out);
    snprintf(coarse, sizeof coarse, "%s/res_v64", g_out);
    snprintf(empty, sizeof empty, "%s/no_models", g_out);
    snprintf(out, sizeof out, "%s/res_levels", g_out);
    mkdir(empty, 0755);
    mkdir(out, 0755);
    const char *gen_fine[] = {g_exe, "simgen", "--out", fine, "--scenario", "drop", "--count", "1", "--vertices", "256",
                              "--frames", "6", "--resolution-series", "--seed", "3", NULL};
    const char *gen_coarse[] = {g_exe, "simgen", "--out", coarse, "--scenario", "drop", "--count", "1", "--vertices",
                                "64", "--frames", "6", "--resolution-series", "--seed", "3", NULL};
    CHECK_EQ_INT(run(gen_fine), 0);
    CHECK_EQ_INT(run(gen_coarse), 0);
    snprintf(csv, sizeof csv, "%s/lod.csv", out);
    unlink(csv);
    const char *argv[] = {g_exe, "bench", "lod", "--data", fine, "--split", "all", "--frames", "3", "--xpbd", "1",
                          "--models", empty, "--out", out, "--no-scale", "--sim-data", coarse, NULL};
    weft_context *ctx = NULL;
    weft_lod_table *t = bench_table(argv, csv, &ctx);
    if (t) {
        CHECK_EQ_INT(weft_lod_table_count(t), 6); /* lbs x2, xpbd-1, each again on the coarse mesh */
        uint32_t n = weft_lod_table_count(t), coarse_levels = 0;
        for (uint32_t i = 0; i < n; ++i) {
            const weft_lod_level *l = weft_lod_table_level(t, i);
            if (l && l->resolution < 1.0f) {
                coarse_levels++;
                CHECK_MSG(l->resolution > 0.1f && l->resolution < 0.4f && strstr(l->name, "-r0.") != NULL &&
                              l->frames == 3 && isfinite(l->mve_cm),
                          "%s: resolution %g", l->name, (double)l->resolution);
            }
        }
        CHECK_EQ_INT(coarse_levels, 3);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
    /* The fine folder has no coarser twin of itself: refused. */
    const char *bad[] = {g_exe, "bench", "lod", "--data", fine, "--split", "all", "--models", empty, "--out", out,
                         "--no-scale", "--sim-data", fine, NULL};
    CHECK_EQ_INT(run(bad), 1);
}

int main(int argc, char **argv)
{
    if (argc != 5) {
        fprintf(stderr, "usage: %s WEFT DATA MODELS OUT\n", argv[0]);
        return 2;
    }
    g_exe = argv[1];
    g_data = argv[2];
    g_models = argv[3];
    g_out = argv[4];
    char probe[1024];
    snprintf(probe, sizeof probe, "%s/sample_seq/meta.json", g_data);
    struct stat st;
    if (stat(probe, &st) != 0) {
        printf("skipped: no %s\n", probe);
        return 77;
    }
    static const test_case_ cases[] = {TEST_CASE(bench_writes_loadable_table), TEST_CASE(bench_measures_crop_levels),
                                       TEST_CASE(bench_measures_deployed_levels),
                                       TEST_CASE(max_seqs_counts_per_scenario),
                                       TEST_CASE(sim_data_adds_resolution_levels), TEST_CASE(csv_dir_holds_the_table)};
    return test_run_(cases, sizeof cases / sizeof cases[0], 1, argv);
}
