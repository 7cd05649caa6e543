/* WEFT_METHOD_EXTERNAL: positions from the host's own solver go through the garment's constraint
 * stage. A patch the host drives into a box comes out in front of it (collision.push), keeps its
 * pins, is held by its tethers; it matches an LBS garment's stage on the same input; step and
 * constrain refuse the wrong garment; bad input leaves the state untouched; a teleport is a cut. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <string.h>

static weft_context *ctx_;

static void setup(void)
{
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx_), WEFT_OK);
}

typedef struct scene {
    test_mesh sheet, box;
} scene;

/* A 0.4 m sheet 1 cm above a 0.3 m box whose top is at y = 0.2. */
static scene make_scene(void)
{
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    scene s = {test_sheet(9, 9, 0.4f, 0.4f, 0.0f, 0.21f, 0.0f), test_box(lo, hi)};
    return s;
}

static weft_garment_def def_of(const scene *s, weft_method method)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = method;
    gd.ccd.enabled = false;
    gd.rest_positions = s->sheet.pos;
    gd.vertex_count = s->sheet.nv;
    gd.triangles = s->sheet.tris;
    gd.triangle_count = s->sheet.nt;
    gd.collider_rest_positions = s->box.pos;
    gd.collider_vertex_count = s->box.nv;
    gd.collider_triangles = s->box.tris;
    gd.collider_triangle_count = s->box.nt;
    gd.collision.push = 0.005f;
    return gd;
}

/* The host's "solver": the sheet dropped 1.5 cm, so its middle sinks 0.5 cm into the box top. */
static void host_positions(const scene *s, float *out)
{
    for (uint32_t i = 0; i < s->sheet.nv; ++i) {
        out[3 * i] = s->sheet.pos[3 * i];
        out[3 * i + 1] = s->sheet.pos[3 * i + 1] - 0.015f;
        out[3 * i + 2] = s->sheet.pos[3 * i + 2];
    }
}

static void test_host_positions_pushed_out(void)
{
    scene s = make_scene();
    weft_garment_def gd = def_of(&s, WEFT_METHOD_EXTERNAL);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
    float *next = malloc(sizeof(float) * 3 * s.sheet.nv);
    host_positions(&s, next);
    const uint32_t pin = 0;
    const float target[3] = {-0.2f, 0.3f, -0.2f};
    CHECK_RESULT(weft_garment_set_pins(g, &pin, target, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(g, s.box.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_OK);
    const float *x = weft_garment_positions(g);
    uint32_t over_box = 0;
    for (uint32_t i = 1; i < s.sheet.nv; ++i) {
        const float *p = x + 3 * i;
        if (fabsf(p[0]) < 0.149f && fabsf(p[2]) < 0.149f) { /* over the box top: pushed to 0.5 cm above it */
            CHECK_NEAR(p[1], 0.205f, 1e-4);
            over_box++;
        } else { /* beyond it: as the host left them */
            CHECK_NEAR(p[1], next[3 * i + 1], 1e-6);
        }
    }
    CHECK(over_box > 0);
    CHECK(memcmp(x, target, sizeof target) == 0); /* the pin holds */
    CHECK(weft_garment_stats(g).pushed_vertices >= over_box);
    CHECK_EQ_INT(weft_garment_stats(g).frame, 1);
    free(next);
    weft_garment_destroy(g);
    test_mesh_free(&s.sheet);
    test_mesh_free(&s.box);
}

/* Tethers on host positions: a vertex the host throws 1 m away is held within its radius of the
 * skinned garment (the box did not move: its initial position). */
static void test_tethers_hold_host_positions(void)
{
    scene s = make_scene();
    weft_garment_def gd = def_of(&s, WEFT_METHOD_EXTERNAL);
    gd.collision.push = 0.0f;
    gd.tethers.distance = 0.05f;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
    float *next = malloc(sizeof(float) * 3 * s.sheet.nv);
    memcpy(next, s.sheet.pos, sizeof(float) * 3 * s.sheet.nv);
    next[3 * 40 + 1] += 1.0f;
    CHECK_RESULT(weft_garment_set_collider(g, s.box.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_OK);
    const float *x = weft_garment_positions(g);
    CHECK_NEAR(x[3 * 40 + 1], s.sheet.pos[3 * 40 + 1] + 0.05f, 1e-5);
    CHECK_EQ_INT(weft_garment_stats(g).tether_vertices_clamped, 1);
    free(next);
    weft_garment_destroy(g);
    test_mesh_free(&s.sheet);
    test_mesh_free(&s.box);
}

static void test_refusals_leave_state(void)
{
    scene s = make_scene();
    weft_garment_def gd = def_of(&s, WEFT_METHOD_EXTERNAL);
    weft_garment *g = NULL, *lbs = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
    float *next = malloc(sizeof(float) * 3 * s.sheet.nv);
    host_positions(&s, next);
    /* no collider of t+1 yet */
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_ERROR_NO_COLLIDER);
    CHECK_RESULT(weft_garment_set_collider(g, s.box.pos), WEFT_OK);
    /* an external garment has no step of its own */
    CHECK_RESULT(weft_garment_step(g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "weft_garment_constrain") != NULL);
    /* NaN and out-of-range host positions fail, state kept */
    next[5] = NAN;
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_ERROR_NOT_FINITE);
    next[5] = 2.0e4f;
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(weft_garment_positions(g), s.sheet.pos, sizeof(float) * 3 * s.sheet.nv) == 0);
    CHECK_EQ_INT(weft_garment_stats(g).frame, 0);
    CHECK_RESULT(weft_garment_constrain(NULL, next), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_garment_constrain(g, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    /* other methods refuse constrain */
    gd.method = WEFT_METHOD_LBS;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &lbs), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(lbs, s.box.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(lbs, next), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "'lbs'") != NULL);
    /* a teleport is a cut: the skinned garment on the moved box, not the host's positions */
    float *far = malloc(sizeof(float) * 3 * s.box.nv);
    for (uint32_t i = 0; i < 3 * s.box.nv; ++i) {
        far[i] = s.box.pos[i] + (i % 3 == 2 ? 4.0f : 0.0f);
    }
    host_positions(&s, next);
    CHECK_RESULT(weft_garment_set_collider(g, far), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, next), WEFT_OK);
    CHECK(weft_garment_stats(g).collider_cut);
    CHECK_NEAR(weft_garment_positions(g)[2], s.sheet.pos[2] + 4.0f, 1e-4);
    free(far);
    free(next);
    weft_garment_destroy(lbs);
    weft_garment_destroy(g);
    test_mesh_free(&s.sheet);
    test_mesh_free(&s.box);
}

static void teardown(void) { weft_context_destroy(ctx_); }

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_host_positions_pushed_out), TEST_CASE(test_tethers_hold_host_positions),
          TEST_CASE(test_refusals_leave_state), TEST_CASE(teardown))
