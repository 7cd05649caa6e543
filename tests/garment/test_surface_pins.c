/* Surface pins (runtime/garment/surface_pins.c): points bound to a collider's surface come back
 * exactly at rest, move rigidly with a rigidly moved collider, and hold a skirt's waistband on
 * weft's walking avatar under fast XPBD, where the unpinned skirt slides down; bad input is
 * refused by name. */
#include "test.h"
#include "weft/body.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static weft_context *g_ctx;
static weft_body *g_body;
static weft_cloth_mesh *g_skirt;

static void setup(void)
{
    weft_context_def cdef = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cdef, &g_ctx), WEFT_OK);
    weft_avatar_def adef = weft_default_avatar_def();
    CHECK_RESULT(weft_avatar_create(g_ctx, &adef, &g_body), WEFT_OK);
    weft_cloth_def cd = weft_default_cloth_def(WEFT_CLOTH_SKIRT);
    cd.resolution = WEFT_CLOTH_RES_1K;
    CHECK_RESULT(weft_cloth_create(g_ctx, &cd, g_body, &g_skirt), WEFT_OK);
}

/* The skirt's waistband bound to the avatar at its bind pose. */
static weft_surface_pins *waist_pins(uint32_t *out_n)
{
    const uint32_t n = weft_mesh_top_ring(g_skirt->positions, g_skirt->vertex_count, 0.012f, NULL, 0);
    uint32_t *idx = malloc(n * sizeof *idx);
    float *pts = malloc((size_t)n * 3 * sizeof *pts);
    CHECK_EQ_INT(weft_mesh_top_ring(g_skirt->positions, g_skirt->vertex_count, 0.012f, idx, n), n);
    for (uint32_t i = 0; i < n; ++i) {
        memcpy(pts + 3 * (size_t)i, g_skirt->positions + 3 * (size_t)idx[i], 3 * sizeof(float));
    }
    weft_surface_pins_def d = weft_default_surface_pins_def();
    d.collider_rest_positions = weft_body_rest_vertices(g_body);
    d.collider_vertex_count = weft_body_vertex_count(g_body);
    d.collider_triangles = weft_body_triangles(g_body);
    d.collider_triangle_count = weft_body_triangle_count(g_body);
    d.rest_points = pts;
    d.vertex_indices = idx;
    d.count = n;
    weft_surface_pins *p = NULL;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &d, &p), WEFT_OK);
    free(idx);
    free(pts);
    *out_n = n;
    return p;
}

static void test_rest_and_rigid_motion(void)
{
    uint32_t n = 0;
    weft_surface_pins *p = waist_pins(&n);
    CHECK(n >= 20 && n < g_skirt->vertex_count / 4);
    if (!p) {
        return;
    }
    CHECK_EQ_INT(weft_surface_pins_count(p), n);
    const uint32_t *idx = weft_surface_pins_indices(p);
    float *t = malloc((size_t)n * 3 * sizeof *t);
    CHECK_RESULT(weft_surface_pins_targets(p, weft_body_rest_vertices(g_body), t), WEFT_OK);
    double worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            worst = fmax(worst, fabs((double)t[3 * i + (uint32_t)k] - g_skirt->positions[3 * (size_t)idx[i] + (size_t)k]));
        }
    }
    CHECK_MSG(worst < 1e-5, "at rest: %.2e m", worst);
    /* the collider turned 40 degrees about y and moved: the points follow rigidly */
    const uint32_t nb = weft_body_vertex_count(g_body);
    float *moved = malloc((size_t)nb * 3 * sizeof *moved);
    const double c = cos(0.7), s = sin(0.7), shift[3] = {0.3, -0.1, 1.2};
    const float *rest = weft_body_rest_vertices(g_body);
    for (uint32_t i = 0; i < nb; ++i) {
        const float *x = rest + 3 * (size_t)i;
        moved[3 * i] = (float)(c * x[0] + s * x[2] + shift[0]);
        moved[3 * i + 1] = (float)(x[1] + shift[1]);
        moved[3 * i + 2] = (float)(-s * x[0] + c * x[2] + shift[2]);
    }
    CHECK_RESULT(weft_surface_pins_targets(p, moved, t), WEFT_OK);
    worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const float *x = g_skirt->positions + 3 * (size_t)idx[i];
        const double want[3] = {c * x[0] + s * x[2] + shift[0], x[1] + shift[1], -s * x[0] + c * x[2] + shift[2]};
        for (int k = 0; k < 3; ++k) {
            worst = fmax(worst, fabs(t[3 * i + (uint32_t)k] - want[k]));
        }
    }
    CHECK_MSG(worst < 1e-5, "rigid motion: %.2e m", worst);
    for (uint32_t i = 0; i < nb * 3; ++i) {
        moved[i] = NAN; /* a non-finite collider */
    }
    CHECK(weft_surface_pins_targets(p, moved, t) != WEFT_OK && weft_last_error()[0] != '\0');
    free(moved);
    free(t);
    weft_surface_pins_destroy(p);
}

/* The skirt on the avatar (bind pose), no tethers, no CCD. */
static weft_garment_def skirt_on_body(weft_method method)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.rest_positions = g_skirt->positions;
    d.vertex_count = g_skirt->vertex_count;
    d.triangles = g_skirt->triangles;
    d.triangle_count = g_skirt->triangle_count;
    d.collider_rest_positions = weft_body_rest_vertices(g_body);
    d.collider_vertex_count = weft_body_vertex_count(g_body);
    d.collider_triangles = weft_body_triangles(g_body);
    d.collider_triangle_count = weft_body_triangle_count(g_body);
    d.ccd.enabled = false;
    return d;
}

/* Mean height of the skirt below its skinned self after `frames` of the walk under fast XPBD. */
static double skirt_drop(bool pinned, uint32_t frames)
{
    const weft_garment_def d = skirt_on_body(WEFT_METHOD_XPBD_FAST);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_OK);
    uint32_t n = 0;
    weft_surface_pins *p = pinned ? waist_pins(&n) : NULL;
    const uint32_t nb = weft_body_vertex_count(g_body), nv = g_skirt->vertex_count;
    float *body = malloc((size_t)nb * 3 * sizeof *body), *skinned = malloc((size_t)nv * 3 * sizeof *skinned);
    float *targets = malloc((size_t)(n ? n : 1) * 3 * sizeof *targets);
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    weft_pose bind, first, pose;
    weft_body_bind_pose(g_body, &bind);
    weft_motion_sample(&md, 0.0, &first);
    const uint32_t settle = 20;
    for (uint32_t k = 0; g && k < settle + frames; ++k) {
        if (k < settle) {
            weft_pose_blend(&bind, &first, (k + 1.0) / settle, &pose);
        } else {
            weft_motion_sample(&md, (k - settle) / 60.0, &pose);
        }
        CHECK_RESULT(weft_body_pose(g_body, &pose, body, NULL), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(g, body), WEFT_OK);
        if (p) {
            CHECK_RESULT(weft_surface_pins_targets(p, body, targets), WEFT_OK);
            CHECK_RESULT(weft_garment_set_pins(g, weft_surface_pins_indices(p), targets, n), WEFT_OK);
        }
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    }
    double drop = 0.0;
    if (g) {
        CHECK_RESULT(weft_body_skin_points(g_body, &pose, g_skirt->positions, g_skirt->weights, nv, skinned), WEFT_OK);
        const float *x = weft_garment_positions(g);
        for (uint32_t i = 0; i < nv; ++i) {
            drop += ((double)skinned[3 * i + 1] - x[3 * i + 1]) / nv;
        }
    }
    free(body);
    free(skinned);
    free(targets);
    weft_surface_pins_destroy(p);
    weft_garment_destroy(g);
    return drop;
}

static void test_waistband_holds_a_skirt(void)
{
    const double free_drop = skirt_drop(false, 120), pinned_drop = skirt_drop(true, 120);
    printf("  skirt on the walk, fast XPBD, 2 s: mean drop below its skinned self %.1f cm unpinned, %.1f cm with the "
           "waistband pinned\n", 100.0 * free_drop, 100.0 * pinned_drop);
    CHECK_MSG(fabs(pinned_drop) < 0.03, "pinned skirt dropped %.3f m", pinned_drop);
    CHECK_MSG(free_drop > pinned_drop + 0.05, "unpinned %.3f m vs pinned %.3f m", free_drop, pinned_drop);
}

/* weft_garment_skinned_positions: under LBS it is the garment itself, frame after frame; a garment
 * without a collider has none. */
static void test_skinned_positions(void)
{
    const weft_garment_def d = skirt_on_body(WEFT_METHOD_LBS);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_OK);
    const uint32_t nb = weft_body_vertex_count(g_body), nv = g_skirt->vertex_count;
    float *body = malloc((size_t)nb * 3 * sizeof *body), *skinned = malloc((size_t)nv * 3 * sizeof *skinned);
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    double worst = 0.0;
    for (uint32_t k = 0; g && k < 30; ++k) {
        weft_pose pose;
        weft_motion_sample(&md, k / 60.0, &pose);
        CHECK_RESULT(weft_body_pose(g_body, &pose, body, NULL), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(g, body), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        CHECK_RESULT(weft_garment_skinned_positions(g, skinned), WEFT_OK);
        const float *x = weft_garment_positions(g);
        for (uint32_t i = 0; i < nv * 3; ++i) {
            worst = fmax(worst, fabs((double)x[i] - skinned[i]));
        }
    }
    CHECK_MSG(worst < 1e-6, "LBS vs skinned positions: %.2e m", worst);
    weft_garment_destroy(g);
    /* no collider: no binding */
    weft_garment_def e = weft_default_garment_def();
    e.method = WEFT_METHOD_XPBD;
    e.rest_positions = g_skirt->positions;
    e.vertex_count = nv;
    e.triangles = g_skirt->triangles;
    e.triangle_count = g_skirt->triangle_count;
    CHECK_RESULT(weft_garment_create(g_ctx, &e, &g), WEFT_OK);
    CHECK_RESULT(weft_garment_skinned_positions(g, skinned), WEFT_ERROR_UNSUPPORTED);
    CHECK_RESULT(weft_garment_skinned_positions(NULL, skinned), WEFT_ERROR_INVALID_ARGUMENT);
    weft_garment_destroy(g);
    free(body);
    free(skinned);
}

static void test_bad_input(void)
{
    const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t faces[3] = {0, 1, 2}, bad_faces[3] = {0, 1, 3}, idx[1] = {7};
    const float pt[3] = {0.2f, 0.2f, 0.1f}, nan_pt[3] = {0.2f, NAN, 0.1f};
    weft_surface_pins_def d = weft_default_surface_pins_def();
    d.collider_rest_positions = tri;
    d.collider_vertex_count = 3;
    d.collider_triangles = faces;
    d.collider_triangle_count = 1;
    d.rest_points = pt;
    d.vertex_indices = idx;
    d.count = 1;
    weft_surface_pins *p = NULL;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &d, &p), WEFT_OK);
    float t[3];
    CHECK_RESULT(weft_surface_pins_targets(p, tri, t), WEFT_OK);
    CHECK(fabsf(t[0] - 0.2f) < 1e-6f && fabsf(t[1] - 0.2f) < 1e-6f && fabsf(t[2] - 0.1f) < 1e-6f);
    weft_surface_pins_destroy(p);
    weft_surface_pins *untouched = (weft_surface_pins *)(uintptr_t)8;
    weft_surface_pins_def e = d;
    e.collider_triangles = bad_faces;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &e, &untouched), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "names vertex 3") != NULL);
    e = d;
    e.rest_points = nan_pt;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &e, &untouched), WEFT_ERROR_NOT_FINITE);
    e = d;
    e.internal_cookie = 0;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &e, &untouched), WEFT_ERROR_INVALID_ARGUMENT);
    e = d;
    e.count = 0;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &e, &untouched), WEFT_ERROR_INVALID_ARGUMENT);
    const float flat[9] = {0, 0, 0, 1, 0, 0, 2, 0, 0};
    e = d;
    e.collider_rest_positions = flat;
    CHECK_RESULT(weft_surface_pins_create(g_ctx, &e, &untouched), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(untouched == (weft_surface_pins *)(uintptr_t)8);
    CHECK_EQ_INT(weft_mesh_top_ring(tri, 3, 0.5f, NULL, 0), 1);
    CHECK_EQ_INT(weft_mesh_top_ring(tri, 3, 2.0f, NULL, 0), 3);
    CHECK_EQ_INT(weft_mesh_top_ring(tri, 3, NAN, NULL, 0), 0);
}

static void teardown(void)
{
    weft_cloth_destroy(g_skirt);
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
}

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_rest_and_rigid_motion), TEST_CASE(test_waistband_holds_a_skirt), TEST_CASE(test_skinned_positions),
          TEST_CASE(test_bad_input), TEST_CASE(teardown))
