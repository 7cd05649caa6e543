/* weft bench lod: the measured level-of-detail table, and the per-character cost of a crowd.
 *
 * 1. Every candidate level (LBS, XPBD at a few substep counts, each model in DIR at fp32/fp16/
 *    int8 with and without CCD) runs over the split's sequences, one `weft eval --json` child per
 *    (level, sequence), exactly as `weft bench chart` does. Frame-weighted means go to
 *    <out>/lod.csv, the file weft_lod_table_load_file() reads (include/weft/lod.h), and to the
 *    generated sections of <out>/LOD.md.
 * 2. Per-character step cost at 1, 8 and 64 characters: N default avatars walking, each wearing
 *    a T-shirt driven by a weft_lod_garment at one level of the table just written, stepped in
 *    one thread. Pose and collider upload are outside the timed region.
 *
 * LOD.md keeps its hand-written text: only the blocks between "<!-- lod:table -->" /
 * "<!-- lod:scaling -->" and their "<!-- /lod:... -->" end markers are replaced. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "weft.h"
#include "weft/body.h"
#include "weft/lod.h"
#include "support_bench.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const char weft_bench_lod_help[] =
    "level-of-detail table: ms/frame and MVE per level (CSV the runtime loads + docs/LOD.md), crowd cost at 1/8/64";

#define LOD_MAX_CANDS 96
#define LOD_MAX_SCALE 16

typedef struct lod_cand {
    char name[WEFT_LOD_NAME_CAP];
    char method[16];            /* --method value for eval: lbs, xpbd:S, model */
    const char *family;         /* lbs, xpbd, model */
    char model_name[WEFT_LOD_NAME_CAP]; /* metadata name */
    char model_file[1024];
    char precision[8];
    unsigned substeps;
    bool ccd;
    uint32_t sequences, frames, failed, nan_runs;
    double mve_w, ms_w, strain;
    char note[240];
} lod_cand;

typedef struct lod_opts {
    const char *data, *split, *models, *out, *scale_levels, *scale_res;
    uint32_t frames, max_seqs, scale_frames;
    unsigned xpbd[8];
    size_t nxpbd;
    bool scale, scale_only;
} lod_opts;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: weft bench lod --data DIR [--split test|val|train|all] [--models DIR] [--out DIR] [--frames N]\n"
            "                      [--max-seqs N] [--xpbd 5,10,20] [--no-scale] [--scale-levels a,b,...]\n"
            "                      [--scale-frames N] [--scale-res 1k|4k] [--scale-only]\n"
            "  Measures every level (LBS, XPBD at the given substeps, each DIR/*.safetensors model at\n"
            "  fp32/fp16/int8 with and without CCD) on the split through `weft eval --json`, writes OUT/lod.csv\n"
            "  (loadable by weft_lod_table_load_file) and the table in OUT/LOD.md, then measures the\n"
            "  per-character step cost of 1, 8 and 64 walking avatars at the --scale-levels (default: lbs,\n"
            "  xpbd-5, every model at int8 and fp32 with CCD and at fp32 without). Default OUT: docs.\n"
            "  --scale-only  skip the table: reuse OUT/lod.csv and regenerate only the per-character section\n");
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static bool cand_valid(const lod_cand *c)
{
    return c->frames > 0 && c->nan_runs == 0 && c->failed == 0 && isfinite(c->mve_w / c->frames) &&
           c->ms_w / c->frames > 0.0;
}

/* Metadata "name" of a model file, for the table's model column. */
static bool model_meta_name(weft_context *ctx, const char *file, char *out, size_t cap)
{
    weft_model *m = NULL;
    if (weft_model_load_file(ctx, file, &m) != WEFT_OK) {
        return false;
    }
    weft_model_info info = weft_model_get_info(m);
    bool ok = info.name && info.name[0] && strlen(info.name) < cap;
    if (ok) {
        snprintf(out, cap, "%s", info.name);
        for (char *p = out; *p; ++p) { /* the table's name alphabet */
            bool good = (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') ||
                        *p == '_' || *p == '.' || *p == '-';
            ok = ok && good;
        }
    }
    weft_model_destroy(m);
    return ok;
}

/* ---------------------------------------------------------------------------------------- */
/* Part 1: the table                                                                          */

static size_t build_candidates(weft_context *ctx, const lod_opts *o, lod_cand *c, char skipped[][300], size_t *nskip)
{
    size_t n = 0;
    for (int ccd = 1; ccd >= 0; --ccd) {
        lod_cand *k = &c[n++];
        memset(k, 0, sizeof *k);
        snprintf(k->name, sizeof k->name, "lbs%s", ccd ? "" : "-noccd");
        snprintf(k->method, sizeof k->method, "lbs");
        k->family = "lbs";
        k->ccd = ccd != 0;
    }
    for (size_t i = 0; i < o->nxpbd; ++i) {
        lod_cand *k = &c[n++];
        memset(k, 0, sizeof *k);
        snprintf(k->name, sizeof k->name, "xpbd-%u", o->xpbd[i]);
        snprintf(k->method, sizeof k->method, "xpbd:%u", o->xpbd[i]);
        k->family = "xpbd";
        k->substeps = o->xpbd[i];
        k->ccd = true;
    }
    static char files[32][256];
    size_t nf = bench_list_models(o->models, files, 32);
    if (nf == 0) {
        snprintf(skipped[(*nskip)++], 300, "learned models: no `*.safetensors` under `%s`", o->models);
    }
    static const char *const precs[] = {"fp32", "fp16", "int8"};
    for (size_t i = 0; i < nf && n + 6 <= LOD_MAX_CANDS; ++i) {
        char stem[256], base[1300], meta[WEFT_LOD_NAME_CAP];
        snprintf(stem, sizeof stem, "%s", files[i]);
        stem[strlen(stem) - 12] = '\0';
        snprintf(base, sizeof base, "%s/%s", o->models, files[i]);
        if (!model_meta_name(ctx, base, meta, sizeof meta)) {
            snprintf(skipped[(*nskip)++], 300, "model `%.150s`: not loadable or no usable metadata name (%.60s)", base,
                     weft_last_error());
            continue;
        }
        for (int p = 0; p < 3; ++p) {
            for (int ccd = 1; ccd >= 0; --ccd) {
                lod_cand *k = &c[n++];
                memset(k, 0, sizeof *k);
                snprintf(k->name, sizeof k->name, "%.30s-%s%s", meta, precs[p], ccd ? "" : "-noccd");
                snprintf(k->method, sizeof k->method, "model");
                k->family = "model";
                snprintf(k->model_name, sizeof k->model_name, "%s", meta);
                snprintf(k->precision, sizeof k->precision, "%s", precs[p]);
                bench_model_file(o->models, stem, files[i], precs[p], k->model_file, sizeof k->model_file);
                k->ccd = ccd != 0;
            }
        }
    }
    return n;
}

static void run_candidates(const char *exe, const lod_opts *o, const bench_seq *seqs, size_t nseq, lod_cand *c,
                           size_t nc)
{
    char frames_arg[16];
    snprintf(frames_arg, sizeof frames_arg, "%u", o->frames);
    for (size_t k = 0; k < nc; ++k) {
        for (size_t s = 0; s < nseq; ++s) {
            const char *extra[16];
            int n = 0;
            extra[n++] = "--method";
            extra[n++] = c[k].method;
            extra[n++] = "--ccd";
            extra[n++] = c[k].ccd ? "on" : "off";
            if (o->frames) {
                extra[n++] = "--frames";
                extra[n++] = frames_arg;
            }
            if (strcmp(c[k].family, "model") == 0) {
                extra[n++] = "--model";
                extra[n++] = c[k].model_file;
                extra[n++] = "--precision";
                extra[n++] = c[k].precision;
            }
            extra[n] = NULL;
            bench_eval_result e;
            bench_eval(exe, seqs[s].dir, extra, &e);
            c[k].sequences++;
            if (!e.ok) {
                c[k].failed++;
                if (!c[k].note[0]) {
                    snprintf(c[k].note, sizeof c[k].note, "%s", e.why);
                }
                printf("%-24s %-22s FAILED: %s\n", seqs[s].name, c[k].name, e.why);
                continue;
            }
            c[k].frames += e.frames;
            c[k].mve_w += e.mve_cm * e.frames;
            c[k].ms_w += e.ms_per_frame * e.frames;
            c[k].strain = fmax(c[k].strain, e.max_edge_strain);
            c[k].nan_runs += e.nan;
            printf("%-24s %-22s frames %4u  MVE %8.3f cm  %9.3f ms/frame%s\n", seqs[s].name, c[k].name, e.frames,
                   e.mve_cm, e.ms_per_frame, e.nan ? "  NaN" : "");
            fflush(stdout);
        }
    }
}

static bool write_csv(const char *path, const lod_cand *c, size_t nc, const char *command, const lod_opts *o)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "weft bench lod: cannot write %s\n", path);
        return false;
    }
    fprintf(f, "# weft level-of-detail table, measured by: %s\n", command);
    fprintf(f, "# data %s, split %s; build and machine: %s\n", o->data, o->split, weft_config_string());
    fprintf(f, "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,"
               "frames\n");
    for (size_t k = 0; k < nc; ++k) {
        if (!cand_valid(&c[k])) {
            continue;
        }
        char sub[16] = "-";
        if (c[k].substeps) {
            snprintf(sub, sizeof sub, "%u", c[k].substeps);
        }
        bool model = strcmp(c[k].family, "model") == 0;
        fprintf(f, "%s,%s,%s,%s,%s,%s,1,%.6g,%.6g,%.6g,%u,%u\n", c[k].name, c[k].family, model ? c[k].model_name : "-",
                model ? c[k].precision : "-", sub, c[k].ccd ? "on" : "off", c[k].ms_w / c[k].frames,
                c[k].mve_w / c[k].frames, c[k].strain, c[k].sequences, c[k].frames);
    }
    fclose(f);
    return true;
}

/* ---------------------------------------------------------------------------------------- */
/* Part 2: per-character cost                                                                 */

typedef struct scale_row {
    char level[WEFT_LOD_NAME_CAP];
    uint32_t n;
    bool batched;                       /* weft_garments_step over all characters, else one by one */
    double ms_per_char, ms_total;
    char note[160];
} scale_row;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Steps n avatars at one level for `frames` timed frames after `lead` untimed ones; median ms. */
static bool scale_one(weft_context *ctx, const weft_body *body, const weft_cloth_mesh *cloth, const weft_lod_table *t,
                      uint32_t level, const weft_model *const *models, uint32_t nmodels, uint32_t n, uint32_t frames,
                      scale_row *row)
{
    const uint32_t nb = weft_body_vertex_count(body);
    weft_lod_garment **g = calloc(n, sizeof *g);
    weft_garment **cur = calloc(n, sizeof *cur);
    float *verts = malloc((size_t)nb * 3 * sizeof(float));
    float *placed = malloc((size_t)nb * 3 * sizeof(float));
    float *rest = malloc((size_t)cloth->vertex_count * 3 * sizeof(float));
    bool ok = g && cur && verts && placed && rest;
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    /* Per-frame totals; the median is reported, as the machine these run on is shared and a
     * mean is dragged by frames where another process held the core. */
    double *frame_ms = calloc(frames, sizeof *frame_ms);
    ok = ok && frame_ms;
    for (uint32_t i = 0; ok && i < n; ++i) {
        /* Characters 1.2 m apart along X; the garment is created on the bind pose there. */
        const float dx = 1.2f * (float)i;
        const float *br = weft_body_rest_vertices(body);
        for (uint32_t v = 0; v < nb; ++v) {
            placed[3 * v] = br[3 * v] + dx;
            placed[3 * v + 1] = br[3 * v + 1];
            placed[3 * v + 2] = br[3 * v + 2];
        }
        for (uint32_t v = 0; v < cloth->vertex_count; ++v) {
            rest[3 * v] = cloth->positions[3 * v] + dx;
            rest[3 * v + 1] = cloth->positions[3 * v + 1];
            rest[3 * v + 2] = cloth->positions[3 * v + 2];
        }
        weft_lod_garment_def d = weft_default_lod_garment_def();
        d.table = t;
        d.level = level;
        d.models = models;
        d.model_count = nmodels;
        d.rest_positions = rest;
        d.vertex_count = cloth->vertex_count;
        d.triangles = cloth->triangles;
        d.triangle_count = cloth->triangle_count;
        d.collider_rest_positions = placed;
        d.collider_vertex_count = nb;
        d.collider_triangles = weft_body_triangles(body);
        d.collider_triangle_count = weft_body_triangle_count(body);
        if (weft_lod_garment_create(ctx, &d, &g[i]) != WEFT_OK) {
            snprintf(row->note, sizeof row->note, "%s", weft_last_error());
            ok = false;
        }
    }
    /* The walk starts from the bind pose: blend in over the first frames so XPBD is not asked to
     * resolve a teleporting body (the blend frames are untimed). */
    const uint32_t lead = 4;
    for (uint32_t f = 0; ok && f < lead + frames; ++f) {
        for (uint32_t i = 0; ok && i < n; ++i) {
            weft_pose pose, bind;
            double tt = (double)f / 60.0 + 0.05 * i;
            ok = weft_motion_sample(&md, tt, &pose) == WEFT_OK;
            if (ok && f < lead) {
                weft_body_bind_pose(body, &bind);
                float u = (float)(f + 1) / (float)lead;
                for (int j = 0; j < 3 * WEFT_BODY_JOINTS; ++j) {
                    pose.rotations[j] = bind.rotations[j] + u * (pose.rotations[j] - bind.rotations[j]);
                }
            }
            pose.translation[0] = 1.2f * (float)i;
            pose.translation[2] = 0.0f;
            ok = ok && weft_body_pose(body, &pose, verts, NULL) == WEFT_OK &&
                 weft_lod_garment_set_collider(g[i], verts) == WEFT_OK;
        }
        double t0 = now_s();
        if (ok && row->batched) {
            /* set_collider has recorded each garment's frame, so stepping the current garments
             * directly keeps the LOD state complete. */
            for (uint32_t i = 0; i < n; ++i) {
                cur[i] = weft_lod_garment_current(g[i]);
            }
            ok = weft_garments_step(cur, n) == WEFT_OK;
        }
        for (uint32_t i = 0; ok && !row->batched && i < n; ++i) {
            ok = weft_lod_garment_step(g[i]) == WEFT_OK;
        }
        if (!ok && !row->note[0]) {
            snprintf(row->note, sizeof row->note, "%s", weft_last_error());
        }
        if (f >= lead) {
            frame_ms[f - lead] = (now_s() - t0) * 1e3;
        }
    }
    for (uint32_t i = 0; g && i < n; ++i) {
        weft_lod_garment_destroy(g[i]);
    }
    free(g);
    free(cur);
    free(verts);
    free(placed);
    free(rest);
    row->n = n;
    if (ok) {
        qsort(frame_ms, frames, sizeof *frame_ms, cmp_double);
        row->ms_total = frames % 2 ? frame_ms[frames / 2] : 0.5 * (frame_ms[frames / 2 - 1] + frame_ms[frames / 2]);
    } else {
        row->ms_total = NAN;
    }
    free(frame_ms);
    row->ms_per_char = ok ? row->ms_total / n : NAN;
    return ok;
}

static size_t run_scaling(const lod_opts *o, const char *csv, scale_row *rows, size_t cap, char *desc, size_t desc_cap)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_body *body = NULL;
    weft_cloth_mesh *cloth = NULL;
    weft_lod_table *t = NULL;
    weft_model *models[32] = {NULL};
    uint32_t nmodels = 0;
    size_t nrows = 0;
    weft_avatar_def ad = weft_default_avatar_def();
    weft_cloth_def cl = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    bool ok = weft_context_create(&cd, &ctx) == WEFT_OK && weft_avatar_create(ctx, &ad, &body) == WEFT_OK &&
              weft_cloth_resolution_from_name(o->scale_res, &cl.resolution) == WEFT_OK &&
              weft_cloth_create(ctx, &cl, body, &cloth) == WEFT_OK && weft_lod_table_load_file(ctx, csv, &t) == WEFT_OK;
    if (!ok) {
        fprintf(stderr, "weft bench lod: scaling setup: %s\n", weft_last_error());
    }
    static char files[32][256];
    size_t nf = ok ? bench_list_models(o->models, files, 32) : 0;
    for (size_t i = 0; i < nf; ++i) {
        char path[1300];
        snprintf(path, sizeof path, "%s/%s", o->models, files[i]);
        if (weft_model_load_file(ctx, path, &models[nmodels]) == WEFT_OK) {
            nmodels++;
        }
    }
    if (ok) {
        snprintf(desc, desc_cap, "default avatar (%u vertices, %u triangles) walking, T-shirt %s (%u vertices)",
                 weft_body_vertex_count(body), weft_body_triangle_count(body), o->scale_res, cloth->vertex_count);
    }
    /* Levels: the list given, else lbs, xpbd-5 and each model's int8 and fp32 with CCD. */
    char list[1024];
    if (o->scale_levels) {
        snprintf(list, sizeof list, "%s", o->scale_levels);
    } else {
        list[0] = '\0';
        for (uint32_t i = 0; ok && i < weft_lod_table_count(t); ++i) {
            const weft_lod_level *l = weft_lod_table_level(t, i);
            /* fp32 without CCD shows the model step alone, where batching can matter. */
            bool want = strcmp(l->name, "lbs") == 0 || strcmp(l->name, "xpbd-5") == 0 ||
                        (l->method == WEFT_METHOD_MODEL && l->precision != WEFT_PRECISION_FP16 &&
                         (l->ccd || l->precision == WEFT_PRECISION_FP32));
            if (want) {
                size_t len = strlen(list);
                snprintf(list + len, sizeof list - len, "%s%s", len ? "," : "", l->name);
            }
        }
    }
    static const uint32_t counts[] = {1, 8, 64};
    for (char *p = list; ok && *p;) {
        char *comma = strchr(p, ',');
        char name[WEFT_LOD_NAME_CAP];
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        snprintf(name, sizeof name, "%.*s", (int)(len < WEFT_LOD_NAME_CAP - 1 ? len : WEFT_LOD_NAME_CAP - 1), p);
        p = comma ? comma + 1 : p + len;
        uint32_t level = 0;
        if (weft_lod_table_find(t, name, &level) != WEFT_OK) {
            fprintf(stderr, "weft bench lod: --scale-levels: %s (not in the measured table)\n", name);
            continue;
        }
        /* Only model levels differ when batched: weft_garments_step steps other methods one by one. */
        const weft_lod_level *lv = weft_lod_table_level(t, level);
        for (int batched = 0; batched < (lv->method == WEFT_METHOD_MODEL ? 2 : 1); ++batched) {
            for (size_t c = 0; c < sizeof counts / sizeof counts[0] && nrows < cap; ++c) {
                scale_row *r = &rows[nrows++];
                memset(r, 0, sizeof *r);
                snprintf(r->level, sizeof r->level, "%s", name);
                r->batched = batched != 0;
                scale_one(ctx, body, cloth, t, level, (const weft_model *const *)models, nmodels, counts[c],
                          o->scale_frames, r);
                printf("scaling %-22s x%-3u %-10s %9.3f ms/character  %10.3f ms/frame total%s%s\n", name, counts[c],
                       batched ? "batched" : "sequential", r->ms_per_char, r->ms_total, r->note[0] ? "  " : "",
                       r->note);
                fflush(stdout);
            }
        }
    }
    for (uint32_t i = 0; i < nmodels; ++i) {
        weft_model_destroy(models[i]);
    }
    weft_lod_table_destroy(t);
    weft_cloth_destroy(cloth);
    weft_body_destroy(body);
    if (ctx) {
        weft_context_destroy(ctx);
    }
    return nrows;
}

/* ---------------------------------------------------------------------------------------- */
/* LOD.md: replace the generated blocks, keep the rest.                                        */

static char *append(char *buf, size_t *len, size_t *cap, const char *s)
{
    size_t n = strlen(s);
    if (*len + n + 1 > *cap) {
        size_t nc = (*cap + n + 1) * 2;
        char *nb = realloc(buf, nc);
        if (!nb) {
            free(buf);
            return NULL;
        }
        buf = nb;
        *cap = nc;
    }
    memcpy(buf + *len, s, n + 1);
    *len += n;
    return buf;
}

/* Replaces the text between "<!-- lod:TAG -->" and "<!-- /lod:TAG -->" in doc (appending the
 * block when the markers are absent). Returns the new document (malloc'd) or NULL. */
static char *replace_block(char *doc, const char *tag, const char *body)
{
    char open[64], close[64];
    snprintf(open, sizeof open, "<!-- lod:%s -->", tag);
    snprintf(close, sizeof close, "<!-- /lod:%s -->", tag);
    size_t len = 0, cap = 0;
    char *out = NULL;
    char *a = doc ? strstr(doc, open) : NULL;
    char *b = a ? strstr(a, close) : NULL;
    if (a && b) {
        char saved = *a;
        *a = '\0';
        out = append(out, &len, &cap, doc);
        *a = saved;
        out = out ? append(out, &len, &cap, open) : NULL;
        out = out ? append(out, &len, &cap, "\n") : NULL;
        out = out ? append(out, &len, &cap, body) : NULL;
        out = out ? append(out, &len, &cap, b) : NULL;
    } else {
        out = append(out, &len, &cap, doc ? doc : "# Level of detail\n");
        out = out ? append(out, &len, &cap, "\n") : NULL;
        out = out ? append(out, &len, &cap, open) : NULL;
        out = out ? append(out, &len, &cap, "\n") : NULL;
        out = out ? append(out, &len, &cap, body) : NULL;
        out = out ? append(out, &len, &cap, close) : NULL;
        out = out ? append(out, &len, &cap, "\n") : NULL;
    }
    free(doc);
    return out;
}

static char *table_block(const lod_cand *c, size_t nc, const char *command, const lod_opts *o, double wall,
                         char skipped[][300], size_t nskip)
{
    size_t len = 0, cap = 0;
    char *s = NULL, line[4096];
    time_t now = time(NULL);
    char date[64];
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    snprintf(line, sizeof line,
             "Generated by `%s` on %s in %.0f s (data `%s`, split `%s`%s). Build and machine: `%s`.\n\n", command,
             date, wall, o->data, o->split, o->frames ? ", rollouts cut at --frames" : "", weft_config_string());
    s = append(s, &len, &cap, line);
    s = s ? append(s, &len, &cap,
                   "| level | method | precision | substeps | CCD | sequences | frames | ms/frame | MVE (cm) | "
                   "max edge strain | in lod.csv |\n|---|---|---|---|---|---|---|---|---|---|---|\n")
          : NULL;
    /* Cheapest first. */
    bool done[LOD_MAX_CANDS] = {false};
    for (size_t pass = 0; s && pass < nc; ++pass) {
        size_t best = nc;
        for (size_t k = 0; k < nc; ++k) {
            if (done[k]) {
                continue;
            }
            double mk = c[k].frames ? c[k].ms_w / c[k].frames : INFINITY;
            double mb = best < nc && c[best].frames ? c[best].ms_w / c[best].frames : INFINITY;
            if (best == nc || mk < mb) {
                best = k;
            }
        }
        done[best] = true;
        const lod_cand *k = &c[best];
        double w = k->frames ? (double)k->frames : NAN;
        char sub[16] = "-";
        if (k->substeps) {
            snprintf(sub, sizeof sub, "%u", k->substeps);
        }
        snprintf(line, sizeof line, "| %s | %s%s%s | %s | %s | %s | %u | %u | %.3f | %.3f | %.3f | %s |\n", k->name,
                 k->family, k->model_name[0] ? " " : "", k->model_name, k->precision[0] ? k->precision : "-", sub,
                 k->ccd ? "on" : "off", k->sequences, k->frames, k->ms_w / w, k->mve_w / w, k->strain,
                 cand_valid(k) ? "yes" : (k->nan_runs ? "no: NaN" : "no: failed"));
        s = append(s, &len, &cap, line);
    }
    for (size_t i = 0; s && i < nskip; ++i) {
        snprintf(line, sizeof line, "%s- not measured: %.299s\n", i == 0 ? "\n" : "", skipped[i]);
        s = append(s, &len, &cap, line);
    }
    for (size_t k = 0; s && k < nc; ++k) {
        if (!cand_valid(&c[k]) && c[k].note[0]) {
            snprintf(line, sizeof line, "- `%.47s` left out of lod.csv: %.239s\n", c[k].name, c[k].note);
            s = append(s, &len, &cap, line);
        }
    }
    return s ? append(s, &len, &cap, "\n") : NULL;
}

static char *scaling_block(const scale_row *r, size_t n, const char *desc, const lod_opts *o, const char *command)
{
    size_t len = 0, cap = 0;
    char *s = NULL, line[4096];
    snprintf(line, sizeof line,
             "Measured by `%s`: %s; median over %u timed frames after 4 untimed blend-in frames, one "
             "thread, CCD as in the level. *sequential*: `weft_lod_garment_step` per character; *batched*: one `weft_garments_step` "
             "call over all characters (model garments sharing a model and precision run the temporal "
             "transformer as one stacked GEMM per layer; other methods are stepped one by one inside it).\n\n",
             command, desc, o->scale_frames);
    s = append(s, &len, &cap, line);
    s = s ? append(s, &len, &cap,
                   "| level | stepping | ms/character at 1 | at 8 | at 64 | total ms/frame at 64 |\n"
                   "|---|---|---|---|---|---|\n")
          : NULL;
    for (size_t i = 0; s && i + 2 < n; i += 3) {
        snprintf(line, sizeof line, "| %.47s | %s | %.3f | %.3f | %.3f | %.1f |\n", r[i].level,
                 r[i].batched ? "batched" : "sequential", r[i].ms_per_char, r[i + 1].ms_per_char, r[i + 2].ms_per_char,
                 r[i + 2].ms_total);
        s = append(s, &len, &cap, line);
    }
    return s ? append(s, &len, &cap, "\n") : NULL;
}

/* Writes doc to path; false (with a message) on failure. Frees doc. */
static bool write_doc(const char *path, char *doc)
{
    FILE *f = doc ? fopen(path, "w") : NULL;
    bool wrote = f && fputs(doc, f) >= 0;
    if (f) {
        wrote = fclose(f) == 0 && wrote;
    }
    free(doc);
    if (!wrote) {
        fprintf(stderr, "weft bench lod: cannot write %s\n", path);
    } else {
        printf("wrote %s\n", path);
    }
    return wrote;
}

/* Part 2 alone, on the table already in OUT/lod.csv. */
static int scale_only(const lod_opts *o, const char *command)
{
    char csv[1200], md[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", o->out);
    snprintf(md, sizeof md, "%s/LOD.md", o->out);
    static scale_row rows[LOD_MAX_SCALE * 6];
    char desc[256] = "";
    size_t nr = run_scaling(o, csv, rows, sizeof rows / sizeof rows[0], desc, sizeof desc);
    if (nr == 0) {
        fprintf(stderr, "weft bench lod: nothing measured (is %s there? run without --scale-only first)\n", csv);
        return 1;
    }
    char *block = scaling_block(rows, nr, desc, o, command);
    char *doc = block ? replace_block(bench_slurp(md, NULL), "scaling", block) : NULL;
    free(block);
    return write_doc(md, doc) ? 0 : 1;
}

int weft_bench_lod(int argc, char **argv)
{
    lod_opts o = {.split = "test", .models = "tools/train/models", .out = "docs", .scale = true, .scale_frames = 4,
                  .scale_res = "1k"};
    char command[2048] = "weft bench lod";
    for (int i = 1; i < argc; ++i) {
        size_t cl = strlen(command);
        snprintf(command + cl, sizeof command - cl, " %s", argv[i]);
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--no-scale") == 0) {
            o.scale = false;
            continue;
        } else if (strcmp(a, "--scale-only") == 0) {
            o.scale_only = true;
            continue;
        } else if (!v) {
            fprintf(stderr, "weft bench lod: %s needs a value\n", a);
            usage(stderr);
            return 2;
        }
        if (strcmp(a, "--data") == 0) {
            o.data = v;
        } else if (strcmp(a, "--split") == 0) {
            o.split = v;
        } else if (strcmp(a, "--models") == 0) {
            o.models = v;
        } else if (strcmp(a, "--out") == 0) {
            o.out = v;
        } else if (strcmp(a, "--scale-levels") == 0) {
            o.scale_levels = v;
        } else if (strcmp(a, "--scale-res") == 0) {
            o.scale_res = v;
        } else if (strcmp(a, "--xpbd") == 0) {
            if ((o.nxpbd = bench_parse_substeps(v, o.xpbd, 8)) == 0) {
                fprintf(stderr, "weft bench lod: --xpbd wants substep counts like 5,10,20\n");
                return 2;
            }
        } else if (strcmp(a, "--frames") == 0 || strcmp(a, "--max-seqs") == 0 || strcmp(a, "--scale-frames") == 0) {
            char *end;
            unsigned long x = strtoul(v, &end, 10);
            if (*end || end == v || x > 1000000 || (a[2] == 's' && x == 0)) {
                fprintf(stderr, "weft bench lod: bad number '%s' for %s\n", v, a);
                return 2;
            }
            *(a[2] == 'f' ? &o.frames : a[2] == 'm' ? &o.max_seqs : &o.scale_frames) = (uint32_t)x;
        } else {
            fprintf(stderr, "weft bench lod: unknown option '%s'\n", a);
            usage(stderr);
            return 2;
        }
        cl = strlen(command);
        snprintf(command + cl, sizeof command - cl, " %s", v);
        ++i;
    }
    weft_cloth_resolution res_check;
    if (weft_cloth_resolution_from_name(o.scale_res, &res_check) != WEFT_OK) {
        fprintf(stderr, "weft bench lod: --scale-res must be 1k, 4k, 16k or 40k\n");
        return 2;
    }
    if (o.scale_only) {
        return scale_only(&o, command);
    }
    if (!o.data) {
        fprintf(stderr, "weft bench lod: --data is required\n");
        usage(stderr);
        return 2;
    }
    if (o.nxpbd == 0) {
        static const unsigned k_sub[] = {5, 10, 20};
        memcpy(o.xpbd, k_sub, sizeof k_sub);
        o.nxpbd = 3;
    }
    char exe[1024];
    bench_seq *seqs = NULL;
    size_t nseq = 0;
    if (!bench_start("lod", o.data, o.split, o.out, exe, sizeof exe, &seqs, &nseq)) {
        return 1;
    }
    if (o.max_seqs && nseq > o.max_seqs) {
        nseq = o.max_seqs;
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft bench lod: %s\n", weft_last_error());
        free(seqs);
        return 1;
    }
    static lod_cand cands[LOD_MAX_CANDS];
    static char skipped[16][300];
    size_t nskip = 0;
    size_t nc = build_candidates(ctx, &o, cands, skipped, &nskip);
    weft_context_destroy(ctx);

    double t0 = now_s();
    run_candidates(exe, &o, seqs, nseq, cands, nc);
    double wall = now_s() - t0;
    free(seqs);

    char csv[1200], md[1200];
    snprintf(csv, sizeof csv, "%s/lod.csv", o.out);
    snprintf(md, sizeof md, "%s/LOD.md", o.out);
    size_t valid = 0;
    for (size_t k = 0; k < nc; ++k) {
        valid += cand_valid(&cands[k]);
    }
    if (valid == 0) {
        fprintf(stderr, "weft bench lod: no level produced a valid measurement; %s not written\n", csv);
        return 1;
    }
    if (!write_csv(csv, cands, nc, command, &o)) {
        return 1;
    }
    printf("wrote %s (%zu levels)\n", csv, valid);

    char *doc = bench_slurp(md, NULL);
    char *block = table_block(cands, nc, command, &o, wall, skipped, nskip);
    doc = block ? replace_block(doc, "table", block) : NULL;
    free(block);
    if (o.scale && doc) {
        static scale_row rows[LOD_MAX_SCALE * 6];
        char desc[256] = "";
        size_t nr = run_scaling(&o, csv, rows, sizeof rows / sizeof rows[0], desc, sizeof desc);
        block = nr ? scaling_block(rows, nr, desc, &o, command) : NULL;
        doc = block ? replace_block(doc, "scaling", block) : doc;
        free(block);
    }
    return write_doc(md, doc) ? 0 : 1;
}
