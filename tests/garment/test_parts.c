/* Body parts (weft_garment_def.collision.triangle_parts, runtime/garment/parts.c): a "torso" box
 * and a "limb" box that sinks into it, as a forearm sinks into a chest on real motion. Cloth made
 * against the torso ignores the limb and cloth made against the limb ignores the torso, in the
 * push and in CCD, while cloth still collides with its own part; without parts both claim it.
 * Bad part ids, a missing collider and a bad margin fail at creation.
 *
 * The step is LBS on a still torso, which returns the bound positions, so the push and CCD are
 * what move a vertex. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <string.h>

static const float k_torso_lo[3] = {-0.1f, 0.0f, -0.1f}, k_torso_hi[3] = {0.1f, 0.4f, 0.1f};
static const float k_limb_lo[3] = {0.05f, 0.15f, -0.03f}, k_limb_hi[3] = {0.35f, 0.25f, 0.03f};

typedef struct scene {
    test_mesh cloth, torso, limb, body;
    uint8_t parts[24];
} scene;

static scene make_scene(void)
{
    scene s;
    s.cloth = test_sheet(2, 2, 0.02f, 0.02f, 0.0f, 0.5f, 0.0f); /* one small quad */
    s.torso = test_box(k_torso_lo, k_torso_hi);
    s.limb = test_box(k_limb_lo, k_limb_hi);
    s.body = test_mesh_join(&s.torso, &s.limb); /* two closed boxes sharing no vertex */
    for (int t = 0; t < 24; ++t) {
        s.parts[t] = t < 12 ? 3 : 18; /* spine3, left elbow */
    }
    return s;
}

static void free_scene(scene *s)
{
    test_mesh_free(&s->cloth);
    test_mesh_free(&s->torso);
    test_mesh_free(&s->limb);
    test_mesh_free(&s->body);
}

/* Creation state: a 2 cm quad 1.2 cm in front of the torso's +z face (about 10 cm from the
 * limb), vertex 0 at (0, 0.32, 0.112). */
static void creation_points(float pts[4][3])
{
    const float q[4][3] = {{0.0f, 0.32f, 0.112f}, {-0.02f, 0.32f, 0.112f}, {0.0f, 0.34f, 0.112f}, {-0.02f, 0.34f, 0.112f}};
    memcpy(pts, q, sizeof q);
}

/* The body after the limb swung up and forward through the shirt's front: vertex 0 (still,
 * bound to the still torso) ends 5 mm inside the limb, under its +z face. */
static void swung_body(const scene *s, float *out)
{
    memcpy(out, s->body.pos, sizeof(float) * 3 * s->body.nv);
    const float d[3] = {-0.1f, 0.1f, 0.087f};
    for (uint32_t v = s->torso.nv; v < s->body.nv; ++v) {
        for (int k = 0; k < 3; ++k) {
            out[3 * v + k] += d[k];
        }
    }
}

static weft_garment *make(weft_context *ctx, const scene *s, const float *pts, bool parts, bool ccd, float push)
{
    weft_garment_def gd = test_garment_def(WEFT_METHOD_LBS, &s->cloth, &s->body, 0);
    gd.initial_positions = pts;
    gd.collision.triangle_parts = parts ? s->parts : NULL;
    gd.collision.push = push;
    gd.ccd.enabled = ccd;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    return g;
}

/* One step to the swung body; vertex 0's position afterwards. */
static void step_swung(weft_garment *g, const scene *s, float out[3])
{
    float *body = malloc(sizeof(float) * 3 * s->body.nv);
    swung_body(s, body);
    CHECK_RESULT(weft_garment_set_collider(g, body), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    memcpy(out, weft_garment_positions(g), 3 * sizeof(float));
    free(body);
}

/* The quad made in front of the torso, stepped once to the swung body with and without parts;
 * vertex 0's positions and the two garments' stats afterwards. */
typedef struct pair_run {
    float with_x[3], without_x[3];
    weft_step_stats with, without;
    bool ok;
} pair_run;

static pair_run run_pair(bool ccd, float push)
{
    pair_run out = {0};
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    scene s = make_scene();
    float pts[4][3];
    creation_points(pts);
    weft_garment *with = make(ctx, &s, &pts[0][0], true, ccd, push);
    weft_garment *without = make(ctx, &s, &pts[0][0], false, ccd, push);
    out.ok = with && without;
    if (out.ok) {
        step_swung(with, &s, out.with_x);
        step_swung(without, &s, out.without_x);
        out.with = weft_garment_stats(with);
        out.without = weft_garment_stats(without);
    }
    weft_garment_destroy(with);
    weft_garment_destroy(without);
    free_scene(&s);
    weft_context_destroy(ctx);
    return out;
}

/* Vertex 0 of the torso cloth is where it was made: on the shirt's front. */
static void check_on_the_front(const float x[3])
{
    CHECK_NEAR(x[0], 0.0f, 1e-6);
    CHECK_NEAR(x[1], 0.32f, 1e-6);
    CHECK_NEAR(x[2], 0.112f, 1e-6);
}

static void test_push_meets_only_the_vertex_parts(void)
{
    const pair_run r = run_pair(false, 0.01f);
    CHECK(r.ok);
    check_on_the_front(r.with_x); /* torso cloth ignores the limb */
    CHECK_EQ_INT(r.with.pushed_vertices, 0);
    /* one collider for all: the limb claims it and pushes it 1 cm in front of its +z face */
    CHECK_NEAR(r.without_x[2], 0.117f + 0.01f, 1e-4);
    CHECK_EQ_INT(r.without.pushed_vertices, 4); /* the whole quad is inside it */
}

static void test_ccd_meets_only_the_vertex_parts(void)
{
    const pair_run r = run_pair(true, 0.0f);
    CHECK(r.ok);
    check_on_the_front(r.with_x); /* the limb's face sweeps through vertex 0: no contact */
    CHECK_EQ_INT(r.with.ccd_vertices_moved, 0);
    CHECK(!r.with.ccd_fallback);
    /* without parts CCD sees the crossing and moves the vertex (its fallback carries it along) */
    const float d[3] = {r.without_x[0], r.without_x[1] - 0.32f, r.without_x[2] - 0.112f};
    CHECK_MSG(sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) > 1e-3f, "vertex 0 at (%g, %g, %g)",
              (double)r.without_x[0], (double)r.without_x[1], (double)r.without_x[2]);
}

/* Cloth made against a part still collides with it. */
static void test_own_part_still_collides(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    scene s = make_scene();
    float pts[4][3];
    creation_points(pts);
    pts[0][2] = 0.095f; /* 5 mm inside the torso's +z face at creation (and 6.5 cm from the limb) */
    weft_garment *g = make(ctx, &s, &pts[0][0], true, false, 0.01f);
    if (g) {
        CHECK_RESULT(weft_garment_set_collider(g, s.body.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        CHECK_NEAR(weft_garment_positions(g)[2], 0.11f, 1e-4);
    }
    weft_garment_destroy(g);
    free_scene(&s);
    weft_context_destroy(ctx);
}

static void test_bad_parts_fail_at_creation(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    scene s = make_scene();
    weft_garment *g = NULL;
    weft_garment_def gd = test_garment_def(WEFT_METHOD_LBS, &s.cloth, &s.body, 0);
    s.parts[5] = 32;
    gd.collision.triangle_parts = s.parts;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "collision.triangle_parts[5]") != NULL);
    s.parts[5] = 3;
    gd.collision.part_margin = -0.01f;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    gd.collision.part_margin = NAN;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    weft_garment_def none = test_garment_def(WEFT_METHOD_LBS, &s.cloth, NULL, 0);
    none.collision.triangle_parts = s.parts;
    CHECK_RESULT(weft_garment_create(ctx, &none, &g), WEFT_ERROR_NO_COLLIDER);
    CHECK(g == NULL);
    free_scene(&s);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_push_meets_only_the_vertex_parts), TEST_CASE(test_ccd_meets_only_the_vertex_parts),
          TEST_CASE(test_own_part_still_collides), TEST_CASE(test_bad_parts_fail_at_creation))
