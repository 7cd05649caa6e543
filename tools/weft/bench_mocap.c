/* weft bench mocap: garments on real motion capture, per method, clip and garment.
 *
 * Every clip of the mocap library's split (samples/mocap/clips.csv; test by default) drives the
 * default avatar through the BVH retargeting; a garment (T-shirt, dress, skirt) is put on in the
 * bind pose, settled into the clip's first pose over 30 frames as the render sample does, and
 * stepped for --frames frames by each method. There is no ground truth here: the table says
 * whether the garment stays on (off_body, wear.h), how much of it is inside the body, how much
 * the body overlaps itself, and what a frame costs (p50, p99, max, max / p50), measured in one
 * run on one thread. A method whose step fails is printed as failed in its row, and the bench
 * then exits non-zero without writing --md; so does a clip that cannot be loaded, a garment
 * that cannot be made, or a write that fails. */
#define _POSIX_C_SOURCE 200809L
#include "weft.h"
#include "weft/body.h"
#include "support_bench.h"
#include "support_cli.h"
#include "core/core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char weft_bench_mocap_help[] = "garments on the mocap library's clips: garments lost, inside the body, ms p50/p99/max";

#if WEFT_RENDER_HAVE_SAMPLE && WEFT_RENDER_HAVE_ASSETS
#include "bvh.h"
#include "weft/clip_place.h"
#include "weft/wear.h"
#include "weft_sample.h"

#define MC_MAX_CLIPS 128
#define MC_MAX_METHODS 8
#define MC_SETTLE 30 /* default settle frames */
#define MC_CHAIN_BLEND 30 /* frames blending one clip of a --chain into the next */

typedef struct mc_options {
    const char *split, *clips, *garments, *methods, *model, *md, *block, *resolution, *csv;
    const char *fnopt_model;    /* the cape's FNOpt weights (NULL: the render sample's default) */
    uint32_t frames, settle, tokens;
    uint32_t chain;   /* --chain N: the clips back to back as one motion of N frames (0: one row per clip) */
    uint32_t retime;  /* timing runs again for a cell whose worst frame passes retime_over x its median */
    float retime_over;
    bool ccd;
    int parts; /* 1 on, 0 off, -1 auto (weft_sample_parts_on) */
    float tether_cm, push_cm, push_depth_cm, strain_pct;
} mc_options;

typedef struct mc_method {
    char label[32];
    weft_method method;
    uint32_t substeps;
    bool fnopt;                 /* the cape's FNOpt (only the cape runs it) */
    weft_precision precision;   /* FNOpt's arithmetic */
} mc_method;

static bool parse_method(const char *s, size_t n, mc_method *m)
{
    char buf[32];
    if (n == 0 || n >= sizeof buf) {
        return false;
    }
    memcpy(buf, s, n);
    buf[n] = '\0';
    snprintf(m->label, sizeof m->label, "%s", buf);
    m->substeps = 0;
    m->fnopt = false;
    m->precision = WEFT_PRECISION_FP32;
    static const char *const fnopt_names[] = {"fnopt", "fnopt-fp16", "fnopt-int8"};
    for (int p = 0; p < WEFT_PRECISION_COUNT; ++p) {
        if (!strcmp(buf, fnopt_names[p])) {
            static const char *const labels[] = {"FNOpt fp32", "FNOpt fp16", "FNOpt int8"};
            snprintf(m->label, sizeof m->label, "%s", labels[p]);
            m->fnopt = true;
            m->method = WEFT_METHOD_EXTERNAL;
            m->precision = (weft_precision)p;
            return true;
        }
    }
    if (!strcmp(buf, "lbs")) {
        m->method = WEFT_METHOD_LBS;
        return true;
    }
    if (!strcmp(buf, "model")) {
        m->method = WEFT_METHOD_MODEL;
        snprintf(m->label, sizeof m->label, "model int8");
        return true;
    }
    const char *colon = strchr(buf, ':');
    if (!colon) {
        return false;
    }
    char *end = NULL;
    unsigned long sub = strtoul(colon + 1, &end, 10);
    if (!end || *end || sub < 1 || sub > 200 || colon[1] == '\0') {
        return false;
    }
    m->substeps = (uint32_t)sub;
    if (!strncmp(buf, "xpbd-fast:", 10)) {
        m->method = WEFT_METHOD_XPBD_FAST;
        return true;
    }
    if (!strncmp(buf, "xpbd:", 5)) {
        m->method = WEFT_METHOD_XPBD;
        return true;
    }
    return false;
}

static bool in_list(const char *list, const char *name)
{
    if (!list) {
        return true;
    }
    const size_t n = strlen(name);
    for (const char *p = list; *p;) {
        const size_t k = strcspn(p, ",");
        if (k == n && !strncmp(p, name, n)) {
            return true;
        }
        p += k + (p[k] == ',');
    }
    return false;
}

/* Clip names of the split, from clips.csv (file,split,...). */
static int read_clips(const mc_options *o, char names[][64], uint32_t *count)
{
    char path[1024];
    const char *dir = weft_sample_mocap_dir();
    snprintf(path, sizeof path, "%s/clips.csv", dir ? dir : ".");
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "weft bench mocap: cannot read %s\n", path);
        return 1;
    }
    char line[2048];
    uint32_t n = 0;
    bool header = true;
    while (fgets(line, sizeof line, f)) {
        if (header) {
            header = false;
            continue;
        }
        char *comma = strchr(line, ',');
        if (!comma) {
            continue;
        }
        *comma = '\0';
        const char *split = comma + 1;
        const char *base = strrchr(line, '/');
        base = base ? base + 1 : line;
        char name[64];
        size_t k = strcspn(base, ".");
        if (k == 0 || k >= sizeof name) {
            continue;
        }
        memcpy(name, base, k);
        name[k] = '\0';
        const bool split_ok = !strcmp(o->split, "all") || !strncmp(split, o->split, strlen(o->split));
        if ((o->clips ? in_list(o->clips, name) : split_ok) && n < MC_MAX_CLIPS) {
            memcpy(names[n++], name, k + 1);
        }
    }
    fclose(f);
    if (n == 0) {
        fprintf(stderr, "weft bench mocap: no clip of %s matches\n", path);
        return 1;
    }
    *count = n;
    return 0;
}

typedef struct mc_cell {
    bool failed;
    char why[160];
    weft_wear_summary wear;
    double p50, p99, max;           /* of ms, each frame's fastest run */
    double *ms;                     /* the frames' times in frame order (owned; cell_free) */
    uint32_t frames;
    uint32_t cuts, ccd_over_budget; /* frames that were cuts, or where CCD ran out of its bound */
    uint32_t ccd_released;          /* frames where the tethers released vertices CCD held */
} mc_cell;

/* Frames a cell runs after the settle: --frames, at most the clip's own length at 60 Hz (past
 * its end a clip holds its last pose). */
static uint32_t cell_frames(const mc_options *o, const weft_clip *clip)
{
    const uint32_t clip_frames = (uint32_t)floor((double)clip->frame_count / (double)clip->fps * 60.0);
    return o->frames && o->frames < clip_frames ? o->frames : clip_frames;
}

/* A library clip by name, retargeted onto the body; non-zero (reported) on failure. */
static int load_clip(weft_context *ctx, const weft_body *body, const char *name, weft_clip **out)
{
    char spec[128], path[1024];
    snprintf(spec, sizeof spec, "mocap:%.63s", name);
    weft_bvh_def bdef = weft_default_bvh_def();
    bdef.rest_joints = weft_body_rest_joints(body);
    if (weft_sample_motion_path(spec, path, sizeof path) != WEFT_OK ||
        weft_bvh_load_file(ctx, path, &bdef, out) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: clip %s: %s\n", name, weft_last_error());
        return 1;
    }
    return 0;
}

/* --chain: the clips back to back as one motion of `frames` frames (weft_clip_chain: each placed
 * where the one before ended and blended into over MC_CHAIN_BLEND frames, as a game crossfades one
 * animation into the next). */
static int make_chain(weft_context *ctx, const weft_body *body, char names[][64], uint32_t n, uint32_t frames,
                      weft_clip **out)
{
    *out = NULL;
    weft_clip *clips[MC_MAX_CLIPS] = {NULL};
    int rc = 0;
    for (uint32_t c = 0; rc == 0 && c < n; ++c) {
        rc = load_clip(ctx, body, names[c], &clips[c]);
    }
    if (rc == 0 && weft_clip_chain(ctx, body, (const weft_clip *const *)clips, n, frames, MC_CHAIN_BLEND, out) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: --chain: %s\n", weft_last_error());
        rc = 1;
    }
    for (uint32_t c = 0; c < n; ++c) {
        weft_clip_destroy(clips[c]);
    }
    return rc;
}

/* Frame k's pose (the settle frames blend from the bind pose into the clip's first pose) and
 * the body posed there; non-zero on failure. */
static int pose_frame(const mc_options *o, const weft_body *body, const weft_clip *clip, const weft_pose *bind,
                      const weft_pose *first, uint32_t k, weft_pose *pose, float *bverts)
{
    if (k < o->settle) {
        weft_avatar_sample_settle_pose(bind, first, k, o->settle, pose);
    } else if (weft_clip_sample(clip, (double)(k - o->settle) / 60.0, pose) != WEFT_OK) {
        return 1;
    }
    return weft_body_pose(body, pose, bverts, NULL) != WEFT_OK;
}

/* The cell's timing percentiles from its frame times (sorted in a copy); non-zero when out of
 * memory. */
static int cell_times(mc_cell *cell)
{
    double *sorted = malloc((cell->frames ? cell->frames : 1) * sizeof(double));
    if (!sorted) {
        fprintf(stderr, "weft bench mocap: out of memory\n");
        return 1;
    }
    memcpy(sorted, cell->ms, cell->frames * sizeof(double));
    cell->p50 = weft_wear_percentile(sorted, cell->frames, 50.0);
    cell->p99 = weft_wear_percentile(sorted, cell->frames, 99.0);
    cell->max = weft_wear_percentile(sorted, cell->frames, 100.0);
    free(sorted);
    return 0;
}

/* A cell once its frames ran (or the error that stopped it): it takes the frame times. */
static int cell_finish(int rc, double *ms, uint32_t frames, mc_cell *cell)
{
    cell->ms = ms;
    cell->frames = frames;
    if (rc != 0) {
        fprintf(stderr, "weft bench mocap: %s\n", weft_last_error());
    } else if (!cell->failed) {
        rc = cell_times(cell);
    }
    return rc;
}

static void cell_free(mc_cell *cell)
{
    free(cell->ms);
    cell->ms = NULL;
}

/* A rerun of the cell: each frame keeps its faster time. A frame slow for the cloth's sake is
 * slow in every run (the cloth is the same); one that lost its core to another job rarely loses
 * it again in the same frame. Non-zero when the rerun's cloth differs or memory runs out. */
static int cell_merge_rerun(mc_cell *cell, const mc_cell *re)
{
    if (re->failed || re->frames != cell->frames || memcmp(&re->wear, &cell->wear, sizeof re->wear) != 0) {
        return 1;
    }
    for (uint32_t i = 0; i < cell->frames; ++i) {
        cell->ms[i] = re->ms[i] < cell->ms[i] ? re->ms[i] : cell->ms[i];
    }
    return cell_times(cell);
}

/* One (clip, garment, method) run; memo: the clip's body self-overlap per frame, shared by its
 * cells. Returns non-zero only for setup failures. */
static int run_cell(const mc_options *o, weft_context *ctx, const weft_body *body, weft_model *model,
                    const weft_clip *clip, weft_wear_memo *memo, weft_cloth_kind kind, const mc_method *m, mc_cell *cell)
{
    memset(cell, 0, sizeof *cell);
    weft_cloth_def cdef = weft_default_cloth_def(kind);
    weft_cloth_resolution res;
    if (weft_cloth_resolution_from_name(o->resolution, &res) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: --resolution %s is not 1k, 4k, 16k or 40k\n", o->resolution);
        return 1;
    }
    cdef.resolution = res;
    weft_cloth_mesh *cloth = NULL;
    if (weft_cloth_create(ctx, &cdef, body, &cloth) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: garment: %s\n", weft_last_error());
        return 1;
    }
    const uint32_t nbv = weft_body_vertex_count(body), nbt = weft_body_triangle_count(body);
    uint8_t *parts = malloc(nbt);
    float *bverts = malloc((size_t)nbv * 3 * sizeof(float));
    float *skinned = malloc((size_t)cloth->vertex_count * 3 * sizeof(float));
    const uint32_t frames = cell_frames(o, clip);
    double *ms = calloc(frames ? frames : 1, sizeof(double));
    weft_wear *wear = NULL;
    int rc = 0;
    if (!parts || !bverts || !skinned || !ms ||
        weft_wear_create(weft_body_triangles(body), nbt, nbv, cloth->vertex_count, &wear) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: setup: %s\n", weft_last_error());
        rc = 1;
    }
    weft_garment *g = NULL;
    if (rc == 0) {
        weft_garment_def d;
        if (weft_sample_worn_def(body, cloth, m->method, parts, &d) != WEFT_OK) {
            rc = 1;
        }
        d.model = m->method == WEFT_METHOD_MODEL ? model : NULL;
        d.precision = WEFT_PRECISION_INT8;
        weft_sample_set_substeps(&d, m->substeps);
        d.ccd.enabled = o->ccd;
        d.collision.triangle_parts = weft_sample_parts_on(o->parts, o->ccd) ? parts : NULL;
        if (o->tether_cm >= 0.0f) { /* else the recipe's for the garment kind */
            d.tethers.distance = o->tether_cm / 100.0f;
        }
        if (m->method != WEFT_METHOD_XPBD) { /* the reference pushes nothing (weft_sample_worn_def) */
            d.collision.push = o->push_cm / 100.0f;
            d.collision.push_depth = o->push_depth_cm / 100.0f;
        }
        d.strain.limit = m->method == WEFT_METHOD_MODEL ? o->strain_pct / 100.0f : 0.0f;
        d.max_collider_tokens = o->tokens; /* the recipe's sample cap, or the whole crop (0) */
        if (rc == 0 && weft_garment_create(ctx, &d, &g) != WEFT_OK) {
            fprintf(stderr, "weft bench mocap: %s: %s\n", m->label, weft_last_error());
            rc = 1;
        }
    }
    /* the reference's waistband (the other methods' max distance holds theirs) */
    weft_surface_pins *band = NULL;
    float *band_targets = NULL;
    if (rc == 0 && m->method == WEFT_METHOD_XPBD) {
        if (weft_sample_waistband_create(ctx, body, cloth, &band) != WEFT_OK ||
            !(band_targets = malloc(((size_t)weft_surface_pins_count(band) + 1) * 3 * sizeof(float)))) {
            fprintf(stderr, "weft bench mocap: waistband: %s\n", weft_last_error());
            rc = 1;
        }
    }
    const float off_distance = kind == WEFT_CLOTH_TSHIRT ? 0.10f : 0.25f;
    weft_pose bind, first, pose;
    weft_body_bind_pose(body, &bind);
    if (rc == 0 && weft_clip_sample(clip, 0.0, &first) != WEFT_OK) {
        rc = 1;
    }
    const uint32_t settle = o->settle;
    for (uint32_t k = 0; rc == 0 && !cell->failed && k < settle + frames; ++k) {
        if ((rc = pose_frame(o, body, clip, &bind, &first, k, &pose, bverts)) != 0) {
            break;
        }
        const double t0 = weft__now_ms();
        weft_result r = weft_garment_set_collider(g, bverts);
        if (r == WEFT_OK) {
            r = weft_sample_waistband_pin(band, g, bverts, band_targets);
        }
        if (r == WEFT_OK) {
            r = weft_garment_step(g);
        }
        const double t1 = weft__now_ms();
        if (r != WEFT_OK) {
            cell->failed = true;
            snprintf(cell->why, sizeof cell->why, "frame %u: %s", k, weft_last_error());
            break;
        }
        if (k < settle) {
            continue;
        }
        ms[k - settle] = t1 - t0;
        const weft_step_stats st = weft_garment_stats(g);
        cell->cuts += st.collider_cut;
        cell->ccd_over_budget += st.ccd_over_budget;
        cell->ccd_released += st.ccd_released > 0;
        weft_wear_frame wf;
        if (weft_body_skin_points(body, &pose, cloth->positions, cloth->weights, cloth->vertex_count, skinned) != WEFT_OK ||
            weft_wear_measure_memo(wear, memo, k - settle, bverts, weft_garment_positions(g), skinned, off_distance,
                                   &wf) != WEFT_OK) {
            rc = 1;
            break;
        }
        weft_wear_summary_add(&cell->wear, &wf);
    }
    rc = cell_finish(rc, ms, frames, cell);
    weft_garment_destroy(g);
    weft_surface_pins_destroy(band);
    free(band_targets);
    weft_wear_destroy(wear);
    free(parts);
    free(bverts);
    free(skinned);
    weft_cloth_destroy(cloth);
    return rc;
}

/* Share of cape vertices farther from their column's pin than 1.25 times their rest distance
 * down the column plus 5 cm (the body pushing the cloth next to a pin out by a few centimetres is
 * not a tear): a cape pinned along its top row can leave the body only by tearing away from its
 * pins, so this is the cape's off_body (a swinging cape is not off). */
static double cape_torn(const float *x, uint32_t across, uint32_t down, float units_per_metre)
{
    uint32_t torn = 0;
    for (uint32_t i = 0; i < across; ++i) {
        const float *pin = x + 3 * (size_t)i * down;
        for (uint32_t j = 1; j < down; ++j) {
            const float *p = x + 3 * ((size_t)i * down + j);
            const float dx = p[0] - pin[0], dy = p[1] - pin[1], dz = p[2] - pin[2];
            const float limit = 1.25f * (float)j / units_per_metre + 0.05f;
            torn += dx * dx + dy * dy + dz * dz > limit * limit;
        }
    }
    return (double)torn / ((double)across * down);
}

/* One (clip, cape, method) run: the render sample's cape (32 x 40, pinned behind the shoulders)
 * stepped by FNOpt or fast XPBD. Its off_body is cape_torn's share (over 1 % in a frame: lost);
 * inside_body as for the garments. */
static int run_cape_cell(const mc_options *o, weft_context *ctx, const weft_body *body, const weft_clip *clip,
                         weft_wear_memo *memo, const mc_method *m, mc_cell *cell)
{
    memset(cell, 0, sizeof *cell);
    weft_sample_cape_def cd = weft_sample_default_cape_def();
    cd.precision = m->precision;
    if (o->fnopt_model) {
        cd.model_path = o->fnopt_model;
    }
    cd.xpbd_substeps = m->fnopt ? 0 : m->substeps;
    weft_sample_cape *cape = NULL;
    if (weft_sample_cape_create(ctx, body, &cd, &cape) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: cape (%s): %s\n", m->label, weft_last_error());
        return 1;
    }
    const uint32_t n = weft_sample_cape_vertex_count(cape);
    const uint32_t nbv = weft_body_vertex_count(body), nbt = weft_body_triangle_count(body);
    float *bverts = malloc((size_t)nbv * 3 * sizeof(float));
    const uint32_t frames = cell_frames(o, clip);
    double *ms = calloc(frames ? frames : 1, sizeof(double));
    weft_wear *wear = NULL;
    int rc = 0;
    if (!bverts || !ms || weft_wear_create(weft_body_triangles(body), nbt, nbv, n, &wear) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: cape setup: %s\n", weft_last_error());
        rc = 1;
    }
    weft_pose bind, first, pose;
    weft_body_bind_pose(body, &bind);
    if (rc == 0 && weft_clip_sample(clip, 0.0, &first) != WEFT_OK) {
        rc = 1;
    }
    for (uint32_t k = 0; rc == 0 && !cell->failed && k < o->settle + frames; ++k) {
        if ((rc = pose_frame(o, body, clip, &bind, &first, k, &pose, bverts)) != 0) {
            break;
        }
        const double t0 = weft__now_ms();
        weft_result r = weft_sample_cape_step(cape, body, &pose, bverts);
        const double t1 = weft__now_ms();
        if (r != WEFT_OK) {
            cell->failed = true;
            snprintf(cell->why, sizeof cell->why, "frame %u: %s", k, weft_last_error());
            break;
        }
        if (k < o->settle) {
            continue;
        }
        ms[k - o->settle] = t1 - t0;
        weft_wear_frame wf;
        const float *x = weft_sample_cape_positions(cape);
        /* inside_body and the body's overlap; off_body is the cape's own (cape_torn) */
        if (weft_wear_measure_memo(wear, memo, k - o->settle, bverts, x, x, 1.0f, &wf) != WEFT_OK) {
            rc = 1;
            break;
        }
        wf.off_body = cape_torn(x, cd.across, cd.down, weft_sample_cape_units_per_metre(cape));
        weft_wear_summary_add(&cell->wear, &wf);
    }
    rc = cell_finish(rc, ms, frames, cell);
    weft_wear_destroy(wear);
    weft_sample_cape_destroy(cape);
    free(bverts);
    return rc;
}

typedef struct mc_total {
    uint32_t cells, lost, failed, cuts, ccd_over_budget, ccd_released, retimed;
    double inside_mean_sum, inside_max, clear_max, ratio_max, p50_sum;
} mc_total;

enum {
    OPT_SPLIT = 1, OPT_CLIPS, OPT_GARMENTS, OPT_METHODS, OPT_FRAMES, OPT_SETTLE, OPT_RESOLUTION, OPT_MODEL, OPT_CCD,
    OPT_BODY_PARTS, OPT_TETHER_CM, OPT_PUSH_CM, OPT_PUSH_DEPTH_CM, OPT_STRAIN_LIMIT, OPT_FNOPT_MODEL, OPT_COLLIDER_TOKENS, OPT_MD, OPT_BLOCK, OPT_CSV,
    OPT_RETIME, OPT_RETIME_OVER, OPT_CHAIN,
};

static const cli_option k_options[] = {
    {"split", "test|train|all", OPT_SPLIT, "the clips of this split of the library (default test)"},
    {"clips", "A,B,...", OPT_CLIPS, "only these clips, by name (instead of a split)"},
    {"garments", "tshirt,dress,skirt,cape", OPT_GARMENTS,
     "the garments (default tshirt,dress,skirt); cape: the render sample's\n"
     "32x40 cape, run only by fnopt* and xpbd-fast:S"},
    {"methods", "lbs,model,xpbd-fast:5,xpbd-fast:10,xpbd:S,fnopt", OPT_METHODS,
     "the methods, at most 8 (default lbs,model,xpbd-fast:5,xpbd-fast:10); S:\n"
     "substeps, 1..200. xpbd:S is the reference as weft simgen runs it on real\n"
     "motion (the body projected each substep, the max distance, no push, up to\n"
     "8 S substeps on fast frames). fnopt, fnopt-fp16, fnopt-int8: the cape by FNOpt\n"
     "(K = 10) at that precision; the garments skip them"},
    {"frames", "N", OPT_FRAMES,
     "frames after the settle, 0..100000 (default 300; 0: every frame of each\n"
     "clip)"},
    {"chain", "N", OPT_CHAIN,
     "the clips back to back as one motion of N frames, 1..100000 (each placed\n"
     "where the one before ended and blended into over 30 frames, the clips\n"
     "repeating in order): one row per garment and method; --frames is then N"},
    {"settle", "N", OPT_SETTLE,
     "settle frames blending from the bind pose into the clip's first pose,\n"
     "1..1000 (default 30)"},
    {"resolution", "1k|4k", OPT_RESOLUTION, "the garments' resolution (default 1k)"},
    {"model", "FILE", OPT_MODEL,
     "the learned model (default the shipped int8 garment model,\n"
     "tools/train/models/garment.int8.safetensors)"},
    {"fnopt-model", "FILE", OPT_FNOPT_MODEL,
     "the cape's FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors)"},
    {"ccd", "on|off", OPT_CCD, "the CCD post-process (default off)"},
    {"body-parts", "auto|on|off", OPT_BODY_PARTS,
     "collision by body parts (default auto: on where CCD runs, off\n"
     "otherwise)"},
    {"tether-cm", "X", OPT_TETHER_CM, "the max distance to the skinned garment for every garment, 0..1000 cm\n"
     "(default: the recipe's for each garment, below)"},
    {"push-cm", "X", OPT_PUSH_CM, "the collider push, 0..10 cm (default below; not for the xpbd:S reference)"},
    {"push-depth-cm", "X", OPT_PUSH_DEPTH_CM, "the deepest cloth the push moves out, 0..50 cm (default below)"},
    {"strain-limit", "PCT", OPT_STRAIN_LIMIT, "the learned model's strain limit, 0..1000 % (default below)"},
    {"collider-tokens", "N", OPT_COLLIDER_TOKENS,
     "the learned model's collider tokens: an even, weighted sample of its crop\n"
     "of at most N, 0..1000000 (0: the whole crop; default below)"},
    {"retime", "N", OPT_RETIME,
     "a cell whose worst frame is more than --retime-over times its median runs\n"
     "again, up to N times, 0..10 (default 1): each frame keeps its fastest run\n"
     "and the row shows the first run's ratio too; the cloth must come out the\n"
     "same (every other column), else the bench fails"},
    {"retime-over", "X", OPT_RETIME_OVER, "the worst / median ratio that times a cell again, 0..100 (default 3)"},
    {"md", "FILE", OPT_MD,
     "write the table into FILE between <!-- mocap-table --> markers\n"
     "(docs/STABILITY_MOCAP.md)"},
    {"csv", "FILE", OPT_CSV,
     "also write one CSV row per (clip, garment, method) cell (percentages and ms;\n"
     "lost 0/1); written only when every cell ran"},
    {"block", "NAME", OPT_BLOCK,
     "with --md: between <!-- NAME --> markers instead (another variant's\n"
     "table on the same page): NAME starts with mocap-table; lowercase\n"
     "letters, digits and '-', under 64"},
    {0},
};

static void notes(FILE *out)
{
    fprintf(out,
            "Defaults: the test split, all three garments, lbs,model,xpbd-fast:5,xpbd-fast:10, 300 frames\n"
            "(0: every frame of each clip) after %d settle frames blending from the bind pose into the clip's\n"
            "first pose (--settle N, 1..1000), 1k, the shipped int8 garment model, and the worn-garment recipe\n"
            "of the render sample: CCD off, the whole body as collider (no parts), a max distance of %g cm (skirts\n"
            "%g, dresses %g), a push of %g cm from up to %g cm deep, and for the learned model a strain limit\n"
            "of %g %% and %u collider tokens (the xpbd:S reference runs as simgen runs it on real motion: the\n"
            "body projected each substep, the max distance, no push; docs/REFSIM.md).\n",
            MC_SETTLE, (double)WEFT_WORN_TETHER_CM, (double)WEFT_WORN_TETHER_SKIRT_CM,
            (double)WEFT_WORN_TETHER_DRESS_CM, (double)WEFT_WORN_PUSH_CM, (double)WEFT_WORN_PUSH_DEPTH_CM,
            (double)WEFT_WORN_STRAIN_PCT,
            WEFT_WORN_COLLIDER_TOKENS);
}

static const cli_command k_command = {
    .tool = "weft bench mocap",
    .synopsis = "weft bench mocap [--split test|train|all] [--clips A,B,...] [--garments tshirt,dress,skirt,cape]\n"
                "                 [--methods lbs,model,xpbd-fast:S,xpbd:S,fnopt] [--frames N] [--chain N]\n"
                "                 [--resolution 1k|4k] [--model FILE] [--fnopt-model FILE] [--ccd on|off]\n"
                "                 [--body-parts auto|on|off]\n"
                "                 [--tether-cm X] [--push-cm X] [--push-depth-cm X] [--strain-limit PCT]\n"
                "                 [--collider-tokens N]\n"
                "                 [--settle N]\n"
                "                 [--md FILE [--block NAME]]",
    .about = "Garments on the mocap library's clips (samples/mocap/clips.csv), per method, clip and garment:\n"
             "garments lost, inside the body, ms p50/p99/max, on one thread.",
    .options = k_options,
    .notes = notes,
};

int weft_bench_mocap(int argc, char **argv)
{
    mc_options o = {.split = "test", .garments = "tshirt,dress,skirt", .methods = "lbs,model,xpbd-fast:5,xpbd-fast:10",
                    .model = "tools/train/models/garment.int8.safetensors", .resolution = "1k", .frames = 300, .settle = MC_SETTLE,
                    .ccd = false, .parts = -1, .tether_cm = -1.0f, .push_cm = WEFT_WORN_PUSH_CM,
                    .push_depth_cm = WEFT_WORN_PUSH_DEPTH_CM,
                    .strain_pct = WEFT_WORN_STRAIN_PCT, .tokens = WEFT_WORN_COLLIDER_TOKENS, .block = "mocap-table",
                    .retime = 1, .retime_over = 3.0f};
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        bool ok = true;
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_SPLIT:
            o.split = v;
            ok = !strcmp(v, "test") || !strcmp(v, "train") || !strcmp(v, "all");
            break;
        case OPT_CLIPS:
            o.clips = v;
            break;
        case OPT_GARMENTS:
            o.garments = v;
            break;
        case OPT_METHODS:
            o.methods = v;
            break;
        case OPT_MODEL:
            o.model = v;
            break;
        case OPT_FNOPT_MODEL:
            o.fnopt_model = v;
            break;
        case OPT_CSV:
            o.csv = v;
            break;
        case OPT_MD:
            o.md = v;
            break;
        case OPT_BLOCK:
            o.block = v;
            ok = strncmp(v, "mocap-table", 11) == 0 && strlen(v) < 64 &&
                 strspn(v, "abcdefghijklmnopqrstuvwxyz0123456789-") == strlen(v);
            break;
        case OPT_RESOLUTION:
            o.resolution = v;
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, a, v, 0, 100000, &o.frames)) {
                return 2;
            }
            break;
        case OPT_CHAIN:
            if (!cli_u32(k_command.tool, a, v, 1, 100000, &o.chain)) {
                return 2;
            }
            break;
        case OPT_SETTLE:
            if (!cli_u32(k_command.tool, a, v, 1, 1000, &o.settle)) {
                return 2;
            }
            break;
        case OPT_RETIME:
            if (!cli_u32(k_command.tool, a, v, 0, 10, &o.retime)) {
                return 2;
            }
            break;
        case OPT_RETIME_OVER:
            if (!cli_float(k_command.tool, a, v, 0.0f, 100.0f, &o.retime_over)) {
                return 2;
            }
            break;
        case OPT_COLLIDER_TOKENS:
            if (!cli_u32(k_command.tool, a, v, 0, 1000000, &o.tokens)) {
                return 2;
            }
            break;
        case OPT_CCD:
            ok = !strcmp(v, "on") || !strcmp(v, "off");
            o.ccd = !strcmp(v, "on");
            break;
        case OPT_BODY_PARTS:
            ok = !strcmp(v, "on") || !strcmp(v, "off") || !strcmp(v, "auto");
            o.parts = !strcmp(v, "auto") ? -1 : !strcmp(v, "on");
            break;
        case OPT_TETHER_CM:
        case OPT_PUSH_CM:
        case OPT_PUSH_DEPTH_CM:
        case OPT_STRAIN_LIMIT: {
            float *dst = id == OPT_TETHER_CM ? &o.tether_cm
                         : id == OPT_PUSH_CM  ? &o.push_cm
                         : id == OPT_PUSH_DEPTH_CM ? &o.push_depth_cm
                                                   : &o.strain_pct;
            const float hi = id == OPT_PUSH_CM ? 10.0f : id == OPT_PUSH_DEPTH_CM ? 50.0f : 1000.0f;
            if (!cli_float(k_command.tool, a, v, 0.0f, hi, dst)) {
                return 2;
            }
            break;
        }
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
        if (!ok) {
            fprintf(stderr, "weft bench mocap: bad value '%s' for %s\n", v, a);
            return 2;
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    mc_method methods[MC_MAX_METHODS];
    uint32_t nm = 0;
    for (const char *p = o.methods; *p;) {
        const size_t k = strcspn(p, ",");
        if (nm == MC_MAX_METHODS || !parse_method(p, k, &methods[nm])) {
            fprintf(stderr, "weft bench mocap: bad method '%.*s' (lbs, model, xpbd-fast:S, xpbd:S, fnopt, fnopt-fp16, "
                    "fnopt-int8; at most %d)\n", (int)k,
                    p, MC_MAX_METHODS);
            return 2;
        }
        ++nm;
        p += k + (p[k] == ',');
    }
    static const weft_cloth_kind kinds[] = {WEFT_CLOTH_TSHIRT, WEFT_CLOTH_DRESS, WEFT_CLOTH_SKIRT};
    static const char *const kind_names[] = {"tshirt", "dress", "skirt", "cape"};
    for (const char *p = o.garments; *p;) {
        const size_t k = strcspn(p, ",");
        bool known = false;
        for (int g = 0; g < 4; ++g) {
            known |= strlen(kind_names[g]) == k && !strncmp(p, kind_names[g], k);
        }
        if (!known) {
            fprintf(stderr, "weft bench mocap: unknown garment '%.*s' (tshirt, dress, skirt, cape)\n", (int)k, p);
            return 2;
        }
        p += k + (p[k] == ',');
    }
    static char clip_names[MC_MAX_CLIPS][64];
    uint32_t nclips = 0;
    if (read_clips(&o, clip_names, &nclips) != 0) {
        return 1;
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_body *body = NULL;
    weft_model *model = NULL;
    weft_avatar_def adef = weft_default_avatar_def();
    if (weft_context_create(&cdef, &ctx) != WEFT_OK || weft_avatar_create(ctx, &adef, &body) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    bool need_model = false;
    for (uint32_t k = 0; k < nm; ++k) {
        need_model |= methods[k].method == WEFT_METHOD_MODEL;
    }
    if (need_model && weft_model_load_file_as(ctx, o.model, "clothtransformer", &model) != WEFT_OK) {
        fprintf(stderr, "weft bench mocap: model %s: %s\n", o.model, weft_last_error());
        weft_body_destroy(body);
        weft_context_destroy(ctx);
        return 1;
    }
    char *table = NULL;
    size_t len = 0, cap = 0;
    char line[4096];
    char settle_arg[32] = "", tether_arg[32] = "", chain_arg[32] = "";
    if (o.chain) { /* the chain's rows run its whole length */
        o.frames = o.chain;
        snprintf(chain_arg, sizeof chain_arg, " --chain %u", o.chain);
    }
    if (o.tether_cm >= 0.0f) {
        snprintf(tether_arg, sizeof tether_arg, " --tether-cm %g", (double)o.tether_cm);
    }
    if (o.settle != MC_SETTLE) {
        snprintf(settle_arg, sizeof settle_arg, " --settle %u", o.settle);
    }
    char retime_arg[64] = "";
    if (o.retime != 1 || o.retime_over != 3.0f) {
        snprintf(retime_arg, sizeof retime_arg, " --retime %u --retime-over %g", o.retime, (double)o.retime_over);
    }
    snprintf(line, sizeof line,
             "`weft bench mocap --split %s%s%s --frames %u%s%s --resolution %s --methods %s --garments %s --ccd %s --body-parts "
             "%s%s --push-cm %g --push-depth-cm %g --strain-limit %g --collider-tokens %u%s` "
             "(%s)\n\n"
             "| clip | garment | method | lost | worst off_body %% | inside_body mean / max %% | inside_clear max %% | "
             "body_self_overlap mean / max %% | ms p50 / p99 / max | max / p50 |\n"
             "|---|---|---|---|---:|---:|---:|---:|---:|---:|\n",
             o.split, o.clips ? " --clips " : "", o.clips ? o.clips : "", o.frames, chain_arg, settle_arg, o.resolution,
             o.methods,
             o.garments, o.ccd ? "on" : "off", o.parts < 0 ? "auto" : o.parts ? "on" : "off", tether_arg,
             (double)o.push_cm, (double)o.push_depth_cm, (double)o.strain_pct, o.tokens, retime_arg,
             weft_config_string());
    fputs(line, stdout); /* the command and the table's head, as the page gets them */
    table = bench_append(table, &len, &cap, line);
    mc_total totals[MC_MAX_METHODS];
    memset(totals, 0, sizeof totals);
    char *csv = NULL;
    size_t csv_len = 0, csv_cap = 0;
    csv = bench_append(csv, &csv_len, &csv_cap,
                       "clip,garment,method,lost,worst_off_body_pct,inside_body_mean_pct,inside_body_max_pct,"
                       "body_self_overlap_mean_pct,body_self_overlap_max_pct,ms_p50,ms_p99,ms_max,inside_clear_max_pct,"
                       "inside_clear_mean_pct\n");
    int rc = table && csv ? 0 : 1;
    /* --chain: one motion of every clip back to back, one row per garment and method */
    weft_clip *chain = NULL;
    if (rc == 0 && o.chain && make_chain(ctx, body, clip_names, nclips, o.chain, &chain) != 0) {
        rc = 1;
    }
    for (uint32_t c = 0; rc == 0 && c < (o.chain ? 1u : nclips); ++c) {
        weft_clip *clip = chain;
        if (!chain && (rc = load_clip(ctx, body, clip_names[c], &clip)) != 0) {
            break;
        }
        const char *row_name = chain ? chain->name : clip_names[c]; /* "chain of N clips" */
        /* the body's self-overlap, measured once per frame for all the clip's cells */
        weft_wear_memo *memo = NULL;
        const uint32_t memo_frames = cell_frames(&o, clip);
        if (weft_wear_memo_create(weft_body_vertex_count(body), memo_frames ? memo_frames : 1, &memo) != WEFT_OK) {
            fprintf(stderr, "weft bench mocap: %s\n", weft_last_error());
            rc = 1;
        }
        for (uint32_t gk = 0; rc == 0 && gk < 4; ++gk) {
            if (!in_list(o.garments, kind_names[gk])) {
                continue;
            }
            const bool cape = gk == 3;
            for (uint32_t k = 0; rc == 0 && k < nm; ++k) {
                /* the cape runs FNOpt and fast XPBD; the garments every method but FNOpt */
                const bool runs = cape ? methods[k].fnopt || methods[k].method == WEFT_METHOD_XPBD_FAST
                                       : !methods[k].fnopt;
                if (!runs) {
                    continue;
                }
                mc_cell cell;
                rc = cape ? run_cape_cell(&o, ctx, body, clip, memo, &methods[k], &cell)
                          : run_cell(&o, ctx, body, model, clip, memo, kinds[gk], &methods[k], &cell);
                /* A worst frame past the bound is timed again: on a shared machine one frame can
                 * lose its core's cache or clock to another job; the cloth must come out the same. */
                const double first_ratio = rc == 0 && !cell.failed && cell.p50 > 0.0 ? cell.max / cell.p50 : 0.0;
                for (uint32_t again = 0; rc == 0 && !cell.failed && again < o.retime &&
                                         cell.max > (double)o.retime_over * cell.p50;
                     ++again) {
                    mc_cell re;
                    rc = cape ? run_cape_cell(&o, ctx, body, clip, memo, &methods[k], &re)
                              : run_cell(&o, ctx, body, model, clip, memo, kinds[gk], &methods[k], &re);
                    if (rc == 0 && cell_merge_rerun(&cell, &re) != 0) {
                        fprintf(stderr, "weft bench mocap: %s %s %s: timing it again changed the cloth\n", row_name,
                                kind_names[gk], methods[k].label);
                        rc = 1;
                    }
                    cell_free(&re);
                }
                cell_free(&cell); /* its percentiles stay */
                if (rc != 0) {
                    break;
                }
                mc_total *t = &totals[k];
                t->cells++;
                if (cell.failed) {
                    t->failed++;
                    snprintf(line, sizeof line, "| %.63s | %s | %s | failed: %.159s | | | | | | |\n", row_name,
                             kind_names[gk], methods[k].label, cell.why);
                } else {
                    const weft_wear_summary *w = &cell.wear;
                    t->lost += w->frames_off > 0;
                    t->inside_mean_sum += w->inside_mean;
                    t->inside_max = w->inside_max > t->inside_max ? w->inside_max : t->inside_max;
                    t->clear_max = w->inside_clear_max > t->clear_max ? w->inside_clear_max : t->clear_max;
                    const double ratio = cell.p50 > 0.0 ? cell.max / cell.p50 : 0.0;
                    t->ratio_max = ratio > t->ratio_max ? ratio : t->ratio_max;
                    char first[32] = "";
                    if (first_ratio > (double)o.retime_over) {
                        snprintf(first, sizeof first, " (first run %.1f)", first_ratio);
                        t->retimed++;
                    }
                    t->p50_sum += cell.p50;
                    t->cuts += cell.cuts;
                    t->ccd_over_budget += cell.ccd_over_budget;
                    t->ccd_released += cell.ccd_released;
                    snprintf(line, sizeof line,
                             "| %.63s | %s | %.31s | %s | %.1f | %.1f / %.1f | %.1f | %.1f / %.1f | %.2f / %.2f / %.2f | "
                             "%.1f%s |\n",
                             row_name, kind_names[gk], methods[k].label, w->frames_off ? "**lost**" : "no",
                             100.0 * w->off_body_max, 100.0 * w->inside_mean, 100.0 * w->inside_max,
                             100.0 * w->inside_clear_max, 100.0 * w->overlap_mean, 100.0 * w->overlap_max, cell.p50, cell.p99, cell.max, ratio,
                             first);
                    char row[512];
                    snprintf(row, sizeof row, "%.63s,%s,%.31s,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n",
                             row_name, kind_names[gk], methods[k].label, w->frames_off > 0,
                             100.0 * w->off_body_max, 100.0 * w->inside_mean, 100.0 * w->inside_max,
                             100.0 * w->overlap_mean, 100.0 * w->overlap_max, cell.p50, cell.p99, cell.max,
                             100.0 * w->inside_clear_max, 100.0 * w->inside_clear_mean);
                    csv = bench_append(csv, &csv_len, &csv_cap, row);
                    if (!csv) {
                        rc = 1;
                        break;
                    }
                }
                fputs(line, stdout);
                fflush(stdout);
                table = bench_append(table, &len, &cap, line);
                rc = table ? 0 : 1;
            }
        }
        weft_wear_memo_destroy(memo);
        if (clip != chain) {
            weft_clip_destroy(clip);
        }
    }
    weft_clip_destroy(chain);
    if (rc == 0) {
        table = bench_append(table, &len, &cap,
                             "\n| method | cells | garments lost | failed | inside_body mean of means / worst frame % | "
                             "inside_clear worst frame % | worst max / p50 | cells timed again | mean p50 ms | cut frames | "
                             "CCD over budget | CCD released |\n"
                             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        for (uint32_t k = 0; table && k < nm; ++k) {
            const mc_total *t = &totals[k];
            const uint32_t ok_cells = t->cells - t->failed;
            snprintf(line, sizeof line, "| %s | %u | %u | %u | %.1f / %.1f | %.1f | %.1f | %u | %.2f | %u | %u | %u |\n",
                     methods[k].label, t->cells, t->lost, t->failed,
                     ok_cells ? 100.0 * t->inside_mean_sum / ok_cells : 0.0, 100.0 * t->inside_max,
                     100.0 * t->clear_max, t->ratio_max, t->retimed,
                     ok_cells ? t->p50_sum / ok_cells : 0.0, t->cuts, t->ccd_over_budget, t->ccd_released);
            fputs(line, stdout);
            table = bench_append(table, &len, &cap, line);
        }
        rc = table ? 0 : 1;
    }
    uint32_t failed = 0;
    for (uint32_t k = 0; k < nm; ++k) {
        failed += totals[k].failed;
    }
    if (rc == 0 && failed > 0) {
        /* a step that failed is printed above with its reason, but a table with holes is no
         * result: nothing is written and the bench fails */
        fprintf(stderr, "weft bench mocap: %u runs failed (rows above); no table written\n", failed);
        rc = 1;
    }
    if (rc == 0 && o.csv) {
        FILE *f = fopen(o.csv, "w");
        const bool ok = f && fputs(csv, f) >= 0;
        if (!f || fclose(f) != 0 || !ok) {
            fprintf(stderr, "weft bench mocap: cannot write %s\n", o.csv);
            rc = 1;
        }
    }
    free(csv);
    if (rc == 0 && o.md) {
        size_t dsize = 0;
        char *doc = bench_slurp(o.md, &dsize);
        doc = bench_replace_block(doc, o.block, table, "# Stability");
        rc = bench_write_doc("mocap", o.md, doc) ? 0 : 1;
    }
    free(table);
    weft_model_destroy(model);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
    return rc;
}

#else
int weft_bench_mocap(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    fprintf(stderr, "weft bench mocap: this build has no avatar, wardrobe and BVH import (weft_render, weft_assets)\n");
    return 1;
}
#endif
