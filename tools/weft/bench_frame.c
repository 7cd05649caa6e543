/* weft bench frame: what a worn garment costs a game per frame, split by stage.
 *
 * The default avatar wears the T-shirt with the worn-garment recipe of the render sample (body
 * parts, an 8 cm max distance, a 0.5 cm push, a 10 % strain limit and 1024 sampled collider
 * tokens for the learned model, no CCD), is settled from the bind pose into each motion over 30
 * frames, and is stepped --frames frames by each method at each resolution, one thread. A
 * resolution D@S simulates the garment at S and draws it at D through a weft_mesh_map (the render
 * sample's default for the learned model at 4k: 4k@1k). Per cell the medians of: posing the body
 * (the game's own skinning, listed for scale), the whole cloth step (with the map), and its parts
 * from weft_step_stats: the method, the constraint stage, CCD, and the map. Then the ratios that
 * matter for a game budget, each from medians of this one run: learned int8 over fast XPBD-10
 * (same resolution item; for D@S also against fast XPBD-10 stepping D itself when that item ran),
 * int8 over fp32 (whole step and network), the network's share, the slowest frame over the median.
 * Then the learned int8 step's largest GEMM (found by the calibration observer, timed alone)
 * against the int8 dot-product peak measured in the same run, the crowd, and a table of the
 * game-budget targets against these figures. A step that fails makes the bench exit non-zero and
 * write no table. */
#define _POSIX_C_SOURCE 200809L
#include "weft.h"
#include "weft/body.h"
#include "weft/lod.h"
#include "support_bench.h"
#include "support_cli.h"
#include "core/core.h"
#include "kernels/kernels_internal.h"
#include "kernels/qkernels.h"
#include "model/transformer.h"
#include "support_peaks.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char weft_bench_frame_help[] =
    "a worn garment's whole frame by stage (method, constraints, CCD) at 1k/4k: learned int8/fp16/fp32, fast XPBD, LBS";

#if WEFT_RENDER_HAVE_SAMPLE && WEFT_RENDER_HAVE_ASSETS
#include "weft_sample.h"

#define FR_SETTLE 30
#define FR_MAX 8
#define FR_MAX_RES 8
/* A cell whose body posing (the same work in every cell) has a median more than FR_SLOW times
 * the least posing median of the motion's cells ran through a slow spell of its core: it is
 * timed again, up to FR_RETIME times, and keeps the run with the fastest posing (the cloth is the
 * same: the step is deterministic). */
#define FR_SLOW 1.2
#define FR_RETIME 2

typedef struct fr_method {
    char label[40];
    weft_method method;
    weft_precision precision;
    uint32_t substeps;
} fr_method;

typedef struct fr_cell {
    double pose, step, method, constraints, ccd, map; /* medians, ms; step includes the map */
    double worst;                                     /* the slowest frame's whole step, ms */
} fr_cell;

/* The learned step's largest linear layer by multiply-accumulates per call, as run (the
 * calibration observer's row counts; layers constant for a garment are skipped, as the normal
 * step computes them once at creation). */
typedef struct fr_largest {
    char name[48];
    uint32_t M, K, N;
    uint32_t vertices; /* the simulated garment's */
} fr_largest;

static void observe_largest(const char *name, const float *in, uint32_t rows, uint32_t in_cols, const float *out,
                            uint32_t out_cols, void *user)
{
    (void)in;
    (void)out;
    fr_largest *l = user;
    if (!bench_ct_layer_per_step(name)) {
        return;
    }
    if ((double)rows * in_cols * out_cols > (double)l->M * l->K * l->N) {
        snprintf(l->name, sizeof l->name, "%s", name);
        l->M = rows;
        l->K = in_cols;
        l->N = out_cols;
    }
}

static bool parse_method(const char *item, size_t n, fr_method *m)
{
    char buf[32];
    if (n == 0 || n >= sizeof buf) {
        return false;
    }
    memcpy(buf, item, n);
    buf[n] = '\0';
    memset(m, 0, sizeof *m);
    snprintf(m->label, sizeof m->label, "%s", buf);
    if (!strcmp(buf, "lbs")) {
        m->method = WEFT_METHOD_LBS;
        return true;
    }
    static const char *const prec[] = {"fp32", "fp16", "int8"};
    for (int p = 0; p < 3; ++p) {
        char want[16];
        snprintf(want, sizeof want, "model:%s", prec[p]);
        if (!strcmp(buf, want)) {
            m->method = WEFT_METHOD_MODEL;
            m->precision = (weft_precision)p;
            snprintf(m->label, sizeof m->label, "learned %s", prec[p]);
            return true;
        }
    }
    const char *colon = strchr(buf, ':');
    if (colon && (!strncmp(buf, "xpbd-fast:", 10) || !strncmp(buf, "xpbd:", 5))) {
        m->method = !strncmp(buf, "xpbd-fast:", 10) ? WEFT_METHOD_XPBD_FAST : WEFT_METHOD_XPBD;
        return cli_u32("weft bench frame", "--methods", colon + 1, 1, 1000, &m->substeps);
    }
    return false;
}

static const char *shipped_model(weft_precision p)
{
    static const char *const path[] = {"tools/train/models/garment.safetensors",
                                       "tools/train/models/garment.fp16.safetensors",
                                       "tools/train/models/garment.int8.safetensors"};
    return path[p];
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, uint32_t n)
{
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The loaded model a method steps with (NULL for the classical methods). */
static weft_model *cell_model(const fr_method *m, weft_model *const *models)
{
    return m->method == WEFT_METHOD_MODEL ? models[m->precision] : NULL;
}

/* A resolution item: "D" (simulate and draw D) or "D@S" (simulate S, draw D through a mesh map). */
typedef struct fr_res {
    char name[16];                      /* as given: "4k", "4k@1k" */
    char garment[48];                   /* the table's garment column */
    weft_cloth_resolution drawn, simulated;
} fr_res;

static bool parse_resolution(const char *item, fr_res *r)
{
    char d[16];
    const char *at = strchr(item, '@');
    const size_t n = at ? (size_t)(at - item) : strlen(item);
    if (n == 0 || n >= sizeof d || strlen(item) >= sizeof r->name) {
        return false;
    }
    memcpy(d, item, n);
    d[n] = '\0';
    if (weft_cloth_resolution_from_name(d, &r->drawn) != WEFT_OK) {
        return false;
    }
    r->simulated = r->drawn;
    if (at && (weft_cloth_resolution_from_name(at + 1, &r->simulated) != WEFT_OK || r->simulated == r->drawn)) {
        return false;
    }
    snprintf(r->name, sizeof r->name, "%s", item);
    if (at) {
        snprintf(r->garment, sizeof r->garment, "T-shirt %s (%s simulated)", d, at + 1);
    } else {
        snprintf(r->garment, sizeof r->garment, "T-shirt %s", d);
    }
    return true;
}

/* One (motion, resolution, method) run. Returns 0, or 1 with the reason printed. */
static int run_cell(weft_context *ctx, weft_body *body, const weft_sample_motion *mo, const fr_res *res,
                    const fr_method *m, weft_model *model, uint32_t frames, uint32_t tokens, fr_cell *out,
                    fr_largest *largest)
{
    weft_cloth_def cdef = weft_default_cloth_def(WEFT_CLOTH_TSHIRT), ddef = cdef;
    cdef.resolution = res->simulated;
    ddef.resolution = res->drawn;
    const bool mapped = ddef.resolution != cdef.resolution;
    weft_cloth_mesh *cloth = NULL, *drawn = NULL;
    weft_mesh_map *map = NULL;
    if (weft_cloth_create(ctx, &cdef, body, &cloth) != WEFT_OK ||
        (mapped && weft_cloth_create(ctx, &ddef, body, &drawn) != WEFT_OK)) {
        fprintf(stderr, "weft bench frame: garment: %s\n", weft_last_error());
        weft_cloth_destroy(cloth);
        return 1;
    }
    if (mapped) {
        weft_mesh_map_def md = weft_default_mesh_map_def();
        md.from_rest_positions = cloth->positions;
        md.from_vertex_count = cloth->vertex_count;
        md.from_triangles = cloth->triangles;
        md.from_triangle_count = cloth->triangle_count;
        md.to_rest_positions = drawn->positions;
        md.to_vertex_count = drawn->vertex_count;
        if (weft_mesh_map_create(ctx, &md, &map) != WEFT_OK) {
            fprintf(stderr, "weft bench frame: mesh map %s: %s\n", res->name, weft_last_error());
            weft_cloth_destroy(drawn);
            weft_cloth_destroy(cloth);
            return 1;
        }
    }
    const uint32_t nbv = weft_body_vertex_count(body);
    uint8_t *parts = malloc(weft_body_triangle_count(body));
    float *bverts = malloc((size_t)nbv * 3 * sizeof(float));
    float *dverts = mapped ? malloc((size_t)drawn->vertex_count * 3 * sizeof(float)) : NULL;
    double *t[6];
    for (int k = 0; k < 6; ++k) {
        t[k] = calloc(frames, sizeof(double));
    }
    int rc = parts && bverts && (!mapped || dverts) && t[0] && t[1] && t[2] && t[3] && t[4] && t[5] ? 0 : 1;
    weft_garment *g = NULL;
    weft_garment_def d;
    if (rc == 0 && weft_sample_worn_def(body, cloth, m->method, parts, &d) != WEFT_OK) {
        rc = 1;
    }
    if (rc == 0) {
        d.model = model;
        d.precision = m->precision;
        d.max_collider_tokens = tokens; /* the recipe's sample cap, or the whole crop (0) */
        weft_sample_set_substeps(&d, m->substeps);
        if (weft_garment_create(ctx, &d, &g) != WEFT_OK ||
            (largest && weft__ct_set_observer(g, observe_largest, largest) != WEFT_OK)) {
            rc = 1;
        }
        if (largest) {
            largest->vertices = cloth->vertex_count;
        }
    }
    weft_pose bind, first, pose;
    weft_body_bind_pose(body, &bind);
    if (rc == 0 && weft_sample_motion_pose(mo, 0.0, &first) != WEFT_OK) {
        rc = 1;
    }
    for (uint32_t k = 0; rc == 0 && k < FR_SETTLE + frames; ++k) {
        if (k < FR_SETTLE) {
            weft_avatar_sample_settle_pose(&bind, &first, k, FR_SETTLE, &pose);
        } else if (weft_sample_motion_pose(mo, (double)(k - FR_SETTLE) / 60.0, &pose) != WEFT_OK) {
            rc = 1;
            break;
        }
        const double t0 = weft__now_ms();
        if (weft_body_pose(body, &pose, bverts, NULL) != WEFT_OK) {
            rc = 1;
            break;
        }
        const double t1 = weft__now_ms();
        if (weft_garment_set_collider(g, bverts) != WEFT_OK || weft_garment_step(g) != WEFT_OK) {
            rc = 1;
            break;
        }
        const double t2 = weft__now_ms();
        if (mapped && weft_mesh_map_apply(map, weft_garment_positions(g), dverts) != WEFT_OK) {
            rc = 1;
            break;
        }
        const double t3 = weft__now_ms();
        if (k >= FR_SETTLE) {
            const weft_step_stats st = weft_garment_stats(g);
            const uint32_t i = k - FR_SETTLE;
            t[0][i] = t1 - t0;
            t[1][i] = st.step_ms + (t3 - t2);
            t[2][i] = st.method_ms;
            t[3][i] = st.constraints_ms;
            t[4][i] = st.ccd_ms;
            t[5][i] = t3 - t2;
        }
    }
    if (rc != 0) {
        fprintf(stderr, "weft bench frame: %s at %s: %s\n", m->label, res->name, weft_last_error());
    } else {
        out->worst = 0.0;
        for (uint32_t i = 0; i < frames; ++i) {
            out->worst = t[1][i] > out->worst ? t[1][i] : out->worst;
        }
        out->pose = median(t[0], frames);
        out->step = median(t[1], frames);
        out->method = median(t[2], frames);
        out->constraints = median(t[3], frames);
        out->ccd = median(t[4], frames);
        out->map = median(t[5], frames);
    }
    weft_garment_destroy(g);
    for (int k = 0; k < 6; ++k) {
        free(t[k]);
    }
    free(parts);
    free(bverts);
    free(dverts);
    weft_mesh_map_destroy(map);
    weft_cloth_destroy(drawn);
    weft_cloth_destroy(cloth);
    return rc;
}

/* ---- Crowds: instances of one garment asset ------------------------------------------------ */

/* Live bytes through the crowd context's allocator. */
static size_t g_crowd_live;

static void *crowd_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    void *p = NULL;
    if (posix_memalign(&p, alignment < sizeof(void *) ? sizeof(void *) : alignment, size ? size : 1) != 0) {
        return NULL;
    }
    g_crowd_live += size;
    return p;
}

static void crowd_free(void *p, size_t size, void *user)
{
    (void)user;
    if (p) {
        g_crowd_live -= size;
        free(p);
    }
}

typedef struct fr_crowd {
    double ms_per_character;            /* median over frames of (all characters' steps) / n */
    double first_mb, extra_mb, own_mb;  /* asset + first instance, each further one, a garment of its own */
} fr_crowd;

/* n characters wearing instances of one asset of the learned int8 T-shirt at 1k, each on the
 * motion shifted by 0.137 s per character, settled over FR_SETTLE frames, then `frames` frames of
 * weft_garments_step over all of them (posing excluded). Returns 0, or 1 with the reason printed. */
static int run_crowd(weft_body *body, const weft_sample_motion *mo, uint32_t n, uint32_t frames, uint32_t tokens,
                     fr_crowd *out)
{
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = crowd_alloc;
    cd.allocator.free = crowd_free;
    weft_context *ctx = NULL;
    weft_model *model = NULL;
    weft_cloth_mesh *cloth = NULL;
    weft_garment_asset *asset = NULL;
    weft_garment **gs = calloc(n, sizeof *gs);
    const uint32_t nbv = weft_body_vertex_count(body);
    float *verts = malloc((size_t)n * nbv * 3 * sizeof(float));
    uint8_t *parts = malloc(weft_body_triangle_count(body));
    double *ms = calloc(frames, sizeof(double));
    weft_cloth_def cdef = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    cdef.resolution = WEFT_CLOTH_RES_1K;
    weft_garment_def d;
    int rc = gs && verts && parts && ms ? 0 : 1;
    if (rc == 0 && (weft_context_create(&cd, &ctx) != WEFT_OK ||
                    weft_model_load_file_as(ctx, shipped_model(WEFT_PRECISION_INT8), "clothtransformer", &model) != WEFT_OK ||
                    weft_cloth_create(ctx, &cdef, body, &cloth) != WEFT_OK ||
                    weft_sample_worn_def(body, cloth, WEFT_METHOD_MODEL, parts, &d) != WEFT_OK)) {
        rc = 1;
    }
    if (rc == 0) {
        d.model = model;
        d.precision = WEFT_PRECISION_INT8;
        d.max_collider_tokens = tokens;
        weft_garment *own = NULL;
        const size_t b0 = g_crowd_live;
        rc = weft_garment_create(ctx, &d, &own) == WEFT_OK ? 0 : 1;
        out->own_mb = (double)(g_crowd_live - b0) / 1e6;
        weft_garment_destroy(own);
    }
    const size_t before = g_crowd_live;
    if (rc == 0 && weft_garment_asset_create(ctx, &d, &asset) != WEFT_OK) {
        rc = 1;
    }
    for (uint32_t c = 0; rc == 0 && c < n; ++c) {
        rc = weft_garment_asset_instance(asset, &gs[c]) == WEFT_OK ? 0 : 1;
        if (c == 0) {
            out->first_mb = (double)(g_crowd_live - before) / 1e6;
        }
    }
    out->extra_mb = n > 1 ? (double)(g_crowd_live - before) / 1e6 - out->first_mb : 0.0;
    out->extra_mb /= n > 1 ? (double)(n - 1) : 1.0;
    weft_pose bind, first, pose;
    weft_body_bind_pose(body, &bind);
    for (uint32_t k = 0; rc == 0 && k < FR_SETTLE + frames; ++k) {
        for (uint32_t c = 0; rc == 0 && c < n; ++c) {
            const double phase = 0.137 * c;
            if (weft_sample_motion_pose(mo, phase, &first) != WEFT_OK) {
                rc = 1;
            } else if (k < FR_SETTLE) {
                weft_avatar_sample_settle_pose(&bind, &first, k, FR_SETTLE, &pose);
            } else if (weft_sample_motion_pose(mo, phase + (double)(k - FR_SETTLE) / 60.0, &pose) != WEFT_OK) {
                rc = 1;
            }
            float *v = verts + (size_t)c * nbv * 3;
            if (rc == 0 && (weft_body_pose(body, &pose, v, NULL) != WEFT_OK || weft_garment_set_collider(gs[c], v) != WEFT_OK)) {
                rc = 1;
            }
        }
        const double t0 = weft__now_ms();
        if (rc == 0 && weft_garments_step(gs, n) != WEFT_OK) {
            rc = 1;
        }
        if (rc == 0 && k >= FR_SETTLE) {
            ms[k - FR_SETTLE] = (weft__now_ms() - t0) / (double)n;
        }
    }
    if (rc != 0) {
        fprintf(stderr, "weft bench frame: crowd of %u: %s\n", n, weft_last_error());
    } else {
        out->ms_per_character = median(ms, frames);
    }
    for (uint32_t c = 0; gs && c < n; ++c) {
        weft_garment_destroy(gs[c]);
    }
    weft_garment_asset_destroy(asset);
    weft_cloth_destroy(cloth);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    free(gs);
    free(verts);
    free(parts);
    free(ms);
    return rc;
}

/* The smallest and largest of a set of ratios (n == 0: none measured). */
typedef struct fr_span {
    double lo, hi;
    uint32_t n;
} fr_span;

static void span_add(fr_span *s, double v)
{
    s->lo = s->n == 0 || v < s->lo ? v : s->lo;
    s->hi = s->n == 0 || v > s->hi ? v : s->hi;
    s->n++;
}

/* "a-b" (or "a" when equal) with `digits` decimals; "not run" when empty. */
static const char *span_text(const fr_span *s, int digits, char *buf, size_t cap)
{
    char lo[32], hi[32];
    if (s->n == 0) {
        snprintf(buf, cap, "not run");
        return buf;
    }
    snprintf(lo, sizeof lo, "%.*f", digits, s->lo);
    snprintf(hi, sizeof hi, "%.*f", digits, s->hi);
    if (strcmp(lo, hi) == 0) {
        snprintf(buf, cap, "%s", lo);
    } else {
        snprintf(buf, cap, "%s-%s", lo, hi);
    }
    return buf;
}

typedef struct fr_summary {
    fr_span native4k, mapped_vs_drawn, mapped_vs_same, net_speedup, worst_real, gemm_peak;
} fr_summary;

/* The list item `name` of a comma-separated list, copied into buf; false past the end. */
static bool list_item(const char *list, uint32_t index, char *buf, size_t cap)
{
    const char *p = list;
    for (uint32_t i = 0; i < index; ++i) {
        p = strchr(p, ',');
        if (!p) {
            return false;
        }
        ++p;
    }
    const size_t n = strcspn(p, ",");
    if (n == 0 || n >= cap) {
        return false;
    }
    memcpy(buf, p, n);
    buf[n] = '\0';
    return true;
}

enum { OPT_MOTIONS = 1, OPT_RESOLUTIONS, OPT_METHODS, OPT_FRAMES, OPT_CROWD, OPT_TOKENS, OPT_MD };

static const cli_option k_options[] = {
    {"motions", "walk,mocap:CLIP,...", OPT_MOTIONS,
     "the motions, comma-separated (default: the procedural walk and the mocap\n"
     "clip walk_cmu07_01)"},
    {"resolutions", "R,D@S,...", OPT_RESOLUTIONS,
     "the T-shirt's resolutions, comma-separated, at most 8: R (1k, 4k, 16k,\n"
     "40k) steps that mesh; D@S steps S and draws D through a mesh map, as\n"
     "the render sample draws a learned 4k garment (default 1k,4k,4k@1k)"},
    {"methods", "M,...", OPT_METHODS,
     "at most 8 of model:int8|fp16|fp32 (the shipped garment model at that\n"
     "precision), xpbd-fast:S, xpbd:S (S substeps, 1..1000), lbs (default\n"
     "model:int8,model:fp16,model:fp32,xpbd-fast:5,xpbd-fast:10,lbs)"},
    {"frames", "N", OPT_FRAMES, "measured frames after a 30-frame settle, 1..100000 (default 60)"},
    {"crowd", "N", OPT_CROWD,
     "also N characters wearing instances of one garment asset (learned int8, T-shirt 1k,\nfirst motion) against "
     "one: ms and memory per character; 0 = off,\n2..1024 (default 64)"},
    {"collider-tokens", "N", OPT_TOKENS,
     "the learned model's collider tokens: an even, weighted sample of its crop\n"
     "of at most N, 0..1000000 (0: the whole crop; default 1024, the recipe's)"},
    {"md", "FILE", OPT_MD, "write the table into FILE between <!-- frame-table --> markers\n(docs/MODEL_BENCH.md)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench frame",
    .synopsis = "weft bench frame [--motions walk,mocap:CLIP,...] [--resolutions 1k,4k,4k@1k]\n"
                "                 [--methods model:int8,model:fp16,model:fp32,xpbd-fast:5,xpbd-fast:10,lbs]\n"
                "                 [--frames N] [--crowd N] [--collider-tokens N] [--md FILE]",
    .about = "What a worn garment costs a game per frame, split by stage: the default avatar wears the T-shirt\n"
             "(the render sample's worn-garment recipe), settles into each motion over 30 frames and is\n"
             "stepped --frames frames by each method at each resolution, one thread. Per cell the medians\n"
             "of posing the body, the whole cloth step, the method, the constraint stage, CCD and the mesh\n"
             "map (D@S); then the ratios learned int8 / fast XPBD-10 (for D@S also against fast XPBD-10\n"
             "stepping D), int8 / fp32, the network's int8 speed-up and share, the worst frame over the\n"
             "median; the int8 step's largest GEMM alone against the int8 peak measured in the same run;\n"
             "the crowd; and the game-budget targets against this run's figures.\n"
             "Run from the repository root (the shipped models are read from tools/train/models).",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_frame(int argc, char **argv)
{
    const char *motions = "walk,mocap:walk_cmu07_01", *resolutions = "1k,4k,4k@1k", *md = NULL;
    const char *methods_text = "model:int8,model:fp16,model:fp32,xpbd-fast:5,xpbd-fast:10,lbs";
    uint32_t frames = 60, crowd = 64, tokens = WEFT_WORN_COLLIDER_TOKENS;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_MOTIONS:
            motions = v;
            break;
        case OPT_RESOLUTIONS:
            resolutions = v;
            break;
        case OPT_METHODS:
            methods_text = v;
            break;
        case OPT_MD:
            md = v;
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 1, 100000, &frames)) {
                return 2;
            }
            break;
        case OPT_TOKENS:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 0, 1000000, &tokens)) {
                return 2;
            }
            break;
        case OPT_CROWD:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 0, 1024, &crowd)) {
                return 2;
            }
            if (crowd == 1) {
                return cli_fail(&k_command, "--crowd 1: a crowd is 2..1024 characters (0: off)");
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    fr_method methods[FR_MAX];
    uint32_t nm = 0;
    char item[64];
    for (uint32_t k = 0; list_item(methods_text, k, item, sizeof item); ++k) {
        if (nm == FR_MAX || !parse_method(item, strlen(item), &methods[nm])) {
            fprintf(stderr, "weft bench frame: bad method '%s' (model:int8|fp16|fp32, xpbd-fast:S, xpbd:S, lbs; at "
                            "most %d)\n", item, FR_MAX);
            return 2;
        }
        ++nm;
    }
    if (nm == 0) {
        fprintf(stderr, "weft bench frame: --methods is empty\n");
        return 2;
    }
    fr_res res[FR_MAX_RES];
    uint32_t nres = 0;
    for (uint32_t k = 0; list_item(resolutions, k, item, sizeof item); ++k) {
        if (nres == FR_MAX_RES || !parse_resolution(item, &res[nres])) {
            fprintf(stderr, "weft bench frame: --resolutions: %s is not R or R@S (R, S: 1k, 4k, 16k, 40k; S not R; "
                            "at most %d items)\n", item, FR_MAX_RES);
            return 2;
        }
        ++nres;
    }
    if (nres == 0) {
        fprintf(stderr, "weft bench frame: --resolutions is empty\n");
        return 2;
    }
    /* the columns of the ratios: learned int8 and fp32, fast XPBD-10 (-1 where not run) */
    int i8 = -1, f32 = -1, x10 = -1;
    for (uint32_t k = 0; k < nm; ++k) {
        if (methods[k].method == WEFT_METHOD_MODEL && methods[k].precision == WEFT_PRECISION_INT8) {
            i8 = (int)k;
        } else if (methods[k].method == WEFT_METHOD_MODEL && methods[k].precision == WEFT_PRECISION_FP32) {
            f32 = (int)k;
        } else if (methods[k].method == WEFT_METHOD_XPBD_FAST && methods[k].substeps == 10) {
            x10 = (int)k;
        }
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_body *body = NULL;
    weft_avatar_def ad = weft_default_avatar_def();
    if (weft_context_create(&cd, &ctx) != WEFT_OK || weft_avatar_create(ctx, &ad, &body) != WEFT_OK) {
        fprintf(stderr, "weft bench frame: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    weft_model *models[WEFT_PRECISION_COUNT] = {NULL, NULL, NULL};
    fr_summary sum;
    memset(&sum, 0, sizeof sum);
    /* the int8 dot-product and fp32 FMA peaks of this CPU: measured after the cells, so the probes
     * do not slow the first cell, before and after the GEMM probes, keeping the higher (a slow
     * spell must not flatter the GEMMs' share) */
    const weft_isa isa = weft_context_isa(ctx);
    const weft_qkernels *qk = weft_qkernels_for_isa(isa);
    const weft_kernels *kt = weft_kernels_for_isa(isa);
    peak_fn *dot = NULL, *fma = weft__peak_fma_scalar;
    if (qk) {
        bench_variant_peaks(qk->variant, &dot, &fma);
    }
    double dot_peak = NAN, fma_peak = NAN;
    int rc = 0;
    for (uint32_t k = 0; rc == 0 && k < nm; ++k) {
        const weft_precision p = methods[k].precision;
        if (methods[k].method == WEFT_METHOD_MODEL && !models[p] &&
            weft_model_load_file_as(ctx, shipped_model(p), "clothtransformer", &models[p]) != WEFT_OK) {
            fprintf(stderr, "weft bench frame: %s: %s (run from the repository root)\n", shipped_model(p),
                    weft_last_error());
            rc = 1;
        }
    }
    char *table = NULL;
    size_t len = 0, cap = 0;
    char line[1024];
    snprintf(line, sizeof line,
             "`weft bench frame --motions %s --resolutions %s --methods %s --frames %u --crowd %u --collider-tokens %u` "
             "(%s; one thread; medians of %u frames; ms)\n\n"
             "| motion | garment | method | body posing | whole cloth step | method | constraints | CCD | mesh map |\n"
             "|---|---|---|---:|---:|---:|---:|---:|---:|\n",
             motions, resolutions, methods_text, frames, crowd, tokens, weft_config_string(), frames);
    table = rc == 0 ? bench_append(table, &len, &cap, line) : NULL;
    char ratios[4096] = "";
    char motion_spec[128];
    double pose_min = INFINITY; /* ms: the least posing median of the cells so far */
    uint32_t retimed = 0;       /* cells timed again for a slow spell */
    for (uint32_t mi = 0; rc == 0 && table && list_item(motions, mi, motion_spec, sizeof motion_spec); ++mi) {
        weft_sample_motion mo;
        if (weft_sample_motion_load(ctx, body, motion_spec, 1.0f, false, &mo) != WEFT_OK) {
            fprintf(stderr, "weft bench frame: motion %s: %s\n", motion_spec, weft_last_error());
            rc = 1;
            break;
        }
        fr_cell all[FR_MAX_RES][FR_MAX];
        for (uint32_t ri = 0; rc == 0 && ri < nres; ++ri) {
            for (uint32_t k = 0; rc == 0 && k < nm; ++k) {
                rc = run_cell(ctx, body, &mo, &res[ri], &methods[k], cell_model(&methods[k], models), frames, tokens,
                              &all[ri][k], NULL);
                pose_min = rc == 0 && all[ri][k].pose < pose_min ? all[ri][k].pose : pose_min;
            }
        }
        /* slow spells: the cells that posed slower than the run's fastest are timed again */
        for (uint32_t ri = 0; rc == 0 && ri < nres; ++ri) {
            for (uint32_t k = 0; rc == 0 && k < nm; ++k) {
                fr_cell *c = &all[ri][k];
                for (uint32_t again = 0; rc == 0 && again < FR_RETIME && c->pose > FR_SLOW * pose_min; ++again) {
                    fr_cell c2;
                    rc = run_cell(ctx, body, &mo, &res[ri], &methods[k], cell_model(&methods[k], models), frames,
                                  tokens, &c2, NULL);
                    retimed += again == 0;
                    if (rc == 0 && c2.pose < c->pose) {
                        *c = c2;
                    }
                }
            }
        }
        for (uint32_t ri = 0; rc == 0 && ri < nres; ++ri) {
            const fr_cell *cells = all[ri];
            for (uint32_t k = 0; rc == 0 && k < nm; ++k) {
                snprintf(line, sizeof line, "| %s | %s | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f |\n", motion_spec,
                         res[ri].garment, methods[k].label, cells[k].pose, cells[k].step, cells[k].method, cells[k].constraints,
                         cells[k].ccd, cells[k].map);
                fputs(line, stdout);
                fflush(stdout);
                table = bench_append(table, &len, &cap, line);
                rc = table ? 0 : 1;
            }
        }
        /* a library clip or a BVH file: real motion, where the worst-frame target applies */
        const bool real = strncmp(motion_spec, "mocap:", 6) == 0 || strncmp(motion_spec, "bvh:", 4) == 0;
        for (uint32_t ri = 0; rc == 0 && ri < nres; ++ri) {
            /* ratios of medians of this run, where both sides were measured */
            const fr_cell *cells = all[ri];
            /* D@S: also against fast XPBD-10 stepping D itself, when that item ran */
            double x10_drawn = 0.0;
            for (uint32_t rj = 0; res[ri].simulated != res[ri].drawn && rj < nres && x10 >= 0; ++rj) {
                if (res[rj].simulated == res[rj].drawn && res[rj].drawn == res[ri].drawn) {
                    x10_drawn = all[rj][x10].step;
                }
            }
            char r[512];
            int w = snprintf(r, sizeof r, "| %s | T-shirt %s |", motion_spec, res[ri].name);
            w += snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 && x10 >= 0 ? " %.2f (target <= 0.05) |" : " - |",
                          i8 >= 0 && x10 >= 0 ? cells[i8].step / cells[x10].step : 0.0);
            w += snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 && x10_drawn > 0.0 ? " %.3f |" : " - |",
                          i8 >= 0 && x10_drawn > 0.0 ? cells[i8].step / x10_drawn : 0.0);
            w += snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 && f32 >= 0 ? " %.2f |" : " - |",
                          i8 >= 0 && f32 >= 0 ? cells[i8].step / cells[f32].step : 0.0);
            w += snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 && f32 >= 0 ? " %.2f (target >= 3) |" : " - |",
                          i8 >= 0 && f32 >= 0 ? cells[f32].method / cells[i8].method : 0.0);
            w += snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 ? " %.0f %% |" : " - |",
                          i8 >= 0 && cells[i8].step > 0.0 ? 100.0 * cells[i8].method / cells[i8].step : 0.0);
            snprintf(r + w, sizeof r - (size_t)w, i8 >= 0 ? " %.2f%s |\n" : " - |\n",
                     i8 >= 0 ? cells[i8].worst / cells[i8].step : 0.0, real ? " (target <= 2)" : "");
            strncat(ratios, r, sizeof ratios - strlen(ratios) - 1);
            /* the targets' summary: extremes over motions and items */
            if (i8 >= 0 && x10 >= 0 && res[ri].drawn == res[ri].simulated && res[ri].drawn == WEFT_CLOTH_RES_4K) {
                span_add(&sum.native4k, cells[i8].step / cells[x10].step);
            }
            if (i8 >= 0 && res[ri].drawn == WEFT_CLOTH_RES_4K && res[ri].simulated != res[ri].drawn) {
                if (x10_drawn > 0.0) {
                    span_add(&sum.mapped_vs_drawn, cells[i8].step / x10_drawn);
                }
                if (x10 >= 0) {
                    span_add(&sum.mapped_vs_same, cells[i8].step / cells[x10].step);
                }
            }
            if (i8 >= 0 && f32 >= 0) {
                span_add(&sum.net_speedup, cells[f32].method / cells[i8].method);
            }
            if (i8 >= 0 && real) {
                span_add(&sum.worst_real, cells[i8].worst / cells[i8].step);
            }
        }
        weft_sample_motion_free(&mo);
    }
    if (rc == 0 && table) {
        snprintf(line, sizeof line,
                 "\nBody posing, the same work in every cell, had a least median of %.3f ms; %u cell%s posed more "
                 "than %.1f times slower (a slow spell of the core) and %s timed again, up to %d times, keeping "
                 "the fastest posing (the cloth is the same).\n",
                 pose_min, retimed, retimed == 1 ? "" : "s", FR_SLOW, retimed == 1 ? "was" : "were", FR_RETIME);
        table = bench_append(table, &len, &cap, line);
        fputs(line, stdout);
        table = table ? bench_append(table, &len, &cap,
                             "\n| motion | garment | learned int8 / fast XPBD-10 (whole step) | ... / fast XPBD-10 "
                             "stepping the drawn mesh | int8 / fp32 (whole step) | network speed-up int8 over fp32 | "
                             "network share of the int8 step | worst / median frame, learned int8 |\n"
                             "|---|---|---:|---:|---:|---:|---:|---:|\n") : NULL;
        table = table ? bench_append(table, &len, &cap, ratios) : NULL;
        rc = table ? 0 : 1;
        if (table) {
            printf("\n%s", strstr(table, "| motion | garment | learned int8 /"));
        }
    }
    if (rc == 0 && table && i8 >= 0 && dot && qk && kt) {
        /* the learned int8 step's largest GEMM at each simulated resolution, on the first motion,
         * alone against the peaks */
        weft_sample_motion mo;
        const bool loaded = list_item(motions, 0, motion_spec, sizeof motion_spec) &&
                            weft_sample_motion_load(ctx, body, motion_spec, 1.0f, false, &mo) == WEFT_OK;
        if (!loaded) {
            fprintf(stderr, "weft bench frame: motion %s: %s\n", motion_spec, weft_last_error());
            rc = 1;
        }
        if (rc == 0) {
            dot_peak = bench_peak_rate(dot, 0.2) * 1e-9;
            fma_peak = bench_peak_rate(fma, 0.2) * 1e-9;
        }
        fr_largest big[FR_MAX_RES];
        bench_gemm_probe probe[FR_MAX_RES];
        uint32_t nbig = 0;
        for (uint32_t ri = 0; rc == 0 && ri < nres; ++ri) {
            bool seen = false;
            for (uint32_t rj = 0; rj < ri; ++rj) {
                seen = seen || res[rj].simulated == res[ri].simulated;
            }
            if (seen) {
                continue;
            }
            fr_cell unused;
            memset(&big[nbig], 0, sizeof big[nbig]);
            rc = run_cell(ctx, body, &mo, &res[ri], &methods[i8], models[WEFT_PRECISION_INT8], 5, tokens, &unused,
                          &big[nbig]);
            if (rc == 0) {
                probe[nbig] = bench_probe_gemm(qk, kt, big[nbig].M, big[nbig].N, big[nbig].K, 0.2);
                if (isnan(probe[nbig].i8_gmacs)) {
                    fprintf(stderr, "weft bench frame: timing %s alone: out of memory\n", big[nbig].name);
                    rc = 1;
                }
                ++nbig;
            }
        }
        if (loaded) {
            weft_sample_motion_free(&mo);
        }
        if (rc == 0) {
            dot_peak = fmax(dot_peak, bench_peak_rate(dot, 0.2) * 1e-9);
            fma_peak = fmax(fma_peak, bench_peak_rate(fma, 0.2) * 1e-9);
            snprintf(line, sizeof line,
                     "\nThe learned int8 step's largest GEMM (rows x in -> out as run on %s, with its per-row "
                     "quantisation, no activation) alone, against this run's peaks; then `gemm_q8` without "
                     "the quantisation, and the quantisation's share of the two timed apart: int8 dot product %.1f GMAC/s "
                     "(%s), fp32 FMA %.1f GMAC/s.\n\n"
                     "| simulated | layer | shape | int8 GMAC/s | of the int8 peak | `gemm_q8` alone, of the peak | "
                     "quantisation's share | fp32 GMAC/s | of the fp32 peak |\n"
                     "|---|---|---|---:|---:|---:|---:|---:|---:|\n",
                     motion_spec, dot_peak, qk->variant, fma_peak);
            table = bench_append(table, &len, &cap, line);
            for (uint32_t b = 0; table && b < nbig; ++b) {
                snprintf(line, sizeof line, "| %u vertices | `%s` | %u x %u -> %u | %.1f | %.0f %% (target >= 50 %%) | "
                         "%.0f %% | %.0f %% | %.1f | %.0f %% |\n", big[b].vertices, big[b].name, big[b].M, big[b].K, big[b].N,
                         probe[b].i8_gmacs, 100.0 * probe[b].i8_gmacs / dot_peak, 100.0 * probe[b].dot_gmacs / dot_peak,
                         100.0 * probe[b].quantize_share, probe[b].f32_gmacs, 100.0 * probe[b].f32_gmacs / fma_peak);
                span_add(&sum.gemm_peak, 100.0 * probe[b].i8_gmacs / dot_peak);
                table = bench_append(table, &len, &cap, line);
            }
            rc = table ? 0 : 1;
            if (table) {
                printf("%s", strstr(table, "\nThe learned int8 step's largest GEMM"));
            }
        }
    }
    fr_span crowd_time = {0, 0, 0}, crowd_memory = {0, 0, 0};
    if (rc == 0 && table && crowd > 0) {
        /* the crowd on the first motion: one character, then `crowd`, the same code path */
        weft_sample_motion mo;
        fr_crowd one, many;
        if (!list_item(motions, 0, motion_spec, sizeof motion_spec) ||
            weft_sample_motion_load(ctx, body, motion_spec, 1.0f, false, &mo) != WEFT_OK) {
            fprintf(stderr, "weft bench frame: crowd motion: %s\n", weft_last_error());
            rc = 1;
        } else {
            rc = run_crowd(body, &mo, 1, frames, tokens, &one);
            rc = rc == 0 ? run_crowd(body, &mo, crowd, frames, tokens, &many) : rc;
            weft_sample_motion_free(&mo);
        }
        if (rc == 0) {
            snprintf(line, sizeof line,
                     "\nCrowd on %s: characters wearing instances of one garment asset (learned int8, T-shirt 1k, "
                     "each character 0.137 s further into the motion), stepped by `weft_garments_step`; ms per "
                     "character are medians over frames of the call's time / characters.\n\n"
                     "| characters | ms per character | vs one character | asset + first instance MB | each "
                     "further instance MB | further / first | a garment of its own MB |\n"
                     "|---:|---:|---:|---:|---:|---:|---:|\n"
                     "| 1 | %.2f | 1.00 | %.2f | - | - | %.2f |\n"
                     "| %u | %.2f | %.2f (target <= 1.1) | %.2f | %.3f | %.1f %% (target <= 10 %%) | %.2f |\n",
                     motion_spec, one.ms_per_character, one.first_mb, one.own_mb, crowd, many.ms_per_character,
                     many.ms_per_character / one.ms_per_character, many.first_mb, many.extra_mb,
                     100.0 * many.extra_mb / many.first_mb, many.own_mb);
            fputs(line, stdout);
            table = bench_append(table, &len, &cap, line);
            rc = table ? 0 : 1;
            span_add(&crowd_time, many.ms_per_character / one.ms_per_character);
            span_add(&crowd_memory, 100.0 * many.extra_mb / many.first_mb);
        }
    }
    if (rc == 0 && table) {
        /* the targets against this run's figures */
        char buf[64];
        const struct {
            const char *what;
            const fr_span *v;
            int digits;
            double target;
            bool at_least;
        } rows[] = {
            {"worn 4k T-shirt, learned int8 whole step / fast XPBD-10, both stepping the 4k mesh", &sum.native4k, 3,
             0.05, false},
            {"4k T-shirt simulated at 1k (the render sample), learned int8 / fast XPBD-10 stepping the 4k mesh",
             &sum.mapped_vs_drawn, 3, 0.05, false},
            {"4k T-shirt simulated at 1k, learned int8 / fast XPBD-10 stepping the same 1k mesh", &sum.mapped_vs_same,
             3, 0.05, false},
            {"network, int8 speed-up over fp32", &sum.net_speedup, 2, 3.0, true},
            {"largest GEMM of the int8 step, % of the int8 peak", &sum.gemm_peak, 0, 50.0, true},
            {"crowd, ms per character / one character's", &crowd_time, 2, 1.1, false},
            {"each further instance's memory, % of the first", &crowd_memory, 1, 10.0, false},
            {"worst frame / median on real motion, learned int8", &sum.worst_real, 2, 2.0, false},
        };
        table = bench_append(table, &len, &cap,
                             "\nTargets (ranges over the motions and items of this run):\n\n"
                             "| target | measured | bound | met |\n|---|---:|---:|---|\n");
        for (size_t k = 0; table && k < sizeof rows / sizeof rows[0]; ++k) {
            const fr_span *sp = rows[k].v;
            const char *met = sp->n == 0 ? "not run"
                              : rows[k].at_least ? (sp->lo >= rows[k].target ? "yes" : "no")
                                                 : (sp->hi <= rows[k].target ? "yes" : "no");
            snprintf(line, sizeof line, "| %s | %s | %s %g | %s |\n", rows[k].what,
                     span_text(sp, rows[k].digits, buf, sizeof buf), rows[k].at_least ? ">=" : "<=", rows[k].target, met);
            table = bench_append(table, &len, &cap, line);
        }
        rc = table ? 0 : 1;
        if (table) {
            printf("%s", strstr(table, "\nTargets ("));
        }
    }
    if (rc == 0 && md) {
        size_t dsize = 0;
        char *doc = bench_slurp(md, &dsize);
        doc = bench_replace_block(doc, "frame-table", table, "# The frame");
        rc = bench_write_doc("frame", md, doc) ? 0 : 1;
    }
    free(table);
    for (int p = 0; p < WEFT_PRECISION_COUNT; ++p) {
        weft_model_destroy(models[p]);
    }
    weft_body_destroy(body);
    weft_context_destroy(ctx);
    return rc;
}

#else

int weft_bench_frame(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    fprintf(stderr, "weft bench frame: this build has no avatar, wardrobe and BVH import (weft_render, weft_assets)\n");
    return 1;
}

#endif
