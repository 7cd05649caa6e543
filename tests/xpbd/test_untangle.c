/* Untangling in the reference with a projected body (weft__xpbd_set_untangle): two sheets lie
 * one above the other over a box, and a patch of the upper one has been pushed through the lower
 * one (as a squeeze between two body parts leaves it). Given the cloth crossing itself at each
 * frame's start (the validator's marks, as simgen passes them), the reference brings the patch
 * back within a few frames and the sheets stay apart; without the marks the bounded contacts hold
 * the crossing. Marks on cloth that crosses nothing change nothing, bit for bit. */
#include "scene.h"
#include "test.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

#include <string.h>

typedef struct tangle_scene {
    test_mesh lower, upper, both, box;
    float *start;
} tangle_scene;

/* The lower sheet 3 cm above the box's top, the upper 1 cm above it, and the upper sheet's
 * vertices within 3.5 cm of its centre 6 mm below the lower sheet. */
static tangle_scene make_scene(void)
{
    tangle_scene s;
    s.lower = test_sheet(15, 15, 0.4f, 0.4f, 0.0f, 0.23f, 0.0f);
    s.upper = test_sheet(15, 15, 0.4f, 0.4f, 0.007f, 0.24f, 0.005f);
    s.both = test_mesh_join(&s.lower, &s.upper);
    const float lo[3] = {-0.25f, 0.0f, -0.25f}, hi[3] = {0.25f, 0.2f, 0.25f};
    s.box = test_box(lo, hi);
    s.start = malloc(sizeof(float) * 3 * s.both.nv);
    CHECK(s.both.pos && s.start);
    memcpy(s.start, s.both.pos, sizeof(float) * 3 * s.both.nv);
    for (uint32_t i = s.lower.nv; i < s.both.nv; ++i) {
        float *p = s.start + 3 * i;
        if ((p[0] - 0.007f) * (p[0] - 0.007f) + (p[2] - 0.005f) * (p[2] - 0.005f) < 0.035f * 0.035f) {
            p[1] = 0.224f;
        }
    }
    return s;
}

static void free_scene(tangle_scene *s)
{
    test_mesh_free(&s->lower);
    test_mesh_free(&s->upper);
    test_mesh_free(&s->both);
    test_mesh_free(&s->box);
    free(s->start);
}

/* Runs frames with the box still from `start`; marks: whether each step is given the cloth
 * crossing itself at its start (all_marked: every vertex instead). Returns the cloth vertices at
 * the corners of crossing triangles at the start; crossed[f]: after frame f. */
static uint32_t run_from(weft_context *ctx, tangle_scene *s, const float *start, bool marks, bool all_marked,
                         int frames, uint32_t *crossed, float *out)
{
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD, &s->both, &s->box, 10);
    gd.substeps_max = 80;
    gd.collider_projection = true;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    CHECK_RESULT(weft_garment_set_state(g, start, start), WEFT_OK);
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, s->both.tris, s->both.nt, s->both.nv, NULL, 0, 0, &v), WEFT_OK);
    uint8_t *mask = calloc(s->both.nv, 1);
    CHECK(mask != NULL);
    uint32_t count = 0;
    CHECK_RESULT(weft_sim_validator_tangled(v, start, NULL, mask, &count, NULL), WEFT_OK);
    for (int f = 0; f < frames; ++f) {
        if (all_marked) {
            memset(mask, 1, s->both.nv);
        }
        CHECK_RESULT(weft__xpbd_set_untangle(g, marks ? mask : NULL), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(g, s->box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        CHECK_RESULT(weft_sim_validator_tangled(v, weft_garment_positions(g), NULL, mask, &crossed[f], NULL), WEFT_OK);
    }
    memcpy(out, weft_garment_positions(g), sizeof(float) * 3 * s->both.nv);
    free(mask);
    weft_sim_validator_destroy(v);
    weft_garment_destroy(g);
    return count;
}

static void test_patch_comes_back(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    tangle_scene s = make_scene();
    enum { FRAMES = 30 };
    uint32_t with[FRAMES], without[FRAMES];
    float *x = malloc(sizeof(float) * 3 * s.both.nv), *y = malloc(sizeof(float) * 3 * s.both.nv);
    CHECK(x && y);
    CHECK_RESULT(weft__xpbd_set_untangle(NULL, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_MSG(run_from(ctx, &s, s.start, true, false, FRAMES, with, x) > 0, "the scene does not start tangled");
    run_from(ctx, &s, s.start, false, false, FRAMES, without, y);
    int undone = -1;
    for (int f = 0; f < FRAMES; ++f) {
        if (with[f] == 0 && undone < 0) {
            undone = f;
        }
        CHECK_MSG(undone < 0 || with[f] == 0, "frame %d: %u vertices crossing again", f, with[f]);
    }
    CHECK_MSG(undone >= 0 && undone < 10, "the crossing lasted %d frames (%u vertices at the end)", undone,
              with[FRAMES - 1]);
    CHECK_MSG(without[FRAMES - 1] > 0, "without the marks the crossing went too (the test shows nothing)");
    /* the upper sheet ends above the lower one everywhere */
    float centre_lower, upper_min;
    test_two_layer_heights(x, s.lower.nv, s.upper.nv, &centre_lower, &upper_min);
    CHECK_MSG(upper_min > centre_lower, "upper sheet's lowest vertex %g, lower sheet's centre %g", upper_min,
              centre_lower);
    free(x);
    free(y);
    free_scene(&s);
    weft_context_destroy(ctx);
}

/* The sheets as drawn, crossing nothing: every vertex marked, the run is the unmarked one bit for
 * bit (untangling only acts on a crossing). */
static void test_marks_without_crossing_change_nothing(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    tangle_scene s = make_scene();
    enum { FRAMES = 15 };
    uint32_t crossed[2][FRAMES];
    float *x = malloc(sizeof(float) * 3 * s.both.nv), *y = malloc(sizeof(float) * 3 * s.both.nv);
    CHECK(x && y);
    CHECK_EQ_INT(run_from(ctx, &s, s.both.pos, true, true, FRAMES, crossed[0], x), 0);
    run_from(ctx, &s, s.both.pos, false, false, FRAMES, crossed[1], y);
    CHECK(memcmp(x, y, sizeof(float) * 3 * s.both.nv) == 0);
    CHECK_EQ_INT(crossed[0][FRAMES - 1], 0);
    free(x);
    free(y);
    free_scene(&s);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_patch_comes_back), TEST_CASE(test_marks_without_crossing_change_nothing))
