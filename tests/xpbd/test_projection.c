/* The reference XPBD with its collider projected (weft_garment_def.collider_projection), the
 * reference on real motion: cloth a body has passed gets out instead of being held inside by the
 * bounded contacts; a body faster than the cloth's bounds per substep raises the substeps and
 * carries the cloth; cloth-cloth contacts keep their bounds, so
 * stacked sheets on a box never cross (exact validator); without a collider nothing changes; the
 * exported state after the constraint stage moved the cloth resumes bit for bit. */
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

static weft_garment *make_ref(weft_context *ctx, const test_mesh *cloth, const test_mesh *collider, uint32_t substeps,
                              bool projection)
{
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD, cloth, collider, substeps);
    gd.substeps_max = 8 * substeps;
    gd.collider_projection = projection;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    return g;
}

static bool in_box(const float *p, const float lo[3], const float hi[3])
{
    return p[0] > lo[0] && p[0] < hi[0] && p[1] > lo[1] && p[1] < hi[1] && p[2] > lo[2] && p[2] < hi[2];
}

/* A patch 1 cm below a box's top face, inside it (a limb that passed through the cloth): one
 * projected step puts every vertex above the top face; the bounded contacts keep it inside. */
static void test_cloth_inside_gets_out(void)
{
    weft_context *ctx = make_ctx();
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    test_mesh box = test_box(lo, hi);
    test_mesh patch = test_sheet(9, 9, 0.1f, 0.1f, 0.0f, 0.19f, 0.0f);
    uint32_t inside[2] = {0, 0};
    for (int projection = 0; projection < 2; ++projection) {
        weft_garment *g = make_ref(ctx, &patch, &box, 10, projection != 0);
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        const float *x = weft_garment_positions(g);
        for (uint32_t i = 0; i < patch.nv; ++i) {
            inside[projection] += in_box(x + 3 * i, lo, hi);
            if (projection) {
                CHECK_MSG(x[3 * i + 1] > hi[1], "vertex %u at %g, the top face at %g", i, x[3 * i + 1], hi[1]);
            }
        }
        weft_garment_destroy(g);
    }
    CHECK_MSG(inside[0] == patch.nv, "the bounded reference let %u of %u vertices out", patch.nv - inside[0], patch.nv);
    CHECK_EQ_INT(inside[1], 0);
    test_mesh_free(&patch);
    test_mesh_free(&box);
    weft_context_destroy(ctx);
}

/* A box lifts a sheet resting on it at 3.6 m/s, 6 mm per substep at S = 10, more than the
 * sheet's cloth-cloth bounds let a vertex move in a substep: the moving frames take more substeps
 * (up to substeps_max), the still ones 10, and the projection carries the sheet up. */
static void test_fast_body_raised_substeps(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(11, 11, 0.16f, 0.16f, 0.0f, 0.2025f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    test_mesh box = test_box(lo, hi);
    weft_garment *g = make_ref(ctx, &sheet, &box, 10, true);
    float top = hi[1];
    for (int f = 0; f < 15; ++f) {
        const float rise = test_lift_box(&box, f);
        top += rise;
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        const uint32_t S = weft__xpbd_last_stats(g).substeps;
        CHECK_MSG(rise > 0.0f ? S > 10 && S <= 80 : S == 10, "frame %d: %u substeps", f, S);
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

/* Two sheets 2 cm apart fall onto a box: the bounded cloth-cloth contacts hold under the
 * projected collider, every frame certified by the exact validator on the cloth alone, and the
 * upper sheet ends on the lower one, the lower one on the box. */
static void test_layers_stay_certified(void)
{
    weft_context *ctx = make_ctx();
    test_mesh a = test_sheet(15, 15, 0.4f, 0.4f, 0.0f, 0.25f, 0.0f);
    test_mesh b = test_sheet(15, 15, 0.4f, 0.4f, 0.03f, 0.27f, 0.02f);
    test_mesh both = test_mesh_join(&a, &b);
    CHECK(both.pos && both.tris);
    const float lo[3] = {-0.1f, 0.0f, -0.1f}, hi[3] = {0.1f, 0.2f, 0.1f};
    test_mesh box = test_box(lo, hi);
    weft_garment *g = make_ref(ctx, &both, &box, 10, true);
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, both.tris, both.nt, both.nv, NULL, 0, 0, &v), WEFT_OK);
    float *prev = malloc(sizeof(float) * 3 * both.nv);
    CHECK(prev != NULL);
    uint32_t hits = 0;
    for (int f = 0; f < 60; ++f) {
        memcpy(prev, weft_garment_positions(g), sizeof(float) * 3 * both.nv);
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        weft_sim_validation val;
        CHECK_RESULT(weft_sim_validator_check(v, prev, weft_garment_positions(g), NULL, NULL, &val), WEFT_OK);
        hits += val.ccd_hits + val.intersection_hits;
    }
    CHECK_MSG(hits == 0, "%u cloth-cloth hits", hits);
    const float *x = weft_garment_positions(g);
    float centre_a, top_b_min;
    test_two_layer_heights(x, a.nv, b.nv, &centre_a, &top_b_min);
    CHECK_MSG(centre_a > 0.2f && centre_a < 0.21f, "lower sheet's centre at %g", centre_a);
    CHECK_MSG(top_b_min > centre_a, "upper sheet %g, lower sheet %g", top_b_min, centre_a);
    free(prev);
    weft_sim_validator_destroy(v);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&both);
    weft_context_destroy(ctx);
}

/* Without a collider the setting changes nothing: a falling sheet, bit for bit. */
static void test_no_collider_unchanged(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(9, 9, 0.3f, 0.3f, 0.0f, 1.0f, 0.0f);
    float *out[2];
    for (int projection = 0; projection < 2; ++projection) {
        weft_garment *g = make_ref(ctx, &sheet, NULL, 10, projection != 0);
        for (int f = 0; f < 20; ++f) {
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        }
        out[projection] = malloc(sizeof(float) * 3 * sheet.nv);
        CHECK(out[projection] != NULL);
        memcpy(out[projection], weft_garment_positions(g), sizeof(float) * 3 * sheet.nv);
        weft_garment_destroy(g);
    }
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * sheet.nv) == 0);
    free(out[0]);
    free(out[1]);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

/* The constraint stage (a 1 cm push: the projection leaves cloth at the 2.5 mm contact radius)
 * moves the cloth after the solve. The state exported then is the positions the next step starts
 * from, so importing it into a second garment resumes the first one's next frames bit for bit
 * (simgen's checkpoints). */
static void test_export_after_constraints(void)
{
    weft_context *ctx = make_ctx();
    test_mesh sheet = test_sheet(9, 9, 0.4f, 0.4f, 0.0f, 0.25f, 0.0f);
    const float lo[3] = {-0.1f, 0.0f, -0.1f}, hi[3] = {0.1f, 0.2f, 0.1f};
    test_mesh box = test_box(lo, hi);
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD, &sheet, &box, 10);
    gd.collider_projection = true;
    gd.collision.push = 0.01f;
    weft_garment *a = NULL, *b = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &a), WEFT_OK);
    CHECK_RESULT(weft_garment_create(ctx, &gd, &b), WEFT_OK);
    const size_t n3 = 3 * (size_t)sheet.nv;
    float *prev = malloc(sizeof(float) * n3);
    double *state = malloc(sizeof(double) * 2 * n3);
    CHECK(prev && state);
    uint32_t clamped = 0;
    for (int f = 0; f < 20; ++f) {
        memcpy(prev, weft_garment_positions(a), sizeof(float) * n3);
        CHECK_RESULT(weft_garment_set_collider(a, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(a), WEFT_OK);
        clamped += weft_garment_stats(a).pushed_vertices;
    }
    CHECK_MSG(clamped > 0, "the push never moved the cloth");
    CHECK_RESULT(weft__xpbd_export_state(a, state, state + n3), WEFT_OK);
    CHECK_RESULT(weft_garment_set_state(b, weft_garment_positions(a), prev), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider_current(b, box.pos), WEFT_OK);
    CHECK_RESULT(weft__xpbd_import_state(b, state, state + n3), WEFT_OK);
    for (int f = 0; f < 5; ++f) {
        CHECK_RESULT(weft_garment_set_collider(a, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(a), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(b, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(b), WEFT_OK);
        CHECK_MSG(memcmp(weft_garment_positions(a), weft_garment_positions(b), sizeof(float) * n3) == 0,
                  "frame %d after the import differs", f);
    }
    free(prev);
    free(state);
    weft_garment_destroy(a);
    weft_garment_destroy(b);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_cloth_inside_gets_out), TEST_CASE(test_fast_body_raised_substeps),
          TEST_CASE(test_layers_stay_certified), TEST_CASE(test_no_collider_unchanged),
          TEST_CASE(test_export_after_constraints))
