/* What every garment gets whatever its method: one mesh validation (a host falling back from the
 * learned model to XPBD never meets a mesh the second refuses), positions within
 * WEFT_MAX_COORDINATE everywhere (named as such, not as a degenerate triangle), and cuts: a
 * collider that jumps farther than collision.cut_distance resets the cloth to the skinned garment
 * at rest instead of sweeping it through the jump, single and batched. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <string.h>

#define MODEL_PATH WEFT_SOURCE_DIR "/tests/model/data/golden_model.safetensors"

static weft_context *ctx_;
static weft_model *model_;

static const weft_method methods_[] = {WEFT_METHOD_MODEL, WEFT_METHOD_XPBD, WEFT_METHOD_XPBD_FAST, WEFT_METHOD_LBS};
static const char *const method_names_[] = {"model", "xpbd", "xpbd-fast", "lbs"};
#define METHOD_COUNT 4

static void setup(void)
{
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx_), WEFT_OK);
    CHECK_RESULT(weft_model_load_file(ctx_, MODEL_PATH, &model_), WEFT_OK);
}

static weft_garment_def def_for(weft_method method, const test_mesh *cloth, const test_mesh *box)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = method;
    gd.model = method == WEFT_METHOD_MODEL ? model_ : NULL;
    gd.substeps = 4;
    gd.ccd.enabled = false;
    gd.rest_positions = cloth->pos;
    gd.vertex_count = cloth->nv;
    gd.triangles = cloth->tris;
    gd.triangle_count = cloth->nt;
    gd.collider_rest_positions = box->pos;
    gd.collider_vertex_count = box->nv;
    gd.collider_triangles = box->tris;
    gd.collider_triangle_count = box->nt;
    return gd;
}

static test_mesh box_mesh(void)
{
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    return test_box(lo, hi);
}

/* Each bad mesh is refused by every method with the same message. */
static void test_same_mesh_rules_for_every_method(void)
{
    test_mesh box = box_mesh();
    /* three triangles on edge (0, 1) */
    float nm_pos[] = {0, 0.5f, 0, 0.1f, 0.5f, 0, 0.05f, 0.5f, 0.1f, 0.05f, 0.5f, -0.1f, 0.05f, 0.6f, 0};
    uint32_t nm_tris[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    /* the same triangle twice, once flipped */
    float dup_pos[] = {0, 0.5f, 0, 0.1f, 0.5f, 0, 0, 0.5f, 0.1f};
    uint32_t dup_tris[] = {0, 1, 2, 1, 0, 2};
    /* vertex 3 in no triangle */
    float iso_pos[] = {0, 0.5f, 0, 0.1f, 0.5f, 0, 0, 0.5f, 0.1f, 0.3f, 0.5f, 0.3f};
    uint32_t iso_tris[] = {0, 1, 2};
    const struct {
        test_mesh mesh;
        const char *says;
    } bad[] = {
        {{nm_pos, nm_tris, 5, 3}, "non-manifold edge"},
        {{dup_pos, dup_tris, 3, 2}, "are duplicates"},
        {{iso_pos, iso_tris, 4, 1}, "vertex 3 belongs to no triangle"},
    };
    for (size_t b = 0; b < sizeof bad / sizeof bad[0]; ++b) {
        for (int m = 0; m < METHOD_COUNT; ++m) {
            weft_garment_def gd = def_for(methods_[m], &bad[b].mesh, &box);
            weft_garment *g = (weft_garment *)&gd; /* must be left alone */
            CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_DEGENERATE_MESH);
            CHECK_MSG(strstr(weft_last_error(), bad[b].says) != NULL, "%s: %s", method_names_[m], weft_last_error());
            CHECK_MSG(strstr(weft_last_error(), "garment rest mesh") != NULL, "%s: %s", method_names_[m],
                      weft_last_error());
            CHECK(g == (weft_garment *)&gd);
        }
    }
    test_mesh_free(&box);
}

/* A 1e38 coordinate is out of range (not "zero area"); inputs beyond 10 km are refused with the
 * state untouched; a step is never handed such a collider. */
static void test_coordinates_beyond_range(void)
{
    test_mesh box = box_mesh();
    test_mesh sheet = test_sheet(6, 6, 0.4f, 0.4f, 0.0f, 0.21f, 0.0f);
    for (int m = 0; m < METHOD_COUNT; ++m) {
        weft_garment_def gd = def_for(methods_[m], &sheet, &box);
        const float keep = sheet.pos[4];
        sheet.pos[4] = 1e38f;
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_NOT_FINITE);
        CHECK_MSG(strstr(weft_last_error(), "vertex 1 has coordinate 1e+38, beyond") != NULL, "%s",
                  weft_last_error());
        CHECK(strstr(weft_last_error(), "zero area") == NULL);
        sheet.pos[4] = keep;

        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
        float *c = malloc(sizeof(float) * 3 * box.nv);
        memcpy(c, box.pos, sizeof(float) * 3 * box.nv);
        c[0] = 2.0e4f; /* 20 km */
        CHECK_RESULT(weft_garment_set_collider(g, c), WEFT_ERROR_NOT_FINITE);
        CHECK(strstr(weft_last_error(), "WEFT_MAX_COORDINATE") != NULL);
        CHECK_RESULT(weft_garment_step(g), WEFT_ERROR_NO_COLLIDER); /* the bad collider was not taken */
        CHECK_RESULT(weft_garment_set_collider_current(g, c), WEFT_ERROR_NOT_FINITE);
        float *x = malloc(sizeof(float) * 3 * sheet.nv);
        memcpy(x, sheet.pos, sizeof(float) * 3 * sheet.nv);
        x[5] = -1.5e4f;
        CHECK_RESULT(weft_garment_set_state(g, x, NULL), WEFT_ERROR_NOT_FINITE);
        CHECK(memcmp(weft_garment_positions(g), sheet.pos, sizeof(float) * 3 * sheet.nv) == 0);
        const uint32_t pin = 0;
        CHECK_RESULT(weft_garment_set_pins(g, &pin, x + 3, 1), WEFT_ERROR_NOT_FINITE);
        CHECK_EQ_INT(weft_garment_pin_count(g), 0);
        free(x);
        free(c);
        weft_garment_destroy(g);
    }
    test_mesh_free(&sheet);
    test_mesh_free(&box);
}

/* The box teleported by `jump` at frame 3 of a slow slide: the step is a cut and the cloth is its
 * initial state carried by the box (a translation: the binding is rigid-invariant), at rest. */
static void test_cut_resets_to_the_skinned_garment(void)
{
    test_mesh box = box_mesh();
    test_mesh sheet = test_sheet(8, 8, 0.4f, 0.4f, 0.0f, 0.22f, 0.0f);
    float *c = malloc(sizeof(float) * 3 * box.nv);
    for (int m = 0; m < METHOD_COUNT; ++m) {
        weft_garment_def gd = def_for(methods_[m], &sheet, &box);
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
        const float jump[3] = {5.0f, 0.0f, -2.0f};
        for (int f = 1; f <= 4; ++f) {
            const float dx = 0.01f * (float)f + (f >= 3 ? jump[0] : 0.0f);
            const float dz = f >= 3 ? jump[2] : 0.0f;
            for (uint32_t i = 0; i < box.nv; ++i) {
                c[3 * i] = box.pos[3 * i] + dx;
                c[3 * i + 1] = box.pos[3 * i + 1];
                c[3 * i + 2] = box.pos[3 * i + 2] + dz;
            }
            CHECK_RESULT(weft_garment_set_collider(g, c), WEFT_OK);
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
            const weft_step_stats st = weft_garment_stats(g);
            CHECK_MSG(st.collider_cut == (f == 3), "%s frame %d: cut %d", method_names_[m], f, (int)st.collider_cut);
            /* the stage split of step_ms: parts within the whole; a cut runs no stage */
            CHECK(st.method_ms >= 0.0 && st.constraints_ms >= 0.0 && st.ccd_ms >= 0.0);
            CHECK(st.method_ms + st.constraints_ms + st.ccd_ms <= st.step_ms + 1e-6);
            CHECK(f != 3 || (st.method_ms == 0.0 && st.constraints_ms == 0.0 && st.ccd_ms == 0.0));
            CHECK_EQ_INT(st.frame, (uint64_t)f);
            if (f == 3) {
                const float *x = weft_garment_positions(g);
                float worst = 0.0f;
                for (uint32_t i = 0; i < sheet.nv; ++i) {
                    const float d[3] = {x[3 * i] - (sheet.pos[3 * i] + dx), x[3 * i + 1] - sheet.pos[3 * i + 1],
                                        x[3 * i + 2] - (sheet.pos[3 * i + 2] + dz)};
                    worst = fmaxf(worst, sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
                }
                CHECK_MSG(worst < 1e-4f, "%s: cut state %g m from the skinned garment", method_names_[m],
                          (double)worst);
            }
        }
        weft_garment_destroy(g);

        /* cut_distance 0: the jump is stepped through (no cut) */
        gd.collision.cut_distance = 0.0f;
        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
        for (uint32_t i = 0; i < 3 * box.nv; ++i) {
            c[i] = box.pos[i] + (i % 3 == 0 ? 5.0f : 0.0f);
        }
        CHECK_RESULT(weft_garment_set_collider(g, c), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        CHECK(!weft_garment_stats(g).collider_cut);
        weft_garment_destroy(g);

        gd.collision.cut_distance = -1.0f;
        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(strstr(weft_last_error(), "collision.cut_distance") != NULL);
    }
    free(c);
    test_mesh_free(&sheet);
    test_mesh_free(&box);
}

/* Batched: a crowd where one character teleports. It is cut, the others step as alone. */
static void test_cut_in_a_batch(void)
{
    test_mesh box = box_mesh();
    test_mesh sheet = test_sheet(8, 8, 0.4f, 0.4f, 0.0f, 0.22f, 0.0f);
    float *c = malloc(sizeof(float) * 3 * box.nv);
    float *far = malloc(sizeof(float) * 3 * box.nv);
    for (uint32_t i = 0; i < 3 * box.nv; ++i) {
        c[i] = box.pos[i] + (i % 3 == 0 ? 0.01f : 0.0f);
        far[i] = box.pos[i] + (i % 3 == 1 ? 3.0f : 0.0f);
    }
    weft_garment_def gd = def_for(WEFT_METHOD_MODEL, &sheet, &box);
    weft_garment *g[3] = {NULL, NULL, NULL}, *alone = NULL;
    for (int k = 0; k < 3; ++k) {
        CHECK_RESULT(weft_garment_create(ctx_, &gd, &g[k]), WEFT_OK);
    }
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &alone), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g[0], far), WEFT_OK); /* the one that teleports leads */
    CHECK_RESULT(weft_garment_set_collider(g[1], c), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g[2], c), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(alone, c), WEFT_OK);
    CHECK_RESULT(weft_garments_step(g, 3), WEFT_OK);
    CHECK_RESULT(weft_garment_step(alone), WEFT_OK);
    CHECK(weft_garment_stats(g[0]).collider_cut);
    CHECK_NEAR(weft_garment_positions(g[0])[1], sheet.pos[1] + 3.0f, 1e-4);
    for (int k = 1; k < 3; ++k) {
        CHECK(!weft_garment_stats(g[k]).collider_cut);
        CHECK_EQ_INT(weft_garment_stats(g[k]).frame, 1);
        CHECK(memcmp(weft_garment_positions(g[k]), weft_garment_positions(alone), sizeof(float) * 3 * sheet.nv) == 0);
    }
    for (int k = 0; k < 3; ++k) {
        weft_garment_destroy(g[k]);
    }
    weft_garment_destroy(alone);
    free(far);
    free(c);
    test_mesh_free(&sheet);
    test_mesh_free(&box);
}

/* CCD's work bound at the garment: a two-triangle 1 m patch pinned and dragged 40 cm across and
 * 2 cm down a frame, through a 20,000-triangle floor, overlaps every floor triangle: more pairs
 * than the bound (64 per cloth triangle plus 16384). The step says so and keeps the stages'
 * result (the pins' targets, as without CCD) instead of holding the patch where it was. */
static void test_ccd_over_budget_keeps_the_step(void)
{
    test_mesh floor_mesh = test_sheet(101, 101, 1.0f, 1.0f, 0.0f, 0.0f, 0.0f);
    float patch_pos[] = {-0.5f, 0.01f, -0.5f, 0.5f, 0.01f, -0.5f, 0.5f, 0.01f, 0.5f, -0.5f, 0.01f, 0.5f};
    uint32_t patch_tris[] = {0, 2, 1, 0, 3, 2};
    const test_mesh patch = {patch_pos, patch_tris, 4, 2};
    weft_garment_def gd = def_for(WEFT_METHOD_LBS, &patch, &floor_mesh);
    weft_garment *with = NULL, *without = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &without), WEFT_OK);
    gd.ccd.enabled = true;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &with), WEFT_OK);
    const uint32_t pins[4] = {0, 1, 2, 3};
    float targets[12];
    for (int f = 1; f <= 2; ++f) {
        for (int i = 0; i < 12; ++i) {
            targets[i] = patch_pos[i] + (i % 3 == 0 ? 0.4f * (float)f : i % 3 == 1 ? -0.02f * (float)f : 0.0f);
        }
        weft_garment *both[2] = {with, without};
        for (int k = 0; k < 2; ++k) {
            CHECK_RESULT(weft_garment_set_pins(both[k], pins, targets, 4), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(both[k], floor_mesh.pos), WEFT_OK);
            CHECK_RESULT(weft_garment_step(both[k]), WEFT_OK);
        }
        const weft_step_stats st = weft_garment_stats(with);
        /* frame 1 crosses the floor; frame 2 stays under it, where no box meets the floor's */
        CHECK_MSG(st.ccd_over_budget == (f == 1) && !st.collider_cut, "frame %d", f);
        CHECK(memcmp(weft_garment_positions(with), weft_garment_positions(without), sizeof patch_pos) == 0);
        CHECK(memcmp(weft_garment_positions(with), targets, sizeof targets) == 0);
    }
    weft_garment_destroy(with);
    weft_garment_destroy(without);
    test_mesh_free(&floor_mesh);
}

static void teardown(void)
{
    weft_model_destroy(model_);
    weft_context_destroy(ctx_);
}

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_same_mesh_rules_for_every_method), TEST_CASE(test_coordinates_beyond_range),
          TEST_CASE(test_cut_resets_to_the_skinned_garment), TEST_CASE(test_cut_in_a_batch),
          TEST_CASE(test_ccd_over_budget_keeps_the_step), TEST_CASE(teardown))
