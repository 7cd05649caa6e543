/* weft_fnopt argument checking: bad defs, NaN, wrong models and bad handles fail with a named
 * result and leave the object as it was; a step that blows up is rolled back. */
#include "fnopt_test_util.h"

static void test_bad_defs(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_fnopt *f = NULL;
    weft_fnopt_def def = weft_default_fnopt_def();
    def.optimizer = WEFT_FNOPT_GD;

    weft_fnopt_def d = def;
    d.internal_cookie = 0;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.height = 9;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "height") != NULL);
    d = def;
    d.stretch = NAN;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.bend = -1.0f;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.gravity[1] = INFINITY;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_NOT_FINITE);
    d = def;
    d.iterations = 0;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.learning_rate = 0.0f;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.optimizer = WEFT_FNOPT_OPTIMIZER_COUNT;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_INVALID_ARGUMENT);
    d = def;
    d.optimizer = WEFT_FNOPT_LEARNED;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_NO_MODEL);
    d = def;
    float *bad = calloc(3 * 32 * 32, sizeof(float));
    bad[77] = NAN;
    d.initial_positions = bad;
    CHECK_RESULT(weft_fnopt_create(ctx, &d, &f), WEFT_ERROR_NOT_FINITE);
    free(bad);
    CHECK(f == NULL);
    CHECK_RESULT(weft_fnopt_create(ctx, NULL, &f), WEFT_ERROR_INVALID_ARGUMENT);
    weft_context_destroy(ctx);
}

static void test_wrong_model(void)
{
    /* a safetensors file that is not an fnopt model (the loss golden) */
    weft_context *ctx = fnopt_test_context();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, FNOPT_DATA("loss_golden.safetensors"), &m), WEFT_OK);
    if (m) {
        weft_fnopt_def def = weft_default_fnopt_def();
        def.model = m;
        weft_fnopt *f = NULL;
        CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_ERROR_BAD_METADATA);
        CHECK(strstr(weft_last_error(), "fnopt") != NULL);
        CHECK(f == NULL);
        weft_model_destroy(m);
    }
    weft_context_destroy(ctx);
}

static void test_bad_handles_leave_state(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = def.width = 10;
    def.optimizer = WEFT_FNOPT_ADAM;
    def.report_loss = true;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    if (!f) {
        weft_context_destroy(ctx);
        return;
    }
    uint32_t good[2] = {0, 90};
    float t[6] = {-4.5f, 0, 0, 4.5f, 0, 0};
    CHECK_RESULT(weft_fnopt_set_handles(f, good, t, 2), WEFT_OK);
    double before = 0.0, after = 0.0;
    CHECK_RESULT(weft_fnopt_loss(f, NULL, &before, NULL), WEFT_OK);

    uint32_t dup[2] = {5, 5}, range[2] = {0, 100};
    float tn[6] = {0, 0, 0, NAN, 0, 0};
    CHECK_RESULT(weft_fnopt_set_handles(f, dup, t, 2), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "twice") != NULL);
    CHECK_RESULT(weft_fnopt_set_handles(f, range, t, 2), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_fnopt_set_handles(f, good, tn, 2), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_fnopt_set_handles(f, NULL, t, 2), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_fnopt_set_handles(f, good, t, 101), WEFT_ERROR_SIZE_MISMATCH);
    CHECK_RESULT(weft_fnopt_set_material(f, 1.0f, NAN, 1.0f), WEFT_ERROR_INVALID_ARGUMENT);
    const float g_bad[3] = {0, NAN, 0};
    CHECK_RESULT(weft_fnopt_set_gravity(f, g_bad), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_fnopt_loss(f, NULL, &after, NULL), WEFT_OK);
    CHECK(before == after);

    /* a duplicate rejected after a valid prefix must not leave stale marks behind */
    uint32_t ok3[3] = {1, 2, 3};
    float t3[9] = {0};
    CHECK_RESULT(weft_fnopt_set_handles(f, ok3, t3, 3), WEFT_OK);
    CHECK_RESULT(weft_fnopt_set_handles(f, good, t, 2), WEFT_OK);
    CHECK_RESULT(weft_fnopt_loss(f, NULL, &after, NULL), WEFT_OK);
    CHECK(before == after);

    float *x = malloc(300 * sizeof(float));
    memcpy(x, weft_fnopt_positions(f), 300 * sizeof(float));
    x[5] = INFINITY;
    CHECK_RESULT(weft_fnopt_set_state(f, x, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(isfinite(weft_fnopt_positions(f)[5]));
    float acc[300] = {0};
    acc[7] = NAN;
    CHECK_RESULT(weft_fnopt_loss(f, acc, &after, NULL), WEFT_ERROR_NOT_FINITE);
    free(x);
    weft_fnopt_destroy(f);
    weft_context_destroy(ctx);
}

static void test_blowup_rolls_back(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = def.width = 10;
    def.optimizer = WEFT_FNOPT_GD;
    def.learning_rate = 1e30f; /* overflows to infinity within a few iterations */
    def.iterations = 50;
    def.descent_guard = false; /* the guard would commit a = 0 (below) */
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    if (f) {
        float before[300];
        memcpy(before, weft_fnopt_positions(f), sizeof before);
        CHECK_RESULT(weft_fnopt_step(f), WEFT_ERROR_NOT_FINITE);
        CHECK(memcmp(before, weft_fnopt_positions(f), sizeof before) == 0);
        CHECK_EQ_INT(weft_fnopt_get_stats(f).frame, 0);
        weft_fnopt_destroy(f);
    }
    /* with the descent guard the same step commits the lowest-loss iterate, a = 0 here */
    def.descent_guard = true;
    f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    if (f) {
        CHECK_RESULT(weft_fnopt_step(f), WEFT_OK);
        CHECK_EQ_INT(weft_fnopt_get_stats(f).committed_iterate, 0);
        CHECK_EQ_INT(weft_fnopt_get_stats(f).frame, 1);
        weft_fnopt_destroy(f);
    }
    weft_context_destroy(ctx);
}

static void test_units(void)
{
    /* 9.76 m/s^2 on a 1 m cloth at 32 x 32 and 50 steps/s: 9.76 * 31 / 2500 grid units/step^2 */
    CHECK_NEAR(weft_fnopt_acceleration(9.76f, 32, 1.0f, 50.0f), 0.1210240, 1e-6);
    CHECK_NEAR(weft_fnopt_acceleration(9.76f, 100, 1.0f, 50.0f), 0.3865, 1e-4);
    CHECK_NEAR(weft_fnopt_acceleration(9.76f, 1, 1.0f, 50.0f), 0.0, 0.0);
    weft_fnopt_def d = weft_default_fnopt_def();
    CHECK_NEAR(d.gravity[2], -weft_fnopt_acceleration(9.76f, 32, 1.0f, 50.0f), 1e-7);
    CHECK_EQ_INT(d.iterations, 10);
}

TEST_MAIN(TEST_CASE(test_bad_defs), TEST_CASE(test_wrong_model), TEST_CASE(test_bad_handles_leave_state),
          TEST_CASE(test_blowup_rolls_back), TEST_CASE(test_units))
