/* Shared garment assets (weft_garment_asset_*): two instances of one asset, stepped in turn on
 * different motions, end bit-identical to two garments made from the same def, for every method
 * of the worn recipe (LBS, the shipped garment model in int8 and fp32, the fast XPBD, an external
 * solver through the constraint stage; tethers, strain limit, push, body parts, floor, CCD on and
 * off), through a cut and a set_state; an extra instance costs at most a tenth of the first's
 * memory for the learned model and LBS; an instance entered while another is stepping fails with
 * WEFT_ERROR_BUSY and is left as it was; bad arguments fail by name. The T-shirt at 1k on weft's
 * avatar. */
#define _POSIX_C_SOURCE 200809L /* posix_memalign */
#include "test.h"
#include "weft.h"
#include "weft/body.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GARMENT_MODEL WEFT_SOURCE_DIR "/tools/train/models/garment.safetensors"
/* a model with a latent history (2 frames): the state an instance carries between steps */
/* a skinned-prior model with a latent history of two frames (the parity tests' golden_skin) */
#define HISTORY_MODEL WEFT_SOURCE_DIR "/tests/model/data/garment_seq/golden_skin.safetensors"
#define FRAMES 10u

/* Live bytes through the context's allocator. */
static size_t g_live;

static void *count_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    void *p = NULL;
    if (alignment < sizeof(void *)) {
        alignment = sizeof(void *);
    }
    if (posix_memalign(&p, alignment, size ? size : 1) != 0) {
        return NULL;
    }
    g_live += size;
    return p;
}

static void count_free(void *p, size_t size, void *user)
{
    (void)user;
    if (p) {
        g_live -= size;
        free(p);
    }
}

/* The job hook: while `busy_probe` is set, the first chunk a step hands out tries to step the
 * probe garment (another instance of the stepping garment's asset) and records the result. */
static weft_garment *g_probe;
static weft_result g_probe_result;
static bool g_probe_tried;
static void serial_for(weft_task_fn *task, uint32_t count, uint32_t min_chunk, void *task_context, void *user)
{
    (void)min_chunk;
    (void)user;
    if (g_probe && !g_probe_tried) {
        g_probe_tried = true;
        g_probe_result = weft_garment_step(g_probe);
    }
    task(0, count, 0, task_context);
}

typedef struct scene {
    weft_context *ctx;
    weft_body *body;
    weft_cloth_mesh *cloth;
    weft_model *model, *history;
    uint8_t *parts;
    float *bind;                        /* the body in its bind pose */
    float *verts;                       /* scratch: the posed body */
    uint32_t nbv;
} scene;

static bool scene_make(scene *s)
{
    memset(s, 0, sizeof *s);
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    cd.parallel_for = serial_for;
    cd.max_workers = 1;
    CHECK_RESULT(weft_context_create(&cd, &s->ctx), WEFT_OK);
    if (!s->ctx) {
        return false;
    }
    weft_avatar_def ad = weft_default_avatar_def();
    CHECK_RESULT(weft_avatar_create(s->ctx, &ad, &s->body), WEFT_OK);
    weft_cloth_def cdef = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    cdef.resolution = WEFT_CLOTH_RES_1K;
    CHECK_RESULT(weft_cloth_create(s->ctx, &cdef, s->body, &s->cloth), WEFT_OK);
    CHECK_RESULT(weft_model_load_file(s->ctx, GARMENT_MODEL, &s->model), WEFT_OK);
    CHECK_RESULT(weft_model_load_file(s->ctx, HISTORY_MODEL, &s->history), WEFT_OK);
    if (!s->body || !s->cloth || !s->model || !s->history) {
        return false;
    }
    s->nbv = weft_body_vertex_count(s->body);
    s->parts = malloc(weft_body_triangle_count(s->body));
    s->bind = malloc((size_t)s->nbv * 3 * sizeof(float));
    s->verts = malloc((size_t)s->nbv * 3 * sizeof(float));
    CHECK(s->parts && s->bind && s->verts);
    CHECK_RESULT(weft_body_triangle_parts(s->body, s->parts, weft_body_triangle_count(s->body)), WEFT_OK);
    weft_pose bind;
    weft_body_bind_pose(s->body, &bind);
    CHECK_RESULT(weft_body_pose(s->body, &bind, s->bind, NULL), WEFT_OK);
    return true;
}

static void scene_free(scene *s)
{
    weft_model_destroy(s->model);
    weft_model_destroy(s->history);
    weft_cloth_destroy(s->cloth);
    weft_body_destroy(s->body);
    weft_context_destroy(s->ctx);
    free(s->parts);
    free(s->bind);
    free(s->verts);
}

typedef struct variant {
    const char *name;
    weft_method method;
    weft_precision precision;
    bool ccd;
    bool memory_bound;                  /* the extra instance must cost <= 10 % of the first */
    bool history;                       /* the history-2 model instead of the garment model */
} variant;

/* The worn-garment recipe (docs/WEAR.md) for the variant. */
static weft_garment_def worn_def(const scene *s, const variant *v)
{
    const weft_model *m = v->history ? s->history : s->model;
    weft_garment_def d = v->method == WEFT_METHOD_MODEL ? weft_model_garment_def(m) : weft_default_garment_def();
    d.method = v->method;
    d.precision = v->precision;
    d.rest_positions = s->cloth->positions;
    d.vertex_count = s->cloth->vertex_count;
    d.triangles = s->cloth->triangles;
    d.triangle_count = s->cloth->triangle_count;
    d.collider_rest_positions = s->bind;
    d.collider_vertex_count = s->nbv;
    d.collider_triangles = weft_body_triangles(s->body);
    d.collider_triangle_count = weft_body_triangle_count(s->body);
    d.collision.triangle_parts = s->parts;
    d.collision.ground = true;
    d.collision.push = 0.005f;
    d.tethers.distance = 0.08f;
    d.strain.limit = v->method == WEFT_METHOD_MODEL ? 0.10f : 0.0f;
    d.ccd.enabled = v->ccd;
    d.substeps = 5;
    return d;
}

/* Character k's body at frame f: a procedural motion (walk or dance) blended in from the bind
 * pose over the first frames; character 1 is teleported 3 m at frame 6 (a cut). */
static const float *body_at(scene *s, uint32_t k, uint32_t f)
{
    weft_motion_def md = weft_default_motion_def(k == 0 ? WEFT_MOTION_WALK : WEFT_MOTION_DANCE);
    weft_pose bind, p, out;
    weft_body_bind_pose(s->body, &bind);
    CHECK_RESULT(weft_motion_sample(&md, (double)f / 60.0, &p), WEFT_OK);
    CHECK_RESULT(weft_pose_blend(&bind, &p, fmin(1.0, (double)(f + 1) / 6.0), &out), WEFT_OK);
    if (k == 1 && f >= 6) {
        out.translation[0] += 3.0f;
    }
    CHECK_RESULT(weft_body_pose(s->body, &out, s->verts, NULL), WEFT_OK);
    return s->verts;
}

/* One frame of garment g worn by character k: the external method gets the skinned garment
 * shaken by a fixed pattern as its host solver's result. */
static weft_result step_one(scene *s, weft_garment *g, const variant *v, uint32_t k, uint32_t f, float *ext)
{
    weft_result r = weft_garment_set_collider(g, body_at(s, k, f + 1));
    if (r != WEFT_OK || v->method != WEFT_METHOD_EXTERNAL) {
        return r == WEFT_OK ? weft_garment_step(g) : r;
    }
    r = weft_garment_skinned_positions(g, ext);
    for (uint32_t i = 0; r == WEFT_OK && i < 3 * s->cloth->vertex_count; ++i) {
        ext[i] += 0.004f * sinf(0.37f * (float)i + (float)f);
    }
    return r == WEFT_OK ? weft_garment_constrain(g, ext) : r;
}

static bool same_stats(weft_step_stats a, weft_step_stats b)
{
    return a.frame == b.frame && a.ccd_iterations == b.ccd_iterations && a.ccd_vertices_moved == b.ccd_vertices_moved &&
           a.collider_tokens == b.collider_tokens && a.tether_vertices_clamped == b.tether_vertices_clamped &&
           a.strain_limited_edges == b.strain_limited_edges && a.pushed_vertices == b.pushed_vertices &&
           a.collider_cut == b.collider_cut && a.ground_vertices == b.ground_vertices &&
           a.ccd_released == b.ccd_released && a.ccd_over_budget == b.ccd_over_budget;
}

static void check_variant(scene *s, const variant *v)
{
    const weft_garment_def d = worn_def(s, v);
    const size_t n3 = 3 * (size_t)s->cloth->vertex_count;
    float *ext = malloc(n3 * sizeof(float));
    weft_garment *own[2] = {NULL, NULL}, *inst[2] = {NULL, NULL};
    CHECK_RESULT(weft_garment_create(s->ctx, &d, &own[0]), WEFT_OK);
    CHECK_RESULT(weft_garment_create(s->ctx, &d, &own[1]), WEFT_OK);
    const size_t before = g_live;
    weft_garment_asset *asset = NULL;
    CHECK_RESULT(weft_garment_asset_create(s->ctx, &d, &asset), WEFT_OK);
    CHECK_RESULT(weft_garment_asset_instance(asset, &inst[0]), WEFT_OK);
    const size_t first = g_live - before;
    CHECK_RESULT(weft_garment_asset_instance(asset, &inst[1]), WEFT_OK);
    const size_t extra = g_live - before - first;
    CHECK_EQ_INT(weft_garment_asset_instance_count(asset), 2);
    printf("  %-22s asset + first instance %8.2f MB, another instance %6.3f MB (%.1f %%)\n", v->name,
           (double)first / 1e6, (double)extra / 1e6, 100.0 * (double)extra / (double)first);
    if (v->memory_bound) {
        CHECK_MSG(extra * 10 <= first, "%s: an extra instance costs %zu bytes, the first %zu", v->name, extra, first);
    }
    bool same = own[0] && own[1] && inst[0] && inst[1] && ext;
    uint32_t cuts = 0;
    for (uint32_t f = 0; same && f < FRAMES; ++f) {
        if (f == 4) { /* a restart mid-way: set_state clears the history of instance and garment alike */
            for (uint32_t k = 0; k < 2; ++k) {
                memcpy(ext, weft_garment_positions(own[k]), n3 * sizeof(float));
                CHECK_RESULT(weft_garment_set_state(own[k], ext, NULL), WEFT_OK);
                CHECK_RESULT(weft_garment_set_state(inst[k], ext, NULL), WEFT_OK);
            }
        }
        for (uint32_t k = 0; k < 2; ++k) { /* instances in turn, as a crowd steps them */
            CHECK_RESULT(step_one(s, inst[k], v, k, f, ext), WEFT_OK);
        }
        for (uint32_t k = 0; k < 2; ++k) {
            CHECK_RESULT(step_one(s, own[k], v, k, f, ext), WEFT_OK);
            const bool eq = memcmp(weft_garment_positions(own[k]), weft_garment_positions(inst[k]), n3 * sizeof(float)) == 0;
            CHECK_MSG(eq, "%s: character %u differs from its own garment at frame %u", v->name, k, f);
            CHECK_MSG(same_stats(weft_garment_stats(own[k]), weft_garment_stats(inst[k])), "%s: character %u stats at frame %u",
                      v->name, k, f);
            same = same && eq;
            cuts += weft_garment_stats(inst[k]).collider_cut;
        }
    }
    CHECK_MSG(weft_garment_stats(inst[1]).frame == FRAMES - 4, "%s", v->name); /* frames since set_state */
    CHECK_MSG(cuts == 1, "%s: %u cuts (character 1 teleports once)", v->name, cuts);
    weft_garment_destroy(inst[0]);
    CHECK_EQ_INT(weft_garment_asset_instance_count(asset), 1);
    weft_garment_destroy(inst[1]);
    CHECK_EQ_INT(weft_garment_asset_instance_count(asset), 0);
    weft_garment_asset_destroy(asset);
    CHECK_MSG(g_live == before, "%s: %zu bytes left after the asset and its instances", v->name, g_live - before);
    weft_garment_destroy(own[0]);
    weft_garment_destroy(own[1]);
    free(ext);
}

static void test_instances_match_own_garments(void)
{
    scene s;
    if (scene_make(&s)) {
        const variant vs[] = {
            {"lbs", WEFT_METHOD_LBS, WEFT_PRECISION_FP32, false, true, false},
            {"lbs, ccd", WEFT_METHOD_LBS, WEFT_PRECISION_FP32, true, true, false},
            {"model int8", WEFT_METHOD_MODEL, WEFT_PRECISION_INT8, false, true, false},
            {"model fp32, ccd", WEFT_METHOD_MODEL, WEFT_PRECISION_FP32, true, true, false},
            {"history-2 model int8", WEFT_METHOD_MODEL, WEFT_PRECISION_INT8, false, true, true},
            {"xpbd-fast:5", WEFT_METHOD_XPBD_FAST, WEFT_PRECISION_FP32, false, false, false},
            {"external, ccd", WEFT_METHOD_EXTERNAL, WEFT_PRECISION_FP32, true, true, false},
        };
        for (size_t i = 0; i < sizeof vs / sizeof vs[0]; ++i) {
            check_variant(&s, &vs[i]);
        }
    }
    scene_free(&s);
}

/* A step that finds another instance of its asset stepping (here: called from inside the first
 * one's job hook, as a second thread would) fails with WEFT_ERROR_BUSY, state untouched; the
 * asset is free again afterwards. */
static void test_busy(void)
{
    scene s;
    if (scene_make(&s)) {
        const variant v = {"model int8", WEFT_METHOD_MODEL, WEFT_PRECISION_INT8, false, true, false};
        const weft_garment_def d = worn_def(&s, &v);
        weft_garment_asset *asset = NULL;
        weft_garment *a = NULL, *b = NULL;
        CHECK_RESULT(weft_garment_asset_create(s.ctx, &d, &asset), WEFT_OK);
        CHECK_RESULT(weft_garment_asset_instance(asset, &a), WEFT_OK);
        CHECK_RESULT(weft_garment_asset_instance(asset, &b), WEFT_OK);
        if (a && b) {
            const size_t n3 = 3 * (size_t)s.cloth->vertex_count;
            float *before = malloc(n3 * sizeof(float));
            memcpy(before, weft_garment_positions(b), n3 * sizeof(float));
            CHECK_RESULT(weft_garment_set_collider(b, body_at(&s, 0, 1)), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(a, body_at(&s, 0, 1)), WEFT_OK);
            g_probe = b;
            g_probe_tried = false;
            CHECK_RESULT(weft_garment_step(a), WEFT_OK);
            g_probe = NULL;
            CHECK(g_probe_tried);
            CHECK_RESULT(g_probe_result, WEFT_ERROR_BUSY);
            CHECK(strstr(weft_last_error(), "another instance") != NULL);
            CHECK(memcmp(before, weft_garment_positions(b), n3 * sizeof(float)) == 0);
            CHECK_EQ_INT(weft_garment_stats(b).frame, 0);
            CHECK_RESULT(weft_garment_step(b), WEFT_OK); /* its collider is still set */
            CHECK_EQ_INT(weft_garment_stats(b).frame, 1);
            free(before);
        }
        weft_garment_destroy(a);
        weft_garment_destroy(b);
        weft_garment_asset_destroy(asset);
    }
    scene_free(&s);
}

static void test_bad_arguments(void)
{
    scene s;
    if (scene_make(&s)) {
        weft_garment_asset *asset = (weft_garment_asset *)(uintptr_t)0x1;
        weft_garment_def d = weft_default_garment_def(); /* no meshes */
        CHECK_RESULT(weft_garment_asset_create(s.ctx, &d, &asset), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(asset == (weft_garment_asset *)(uintptr_t)0x1);
        CHECK_RESULT(weft_garment_asset_create(s.ctx, NULL, &asset), WEFT_ERROR_INVALID_ARGUMENT);
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_asset_instance(NULL, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK_EQ_INT(weft_garment_asset_instance_count(NULL), 0);
        weft_garment_asset_destroy(NULL);
    }
    scene_free(&s);
}

TEST_MAIN(TEST_CASE(test_instances_match_own_garments), TEST_CASE(test_busy), TEST_CASE(test_bad_arguments))
