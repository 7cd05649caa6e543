/* The C learned optimizer against PyTorch (float64) on the shipped weights: the acceleration
 * after every inner iteration of two steps on a 20 x 24 grid, and positions over a 6-step
 * 16 x 16 rollout (tools/fnopt/make_golden.py writes the goldens). */
#include "fnopt_test_util.h"

static weft_model *load(weft_context *ctx, const char *path)
{
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, path, &m), WEFT_OK);
    return m;
}

static void handle_targets(const float *bc, const uint32_t *idx, float *t)
{
    for (int k = 0; k < 2; ++k) {
        for (int c = 0; c < 3; ++c) {
            t[3 * k + c] = bc[3 * idx[k] + c];
        }
    }
}

static void test_per_iteration(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_model *model = load(ctx, FNOPT_MODEL_PATH), *g = load(ctx, FNOPT_DATA("rollout_golden.safetensors"));
    const float *p = g ? fnopt_golden(g, "iter.params", 10) : NULL;
    if (!model || !p) {
        weft_model_destroy(model);
        weft_model_destroy(g);
        weft_context_destroy(ctx);
        return;
    }
    const uint32_t h = (uint32_t)p[0], w = (uint32_t)p[1];
    const size_t n = (size_t)h * w, n3 = 3 * n;
    const uint32_t idx[2] = {(uint32_t)p[8], (uint32_t)p[9]};
    const float *x0 = fnopt_golden(g, "iter.x0", n3);

    /* internal loop: loss gradient -> learned update, compared after every iteration */
    fnopt_weights wt;
    CHECK_RESULT(fnopt__weights_from_model(model, &wt), WEFT_OK);
    fnopt_loss L;
    fnopt_learned lo;
    CHECK_RESULT(fnopt__loss_init(ctx, &L, h, w), WEFT_OK);
    CHECK_RESULT(fnopt__learned_init(ctx, &lo, &wt, h, w, WEFT_PRECISION_FP32), WEFT_OK);
    float *x = malloc(n3 * sizeof(float)), *v = calloc(n3, sizeof(float)), *acc = malloc(n3 * sizeof(float));
    float *grad = malloc(n3 * sizeof(float)), *bcv = calloc(n3, sizeof(float));
    uint8_t *mask = calloc(n, 1);
    memcpy(x, x0, n3 * sizeof(float));
    mask[idx[0]] = mask[idx[1]] = 1;
    fnopt_loss_input in = {.x = x, .v = v, .mask = mask, .bc = bcv, .Y = p[2], .S = p[3], .B = p[4],
                           .gravity = {p[5], p[6], p[7]}, .k_rep = 0.0f, .rep_thres = 0.5f};
    double worst = 0.0;
    for (int s = 0; s < 2; ++s) {
        char name[32];
        snprintf(name, sizeof name, "iter.bc%d", s);
        const float *bc = fnopt_golden(g, name, n3);
        snprintf(name, sizeof name, "iter.acc%d", s);
        const float *ref = fnopt_golden(g, name, 10 * n3);
        if (!bc || !ref) {
            break;
        }
        memcpy(bcv, bc, n3 * sizeof(float));
        memset(acc, 0, n3 * sizeof(float));
        for (int k = 0; k < 10; ++k) {
            fnopt__loss_eval(&L, &in, acc, grad);
            fnopt__learned_update(&lo, grad, acc);
            double mref = 0.0, d = fnopt_max_diff(acc, ref + (size_t)k * n3, n3, &mref);
            double rel = d / (mref > 1e-12 ? mref : 1e-12);
            worst = rel > worst ? rel : worst;
            CHECK_MSG(rel < 2e-3, "step %d iteration %d: max |C - torch| %.3g, max |torch| %.3g", s, k, d, mref);
        }
        for (size_t q = 0; q < n3; ++q) {
            v[q] += acc[q];
            x[q] += v[q];
        }
        for (int k = 0; k < 2; ++k) {
            for (int c = 0; c < 3; ++c) {
                size_t q = 3 * idx[k] + c;
                v[q] = bc[q] - (x[q] - v[q]);
                x[q] = bc[q];
            }
        }
    }
    printf("per-iteration: worst relative difference %.3g over 20 iterations\n", worst);

    /* the public object does the same two steps */
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = h;
    def.width = w;
    def.model = model;
    def.stretch = p[2];
    def.shear = p[3];
    def.bend = p[4];
    def.gravity[0] = p[5];
    def.gravity[1] = p[6];
    def.gravity[2] = p[7];
    def.initial_positions = x0;
    def.descent_guard = false; /* the goldens are the paper's update rule: no guard, no trust region */
    def.max_step = 0.0f;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    for (int s = 0; s < 2 && f; ++s) {
        char name[32];
        snprintf(name, sizeof name, "iter.bc%d", s);
        const float *bc = fnopt_golden(g, name, n3);
        snprintf(name, sizeof name, "iter.xs%d", s);
        const float *xr = fnopt_golden(g, name, n3);
        if (!bc || !xr) {
            break;
        }
        float t[6];
        handle_targets(bc, idx, t);
        CHECK_RESULT(weft_fnopt_set_handles(f, idx, t, 2), WEFT_OK);
        CHECK_RESULT(weft_fnopt_step(f), WEFT_OK);
        double d = fnopt_max_diff(weft_fnopt_positions(f), xr, n3, NULL);
        printf("public step %d: max |x_C - x_torch| = %.3g grid units\n", s, d);
        CHECK(d < 1e-3);
    }
    weft_fnopt_destroy(f);
    fnopt__learned_free(ctx, &lo);
    fnopt__loss_free(ctx, &L);
    free(x);
    free(v);
    free(acc);
    free(grad);
    free(bcv);
    free(mask);
    weft_model_destroy(g);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
}

static void test_rollout(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_model *model = load(ctx, FNOPT_MODEL_PATH), *g = load(ctx, FNOPT_DATA("rollout_golden.safetensors"));
    const float *p = g ? fnopt_golden(g, "roll.params", 10) : NULL;
    if (!model || !p) {
        weft_model_destroy(model);
        weft_model_destroy(g);
        weft_context_destroy(ctx);
        return;
    }
    const uint32_t h = (uint32_t)p[0], w = (uint32_t)p[1];
    const size_t n3 = 3 * (size_t)h * w;
    const uint32_t idx[2] = {(uint32_t)p[8], (uint32_t)p[9]};
    const float *x0 = fnopt_golden(g, "roll.x0", n3), *xs = fnopt_golden(g, "roll.x", 6 * n3);
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = h;
    def.width = w;
    def.model = model;
    def.gravity[2] = p[7];
    def.initial_positions = x0;
    def.descent_guard = false; /* the goldens are the paper's update rule: no guard, no trust region */
    def.max_step = 0.0f;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    for (int s = 0; s < 6 && f && xs; ++s) {
        float t[6];
        for (int k = 0; k < 2; ++k) {
            t[3 * k + 0] = x0[3 * idx[k] + 0] + 0.25f * (float)(s + 1);
            t[3 * k + 1] = x0[3 * idx[k] + 1];
            t[3 * k + 2] = x0[3 * idx[k] + 2] + 0.25f * (float)(s + 1);
        }
        CHECK_RESULT(weft_fnopt_set_handles(f, idx, t, 2), WEFT_OK);
        CHECK_RESULT(weft_fnopt_step(f), WEFT_OK);
        double d = fnopt_max_diff(weft_fnopt_positions(f), xs + (size_t)s * n3, n3, NULL);
        printf("rollout step %d: max |x_C - x_torch| = %.3g grid units (%.1f ms)\n", s, d,
               weft_fnopt_get_stats(f).step_ms);
        CHECK(d < 5e-4);
    }
    weft_fnopt_destroy(f);
    weft_model_destroy(g);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_per_iteration), TEST_CASE(test_rollout))
