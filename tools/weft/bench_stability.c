/* weft bench stability: where each method fails, against reference-simulator ground truth.
 *
 * Stress cases are generated with `weft simgen` (resumable: finished sequences are kept under
 * --data) and every (method, case, sequence) is scored by `weft eval --json` child processes:
 *   resolution  x1 x2 x4 x10 of the base cloth vertex count
 *   long        one rollout of --long-frames frames (2400 by default, 10x the 240-frame horizon)
 *   unseen      the training scenario with a seed outside the training set (new objects/motions),
 *               and the garment scenario when simgen can build it
 *   speed       x1.5 x2 x3 of the scenario's kinematic motion (`weft simgen --speed`; x1 is
 *               res_x1), and x1 x1.5 x2 x3 on the FNOpt grid scenes (`weft fnopt run --gt --speed`)
 * Per cell: NaN, explosion (more than 1% of the edges strained over 25% in some frame: one edge
 * over 25% is common at pins and tight contacts, in the reference too), a rollout too slow to
 * finish under --time-limit, penetrations after CCD (collision_rate), and MVE growth: the last quarter's MVE over the first quarter's. eval reports only a whole-rollout
 * mean, but rollouts are deterministic and a shorter rollout is a prefix of a longer one, so the
 * quarter means follow exactly from runs cut at 1/4, 3/4 and the full length.
 *
 * Resumable: every eval's result is kept next to its sequence (<seq>/scores/<hash>.json, keyed by
 * the eval's arguments and, for a model, the model file's contents) and reused by a later run
 * unless --rescore; the tables are rewritten after every case, so a run stopped part-way leaves
 * what it scored, and the next run goes on from there. */
#define _POSIX_C_SOURCE 200809L /* opendir, stat */
#include "weft.h"
#include "support_bench.h"
#include "support_cli.h"

#include <cjson/cJSON.h>

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

const char weft_bench_stability_help[] = "stability suite: NaN, explosions, penetrations, MVE growth per method and stress case";

#define ST_MAX_METHODS 64
#define ST_MAX_CASES 16
#define ST_STRAIN_LIMIT 0.25   /* an edge stretched by more than 25% (eval's overstretched_pct) ... */
#define ST_OVERSTRETCH_PCT 1.0 /* ... on more than 1% of the edges in some frame: explosion */
#define ST_COLL_WARN 1.0       /* % of vertices penetrating after CCD that counts as a failure sign */
#define ST_GROWTH_WARN 2.0     /* last-quarter MVE more than twice the first quarter's ... */
#define ST_GROWTH_FLOOR_CM 0.5 /* ... and at least this large: ratios of near-zero errors are noise */
#define ST_RATIO_FLOOR_CM 0.1  /* growth ratios are printed only above this first-quarter MVE */

typedef struct st_method {
    char label[96], family[16], method[16], precision[8], model[1024];
    char tether_cm[16]; /* "" or `weft eval --tether-cm` */
    char strain_pct[16]; /* "" or `weft eval --strain-limit` */
    char model_content[40]; /* model methods: the file's fingerprint, part of a kept score's key */
} st_method;

typedef struct st_case {
    char name[32], axis[16], level[32];
    char scenario[16];
    uint32_t vertices, frames, count;
    unsigned long long seed;
    double speed;          /* FNOpt cases; simgen cases: --speed (motion speed scale) when > 0 */
    bool fnopt;
    bool available;
    char note[240];
} st_case;

typedef struct st_cell {
    uint32_t sequences, frames, nan_runs, exploded_runs, failed_runs, slow_runs;
    double mve_w, coll_w, self_w, ms_w, max_strain, e3d_w;
    double overstretched_pct, gt_strain; /* max over runs; gt_strain: the reference's own max strain */
    double q1_sum, q1_frames, q4_sum, q4_frames; /* error sums (cm x frames) of the first / last quarter */
    bool growth_ok;
    char note[240];
} st_cell;

typedef struct st_opts {
    const char *data, *out, *models, *scenario, *fnopt_model;
    const char *csv_dir; /* where stability.csv goes (bench_csv_dir) */
    const char *axes; /* NULL: every axis; else a comma list of resolution, long, unseen, speed */
    uint32_t base_vertices, frames, long_frames, count;
    uint32_t time_limit; /* s of stepping per rollout before it counts as too slow */
    unsigned xpbd[8];
    size_t nxpbd;
    unsigned xpbd_fast[8]; /* WEFT_METHOD_XPBD_FAST substep counts */
    size_t nxpbd_fast;
    bool quick, plot, fnopt, garment, rescore;
    bool no_ccd; /* --ccd off: every method without the CCD post-process (the default runs it) */
} st_opts;

/* The --axes keywords, each the first word of a case's axis name. */
static const char *const k_axes[] = {"resolution", "long", "unseen", "speed"};

static bool axes_valid(const char *list)
{
    for (const char *p = list; *p;) {
        size_t n = strcspn(p, ",");
        bool known = false;
        for (size_t k = 0; k < sizeof k_axes / sizeof k_axes[0]; ++k) {
            known |= n == strlen(k_axes[k]) && strncmp(p, k_axes[k], n) == 0;
        }
        if (!known) {
            return false;
        }
        p += n + (p[n] == ',');
    }
    return list[0] != '\0';
}

static bool axis_wanted(const char *list, const char *axis)
{
    const size_t w = strcspn(axis, " ");
    for (const char *p = list; list && *p;) {
        size_t n = strcspn(p, ",");
        if (n == w && strncmp(p, axis, n) == 0) {
            return true;
        }
        p += n + (p[n] == ',');
    }
    return !list;
}

/* When simgen's validator rejected the case, say why from the rejected sequence's meta.json. */
static void rejection_note(const char *dir, st_case *c)
{
    DIR *dh = opendir(dir);
    struct dirent *de;
    while (dh && (de = readdir(dh)) != NULL) {
        char path[1400];
        if (de->d_name[0] == '.' || snprintf(path, sizeof path, "%s/%s/meta.json", dir, de->d_name) >= (int)sizeof path) {
            continue;
        }
        char *text = bench_slurp(path, NULL);
        cJSON *j = text ? cJSON_Parse(text) : NULL;
        free(text);
        const cJSON *v = j ? cJSON_GetObjectItemCaseSensitive(j, "validator") : NULL;
        const cJSON *ih = cJSON_GetObjectItemCaseSensitive(v, "intersection_hits");
        const cJSON *ch = cJSON_GetObjectItemCaseSensitive(v, "ccd_hits");
        const cJSON *ff = cJSON_GetObjectItemCaseSensitive(v, "first_hit_frame");
        const cJSON *ss = j ? cJSON_GetObjectItemCaseSensitive(j, "substeps") : NULL;
        if (j && cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(j, "accepted")) && cJSON_IsNumber(ih) &&
            cJSON_IsNumber(ch) && cJSON_IsNumber(ff) && cJSON_IsNumber(ss)) {
            snprintf(c->note, sizeof c->note,
                     "the reference simulation was rejected by its validator (%d intersection and %d CCD hits, "
                     "first at frame %d, even at %d substeps), so there is no ground truth",
                     ih->valueint, ch->valueint, ff->valueint, ss->valueint);
            cJSON_Delete(j);
            break;
        }
        cJSON_Delete(j);
    }
    if (dh) {
        closedir(dh);
    }
}

/* Runs simgen for one case; resumes when the sequences already exist. */
static bool generate_case(const char *exe, const st_opts *o, st_case *c, char *dir, size_t dir_cap)
{
    snprintf(dir, dir_cap, "%s/%s", o->data, c->name);
    char vert[16], frames[16], count[16], seed[32], speed[16];
    snprintf(speed, sizeof speed, "%g", c->speed);
    snprintf(vert, sizeof vert, "%u", c->vertices);
    snprintf(frames, sizeof frames, "%u", c->frames);
    snprintf(count, sizeof count, "%u", c->count);
    snprintf(seed, sizeof seed, "%llu", c->seed);
    /* --resolution-series: res_x2 is res_x1's scene (objects, body, motion, garment type) at twice the
     * vertices, and the speed cases replay it faster, so an axis changes only what it names. */
    const char *argv[] = {exe,    "simgen", "--out",   dir,    "--scenario", c->scenario, "--count",
                          count,  "--vertices", vert,  "--frames", frames, "--seed", seed, "--resolution-series",
                          c->speed > 0.0 ? "--speed" : NULL, speed, NULL};
    char *out = NULL, why[240];
    printf("generating %-14s %s, %u vertices, %u frames, %u sequence(s)\n", c->name, c->scenario, c->vertices,
           c->frames, c->count);
    fflush(stdout);
    int rc = bench_spawn(argv, &out, why, sizeof why);
    free(out);
    bench_seq *seqs = NULL;
    size_t n = 0;
    bool listed = bench_list_sequences(dir, NULL, &seqs, &n);
    free(seqs);
    if (!listed || n == 0) {
        bench_sanitize(why);
        snprintf(c->note, sizeof c->note, "simgen produced no accepted sequence (exit %d: %.150s)", rc, why);
        rejection_note(dir, c);
        return false;
    }
    return true;
}

#define FNV_START 1469598103934665603ull

static unsigned long long fnv1a(unsigned long long h, const unsigned char *p, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        h = (h ^ p[i]) * 1099511628211ull;
    }
    return h;
}

/* FNV-1a of the eval's arguments: the name of its kept score. */
static unsigned long long score_hash(const char *const *args)
{
    static const unsigned char separator = 0x1f;
    unsigned long long h = FNV_START;
    for (int i = 0; args[i]; ++i) {
        h = fnv1a(fnv1a(h, (const unsigned char *)args[i], strlen(args[i])), &separator, 1);
    }
    return h;
}

/* "<bytes>-<FNV-1a of the contents>" of a file: what a kept model score is tied to. */
static bool file_fingerprint(const char *path, char *out, size_t cap)
{
    size_t size = 0;
    char *data = bench_slurp(path, &size);
    if (!data) {
        return false;
    }
    unsigned long long h = fnv1a(FNV_START, (const unsigned char *)data, size);
    free(data);
    int n = snprintf(out, cap, "%zu-%016llx", size, h);
    return n > 0 && (size_t)n < cap;
}

static bool score_path(const char *seq, const char *const *args, char *out, size_t cap)
{
    int n = snprintf(out, cap, "%s/scores/%016llx.json", seq, score_hash(args));
    return n > 0 && (size_t)n < cap;
}

/* A score kept by an earlier run with the same arguments (and the same key text, against hash
 * collisions). */
static bool score_load(const char *seq, const char *const *args, const char *key, bench_eval_result *e)
{
    char path[1400];
    if (!score_path(seq, args, path, sizeof path)) {
        return false;
    }
    char *text = bench_slurp(path, NULL);
    cJSON *j = text ? cJSON_Parse(text) : NULL;
    free(text);
    const cJSON *k = j ? cJSON_GetObjectItemCaseSensitive(j, "key") : NULL;
    bool ok = cJSON_IsString(k) && strcmp(k->valuestring, key) == 0;
    const char *names[] = {"mve_cm", "collision_rate", "self_collision_rate", "ms_per_frame", "max_edge_strain",
                           "overstretched_pct", "gt_max_edge_strain", "frames"};
    double v[8];
    for (int i = 0; ok && i < 8; ++i) {
        const cJSON *x = cJSON_GetObjectItemCaseSensitive(j, names[i]);
        ok = cJSON_IsNumber(x);
        v[i] = ok ? x->valuedouble : 0.0;
    }
    if (ok) {
        memset(e, 0, sizeof *e);
        e->ok = true;
        e->mve_cm = v[0], e->collision_rate = v[1], e->self_collision_rate = v[2], e->ms_per_frame = v[3];
        e->max_edge_strain = v[4], e->overstretched_pct = v[5], e->gt_max_edge_strain = v[6];
        e->frames = v[7] >= 0 && v[7] < 4e9 ? (uint32_t)v[7] : 0;
        e->nan = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "nan"));
        e->time_limited = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(j, "time_limited"));
    }
    cJSON_Delete(j);
    return ok;
}

static void score_save(const char *seq, const char *const *args, const char *key, const bench_eval_result *e)
{
    char dir[1200], path[1400];
    snprintf(dir, sizeof dir, "%s/scores", seq);
    if (!bench_mkdirs(dir) || !score_path(seq, args, path, sizeof path)) {
        return;
    }
    FILE *f = fopen(path, "w");
    if (!f) {
        return;
    }
    cJSON *ks = cJSON_CreateString(key);
    char *kt = ks ? cJSON_PrintUnformatted(ks) : NULL; /* the key, escaped */
    fprintf(f,
            "{\"key\": %s, \"mve_cm\": %.9g, \"collision_rate\": %.9g, \"self_collision_rate\": %.9g, "
            "\"ms_per_frame\": %.9g, \"max_edge_strain\": %.9g, \"overstretched_pct\": %.9g, "
            "\"gt_max_edge_strain\": %.9g, \"frames\": %u, \"nan\": %s, \"time_limited\": %s}\n",
            kt ? kt : "\"\"", e->mve_cm, e->collision_rate, e->self_collision_rate, e->ms_per_frame,
            e->max_edge_strain, e->overstretched_pct, e->gt_max_edge_strain, e->frames, e->nan ? "true" : "false",
            e->time_limited ? "true" : "false");
    free(kt);
    cJSON_Delete(ks);
    fclose(f);
}

/* One eval with the method's arguments, cut at `frames` predicted frames (0: all); a score kept
 * from an earlier run with the same arguments is reused unless --rescore. */
static bool eval_method(const char *exe, const st_opts *o, const st_method *m, const char *seq, uint32_t frames,
                        bench_eval_result *e)
{
    const uint32_t time_limit = o->time_limit;
    char fr[16], tl[16];
    snprintf(fr, sizeof fr, "%u", frames);
    snprintf(tl, sizeof tl, "%u", time_limit);
    const bool is_model = strcmp(m->family, "model") == 0;
    const bench_method_spec spec = {m->method,
                                    !o->no_ccd,
                                    frames ? fr : NULL,
                                    is_model ? m->model : NULL,
                                    is_model ? m->precision : NULL,
                                    m->tether_cm,
                                    m->strain_pct,
                                    NULL,
                                    NULL};
    const char *extra[24];
    extra[0] = "--time-limit";
    extra[1] = tl;
    const int n = bench_method_args(&spec, extra, 2);
    /* The kept score's key: the arguments, plus the model file's contents for a model method, so
     * a retrained model at the same path is scored again rather than matched to an old score. */
    const char *keyargs[22];
    int nk = 0;
    for (int i = 0; i < n; ++i) {
        keyargs[nk++] = extra[i];
    }
    if (is_model) {
        keyargs[nk++] = "model-content";
        keyargs[nk++] = m->model_content;
    }
    keyargs[nk] = NULL;
    char key[2048] = "";
    for (int i = 0; i < nk; ++i) {
        size_t kl = strlen(key);
        snprintf(key + kl, sizeof key - kl, "%s%s", i ? " " : "", keyargs[i]);
    }
    if (!o->rescore && score_load(seq, keyargs, key, e)) {
        return true;
    }
    if (!bench_eval(exe, seq, extra, e)) {
        return false; /* failures are not kept: the next run tries again */
    }
    score_save(seq, keyargs, key, e);
    return true;
}

static void score_sequence(const char *exe, const st_opts *o, const st_method *m, const bench_seq *s, st_cell *cell)
{
    bench_eval_result full;
    cell->sequences++;
    if (!eval_method(exe, o, m, s->dir, 0, &full)) {
        cell->failed_runs++;
        if (!cell->note[0]) {
            snprintf(cell->note, sizeof cell->note, "%s", full.why);
        }
        return;
    }
    uint32_t F = full.frames;
    cell->frames += F;
    cell->mve_w += full.mve_cm * F;
    cell->coll_w += full.collision_rate * F;
    cell->self_w += full.self_collision_rate * F;
    cell->ms_w += full.ms_per_frame * F;
    cell->max_strain = fmax(cell->max_strain, full.max_edge_strain);
    cell->overstretched_pct = fmax(cell->overstretched_pct, full.overstretched_pct);
    cell->gt_strain = fmax(cell->gt_strain, full.gt_max_edge_strain);
    cell->nan_runs += full.nan;
    cell->exploded_runs += full.overstretched_pct > ST_OVERSTRETCH_PCT;
    if (full.time_limited) {
        cell->slow_runs++;
        if (!cell->note[0]) {
            snprintf(cell->note, sizeof cell->note,
                     "stopped after %u of %u frames: %u s of stepping (%.0f ms/frame); the prefix is scored", F,
                     s->frames > 2 ? s->frames - 2 : 0, o->time_limit, full.ms_per_frame);
        }
    }
    if (full.nan || full.time_limited || F < 8) {
        return; /* growth is undefined for a rollout that stopped or is too short */
    }
    bench_eval_result q1, q3;
    uint32_t f1 = F / 4, f3 = F - F / 4;
    if (eval_method(exe, o, m, s->dir, f1, &q1) && eval_method(exe, o, m, s->dir, f3, &q3) &&
        !q1.nan && !q3.nan &&
        q1.frames == f1 && q3.frames == f3) {
        cell->q1_sum += q1.mve_cm * f1;
        cell->q1_frames += f1;
        cell->q4_sum += full.mve_cm * F - q3.mve_cm * f3;
        cell->q4_frames += F - f3;
        cell->growth_ok = true;
    }
}

static void score_fnopt(const char *exe, const st_opts *o, const st_method *m, const st_case *c, st_cell *cell)
{
    static const char *const motions[] = {"xy", "xyz", "rot_h0"};
    size_t nmot = o->quick ? 1 : 3;
    char speed[16], frames[16];
    snprintf(speed, sizeof speed, "%g", c->speed);
    /* Always the whole trajectory: the handles start moving only after a rest phase, so a cut
     * rollout would not see the speed change at all. */
    snprintf(frames, sizeof frames, "%u", 0u);
    for (size_t k = 0; k < nmot; ++k) {
        const char *argv[20];
        int n = 0;
        argv[n++] = exe;
        argv[n++] = "fnopt";
        argv[n++] = "run";
        argv[n++] = "--gt";
        argv[n++] = "--material";
        argv[n++] = BENCH_FNOPT_MATERIAL;
        argv[n++] = "--speed";
        argv[n++] = speed;
        argv[n++] = "--motion";
        argv[n++] = motions[k];
        argv[n++] = "--optimizer";
        argv[n++] = m->method;
        argv[n++] = "--frames";
        argv[n++] = frames;
        if (strcmp(m->method, "learned") == 0) {
            argv[n++] = "--model";
            argv[n++] = m->model;
        }
        argv[n] = NULL;
        char *out = NULL, why[240];
        int rc = bench_spawn(argv, &out, why, sizeof why);
        const char *row = out ? strchr(out, '\n') : NULL;
        unsigned res, iters, fr = 0;
        int diverged = 0;
        double sp, lr, Y, S, B, ms = NAN, e3d = NAN, ch, loss;
        char mo[64], ha[64], opt[32];
        bool ok = rc == 0 && row &&
                  sscanf(row + 1, "%u,%63[^,],%63[^,],%lf,%31[^,],%u,%lf,%lf,%lf,%lf,%u,%d,%lf,%lf,%lf,%lf", &res, mo,
                         ha, &sp, opt, &iters, &lr, &Y, &S, &B, &fr, &diverged, &ms, &e3d, &ch, &loss) == 16;
        free(out);
        cell->sequences++;
        if (!ok) {
            cell->failed_runs++;
            bench_sanitize(why);
            if (!cell->note[0]) {
                snprintf(cell->note, sizeof cell->note, "%s", why[0] ? why : "fnopt printed no result row");
            }
            continue;
        }
        cell->nan_runs += diverged || !isfinite(e3d);
        cell->frames += fr;
        cell->e3d_w += isfinite(e3d) ? e3d * fr : 0.0;
        cell->ms_w += ms * fr;
        printf("  fnopt %-6s speed %-4s %-14s e3D %.4f  %.2f ms/frame%s\n", motions[k], speed, m->label, e3d, ms,
               diverged ? "  DIVERGED" : "");
        fflush(stdout);
    }
}

/* pass, warn (penetrations or drift), fail (NaN / explosion / could not run), n/a */
static const char *cell_status(const st_cell *c)
{
    if (c->sequences == 0) {
        return "n/a";
    }
    if (c->failed_runs == c->sequences) {
        return strstr(c->note, "nsupported") ? "n/a" : "error";
    }
    if (c->nan_runs) {
        return "NaN";
    }
    if (c->exploded_runs) {
        return "exploded";
    }
    if (c->slow_runs) {
        return "too slow";
    }
    if (c->frames && c->coll_w / c->frames > ST_COLL_WARN) {
        return "penetrates";
    }
    if (c->growth_ok && c->q1_sum > 0 && (c->q4_sum / c->q4_frames) / (c->q1_sum / c->q1_frames) > ST_GROWTH_WARN &&
        c->q4_sum / c->q4_frames >= ST_GROWTH_FLOOR_CM) {
        return "drifts";
    }
    return "pass";
}

static void num_or_empty(FILE *f, bool have, double v)
{
    if (have && isfinite(v)) {
        fprintf(f, ",%.6g", v);
    } else {
        fprintf(f, ",");
    }
}

/* Everything a run's tables need; rewritten after every case so a stopped run leaves its scores. */
typedef struct st_run {
    const st_opts *o;
    const char *command, *exe;
    const st_method *methods;
    size_t nm, nmodels;
    const st_case *cases;
    size_t nc, done; /* cases [done, nc) are not scored yet */
    st_cell (*cells)[ST_MAX_METHODS];
    double wall;
    bool fnopt_weights, garment_scenario;
} st_run;

static int write_tables(const st_run *run)
{
    const st_opts *opts = run->o;
    const st_opts o = *opts;
    const char *command = run->command, *exe = run->exe;
    const st_method *methods = run->methods;
    const st_case *cases = run->cases;
    const size_t nm = run->nm, nc = run->nc, nmodels = run->nmodels;
    st_cell(*cells)[ST_MAX_METHODS] = run->cells;
    const double wall = run->wall;
    const bool fnopt_weights = run->fnopt_weights, garment_scenario = run->garment_scenario;
    /* CSV */
    char path[1200], csv[1200], link[1200];
    snprintf(csv, sizeof csv, "%s/stability.csv", o.csv_dir);
    FILE *f = fopen(csv, "w");
    if (!f) {
        fprintf(stderr, "weft bench stability: cannot write %s\n", csv);
        return 1;
    }
    fprintf(f, "case,axis,level,method,family,precision,sequences,frames,mve_cm,e3d,mve_first_quarter,"
               "mve_last_quarter,mve_growth,collision_rate,self_collision_rate,max_edge_strain,overstretched_pct,"
               "gt_max_edge_strain,ms_per_frame,nan_runs,exploded_runs,slow_runs,failed_runs,status,note\n");
    for (size_t ci = 0; ci < nc; ++ci) {
        for (size_t k = 0; k < nm; ++k) {
            const st_case *cs = &cases[ci];
            bool fn = strcmp(methods[k].family, "fnopt") == 0;
            if (fn != cs->fnopt) {
                continue;
            }
            const st_cell *cell = &cells[ci][k];
            double w = cell->frames ? (double)cell->frames : NAN;
            bool have = cell->frames > 0;
            const bool pending = ci >= run->done;
            double q1 = cell->q1_frames ? cell->q1_sum / cell->q1_frames : NAN;
            double q4 = cell->q4_frames ? cell->q4_sum / cell->q4_frames : NAN;
            fprintf(f, "%s,%s,%s,%s,%s,%s,%u,%u", cs->name, cs->axis, cs->level, methods[k].label, methods[k].family,
                    methods[k].precision, cell->sequences, cell->frames);
            num_or_empty(f, have && !fn, cell->mve_w / w);
            num_or_empty(f, have && fn, cell->e3d_w / w);
            num_or_empty(f, cell->growth_ok, q1);
            num_or_empty(f, cell->growth_ok, q4);
            num_or_empty(f, cell->growth_ok && q1 > 0, q4 / q1);
            num_or_empty(f, have && !fn, cell->coll_w / w);
            num_or_empty(f, have && !fn, cell->self_w / w);
            num_or_empty(f, have && !fn, cell->max_strain);
            num_or_empty(f, have && !fn, cell->overstretched_pct);
            num_or_empty(f, have && !fn, cell->gt_strain);
            num_or_empty(f, have, cell->ms_w / w);
            char note[240];
            snprintf(note, sizeof note, "%s", cs->available ? cell->note : cs->note);
            bench_sanitize(note);
            fprintf(f, ",%u,%u,%u,%u,%s,%s\n", cell->nan_runs, cell->exploded_runs, cell->slow_runs, cell->failed_runs,
                    pending ? "not scored yet" : cs->available ? cell_status(cell) : "not generated", note);
        }
    }
    fclose(f);

    /* Markdown */
    /* The generated text goes between "<!-- stability:table -->" markers, so prose written
     * around it in STABILITY.md survives a rerun. */
    snprintf(path, sizeof path, "%s/STABILITY.md", o.out);
    char *gen = NULL;
    size_t gen_len = 0;
    f = open_memstream(&gen, &gen_len);
    if (!f) {
        fprintf(stderr, "weft bench stability: out of memory writing %s\n", path);
        return 1;
    }
    time_t now = time(NULL);
    char date[64];
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    fprintf(f, "![pass/fail per method and stress case](img/stability.png)\n\n");
    fprintf(f, "Generated by `weft bench stability` on %s; this run took %.0f s (cases already generated under `%s` "
               "and scores kept there by earlier runs of the same command are reused; `--rescore` evaluates "
               "again):\n\n```\n%s\n```\n\n",
            date, wall, o.data, command);
    fprintf(f, "Machine and build: `%s`\n\n", weft_config_string());
    fprintf(f, "Ground truth: `weft simgen` (validated XPBD reference, scenario `%s`), base %u cloth vertices, %u "
               "frames, %u sequence(s) per case. Every method runs with CCD post-processing %s, from the first two "
               "ground-truth frames, and then sees only the collider and the scene's pins (a gripper's grasped "
               "vertices, a skirt's waistband; `weft eval --pins all`), as a game would set them.\n\n",
            o.scenario, o.base_vertices, o.frames, o.count, o.no_ccd ? "off (`--ccd off`)" : "on");
    fprintf(f, "Status: **NaN** (non-finite state), **exploded** (more than %.0f%% of the edges strained by more than "
               "%.0f%% in some frame; a single edge over %.0f%% is common at pins and tight contacts, in the reference "
               "too, so the max strain is shown next to the reference's own), **too slow** (the rollout's steps took more "
               "than %u s, so it was stopped and only its prefix is scored), **error** (the run "
               "failed, see note), **penetrates** (more than %.0f%% of cloth vertices in collision per frame, after "
               "CCD when it is on), **drifts** (last-quarter MVE > %.0fx first-quarter MVE and >= %.1f cm), else **pass**. MVE growth compares "
               "the MVE of the last quarter of the rollout with the first quarter's (exact: rollouts are "
               "deterministic prefixes, scored at 1/4, 3/4 and full length); the ratio is shown only when the "
               "first quarter is at least %.1f cm, since rollouts start from ground truth.\n\n",
            ST_OVERSTRETCH_PCT, ST_STRAIN_LIMIT * 100, ST_STRAIN_LIMIT * 100, o.time_limit, ST_COLL_WARN,
            ST_GROWTH_WARN, ST_GROWTH_FLOOR_CM, ST_RATIO_FLOOR_CM);
    fprintf(f, "XPBD at 40 substeps matches the reference solver's own setting (simgen: XPBD, 40 substeps, "
               "double precision), so near-zero errors there are expected; the axes show where fewer substeps, "
               "LBS and the learned models leave that envelope.\n\n");
    fprintf(f, "| case | axis | method | status | MVE (cm) | MVE first → last quarter (cm) | collision %% | self %% | "
               "max strain (reference) | edges > %.0f%% | ms/frame | note |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
            ST_STRAIN_LIMIT * 100);
    for (size_t ci = 0; ci < nc; ++ci) {
        const st_case *cs = &cases[ci];
        if (ci >= run->done) {
            fprintf(f, "| %s | %s | all | not scored yet | | | | | | | | the run was stopped before this case |\n",
                    cs->name, cs->axis);
            continue;
        }
        if (!cs->available) {
            fprintf(f, "| %s | %s | all | not generated | | | | | | | | %s |\n", cs->name, cs->axis, cs->note);
            continue;
        }
        for (size_t k = 0; k < nm; ++k) {
            bool fn = strcmp(methods[k].family, "fnopt") == 0;
            if (fn != cs->fnopt) {
                continue;
            }
            const st_cell *cell = &cells[ci][k];
            double w = cell->frames ? (double)cell->frames : NAN;
            double g = cell->growth_ok && cell->q1_sum > 0
                           ? (cell->q4_sum / cell->q4_frames) / (cell->q1_sum / cell->q1_frames)
                           : NAN;
            /* First and last quarter side by side; the ratio only when the first quarter is large enough
             * for it to mean something (rollouts start from ground truth, so it is often ~0). */
            char gs[96] = "";
            if (cell->growth_ok) {
                double q1 = cell->q1_sum / cell->q1_frames, q4 = cell->q4_sum / cell->q4_frames;
                int n = snprintf(gs, sizeof gs, "%.3f → %.3f", q1, q4);
                if (isfinite(g) && q1 >= ST_RATIO_FLOOR_CM && n > 0 && (size_t)n < sizeof gs) {
                    snprintf(gs + n, sizeof gs - (size_t)n, " (%.1fx)", g);
                }
            }
            if (fn) {
                fprintf(f, "| %s | %s | %s | %s | e3D %.4f | | | | | | %.2f | %s |\n", cs->name, cs->axis,
                        methods[k].label, cell_status(cell), cell->e3d_w / w, cell->ms_w / w, cell->note);
            } else {
                fprintf(f, "| %s | %s | %s | %s | %.3f | %s | %.2f | %.2f | %.3f (%.3f) | %.2f%% | %.3f | %s |\n",
                        cs->name, cs->axis, methods[k].label, cell_status(cell), cell->mve_w / w, gs, cell->coll_w / w,
                        cell->self_w / w, cell->max_strain, cell->gt_strain, cell->overstretched_pct, cell->ms_w / w,
                        cell->note);
            }
        }
    }
    fprintf(f, "\n## Not measured in this run\n\n");
    fprintf(f, "- the speed axis of the simgen methods at x1 is the res_x1 case (same seeds, speed 1); x1.5/x2/x3 "
               "regenerate the reference with `weft simgen --speed`, which plays the scenario's kinematic motion "
               "(gripper schedule, avatar motion) faster.\n");
    if (nmodels == 0) {
        fprintf(f, "- learned models: no `*.safetensors` under `%s` yet.\n", o.models);
    }
    if (o.fnopt && !fnopt_weights) {
        fprintf(f, "- FNOpt learned optimizer: no weights at `%s`.\n", o.fnopt_model);
    }
    if (garment_scenario) {
        fprintf(f, "- unseen garments: on the garment scenario the unseen_motion case is the new draw (body, motion, "
                   "garment type and size from a seed outside the training set).\n");
    } else if (!o.garment) {
        fprintf(f, "- unseen garments: disabled with --no-garment.\n");
    }
    if (!o.fnopt) {
        fprintf(f, "- FNOpt speed axis: disabled with --no-fnopt.\n");
    } else if (o.quick) {
        fprintf(f, "- FNOpt speed axis for the learned FNOpt optimizer, gd and L-BFGS: left out by --quick (adam "
                   "only, one motion instead of three). Each learned run re-simulates the reference and steps the "
                   "whole trajectory, minutes per speed on a loaded machine.\n");
    }
    for (size_t ci = 0; ci < run->done; ++ci) {
        if (!cases[ci].available) {
            fprintf(f, "- %s: %s\n", cases[ci].name, cases[ci].note);
        }
    }
    if (run->done < nc) {
        fprintf(f, "- %zu of %zu cases are not scored yet: this table was written when the run had scored the "
                   "first %zu (it is rewritten after every case; running the same command again reuses the kept "
                   "scores and goes on).\n", nc - run->done, nc, run->done);
    }
    if (o.quick) {
        fprintf(f, "\nThis is the --quick suite: %u-frame cases, a %u-frame long rollout, one sequence per case, FNOpt "
                   "with adam only. The full suite is `weft bench stability` without --quick (240-frame cases, a "
                   "2400-frame rollout, two sequences per case, all four FNOpt optimizers on three motions).\n",
                o.frames, o.long_frames);
    }
    bench_link(o.out, o.csv_dir, "stability.csv", link, sizeof link);
    fprintf(f, "\nRaw numbers: [stability.csv](%s). Plot drawn by `tools/bench/plot_stability.py`.\n", link);
    fclose(f);
    char *doc = gen ? bench_replace_block(bench_slurp(path, NULL), "stability:table", gen, "# Stability suite\n") : NULL;
    free(gen);
    if (!bench_write_doc("stability", path, doc)) {
        return 1;
    }
    printf("wrote %s and %s/STABILITY.md (%zu of %zu cases, %.1f s)\n", csv, o.out, run->done, nc, wall);

    if (o.plot) {
        bench_plot(exe, "stability", "plot_stability.py", o.out, csv, "stability");
    }
    return 0;
}

enum {
    OPT_DATA = 1, OPT_OUT, OPT_CSV_DIR, OPT_MODELS, OPT_SCENARIO, OPT_BASE_VERTICES, OPT_FRAMES, OPT_LONG_FRAMES,
    OPT_COUNT, OPT_XPBD, OPT_XPBD_FAST, OPT_QUICK, OPT_NO_PLOT, OPT_NO_FNOPT, OPT_NO_GARMENT, OPT_FNOPT_MODEL,
    OPT_TIME_LIMIT, OPT_RESCORE, OPT_AXES, OPT_CCD,
};

static const cli_option k_options[] = {
    {"data", "DIR", OPT_DATA, "where the stress cases are generated (default data/stability; resumable)"},
    {"out", "DIR", OPT_OUT, "where STABILITY.md and img/stability.png go (default docs)"},
    {"csv-dir", "DIR", OPT_CSV_DIR, "where stability.csv goes (default docs/data when OUT is docs, else OUT)"},
    {"models", "DIR", OPT_MODELS, "score every DIR/*.safetensors model (default tools/train/models)"},
    {"scenario", "gripper|drop|garment", OPT_SCENARIO, "the simgen scenario of the cases (default gripper)"},
    {"base-vertices", "V", OPT_BASE_VERTICES, "the base cloth vertex count, 1..1000000 (default 256; 64 with --quick)"},
    {"frames", "T", OPT_FRAMES, "frames per case, 10..1000000 (default 240; 60 with --quick)"},
    {"long-frames", "T", OPT_LONG_FRAMES, "frames of the long rollout, 10..1000000 (default 2400; 480 with --quick)"},
    {"count", "N", OPT_COUNT, "sequences per case, 1..1000000 (default 2; 1 with --quick)"},
    {"xpbd", "5,10,20,40", OPT_XPBD,
     "the reference XPBD's substep counts, up to 8 of 1..1000 (default\n"
     "5,10,20,40)"},
    {"xpbd-fast", "5,10", OPT_XPBD_FAST,
     "the fast XPBD's (game collisions) substep counts, up to 8 of 1..1000\n"
     "(default 5,10)"},
    {"quick", NULL, OPT_QUICK,
     "V=64, T=60, long 480 frames, 1 sequence per case, FNOpt speed axis with\n"
     "adam only, S=300"},
    {"no-plot", NULL, OPT_NO_PLOT, "do not draw img/stability.png"},
    {"no-fnopt", NULL, OPT_NO_FNOPT, "without the FNOpt speed axis"},
    {"no-garment", NULL, OPT_NO_GARMENT, "without the unseen-garment case"},
    {"fnopt-model", "PATH", OPT_FNOPT_MODEL,
     "the FNOpt learned optimizer's weights (default\n"
     "tools/fnopt/models/fnopt_32.safetensors)"},
    {"time-limit", "S", OPT_TIME_LIMIT,
     "seconds of stepping per rollout before a method is marked too slow (its\n"
     "prefix is still scored), 1..1000000 (default 900; 300 with --quick)"},
    {"rescore", NULL, OPT_RESCORE,
     "ignore the scores kept from earlier runs (<seq>/scores/*.json) and\n"
     "evaluate again (scores are kept by the eval's arguments and, for models,\n"
     "the model file's contents: a retrained model is scored again by itself;\n"
     "a changed weft needs --rescore)"},
    {"axes", "LIST", OPT_AXES,
     "only the cases of these axes, a comma list of resolution, long, unseen,\n"
     "speed (e.g. --axes long: the 2400-frame rollout alone, into its own\n"
     "--out)"},
    {"ccd", "on|off", OPT_CCD,
     "off: every method without the CCD post-process (default on): the\n"
     "methods' own stability, without the cost of CCD once cloth is inside the\n"
     "body"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench stability",
    .synopsis = "weft bench stability [--data DIR] [--out DIR] [--csv-dir DIR] [--models DIR]\n"
                "                     [--scenario gripper|drop|garment]\n"
                "                     [--base-vertices V] [--frames T] [--long-frames T] [--count N]\n"
                "                     [--xpbd 5,10,20,40] [--xpbd-fast 5,10] [--quick] [--no-plot]\n"
                "                     [--no-fnopt] [--no-garment] [--fnopt-model PATH] [--time-limit S]\n"
                "                     [--rescore] [--axes LIST] [--ccd on|off]",
    .about = "Generates the stress cases with weft simgen under DIR (default data/stability; resumable), scores\n"
             "LBS, XPBD 5/10/20/40, the fast XPBD (game collisions) 5/10 and every DIR/*.safetensors model\n"
             "(fp32/fp16/int8, CCD on) on each, and writes the table in OUT/STABILITY.md (between\n"
             "<!-- stability:table --> markers; the text around them is kept), OUT/img/stability.png and the\n"
             "CSV behind them, CSVDIR/stability.csv (default OUT: docs; default CSVDIR: docs/data when OUT is\n"
             "docs, else OUT).\n"
             "defaults: V=256 vertices, T=240 frames, long 2400 frames, 2 sequences per case, S=900 s of stepping\n"
             "per rollout before a method is marked too slow (its prefix is still scored)",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_stability(int argc, char **argv)
{
    st_opts o = {.data = "data/stability", .out = "docs", .models = "tools/train/models", .scenario = "gripper",
                 .fnopt_model = "tools/fnopt/models/fnopt_32.safetensors", .plot = true, .fnopt = true,
                 .garment = true};
    char command[2048];
    bench_command_line(command, sizeof command, "weft bench stability", argc, argv); /* before getopt reorders argv */
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_QUICK:
            o.quick = true;
            break;
        case OPT_NO_PLOT:
            o.plot = false;
            break;
        case OPT_NO_FNOPT:
            o.fnopt = false;
            break;
        case OPT_NO_GARMENT:
            o.garment = false;
            break;
        case OPT_RESCORE:
            o.rescore = true;
            break;
        case OPT_BASE_VERTICES:
        case OPT_FRAMES:
        case OPT_LONG_FRAMES:
        case OPT_COUNT:
        case OPT_TIME_LIMIT: {
            uint32_t *num = id == OPT_BASE_VERTICES ? &o.base_vertices
                            : id == OPT_FRAMES      ? &o.frames
                            : id == OPT_LONG_FRAMES ? &o.long_frames
                            : id == OPT_COUNT       ? &o.count
                                                    : &o.time_limit;
            if (!bench_parse_u32("stability", a, v, 1, 1000000, num)) {
                return 2;
            }
            break;
        }
        case OPT_XPBD:
        case OPT_XPBD_FAST: {
            const bool fast = id == OPT_XPBD_FAST;
            size_t *n = fast ? &o.nxpbd_fast : &o.nxpbd;
            if (!bench_parse_substeps("stability", a, v, fast ? o.xpbd_fast : o.xpbd, 8, n)) {
                return 2;
            }
            break;
        }
        case OPT_DATA:
            o.data = v;
            break;
        case OPT_OUT:
            o.out = v;
            break;
        case OPT_CSV_DIR:
            o.csv_dir = v;
            break;
        case OPT_MODELS:
            o.models = v;
            break;
        case OPT_SCENARIO:
            o.scenario = v;
            break;
        case OPT_FNOPT_MODEL:
            o.fnopt_model = v;
            break;
        case OPT_CCD:
            if (!cli_either("weft bench stability", a, v, "on", "off", &o.no_ccd)) {
                return 2;
            }
            break;
        case OPT_AXES:
            if (!axes_valid(v)) {
                fprintf(stderr, "weft bench stability: --axes wants a comma list of resolution, long, unseen, speed\n");
                return 2;
            }
            o.axes = v;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    if (strcmp(o.scenario, "gripper") != 0 && strcmp(o.scenario, "drop") != 0 && strcmp(o.scenario, "garment") != 0) {
        fprintf(stderr, "weft bench stability: --scenario takes gripper, drop or garment\n");
        return 2;
    }
    /* On the garment scenario the unseen-seed case already draws a new body, motion and garment. */
    const bool garment_scenario = strcmp(o.scenario, "garment") == 0;
    if (garment_scenario) {
        o.garment = false;
    }
    o.base_vertices = o.base_vertices ? o.base_vertices : (o.quick ? 64 : 256);
    if (garment_scenario && o.base_vertices < 256) {
        o.base_vertices = 256; /* simgen's garments need >= 200 vertices */
    }
    o.frames = o.frames ? o.frames : (o.quick ? 60 : 240);
    o.long_frames = o.long_frames ? o.long_frames : (o.quick ? 480 : 2400);
    o.count = o.count ? o.count : (o.quick ? 1 : 2);
    o.time_limit = o.time_limit ? o.time_limit : (o.quick ? 300 : 900);
    if (o.frames < 10 || o.long_frames < 10) {
        fprintf(stderr, "weft bench stability: --frames and --long-frames must be >= 10\n");
        return 2;
    }
    char exe[1024];
    if (!bench_self_exe(exe, sizeof exe)) {
        fprintf(stderr, "weft bench stability: cannot find the running weft binary (/proc/self/exe)\n");
        return 1;
    }
    o.csv_dir = bench_csv_dir(o.csv_dir, o.out, BENCH_DOCS_DATA_DIR);
    if (!bench_mkdirs(o.data) || !bench_mkdirs(o.out) || !bench_mkdirs(o.csv_dir)) {
        fprintf(stderr, "weft bench stability: cannot create %s, %s or %s\n", o.data, o.out, o.csv_dir);
        return 1;
    }

    /* Methods. */
    static st_method methods[ST_MAX_METHODS];
    memset(methods, 0, sizeof methods);
    size_t nm = 0;
    snprintf(methods[nm].label, 96, "LBS");
    snprintf(methods[nm].family, 16, "lbs");
    snprintf(methods[nm].method, 16, "lbs");
    snprintf(methods[nm++].precision, 8, "-");
    /* The reference XPBD and the fast one at their substep counts (defaults 5/10/20/40 and 5/10). */
    static const unsigned k_substeps[] = {5, 10, 20, 40};
    const struct {
        const char *family, *label;
        const unsigned *substeps;
        size_t n;
    } xpbd_methods[] = {{"xpbd", "XPBD", o.nxpbd ? o.xpbd : k_substeps, o.nxpbd ? o.nxpbd : 4},
                        {"xpbd-fast", "XPBD-fast", o.nxpbd_fast ? o.xpbd_fast : k_substeps, o.nxpbd_fast ? o.nxpbd_fast : 2}};
    for (size_t f = 0; f < 2; ++f) {
        for (size_t k = 0; k < xpbd_methods[f].n; ++k) {
            snprintf(methods[nm].label, 96, "%s-%u", xpbd_methods[f].label, xpbd_methods[f].substeps[k]);
            snprintf(methods[nm].family, 16, "%s", xpbd_methods[f].family);
            snprintf(methods[nm].method, 16, "%s:%u", xpbd_methods[f].family, xpbd_methods[f].substeps[k]);
            snprintf(methods[nm++].precision, 8, "-");
        }
    }
    static char model_names[16][256];
    size_t nmodels = bench_list_models(o.models, model_names, 16);
    static const char *const k_prec[] = {"fp32", "fp16", "int8"};
    for (size_t i = 0; i < nmodels && nm + 4 < ST_MAX_METHODS - 4; ++i) {
        char stem[256];
        snprintf(stem, sizeof stem, "%.240s", model_names[i]);
        stem[strlen(stem) - 12] = '\0';
        for (int p = 0; p < 3; ++p) {
            snprintf(methods[nm].label, 96, "%.60s %s", stem, k_prec[p]);
            snprintf(methods[nm].family, 16, "model");
            snprintf(methods[nm].method, 16, "model");
            snprintf(methods[nm].precision, 8, "%s", k_prec[p]);
            bench_model_file(o.models, stem, model_names[i], k_prec[p], methods[nm].model, 1024);
            if (!file_fingerprint(methods[nm].model, methods[nm].model_content, sizeof methods[nm].model_content)) {
                fprintf(stderr, "weft bench stability: cannot read model %s\n", methods[nm].model);
                return 1;
            }
            nm++;
        }
        if (garment_scenario) {
            /* Worn garments also get the game-engine remedies: int8 with 3 cm tethers (drift) and a 10 %
             * strain limit (torn edges), the render sample's setting. */
            methods[nm] = methods[nm - 1];
            snprintf(methods[nm].label, 96, "%.60s int8 + tethers 3 cm + strain 10%%", stem);
            snprintf(methods[nm].strain_pct, 16, "10");
            snprintf(methods[nm++].tether_cm, 16, "3");
        }
    }
    size_t first_fnopt = nm;
    static const char *const k_fnopt_opt[] = {"learned", "gd", "adam", "lbfgs"};
    bool fnopt_weights = bench_file_exists(o.fnopt_model);
    for (int k = 0; o.fnopt && k < 4; ++k) {
        /* Each FNOpt run re-simulates its XPBD reference, and the learned optimizer's whole trajectory
         * takes minutes on a loaded machine: --quick keeps the best classical optimizer (adam) only. */
        if ((k == 0 && !fnopt_weights) || (o.quick && k != 2)) {
            continue;
        }
        snprintf(methods[nm].label, 96, k == 0 ? "FNOpt" : "%s (10 it)", k_fnopt_opt[k]);
        snprintf(methods[nm].family, 16, "fnopt");
        snprintf(methods[nm].method, 16, "%s", k_fnopt_opt[k]);
        snprintf(methods[nm].precision, 8, "fp32");
        snprintf(methods[nm++].model, 1024, "%s", o.fnopt_model);
    }

    /* Cases. The seed offset keeps the "unseen" draws out of the default-seed training names. */
    static st_case cases[ST_MAX_CASES];
    memset(cases, 0, sizeof cases);
    size_t nc = 0;
    static const unsigned k_res[] = {1, 2, 4, 10};
    for (int k = 0; k < 4; ++k) {
        st_case *c = &cases[nc++];
        snprintf(c->name, sizeof c->name, "res_x%u", k_res[k]);
        snprintf(c->axis, sizeof c->axis, "resolution");
        snprintf(c->level, sizeof c->level, "x%u", k_res[k]);
        snprintf(c->scenario, sizeof c->scenario, "%s", o.scenario);
        c->vertices = o.base_vertices * k_res[k];
        c->frames = o.frames;
        c->count = o.count;
    }
    st_case *c = &cases[nc++];
    snprintf(c->name, sizeof c->name, "long_%u", o.long_frames);
    snprintf(c->axis, sizeof c->axis, "long rollout");
    snprintf(c->level, sizeof c->level, "%u frames", o.long_frames);
    snprintf(c->scenario, sizeof c->scenario, "%s", o.scenario);
    c->vertices = o.base_vertices;
    c->frames = o.long_frames;
    c->count = 1;
    c = &cases[nc++];
    snprintf(c->name, sizeof c->name, "unseen_motion");
    snprintf(c->axis, sizeof c->axis, "unseen");
    snprintf(c->level, sizeof c->level, "%s", garment_scenario ? "new body + motion + garment" : "new seed");
    snprintf(c->scenario, sizeof c->scenario, "%s", o.scenario);
    c->vertices = o.base_vertices;
    c->frames = o.frames;
    c->count = o.count;
    c->seed = 0x57AB1E5EEDull;
    c = o.garment ? &cases[nc++] : &cases[ST_MAX_CASES - 1]; /* the spare slot is never listed */
    snprintf(c->name, sizeof c->name, "unseen_garment");
    snprintf(c->axis, sizeof c->axis, "unseen");
    snprintf(c->level, sizeof c->level, "garment");
    snprintf(c->scenario, sizeof c->scenario, "garment");
    c->vertices = o.base_vertices < 256 ? 256 : o.base_vertices; /* simgen's garments need >= 200 vertices */
    c->frames = o.frames;
    c->count = 1;
    c->seed = 0x57AB1E5EEDull;
    static const double k_speed[] = {1.0, 1.5, 2.0, 3.0};
    /* Motion speed of the simgen scenario: the same seeds as res_x1 (which is speed x1), the
     * kinematic motion (gripper schedule, avatar motion) played faster. */
    for (int k = 1; k < 4; ++k) {
        c = &cases[nc++];
        snprintf(c->name, sizeof c->name, "speed_x%g", k_speed[k]);
        snprintf(c->axis, sizeof c->axis, "speed");
        snprintf(c->level, sizeof c->level, "x%g", k_speed[k]);
        snprintf(c->scenario, sizeof c->scenario, "%s", o.scenario);
        c->vertices = o.base_vertices;
        c->frames = o.frames;
        c->count = o.count;
        c->speed = k_speed[k];
    }
    for (int k = 0; o.fnopt && k < 4; ++k) {
        c = &cases[nc++];
        snprintf(c->name, sizeof c->name, "fnopt_speed_x%g", k_speed[k]);
        snprintf(c->axis, sizeof c->axis, "speed");
        snprintf(c->level, sizeof c->level, "x%g", k_speed[k]);
        snprintf(c->scenario, sizeof c->scenario, "fnopt-grid");
        c->speed = k_speed[k];
        c->fnopt = true;
    }

    /* --axes: keep only the chosen axes' cases, in order. */
    size_t kept = 0;
    for (size_t ci = 0; ci < nc; ++ci) {
        if (axis_wanted(o.axes, cases[ci].axis)) {
            cases[kept++] = cases[ci];
        }
    }
    nc = kept;

    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    static st_cell cells[ST_MAX_CASES][ST_MAX_METHODS];
    memset(cells, 0, sizeof cells);
    st_run run = {.o = &o, .command = command, .exe = exe, .methods = methods, .nm = nm, .nmodels = nmodels,
                  .cases = cases, .nc = nc, .cells = cells, .fnopt_weights = fnopt_weights,
                  .garment_scenario = garment_scenario};
    for (size_t ci = 0; ci < nc; ++ci) {
        st_case *cs = &cases[ci];
        if (cs->fnopt) {
            cs->available = true;
            for (size_t k = first_fnopt; k < nm; ++k) {
                score_fnopt(exe, &o, &methods[k], cs, &cells[ci][k]);
            }
        } else {
            char dir[1100];
            cs->available = generate_case(exe, &o, cs, dir, sizeof dir);
            if (!cs->available) {
                printf("  %s: %s\n", cs->name, cs->note);
            }
            bench_seq *seqs = NULL;
            size_t ns = 0;
            if (cs->available) {
                bench_list_sequences(dir, NULL, &seqs, &ns);
            }
            if (ns && seqs[0].vertices) {
                snprintf(cs->note, sizeof cs->note, "%u cloth vertices, %u frames, %zu sequence(s)", seqs[0].vertices,
                         seqs[0].frames, ns);
            }
            for (size_t s = 0; s < ns; ++s) {
                for (size_t k = 0; k < first_fnopt; ++k) {
                    st_cell *cell = &cells[ci][k];
                    score_sequence(exe, &o, &methods[k], &seqs[s], cell);
                    double w = cell->frames ? (double)cell->frames : NAN;
                    printf("  %-14s %-22s %-20s MVE %8.3f cm  coll %5.2f%%  strain %.3f (%.2f%% of edges > 25%%, "
                           "reference %.3f)  %.1f ms/frame  %s\n",
                           cs->name, seqs[s].name, methods[k].label, cell->mve_w / w, cell->coll_w / w,
                           cell->max_strain, cell->overstretched_pct, cell->gt_strain, cell->ms_w / w,
                           cell_status(cell));
                    fflush(stdout);
                }
            }
            free(seqs);
        }
        /* Tables after every case: a run stopped later still leaves these. */
        clock_gettime(CLOCK_MONOTONIC, &t1);
        run.wall = (double)(t1.tv_sec - t0.tv_sec) + (double)(t1.tv_nsec - t0.tv_nsec) * 1e-9;
        run.done = ci + 1;
        int rc = write_tables(&run);
        if (rc != 0) {
            return rc;
        }
    }
    return 0;
}
