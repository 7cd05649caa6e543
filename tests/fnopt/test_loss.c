/* The FNOpt physics loss: analytic gradient against central finite differences (with and
 * without repulsion, with handles), and value and gradient against PyTorch float64 goldens. */
#include "fnopt_test_util.h"

/* A perturbed hanging sheet (scaled by `squeeze`) with three handles, on a GD object (no model). */
static weft_fnopt *make_scene(weft_context *ctx, uint32_t h, uint32_t w, float squeeze, float k_rep, float thres,
                              test_rng *rng, float *acc)
{
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = h;
    def.width = w;
    def.optimizer = WEFT_FNOPT_GD;
    def.stretch = 500.0f;
    def.shear = 20.0f;
    def.bend = 2.0f;
    def.gravity[0] = 0.01f;
    def.gravity[1] = -0.02f;
    def.gravity[2] = -0.12f;
    def.repulsion = k_rep;
    def.repulsion_threshold = thres;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    if (!f) {
        return NULL;
    }
    size_t n = (size_t)h * w;
    float *x = malloc(3 * n * sizeof(float)), *v = malloc(3 * n * sizeof(float));
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            float *p = x + 3 * ((size_t)i * w + j);
            p[0] = squeeze * ((float)i - 0.5f * (float)(h - 1)) + test_rng_float(rng, -0.3f, 0.3f);
            p[1] = test_rng_float(rng, -0.3f, 0.3f);
            p[2] = -squeeze * (float)j + test_rng_float(rng, -0.3f, 0.3f);
        }
    }
    for (size_t q = 0; q < 3 * n; ++q) {
        v[q] = test_rng_float(rng, -0.05f, 0.05f);
        acc[q] = test_rng_float(rng, -0.1f, 0.1f);
    }
    CHECK_RESULT(weft_fnopt_set_state(f, x, v), WEFT_OK);
    uint32_t handles[3] = {0, w - 1, 3 * w + 4};
    float targets[9];
    for (int k = 0; k < 3; ++k) {
        for (int c = 0; c < 3; ++c) {
            targets[3 * k + c] = x[3 * handles[k] + c] + 0.2f;
        }
    }
    CHECK_RESULT(weft_fnopt_set_handles(f, handles, targets, 3), WEFT_OK);
    free(x);
    free(v);
    return f;
}

static void fd_check(float squeeze, float k_rep)
{
    weft_context *ctx = fnopt_test_context();
    test_rng rng = {0x1234567ull + (unsigned long long)(k_rep * 1000)};
    const uint32_t h = 12, w = 14;
    size_t n3 = 3 * (size_t)h * w;
    float *acc = malloc(n3 * sizeof(float)), *grad = malloc(n3 * sizeof(float));
    /* with repulsion, a threshold beyond every pair distance: the barrier's cut-off is a jump in
     * the energy that finite differences would straddle (the golden test covers the default) */
    weft_fnopt *f = make_scene(ctx, h, w, squeeze, k_rep, k_rep > 0.0f ? 100.0f : 0.5f, &rng, acc);
    if (f) {
        double L0 = 0.0;
        CHECK_RESULT(weft_fnopt_loss(f, acc, &L0, grad), WEFT_OK);
        double gmax = 0.0;
        for (size_t q = 0; q < n3; ++q) {
            gmax = fabs(grad[q]) > gmax ? fabs(grad[q]) : gmax;
        }
        CHECK(gmax > 0.0);
        /* every coordinate of a handle (gradient (M/N)(a - g) only) and a spread of others */
        int checked = 0, bad = 0;
        double worst = 0.0;
        for (size_t q = 0; q < n3; q += (q < 9 ? 1 : 7)) {
            /* the barrier's curvature is large for close pairs: a shorter step there */
            const float hstep = k_rep > 0.0f ? 1e-3f : 1e-2f;
            float keep = acc[q];
            double lp = 0.0, lm = 0.0;
            acc[q] = keep + hstep;
            weft_fnopt_loss(f, acc, &lp, NULL);
            acc[q] = keep - hstep;
            weft_fnopt_loss(f, acc, &lm, NULL);
            acc[q] = keep;
            double fd = (lp - lm) / ((double)(keep + hstep) - (double)(keep - hstep));
            double err = fabs(fd - grad[q]);
            worst = err > worst ? err : worst;
            if (err > 2e-3 * gmax + 1e-6) {
                bad++;
                fprintf(stderr, "coordinate %zu: analytic %.9g, finite difference %.9g\n", q, grad[q], fd);
            }
            checked++;
        }
        printf("squeeze %.2f k_rep %.3f: %d coordinates, max |fd - analytic| %.3g (max |g| %.3g)\n",
               (double)squeeze, (double)k_rep, checked, worst, gmax);
        CHECK(checked > 50);
        CHECK_EQ_INT(bad, 0);
        weft_fnopt_destroy(f);
    }
    free(acc);
    free(grad);
    weft_context_destroy(ctx);
}

static void test_fd_gradient(void) { fd_check(1.0f, 0.0f); }

static void test_fd_gradient_repulsion(void)
{
    /* a squeezed sheet: resampled points closer than the threshold, so the barrier is active */
    weft_context *ctx = fnopt_test_context();
    test_rng rng = {99};
    size_t n3 = 3 * 12 * 14;
    float *acc = malloc(n3 * sizeof(float));
    weft_fnopt *with = make_scene(ctx, 12, 14, 0.25f, 0.01f, 0.5f, &rng, acc);
    rng.s = 99;
    weft_fnopt *without = make_scene(ctx, 12, 14, 0.25f, 0.0f, 0.5f, &rng, acc);
    double a = 0.0, b = 0.0;
    CHECK_RESULT(weft_fnopt_loss(with, acc, &a, NULL), WEFT_OK);
    CHECK_RESULT(weft_fnopt_loss(without, acc, &b, NULL), WEFT_OK);
    CHECK_MSG(a - b > 1e-3, "repulsion adds %.6g", a - b);
    weft_fnopt_destroy(with);
    weft_fnopt_destroy(without);
    free(acc);
    weft_context_destroy(ctx);
    fd_check(0.25f, 0.01f);
}

static void golden_case(const weft_model *g, const char *prefix)
{
    char name[64];
#define G(field, count) (snprintf(name, sizeof name, "%s%s", prefix, field), fnopt_golden(g, name, (count)))
    const float *p = G("params", 9);
    if (!p) {
        return;
    }
    uint32_t h = (uint32_t)p[0], w = (uint32_t)p[1];
    size_t n3 = 3 * (size_t)h * w;
    const float *x = G("x", n3), *v = G("v", n3), *acc = G("acc", n3), *bc = G("bc", n3), *hd = G("handles", 3);
    const float *loss = G("loss", 1), *grad = G("grad", n3);
#undef G
    if (!x || !v || !acc || !bc || !hd || !loss || !grad) {
        return;
    }
    weft_context *ctx = fnopt_test_context();
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = h;
    def.width = w;
    def.optimizer = WEFT_FNOPT_GD;
    def.stretch = p[2];
    def.shear = p[3];
    def.bend = p[4];
    def.gravity[0] = p[5];
    def.gravity[1] = p[6];
    def.gravity[2] = p[7];
    def.repulsion = p[8];
    def.initial_positions = x;
    def.initial_velocities = v;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    uint32_t idx[3];
    float targets[9];
    for (int k = 0; k < 3; ++k) {
        idx[k] = (uint32_t)hd[k];
        for (int c = 0; c < 3; ++c) {
            targets[3 * k + c] = bc[3 * idx[k] + c];
        }
    }
    CHECK_RESULT(weft_fnopt_set_handles(f, idx, targets, 3), WEFT_OK);
    float *out = malloc(n3 * sizeof(float));
    double L = 0.0;
    CHECK_RESULT(weft_fnopt_loss(f, acc, &L, out), WEFT_OK);
    double ref = 0.0, d = fnopt_max_diff(out, grad, n3, &ref);
    printf("%s loss C %.9g torch %.9g; gradient max diff %.3g (max %.3g)\n", prefix, L, (double)loss[0], d, ref);
    CHECK_NEAR(L, loss[0], 1e-5 * fabs((double)loss[0]) + 1e-6);
    CHECK(d <= 1e-4 * ref + 1e-7);
    free(out);
    weft_fnopt_destroy(f);
    weft_context_destroy(ctx);
}

static void test_golden(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_model *g = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, FNOPT_DATA("loss_golden.safetensors"), &g), WEFT_OK);
    if (g) {
        golden_case(g, "plain.");
        golden_case(g, "rep.");
        weft_model_destroy(g);
    }
    weft_context_destroy(ctx);
}

static void test_straight_line_no_bending(void)
{
    /* the flat default sheet at rest: zero stretch/shear/bend gradient, so the gradient at a = 0
     * is exactly the gravity term -(M/N) g at every free vertex */
    weft_context *ctx = fnopt_test_context();
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = 10;
    def.width = 11;
    def.optimizer = WEFT_FNOPT_ADAM;
    weft_fnopt *f = NULL;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
    float grad[3 * 110];
    double L = 1.0;
    CHECK_RESULT(weft_fnopt_loss(f, NULL, &L, grad), WEFT_OK);
    /* not exactly 0: the acos clamp leaves each straight pair a bend angle of about 4.9e-4 rad */
    CHECK(L >= 0.0 && L < 1e-6);
    double worst = 0.0;
    for (uint32_t i = 0; i < 10; ++i) {
        for (uint32_t j = 0; j < 11; ++j) {
            double m = ((i == 0 || i == 9) ? 0.5 : 1.0) * ((j == 0 || j == 10) ? 0.5 : 1.0);
            size_t v = (size_t)i * 11 + j;
            for (int c = 0; c < 3; ++c) {
                double e = fabs(grad[3 * v + c] + m / 110.0 * def.gravity[c]);
                worst = e > worst ? e : worst;
            }
        }
    }
    CHECK_MSG(worst < 1e-9, "worst %.3g", worst);
    weft_fnopt_destroy(f);
    weft_context_destroy(ctx);
}

static void test_erf(void)
{
    double worst = 0.0;
    for (int k = -60000; k <= 60000; ++k) {
        float x = (float)k * 1e-4f;
        double e = fabs((double)fnopt__erf(x) - erf((double)x));
        worst = e > worst ? e : worst;
    }
    printf("erf approximation: max abs error %.3g on [-6, 6]\n", worst);
    CHECK(worst < 1e-6);
    CHECK(fnopt__erf(0.0f) == 0.0f);
    CHECK(fnopt__erf(-1.0f) == -fnopt__erf(1.0f));
}

TEST_MAIN(TEST_CASE(test_erf), TEST_CASE(test_fd_gradient), TEST_CASE(test_fd_gradient_repulsion), TEST_CASE(test_golden),
          TEST_CASE(test_straight_line_no_bending))
