/* The procedural avatar: closed 2-manifold, size, proportions, weights, no self-intersection,
 * determinism, bind-pose consistency, parameter validation. */
#include "test.h"

#include "body/mesh.h"
#include "mesh_check.h"
#include "weft.h"
#include "weft/body.h"

static weft_context *g_ctx;
static weft_body *g_body; /* default avatar, shared by the cases */

static void ensure_default(void)
{
    if (!g_ctx) {
        weft_context_def def = weft_default_context_def();
        CHECK_RESULT(weft_context_create(&def, &g_ctx), WEFT_OK);
    }
    if (!g_body) {
        weft_avatar_def def = weft_default_avatar_def();
        double t0 = weft__now_ms();
        CHECK_RESULT(weft_avatar_create(g_ctx, &def, &g_body), WEFT_OK);
        printf("default avatar: %u vertices, %u triangles in %.0f ms\n", weft_body_vertex_count(g_body),
               weft_body_triangle_count(g_body), weft__now_ms() - t0);
    }
}

static void bounds(const float *v, uint32_t n, float lo[3], float hi[3])
{
    for (int a = 0; a < 3; ++a) {
        lo[a] = 1e30f, hi[a] = -1e30f;
    }
    for (uint32_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = fminf(lo[a], v[3 * i + a]);
            hi[a] = fmaxf(hi[a], v[3 * i + a]);
        }
    }
}

static double volume(const float *v, const uint32_t *t, uint32_t nt)
{
    double vol = 0;
    for (uint32_t f = 0; f < nt; ++f) {
        const float *a = v + 3 * t[3 * f], *b = v + 3 * t[3 * f + 1], *c = v + 3 * t[3 * f + 2];
        vol += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    return vol;
}

static void test_closed_manifold(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    uint32_t nv = weft_body_vertex_count(g_body), nt = weft_body_triangle_count(g_body);
    CHECK_MSG(nv >= 6000 && nv <= 10000, "vertex count %u outside [6000, 10000]", nv);
    weft__mesh_topology topo;
    CHECK_RESULT(weft__mesh_topology_of(g_ctx, weft_body_rest_vertices(g_body), nv, weft_body_triangles(g_body), nt, &topo),
                 WEFT_OK);
    CHECK_EQ_INT(topo.boundary_edges, 0);
    CHECK_EQ_INT(topo.nonmanifold_edges, 0);
    CHECK_EQ_INT(topo.misoriented_edges, 0);
    CHECK_EQ_INT(topo.nonmanifold_vertices, 0);
    CHECK_EQ_INT(topo.components, 1);
    CHECK_EQ_INT(topo.euler, 2);
    CHECK_MSG(topo.min_angle_deg > 5.0f, "min angle %.2f deg", (double)topo.min_angle_deg);
    /* Outward orientation: positive enclosed volume, roughly a human's (~0.06-0.08 m^3). */
    double vol = volume(weft_body_rest_vertices(g_body), weft_body_triangles(g_body), nt);
    printf("volume %.4f m^3, min angle %.1f deg\n", vol, (double)topo.min_angle_deg);
    CHECK_MSG(vol > 0.045 && vol < 0.10, "volume %.4f m^3", vol);
}

static void test_proportions(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    uint32_t nv = weft_body_vertex_count(g_body);
    float lo[3], hi[3];
    bounds(weft_body_rest_vertices(g_body), nv, lo, hi);
    CHECK_NEAR(lo[1], 0.0, 1e-5);       /* soles on the ground */
    CHECK_NEAR(hi[1] - lo[1], 1.70, 0.02); /* standing height */
    CHECK_NEAR(0.5 * (lo[0] + hi[0]), 0.0, 0.01); /* centred and symmetric */
    const float *j = weft_body_rest_joints(g_body);
    CHECK_NEAR(j[0], 0.0, 1e-6);
    CHECK_NEAR(j[2], 0.0, 1e-6);
    /* Zero pose is the T-pose: the arms are horizontal (wrist at shoulder height). */
    CHECK_NEAR(j[3 * WEFT_JOINT_LEFT_WRIST + 1], j[3 * WEFT_JOINT_LEFT_SHOULDER + 1], 0.03);
    CHECK(j[3 * WEFT_JOINT_LEFT_WRIST] > 0.5f); /* +X is the body's left */
    CHECK(j[3 * WEFT_JOINT_HEAD + 1] > 1.45f && j[3 * WEFT_JOINT_HEAD + 1] < 1.65f);
    /* The bind pose lowers the arms by the def's 45 degrees. */
    weft_pose bind;
    weft_body_bind_pose(g_body, &bind);
    float xf[WEFT_BODY_JOINTS * 16];
    CHECK_RESULT(weft_body_pose(g_body, &bind, NULL, xf), WEFT_OK);
    const float *sh = xf + 16 * WEFT_JOINT_LEFT_SHOULDER + 12, *wr = xf + 16 * WEFT_JOINT_LEFT_WRIST + 12;
    double angle = atan2(sh[1] - wr[1], wr[0] - sh[0]) * 180.0 / 3.14159265358979;
    CHECK_NEAR(angle, 45.0, 2.0);
    /* Feet point forward (+Z), the nose too. */
    CHECK(j[3 * WEFT_JOINT_LEFT_FOOT + 2] > j[3 * WEFT_JOINT_LEFT_ANKLE + 2]);
    CHECK(hi[2] > 0.1f);
}

static void test_weights(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    uint32_t nv = weft_body_vertex_count(g_body);
    const float *w = weft_body_weights(g_body);
    const float *v = weft_body_rest_vertices(g_body);
    double worst = 0;
    uint32_t head_ok = 0, head_n = 0, hand_ok = 0, hand_n = 0;
    for (uint32_t i = 0; i < nv; ++i) {
        double s = 0;
        uint32_t arg = 0;
        for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
            CHECK(w[i * WEFT_BODY_JOINTS + k] >= 0.0f);
            s += w[i * WEFT_BODY_JOINTS + k];
            arg = w[i * WEFT_BODY_JOINTS + k] > w[i * WEFT_BODY_JOINTS + arg] ? k : arg;
        }
        worst = fmax(worst, fabs(s - 1.0));
        if (v[3 * i + 1] > 1.62f) { /* top of the head */
            head_n++;
            head_ok += arg == WEFT_JOINT_HEAD;
        }
        if (v[3 * i] > 0.62f) { /* left fingertips in the A-pose */
            hand_n++;
            hand_ok += arg == WEFT_JOINT_LEFT_HAND || arg == WEFT_JOINT_LEFT_WRIST;
        }
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    CHECK(head_n > 20 && head_ok == head_n);
    CHECK(hand_n > 10 && hand_ok == hand_n);
}

static void test_no_self_intersection(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    uint32_t hits = mc_count_self_intersections(weft_body_rest_vertices(g_body), weft_body_vertex_count(g_body),
                                                weft_body_triangles(g_body), weft_body_triangle_count(g_body), 0.03f);
    CHECK_EQ_INT(hits, 0);
}

static void test_bind_pose_reproduces_rest(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    uint32_t nv = weft_body_vertex_count(g_body);
    float *out = malloc((size_t)nv * 3 * sizeof(float));
    weft_pose bind;
    weft_body_bind_pose(g_body, &bind);
    CHECK_RESULT(weft_body_pose(g_body, &bind, out, NULL), WEFT_OK);
    double worst = 0;
    for (uint32_t i = 0; i < nv * 3; ++i) {
        worst = fmax(worst, fabs((double)out[i] - weft_body_rest_vertices(g_body)[i]));
    }
    CHECK_NEAR(worst, 0.0, 1e-5);
    /* Zero pose raises the arms: the left fingertips go above the shoulder line. */
    weft_pose zero;
    memset(&zero, 0, sizeof zero);
    CHECK_RESULT(weft_body_pose(g_body, &zero, out, NULL), WEFT_OK);
    float lo[3], hi[3];
    bounds(out, nv, lo, hi);
    CHECK(hi[0] > 0.80f); /* arm span of a T-pose: over 1.6 m */
    /* skin_points with the body's own weights reproduces the posed vertices. */
    float *again = malloc((size_t)nv * 3 * sizeof(float));
    CHECK_RESULT(weft_body_skin_points(g_body, &zero, weft_body_rest_vertices(g_body), weft_body_weights(g_body), nv, again),
                 WEFT_OK);
    CHECK(memcmp(out, again, (size_t)nv * 3 * sizeof(float)) == 0);
    free(again);
    free(out);
}

static void test_deterministic_and_shapes(void)
{
    ensure_default();
    if (!g_body) {
        return;
    }
    weft_avatar_def def = weft_default_avatar_def();
    weft_body *again = NULL;
    CHECK_RESULT(weft_avatar_create(g_ctx, &def, &again), WEFT_OK);
    if (again) {
        CHECK_EQ_INT(weft_body_vertex_count(again), weft_body_vertex_count(g_body));
        CHECK(memcmp(weft_body_rest_vertices(again), weft_body_rest_vertices(g_body),
                     (size_t)weft_body_vertex_count(g_body) * 3 * sizeof(float)) == 0);
        CHECK(memcmp(weft_body_weights(again), weft_body_weights(g_body),
                     (size_t)weft_body_vertex_count(g_body) * WEFT_BODY_JOINTS * sizeof(float)) == 0);
        weft_body_destroy(again);
    }
    /* A tall heavy body and a short slim one: height follows, volume follows girth. */
    double base_vol = volume(weft_body_rest_vertices(g_body), weft_body_triangles(g_body), weft_body_triangle_count(g_body));
    const struct {
        float height, girth, legs, shoulders, hips;
    } shapes[] = {{1.90f, 1.3f, 0.53f, 1.15f, 1.0f}, {1.55f, 0.8f, 0.46f, 0.9f, 1.2f}};
    for (int s = 0; s < 2; ++s) {
        def = weft_default_avatar_def();
        def.height = shapes[s].height;
        def.girth = shapes[s].girth;
        def.leg_fraction = shapes[s].legs;
        def.shoulder_width = shapes[s].shoulders;
        def.hip_width = shapes[s].hips;
        weft_body *b = NULL;
        CHECK_RESULT(weft_avatar_create(g_ctx, &def, &b), WEFT_OK);
        if (!b) {
            continue;
        }
        uint32_t nv = weft_body_vertex_count(b);
        float lo[3], hi[3];
        bounds(weft_body_rest_vertices(b), nv, lo, hi);
        CHECK_NEAR(hi[1] - lo[1], shapes[s].height, 0.025 * shapes[s].height);
        weft__mesh_topology topo;
        CHECK_RESULT(weft__mesh_topology_of(g_ctx, weft_body_rest_vertices(b), nv, weft_body_triangles(b),
                                            weft_body_triangle_count(b), &topo),
                     WEFT_OK);
        CHECK_EQ_INT(topo.euler, 2);
        CHECK_EQ_INT(topo.boundary_edges + topo.nonmanifold_edges + topo.nonmanifold_vertices, 0);
        double vol = volume(weft_body_rest_vertices(b), weft_body_triangles(b), weft_body_triangle_count(b));
        CHECK(s == 0 ? vol > 1.5 * base_vol : vol < 0.8 * base_vol);
        const float *j = weft_body_rest_joints(b);
        double legs = j[3 * WEFT_JOINT_LEFT_HIP + 1] / (hi[1] - lo[1]);
        CHECK_NEAR(legs, shapes[s].legs, 0.03);
        weft_body_destroy(b);
    }
}

static void test_bad_defs(void)
{
    ensure_default();
    weft_avatar_def def = weft_default_avatar_def();
    weft_body *b = (weft_body *)(uintptr_t)0x1;
    def.height = NAN;
    CHECK_RESULT(weft_avatar_create(g_ctx, &def, &b), WEFT_ERROR_NOT_FINITE);
    CHECK(strstr(weft_last_error(), "height") != NULL);
    def = weft_default_avatar_def();
    def.girth = 3.0f;
    CHECK_RESULT(weft_avatar_create(g_ctx, &def, &b), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "girth") != NULL);
    def = weft_default_avatar_def();
    def.target_vertices = 10;
    CHECK_RESULT(weft_avatar_create(g_ctx, &def, &b), WEFT_ERROR_INVALID_ARGUMENT);
    weft_avatar_def raw;
    memset(&raw, 0, sizeof raw);
    CHECK_RESULT(weft_avatar_create(g_ctx, &raw, &b), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(b == (weft_body *)(uintptr_t)0x1);
    /* Distances: negative inside (pelvis), positive far away. */
    float pts[6] = {0, 0.95f, 0, 0, 3.0f, 0};
    float d[2];
    CHECK_RESULT(weft_avatar_distance(g_body, pts, 2, d), WEFT_OK);
    CHECK(d[0] < -0.05f && d[1] > 1.0f);
}

static void cleanup(void)
{
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
    g_body = NULL;
    g_ctx = NULL;
    CHECK(1);
}

/* weft_body_triangle_parts: every triangle gets the joint of largest summed weight; on the
 * avatar that makes left-side parts lie on +X and right-side ones on -X, and most joints own
 * triangles. A wrong count fails by name. */
static void test_triangle_parts(void)
{
    ensure_default();
    const uint32_t nt = weft_body_triangle_count(g_body);
    uint8_t *parts = malloc(nt);
    CHECK_RESULT(weft_body_triangle_parts(g_body, parts, nt), WEFT_OK);
    const float *v = weft_body_rest_vertices(g_body);
    const uint32_t *tris = weft_body_triangles(g_body);
    uint32_t owned = 0, count[WEFT_BODY_JOINTS] = {0};
    double cx[WEFT_BODY_JOINTS] = {0};
    for (uint32_t t = 0; t < nt; ++t) {
        CHECK(parts[t] < WEFT_BODY_JOINTS);
        count[parts[t]]++;
        for (int k = 0; k < 3; ++k) {
            cx[parts[t]] += v[3 * (size_t)tris[3 * (size_t)t + k]] / 3.0;
        }
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        owned += count[j] > 0;
    }
    CHECK_MSG(owned >= 20, "%u joints own triangles", owned);
    static const uint32_t left[] = {WEFT_JOINT_LEFT_HIP, WEFT_JOINT_LEFT_KNEE, WEFT_JOINT_LEFT_SHOULDER,
                                    WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_LEFT_WRIST};
    for (size_t k = 0; k < sizeof left / sizeof left[0]; ++k) {
        const uint32_t l = left[k], r = l + 1; /* SMPL puts each right joint right after its left twin */
        CHECK_MSG(count[l] > 0 && cx[l] / count[l] > 0.05, "%s: centroid x %g", weft_joint_name(l), count[l] ? cx[l] / count[l] : 0.0);
        CHECK_MSG(count[r] > 0 && cx[r] / count[r] < -0.05, "%s: centroid x %g", weft_joint_name(r), count[r] ? cx[r] / count[r] : 0.0);
    }
    CHECK_RESULT(weft_body_triangle_parts(g_body, parts, nt - 1), WEFT_ERROR_SIZE_MISMATCH);
    CHECK_RESULT(weft_body_triangle_parts(NULL, parts, nt), WEFT_ERROR_INVALID_ARGUMENT);
    free(parts);
}

TEST_MAIN(TEST_CASE(test_closed_manifold), TEST_CASE(test_proportions), TEST_CASE(test_weights),
          TEST_CASE(test_no_self_intersection), TEST_CASE(test_bind_pose_reproduces_rest),
          TEST_CASE(test_deterministic_and_shapes), TEST_CASE(test_bad_defs), TEST_CASE(test_triangle_parts),
          TEST_CASE(cleanup))
