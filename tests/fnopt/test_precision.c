/* The FNO forward at fp16 and int8 against fp32 on the shipped weights: one forward on a
 * realistic input, a short rollout through the public API (bounds in docs/FNOPT.md,
 * "Reduced precision"), bit-identical results on every kernel level, no allocation per step and
 * argument checking. */
#include "fnopt_test_util.h"

static weft_model *load(weft_context *ctx)
{
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, FNOPT_MODEL_PATH, &m), WEFT_OK);
    return m;
}

/* A crumpled h x w sheet (deterministic), so the loss gradient has structure at every scale. */
static void crumpled(uint32_t h, uint32_t w, float *x)
{
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            float *p = x + 3 * ((size_t)i * w + j);
            p[0] = (float)i + 0.2f * sinf(0.9f * (float)j + 0.3f * (float)i);
            p[1] = 0.3f * cosf(0.7f * (float)i) * sinf(0.5f * (float)j);
            p[2] = -(float)j + 0.15f * sinf(1.3f * (float)(i + j));
        }
    }
}

/* One forward at each precision on the optimizer input of the first iteration of a step.
 * Bound: max |u_p - u_fp32| relative to max |u_fp32| and the same for the scale head d. */
static void test_forward_against_fp32(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_model *model = load(ctx);
    if (!model) {
        weft_context_destroy(ctx);
        return;
    }
    const uint32_t h = 20, w = 24, n = h * w;
    fnopt_weights wt;
    CHECK_RESULT(fnopt__weights_from_model(model, &wt), WEFT_OK);
    fnopt_loss L;
    CHECK_RESULT(fnopt__loss_init(ctx, &L, h, w), WEFT_OK);
    float *x = malloc(3 * n * sizeof(float)), *v = calloc(3 * n, sizeof(float));
    float *grad = malloc(3 * n * sizeof(float)), *acc = calloc(3 * n, sizeof(float));
    uint8_t *mask = calloc(n, 1);
    crumpled(h, w, x);
    mask[0] = mask[(h - 1) * w] = 1;
    fnopt_loss_input in = {.x = x, .v = v, .mask = mask, .bc = x, .Y = 100.0f, .S = 3.0f, .B = 5.0f,
                           .gravity = {0.0f, 0.0f, -0.085f}, .rep_thres = 0.5f};
    fnopt__loss_eval(&L, &in, NULL, grad);

    fnopt_learned lo[3];
    float u[3][3 * 20 * 24], d[3][3];
    for (int p = 0; p < 3; ++p) {
        CHECK_RESULT(fnopt__learned_init(ctx, &lo[p], &wt, h, w, (weft_precision)p), WEFT_OK);
        /* the update builds the normalised input z; the forward is rerun on it to read u and d */
        fnopt__learned_update(&lo[p], grad, acc);
        fnopt__fno_forward(&lo[p].fno, lo[0].z, u[p], d[p]);
    }
    const double bound_u[3] = {0.0, 0.005, 0.03}, bound_d[3] = {0.0, 0.005, 0.02};
    for (int p = 1; p < 3; ++p) {
        double ref = 0.0, ref_d = 0.0;
        double du = fnopt_max_diff(u[p], u[0], 3 * n, &ref), dd = fnopt_max_diff(d[p], d[0], 3, &ref_d);
        printf("precision %s: max |u - u_fp32| %.3g (max |u| %.3g, relative %.3g), max |d - d_fp32| %.3g "
               "(max |d| %.3g)\n", p == 1 ? "fp16" : "int8", du, ref, du / ref, dd, ref_d);
        CHECK_MSG(du <= bound_u[p] * ref, "u differs by %.3g (bound %.3g)", du, bound_u[p] * ref);
        CHECK_MSG(dd <= bound_d[p] * (ref_d > 1.0 ? ref_d : 1.0), "d differs by %.3g", dd);
    }
    for (int p = 0; p < 3; ++p) {
        fnopt__learned_free(ctx, &lo[p]);
    }
    fnopt__loss_free(ctx, &L);
    free(x), free(v), free(grad), free(acc), free(mask);
    weft_model_destroy(model);
    weft_context_destroy(ctx);
}

/* frames x n x 3 positions of a crumpled sheet whose two top corners move sideways and back.
 * Crumpled, not flat: on a flat sheet many bend angles sit at the acos clamp, where the
 * gradient jumps, and float rounding alone separates trajectories (docs/FNOPT.md, "Parity"). */
static bool rollout(weft_context *ctx, const weft_model *model, weft_precision prec, uint32_t res, uint32_t frames,
                    float perturb, float *out)
{
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = def.width = res;
    float *x0 = malloc(3 * (size_t)res * res * sizeof(float));
    crumpled(res, res, x0);
    def.initial_positions = x0;
    def.model = model;
    def.precision = prec;
    x0[3 * (res + 3) + 1] += perturb;
    def.stretch = 100.0f, def.shear = 3.0f, def.bend = 5.0f;
    def.gravity[2] = -weft_fnopt_acceleration(9.81f, res, 1.0f, 60.0f);
    weft_fnopt *f = NULL;
    weft_result r = weft_fnopt_create(ctx, &def, &f);
    free(x0);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return false;
    }
    const size_t n3 = 3 * (size_t)res * res;
    const uint32_t idx[2] = {0, (res - 1) * res};
    float t[6];
    const float *p0 = weft_fnopt_positions(f);
    memcpy(t, p0, 3 * sizeof(float));
    memcpy(t + 3, p0 + 3 * idx[1], 3 * sizeof(float));
    bool ok = true;
    for (uint32_t s = 0; s < frames && ok; ++s) {
        /* 0.4 units per step out along +x and +y for half the frames, then back */
        float dir = s < frames / 2 ? 0.4f : -0.4f;
        for (int k = 0; k < 2; ++k) {
            t[3 * k] += dir;
            t[3 * k + 1] += 0.5f * dir;
        }
        CHECK_RESULT(weft_fnopt_set_handles(f, idx, t, 2), WEFT_OK);
        weft_result sr = weft_fnopt_step(f);
        CHECK_RESULT(sr, WEFT_OK);
        ok = sr == WEFT_OK;
        memcpy(out + s * n3, weft_fnopt_positions(f), n3 * sizeof(float));
    }
    weft_fnopt_destroy(f);
    return ok;
}

/* e3D of `a` against `ref` (frames x n x 3), origin at the initial centre of the sheet: the
 * evaluation's metric (docs/FNOPT.md), here between two precisions of the same solver. */
static double e3d(const float *a, const float *ref, uint32_t res, uint32_t frames)
{
    const size_t n = (size_t)res * res;
    const double centre[3] = {0.5 * (double)(res - 1), 0.0, -0.5 * (double)(res - 1)};
    double sum = 0.0;
    for (uint32_t s = 0; s < frames; ++s) {
        double num = 0.0, den = 0.0;
        for (size_t i = 0; i < n; ++i) {
            for (int c = 0; c < 3; ++c) {
                double d = (double)a[(s * n + i) * 3 + c] - (double)ref[(s * n + i) * 3 + c];
                double g = (double)ref[(s * n + i) * 3 + c] - centre[c];
                num += d * d;
                den += g * g;
            }
        }
        sum += sqrt(num) / sqrt(den);
    }
    return sum / frames;
}

/* The rollout amplifies small differences: an fp32 run whose initial state differs by 1e-6 grid
 * units in one coordinate separates from the unperturbed one by an e3D of 4e-8 after one step
 * and about 3e-3 after 16, and the step-to-step growth is the same for any seed difference
 * (docs/FNOPT.md, "Reduced precision"). So the precisions are checked tightly on the first
 * step, which measures the arithmetic, and loosely over the rollout (their accuracy against the
 * XPBD reference is measured by `weft bench fnopt --gt`). */
static void test_rollout_against_fp32(void)
{
    weft_context *ctx = fnopt_test_context();
    weft_model *model = load(ctx);
    if (!model) {
        weft_context_destroy(ctx);
        return;
    }
    const uint32_t res = 16, frames = 12;
    const size_t frame = (size_t)res * res * 3, count = frames * frame;
    float *traj[4];
    bool ok = true;
    for (int p = 0; p < 4; ++p) {
        traj[p] = malloc(count * sizeof(float));
        /* traj[3]: fp32 again with a 1e-6 perturbation */
        ok = rollout(ctx, model, p < 3 ? (weft_precision)p : WEFT_PRECISION_FP32, res, frames, p < 3 ? 0.0f : 1e-6f,
                     traj[p]) && ok;
    }
    if (ok) {
        const double floor_first = e3d(traj[3], traj[0], res, 1), floor_all = e3d(traj[3], traj[0], res, frames);
        printf("fp32 with a 1e-6 perturbation: e3D after the first step %.3g, over %u frames %.3g\n", floor_first,
               frames, floor_all);
        const double bound_first[3] = {0.0, 2e-4, 2e-3};
        for (int p = 1; p < 3; ++p) {
            const double first = e3d(traj[p], traj[0], res, 1), all = e3d(traj[p], traj[0], res, frames);
            printf("%s: e3D against fp32 after the first step %.3g, over %u frames %.3g\n", p == 1 ? "fp16" : "int8",
                   first, frames, all);
            CHECK_MSG(first <= bound_first[p], "first-step e3D %.3g above %.3g", first, bound_first[p]);
            /* loose: over the rollout the separation is the amplified first-step difference
             * (measured about 0.03 for both precisions) */
            CHECK_MSG(all <= fmax(0.1, 3.0 * floor_all), "rollout e3D %.3g above max(0.1, 3 x floor %.3g)", all,
                      floor_all);
        }
    }
    for (int p = 0; p < 4; ++p) {
        free(traj[p]);
    }
    weft_model_destroy(model);
    weft_context_destroy(ctx);
}

/* fp16 and int8 steps give the same bits on every kernel level this CPU runs. */
static void test_same_bits_on_every_isa(void)
{
    const uint32_t res = 12, frames = 1;
    const size_t count = (size_t)frames * res * res * 3;
    for (int p = 1; p < 3; ++p) {
        float *first = NULL;
        const char *first_isa = NULL;
        int levels = 0;
        for (int isa = WEFT_ISA_SCALAR; isa < WEFT_ISA_COUNT; ++isa) {
            weft_context_def cd = weft_default_context_def();
            cd.isa = (weft_isa)isa;
            weft_context *ctx = NULL;
            if (weft_context_create(&cd, &ctx) != WEFT_OK) {
                continue; /* this CPU or build lacks the level */
            }
            weft_model *model = load(ctx);
            float *traj = malloc(count * sizeof(float));
            if (model && rollout(ctx, model, (weft_precision)p, res, frames, 0.0f, traj)) {
                if (!first) {
                    first = traj, traj = NULL;
                    first_isa = weft_isa_name((weft_isa)isa);
                } else {
                    CHECK_MSG(memcmp(first, traj, count * sizeof(float)) == 0, "%s: %s differs from %s",
                              p == 1 ? "fp16" : "int8", weft_isa_name((weft_isa)isa), first_isa);
                }
                ++levels;
            }
            free(traj);
            weft_model_destroy(model);
            weft_context_destroy(ctx);
        }
        printf("%s: %d kernel levels compared\n", p == 1 ? "fp16" : "int8", levels);
        CHECK(levels >= 1);
        free(first);
    }
}

static void test_no_allocation_and_bad_precision(void)
{
    counting cnt = {0, 0};
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    cd.allocator.user = &cnt;
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    weft_model *model = ctx ? load(ctx) : NULL;
    if (!model) {
        weft_context_destroy(ctx);
        return;
    }
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = 12;
    def.width = 10;
    def.model = model;
    weft_fnopt *f = NULL;
    def.precision = WEFT_PRECISION_COUNT;
    CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "precision") != NULL);
    CHECK(f == NULL);
    for (int p = 1; p < 3; ++p) {
        def.precision = (weft_precision)p;
        CHECK_RESULT(weft_fnopt_create(ctx, &def, &f), WEFT_OK);
        if (!f) {
            continue;
        }
        size_t before = cnt.allocs;
        uint32_t idx[2] = {0, 11 * 10};
        float t[6] = {0, 0, 0, 11, 0, 0};
        for (int s = 0; s < 3; ++s) {
            t[1] += 0.2f;
            CHECK_RESULT(weft_fnopt_set_handles(f, idx, t, 2), WEFT_OK);
            CHECK_RESULT(weft_fnopt_step(f), WEFT_OK);
        }
        CHECK_EQ_INT(cnt.allocs, before);
        weft_fnopt_destroy(f);
        f = NULL;
    }
    weft_model_destroy(model);
    CHECK_EQ_INT(cnt.live, 1); /* only the context itself */
    weft_context_destroy(ctx);
    CHECK_EQ_INT(cnt.live, 0);
}

TEST_MAIN(TEST_CASE(test_forward_against_fp32), TEST_CASE(test_rollout_against_fp32),
          TEST_CASE(test_same_bits_on_every_isa), TEST_CASE(test_no_allocation_and_bad_precision))
