/* Bad input to the CCD API: malformed defs, NaN / infinity, zero-area triangles, huge coordinates.
 * Every call returns a defined result, names the problem, and leaves caller state untouched. */
#include "ccd/ccd_internal.h"
#include "test.h"

static const uint32_t k_tris[6] = {0, 1, 2, 1, 3, 2};
static const float k_pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};

static weft_context *ctx_make(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

static weft_ccd_world_def base_def(void)
{
    weft_ccd_world_def d = weft_default_ccd_world_def();
    d.cloth_triangles = k_tris;
    d.cloth_triangle_count = 2;
    d.cloth_vertex_count = 4;
    d.collider_triangles = k_tris;
    d.collider_triangle_count = 2;
    d.collider_vertex_count = 4;
    return d;
}

static void malformed_defs(void)
{
    weft_context *ctx = ctx_make();
    weft_ccd_world *w = (weft_ccd_world *)(uintptr_t)1; /* must stay untouched on failure */
    weft_ccd_world_def d = base_def();
    CHECK_RESULT(weft_ccd_world_create(NULL, &d, &w), WEFT_ERROR_INVALID_ARGUMENT);
    weft_ccd_world_def raw = d;
    raw.internal_cookie = 0;
    CHECK_RESULT(weft_ccd_world_create(ctx, &raw, &w), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "weft_default_ccd_world_def") != NULL);
    uint32_t bad[3] = {0, 1, 7};
    d.cloth_triangles = bad;
    d.cloth_triangle_count = 1;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_DEGENERATE_MESH);
    bad[2] = 1;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_DEGENERATE_MESH);
    d = base_def();
    d.collider_vertex_count = 0;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_INVALID_ARGUMENT);
    d = base_def();
    d.min_separation = NAN;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_INVALID_ARGUMENT);
    d = base_def();
    d.max_iterations = 0;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_INVALID_ARGUMENT);
    d = base_def();
    float nanpos[12];
    memcpy(nanpos, k_pos, sizeof nanpos);
    nanpos[4] = NAN;
    d.cloth_layout_positions = nanpos;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_ERROR_NOT_FINITE);
    CHECK(w == (weft_ccd_world *)(uintptr_t)1);
    weft_context_destroy(ctx);
}

static void non_finite_frames(void)
{
    weft_context *ctx = ctx_make();
    weft_ccd_world_def d = base_def();
    weft_ccd_world *w = NULL;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_OK);
    float x0[12], x1[12], c[12];
    memcpy(x0, k_pos, sizeof x0);
    for (int i = 0; i < 12; ++i) {
        x1[i] = k_pos[i] + (i % 3 == 2 ? 0.5f : 0.0f);
        c[i] = k_pos[i] + (i % 3 == 2 ? 0.25f : 0.0f);
    }
    weft_ccd_report rep = {.hit_total = 77};
    x1[7] = INFINITY;
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c, c, WEFT_CCD_MASK_ALL, &rep), WEFT_ERROR_NOT_FINITE);
    CHECK_EQ_INT(rep.hit_total, 77);
    x1[7] = 0.0f;
    c[2] = NAN;
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c, c, WEFT_CCD_MASK_ALL, &rep), WEFT_ERROR_NOT_FINITE);
    float before[12];
    memcpy(before, x1, sizeof before);
    weft_ccd_postprocess_stats st = {.iterations = 5};
    CHECK_RESULT(weft_ccd_postprocess(w, x0, x1, c, c, &st), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(before, x1, sizeof before) == 0);
    CHECK_EQ_INT(st.iterations, 5);
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, NULL, NULL, WEFT_CCD_MASK_ALL, &rep), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c, c, 1u << 9, &rep), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_ccd_detect(NULL, x0, x1, c, c, WEFT_CCD_MASK_ALL, &rep), WEFT_ERROR_INVALID_ARGUMENT);
    weft_ccd_intersections in = {0};
    CHECK_RESULT(weft_ccd_intersect_frame(w, x0, c, &in), WEFT_ERROR_NOT_FINITE);
    c[2] = 0.25f;
    /* The cloth sheet moves from z = 0 to z = 0.5 through the collider copy at z = 0.25. */
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c, c, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
    CHECK(rep.hits[WEFT_CCD_VF] > 0 && rep.hits[WEFT_CCD_FV] > 0);
    CHECK(rep.earliest_toi <= 0.5 && rep.earliest_toi > 0.5 - 1e-5); /* conservative: never late */
    weft_ccd_world_destroy(w);
    weft_context_destroy(ctx);
}

static void zero_area_and_huge(void)
{
    weft_context *ctx = ctx_make();
    weft_ccd_world_def d = base_def();
    weft_ccd_world *w = NULL;
    CHECK_RESULT(weft_ccd_world_create(ctx, &d, &w), WEFT_OK);
    /* Every cloth triangle collapsed onto a line; the collider collapsed to a point. */
    float x0[12] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0}, x1[12], c0[12], c1[12];
    for (int i = 0; i < 12; ++i) {
        x1[i] = x0[i] + (i % 3 == 1 ? 1.0f : 0.0f);
        c0[i] = (i % 3 == 0) ? 1.5f : (i % 3 == 1 ? 0.5f : 0.0f);
        c1[i] = c0[i];
    }
    weft_ccd_report rep = {0};
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c0, c1, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
    CHECK(rep.hit_total > 0); /* the segment sweeps over the point */
    weft_ccd_postprocess_stats st = {0};
    weft_result r = weft_ccd_postprocess(w, x0, x1, c0, c1, &st);
    CHECK(r == WEFT_OK || r == WEFT_ERROR_NOT_CONVERGED);
    weft_ccd_intersections in = {0};
    CHECK_RESULT(weft_ccd_intersect_frame(w, x0, c0, &in), WEFT_OK);
    /* Huge coordinates: defined results, no overflow traps. */
    for (int i = 0; i < 12; ++i) {
        x0[i] = k_pos[i] * 1e30f;
        x1[i] = x0[i] + 3e29f;
        c0[i] = k_pos[i] * 1e30f + 1e29f;
        c1[i] = c0[i];
    }
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c0, c1, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
    CHECK_RESULT(weft_ccd_intersect_frame(w, x0, c0, &in), WEFT_OK);
    weft_ccd_world_destroy(w);
    double P[24];
    for (int i = 0; i < 24; ++i) {
        P[i] = (i % 5) * 1e300;
    }
    double toi = -1;
    int hit = weft_ccd_vertex_face(P, 0, &toi);
    CHECK((hit == 0 || hit == 1) && toi >= 0.0 && toi <= 1.0);
    hit = weft_ccd_edge_edge(P, 0, &toi);
    CHECK((hit == 0 || hit == 1) && toi >= 0.0 && toi <= 1.0);
    double big[9] = {1e300, 0, 0, 0, 1e300, 0, 0, 0, 1e300}, nan9[9] = {NAN};
    hit = weft_ccd_triangles_intersect(big, big);
    CHECK(hit == 0 || hit == 1);
    CHECK_EQ_INT(weft_ccd_triangles_intersect(big, nan9), 1);
    weft_context_destroy(ctx);
}

/* The garment step runs the post-process when def.ccd is set and reports it in the stats; with
 * one back-off pass (def.ccd_iterations) the result is still above the ground. Bad pass counts
 * are refused. */
static void garment_step_ccd(uint32_t iterations)
{
    weft_context *ctx = ctx_make();
    enum { N = 6 };
    float rest[3 * N * N];
    uint32_t tris[6 * (N - 1) * (N - 1)];
    for (int i = 0; i < N; ++i) {
        for (int j = 0; j < N; ++j) {
            rest[3 * (i * N + j)] = 0.1f * (float)j;
            rest[3 * (i * N + j) + 1] = 0.02f;
            rest[3 * (i * N + j) + 2] = 0.1f * (float)i;
        }
    }
    int k = 0;
    for (int i = 0; i + 1 < N; ++i) {
        for (int j = 0; j + 1 < N; ++j) {
            uint32_t a = (uint32_t)(i * N + j);
            uint32_t t[6] = {a, a + N, a + 1, a + 1, a + N, a + N + 1};
            memcpy(tris + 6 * k++, t, sizeof t);
        }
    }
    /* A ground quad just below the cloth. */
    float ground[12] = {-1, 0, -1, 2, 0, -1, -1, 0, 2, 2, 0, 2};
    uint32_t gt[6] = {0, 2, 1, 1, 2, 3};
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_XPBD;
    gd.rest_positions = rest;
    gd.vertex_count = N * N;
    gd.triangles = tris;
    gd.triangle_count = 2 * (N - 1) * (N - 1);
    gd.collider_rest_positions = ground;
    gd.collider_vertex_count = 4;
    gd.collider_triangles = gt;
    gd.collider_triangle_count = 2;
    weft_garment *g = NULL;
    static const uint32_t bad[] = {0, 65, 1000};
    for (size_t b = 0; b < sizeof bad / sizeof bad[0]; ++b) {
        gd.ccd.iterations = bad[b];
        CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "ccd.iterations") != NULL);
    }
    gd.ccd.enabled = false;
    gd.ccd.iterations = 0; /* not looked at without CCD */
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    weft_garment_destroy(g);
    g = NULL;
    gd.ccd.enabled = true;
    gd.ccd.iterations = iterations;
    weft_result r = weft_garment_create(ctx, &gd, &g);
    CHECK_RESULT(r, WEFT_OK);
    if (r == WEFT_OK) {
        for (int f = 0; f < 30; ++f) {
            CHECK_RESULT(weft_garment_set_collider(g, ground), WEFT_OK);
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
            weft_step_stats s = weft_garment_stats(g);
            CHECK(s.ccd_iterations >= 1);
            CHECK(s.ccd_fallback || s.ccd_iterations <= iterations);
            const float *x = weft_garment_positions(g);
            for (int v = 0; v < N * N; ++v) {
                CHECK_MSG(x[3 * v + 1] > 0.0f, "frame %d vertex %d below the ground: %g", f, v, x[3 * v + 1]);
            }
        }
        weft_garment_destroy(g);
    }
    weft_context_destroy(ctx);
}

static void garment_step_reports_ccd(void) { garment_step_ccd(16); }
static void garment_step_one_ccd_pass(void) { garment_step_ccd(1); }

TEST_MAIN(TEST_CASE(malformed_defs), TEST_CASE(non_finite_frames), TEST_CASE(zero_area_and_huge),
          TEST_CASE(garment_step_reports_ccd), TEST_CASE(garment_step_one_ccd_pass))
