/* `weft simgen` plan options: --tier generates only that tier of --all (here one 16k drop
 * sequence, a few frames, unvalidated, to stay quick) and the manifest lists it; --split
 * generates exactly the names that hash into that split; --only keeps one scenario; bad --tier /
 * --shard / --split / --only / --arm-spread-retry / --ease-in-retry / --amplitude-retry / --fast-collider values fail with a usage exit. argv: weft binary, output folder. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, stat */
#include "test.h"

#include "tool_run.h"
#include "weft/sim.h"
#include "weft/wear.h"

#include <math.h>
#include <stdbool.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *g_exe, *g_out;

static bool exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void tier_generates_only_that_tier(void)
{
    char dir[1024], meta[1200], other[1200], manifest[1200];
    snprintf(dir, sizeof dir, "%s/tier", g_out);
    snprintf(meta, sizeof meta, "%s/drop_16k_0000/meta.json", dir);
    snprintf(other, sizeof other, "%s/drop_1k_0000/meta.json", dir);
    snprintf(manifest, sizeof manifest, "%s/manifest.json", dir);
    unlink(meta); /* a rerun must generate again, not resume past it */
    const char *argv[] = {g_exe, "simgen", "--out", dir, "--all", "--tier", "16k", "--limit", "1",
                          "--frames", "3", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    CHECK_MSG(exists(meta), "no %s", meta);
    CHECK_MSG(!exists(other), "--tier 16k generated a 1k sequence");
    static char text[1 << 20];
    tool_slurp(manifest, text, sizeof text);
    /* The manifest lists finished sequences: the 16k one with its vertex count, no 1k one. */
    const char *entry = strstr(text, "\"drop_16k_0000\"");
    const char *v = entry ? strstr(entry, "\"vertices\":") : NULL;
    long vertices = v ? strtol(v + 11, NULL, 10) : 0;
    CHECK_MSG(vertices > 12000 && vertices < 20000, "16k sequence with %ld vertices", vertices);
    CHECK(strstr(text, "_1k_") == NULL);
}

/* Tiny unvalidated sheets: every name of the plan exists afterwards iff it hashes into "test". */
static void split_generates_only_that_split(void)
{
    char dir[1024], meta[1200], name[64];
    snprintf(dir, sizeof dir, "%s/split", g_out);
    const char *argv[] = {g_exe,      "simgen", "--out",   dir, "--scenario",    "drop", "--count", "24", "--vertices",
                          "64",       "--frames", "2",     "--split", "test", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    int generated = 0, skipped = 0;
    for (int k = 0; k < 24; ++k) {
        snprintf(name, sizeof name, "drop_v64_%04d", k);
        snprintf(meta, sizeof meta, "%s/%s/meta.json", dir, name);
        bool in_test = strcmp(weft_sim_split_of(name), "test") == 0;
        CHECK_MSG(exists(meta) == in_test, "%s (split %s) %s", name, weft_sim_split_of(name),
                  exists(meta) ? "generated" : "missing");
        generated += in_test;
        skipped += !in_test;
    }
    /* 24 names at 1 in 10: the plan must have held both kinds for the check to mean anything. */
    CHECK(generated > 0 && skipped > 0);
}

/* Two --scenario runs into one folder: the manifest and the split files of the second list the
 * first run's sequences too. */
static void manifest_keeps_other_runs(void)
{
    char dir[1024], manifest[1200];
    snprintf(dir, sizeof dir, "%s/two_runs", g_out);
    snprintf(manifest, sizeof manifest, "%s/manifest.json", dir);
    const char *drops[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--count", "2", "--vertices", "64",
                           "--frames", "2", "--no-validate", NULL};
    const char *grips[] = {g_exe, "simgen", "--out", dir, "--scenario", "gripper", "--count", "1", "--vertices", "64",
                           "--frames", "2", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(drops, NULL), 0);
    CHECK_EQ_INT(tool_run(grips, NULL), 0);
    static char text[1 << 16];
    tool_slurp(manifest, text, sizeof text);
    CHECK_MSG(strstr(text, "\"drop_v64_0000\"") && strstr(text, "\"drop_v64_0001\"") && strstr(text, "\"gripper_v64_0000\""),
              "the manifest lost a run's sequences:\n%.400s", text);
    const char *entry = strstr(text, "\"drop_v64_0001\"");
    const char *sc = entry ? strstr(entry, "\"scenario\":") : NULL;
    CHECK_MSG(sc && strncmp(sc, "\"scenario\":\t\"drop\"", strlen("\"scenario\":\t\"drop\"")) == 0, "drop_v64_0001 listed as %.30s", sc ? sc : "-");
}

/* --only keeps one scenario of --all with the plan's names: the first gripper, no drop. */
static void only_generates_that_scenario(void)
{
    char dir[1024], grip[1200], drop[1200];
    snprintf(dir, sizeof dir, "%s/only", g_out);
    snprintf(grip, sizeof grip, "%s/gripper_1k_0000/meta.json", dir);
    snprintf(drop, sizeof drop, "%s/drop_1k_0000/meta.json", dir);
    unlink(grip);
    const char *argv[] = {g_exe, "simgen", "--out", dir, "--all", "--only", "gripper", "--limit", "1",
                          "--frames", "2", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(argv, NULL), 0);
    CHECK_MSG(exists(grip), "no %s", grip);
    CHECK_MSG(!exists(drop), "--only gripper generated a drop");
}

/* --redo-rejected runs a finished but rejected sequence again; without it the sequence counts as
 * done. The rejection is written into a tiny unvalidated sequence's meta.json by hand. */
static void redo_rejected_runs_rejected_again(void)
{
    char dir[1024], meta[1200];
    snprintf(dir, sizeof dir, "%s/redo", g_out);
    snprintf(meta, sizeof meta, "%s/drop_v64_0000/meta.json", dir);
    const char *make[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--count", "1", "--vertices", "64",
                          "--frames", "2", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(make, NULL), 0);
    FILE *f = fopen(meta, "wb");
    CHECK(f != NULL);
    if (f) {
        fputs("{\"scenario\": \"drop\", \"accepted\": false}\n", f);
        fclose(f);
    }
    static char text[1 << 16];
    CHECK_EQ_INT(tool_run(make, NULL), 0); /* finished: left alone */
    tool_slurp(meta, text, sizeof text);
    CHECK_MSG(strstr(text, "\"accepted\": false") != NULL, "a plain rerun regenerated a finished sequence");
    const char *redo[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--count", "1", "--vertices", "64",
                          "--frames", "2", "--no-validate", "--redo-rejected", NULL};
    CHECK_EQ_INT(tool_run(redo, NULL), 0);
    tool_slurp(meta, text, sizeof text);
    CHECK_MSG(strstr(text, "\"accepted\":\ttrue") != NULL, "--redo-rejected left the rejected sequence: %.200s", text);
}

/* --like: the scene of another sequence (scenario and seed from its meta.json) at another vertex
 * count, named after it. */
static void like_makes_the_same_scene(void)
{
    char a[1024], b[1024], meta_a[1200], meta_b[1200];
    snprintf(a, sizeof a, "%s/like_a", g_out);
    snprintf(b, sizeof b, "%s/like_b", g_out);
    snprintf(meta_a, sizeof meta_a, "%s/drop_v300_0000/meta.json", a);
    snprintf(meta_b, sizeof meta_b, "%s/drop_v300_0000_v150/meta.json", b);
    unlink(meta_a);
    unlink(meta_b);
    const char *first[] = {g_exe, "simgen", "--out", a, "--scenario", "drop", "--count", "1", "--vertices", "300",
                           "--frames", "3", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(first, NULL), 0);
    char like[1200];
    snprintf(like, sizeof like, "%s/drop_v300_0000", a);
    const char *twin[] = {g_exe, "simgen", "--out", b, "--like", like, "--vertices", "150", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run(twin, NULL), 0);
    static char ta[1 << 16], tb[1 << 16];
    tool_slurp(meta_a, ta, sizeof ta);
    tool_slurp(meta_b, tb, sizeof tb);
    const char *da = strstr(ta, "\"description\""), *db = strstr(tb, "\"description\"");
    const char *sa = strstr(ta, "\"seed_u64\""), *sb = strstr(tb, "\"seed_u64\"");
    CHECK_MSG(da && db && strncmp(da, db, (size_t)(strchr(da, '\n') - da)) == 0, "twin of another scene: %.120s",
              db ? db : "(no meta.json)");
    CHECK(sa && sb && strncmp(sa, sb, (size_t)(strchr(sa, '\n') - sa)) == 0);
    const char *fa = strstr(ta, "\"frames\""), *fb = strstr(tb, "\"frames\""); /* its frames too */
    CHECK(fa && fb && strtol(strchr(fa, ':') + 1, NULL, 10) == 3 && strtol(strchr(fb, ':') + 1, NULL, 10) == 3);
    const char *va = strstr(ta, "\"cloth\""), *vb = strstr(tb, "\"cloth\"");
    va = va ? strstr(va, "\"vertices\":") : NULL;
    vb = vb ? strstr(vb, "\"vertices\":") : NULL;
    CHECK(va && vb && strtol(va + 11, NULL, 10) > 250 && strtol(vb + 11, NULL, 10) < 200);
    char missing[1200];
    snprintf(missing, sizeof missing, "%s/none", g_out);
    const char *bad[] = {g_exe, "simgen", "--out", b, "--like", missing, NULL};
    CHECK_EQ_INT(tool_run(bad, NULL), 1);
    const char *both[] = {g_exe, "simgen", "--out", b, "--like", like, "--all", NULL};
    CHECK_EQ_INT(tool_run(both, NULL), 2);
}

/* A run where every sequence fails names the bad field and writes no manifest. */
static void failed_run_writes_no_manifest(void)
{
    char dir[1024], err[1100], manifest[1100], text[4096];
    snprintf(dir, sizeof dir, "%s/all_failed", g_out);
    snprintf(err, sizeof err, "%s/all_failed.err", g_out);
    snprintf(manifest, sizeof manifest, "%s/manifest.json", dir);
    const char *argv[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--count", "2", "--frames", "3",
                          "--max-substeps", "1000", "--fast-collider", "16", NULL};
    CHECK_EQ_INT(tool_run_err(argv, NULL, err), 1);
    tool_slurp(err, text, sizeof text);
    CHECK_MSG(strstr(text, "max_substeps x fast_collider_factor = 1000 x 16 is over 4000") != NULL, "%s", text);
    CHECK_MSG(strstr(text, "manifest.json not written") != NULL, "%s", text);
    FILE *f = fopen(manifest, "rb");
    CHECK(f == NULL);
    if (f) {
        fclose(f);
    }
}

/* --mocap: windows of the library's clips (WEFT_MOCAP_DIR, set by the test), here the first of
 * the test clip walk_cmu07_01, short and unvalidated: its meta.json carries the library's split,
 * the clip and the body rule of real motion; the name says clip, vertices and first frame. Bad --mocap
 * values and unknown clips are refused, and --clips needs --mocap. */
static void mocap_windows_of_library_clips(void)
{
    char dir[1024], meta[1200], err[1100], text[1 << 14];
    snprintf(dir, sizeof dir, "%s/mocap", g_out);
    snprintf(meta, sizeof meta, "%s/mocap_walk_cmu07_01_v256_00000/meta.json", dir);
    snprintf(err, sizeof err, "%s/mocap.err", g_out);
    mkdir(g_out, 0777); /* this case may run alone */
    unlink(meta);
    const char *argv[] = {g_exe, "simgen", "--out", dir, "--mocap", "test", "--clips", "walk_cmu07_01", "--vertices",
                          "256", "--frames", "4", "--limit", "1", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run_err(argv, NULL, err), 0);
    tool_slurp(meta, text, sizeof text);
    CHECK_MSG(strstr(text, "\"split\":\t\"test\"") != NULL, "no test split in %.300s", text);
    CHECK_MSG(strstr(text, "\"clip\":\t\"walk_cmu07_01\"") != NULL, "no clip in %.300s", text);
    CHECK_MSG(strstr(text, "mocap walk_cmu07_01 from 0.00 s") != NULL, "description: %.300s", text);
    CHECK(strstr(text, "\"inside_clear_limit\"") != NULL); /* the body rule of real motion */
    /* a T-shirt is held by the recipe's max distance, a skirt or dress by its waistband alone */
    double max_distance = -1.0;
    const char *md = strstr(text, "\"max_distance_m\":");
    CHECK_MSG(md && sscanf(md + 17, "%lf", &max_distance) == 1, "no max_distance_m in %.600s", text);
    const bool tshirt = strstr(text, "garment: tshirt") != NULL;
    CHECK_MSG(tshirt || strstr(text, "garment: skirt") || strstr(text, "garment: dress"), "garment? %.300s", text);
    CHECK_MSG(tshirt ? fabs(max_distance - WEFT_WORN_TETHER_CM / 100.0) < 1e-6 : max_distance == 0.0,
              "max distance %g for %s", max_distance, tshirt ? "a T-shirt" : "a skirt or dress");
    /* validated: the cloth is certified against itself and the body measured in every frame; the
     * window is accepted or rejected for a named reason (a cloth-cloth hit, or cloth inside the body) */
    snprintf(meta, sizeof meta, "%s/mocap_walk_cmu07_01_v256_00020/meta.json", dir);
    unlink(meta);
    const char *checked[] = {g_exe, "simgen", "--out", dir, "--mocap", "test", "--clips", "walk_cmu07_01", "--vertices",
                             "256", "--frames", "20", "--substeps", "10", "--max-substeps", "10", "--limit", "2", NULL};
    CHECK_EQ_INT(tool_run_err(checked, NULL, err), 0);
    tool_slurp(meta, text, sizeof text);
    double inside_mean = -1.0, clear_max = -1.0;
    const char *p = strstr(text, "\"inside_body_mean\":");
    CHECK_MSG(p && sscanf(p + 19, "%lf", &inside_mean) == 1, "no inside_body_mean in %.400s", text);
    p = strstr(text, "\"inside_clear_max\":");
    CHECK_MSG(p && sscanf(p + 19, "%lf", &clear_max) == 1, "no inside_clear_max in %.400s", text);
    CHECK_MSG(inside_mean >= 0.0 && inside_mean <= 1.0 && clear_max >= 0.0 && clear_max <= 1.0, "%g %g", inside_mean,
              clear_max);
    if (strstr(text, "\"accepted\":\tfalse")) {
        CHECK_MSG(strstr(text, "\"inside_clear_rejected\":\ttrue") || strstr(text, "\"tangled_rejected\":\ttrue") ||
                      !strstr(text, "\"first_hit_frame\":\t-1"),
                  "rejected without a reason: %.600s", text);
    } else {
        CHECK_MSG(clear_max <= WEFT_SIM_INSIDE_CLEAR_MAX, "accepted with %g of the cloth inside the clear body", clear_max);
        double tangled_max = -1.0;
        p = strstr(text, "\"tangled_max\":");
        CHECK_MSG(p && sscanf(p + 14, "%lf", &tangled_max) == 1, "no tangled_max in %.400s", text);
        CHECK_MSG(tangled_max >= 0.0 && tangled_max <= WEFT_SIM_TANGLED_MAX, "accepted with %g of the cloth crossing itself",
                  tangled_max);
    }
    const char *bad[] = {g_exe, "simgen", "--out", dir, "--mocap", "holdout", NULL};
    CHECK_EQ_INT(tool_run(bad, NULL), 2);
    const char *unknown[] = {g_exe, "simgen", "--out", dir, "--mocap", "all", "--clips", "moonwalk_cmu99", NULL};
    CHECK_EQ_INT(tool_run_err(unknown, NULL, err), 1);
    tool_slurp(err, text, sizeof text);
    CHECK_MSG(strstr(text, "no clip of") && strstr(text, "moonwalk_cmu99"), "%s", text);
    const char *alone[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--clips", "walk_cmu07_01", NULL};
    CHECK_EQ_INT(tool_run(alone, NULL), 2);
    /* --bvh: a file of the user's, the same windows, train or val by name */
    const char *lib = getenv("WEFT_MOCAP_DIR");
    char bvh[1200], own[1200];
    snprintf(bvh, sizeof bvh, "%s/clips/walk_cmu07_01.bvh.gz", lib ? lib : "samples/mocap");
    snprintf(own, sizeof own, "%s/mocap_walk_cmu07_01_v300_00000/meta.json", dir);
    unlink(own);
    const char *file[] = {g_exe, "simgen", "--out", dir, "--bvh", bvh, "--vertices", "300", "--frames", "4",
                          "--limit", "1", "--no-validate", NULL};
    CHECK_EQ_INT(tool_run_err(file, NULL, err), 0);
    tool_slurp(own, text, sizeof text);
    CHECK_MSG(strstr(text, "mocap walk_cmu07_01 from 0.00 s") != NULL, "--bvh window: %.300s", text);
    CHECK(strstr(text, "\"split\":\t\"train\"") || strstr(text, "\"split\":\t\"val\""));
    const char *missing[] = {g_exe, "simgen", "--out", dir, "--bvh", "/nonexistent/clip.bvh", NULL};
    CHECK_EQ_INT(tool_run_err(missing, NULL, err), 1);
    tool_slurp(err, text, sizeof text);
    CHECK_MSG(strstr(text, "--bvh /nonexistent/clip.bvh") != NULL, "%s", text);
    /* --joint-map: the clip through a map file; a map naming a joint the file lacks fails naming
     * it; a map without --bvh is a usage error */
    char map[1200], bad_map[1200];
    snprintf(map, sizeof map, "%s/samples/data/joint_map_cmu.txt", WEFT_SOURCE_DIR);
    snprintf(bad_map, sizeof bad_map, "%s/bad_joint_map.txt", g_out);
    FILE *f = fopen(bad_map, "w");
    if (f) {
        fputs("pelvis Hips\nleft_knee NoSuchKnee\n", f);
        fclose(f);
    }
    const char *mapped[] = {g_exe, "simgen", "--out", dir, "--bvh", bvh, "--joint-map", map, "--manifest-only", NULL};
    CHECK_EQ_INT(tool_run_err(mapped, NULL, err), 0);
    const char *bad_mapped[] = {g_exe, "simgen", "--out", dir, "--bvh", bvh, "--joint-map", bad_map, "--manifest-only", NULL};
    CHECK_EQ_INT(tool_run_err(bad_mapped, NULL, err), 1);
    tool_slurp(err, text, sizeof text);
    CHECK_MSG(strstr(text, "'NoSuchKnee'") != NULL && strstr(text, "left_knee") != NULL, "%s", text);
    const char *no_bvh[] = {g_exe, "simgen", "--out", dir, "--mocap", "test", "--joint-map", map, NULL};
    CHECK_EQ_INT(tool_run(no_bvh, NULL), 2);
}

/* --prefix-min: a real-motion window the validator rejects keeps the frames recorded before the
 * rejected one. At one substep the walk's first window at 256 vertices is rejected as the clip's
 * motion starts, after the 90-frame pre-roll: with --prefix-min 1 it is accepted as the frames
 * before that one (meta.json "truncated", "planned_frames" and the validator's first hit;
 * cloth_pos.npy and the manifest with that many frames); with the default (60) it is rejected and
 * writes no arrays. */
static void mocap_rejected_window_keeps_its_first_frames(void)
{
    char dir[1024], meta[1200], pos[1200], manifest[1200], err[1100], text[1 << 14];
    snprintf(dir, sizeof dir, "%s/prefix", g_out);
    snprintf(meta, sizeof meta, "%s/mocap_walk_cmu07_01_v256_00000/meta.json", dir);
    snprintf(pos, sizeof pos, "%s/mocap_walk_cmu07_01_v256_00000/cloth_pos.npy", dir);
    snprintf(manifest, sizeof manifest, "%s/manifest.json", dir);
    snprintf(err, sizeof err, "%s/prefix.err", g_out);
    mkdir(g_out, 0777); /* this case may run alone */
    unlink(meta);
    unlink(pos);
    const char *kept[] = {g_exe,      "simgen", "--out",           dir, "--mocap",  "test", "--clips",      "walk_cmu07_01",
                          "--vertices", "256",  "--frames",        "8", "--substeps", "1",  "--max-substeps", "1",
                          "--limit",    "1",    "--prefix-min",    "1", NULL};
    CHECK_EQ_INT(tool_run_err(kept, NULL, err), 0);
    tool_slurp(meta, text, sizeof text);
    int first = -1, frames = -1, planned = -1;
    const char *p = strstr(text, "\"first_hit_frame\":");
    CHECK_MSG(p && sscanf(p + 18, "%d", &first) == 1, "no first_hit_frame in %.600s", text);
    p = strstr(text, "\"frames\":");
    CHECK_MSG(p && sscanf(p + 9, "%d", &frames) == 1, "no frames in %.300s", text);
    p = strstr(text, "\"planned_frames\":");
    CHECK_MSG(p && sscanf(p + 17, "%d", &planned) == 1, "no planned_frames in %.600s", text);
    CHECK_MSG(strstr(text, "\"accepted\":\ttrue") && strstr(text, "\"truncated\":\ttrue"), "%.600s", text);
    CHECK_MSG(first > 90 && frames == first - 90 && frames < planned && planned == 8,
              "first hit at %d, %d of %d frames kept", first, frames, planned);
    /* the array holds the kept frames: the .npy header's shape starts with their count */
    memset(text, 0, sizeof text);
    FILE *npy = fopen(pos, "rb");
    const size_t got = npy ? fread(text, 1, 256, npy) : 0;
    if (npy) {
        fclose(npy);
    }
    for (size_t k = 0; k < got; ++k) {
        text[k] = text[k] ? text[k] : ' '; /* the magic's version bytes hold a NUL */
    }
    p = strstr(text, "'shape': (");
    int rows = -1;
    CHECK_MSG(p && sscanf(p + 10, "%d", &rows) == 1 && rows == frames, "cloth_pos.npy has %d frames, meta %d", rows,
              frames);
    tool_slurp(manifest, text, sizeof text);
    CHECK_MSG(strstr(text, "mocap_walk_cmu07_01_v256_00000") != NULL, "not in the manifest: %.400s", text);
    /* the default minimum: rejected, nothing but meta.json */
    unlink(meta);
    unlink(pos);
    const char *rejected[] = {g_exe,      "simgen", "--out",    dir, "--mocap",    "test", "--clips",        "walk_cmu07_01",
                              "--vertices", "256",  "--frames", "8", "--substeps", "1",    "--max-substeps", "1",
                              "--limit",    "1",    NULL};
    CHECK_EQ_INT(tool_run_err(rejected, NULL, err), 1);
    tool_slurp(meta, text, sizeof text);
    CHECK_MSG(strstr(text, "\"accepted\":\tfalse") && !strstr(text, "\"truncated\""), "%.400s", text);
    CHECK_MSG(!exists(pos), "a rejected window wrote %s", pos);
}

static void bad_plan_options_fail(void)
{
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/bad", g_out);
    const char *unknown[] = {g_exe, "simgen", "--out", dir, "--all", "--tier", "2k", NULL};
    CHECK_EQ_INT(tool_run(unknown, NULL), 2);
    const char *alone[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--tier", "4k", NULL};
    CHECK_EQ_INT(tool_run(alone, NULL), 2);
    const char *shard[] = {g_exe, "simgen", "--out", dir, "--all", "--shard", "3/3", NULL};
    CHECK_EQ_INT(tool_run(shard, NULL), 2);
    const char *split[] = {g_exe, "simgen", "--out", dir, "--all", "--split", "holdout", NULL};
    CHECK_EQ_INT(tool_run(split, NULL), 2);
    const char *only[] = {g_exe, "simgen", "--out", dir, "--all", "--only", "shirt", NULL};
    CHECK_EQ_INT(tool_run(only, NULL), 2);
    const char *only_alone[] = {g_exe, "simgen", "--out", dir, "--scenario", "drop", "--only", "drop", NULL};
    CHECK_EQ_INT(tool_run(only_alone, NULL), 2);
    const char *spread[] = {g_exe, "simgen", "--out", dir, "--all", "--arm-spread-retry", "0.9", NULL};
    CHECK_EQ_INT(tool_run(spread, NULL), 2);
    const char *spread_text[] = {g_exe, "simgen", "--out", dir, "--all", "--arm-spread-retry", "wide", NULL};
    CHECK_EQ_INT(tool_run(spread_text, NULL), 2);
    const char *ease[] = {g_exe, "simgen", "--out", dir, "--all", "--ease-in-retry", "-1", NULL};
    CHECK_EQ_INT(tool_run(ease, NULL), 2);
    const char *amplitude[] = {g_exe, "simgen", "--out", dir, "--all", "--amplitude-retry", "0", NULL};
    CHECK_EQ_INT(tool_run(amplitude, NULL), 2);
    /* every numeric option is a whole value in range: the --count that once wrapped the plan's size
     * (4294967196 + the tiers' 100) and asked for 412 GB (-1) is refused before anything is made */
    static const char *const numeric[][2] = {
        {"--count", "4294967196"}, {"--count", "-1"},      {"--count", "abc"},  {"--count", "2x"},
        {"--count", "3.7"},        {"--count", "0"},       {"--vertices", "1e3"}, {"--frames", "-5"},
        {"--substeps", "99999999999999999999"}, {"--max-substeps", "x"}, {"--limit", "-1"}, {"--seed", "12a"},
        {"--speed", "fast"},       {"--speed", "0"},       {"--garment-substeps", "-3"}};
    for (size_t k = 0; k < sizeof numeric / sizeof numeric[0]; ++k) {
        const char *argv[] = {g_exe, "simgen", "--out", dir, "--manifest-only", "--scenario", "drop",
                              numeric[k][0], numeric[k][1], NULL};
        CHECK_MSG(tool_run(argv, NULL) == 2, "%s %s was accepted", numeric[k][0], numeric[k][1]);
    }
    const char *fast[] = {g_exe, "simgen", "--out", dir, "--all", "--fast-collider", "0", NULL};
    CHECK_EQ_INT(tool_run(fast, NULL), 2);
    const char *fast_big[] = {g_exe, "simgen", "--out", dir, "--all", "--fast-collider", "17", NULL};
    CHECK_EQ_INT(tool_run(fast_big, NULL), 2);
    const char *ckpt[] = {g_exe, "simgen", "--out", dir, "--all", "--checkpoint-frames", "2.5", NULL};
    CHECK_EQ_INT(tool_run(ckpt, NULL), 2);
    const char *limit[] = {g_exe, "simgen", "--out", dir, "--all", "--time-limit", "-3", NULL};
    CHECK_EQ_INT(tool_run(limit, NULL), 2);
    CHECK_MSG(!exists(dir), "a rejected command created %s", dir);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s WEFT OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_out = argv[2];
    static const test_case_ cases[] = {TEST_CASE(tier_generates_only_that_tier),
                                         TEST_CASE(split_generates_only_that_split), TEST_CASE(manifest_keeps_other_runs),
                                         TEST_CASE(only_generates_that_scenario),
                                         TEST_CASE(redo_rejected_runs_rejected_again), TEST_CASE(like_makes_the_same_scene),
                                         TEST_CASE(failed_run_writes_no_manifest), TEST_CASE(mocap_windows_of_library_clips),
                                         TEST_CASE(mocap_rejected_window_keeps_its_first_frames),
                                         TEST_CASE(bad_plan_options_fail)};
    return test_run_(cases, sizeof cases / sizeof cases[0], argc - 2, argv + 2);
}
