/* The floor (weft_garment_def.collision.ground): a sheet dropped with no collider comes to rest
 * on it under every method that moves cloth on its own, never below, without sliding; pins stay
 * on their targets; a bad height is refused. */
#include "test.h"
#include "weft/body.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static weft_context *g_ctx;

static void drop_sheet(weft_method method)
{
    weft_cloth_def cd = weft_default_cloth_def(WEFT_CLOTH_SHEET);
    cd.target_vertices = 400;
    cd.size = 0.6f;
    cd.height = 0.5f;
    weft_cloth_mesh *sheet = NULL;
    CHECK_RESULT(weft_cloth_create(g_ctx, &cd, NULL, &sheet), WEFT_OK);
    if (!sheet) {
        return;
    }
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.rest_positions = sheet->positions;
    d.vertex_count = sheet->vertex_count;
    d.triangles = sheet->triangles;
    d.triangle_count = sheet->triangle_count;
    d.ccd.enabled = false;
    d.collision.ground = true;
    d.collision.ground_height = 0.2f;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_OK);
    if (!g) {
        weft_cloth_destroy(sheet);
        return;
    }
    /* one corner pinned 1 cm above the floor's level stays there */
    const uint32_t pin = 0;
    const float target[3] = {sheet->positions[0], 0.21f, sheet->positions[2]};
    uint32_t held_max = 0;
    float *before = malloc((size_t)sheet->vertex_count * 3 * sizeof(float));
    for (int k = 0; k < 180; ++k) {
        if (k == 120) {
            CHECK_RESULT(weft_garment_set_pins(g, &pin, target, 1), WEFT_OK);
        }
        memcpy(before, weft_garment_positions(g), (size_t)sheet->vertex_count * 3 * sizeof(float));
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        const weft_step_stats st = weft_garment_stats(g);
        held_max = st.ground_vertices > held_max ? st.ground_vertices : held_max;
    }
    const float *x = weft_garment_positions(g);
    float lowest = INFINITY, highest = -INFINITY, slide = 0.0f;
    for (uint32_t i = 0; i < sheet->vertex_count; ++i) {
        lowest = fminf(lowest, x[3 * i + 1]);
        highest = fmaxf(highest, x[3 * i + 1]);
        if (i != pin && x[3 * i + 1] == 0.2f && before[3 * i + 1] == 0.2f) {
            slide = fmaxf(slide, fabsf(x[3 * i] - before[3 * i]) + fabsf(x[3 * i + 2] - before[3 * i + 2]));
        }
    }
    printf("  method %d: %u of %u vertices on the floor at most, lowest %.4f m, highest %.4f m, slide %.1e m\n",
           (int)method, held_max, sheet->vertex_count, (double)lowest, (double)highest, (double)slide);
    CHECK_MSG(lowest >= 0.2f, "below the floor: %.4f", (double)lowest);
    CHECK(held_max > sheet->vertex_count / 2);
    CHECK_MSG(highest < 0.25f, "not at rest on the floor: highest %.4f", (double)highest);
    CHECK(slide == 0.0f);
    CHECK(fabsf(x[1] - 0.21f) < 1e-6f);
    free(before);
    weft_garment_destroy(g);
    weft_cloth_destroy(sheet);
}

static void test_sheet_lands_xpbd(void) { drop_sheet(WEFT_METHOD_XPBD); }

static void test_bad_height(void)
{
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
    const uint32_t tri[3] = {0, 1, 2};
    weft_garment_def d = weft_default_garment_def();
    d.method = WEFT_METHOD_XPBD;
    d.rest_positions = pos;
    d.vertex_count = 3;
    d.triangles = tri;
    d.triangle_count = 1;
    d.collision.ground = true;
    d.collision.ground_height = NAN;
    weft_garment *g = (weft_garment *)(uintptr_t)1;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "ground_height") != NULL);
    d.collision.ground_height = 2e4f;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == (weft_garment *)(uintptr_t)1);
    /* off by default: a NaN height is not looked at */
    d.collision.ground = false;
    CHECK_RESULT(weft_garment_create(g_ctx, &d, &g), WEFT_OK);
    weft_garment_destroy(g);
}

static void setup(void)
{
    weft_context_def cdef = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cdef, &g_ctx), WEFT_OK);
}

static void teardown(void) { weft_context_destroy(g_ctx); }

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_sheet_lands_xpbd), TEST_CASE(test_bad_height), TEST_CASE(teardown))
