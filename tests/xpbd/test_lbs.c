/* The LBS baseline: a garment bound to a rigidly moving collider follows it exactly. */
#include "scene.h"
#include "test.h"
#include "xpbd/xpbd.h"

static void rigid(const float *in, float *out, uint32_t n, double yaw, double pitch, const double t[3])
{
    double cy = cos(yaw), sy = sin(yaw), cp = cos(pitch), sp = sin(pitch);
    for (uint32_t i = 0; i < n; ++i) {
        double x = in[3 * i], y = in[3 * i + 1], z = in[3 * i + 2];
        double x1 = cy * x + sy * z, z1 = -sy * x + cy * z;  /* yaw about Y */
        double y2 = cp * y - sp * z1, z2 = sp * y + cp * z1; /* pitch about X */
        out[3 * i] = (float)(x1 + t[0]);
        out[3 * i + 1] = (float)(y2 + t[1]);
        out[3 * i + 2] = (float)(z2 + t[2]);
    }
}

static void test_lbs_follows_rigid_motion(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    /* A sheet hovering 1 cm over the top of a box and overhanging it. */
    test_mesh sheet = test_sheet(12, 12, 0.5f, 0.5f, 0.0f, 0.21f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    test_mesh box = test_box(lo, hi);
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_LBS;
    gd.ccd.enabled = false;
    gd.rest_positions = sheet.pos;
    gd.vertex_count = sheet.nv;
    gd.triangles = sheet.tris;
    gd.triangle_count = sheet.nt;
    gd.collider_rest_positions = box.pos;
    gd.collider_vertex_count = box.nv;
    gd.collider_triangles = box.tris;
    gd.collider_triangle_count = box.nt;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    float *moved = malloc(sizeof(float) * 3 * box.nv), *expect = malloc(sizeof(float) * 3 * sheet.nv);
    double max_err = 0.0;
    for (int f = 1; f <= 60; ++f) {
        double t[3] = {0.01 * f, 0.3 * sin(0.1 * f), -0.005 * f};
        double yaw = 0.05 * f, pitch = 0.4 * sin(0.07 * f);
        rigid(box.pos, moved, box.nv, yaw, pitch, t);
        rigid(sheet.pos, expect, sheet.nv, yaw, pitch, t);
        CHECK_RESULT(weft_garment_set_collider(g, moved), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        const float *x = weft_garment_positions(g);
        for (uint32_t i = 0; i < 3 * sheet.nv; ++i) {
            max_err = fmax(max_err, fabs(x[i] - expect[i]));
        }
    }
    /* float32 collider input: exact up to rounding (a few micrometres at this scale) */
    CHECK_MSG(max_err < 5e-6, "max deviation from the rigid motion %g m", max_err);
    /* A pin overrides the skinned position of its vertex after the step; the others still follow. */
    uint32_t pin = 0;
    const float target[3] = {0.3f, 0.4f, 0.5f};
    CHECK_RESULT(weft_garment_set_pins(g, &pin, target, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g, moved), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    CHECK(memcmp(weft_garment_positions(g), target, sizeof target) == 0);
    CHECK_NEAR(weft_garment_positions(g)[3], expect[3], 5e-6);
    free(moved);
    free(expect);
    weft_garment_destroy(g);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

static void test_lbs_needs_collider(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(4, 4, 0.5f, 0.5f, 0.0f, 0.0f, 0.0f);
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_LBS;
    gd.rest_positions = sheet.pos;
    gd.vertex_count = sheet.nv;
    gd.triangles = sheet.tris;
    gd.triangle_count = sheet.nt;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_NO_COLLIDER);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "lbs") != NULL);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_lbs_follows_rigid_motion), TEST_CASE(test_lbs_needs_collider))
