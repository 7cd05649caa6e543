/* The validator's cloth-cloth exemption (weft_sim_validator_set_self_exempt): a sheet pushed down
 * through another is a hit in the sweeps and in the triangle test; with the moving sheet's
 * vertices exempt it is not, and with the mask removed again it is. NULL validator is refused.
 * weft_sim_validator_tangled marks cloth crossing itself (the crossing triangles' corners and their
 * ring), nothing on cloth that does not cross, and refuses non-finite positions. */
#include "../xpbd/scene.h"
#include "test.h"
#include "weft/sim.h"

#include <math.h>
#include <string.h>

/* Two flat sheets of n x n vertices as one cloth (the second 1 cm above the first, size_b wide,
 * centred at (cx, cz)) and a validator of it without a collider. */
typedef struct two_sheets {
    weft_context *ctx;
    test_mesh a, b, both;
    weft_sim_validator *v;
} two_sheets;

static two_sheets two_sheets_make(uint32_t n, float size_a, float size_b, float cx, float cz)
{
    two_sheets t = {0};
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &t.ctx), WEFT_OK);
    t.a = test_sheet(n, n, size_a, size_a, 0.0f, 0.0f, 0.0f);
    t.b = test_sheet(n, n, size_b, size_b, cx, 0.01f, cz);
    t.both = test_mesh_join(&t.a, &t.b);
    CHECK(t.both.pos && t.both.tris);
    CHECK_RESULT(weft_sim_validator_create(t.ctx, t.both.tris, t.both.nt, t.both.nv, NULL, 0, 0, &t.v), WEFT_OK);
    return t;
}

static void two_sheets_free(two_sheets *t)
{
    weft_sim_validator_destroy(t->v);
    test_mesh_free(&t->a);
    test_mesh_free(&t->b);
    test_mesh_free(&t->both);
    weft_context_destroy(t->ctx);
}

static void test_exempt_cloth_is_not_certified(void)
{
    two_sheets t = two_sheets_make(6, 0.3f, 0.2f, 0.01f, 0.01f);
    const test_mesh a = t.a, both = t.both;
    weft_sim_validator *v = t.v;
    float *after = malloc(sizeof(float) * 3 * both.nv);
    uint8_t *exempt = calloc(both.nv, 1);
    CHECK(after && exempt);
    memcpy(after, both.pos, sizeof(float) * 3 * both.nv);
    for (uint32_t i = a.nv; i < both.nv; ++i) {
        after[3 * i + 1] -= 0.02f; /* from 1 cm above the other sheet to 1 cm below it */
        exempt[i] = 1;
    }
    weft_sim_validation val;
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK(val.ccd_hits > 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(v, exempt), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK_EQ_INT(val.ccd_hits, 0);
    CHECK_EQ_INT(val.intersection_hits, 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(v, NULL), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK(val.ccd_hits > 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(NULL, exempt), WEFT_ERROR_INVALID_ARGUMENT);
    free(after);
    free(exempt);
    two_sheets_free(&t);
}

static void test_tangled_marks_the_crossing(void)
{
    two_sheets t = two_sheets_make(9, 0.4f, 0.4f, 0.0f, 0.0f);
    const test_mesh a = t.a, both = t.both;
    weft_sim_validator *v = t.v;
    float *x = malloc(sizeof(float) * 3 * both.nv);
    uint8_t *tangled = malloc(both.nv);
    CHECK(x && tangled);
    memcpy(x, both.pos, sizeof(float) * 3 * both.nv);
    uint32_t count = 99;
    memset(tangled, 7, both.nv);
    CHECK_RESULT(weft_sim_validator_tangled(v, x, NULL, tangled, &count, NULL), WEFT_OK);
    CHECK_EQ_INT(count, 0);
    for (uint32_t i = 0; i < both.nv; ++i) {
        CHECK_EQ_INT(tangled[i], 0);
    }
    /* The upper sheet's x > 0 half sinks 2 cm: it crosses the lower sheet along a line near x = 0. */
    for (uint32_t i = a.nv; i < both.nv; ++i) {
        if (x[3 * i] > 0.0f) {
            x[3 * i + 1] -= 0.02f;
        }
    }
    CHECK_RESULT(weft_sim_validator_tangled(v, x, NULL, tangled, &count, NULL), WEFT_OK);
    uint32_t marked = 0, marked_lower = 0, far_marked = 0;
    for (uint32_t i = 0; i < both.nv; ++i) {
        CHECK(tangled[i] <= 1);
        marked += tangled[i];
        marked_lower += i < a.nv && tangled[i];
        far_marked += tangled[i] && fabsf(x[3 * i]) > 0.16f; /* beyond the crossing's triangles and ring */
    }
    CHECK(count > 0 && count < marked); /* the corners; the ring is marked, not counted */
    CHECK(marked_lower > 0 && marked > marked_lower);
    CHECK_EQ_INT(far_marked, 0);
    /* Counted outside a pinch: the lower sheet pinched leaves the upper sheet's corners; all
     * pinched, none; without pinched, all of them. */
    uint8_t *pinched = calloc(both.nv, 1);
    CHECK(pinched != NULL);
    uint32_t all = 0, clear = 99, upper_corners = 0, lower_corners = 0;
    CHECK_RESULT(weft_sim_validator_tangled(v, x, NULL, tangled, &all, &clear), WEFT_OK);
    CHECK_EQ_INT(clear, all);
    memset(pinched, 1, a.nv);
    CHECK_RESULT(weft_sim_validator_tangled(v, x, pinched, tangled, &all, &upper_corners), WEFT_OK);
    memset(pinched, 0, a.nv);
    memset(pinched + a.nv, 1, both.nv - a.nv);
    CHECK_RESULT(weft_sim_validator_tangled(v, x, pinched, tangled, &all, &lower_corners), WEFT_OK);
    CHECK(upper_corners > 0 && lower_corners > 0);
    CHECK_EQ_INT(upper_corners + lower_corners, all);
    memset(pinched, 1, both.nv);
    CHECK_RESULT(weft_sim_validator_tangled(v, x, pinched, tangled, &all, &clear), WEFT_OK);
    CHECK_EQ_INT(clear, 0);
    CHECK_RESULT(weft_sim_validator_tangled(v, x, pinched, tangled, &all, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    free(pinched);
    /* Non-finite positions: refused, the mask untouched. */
    memset(tangled, 5, both.nv);
    x[4] = NAN;
    CHECK_RESULT(weft_sim_validator_tangled(v, x, NULL, tangled, &count, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK_EQ_INT(tangled[0], 5);
    CHECK_RESULT(weft_sim_validator_tangled(NULL, x, NULL, tangled, &count, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    free(x);
    free(tangled);
    two_sheets_free(&t);
}

TEST_MAIN(TEST_CASE(test_exempt_cloth_is_not_certified), TEST_CASE(test_tangled_marks_the_crossing))
