/* weft simgen: generate the reference-simulation dataset (see docs/DATASET.md). */
#define _POSIX_C_SOURCE 200809L
#include "weft.h"
#include "support_cli.h"
#include "support_bench.h"
#include "weft/sim.h"
#include "bvh.h"
#if WEFT_HAVE_RENDER && WEFT_RENDER_HAVE_ASSETS && WEFT_RENDER_HAVE_SAMPLE
#include "character.h"
#include "pc2.h"
#define SIMGEN_HAVE_CHARACTER 1
#else
#define SIMGEN_HAVE_CHARACTER 0
#endif

#include <cjson/cJSON.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

int weft_cmd_simgen(int argc, char **argv); /* the CLI registry declares it in main.c */
const char weft_cmd_simgen_help[] = "generate validated XPBD cloth sequences (drop, gripper, garment) for training";

typedef struct plan_item {
    weft_sim_scenario scenario;
    uint32_t vertices;
    uint32_t index;
    const char *tier; /* the --all tier's tag ("1k", ...); NULL for --scenario items */
    char name[64];
    uint64_t seed;    /* --like: the sequence seed itself (0: hashed from the name) */
    /* --mocap: the clip file, the window's start and length, and its split (the library's) */
    char motion[240];
    double start_s;
    uint32_t frames;  /* 0: the run's --frames */
    const char *split;
} plan_item;

/* The full dataset: small sheets first so training can start early, then larger ones. */
typedef struct plan_tier {
    uint32_t vertices, per_scenario;
    const char *tag;
} plan_tier;
static const plan_tier k_tiers[] = {{1024, 150, "1k"}, {4096, 30, "4k"}, {16384, 2, "16k"}};

/* Which plan items this process generates: its shard, and the --tier and --split filters when given. */
typedef struct plan_filter {
    uint32_t shard_i, shard_n;
    const char *tier;
    const char *split; /* "train", "val" or "test": only names that would land in that split if accepted */
    int only;          /* a weft_sim_scenario, or -1 for all */
} plan_filter;

static bool plan_wanted(const plan_filter *f, const plan_item *items, uint32_t i)
{
    if (i % f->shard_n != f->shard_i) {
        return false;
    }
    if (f->only >= 0 && (int)items[i].scenario != f->only) {
        return false;
    }
    if (f->split && strcmp(items[i].split ? items[i].split : weft_sim_split_of(items[i].name), f->split) != 0) {
        return false;
    }
    return !f->tier || (items[i].tier && strcmp(items[i].tier, f->tier) == 0);
}

static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static uint64_t seq_seed(uint64_t seed0, const char *name)
{
    uint64_t h = 1469598103934665603ull ^ seed0;
    for (const char *c = name; *c; ++c) {
        h = (h ^ (unsigned char)*c) * 1099511628211ull;
    }
    return mix64(h);
}

/* The parsed meta.json at path; NULL when missing or unreadable. */
static cJSON *read_meta(const char *path)
{
    char *text = bench_slurp(path, NULL);
    cJSON *meta = text ? cJSON_Parse(text) : NULL;
    free(text);
    return meta;
}

static bool file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Why the validator rejected the last attempt of a sequence (res->first_hit_frame >= 0), in words. */
static void rejection_reason(const weft_sim_sequence_result *res, char *out, size_t cap)
{
    if (res->inside_clear_rejected) {
        snprintf(out, cap, "%.1f %% of the cloth inside the body where it does not overlap itself at frame %d (limit "
                           "%.1f %%, substeps %u)",
                 100.0 * res->rejected_share, res->first_hit_frame, 100.0 * WEFT_SIM_INSIDE_CLEAR_MAX,
                 res->substeps_used);
    } else if (res->tangled_rejected) {
        snprintf(out, cap, "%.1f %% of the cloth crossing itself at frame %d (limit %.1f %%, substeps %u)",
                 100.0 * res->rejected_share, res->first_hit_frame, 100.0 * WEFT_SIM_TANGLED_MAX, res->substeps_used);
    } else {
        snprintf(out, cap, "the validator's hits (%u CCD, %u intersection, first at frame %d, substeps %u%s%s)",
                 res->ccd_hits, res->intersection_hits, res->first_hit_frame, res->substeps_used,
                 res->hit_joint[0] ? ", near " : "", res->hit_joint);
    }
}

/* Whether the sequence whose meta.json is at path still needs generating: not finished (no
 * meta.json), or with redo_rejected finished and rejected. */
static bool needs_run(const char *path, bool redo_rejected)
{
    if (!file_exists(path)) {
        return true;
    }
    if (!redo_rejected) {
        return false;
    }
    cJSON *meta = read_meta(path);
    bool rejected = meta && cJSON_IsFalse(cJSON_GetObjectItem(meta, "accepted"));
    cJSON_Delete(meta);
    return rejected;
}

typedef struct progress_state {
    uint32_t done, total;
    const char *name;
    double t0;
    double frac0; /* progress when this run began (a resumed sequence starts part way); < 0: not yet known */
} progress_state;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void draw_bar(const progress_state *p, uint32_t frame, uint32_t frames)
{
    double frac = p->total ? (p->done + (frames ? (double)frame / frames : 0.0)) / p->total : 1.0;
    int width = 30, fill = (int)(frac * width);
    char bar[32];
    for (int i = 0; i < width; ++i) {
        bar[i] = i < fill ? '#' : '-';
    }
    bar[width] = '\0';
    double el = now_s() - p->t0, base = p->frac0 > 0.0 ? p->frac0 : 0.0;
    double eta = frac - base > 1e-6 ? el * (1.0 - frac) / (frac - base) : 0.0;
    fprintf(stderr, "\r[%s] %u/%u %-22s frame %3u/%u  %5.0fs elapsed, ~%5.0fs left ", bar, p->done, p->total,
            p->name ? p->name : "", frame, frames, el, eta);
    fflush(stderr);
}

static void on_frame(uint32_t frame, uint32_t frames, void *user)
{
    progress_state *p = user;
    if (p->frac0 < 0.0 && p->total && frames) {
        p->frac0 = (p->done + (frame - 1.0) / frames) / p->total;
    }
    if (frame % 10 == 0 || frame + 1 == frames) {
        draw_bar(user, frame, frames);
    }
}

/* A sequence the manifest lists: this run's plan, then any other finished folder under DIR (a
 * `--scenario` run into a folder another run filled keeps the other run's sequences listed). */
typedef struct manifest_item {
    char name[64];
    int scenario; /* weft_sim_scenario; -1 until read from meta.json */
} manifest_item;

static int cmp_manifest_item(const void *a, const void *b)
{
    return strcmp(((const manifest_item *)a)->name, ((const manifest_item *)b)->name);
}

/* The plan's names in plan order, then the other folders of `out` holding a meta.json, sorted by
 * name. NULL on out of memory. */
static manifest_item *manifest_items(const char *out, const plan_item *plan, uint32_t n, uint32_t *count)
{
    uint32_t cap = n + 64, m = 0;
    manifest_item *items = malloc(cap * sizeof *items);
    for (uint32_t i = 0; items && i < n; ++i) {
        snprintf(items[m].name, sizeof items[m].name, "%s", plan[i].name);
        items[m++].scenario = (int)plan[i].scenario;
    }
    const uint32_t planned = m;
    DIR *dh = items ? opendir(out) : NULL;
    struct dirent *de;
    while (dh && (de = readdir(dh)) != NULL) {
        char meta[1200];
        manifest_item key;
        if (de->d_name[0] == '.' || strlen(de->d_name) >= sizeof key.name) {
            continue;
        }
        snprintf(key.name, sizeof key.name, "%s", de->d_name);
        snprintf(meta, sizeof meta, "%s/%s/meta.json", out, de->d_name);
        bool in_plan = false;
        for (uint32_t i = 0; i < planned && !in_plan; ++i) {
            in_plan = strcmp(items[i].name, key.name) == 0;
        }
        if (in_plan || !file_exists(meta)) {
            continue;
        }
        if (m == cap) {
            manifest_item *grown = realloc(items, (size_t)(cap *= 2) * sizeof *items);
            if (!grown) {
                free(items);
                items = NULL;
                break;
            }
            items = grown;
        }
        key.scenario = -1;
        items[m++] = key;
    }
    if (dh) {
        closedir(dh);
    }
    if (items) {
        qsort(items + planned, m - planned, sizeof *items, cmp_manifest_item);
    }
    *count = m;
    return items;
}

static int write_manifest(const char *out, const plan_item *plan, uint32_t n_plan)
{
    uint32_t n = 0;
    manifest_item *items = manifest_items(out, plan, n_plan, &n);
    if (!items) {
        fprintf(stderr, "simgen: out of memory\n");
        return 1;
    }
    cJSON *root = cJSON_CreateObject();
    cJSON *seqs = cJSON_CreateArray();
    uint32_t counts[WEFT_SIM_SCENARIO_COUNT][4] = {{0}}; /* accepted train/val/test, rejected */
    char path[1200];
    snprintf(path, sizeof path, "%s/splits", out);
    mkdir(path, 0777);
    FILE *split_files[WEFT_SIM_SCENARIO_COUNT][3] = {{NULL}};
    static const char *const names[3] = {"train", "val", "test"};
    for (int s = 0; s < WEFT_SIM_SCENARIO_COUNT; ++s) {
        for (int k = 0; k < 3; ++k) {
            snprintf(path, sizeof path, "%s/splits/%s_%s.txt", out, weft_sim_scenario_name((weft_sim_scenario)s),
                     names[k]);
            split_files[s][k] = fopen(path, "w");
        }
    }
    for (uint32_t i = 0; i < n; ++i) {
        snprintf(path, sizeof path, "%s/%s/meta.json", out, items[i].name);
        cJSON *meta = read_meta(path);
        if (!meta) {
            continue;
        }
        if (items[i].scenario < 0) { /* not planned by this run: the scenario its meta.json names */
            const cJSON *sc = cJSON_GetObjectItem(meta, "scenario");
            for (int k = 0; k < WEFT_SIM_SCENARIO_COUNT && cJSON_IsString(sc); ++k) {
                items[i].scenario = strcmp(sc->valuestring, weft_sim_scenario_name((weft_sim_scenario)k)) == 0
                                        ? k
                                        : items[i].scenario;
            }
            if (items[i].scenario < 0) {
                cJSON_Delete(meta);
                continue;
            }
        }
        const weft_sim_scenario scenario = (weft_sim_scenario)items[i].scenario;
        bool accepted = cJSON_IsTrue(cJSON_GetObjectItem(meta, "accepted"));
        cJSON *e = cJSON_CreateObject();
        cJSON_AddStringToObject(e, "name", items[i].name);
        cJSON_AddStringToObject(e, "scenario", weft_sim_scenario_name(scenario));
        cJSON *cl = cJSON_GetObjectItem(meta, "cloth");
        cJSON_AddNumberToObject(e, "vertices", cJSON_GetNumberValue(cJSON_GetObjectItem(cl, "vertices")));
        cJSON_AddNumberToObject(e, "substeps", cJSON_GetNumberValue(cJSON_GetObjectItem(meta, "substeps")));
        cJSON_AddNumberToObject(e, "frames", cJSON_GetNumberValue(cJSON_GetObjectItem(meta, "frames")));
        cJSON_AddBoolToObject(e, "accepted", accepted);
        const cJSON *ms = cJSON_GetObjectItemCaseSensitive(meta, "split"); /* mocap: the library's split */
        const char *own = cJSON_IsString(ms) && (!strcmp(ms->valuestring, "train") || !strcmp(ms->valuestring, "val") ||
                                                 !strcmp(ms->valuestring, "test"))
                              ? ms->valuestring
                              : weft_sim_split_of(items[i].name);
        const char *split = accepted ? own : "rejected";
        cJSON_AddStringToObject(e, "split", split);
        cJSON_AddItemToArray(seqs, e);
        int k = accepted ? (strcmp(split, "train") == 0 ? 0 : (strcmp(split, "val") == 0 ? 1 : 2)) : 3;
        counts[scenario][k]++;
        if (k < 3 && split_files[scenario][k]) {
            fprintf(split_files[scenario][k], "%s\n", items[i].name);
        }
        cJSON_Delete(meta);
    }
    for (int s = 0; s < WEFT_SIM_SCENARIO_COUNT; ++s) {
        for (int k = 0; k < 3; ++k) {
            if (split_files[s][k]) {
                fclose(split_files[s][k]);
            }
        }
        cJSON *c = cJSON_CreateObject();
        cJSON_AddNumberToObject(c, "train", counts[s][0]);
        cJSON_AddNumberToObject(c, "val", counts[s][1]);
        cJSON_AddNumberToObject(c, "test", counts[s][2]);
        cJSON_AddNumberToObject(c, "rejected", counts[s][3]);
        cJSON_AddItemToObject(root, weft_sim_scenario_name((weft_sim_scenario)s), c);
    }
    free(items);
    cJSON_AddItemToObject(root, "sequences", seqs);
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) {
        return 1;
    }
    /* Shards may rebuild the manifest concurrently: write a private file, then rename. */
    char tmp[1200], fin[1200];
    snprintf(tmp, sizeof tmp, "%s/manifest.json.%ld.tmp", out, (long)getpid());
    snprintf(fin, sizeof fin, "%s/manifest.json", out);
    FILE *f = fopen(tmp, "wb");
    bool ok = f && fputs(text, f) >= 0;
    ok = (f && fclose(f) == 0) && ok && rename(tmp, fin) == 0;
    cJSON_free(text);
    if (!ok) {
        fprintf(stderr, "simgen: cannot write %s\n", fin);
        return 1;
    }
    return 0;
}

/* --mocap: windows of the library's clips (DIR/clips.csv: file,split,...,duration at column 12),
 * window k of every clip before window k + 1 of any, so a partial run covers every clip. Each
 * window starts frames/60 s after the last and plays up to `frames` frames, fewer at a clip's end
 * (at least one second). Train clips give "train" or, by the name's hash, "val" windows; test
 * clips "test". Returns the number of items added to *plan (grown), or -1 after printing why. */
#define MOCAP_MAX_CLIPS 512
typedef struct mocap_clip {
    char name[64], file[240];
    bool test;
    double duration;
} mocap_clip;

static bool clip_listed(const char *list, const char *name)
{
    const size_t n = strlen(name);
    for (const char *p = list; p && *p;) {
        const size_t k = strcspn(p, ",");
        if (k == n && strncmp(p, name, n) == 0) {
            return true;
        }
        p += k + (p[k] == ',');
    }
    return false;
}

static int plan_windows(const mocap_clip *list, uint32_t nc, uint32_t frames, uint32_t vertices, plan_item **plan,
                        uint32_t *n, uint32_t *cap);

/* --bvh PATH: one clip of the user's, windowed like a library train clip; its length from the
 * file itself. */
static int bvh_plan(const char *path, const char *const *joint_map, uint32_t frames, uint32_t vertices, plan_item **plan,
                    uint32_t *n, uint32_t *cap)
{
    mocap_clip c = {0};
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const size_t k = strcspn(base, ".");
    if (k == 0 || k > 40 || strlen(path) >= sizeof c.file) {
        fprintf(stderr, "simgen: --bvh '%s': the file name must be 1..40 characters before its extension and the "
                        "path under %zu\n", path, sizeof c.file);
        return -1;
    }
    memcpy(c.name, base, k);
    snprintf(c.file, sizeof c.file, "%s", path);
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_clip *clip = NULL;
    weft_bvh_def bd = weft_default_bvh_def();
    bd.joint_map = joint_map;
    weft_result r = weft_context_create(&cd, &ctx);
    r = r != WEFT_OK ? r : weft_bvh_load_file(ctx, path, &bd, &clip);
    if (r != WEFT_OK) {
        fprintf(stderr, "simgen: --bvh %s: %s\n", path, weft_last_error());
        weft_context_destroy(ctx);
        return -1;
    }
    c.duration = clip->frame_count > 1 ? (clip->frame_count - 1) / (double)clip->fps : 0.0;
    weft_clip_destroy(clip);
    weft_context_destroy(ctx);
    if (c.duration < 1.0) {
        fprintf(stderr, "simgen: --bvh %s: %.2f s of motion, shorter than the 1 s a window needs\n", path, c.duration);
        return -1;
    }
    return plan_windows(&c, 1, frames, vertices, plan, n, cap);
}

static int mocap_plan(const char *dir, const char *which, const char *clips, uint32_t frames, uint32_t vertices,
                      plan_item **plan, uint32_t *n, uint32_t *cap)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/clips.csv", dir);
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "simgen: cannot read %s (--mocap-dir, or WEFT_MOCAP_DIR)\n", path);
        return -1;
    }
    mocap_clip *list = calloc(MOCAP_MAX_CLIPS, sizeof *list);
    if (!list) {
        fclose(f);
        return -1;
    }
    char line[4096];
    uint32_t nc = 0, line_no = 0;
    while (fgets(line, sizeof line, f) && nc < MOCAP_MAX_CLIPS) {
        if (line_no++ == 0) {
            continue; /* header */
        }
        /* fields split at commas outside quotes */
        char *field[16] = {0};
        int nf = 0;
        bool quoted = false;
        field[nf++] = line;
        for (char *c = line; *c && nf < 16; ++c) {
            if (*c == '"') {
                quoted = !quoted;
            } else if (*c == ',' && !quoted) {
                *c = '\0';
                field[nf++] = c + 1;
            }
        }
        if (nf < 12) {
            continue;
        }
        const char *base = strrchr(field[0], '/');
        base = base ? base + 1 : field[0];
        const size_t k = strcspn(base, ".");
        char *end = NULL;
        const double duration = strtod(field[11], &end);
        if (k == 0 || k > 40 || end == field[11] || !(duration > 0.0 && duration < 1e5)) {
            fprintf(stderr, "simgen: %s line %u is not file,split,...,duration\n", path, line_no);
            free(list);
            fclose(f);
            return -1;
        }
        mocap_clip *c = &list[nc];
        memcpy(c->name, base, k);
        c->name[k] = '\0';
        c->test = strcmp(field[1], "test") == 0;
        c->duration = duration;
        snprintf(c->file, sizeof c->file, "%.150s/%.80s", dir, field[0]);
        const bool split_ok = !strcmp(which, "all") || (c->test ? !strcmp(which, "test") : !strcmp(which, "train"));
        nc += clips ? clip_listed(clips, c->name) : split_ok;
    }
    fclose(f);
    if (nc == 0) {
        fprintf(stderr, "simgen: no clip of %s matches --mocap %s%s%s\n", path, which, clips ? " --clips " : "",
                clips ? clips : "");
        free(list);
        return -1;
    }
    const int added = plan_windows(list, nc, frames, vertices, plan, n, cap);
    free(list);
    return added;
}

static int plan_windows(const mocap_clip *list, uint32_t nc, uint32_t frames, uint32_t vertices, plan_item **plan,
                        uint32_t *n, uint32_t *cap)
{
    const double step = frames / 60.0;
    uint32_t added = 0;
    for (uint32_t w = 0;; ++w) {
        uint32_t here = 0;
        for (uint32_t c = 0; c < nc; ++c) {
            const double start = w * step, left = list[c].duration - start;
            if (left < 1.0) {
                continue;
            }
            if (*n == *cap) {
                const uint32_t grown = *cap ? 2 * *cap : 256;
                plan_item *p = realloc(*plan, grown * sizeof *p);
                if (!p) {
                    return -1;
                }
                memset(p + *cap, 0, (grown - *cap) * sizeof *p);
                *plan = p;
                *cap = grown;
            }
            plan_item *p = &(*plan)[(*n)++];
            p->scenario = WEFT_SIM_SCENARIO_GARMENT;
            p->vertices = vertices;
            p->index = w;
            p->start_s = start;
            const uint32_t fit = (uint32_t)(left * 60.0);
            p->frames = fit < frames ? fit : frames;
            snprintf(p->motion, sizeof p->motion, "%.239s", list[c].file);
            snprintf(p->name, sizeof p->name, "mocap_%.40s_v%u_%05u", list[c].name, vertices, w * frames);
            p->split = list[c].test ? "test" : (strcmp(weft_sim_split_of(p->name), "val") == 0 ? "val" : "train");
            ++here;
            ++added;
        }
        if (here == 0) {
            break;
        }
    }
    return (int)added;
}

enum {
    OPT_OUT = 1, OPT_ALL, OPT_SCENARIO, OPT_COUNT, OPT_VERTICES, OPT_LIKE, OPT_MANIFEST_ONLY, OPT_MOCAP, OPT_CLIPS,
    OPT_MOCAP_DIR, OPT_BVH, OPT_JOINT_MAP, OPT_AVATAR, OPT_GARMENT, OPT_PREROLL, OPT_TIER, OPT_SPLIT, OPT_ONLY,
    OPT_NO_GARMENTS, OPT_SHARD, OPT_LIMIT, OPT_FRAMES, OPT_SUBSTEPS, OPT_MAX_SUBSTEPS, OPT_GARMENT_SUBSTEPS,
    OPT_FAST_COLLIDER, OPT_SEED, OPT_SPEED, OPT_RESOLUTION_SERIES, OPT_ARM_SPREAD, OPT_ARM_SPREAD_RETRY,
    OPT_EASE_IN_RETRY, OPT_AMPLITUDE_RETRY, OPT_NO_GARMENT_RETRY, OPT_NO_VALIDATE, OPT_REDO_REJECTED,
    OPT_CHECKPOINT_FRAMES, OPT_TIME_LIMIT, OPT_PREFIX_MIN,
};

static const cli_option k_options[] = {
    {"out", "DIR", OPT_OUT, "the dataset folder (created with its parents); required"},
    {"all", NULL, OPT_ALL,
     "the whole planned set: per scenario (drop, gripper, garment) 150 x 1k,\n"
     "30 x 4k and 2 x 16k vertices, smallest first"},
    {"scenario", "drop|gripper|garment", OPT_SCENARIO,
     "--count sequences of one scenario at --vertices, named\n"
     "<scenario>_v<V>_<index>"},
    {"count", "N", OPT_COUNT, "sequences of --scenario, 1..100000 (default 10)"},
    {"vertices", "V", OPT_VERTICES, "cloth vertices of --scenario, --mocap, --bvh and --like, 3..10000000\n(default 1024)"},
    {"like", "DIR", OPT_LIKE,
     "the scene of the sequence in DIR (its meta.json's scenario, seed_u64,\n"
     "frames and motion speed) at --vertices, as DIR-NAME_v<vertices>: a twin\n"
     "at another resolution for cross-resolution tests (e.g. the 1k twin of a\n"
     "16k sequence)"},
    {"manifest-only", NULL, OPT_MANIFEST_ONLY,
     "generate nothing: rewrite DIR/manifest.json and the split files from the\n"
     "finished sequences"},
    {"mocap", "train|test|all", OPT_MOCAP,
     "garments on the mocap library's clips of that split\n"
     "(samples/mocap/clips.csv): windows of --frames every --frames/60 s of\n"
     "each clip (fewer frames at a clip's end), named\n"
     "mocap_<clip>_v<V>_<first frame>, the avatar and garment drawn from the\n"
     "name; no arm spread, body parts in the reference and the validator\n"
     "(docs/REFSIM.md, Real motion). Test clips give test sequences, train\n"
     "clips train and (by the name's hash, 1 in 10) val sequences"},
    {"clips", "A,B,...", OPT_CLIPS, "with --mocap: only these clips (names as in clips.csv)"},
    {"mocap-dir", "DIR", OPT_MOCAP_DIR, "the library (default $WEFT_MOCAP_DIR, else samples/mocap)"},
    {"bvh", "PATH", OPT_BVH,
     "the same windows of one BVH file of yours (plain or .gz, any skeleton\n"
     "weft_bvh_load_file maps), named mocap_<file stem>_..., train or val by\n"
     "name"},
    {"joint-map", "FILE", OPT_JOINT_MAP,
     "with --bvh: the file's joint for each SMPL joint, one\n"
     "'smpl_joint source_joint' a line (a skeleton no naming table knows;\n"
     "docs/RENDER.md, BVH import)"},
    {"avatar", "gltf:PATH", OPT_AVATAR,
     "your own skinned character (glTF/FBX, any joint names, metres, Y up) as\n"
     "the collider, played by its own animation after a pre-roll of --preroll\n"
     "frames; body parts from its joints; one sequence,\n"
     "character_<avatar>_<garment>; needs --garment, and no --all, --scenario,\n"
     "--mocap, --bvh, --like or --manifest-only"},
    {"garment", "obj:PATH", OPT_GARMENT,
     "with --avatar: the garment, an OBJ fitted to the character's bind pose\n"
     "(refused when it is not on the character or lies inside it;\n"
     "docs/RENDER.md, Your own character)"},
    {"preroll", "N", OPT_PREROLL,
     "with --avatar: pre-roll frames, 2..1000 (default 90): half blending from\n"
     "the bind pose, half holding the first pose; not recorded"},
    {"tier", "1k|4k|16k", OPT_TIER,
     "generate only that tier of --all (e.g. the 16k cross-resolution\n"
     "sequences before the 1k tier is finished)"},
    {"split", "train|val|test", OPT_SPLIT,
     "only sequences whose name falls in that split (the split is a hash of\n"
     "the name): e.g. the held-out test sequences without the training set"},
    {"only", "drop|gripper|garment", OPT_ONLY, "only that scenario of --all (same names and seeds as in the full plan)"},
    {"no-garments", NULL, OPT_NO_GARMENTS, "leave the garment scenario out of --all (it is the slowest)"},
    {"shard", "I/N", OPT_SHARD,
     "only sequences whose plan index is I modulo N (job arrays;\n"
     "0 <= I < N <= 100000)"},
    {"limit", "N", OPT_LIMIT, "stop after generating N new sequences (0..100000000)"},
    {"frames", "T", OPT_FRAMES,
     "recorded frames per sequence, 1..1000000\n"
     "(default 240; --like: the other sequence's)"},
    {"substeps", "S", OPT_SUBSTEPS, "solver substeps per frame of the first attempt, 1..4000 (default 40)"},
    {"max-substeps", "S", OPT_MAX_SUBSTEPS,
     "a rejected sequence is retried with more substeps up to S, 0..4000\n"
     "(default 80; below --substeps: --substeps)"},
    {"garment-substeps", "S", OPT_GARMENT_SUBSTEPS,
     "first attempt of a garment sequence when above --substeps (0..4000)\n"
     "(default: none, garments start at --substeps like the others)"},
    {"fast-collider", "F", OPT_FAST_COLLIDER,
     "a frame whose collider moves fast near the cloth gets up to F times the\n"
     "attempt's substeps, so the solver's bounds can keep the cloth it pushes\n"
     "outside it (1..16, 1 = fixed substeps; default below)"},
    {"seed", "X", OPT_SEED,
     "every sequence's seed is hashed from X and its name, 0..2^64-1\n"
     "(default 1)"},
    {"speed", "X", OPT_SPEED,
     "scale the avatar's motion and the gripper's schedule (0.1..10, default\n"
     "1; the stability suite's speed axis); same draws as at speed 1"},
    {"resolution-series", NULL, OPT_RESOLUTION_SERIES,
     "seed each sequence from <scenario>_<index>, not its full name, so the\n"
     "same --scenario/--count/--seed at another --vertices draws the same\n"
     "scene (objects, body, motion, garment type) at another resolution"},
    {"arm-spread", "R", OPT_ARM_SPREAD,
     "the avatar's arms held R radians further from the torso than the motion\n"
     "has them, in every garment sequence (0..0.8; 0: as before, when the\n"
     "skinned avatar intersects itself at the armpits in most frames)"},
    {"arm-spread-retry", "R", OPT_ARM_SPREAD_RETRY,
     "a garment still rejected at --max-substeps is retried, gently: with the\n"
     "avatar's arms R radians further still (--arm-spread + R <= 0.8), its\n"
     "motion eased in over --ease-in-retry and scaled by --amplitude-retry"},
    {"ease-in-retry", "S", OPT_EASE_IN_RETRY, "the retry's motion eased in from rest over S seconds (0..2)"},
    {"amplitude-retry", "A", OPT_AMPLITUDE_RETRY, "the retry's motion amplitude scaled by A (0.1..1)"},
    {"no-garment-retry", NULL, OPT_NO_GARMENT_RETRY, "no such retry"},
    {"no-validate", NULL, OPT_NO_VALIDATE, "skip the validator (every finished sequence is accepted)"},
    {"redo-rejected", NULL, OPT_REDO_REJECTED,
     "generate the finished but rejected sequences again (after a generator\n"
     "change, e.g. the gentle garment retry), besides the unfinished ones"},
    {"checkpoint-frames", "N", OPT_CHECKPOINT_FRAMES,
     "save a sequence's state every N frames, 0..100000\n"
     "(DIR/<name>/checkpoint.bin) and continue from it when rerun (default: 10\n"
     "for sequences of 16k vertices or more, 0 = none below); part of what\n"
     "defines the sequence"},
    {"prefix-min", "N", OPT_PREFIX_MIN,
     "with --mocap or --bvh: a window the validator rejects keeps its validated\n"
     "frames before the rejected one when there are at least N, 0..100000\n"
     "(default 60; 0: a rejected window keeps nothing)"},
    {"time-limit", "S", OPT_TIME_LIMIT,
     "stop at the first checkpoint after S seconds, 0..1e9 (sequences without\n"
     "checkpoints are not started once S has passed); rerun to continue"},
    {0},
};

static void notes(FILE *out)
{
    const weft_sim_sequence_def d = weft_sim_default_sequence_def();
    fprintf(out,
            "Defaults: --arm-spread %.2g, --arm-spread-retry %.2g, --ease-in-retry %.2g, --amplitude-retry %.2g,\n"
            "--fast-collider %u.\n"
            "Finished sequences (DIR/<name>/meta.json present) are skipped, so a run resumes.\n"
            "Writes DIR/manifest.json and DIR/splits/<scenario>_{train,val,test}.txt (8:1:1).\n"
            "A value out of range or not a whole number (where one is wanted) is refused.\n",
            (double)d.garment_arm_spread, (double)d.garment_retry_arm_spread, (double)d.garment_retry_ease_in,
            (double)d.garment_retry_amplitude, d.fast_collider_factor);
}

static const cli_command k_command = {
    .tool = "weft simgen",
    .synopsis =
        "weft simgen --out DIR (--all | --scenario drop|gripper|garment [--count N] [--vertices V])\n"
        "            [--shard I/N] [--frames T] [--substeps S] [--max-substeps S] [--seed X]\n"
        "            [--garment-substeps S] [--no-validate] [--manifest-only] [--limit N]\n"
        "            [--no-garments] [--speed X] [--resolution-series] [--tier 1k|4k|16k]\n"
        "            [--split train|val|test] [--only drop|gripper|garment] [--arm-spread-retry R]\n"
        "            [--ease-in-retry S] [--amplitude-retry A] [--no-garment-retry] [--redo-rejected]\n"
        "            [--fast-collider F] [--arm-spread R] [--checkpoint-frames N] [--time-limit S]\n"
        "            [--prefix-min N]\n"
        "weft simgen --out DIR --avatar gltf:PATH --garment obj:PATH [--frames T] [--substeps S]\n"
        "            [--max-substeps S] [--fast-collider F] [--preroll N] [--no-validate]\n"
        "weft simgen --out DIR (--mocap train|test|all [--clips A,B,...] [--mocap-dir DIR]\n"
        "                       | --bvh PATH [--joint-map FILE])\n"
        "            [--vertices V] [--frames T] [--split train|val|test] [--shard I/N] [...]\n"
        "weft simgen --out DIR --like DIR [--vertices V] [--frames T] [...]",
    .about = "Generates the reference-simulation dataset (docs/DATASET.md): XPBD cloth sequences (drop,\n"
             "gripper, garment) certified frame by frame by the validator, for training.",
    .options = k_options,
    .notes = notes,
};

/* "I/N": two whole numbers, 0 <= I < N <= 100000, nothing else. */
static bool parse_shard(const char *v, uint32_t *i, uint32_t *n)
{
    char part[2][16];
    const char *slash = strchr(v, '/');
    const size_t len = slash ? (size_t)(slash - v) : 0;
    if (!slash || len == 0 || len >= sizeof part[0] || strlen(slash + 1) >= sizeof part[1]) {
        return false;
    }
    memcpy(part[0], v, len);
    part[0][len] = '\0';
    snprintf(part[1], sizeof part[1], "%s", slash + 1);
    for (int k = 0; k < 2; ++k) {
        if (part[k][0] == '\0' || strspn(part[k], "0123456789") != strlen(part[k]) || strlen(part[k]) > 6) {
            return false;
        }
    }
    const unsigned long a = strtoul(part[0], NULL, 10), b = strtoul(part[1], NULL, 10);
    if (b == 0 || b > 100000 || a >= b) {
        return false;
    }
    *i = (uint32_t)a;
    *n = (uint32_t)b;
    return true;
}

/* --avatar gltf:PATH --garment obj:PATH: one sequence of the user's garment on the user's
 * character (weft_sim_character). */
typedef struct character_run {
#if SIMGEN_HAVE_CHARACTER
    weft_sample_character *character;
#endif
    uint32_t blend, preroll;
} character_run;

#if SIMGEN_HAVE_CHARACTER
static void character_collider_at(void *user, uint32_t f, float *out)
{
    character_run *run = user;
    const double t = f >= run->preroll ? (f - run->preroll) / 60.0 : 0.0;
    double u = f >= run->blend ? 1.0 : (f + 1.0) / run->blend;
    u = u * u * (3.0 - 2.0 * u);
    /* fails only on arguments checked here (a loaded character, finite t, u in [0, 1]) */
    (void)weft_sample_character_pose(run->character, t, u, out);
}

/* The file's name without folders and extension, as [A-Za-z0-9_-] (others become '_'). */
static void stem_of(const char *path, char *out, size_t cap)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t n = strcspn(base, ".");
    n = n < cap - 1 ? n : cap - 1;
    for (size_t i = 0; i < n; ++i) {
        const char c = base[i];
        out[i] = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' ? c : '_';
    }
    out[n] = '\0';
}
#endif

static int character_simgen(const char *out, const char *avatar, const char *garment, uint32_t preroll,
                            const weft_sim_sequence_def *base)
{
#if SIMGEN_HAVE_CHARACTER
    if (strncmp(avatar, "gltf:", 5) != 0 || strncmp(garment, "obj:", 4) != 0) {
        fprintf(stderr, "simgen: --avatar wants gltf:PATH and --garment obj:PATH\n");
        return 2;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    character_run run = {.blend = preroll / 2 ? preroll / 2 : 1, .preroll = preroll};
    float *gpos = NULL;
    uint32_t *gtri = NULL, gnv = 0, gnt = 0, part_count = 0;
    int rc = 1;
    if (weft_context_create(&cd, &ctx) != WEFT_OK ||
        weft_sample_character_load(ctx, avatar + 5, &run.character) != WEFT_OK) {
        fprintf(stderr, "simgen: --avatar %s: %s\n", avatar + 5, weft_last_error());
    } else if (weft_obj_read(garment + 4, &gpos, &gnv, &gtri, &gnt) != WEFT_OK ||
               weft_sample_character_bind(run.character, gpos, gnv) != WEFT_OK) {
        fprintf(stderr, "simgen: --garment %s: %s\n", garment + 4, weft_last_error());
    } else {
        char a_stem[28], g_stem[28], name[64], dir[1100];
        stem_of(avatar + 5, a_stem, sizeof a_stem);
        stem_of(garment + 4, g_stem, sizeof g_stem);
        snprintf(name, sizeof name, "character_%s_%s", a_stem, g_stem);
        snprintf(dir, sizeof dir, "%s/%s", out, name);
        const weft_sim_character ch = {
            .name = name,
            .rest_positions = weft_sample_character_bind_vertices(run.character),
            .vertex_count = weft_sample_character_vertex_count(run.character),
            .triangles = weft_sample_character_triangles(run.character),
            .triangle_count = weft_sample_character_triangle_count(run.character),
            .triangle_parts = weft_sample_character_parts(run.character, &part_count),
            .garment_positions = gpos,
            .garment_vertex_count = gnv,
            .garment_triangles = gtri,
            .garment_triangle_count = gnt,
            .preroll = run.preroll,
            .collider_at = character_collider_at,
            .user = &run,
        };
        weft_sim_sequence_def def = *base;
        def.scenario = WEFT_SIM_SCENARIO_GARMENT;
        def.character = &ch;
        def.cloth_vertices = gnv < 16 ? 16 : gnv;
        def.garment_retry = false;
        printf("simgen: %s: %u-vertex garment on a %u-vertex character with %u body parts, %.2f s of animation\n",
               name, gnv, ch.vertex_count, part_count, weft_sample_character_duration(run.character));
        fflush(stdout);
        progress_state ps = {.total = 1, .t0 = now_s(), .frac0 = -1.0, .name = name};
        weft_sim_sequence_result res;
        weft_result r = weft_sim_generate(ctx, &def, dir, on_frame, &ps, &res);
        fprintf(stderr, "\n");
        if (r != WEFT_OK) {
            fprintf(stderr, "simgen: %s failed: %s (%s)\n", name, weft_result_string(r), weft_last_error());
        } else {
            printf("simgen: %s %s (%u frames, %u substeps, %u attempts%s)\n", dir,
                   res.accepted ? "accepted" : "REJECTED", res.frames, res.substeps_used, res.attempts,
                   res.accepted ? "" : "; the validator's first hit is in its meta.json");
            rc = res.accepted ? 0 : 3;
        }
    }
    free(gpos);
    free(gtri);
    weft_sample_character_destroy(run.character);
    weft_context_destroy(ctx);
    return rc;
#else
    (void)out;
    (void)avatar;
    (void)garment;
    (void)preroll;
    (void)base;
    fprintf(stderr, "simgen: --avatar needs the samples' character support (weft_render with assimp); this build "
                    "has none\n");
    return 2;
#endif
}

int weft_cmd_simgen(int argc, char **argv)
{
    const char *out = NULL, *scenario = NULL, *tier = NULL, *split = NULL, *only = NULL, *like = NULL;
    const char *mocap = NULL, *mocap_clips = NULL, *bvh = NULL, *mocap_dir = getenv("WEFT_MOCAP_DIR");
    const char *avatar = NULL, *garment = NULL;
    uint32_t preroll = 90;
    weft_bvh_joint_map joint_map;
    bool joint_map_given = false;
    if (!mocap_dir || !mocap_dir[0]) {
        mocap_dir = "samples/mocap";
    }
    bool frames_given = false;
    float arm_spread_retry = weft_sim_default_sequence_def().garment_retry_arm_spread;
    float arm_spread = weft_sim_default_sequence_def().garment_arm_spread;
    float ease_in_retry = weft_sim_default_sequence_def().garment_retry_ease_in;
    float amplitude_retry = weft_sim_default_sequence_def().garment_retry_amplitude;
    bool garment_retry = true;
    bool all = false, manifest_only = false, validate = true, garments = true, resolution_series = false;
    bool redo_rejected = false;
    uint32_t garment_substeps = 0, fast_collider = weft_sim_default_sequence_def().fast_collider_factor;
    float motion_speed = 1.0f;
    uint32_t count = 10, vertices = 1024, frames = 240, substeps = 40, max_substeps = 80, shard_i = 0, shard_n = 1;
    uint32_t limit = UINT32_MAX;
    long checkpoint_frames = -1; /* -1: by size */
    uint32_t prefix_min = weft_sim_default_sequence_def().prefix_frames_min;
    double time_limit = 0.0;
    unsigned long long seed0 = 1;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_ALL:
            all = true;
            break;
        case OPT_MOCAP:
            if (strcmp(v, "train") && strcmp(v, "test") && strcmp(v, "all")) {
                fprintf(stderr, "simgen: --mocap wants train, test or all, got '%s'\n", v);
                return 2;
            }
            mocap = v;
            break;
        case OPT_BVH:
            bvh = v;
            break;
        case OPT_AVATAR:
            avatar = v;
            break;
        case OPT_GARMENT:
            garment = v;
            break;
        case OPT_PREROLL:
            if (!cli_u32("simgen", a, v, 2, 1000, &preroll)) {
                return 2;
            }
            break;
        case OPT_JOINT_MAP:
            if (weft_bvh_read_joint_map(v, &joint_map) != WEFT_OK) {
                fprintf(stderr, "simgen: --joint-map: %s\n", weft_last_error());
                return 2;
            }
            joint_map_given = true;
            break;
        case OPT_CLIPS:
            mocap_clips = v;
            break;
        case OPT_MOCAP_DIR:
            mocap_dir = v;
            break;
        case OPT_NO_GARMENTS:
            garments = false;
            break;
        case OPT_SPEED:
            if (!cli_float("simgen", a, v, 0.1f, 10.0f, &motion_speed)) {
                return 2;
            }
            break;
        case OPT_FAST_COLLIDER:
            if (!cli_u32("simgen", a, v, 1, 16, &fast_collider)) {
                return 2;
            }
            break;
        case OPT_GARMENT_SUBSTEPS:
            if (!cli_u32("simgen", a, v, 0, 4000, &garment_substeps)) {
                return 2;
            }
            break;
        case OPT_ONLY:
            only = v;
            break;
        case OPT_NO_GARMENT_RETRY:
            garment_retry = false;
            break;
        /* range, unit and target of the garment arm spread and the gentle-retry settings */
        case OPT_ARM_SPREAD_RETRY:
            if (!cli_float("simgen", a, v, 0.0f, 0.8f, &arm_spread_retry)) {
                return 2;
            }
            break;
        case OPT_EASE_IN_RETRY:
            if (!cli_float("simgen", a, v, 0.0f, 2.0f, &ease_in_retry)) {
                return 2;
            }
            break;
        case OPT_AMPLITUDE_RETRY:
            if (!cli_float("simgen", a, v, 0.1f, 1.0f, &amplitude_retry)) {
                return 2;
            }
            break;
        case OPT_ARM_SPREAD:
            if (!cli_float("simgen", a, v, 0.0f, 0.8f, &arm_spread)) {
                return 2;
            }
            break;
        case OPT_REDO_REJECTED:
            redo_rejected = true;
            break;
        case OPT_RESOLUTION_SERIES:
            resolution_series = true;
            break;
        case OPT_MANIFEST_ONLY:
            manifest_only = true;
            break;
        case OPT_NO_VALIDATE:
            validate = false;
            break;
        case OPT_OUT:
            out = v;
            break;
        case OPT_TIER:
            tier = NULL;
            for (size_t t = 0; t < sizeof k_tiers / sizeof k_tiers[0]; ++t) {
                tier = strcmp(v, k_tiers[t].tag) == 0 ? k_tiers[t].tag : tier;
            }
            if (!tier) {
                fprintf(stderr, "simgen: --tier wants 1k, 4k or 16k, got '%s'\n", v);
                return 2;
            }
            break;
        case OPT_SPLIT:
            if (strcmp(v, "train") != 0 && strcmp(v, "val") != 0 && strcmp(v, "test") != 0) {
                fprintf(stderr, "simgen: --split wants train, val or test, got '%s'\n", v);
                return 2;
            }
            split = v;
            break;
        case OPT_SCENARIO:
            scenario = v;
            break;
        case OPT_COUNT:
            if (!cli_u32("simgen", a, v, 1, 100000, &count)) {
                return 2;
            }
            break;
        case OPT_VERTICES:
            if (!cli_u32("simgen", a, v, 3, 10000000, &vertices)) {
                return 2;
            }
            break;
        case OPT_FRAMES:
            if (!cli_u32("simgen", a, v, 1, 1000000, &frames)) {
                return 2;
            }
            frames_given = true;
            break;
        case OPT_LIKE:
            like = v;
            break;
        case OPT_SUBSTEPS:
            if (!cli_u32("simgen", a, v, 1, 4000, &substeps)) {
                return 2;
            }
            break;
        case OPT_MAX_SUBSTEPS:
            if (!cli_u32("simgen", a, v, 0, 4000, &max_substeps)) {
                return 2;
            }
            break;
        case OPT_CHECKPOINT_FRAMES: {
            uint32_t every = 0;
            if (!cli_u32("simgen", a, v, 0, 100000, &every)) {
                return 2;
            }
            checkpoint_frames = (long)every;
            break;
        }
        case OPT_PREFIX_MIN:
            if (!cli_u32("simgen", a, v, 0, 100000, &prefix_min)) {
                return 2;
            }
            break;
        case OPT_TIME_LIMIT:
            if (!cli_double("simgen", a, v, 0.0, 1e9, &time_limit)) {
                return 2;
            }
            break;
        case OPT_LIMIT:
            if (!cli_u32("simgen", a, v, 0, 100000000, &limit)) {
                return 2;
            }
            break;
        case OPT_SEED: {
            uint64_t sd = 0;
            if (!cli_u64("simgen", a, v, 0, UINT64_MAX, &sd)) {
                return 2;
            }
            seed0 = sd;
            break;
        }
        case OPT_SHARD:
            if (!parse_shard(v, &shard_i, &shard_n)) {
                fprintf(stderr, "simgen: --shard wants I/N with 0 <= I < N <= 100000, got '%s'\n", v);
                return 2;
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    if ((tier || only) && !all) {
        fprintf(stderr, "simgen: --tier and --only select part of --all; add --all\n");
        return 2;
    }
    int only_scenario = -1;
    for (int s = 0; only && s < WEFT_SIM_SCENARIO_COUNT; ++s) {
        only_scenario = strcmp(only, weft_sim_scenario_name((weft_sim_scenario)s)) == 0 ? s : only_scenario;
    }
    if (only && only_scenario < 0) {
        fprintf(stderr, "simgen: --only wants drop, gripper or garment, got '%s'\n", only);
        return 2;
    }
    if ((avatar != NULL) != (garment != NULL)) {
        fprintf(stderr, "simgen: --avatar and --garment go together (your character and the garment fitted to it)\n");
        return 2;
    }
    if (avatar && (all || scenario || mocap || bvh || like || manifest_only)) {
        fprintf(stderr, "simgen: --avatar makes one sequence; leave out --all, --scenario, --mocap, --bvh and --like\n");
        return 2;
    }
    if (avatar) {
        if (!out) {
            return cli_fail(&k_command, "--out DIR is required");
        }
        weft_sim_sequence_def base = weft_sim_default_sequence_def();
        base.frames = frames;
        base.substeps = substeps;
        base.max_substeps = max_substeps < substeps ? substeps : max_substeps;
        base.fast_collider_factor = fast_collider;
        base.validate = validate;
        return character_simgen(out, avatar, garment, preroll, &base);
    }
    if (joint_map_given && !bvh) {
        fprintf(stderr, "simgen: --joint-map goes with --bvh (the library's clips use CMU names)\n");
        return 2;
    }
    if (like && (all || scenario || mocap || bvh)) {
        fprintf(stderr, "simgen: --like makes one sequence; leave out --all, --scenario, --mocap and --bvh\n");
        return 2;
    }
    if (mocap_clips && !mocap) {
        fprintf(stderr, "simgen: --clips selects clips of --mocap; add --mocap\n");
        return 2;
    }
    if (!out) {
        return cli_fail(&k_command, "--out DIR is required");
    }
    if (!all && !scenario && !manifest_only && !like && !mocap && !bvh) {
        return cli_fail(&k_command, "one of --all, --scenario, --mocap, --bvh, --like, --avatar or --manifest-only is required");
    }
    if (max_substeps < substeps) {
        max_substeps = substeps;
    }
    if (arm_spread + arm_spread_retry > 0.8f) {
        fprintf(stderr, "simgen: --arm-spread plus --arm-spread-retry must stay within 0.8 radians\n");
        return 2;
    }
    if (fast_collider < 1 || fast_collider > 16) {
        fprintf(stderr, "simgen: --fast-collider must be in 1..16\n");
        return 2;
    }
    /* The plan: every sequence name and its parameters, in generation order. */
    const int plan_scenarios = garments ? WEFT_SIM_SCENARIO_COUNT : WEFT_SIM_SCENARIO_GARMENT;
    uint32_t cap = 0;
    if (all || manifest_only) {
        for (size_t t = 0; t < sizeof k_tiers / sizeof k_tiers[0]; ++t) {
            cap += (uint32_t)plan_scenarios * k_tiers[t].per_scenario;
        }
    }
    if (scenario) {
        cap += count;
    }
    cap += like ? 1 : 0;
    plan_item *plan = calloc(cap ? cap : 1, sizeof *plan);
    if (!plan) {
        fprintf(stderr, "simgen: out of memory\n");
        return 1;
    }
    uint32_t n = 0;
    if (all || manifest_only) {
        for (size_t t = 0; t < sizeof k_tiers / sizeof k_tiers[0]; ++t) {
            for (uint32_t k = 0; k < k_tiers[t].per_scenario; ++k) {
                for (int s = 0; s < plan_scenarios; ++s) {
                    plan_item *p = &plan[n++];
                    p->scenario = (weft_sim_scenario)s;
                    p->vertices = k_tiers[t].vertices;
                    p->index = k;
                    p->tier = k_tiers[t].tag;
                    snprintf(p->name, sizeof p->name, "%s_%s_%04u", weft_sim_scenario_name(p->scenario), k_tiers[t].tag, k);
                }
            }
        }
    }
    if (scenario) {
        weft_sim_scenario sc = WEFT_SIM_SCENARIO_COUNT;
        for (int s = 0; s < WEFT_SIM_SCENARIO_COUNT; ++s) {
            if (strcmp(scenario, weft_sim_scenario_name((weft_sim_scenario)s)) == 0) {
                sc = (weft_sim_scenario)s;
            }
        }
        if (sc == WEFT_SIM_SCENARIO_COUNT) {
            fprintf(stderr, "simgen: unknown scenario '%s' (drop, gripper, garment)\n", scenario);
            free(plan);
            return 2;
        }
        for (uint32_t k = 0; k < count; ++k) {
            plan_item *p = &plan[n++];
            p->scenario = sc;
            p->vertices = vertices;
            p->index = k;
            snprintf(p->name, sizeof p->name, "%s_v%u_%04u", scenario, vertices, k);
        }
    }
    if ((mocap && mocap_plan(mocap_dir, mocap, mocap_clips, frames, vertices, &plan, &n, &cap) < 0) ||
        (bvh && bvh_plan(bvh, joint_map_given ? joint_map.entries : NULL, frames, vertices, &plan, &n, &cap) < 0)) {
        free(plan);
        return 1;
    }
    if (like) {
        /* One twin: the other sequence's scenario and seed at this run's vertex count. */
        char path[1200];
        snprintf(path, sizeof path, "%s/meta.json", like);
        cJSON *meta = read_meta(path);
        const cJSON *sc = cJSON_GetObjectItemCaseSensitive(meta, "scenario");
        const cJSON *sd = cJSON_GetObjectItemCaseSensitive(meta, "seed_u64");
        const cJSON *fr = cJSON_GetObjectItemCaseSensitive(meta, "frames");
        const cJSON *sp = cJSON_GetObjectItemCaseSensitive(meta, "motion_speed");
        plan_item *p = &plan[n];
        p->scenario = WEFT_SIM_SCENARIO_COUNT;
        for (int k = 0; cJSON_IsString(sc) && k < WEFT_SIM_SCENARIO_COUNT; ++k) {
            p->scenario = strcmp(sc->valuestring, weft_sim_scenario_name((weft_sim_scenario)k)) == 0
                              ? (weft_sim_scenario)k
                              : p->scenario;
        }
        char *end = NULL;
        p->seed = cJSON_IsString(sd) ? strtoull(sd->valuestring, &end, 10) : 0;
        if (p->scenario == WEFT_SIM_SCENARIO_COUNT || !end || *end || p->seed == 0 || !cJSON_IsNumber(fr)) {
            fprintf(stderr, "simgen: --like %s: no meta.json with scenario, seed_u64 and frames there\n", like);
            cJSON_Delete(meta);
            free(plan);
            return 1;
        }
        frames = frames_given ? frames : (uint32_t)fr->valuedouble;
        motion_speed = cJSON_IsNumber(sp) ? (float)sp->valuedouble : motion_speed;
        size_t len = strlen(like);
        while (len > 1 && like[len - 1] == '/') {
            --len;
        }
        size_t base = len;
        while (base > 0 && like[base - 1] != '/') {
            --base;
        }
        p->vertices = vertices;
        snprintf(p->name, sizeof p->name, "%.*s_v%u", (int)(len - base < 40 ? len - base : 40), like + base, vertices);
        ++n;
        cJSON_Delete(meta);
    }
    bench_mkdirs(out); /* parents too: --out data/sets/a works on a fresh checkout */
    if (!file_exists(out)) {
        fprintf(stderr, "simgen: cannot create '%s'\n", out);
        free(plan);
        return 1;
    }
    int rc = 0;
    bool write_it = true;
    if (!manifest_only) {
        weft_context_def cd = weft_default_context_def();
        weft_context *ctx = NULL;
        if (weft_context_create(&cd, &ctx) != WEFT_OK) {
            fprintf(stderr, "simgen: %s\n", weft_last_error());
            free(plan);
            return 1;
        }
        const plan_filter filter = {shard_i, shard_n, tier, split, only_scenario};
        uint32_t todo = 0;
        for (uint32_t i = 0; i < n; ++i) {
            char path[1200];
            snprintf(path, sizeof path, "%s/%s/meta.json", out, plan[i].name);
            todo += plan_wanted(&filter, plan, i) && needs_run(path, redo_rejected);
        }
        if (todo > limit) {
            todo = limit;
        }
        progress_state ps = {.total = todo, .t0 = now_s(), .frac0 = -1.0};
        uint32_t accepted = 0, rejected = 0, truncated = 0;
        bool stopped = false;
        for (uint32_t i = 0; i < n && ps.done < todo && !stopped; ++i) {
            char dir[1100], path[1200];
            snprintf(dir, sizeof dir, "%s/%s", out, plan[i].name);
            snprintf(path, sizeof path, "%s/meta.json", dir);
            if (!plan_wanted(&filter, plan, i) || !needs_run(path, redo_rejected)) {
                continue;
            }
            weft_sim_sequence_def def = weft_sim_default_sequence_def();
            def.scenario = plan[i].scenario;
            /* The plan's names carry the vertex count; a resolution series hashes the name without it. */
            char scene[96];
            snprintf(scene, sizeof scene, "%s_%04u", weft_sim_scenario_name(plan[i].scenario), plan[i].index);
            def.seed = plan[i].seed ? plan[i].seed : seq_seed(seed0, resolution_series ? scene : plan[i].name);
            def.frames = plan[i].frames ? plan[i].frames : frames;
            def.motion_path = plan[i].motion[0] ? plan[i].motion : NULL;
            def.motion_joint_map = bvh && joint_map_given ? joint_map.entries : NULL;
            def.motion_start_s = plan[i].start_s;
            def.split = plan[i].split;
            def.substeps = substeps;
            def.max_substeps = max_substeps;
            def.fast_collider_factor = fast_collider;
            if (def.scenario == WEFT_SIM_SCENARIO_GARMENT && garment_substeps > def.substeps) {
                def.substeps = garment_substeps;
                def.max_substeps = def.max_substeps > def.substeps ? def.max_substeps : def.substeps;
            }
            def.cloth_vertices = plan[i].vertices;
            def.validate = validate;
            def.motion_speed = motion_speed;
            def.garment_arm_spread = arm_spread;
            def.garment_retry_arm_spread = arm_spread_retry;
            def.garment_retry_ease_in = ease_in_retry;
            def.garment_retry_amplitude = amplitude_retry;
            def.garment_retry = garment_retry;
            def.checkpoint_frames = checkpoint_frames >= 0 ? (uint32_t)checkpoint_frames
                                                           : plan[i].vertices >= 16384 ? 10u : 0u;
            const double left = time_limit > 0.0 ? time_limit - (now_s() - ps.t0) : 0.0;
            if (time_limit > 0.0 && left <= 0.0) {
                stopped = true;
                fprintf(stderr, "\nsimgen: --time-limit reached before %s; rerun to continue\n", plan[i].name);
                break;
            }
            def.time_limit_s = def.checkpoint_frames ? left : 0.0;
            def.prefix_frames_min = prefix_min;
            ps.name = plan[i].name;
            weft_sim_sequence_result res;
            weft_result r = weft_sim_generate(ctx, &def, dir, on_frame, &ps, &res);
            if (r == WEFT_OK && !res.finished) {
                stopped = true;
                fprintf(stderr, "\nsimgen: --time-limit reached; %s stopped at a checkpoint (%s/checkpoint.bin); "
                                "rerun to continue\n", plan[i].name, dir);
                break;
            }
            if (r == WEFT_OK && res.resumed_frame > 0) {
                fprintf(stderr, "\nsimgen: %s continued from its checkpoint at frame %u\n", plan[i].name,
                        res.resumed_frame);
            }
            ps.done++;
            if (r != WEFT_OK) {
                fprintf(stderr, "\nsimgen: %s failed: %s (%s)\n", plan[i].name, weft_result_string(r), weft_last_error());
                rc = 1;
                continue;
            }
            accepted += res.accepted;
            rejected += !res.accepted;
            truncated += res.truncated;
            if (!res.accepted || res.truncated) {
                char why[256];
                rejection_reason(&res, why, sizeof why);
                if (res.truncated) {
                    fprintf(stderr, "\nsimgen: %s accepted as its first %u of %u frames: %s\n", plan[i].name, res.frames,
                            def.frames, why);
                } else {
                    fprintf(stderr, "\nsimgen: %s rejected: %s\n", plan[i].name, why);
                }
            }
        }
        draw_bar(&ps, 0, 0);
        fprintf(stderr, "\nsimgen: %u accepted (%u of them their first frames only), %u rejected, %u failed, %.0f s\n",
                accepted, truncated, rejected, ps.done - accepted - rejected, now_s() - ps.t0);
        if (ps.done > 0 && accepted == 0) {
            /* A manifest of nothing new would let a training run start on an empty or stale set. */
            fprintf(stderr, "simgen: no sequence of this run was accepted; %s/manifest.json not written\n", out);
            write_it = false;
            rc = 1;
        }
        weft_context_destroy(ctx);
    }
    if (write_it && write_manifest(out, plan, n) != 0) {
        rc = 1;
    }
    free(plan);
    return rc;
}
