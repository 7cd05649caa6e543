/* The render sample's FNOpt cape (samples/common/cape.c): argument checks, pins that follow the
 * body, a cloth that hangs below them, and a finite state over a few steps of a walk. */
#include "fnopt_test_util.h"
#include "weft/wear.h"
#include "weft_sample.h"

#if WEFT_RENDER_HAVE_SAMPLE

static weft_result make_cape(weft_context *ctx, const weft_body *body, const char *model, uint32_t across,
                             uint32_t down, uint32_t xpbd_substeps, weft_sample_cape **out)
{
    weft_sample_cape_def d = weft_sample_default_cape_def();
    d.model_path = model;
    d.across = across;
    d.down = down;
    d.xpbd_substeps = xpbd_substeps;
    return weft_sample_cape_create(ctx, body, &d, out);
}

static void test_cape_follows_body(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_avatar_def ad = weft_default_avatar_def();
    ad.target_vertices = 2000; /* the smallest mesh: the cape only reads its shape */
    weft_body *body = NULL;
    CHECK_RESULT(weft_avatar_create(ctx, &ad, &body), WEFT_OK);
    if (!body) {
        weft_context_destroy(ctx);
        return;
    }
    weft_sample_cape *cape = NULL;
    CHECK_RESULT(make_cape(ctx, body, FNOPT_MODEL_PATH, 9, 40, 0, &cape), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(cape == NULL);
    CHECK_RESULT(make_cape(ctx, body, FNOPT_MODEL_PATH, 12, 16, 201, &cape), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(cape == NULL);
    CHECK(make_cape(ctx, body, FNOPT_DATA("no_such_file.safetensors"), 12, 16, 0, &cape) != WEFT_OK);
    CHECK(cape == NULL);
    const uint32_t across = 12, down = 16;
    CHECK_RESULT(make_cape(ctx, body, FNOPT_MODEL_PATH, across, down, 0, &cape), WEFT_OK);
    if (!cape) {
        weft_body_destroy(body);
        weft_context_destroy(ctx);
        return;
    }
    CHECK_EQ_INT(weft_sample_cape_vertex_count(cape), across * down);
    uint32_t tc = 0;
    const uint32_t *tris = weft_sample_cape_triangles(cape, &tc);
    CHECK_EQ_INT(tc, 2 * (across - 1) * (down - 1));
    bool in_range = true;
    for (uint32_t t = 0; t < 3 * tc; ++t) {
        in_range &= tris[t] < across * down;
    }
    CHECK(in_range);
    const float lc = weft_sample_cape_units_per_metre(cape);
    CHECK(lc > 5.0f && lc < 500.0f);

    weft_pose pose;
    weft_body_bind_pose(body, &pose);
    const float *p = weft_sample_cape_positions(cape);
    const float x0 = p[0];
    for (int s = 0; s < 4; ++s) {
        /* the body walks sideways 1 cm per step: the pinned top row must go with it */
        pose.translation[0] += 0.01f;
        CHECK_RESULT(weft_sample_cape_step(cape, body, &pose, NULL), WEFT_OK);
    }
    p = weft_sample_cape_positions(cape);
    CHECK_NEAR(p[0] - x0, 0.04, 1e-4);
    bool finite = true;
    for (uint32_t q = 0; q < 3 * across * down; ++q) {
        finite &= isfinite(p[q]);
    }
    CHECK(finite);
    /* the top row keeps the rest spacing (one grid unit), the bottom row hangs below it */
    for (uint32_t i = 0; i + 1 < across; ++i) {
        const float *a = p + 3 * (size_t)i * down, *b = p + 3 * (size_t)(i + 1) * down;
        float d = sqrtf((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
        CHECK_NEAR(d * lc, 1.0, 0.05);
        CHECK(p[3 * ((size_t)i * down + down - 1) + 1] < a[1] - 0.5f * (float)(down - 1) / lc);
    }
    CHECK_EQ_INT(weft_sample_cape_failed_steps(cape), 0);
    weft_sample_cape_destroy(cape);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

/* Body collision: the body (not the pins) moves 2 cm a step back into the hanging cape. Without
 * the collision stage part of the cape ends up inside it; with it none does, and the push is what
 * moved it. The same for the fast-XPBD cape (its own collision). */
static void cape_collides(uint32_t xpbd_substeps)
{
    weft_context *ctx = fnopt_test_context();
    weft_avatar_def ad = weft_default_avatar_def();
    ad.target_vertices = 2000;
    weft_body *body = NULL;
    CHECK_RESULT(weft_avatar_create(ctx, &ad, &body), WEFT_OK);
    if (!body) {
        weft_context_destroy(ctx);
        return;
    }
    const uint32_t across = 12, down = 16, n = across * down;
    weft_sample_cape *with = NULL, *without = NULL;
    CHECK_RESULT(make_cape(ctx, body, FNOPT_MODEL_PATH, across, down, xpbd_substeps, &with), WEFT_OK);
    CHECK_RESULT(make_cape(ctx, body, FNOPT_MODEL_PATH, across, down, xpbd_substeps, &without), WEFT_OK);
    const uint32_t nbv = weft_body_vertex_count(body), nbt = weft_body_triangle_count(body);
    float *bv = malloc(sizeof(float) * 3 * nbv);
    weft_wear *wear = NULL;
    CHECK_RESULT(weft_wear_create(weft_body_triangles(body), nbt, nbv, n, &wear), WEFT_OK);
    if (!with || !without || !bv || !wear) {
        goto done;
    }
    weft_pose pose;
    weft_body_bind_pose(body, &pose);
    uint32_t pushed = 0;
    float *still = malloc(sizeof(float) * 3 * nbv); /* the XPBD cape "without" collides with the unmoved body */
    CHECK_RESULT(weft_body_pose(body, &pose, still, NULL), WEFT_OK);
    for (int s = 0; s < 6 && still; ++s) {
        CHECK_RESULT(weft_body_pose(body, &pose, bv, NULL), WEFT_OK);
        for (uint32_t v = 0; v < nbv; ++v) {
            bv[3 * v + 2] -= 0.02f * (float)(s + 1); /* the cape hangs behind: -z */
        }
        CHECK_RESULT(weft_sample_cape_step(with, body, &pose, bv), WEFT_OK);
        CHECK_RESULT(weft_sample_cape_step(without, body, &pose, xpbd_substeps ? still : NULL), WEFT_OK);
        pushed += weft_sample_cape_pushed(with);
    }
    /* the pinned top row follows the pose, not the moved body, and pins win over collision: it
     * is left out of the count (moved far away) */
    float *pw = malloc(sizeof(float) * 3 * n), *po = malloc(sizeof(float) * 3 * n);
    memcpy(pw, weft_sample_cape_positions(with), sizeof(float) * 3 * n);
    memcpy(po, weft_sample_cape_positions(without), sizeof(float) * 3 * n);
    for (uint32_t i = 0; i < across; ++i) {
        pw[3 * (size_t)i * down + 1] = po[3 * (size_t)i * down + 1] = 100.0f;
    }
    weft_wear_frame fw = {0}, fo = {0};
    CHECK_RESULT(weft_wear_measure(wear, bv, pw, pw, 0.1f, &fw), WEFT_OK);
    CHECK_RESULT(weft_wear_measure(wear, bv, po, po, 0.1f, &fo), WEFT_OK);
    free(pw);
    free(po);
    printf("%s cape: %.1f %% inside without the collider, %.1f %% with it\n", xpbd_substeps ? "XPBD" : "FNOpt",
           100.0 * fo.inside_body, 100.0 * fw.inside_body);
    CHECK_MSG(fo.inside_body > 0.02, "without collision %.1f %% of the cape inside", 100.0 * fo.inside_body);
    CHECK_MSG(fw.inside_body == 0.0, "with collision %.1f %% of the cape inside", 100.0 * fw.inside_body);
    CHECK(pushed > 0);
    if (!xpbd_substeps) {
        CHECK_EQ_INT(weft_sample_cape_pushed(without), 0);
    }
    free(still);
done:
    weft_wear_destroy(wear);
    free(bv);
    weft_sample_cape_destroy(with);
    weft_sample_cape_destroy(without);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

static void test_cape_collides_with_body(void) { cape_collides(0); }
static void test_xpbd_cape_collides_with_body(void) { cape_collides(5); }

TEST_MAIN(TEST_CASE(test_cape_follows_body), TEST_CASE(test_cape_collides_with_body),
          TEST_CASE(test_xpbd_cape_collides_with_body))

#else

static void test_no_sample(void) { printf("no body runtime in this build: the cape is not built\n"); }

TEST_MAIN(TEST_CASE(test_no_sample))

#endif
