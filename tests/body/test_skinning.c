/* Linear blend skinning on hand-made bodies with known answers, plus def validation. */
#include "test.h"

#include "weft.h"
#include "weft/body.h"

static weft_context *make_ctx(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    return ctx;
}

/* Joints on a vertical line 0.1 m apart (joint j at y = j * 0.1) so bone geometry is simple. */
static void line_joints(float *j)
{
    for (int k = 0; k < WEFT_BODY_JOINTS; ++k) {
        j[3 * k + 0] = 0.0f;
        j[3 * k + 1] = 0.1f * (float)k;
        j[3 * k + 2] = 0.0f;
    }
}

static const float g_verts[4 * 3] = {0.0f, 0.5f, 0.2f, 0.3f, 0.4f, 0.0f, 0.0f, 0.4f, -0.2f, 0.1f, 0.9f, 0.0f};
static const uint32_t g_tris[4 * 3] = {0, 1, 2, 0, 3, 1, 1, 3, 2, 2, 3, 0};

static void test_rigid_and_blend(void)
{
    weft_context *ctx = make_ctx();
    float joints[WEFT_BODY_JOINTS * 3];
    line_joints(joints);
    float weights[4 * WEFT_BODY_JOINTS] = {0};
    weights[0 * WEFT_BODY_JOINTS + WEFT_JOINT_LEFT_KNEE] = 1.0f; /* chain pelvis -> left_hip -> left_knee */
    weights[1 * WEFT_BODY_JOINTS + WEFT_JOINT_LEFT_HIP] = 1.0f;
    weights[2 * WEFT_BODY_JOINTS + WEFT_JOINT_PELVIS] = 0.5f;
    weights[2 * WEFT_BODY_JOINTS + WEFT_JOINT_LEFT_HIP] = 0.5f;
    weights[3 * WEFT_BODY_JOINTS + WEFT_JOINT_HEAD] = 1.0f;
    weft_body_def def = weft_default_body_def();
    def.vertices = g_verts;
    def.vertex_count = 4;
    def.triangles = g_tris;
    def.triangle_count = 4;
    def.weights = weights;
    def.joints = joints;
    weft_body *body = NULL;
    CHECK_RESULT(weft_body_create(ctx, &def, &body), WEFT_OK);
    if (!body) {
        weft_context_destroy(ctx);
        return;
    }
    /* left_hip (joint 1, at y = 0.1) turns +90 deg about Z; the root moves by t. */
    weft_pose pose;
    memset(&pose, 0, sizeof pose);
    const float half_pi = 1.57079632679f;
    pose.rotations[3 * WEFT_JOINT_LEFT_HIP + 2] = half_pi;
    pose.translation[0] = 1.0f, pose.translation[1] = 2.0f, pose.translation[2] = 3.0f;
    float out[12], xf[WEFT_BODY_JOINTS * 16];
    CHECK_RESULT(weft_body_pose(body, &pose, out, xf), WEFT_OK);
    /* Rz(90) about (0, 0.1, 0): (x, y, z) -> (-(y - 0.1), 0.1 + x, z), then + t. */
    /* Vertex 0 follows left_knee, a child of left_hip: rigidly rotated too. */
    CHECK_NEAR(out[0], 1.0 - (0.5 - 0.1), 1e-6);
    CHECK_NEAR(out[1], 2.0 + 0.1 + 0.0, 1e-6);
    CHECK_NEAR(out[2], 3.0 + 0.2, 1e-6);
    CHECK_NEAR(out[3], 1.0 - (0.4 - 0.1), 1e-6);
    CHECK_NEAR(out[4], 2.0 + 0.1 + 0.3, 1e-6);
    /* Vertex 2: half pelvis (translation only), half left_hip (rotated). */
    CHECK_NEAR(out[6], 1.0 + 0.5 * 0.0 + 0.5 * (-(0.4 - 0.1)), 1e-6);
    CHECK_NEAR(out[7], 2.0 + 0.5 * 0.4 + 0.5 * (0.1 + 0.0), 1e-6);
    CHECK_NEAR(out[8], 3.0 - 0.2, 1e-6);
    /* Vertex 3 on the head does not move but for the translation. */
    CHECK_NEAR(out[9], 1.1, 1e-6);
    CHECK_NEAR(out[10], 2.9, 1e-6);
    /* Joint transforms: left_knee (joint 4 at y = 0.4) lands at the rotated position. */
    CHECK_NEAR(xf[16 * WEFT_JOINT_LEFT_KNEE + 12], 1.0 - 0.3, 1e-6);
    CHECK_NEAR(xf[16 * WEFT_JOINT_LEFT_KNEE + 13], 2.1, 1e-6);
    /* Its rotation columns: X axis maps to +Y. */
    CHECK_NEAR(xf[16 * WEFT_JOINT_LEFT_KNEE + 1], 1.0, 1e-6);
    /* Tiny and near-pi rotations stay finite and orthonormal. */
    pose.rotations[3 * WEFT_JOINT_LEFT_HIP + 2] = 1e-9f;
    CHECK_RESULT(weft_body_pose(body, &pose, out, NULL), WEFT_OK);
    CHECK_NEAR(out[0], 1.0, 1e-6);
    pose.rotations[3 * WEFT_JOINT_LEFT_HIP + 2] = 3.14159265f;
    CHECK_RESULT(weft_body_pose(body, &pose, out, NULL), WEFT_OK);
    CHECK_NEAR(out[0], 1.0, 1e-6);
    CHECK_NEAR(out[1], 2.0 + 0.1 - 0.4, 1e-6);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

/* With a bind pose, posing with that pose returns the template, and the zero pose undoes it. */
static void test_bind_pose(void)
{
    weft_context *ctx = make_ctx();
    float joints[WEFT_BODY_JOINTS * 3];
    line_joints(joints);
    float weights[4 * WEFT_BODY_JOINTS] = {0};
    for (int i = 0; i < 4; ++i) {
        weights[i * WEFT_BODY_JOINTS + WEFT_JOINT_LEFT_KNEE] = 1.0f;
    }
    weft_pose bind;
    memset(&bind, 0, sizeof bind);
    bind.rotations[3 * WEFT_JOINT_LEFT_HIP + 0] = 0.7f;
    bind.rotations[3 * WEFT_JOINT_LEFT_KNEE + 1] = -0.4f;
    weft_body_def def = weft_default_body_def();
    def.vertices = g_verts;
    def.vertex_count = 4;
    def.triangles = g_tris;
    def.triangle_count = 4;
    def.weights = weights;
    def.joints = joints;
    def.bind_pose = &bind;
    weft_body *body = NULL;
    CHECK_RESULT(weft_body_create(ctx, &def, &body), WEFT_OK);
    if (!body) {
        weft_context_destroy(ctx);
        return;
    }
    float out[12];
    CHECK_RESULT(weft_body_pose(body, &bind, out, NULL), WEFT_OK);
    for (int i = 0; i < 12; ++i) {
        CHECK_NEAR(out[i], g_verts[i], 1e-6);
    }
    weft_pose zero;
    memset(&zero, 0, sizeof zero);
    CHECK_RESULT(weft_body_pose(body, &zero, out, NULL), WEFT_OK);
    double moved = 0;
    for (int i = 0; i < 12; ++i) {
        moved = fmax(moved, fabs(out[i] - g_verts[i]));
    }
    CHECK(moved > 0.05);
    /* Distances between vertices are preserved (rigid: one bone). */
    double d0 = hypot(hypot(g_verts[0] - g_verts[3], g_verts[1] - g_verts[4]), g_verts[2] - g_verts[5]);
    double d1 = hypot(hypot(out[0] - out[3], out[1] - out[4]), out[2] - out[5]);
    CHECK_NEAR(d0, d1, 1e-6);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

static void test_bad_defs(void)
{
    weft_context *ctx = make_ctx();
    float joints[WEFT_BODY_JOINTS * 3];
    line_joints(joints);
    float weights[4 * WEFT_BODY_JOINTS] = {0};
    for (int i = 0; i < 4; ++i) {
        weights[i * WEFT_BODY_JOINTS] = 1.0f;
    }
    weft_body_def good = weft_default_body_def();
    good.vertices = g_verts;
    good.vertex_count = 4;
    good.triangles = g_tris;
    good.triangle_count = 4;
    good.weights = weights;
    good.joints = joints;
    weft_body *body = (weft_body *)(uintptr_t)0x1;

    weft_body_def d = good;
    d.internal_cookie = 0;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_INVALID_ARGUMENT);
    d = good;
    d.joints = NULL;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "joints") != NULL);
    float bad_w[4 * WEFT_BODY_JOINTS];
    memcpy(bad_w, weights, sizeof bad_w);
    bad_w[0] = 0.7f;
    d = good;
    d.weights = bad_w;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "sum") != NULL);
    uint32_t bad_t[12];
    memcpy(bad_t, g_tris, sizeof bad_t);
    bad_t[4] = 9;
    d = good;
    d.triangles = bad_t;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_DEGENERATE_MESH);
    int32_t parents[WEFT_BODY_JOINTS];
    for (int j = 0; j < WEFT_BODY_JOINTS; ++j) {
        parents[j] = weft_joint_parent((uint32_t)j);
    }
    parents[5] = 7; /* a child before its parent */
    d = good;
    d.parents = parents;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_INVALID_ARGUMENT);
    float nan_v[12];
    memcpy(nan_v, g_verts, sizeof nan_v);
    nan_v[7] = NAN;
    d = good;
    d.vertices = nan_v;
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_NOT_FINITE);
    float flat[12] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0};
    d = good;
    d.vertices = flat; /* triangle 0 (0, 1, 2) is collinear */
    CHECK_RESULT(weft_body_create(ctx, &d, &body), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(body == (weft_body *)(uintptr_t)0x1);
    weft_context_destroy(ctx);
}

static void test_skeleton_names(void)
{
    CHECK(strcmp(weft_joint_name(0), "pelvis") == 0);
    CHECK(strcmp(weft_joint_name(WEFT_JOINT_RIGHT_HAND), "right_hand") == 0);
    CHECK(weft_joint_name(24) == NULL);
    static const int parents[WEFT_BODY_JOINTS] = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8,
                                                  9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        CHECK_EQ_INT(weft_joint_parent(j), parents[j]);
    }
}

TEST_MAIN(TEST_CASE(test_rigid_and_blend), TEST_CASE(test_bind_pose), TEST_CASE(test_bad_defs), TEST_CASE(test_skeleton_names))
