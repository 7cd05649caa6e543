/* The fast XPBD method (WEFT_METHOD_XPBD_FAST): the reference's material and substeps with a
 * game engine's collision projection. Free fall is the reference's integrator; a sheet rests on
 * a box at the collider radius; stacked sheets stay stacked; a collider moving faster than the
 * contact radius per substep still carries the cloth out of its nearest face; pins hold; runs
 * are bitwise deterministic; fixed substeps only. */
#include "scene.h"
#include "test.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

#include <string.h>

static weft_context *make_ctx(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

static weft_garment *make_fast(weft_context *ctx, const test_mesh *cloth, const test_mesh *collider, uint32_t substeps)
{
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD_FAST, cloth, collider, substeps);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    return g;
}

/* Frames of a garment over a standing collider; returns the frames whose cloth triangles
 * intersect each other (the validator's exact test on the cloth alone). The collider is left out:
 * vertex projection keeps the cloth's vertices out of it, but a cloth triangle spanning a box's
 * edge still cuts the corner (no edge or collider-vertex tests; docs/REFSIM.md). */
static uint32_t run_frames(weft_context *ctx, weft_garment *g, const test_mesh *cloth, const test_mesh *box, int frames)
{
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, cloth->tris, cloth->nt, cloth->nv, NULL, 0, 0, &v), WEFT_OK);
    float *prev = malloc(sizeof(float) * 3 * cloth->nv);
    CHECK(prev != NULL);
    uint32_t cut = 0;
    for (int f = 0; f < frames; ++f) {
        memcpy(prev, weft_garment_positions(g), sizeof(float) * 3 * cloth->nv);
        CHECK_RESULT(weft_garment_set_collider(g, box->pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        weft_sim_validation val;
        CHECK_RESULT(weft_sim_validator_check(v, prev, weft_garment_positions(g), NULL, NULL, &val), WEFT_OK);
        cut += val.intersection_hits > 0;
    }
    free(prev);
    weft_sim_validator_destroy(v);
    return cut;
}

static void test_free_fall(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(10, 10, 1.0f, 1.0f, 0.0f, 2.0f, 0.0f);
    const uint32_t S = 10, frames = 30;
    weft_garment *g = make_fast(ctx, &sheet, NULL, S);
    for (uint32_t f = 0; f < frames; ++f) {
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    }
    /* Symplectic Euler per substep from rest: every vertex of a flat, unstrained sheet falls
     * g h^2 K (K + 1) / 2 after K substeps (the constraints stay satisfied). */
    const float *x = weft_garment_positions(g);
    const double K = (double)S * frames, h = 1.0 / (60.0 * S);
    const double expect = 2.0 - 9.81 * h * h * K * (K + 1) / 2.0;
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        CHECK_MSG(fabs(x[3 * i + 1] - expect) < 1e-4, "vertex %u at %g, expected %g", i, x[3 * i + 1], expect);
    }
    weft_garment_destroy(g);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_sheet_on_box(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(21, 21, 0.6f, 0.6f, 0.0f, 0.3f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    test_mesh box = test_box(lo, hi);
    weft_garment *g = make_fast(ctx, &sheet, &box, 20);
    const uint32_t cut = run_frames(ctx, g, &sheet, &box, 90);
    CHECK_MSG(cut == 0, "%u frames with intersecting triangles", cut);
    const float *x = weft_garment_positions(g);
    int on_top = 0;
    float lowest = 1e9f;
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        const float *p = x + 3 * i;
        if (fabsf(p[0]) < 0.1f && fabsf(p[2]) < 0.1f) {
            on_top++;
            /* held at the collider radius (2.5 mm) above the top face */
            CHECK_MSG(p[1] > 0.2f && p[1] < 0.21f, "vertex %u at height %g above the box top", i, p[1]);
        }
        const bool in_box = p[0] > lo[0] && p[0] < hi[0] && p[1] > lo[1] && p[1] < hi[1] && p[2] > lo[2] && p[2] < hi[2];
        CHECK_MSG(!in_box, "vertex %u inside the box at (%g, %g, %g)", i, p[0], p[1], p[2]);
        lowest = fminf(lowest, p[1]);
    }
    CHECK(on_top > 20);
    CHECK(lowest < 0.15f); /* the overhang drapes down the sides */
    xpbd_frame_stats st = weft__xpbd_last_stats(g);
    CHECK_EQ_INT(st.substeps, 20);
    CHECK(st.contacts > 0);
    /* the nearest approach before the projection: inside the radius, never through the face */
    CHECK(st.min_collider_distance > 0.0 && st.min_collider_distance < 0.0025);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_two_layers(void)
{
    /* Two disconnected sheets in one garment, 2 cm apart, fall onto a box: vertex-triangle
     * projection keeps the upper one on the lower one. */
    weft_context *ctx = make_ctx();
    test_mesh a = test_sheet(15, 15, 0.4f, 0.4f, 0.0f, 0.25f, 0.0f);
    test_mesh b = test_sheet(15, 15, 0.4f, 0.4f, 0.03f, 0.27f, 0.02f);
    test_mesh both = test_mesh_join(&a, &b);
    CHECK(both.pos && both.tris);
    const float lo[3] = {-0.1f, 0.0f, -0.1f}, hi[3] = {0.1f, 0.2f, 0.1f};
    test_mesh box = test_box(lo, hi);
    weft_garment *g = make_fast(ctx, &both, &box, 20);
    const uint32_t cut = run_frames(ctx, g, &both, &box, 60);
    CHECK_MSG(cut == 0, "%u frames with intersecting cloth triangles", cut);
    const float *x = weft_garment_positions(g);
    float centre_a, top_b_min;
    test_two_layer_heights(x, a.nv, b.nv, &centre_a, &top_b_min);
    CHECK_MSG(centre_a > 0.2f && centre_a < 0.21f, "lower sheet's centre at %g", centre_a);
    CHECK_MSG(top_b_min > centre_a, "upper sheet %g, lower sheet %g", top_b_min, centre_a);
    CHECK(weft__xpbd_last_stats(g).min_self_distance > 0.0);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&both);
    weft_context_destroy(ctx);
}

/* A box lifts a sheet resting on it at 3.6 m/s (6 mm per substep at S = 10, more than the 2.5 mm
 * contact radius). The reference's bounds need more substeps there (xpbd.physics_fast_collider);
 * the projection pushes the vertices the top face overtook back out of it, so the sheet rides up. */
static void test_lifting_box(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(11, 11, 0.16f, 0.16f, 0.0f, 0.2025f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    test_mesh box = test_box(lo, hi);
    weft_garment *g = make_fast(ctx, &sheet, &box, 10);
    float top = hi[1];
    for (int f = 0; f < 15; ++f) {
        const float rise = test_lift_box(&box, f);
        top += rise;
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    }
    const float *x = weft_garment_positions(g);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        CHECK_MSG(x[3 * i + 1] > top, "vertex %u at %g, box top at %g", i, x[3 * i + 1], top);
    }
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_pins(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(9, 9, 0.4f, 0.4f, 0.0f, 1.0f, 0.0f);
    weft_garment *g = make_fast(ctx, &sheet, NULL, 10);
    const uint32_t idx[2] = {0, 8};
    float tgt[6];
    for (int f = 0; f < 60; ++f) {
        for (int k = 0; k < 2; ++k) { /* the two corners drift sideways at 0.3 m/s */
            tgt[3 * k + 0] = sheet.pos[3 * idx[k]] + 0.005f * (float)(f + 1);
            tgt[3 * k + 1] = sheet.pos[3 * idx[k] + 1];
            tgt[3 * k + 2] = sheet.pos[3 * idx[k] + 2];
        }
        CHECK_RESULT(weft_garment_set_pins(g, idx, tgt, 2), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    }
    const float *x = weft_garment_positions(g);
    for (int k = 0; k < 2; ++k) {
        for (int a = 0; a < 3; ++a) {
            CHECK_MSG(fabsf(x[3 * idx[k] + a] - tgt[3 * k + a]) < 1e-6f, "pin %u axis %d: %g vs %g", idx[k], a,
                      x[3 * idx[k] + a], tgt[3 * k + a]);
        }
    }
    /* The free corner opposite hangs below the pinned edge. */
    CHECK(x[3 * 80 + 1] < 0.75f);
    weft_garment_destroy(g);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_determinism(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(17, 17, 0.5f, 0.5f, 0.02f, 0.25f, -0.01f);
    const float lo[3] = {-0.1f, 0.0f, -0.1f}, hi[3] = {0.1f, 0.2f, 0.1f};
    test_mesh box = test_box(lo, hi);
    float *out[2];
    for (int run = 0; run < 2; ++run) {
        weft_garment *g = make_fast(ctx, &sheet, &box, 10);
        for (int f = 0; f < 40; ++f) {
            CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        }
        out[run] = malloc(sizeof(float) * 3 * sheet.nv);
        CHECK(out[run] != NULL);
        memcpy(out[run], weft_garment_positions(g), sizeof(float) * 3 * sheet.nv);
        weft_garment_destroy(g);
    }
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * sheet.nv) == 0);
    free(out[0]);
    free(out[1]);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_bad_input(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(5, 5, 0.2f, 0.2f, 0.0f, 0.5f, 0.0f);
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD_FAST, &sheet, NULL, 10);
    weft_garment *g = NULL;
    gd.substeps_max = 40; /* adaptive substeps belong to the reference */
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "fixed substeps") != NULL);
    gd.substeps_max = 0;
    gd.substeps = 0;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    gd.substeps = 1001;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    gd.substeps = 5;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    /* The reference's own knobs are not the fast method's. */
    double *state = malloc(sizeof(double) * 6 * sheet.nv);
    CHECK(state != NULL);
    CHECK_RESULT(weft__xpbd_export_state(g, state, state + 3 * sheet.nv), WEFT_ERROR_INVALID_ARGUMENT);
    free(state);
    /* A NaN state is refused and leaves the garment as it was. */
    float *bad = malloc(sizeof(float) * 3 * sheet.nv);
    CHECK(bad != NULL);
    memcpy(bad, sheet.pos, sizeof(float) * 3 * sheet.nv);
    bad[7] = NAN;
    CHECK(weft_garment_set_state(g, bad, NULL) != WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    CHECK(isfinite(weft_garment_positions(g)[7]));
    free(bad);
    weft_garment_destroy(g);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_free_fall), TEST_CASE(test_sheet_on_box), TEST_CASE(test_two_layers),
          TEST_CASE(test_lifting_box), TEST_CASE(test_pins), TEST_CASE(test_determinism), TEST_CASE(test_bad_input))
