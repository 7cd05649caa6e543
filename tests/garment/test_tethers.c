/* Tethers (weft_garment_def.tethers.distance / tethers.distances): after the method's step every
 * vertex lies within its radius of the garment skinned to the collider, with CCD on too (the last
 * clamp releases what CCD held), pins keep their targets,
 * radius 0 glues a vertex, and bad radii or a failing binding leave everything untouched. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <string.h>

/* A 10 x 10 sheet hovering 1 cm over a box, the box carried sideways and up each frame. */
typedef struct tether_scene {
    weft_context *ctx;
    test_mesh sheet, box;
    float *moved;
} tether_scene;

static void scene_make(tether_scene *s)
{
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &s->ctx), WEFT_OK);
    s->sheet = test_sheet(10, 10, 0.5f, 0.5f, 0.0f, 0.21f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    s->box = test_box(lo, hi);
    s->moved = malloc(sizeof(float) * 3 * s->box.nv);
}

static void scene_free(tether_scene *s)
{
    free(s->moved);
    test_mesh_free(&s->box);
    test_mesh_free(&s->sheet);
    weft_context_destroy(s->ctx);
}

static weft_garment_def scene_def(const tether_scene *s, weft_method method)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = method;
    gd.substeps = 5;
    gd.ccd.enabled = false; /* tethers act before CCD; this test checks the tether bound itself */
    gd.rest_positions = s->sheet.pos;
    gd.vertex_count = s->sheet.nv;
    gd.triangles = s->sheet.tris;
    gd.triangle_count = s->sheet.nt;
    gd.collider_rest_positions = s->box.pos;
    gd.collider_vertex_count = s->box.nv;
    gd.collider_triangles = s->box.tris;
    gd.collider_triangle_count = s->box.nt;
    return gd;
}

/* The box and the sheet's skinned position after frame f: a pure translation. */
static void shift_of(int f, float d[3])
{
    d[0] = 0.03f * (float)f;
    d[1] = 0.01f * (float)f;
    d[2] = 0.0f;
}

static void move_box(tether_scene *s, int f)
{
    float d[3];
    shift_of(f, d);
    for (uint32_t i = 0; i < s->box.nv; ++i) {
        for (int k = 0; k < 3; ++k) {
            s->moved[3 * i + k] = s->box.pos[3 * i + k] + d[k];
        }
    }
}

/* Largest distance of a vertex from its skinned position (the initial sheet, translated). */
static double max_tether_gap(const tether_scene *s, const float *x, int f, uint32_t skip)
{
    float d[3];
    shift_of(f, d);
    double worst = 0.0;
    for (uint32_t i = 0; i < s->sheet.nv; ++i) {
        if (i == skip) {
            continue;
        }
        double e2 = 0.0;
        for (int k = 0; k < 3; ++k) {
            double e = (double)x[3 * i + k] - ((double)s->sheet.pos[3 * i + k] + d[k]);
            e2 += e * e;
        }
        worst = fmax(worst, sqrt(e2));
    }
    return worst;
}

static void test_tethers_bound_the_drift(void)
{
    tether_scene s;
    scene_make(&s);
    /* Without tethers XPBD leaves the sheet behind (the box slides out from under it). */
    weft_garment_def gd = scene_def(&s, WEFT_METHOD_XPBD);
    weft_garment *free_g = NULL, *tied = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &free_g), WEFT_OK);
    gd.tethers.distance = 0.01f;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &tied), WEFT_OK);
    double free_gap = 0.0, tied_gap = 0.0;
    uint32_t clamped = 0;
    for (int f = 1; f <= 20; ++f) {
        move_box(&s, f);
        CHECK_RESULT(weft_garment_set_collider(free_g, s.moved), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(tied, s.moved), WEFT_OK);
        CHECK_RESULT(weft_garment_step(free_g), WEFT_OK);
        CHECK_RESULT(weft_garment_step(tied), WEFT_OK);
        free_gap = fmax(free_gap, max_tether_gap(&s, weft_garment_positions(free_g), f, UINT32_MAX));
        tied_gap = fmax(tied_gap, max_tether_gap(&s, weft_garment_positions(tied), f, UINT32_MAX));
        clamped += weft_garment_stats(tied).tether_vertices_clamped;
    }
    CHECK_MSG(free_gap > 0.2, "untethered sheet only %g m from its skinned position: the scene tests nothing",
              free_gap);
    /* float rounding of the skinned target and of the clamp: well under a micrometre */
    CHECK_MSG(tied_gap <= 0.01 + 1e-6, "tethered sheet %g m from its skinned position (radius 0.01 m)", tied_gap);
    CHECK_MSG(clamped > 0, "no vertex was clamped");
    CHECK_EQ_INT(weft_garment_stats(free_g).tether_vertices_clamped, 0);
    weft_garment_destroy(free_g);
    weft_garment_destroy(tied);
    scene_free(&s);
}

static void test_tethers_keep_pins_and_glue(void)
{
    tether_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s, WEFT_METHOD_XPBD);
    float *radii = malloc(sizeof(float) * s.sheet.nv);
    for (uint32_t i = 0; i < s.sheet.nv; ++i) {
        radii[i] = i < 10 ? 0.0f : 0.05f; /* the first row glued */
    }
    gd.tethers.distance = 1.0f; /* replaced by the per-vertex radii */
    gd.tethers.distances = radii;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_OK);
    free(radii); /* copied at creation */
    const uint32_t pin = 55;
    for (int f = 1; f <= 10; ++f) {
        move_box(&s, f);
        /* a pin 30 cm above its skinned position: far outside its 5 cm tether */
        float target[3] = {s.sheet.pos[3 * pin], s.sheet.pos[3 * pin + 1] + 0.3f, s.sheet.pos[3 * pin + 2]};
        CHECK_RESULT(weft_garment_set_collider(g, s.moved), WEFT_OK);
        CHECK_RESULT(weft_garment_set_pins(g, &pin, target, 1), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        const float *x = weft_garment_positions(g);
        CHECK_MSG(memcmp(x + 3 * pin, target, sizeof target) == 0, "pinned vertex left its target at frame %d", f);
        float d[3];
        shift_of(f, d);
        double glue = 0.0;
        for (uint32_t i = 0; i < 10; ++i) {
            for (int k = 0; k < 3; ++k) {
                glue = fmax(glue, fabs((double)x[3 * i + k] - ((double)s.sheet.pos[3 * i + k] + d[k])));
            }
        }
        CHECK_MSG(glue < 5e-6, "glued row %g m off its skinned position at frame %d", glue, f);
        CHECK_MSG(max_tether_gap(&s, x, f, pin) <= 0.05 + 1e-6, "a vertex left its 5 cm tether at frame %d", f);
    }
    weft_garment_destroy(g);
    scene_free(&s);
}

static void test_tethers_bad_input(void)
{
    tether_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s, WEFT_METHOD_XPBD);
    weft_garment *g = NULL;
    const float bad[] = {-0.01f, NAN, INFINITY};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        gd.tethers.distance = bad[k];
        CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "tethers.distance") != NULL);
    }
    float *radii = malloc(sizeof(float) * s.sheet.nv);
    for (uint32_t i = 0; i < s.sheet.nv; ++i) {
        radii[i] = 0.02f;
    }
    radii[17] = NAN;
    gd.tethers.distance = 0.0f;
    gd.tethers.distances = radii;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "tethers.distances[17]") != NULL);
    radii[17] = 0.02f;
    /* tethers follow the collider: none, no tethers */
    weft_garment_def lone = gd;
    lone.collider_rest_positions = NULL;
    lone.collider_vertex_count = 0;
    lone.collider_triangles = NULL;
    lone.collider_triangle_count = 0;
    CHECK_RESULT(weft_garment_create(s.ctx, &lone, &g), WEFT_ERROR_NO_COLLIDER);
    CHECK(g == NULL);

    /* A step whose binding collapses (every collider vertex at one point) fails and keeps the state. */
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_OK);
    move_box(&s, 1);
    CHECK_RESULT(weft_garment_set_collider(g, s.moved), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    float *before = malloc(sizeof(float) * 3 * s.sheet.nv);
    memcpy(before, weft_garment_positions(g), sizeof(float) * 3 * s.sheet.nv);
    const uint64_t frame = weft_garment_stats(g).frame;
    for (uint32_t i = 0; i < s.box.nv; ++i) {
        s.moved[3 * i] = 0.0f, s.moved[3 * i + 1] = 0.1f, s.moved[3 * i + 2] = 0.0f;
    }
    CHECK_RESULT(weft_garment_set_collider(g, s.moved), WEFT_OK);
    weft_result r = weft_garment_step(g);
    CHECK_MSG(r != WEFT_OK, "a collapsed collider stepped without error");
    CHECK(memcmp(before, weft_garment_positions(g), sizeof(float) * 3 * s.sheet.nv) == 0);
    CHECK_EQ_INT(weft_garment_stats(g).frame, frame);
    free(before);
    free(radii);
    weft_garment_destroy(g);
    scene_free(&s);
}

/* A body that passes through itself: a sheet rides on box A (LBS), A slides under a static wall
 * B that reaches below A's top. CCD stops the sheet at B's face while A moves on: without the
 * tethers' last clamp CCD would hold it there and the sheet would be dragged off. With tethers
 * every output vertex stays within its radius, CCD or not, and the release is counted. */
static void test_tethers_outrank_ccd(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh sheet = test_sheet(8, 8, 0.2f, 0.2f, 0.0f, 0.21f, 0.0f);
    const float alo[3] = {-0.15f, 0.0f, -0.15f}, ahi[3] = {0.15f, 0.2f, 0.15f};
    const float blo[3] = {0.3f, 0.15f, -0.5f}, bhi[3] = {0.4f, 0.5f, 0.5f};
    test_mesh a = test_box(alo, ahi), b = test_box(blo, bhi);
    test_mesh body = test_mesh_join(&a, &b);
    CHECK(body.pos != NULL);
    float *moved = malloc(sizeof(float) * 3 * body.nv);
    weft_garment_def gd = test_garment_def(WEFT_METHOD_LBS, &sheet, &body, 1);
    gd.ccd.enabled = true;
    weft_garment *held = NULL, *tied = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &held), WEFT_OK);
    gd.tethers.distance = 0.02f;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &tied), WEFT_OK);
    double held_gap = 0.0, tied_gap = 0.0;
    uint32_t released = 0;
    for (int f = 1; f <= 20; ++f) {
        const float dx = 0.03f * (float)f; /* A moves, B stays */
        memcpy(moved, body.pos, sizeof(float) * 3 * body.nv);
        for (uint32_t i = 0; i < a.nv; ++i) {
            moved[3 * i] += dx;
        }
        CHECK_RESULT(weft_garment_set_collider(held, moved), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(tied, moved), WEFT_OK);
        CHECK_RESULT(weft_garment_step(held), WEFT_OK);
        CHECK_RESULT(weft_garment_step(tied), WEFT_OK);
        released += weft_garment_stats(tied).ccd_released;
        for (uint32_t i = 0; i < sheet.nv; ++i) {
            const float *xh = weft_garment_positions(held) + 3 * i, *xt = weft_garment_positions(tied) + 3 * i;
            const float *r = sheet.pos + 3 * i;
            held_gap = fmax(held_gap, sqrt(pow(xh[0] - (r[0] + dx), 2) + pow(xh[1] - r[1], 2) + pow(xh[2] - r[2], 2)));
            tied_gap = fmax(tied_gap, sqrt(pow(xt[0] - (r[0] + dx), 2) + pow(xt[1] - r[1], 2) + pow(xt[2] - r[2], 2)));
        }
    }
    CHECK_MSG(held_gap > 0.2, "CCD held the untethered sheet only %g m from its skinned position: the scene tests "
              "nothing", held_gap);
    CHECK_MSG(tied_gap <= 0.02 + 1e-6, "tethered sheet %g m from its skinned position with CCD (radius 0.02 m)",
              tied_gap);
    CHECK_MSG(released > 0, "the tethers released no vertex CCD held");
    CHECK_EQ_INT(weft_garment_stats(held).ccd_released, 0);
    weft_garment_destroy(held);
    weft_garment_destroy(tied);
    free(moved);
    test_mesh_free(&body);
    test_mesh_free(&b);
    test_mesh_free(&a);
    test_mesh_free(&sheet);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_tethers_bound_the_drift), TEST_CASE(test_tethers_keep_pins_and_glue),
          TEST_CASE(test_tethers_bad_input), TEST_CASE(test_tethers_outrank_ccd))
