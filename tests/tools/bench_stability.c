/* `weft bench stability` end to end on a tiny gripper suite (64 vertices, 12-frame cases, LBS and
 * XPBD-5, no models, no FNOpt): the run succeeds and writes a CSV with one row per case and
 * method, statuses from the documented set and scores kept under each sequence; a second run
 * reuses the kept scores (the CSV, wall times included, comes out byte-identical); a model's kept
 * scores follow the model file's contents; the table replaces only the marked block of an
 * existing STABILITY.md, which links the CSV beside it or in --csv-dir; bad options fail.
 * argv: weft binary, output folder. */
#define _POSIX_C_SOURCE 200809L /* stat, mkdir */
#include "test.h"
#include "tool_run.h"

#include <dirent.h>
#include <stdbool.h>
#include <sys/stat.h>

static const char *g_exe, *g_out;

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *p = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (p && fread(p, 1, (size_t)n, f) != (size_t)n) {
        free(p);
        p = NULL;
    }
    if (p) {
        p[n] = '\0';
    }
    fclose(f);
    return p;
}

/* The suite into out/<name>, its cases under out/data, the models of out/<models>. */
static int suite_with(const char *name, const char *models_dir, bool rescore)
{
    char data[1200], out[1200], models[1200];
    snprintf(data, sizeof data, "%s/data", g_out);
    snprintf(out, sizeof out, "%s/%s", g_out, name);
    snprintf(models, sizeof models, "%s/%s", g_out, models_dir);
    mkdir(models, 0777);
    const char *argv[] = {g_exe,    "bench", "stability", "--quick", "--frames", "12", "--long-frames", "16",
                          "--xpbd", "5",     "--xpbd-fast", "5",     "--no-fnopt", "--no-garment", "--no-plot",
                          "--models", models, "--data", data, "--out", out, rescore ? "--rescore" : NULL, NULL};
    return tool_run(argv, NULL);
}

static int suite(const char *name, bool rescore)
{
    return suite_with(name, "no_models", rescore);
}

static void remove_files(const char *dir, const char *suffix)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    char path[1600];
    while (d && (e = readdir(d)) != NULL) {
        size_t l = strlen(e->d_name), s = strlen(suffix);
        if (l > s && strcmp(e->d_name + l - s, suffix) == 0) {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            remove(path);
        }
    }
    if (d) {
        closedir(d);
    }
}

static bool copy_file(const char *from, const char *to)
{
    FILE *in = fopen(from, "rb"), *out = in ? fopen(to, "wb") : NULL;
    bool ok = in && out;
    char buf[65536];
    size_t n;
    while (ok && (n = fread(buf, 1, sizeof buf, in)) > 0) {
        ok = fwrite(buf, 1, n, out) == n;
    }
    if (in) {
        fclose(in);
    }
    if (out) {
        ok = fclose(out) == 0 && ok;
    }
    return ok;
}

static size_t count_files(const char *dir, const char *suffix)
{
    DIR *d = opendir(dir);
    size_t n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        size_t l = strlen(e->d_name), s = strlen(suffix);
        n += l > s && strcmp(e->d_name + l - s, suffix) == 0;
    }
    if (d) {
        closedir(d);
    }
    return n;
}

/* DIR/stability.csv's text (NULL, with a failed check, when it was not written). */
static char *stability_csv(const char *dir)
{
    char path[1400];
    snprintf(path, sizeof path, "%s/stability.csv", dir);
    char *csv = slurp(path);
    CHECK_MSG(csv != NULL, "no %s", path);
    return csv;
}

static void runs_and_resumes(void)
{
    /* The data folder may hold scores of an earlier build or of other models from an earlier
     * ctest run: --rescore, and no scores left over. */
    char kept[1300];
    snprintf(kept, sizeof kept, "%s/data/res_x1/gripper_v64_0000/scores", g_out);
    remove_files(kept, ".json");
    CHECK_EQ_INT(suite("first", true), 0);
    char path[1300];
    snprintf(path, sizeof path, "%s/first", g_out);
    char *first = stability_csv(path);
    if (!first) {
        return;
    }
    /* 9 cases (4 resolution, long, unseen seed, 3 speeds) x 3 methods, under one header. */
    size_t rows = 0;
    for (const char *line = strchr(first, '\n'); line && line[1]; line = strchr(line + 1, '\n')) {
        const char *l = line + 1;
        rows++;
        CHECK_MSG(strncmp(l, "res_x", 5) == 0 || strncmp(l, "long_16", 7) == 0 || strncmp(l, "unseen_motion", 13) == 0 ||
                      strncmp(l, "speed_x", 7) == 0,
                  "unexpected case in row: %.60s", l);
        const char *end = strchr(l, '\n');
        size_t len = end ? (size_t)(end - l) : strlen(l);
        char row[1024];
        snprintf(row, sizeof row, "%.*s", (int)(len < sizeof row - 1 ? len : sizeof row - 1), l);
        static const char *const statuses[] = {",pass,", ",drifts,", ",penetrates,", ",exploded,", ",NaN,",
                                               ",too slow,", ",error,", ",not generated,"};
        bool known = false;
        for (size_t k = 0; k < sizeof statuses / sizeof statuses[0]; ++k) {
            known |= strstr(row, statuses[k]) != NULL;
        }
        CHECK_MSG(known, "row without a known status: %s", row);
    }
    CHECK_EQ_INT(rows, 27);
    char scores[1300];
    snprintf(scores, sizeof scores, "%s/data/res_x1/gripper_v64_0000/scores", g_out);
    /* LBS, XPBD-5 and the fast XPBD-5, each scored at the full length and cut at 1/4 and 3/4 */
    CHECK_EQ_INT(count_files(scores, ".json"), 9);

    /* Again: every eval comes from the kept scores, so even the wall times are the same. */
    CHECK_EQ_INT(suite("second", false), 0);
    snprintf(path, sizeof path, "%s/second", g_out);
    char *second = stability_csv(path);
    CHECK_MSG(second && strcmp(first, second) == 0, "the resumed run scored differently");
    free(first);
    free(second);
}

/* The generated table goes between the markers of an existing page; the prose around it stays. */
static void prose_around_the_table_survives(void)
{
    char dir[1200], path[1300];
    snprintf(dir, sizeof dir, "%s/prose", g_out);
    mkdir(dir, 0777);
    snprintf(path, sizeof path, "%s/STABILITY.md", dir);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) {
        return;
    }
    fputs("# Stability\n\nHand-written lead.\n\n<!-- stability:table -->\nstale table\n<!-- /stability:table -->\n\n"
          "Hand-written tail.\n",
          f);
    fclose(f);
    CHECK_EQ_INT(suite("prose", false), 0); /* the scores kept by runs_and_resumes: no evaluation */
    char *doc = slurp(path);
    CHECK(doc != NULL);
    if (!doc) {
        return;
    }
    const char *lead = strstr(doc, "Hand-written lead."), *open = strstr(doc, "<!-- stability:table -->");
    const char *table = strstr(doc, "| case | axis | method |"), *close = strstr(doc, "<!-- /stability:table -->");
    const char *tail = strstr(doc, "Hand-written tail.");
    CHECK(strncmp(doc, "# Stability\n", 12) == 0);
    CHECK(lead && open && table && close && tail);
    CHECK(lead < open && open < table && table < close && close < tail);
    CHECK(strstr(doc, "stale table") == NULL);
    CHECK(strstr(close + 1, "<!-- stability:table -->") == NULL); /* replaced, not appended */
    CHECK_MSG(strstr(doc, "Raw numbers: [stability.csv](stability.csv).") != NULL,
              "no link to the CSV beside the page");
    free(doc);
}

/* --csv-dir: the CSV goes there, not beside the page, and the page links it relatively. */
static void csv_dir_keeps_the_data_apart(void)
{
    char data[1200], page[1200], csv_dir[1200], models[1200], path[1300];
    snprintf(data, sizeof data, "%s/data", g_out);
    snprintf(page, sizeof page, "%s/apart/page", g_out);
    snprintf(csv_dir, sizeof csv_dir, "%s/apart/csv", g_out);
    snprintf(models, sizeof models, "%s/no_models", g_out);
    mkdir(models, 0777);
    snprintf(path, sizeof path, "%s/stability.csv", page);
    remove(path);
    const char *argv[] = {g_exe,       "bench",  "stability", "--quick", "--frames",   "12",       "--long-frames",
                          "16",        "--xpbd", "5",         "--xpbd-fast", "5",      "--no-fnopt", "--no-garment",
                          "--no-plot", "--models", models,    "--data",  data,         "--out",    page,
                          "--csv-dir", csv_dir,  "--axes",    "long",    NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    struct stat st;
    CHECK_MSG(stat(path, &st) != 0, "%s written beside the page", path);
    char *csv = stability_csv(csv_dir);
    CHECK(csv && strstr(csv, "\nlong_16,") != NULL);
    free(csv);
    snprintf(path, sizeof path, "%s/STABILITY.md", page);
    char *doc = slurp(path);
    CHECK_MSG(doc && strstr(doc, "Raw numbers: [stability.csv](../csv/stability.csv).") != NULL,
              "%s does not link ../csv/stability.csv", path);
    free(doc);
}

/* A kept model score belongs to the model file's contents, not its path: a retrained model
 * under the same name is scored again, the same file is not. */
static void model_scores_follow_the_file(void)
{
    char dir[1200], model[1300], scores[1300];
    snprintf(dir, sizeof dir, "%s/one_model", g_out);
    mkdir(dir, 0777);
    snprintf(model, sizeof model, "%s/m.safetensors", dir);
    snprintf(scores, sizeof scores, "%s/data/res_x1/gripper_v64_0000/scores", g_out);
    remove_files(scores, ".json"); /* an earlier ctest run may have left other models' scores */
    CHECK(copy_file(WEFT_SOURCE_DIR "/tools/train/models/game.safetensors", model));
    CHECK_EQ_INT(suite_with("model_a", "one_model", false), 0);
    /* LBS, XPBD-5, the fast XPBD-5 and the model at fp32, fp16 and int8, each at 3 lengths */
    size_t with_a = count_files(scores, ".json");
    CHECK_EQ_INT(with_a, 18);
    CHECK_EQ_INT(suite_with("model_a_again", "one_model", false), 0);
    CHECK_EQ_INT(count_files(scores, ".json"), with_a);
    CHECK(copy_file(WEFT_SOURCE_DIR "/tools/train/models/game_k16.safetensors", model));
    CHECK_EQ_INT(suite_with("model_b", "one_model", false), 0);
    CHECK_EQ_INT(count_files(scores, ".json"), with_a + 9);
}

/* --axes long: the long rollout alone (its sequence and scores are the ones kept above); with
 * --ccd off the page says so. */
static void axes_choose_the_cases(void)
{
    char data[1200], out[1200], models[1200], page[1300];
    snprintf(data, sizeof data, "%s/data", g_out);
    snprintf(out, sizeof out, "%s/long_only", g_out);
    snprintf(models, sizeof models, "%s/no_models", g_out);
    mkdir(models, 0777);
    const char *argv[] = {g_exe,        "bench", "stability", "--quick", "--frames", "12",   "--long-frames",
                          "16",         "--xpbd", "5",         "--xpbd-fast", "5", "--no-fnopt", "--no-garment", "--no-plot", "--models",
                          models,       "--data", data,      "--out",   out,        "--axes", "long",
                          "--ccd",      "off",    NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    char *csv = stability_csv(out);
    if (!csv) {
        return;
    }
    size_t rows = 0;
    for (const char *line = strchr(csv, '\n'); line && line[1]; line = strchr(line + 1, '\n')) {
        rows++;
        CHECK_MSG(strncmp(line + 1, "long_16,", 8) == 0, "unexpected row: %.60s", line + 1);
    }
    CHECK_EQ_INT(rows, 3); /* LBS, XPBD-5 and the fast XPBD-5 */
    free(csv);
    snprintf(page, sizeof page, "%s/STABILITY.md", out);
    char *doc = slurp(page);
    CHECK_MSG(doc && strstr(doc, "CCD post-processing off"), "%s does not say CCD was off", page);
    free(doc);
}

static void bad_options(void)
{
    const char *zero[] = {g_exe, "bench", "stability", "--time-limit", "0", NULL};
    CHECK_EQ_INT(tool_run(zero, NULL), 2);
    const char *scenario[] = {g_exe, "bench", "stability", "--scenario", "cape", NULL};
    CHECK_EQ_INT(tool_run(scenario, NULL), 2);
    const char *unknown[] = {g_exe, "bench", "stability", "--resume", NULL};
    CHECK_EQ_INT(tool_run(unknown, NULL), 2);
    const char *axes[] = {g_exe, "bench", "stability", "--axes", "long,width", NULL};
    CHECK_EQ_INT(tool_run(axes, NULL), 2);
    const char *ccd[] = {g_exe, "bench", "stability", "--ccd", "maybe", NULL};
    CHECK_EQ_INT(tool_run(ccd, NULL), 2);
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
    static const test_case_ cases[] = {TEST_CASE(runs_and_resumes), TEST_CASE(prose_around_the_table_survives),
                                       TEST_CASE(model_scores_follow_the_file), TEST_CASE(axes_choose_the_cases),
                                       TEST_CASE(csv_dir_keeps_the_data_apart), TEST_CASE(bad_options)};
    return test_run_(cases, sizeof cases / sizeof cases[0], 1, argv);
}
