/* Mesh maps (weft/lod.h): a fine mesh bound to a coarse one reproduces the coarse mesh's rest
 * shape and rigid motions exactly, follows a fold, and bad input fails cleanly with the output
 * untouched. */
#include "../xpbd/scene.h"
#include "test.h"
#include "weft/lod.h"

#include <math.h>
#include <string.h>

static void rigid(const float *in, float *out, uint32_t n, double yaw, const double t[3])
{
    double c = cos(yaw), s = sin(yaw);
    for (uint32_t i = 0; i < n; ++i) {
        double x = in[3 * i], y = in[3 * i + 1], z = in[3 * i + 2];
        out[3 * i] = (float)(c * x + s * z + t[0]);
        out[3 * i + 1] = (float)(y + t[1]);
        out[3 * i + 2] = (float)(-s * x + c * z + t[2]);
    }
}

static double max_abs_diff(const float *a, const float *b, size_t n)
{
    double worst = 0.0;
    for (size_t i = 0; i < n; ++i) {
        worst = fmax(worst, fabs((double)a[i] - (double)b[i]));
    }
    return worst;
}

static void test_mesh_map_rest_rigid_and_fold(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh coarse = test_sheet(9, 9, 0.4f, 0.4f, 0.0f, 1.0f, 0.0f);
    test_mesh fine = test_sheet(33, 33, 0.4f, 0.4f, 0.0f, 1.0f, 0.0f);
    weft_mesh_map_def md = weft_default_mesh_map_def();
    md.from_rest_positions = coarse.pos;
    md.from_vertex_count = coarse.nv;
    md.from_triangles = coarse.tris;
    md.from_triangle_count = coarse.nt;
    md.to_rest_positions = fine.pos;
    md.to_vertex_count = fine.nv;
    weft_mesh_map *map = NULL;
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_OK);
    CHECK_EQ_INT(weft_mesh_map_from_vertex_count(map), coarse.nv);
    CHECK_EQ_INT(weft_mesh_map_to_vertex_count(map), fine.nv);
    float *out = malloc(sizeof(float) * 3 * fine.nv), *expect = malloc(sizeof(float) * 3 * fine.nv);
    float *moved = malloc(sizeof(float) * 3 * coarse.nv);

    CHECK_RESULT(weft_mesh_map_apply(map, coarse.pos, out), WEFT_OK);
    double e_rest = max_abs_diff(out, fine.pos, 3 * (size_t)fine.nv);
    CHECK_MSG(e_rest < 1e-6, "rest shape reproduced to %g m", e_rest);

    const double t[3] = {0.3, -0.2, 0.7};
    rigid(coarse.pos, moved, coarse.nv, 0.8, t);
    rigid(fine.pos, expect, fine.nv, 0.8, t);
    CHECK_RESULT(weft_mesh_map_apply(map, moved, out), WEFT_OK);
    double e_rigid = max_abs_diff(out, expect, 3 * (size_t)fine.nv);
    CHECK_MSG(e_rigid < 5e-6, "rigid motion reproduced to %g m", e_rigid);

    /* Fold the coarse sheet 90 degrees down along x = 0 (a column of coarse vertices): fine vertices
     * on the flat half stay put, those on the folded half hang below the hinge. */
    for (uint32_t i = 0; i < coarse.nv; ++i) {
        float x = coarse.pos[3 * i];
        moved[3 * i] = x > 0.0f ? 0.0f : x;
        moved[3 * i + 1] = x > 0.0f ? 1.0f - x : 1.0f;
        moved[3 * i + 2] = coarse.pos[3 * i + 2];
    }
    CHECK_RESULT(weft_mesh_map_apply(map, moved, out), WEFT_OK);
    double e_flat = 0.0, e_hang = 0.0;
    for (uint32_t i = 0; i < fine.nv; ++i) {
        const float *r = fine.pos + 3 * i, *p = out + 3 * i;
        if (r[0] < -0.03f) { /* away from the hinge: exact */
            e_flat = fmax(e_flat, max_abs_diff(p, r, 3));
        } else if (r[0] > 0.03f) {
            const float want[3] = {0.0f, 1.0f - r[0], r[2]};
            e_hang = fmax(e_hang, max_abs_diff(p, want, 3));
        }
    }
    CHECK_MSG(e_flat < 1e-5, "flat half moved by %g m", e_flat);
    /* the blend over neighbouring triangles softens the hinge within a few mm of it only */
    CHECK_MSG(e_hang < 5e-3, "folded half off by %g m", e_hang);

    free(out);
    free(expect);
    free(moved);
    weft_mesh_map_destroy(map);
    test_mesh_free(&coarse);
    test_mesh_free(&fine);
    weft_context_destroy(ctx);
}

static void test_mesh_map_bad_input(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh coarse = test_sheet(4, 4, 0.4f, 0.4f, 0.0f, 0.0f, 0.0f);
    test_mesh fine = test_sheet(7, 7, 0.4f, 0.4f, 0.0f, 0.0f, 0.0f);
    weft_mesh_map_def md = weft_default_mesh_map_def();
    weft_mesh_map *map = NULL;
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_ERROR_INVALID_ARGUMENT); /* nothing given */
    CHECK(map == NULL);
    md.from_rest_positions = coarse.pos;
    md.from_vertex_count = coarse.nv;
    md.from_triangles = coarse.tris;
    md.from_triangle_count = coarse.nt;
    md.to_rest_positions = fine.pos;
    md.to_vertex_count = fine.nv;
    weft_mesh_map_def raw = md;
    raw.internal_cookie = 0;
    CHECK_RESULT(weft_mesh_map_create(ctx, &raw, &map), WEFT_ERROR_INVALID_ARGUMENT);
    coarse.tris[4] = 999; /* index out of range */
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(strstr(weft_last_error(), "from mesh") != NULL);
    coarse.tris[4] = coarse.tris[3]; /* repeated vertex */
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_ERROR_DEGENERATE_MESH);
    test_mesh_free(&coarse);
    coarse = test_sheet(4, 4, 0.4f, 0.4f, 0.0f, 0.0f, 0.0f);
    md.from_rest_positions = coarse.pos;
    md.from_triangles = coarse.tris;
    fine.pos[5] = NAN;
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_ERROR_NOT_FINITE);
    CHECK(map == NULL);
    fine.pos[5] = 0.0f;
    CHECK_RESULT(weft_mesh_map_create(ctx, &md, &map), WEFT_OK);

    float *out = malloc(sizeof(float) * 3 * fine.nv), *before = malloc(sizeof(float) * 3 * fine.nv);
    for (uint32_t i = 0; i < 3 * fine.nv; ++i) {
        out[i] = before[i] = 7.0f;
    }
    float *in = malloc(sizeof(float) * 3 * coarse.nv);
    memcpy(in, coarse.pos, sizeof(float) * 3 * coarse.nv);
    in[7] = INFINITY;
    CHECK_RESULT(weft_mesh_map_apply(map, in, out), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(out, before, sizeof(float) * 3 * fine.nv) == 0);
    for (uint32_t i = 0; i < 3 * coarse.nv; ++i) {
        in[i] = 1.0f; /* every triangle collapsed to a point */
    }
    CHECK_RESULT(weft_mesh_map_apply(map, in, out), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(memcmp(out, before, sizeof(float) * 3 * fine.nv) == 0);
    CHECK_RESULT(weft_mesh_map_apply(map, NULL, out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_EQ_INT(weft_mesh_map_to_vertex_count(NULL), 0);
    weft_mesh_map_destroy(NULL);
    free(in);
    free(out);
    free(before);
    weft_mesh_map_destroy(map);
    test_mesh_free(&coarse);
    test_mesh_free(&fine);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_mesh_map_rest_rigid_and_fold), TEST_CASE(test_mesh_map_bad_input))
