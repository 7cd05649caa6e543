/* C forward pass of the ClothTransformer against PyTorch golden tensors
 * (tools/train/export.py --golden), plus the method's bad-input behaviour. */
#include "test.h"
#include <pthread.h>
#include "quant.h"
#include "weft.h"

#include <stdbool.h>
#include <stdint.h>

#define DATA WEFT_SOURCE_DIR "/tests/model/data/"

/* ---- minimal .npy reader (little-endian <f4 / <u4, C order) ---------------------------- */

typedef struct npy {
    void *data;
    size_t count;
    uint32_t rank;
    size_t shape[4];
} npy;

static int npy_load(const char *name, const char *descr, npy *out)
{
    char path[512];
    snprintf(path, sizeof path, "%s%s.npy", DATA, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return 0;
    }
    unsigned char pre[10];
    int ok = fread(pre, 1, 10, f) == 10 && memcmp(pre, "\x93NUMPY", 6) == 0 && pre[6] == 1;
    size_t hlen = ok ? (size_t)pre[8] | (size_t)pre[9] << 8 : 0;
    char header[1024] = {0};
    ok = ok && hlen < sizeof header && fread(header, 1, hlen, f) == hlen;
    ok = ok && strstr(header, descr) && strstr(header, "'fortran_order': False");
    const char *sh = ok ? strstr(header, "'shape': (") : NULL;
    *out = (npy){0};
    out->count = 1;
    if (sh) {
        sh += 10;
        while (*sh && *sh != ')' && out->rank < 4) {
            char *end;
            size_t v = (size_t)strtoull(sh, &end, 10);
            if (end == sh) {
                break;
            }
            out->shape[out->rank++] = v;
            out->count *= v;
            sh = end;
            while (*sh == ',' || *sh == ' ') {
                sh++;
            }
        }
    }
    ok = ok && sh && out->rank > 0;
    if (ok) {
        out->data = malloc(out->count * 4 + 1);
        ok = out->data && fread(out->data, 4, out->count, f) == out->count;
    }
    fclose(f);
    if (!ok) {
        fprintf(stderr, "malformed %s\n", path);
        free(out->data);
        out->data = NULL;
    }
    return ok;
}

static void *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *p = malloc((size_t)n + 1);
    if (p && fread(p, 1, (size_t)n, f) != (size_t)n) {
        free(p);
        p = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return p;
}

/* ---- fixture --------------------------------------------------------------------------- */

typedef struct golden {
    npy rest, faces, cfaces, gt, cpos, tf_frames, tf_pred, rollout;
    uint32_t V, F, Vc, Fc;
} golden;

static int golden_load(golden *g)
{
    int ok = npy_load("rest", "<f4", &g->rest) && npy_load("faces", "<u4", &g->faces) &&
             npy_load("cfaces", "<u4", &g->cfaces) && npy_load("gt_pos", "<f4", &g->gt) &&
             npy_load("c_pos", "<f4", &g->cpos) && npy_load("tf_frames", "<u4", &g->tf_frames) &&
             npy_load("tf_pred", "<f4", &g->tf_pred) && npy_load("rollout", "<f4", &g->rollout);
    if (ok) {
        g->V = (uint32_t)g->rest.shape[0];
        g->F = (uint32_t)g->faces.shape[0];
        g->Vc = (uint32_t)g->cpos.shape[1];
        g->Fc = (uint32_t)g->cfaces.shape[0];
    }
    return ok;
}

static void golden_free(golden *g)
{
    npy *all[] = {&g->rest, &g->faces, &g->cfaces, &g->gt, &g->cpos, &g->tf_frames, &g->tf_pred, &g->rollout};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; ++i) {
        free(all[i]->data);
    }
}

static const float *frame(const npy *a, size_t t)
{
    size_t per = a->count / a->shape[0];
    return (const float *)a->data + t * per;
}

/* Counting allocator: a step must not allocate. */
static size_t g_allocs;
static void *count_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    g_allocs++;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}
static void count_free(void *p, size_t size, void *user)
{
    (void)size;
    (void)user;
    free(p);
}

static weft_context *make_ctx(void)
{
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

static weft_garment_def garment_def(const golden *g, const weft_model *m, size_t t)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = WEFT_METHOD_MODEL;
    d.model = m;
    d.ccd = false;
    d.rest_positions = g->rest.data;
    d.vertex_count = g->V;
    d.triangles = g->faces.data;
    d.triangle_count = g->F;
    d.collider_rest_positions = frame(&g->cpos, t);
    d.collider_vertex_count = g->Vc;
    d.collider_triangles = g->cfaces.data;
    d.collider_triangle_count = g->Fc;
    d.initial_positions = frame(&g->gt, t);
    return d;
}

/* max |a - b| relative to max |b| (the parity measure) and to the frame's largest motion. */
static void compare(const float *c, const float *p, const float *x_t, size_t n, double *rel, double *rel_motion)
{
    double e = 0, mag = 0, mot = 0;
    for (size_t i = 0; i < n; ++i) {
        e = fmax(e, fabs((double)c[i] - p[i]));
        mag = fmax(mag, fabs((double)p[i]));
        mot = fmax(mot, fabs((double)p[i] - x_t[i]));
    }
    *rel = e / fmax(mag, 1e-12);
    *rel_motion = e / fmax(mot, 1e-12);
}

/* ---- cases ----------------------------------------------------------------------------- */

/* One step from ground-truth frames (t, t-1) per golden frame, against PyTorch's prediction
 * `pred_name` of the model in `model_file`. */
static void teacher_forced_parity_of(const char *model_file, const char *pred_name)
{
    golden g;
    npy pred;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    if (!npy_load(pred_name, "<f4", &pred)) {
        CHECK(!"golden prediction missing");
        golden_free(&g);
        return;
    }
    CHECK(pred.rank == 3 && pred.shape[0] == g.tf_frames.shape[0] && pred.shape[1] == g.V);
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, model_file, &m), WEFT_OK);
    double worst = 0, worst_motion = 0;
    for (size_t i = 0; m && i < g.tf_frames.shape[0]; ++i) {
        uint32_t t = ((const uint32_t *)g.tf_frames.data)[i];
        weft_garment_def d = garment_def(&g, m, t);
        weft_garment *gar = NULL;
        CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
        if (!gar) {
            break;
        }
        CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, t), frame(&g.gt, t - 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, t + 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
        double rel, relm;
        compare(weft_garment_positions(gar), frame(&pred, i), frame(&g.gt, t), (size_t)g.V * 3, &rel, &relm);
        CHECK_MSG(rel <= 1e-4, "frame %u: relative error %.3g > 1e-4", t, rel);
        CHECK_MSG(relm <= 1e-3, "frame %u: error %.3g of the frame's motion > 1e-3", t, relm);
        worst = fmax(worst, rel);
        worst_motion = fmax(worst_motion, relm);
        weft_garment_destroy(gar);
    }
    printf("teacher-forced %s: %zu frames, max relative error %.3g (%.3g of the per-frame motion)\n", pred_name,
           g.tf_frames.shape[0], worst, worst_motion);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(pred.data);
    golden_free(&g);
}

static void teacher_forced_parity(void)
{
    teacher_forced_parity_of(DATA "golden_model.safetensors", "tf_pred");
}

/* The shipped game model (the 'previous' prior, K = 32: the golden model covers the inertial
 * prior); game_tf_pred.npy is export.py --golden of tools/train/models/game.ckpt.pt. */
static void shipped_game_parity(void)
{
    teacher_forced_parity_of(WEFT_SOURCE_DIR "/tools/train/models/game.safetensors", "game_tf_pred");
}

static void rollout_parity(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    weft_garment *gar = NULL;
    weft_garment_def d = garment_def(&g, m, 1);
    if (m) {
        CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    }
    if (!gar) {
        weft_model_destroy(m);
        weft_context_destroy(ctx);
        golden_free(&g);
        return;
    }
    CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, 1), frame(&g.gt, 0)), WEFT_OK);
    size_t allocs_before = g_allocs;
    size_t R = g.rollout.shape[0];
    double worst = 0, first5 = 0;
    float *prev = malloc((size_t)g.V * 3 * sizeof(float));
    for (size_t i = 0; i < R; ++i) {
        memcpy(prev, weft_garment_positions(gar), (size_t)g.V * 3 * sizeof(float));
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, i + 2)), WEFT_OK);
        weft_result r = weft_garment_step(gar);
        CHECK_RESULT(r, WEFT_OK);
        if (r != WEFT_OK) {
            break;
        }
        double rel, relm;
        compare(weft_garment_positions(gar), frame(&g.rollout, i), prev, (size_t)g.V * 3, &rel, &relm);
        worst = fmax(worst, rel);
        if (i < 5) {
            first5 = fmax(first5, rel);
        }
    }
    CHECK_EQ_INT(g_allocs, allocs_before);
    /* Per-frame parity for the first frames; the documented rollout tolerance (docs/MODEL.md)
     * for all of them, since float rounding differences compound through the feedback. */
    CHECK_MSG(first5 <= 1e-4, "first 5 rollout frames: relative error %.3g > 1e-4", first5);
    CHECK_MSG(worst <= 1e-3, "%zu-frame rollout: relative error %.3g > 1e-3", R, worst);
    printf("rollout: %zu frames, max relative error %.3g (first 5: %.3g)\n", R, worst, first5);
    free(prev);
    weft_garment_destroy(gar);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The model file, with `from` replaced by `to` in its header (the length is fixed up). */
static void *patched_model(const char *from, const char *to, size_t *size)
{
    size_t n = 0;
    unsigned char *src = read_file(DATA "golden_model.safetensors", &n);
    if (!src || n < 8) {
        free(src);
        return NULL;
    }
    uint64_t hlen = 0;
    for (int i = 7; i >= 0; --i) {
        hlen = hlen << 8 | src[i];
    }
    char *hdr = malloc(hlen + 1);
    memcpy(hdr, src + 8, hlen);
    hdr[hlen] = '\0';
    char *at = strstr(hdr, from);
    if (!at) {
        free(hdr);
        free(src);
        return NULL;
    }
    size_t lf = strlen(from), lt = strlen(to);
    uint64_t nh = hlen - lf + lt;
    unsigned char *out = malloc(n - hlen + nh);
    for (int i = 0; i < 8; ++i) {
        out[i] = (unsigned char)(nh >> (8 * i));
    }
    size_t pre = (size_t)(at - hdr);
    memcpy(out + 8, hdr, pre);
    memcpy(out + 8 + pre, to, lt);
    memcpy(out + 8 + pre + lt, at + lf, hlen - pre - lf);
    memcpy(out + 8 + nh, src + 8 + hlen, n - 8 - hlen);
    *size = n - hlen + nh;
    free(hdr);
    free(src);
    return out;
}

/* Load must succeed; garment creation must then fail with `expected` (or the load itself may
 * already reject the file with `expected`). */
static void expect_create_fails(const char *from, const char *to, bool with_collider, weft_result expected)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    size_t size = 0;
    void *bytes = patched_model(from, to, &size);
    CHECK_MSG(bytes != NULL, "could not patch '%s'", from);
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    weft_result r = bytes ? weft_model_load_memory(ctx, bytes, size, &m) : WEFT_ERROR_IO;
    if (r == WEFT_OK) {
        weft_garment_def d = garment_def(&g, m, 1);
        if (!with_collider) {
            d.collider_vertex_count = 0;
            d.collider_rest_positions = NULL;
            d.collider_triangles = NULL;
            d.collider_triangle_count = 0;
        }
        weft_garment *gar = NULL;
        r = weft_garment_create(ctx, &d, &gar);
        CHECK(gar == NULL);
        weft_garment_destroy(gar);
    }
    CHECK_MSG(r == expected, "patch '%s' -> '%s': got %s (%s), expected %s", from, to, weft_result_string(r),
              weft_last_error(), weft_result_string(expected));
    CHECK(strlen(weft_last_error()) > 0);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(bytes);
    golden_free(&g);
}

static void bad_model_files(void)
{
    expect_create_fails("\"dec_head.bias\"", "\"dec_head.bixs\"", true, WEFT_ERROR_MISSING_TENSOR);
    expect_create_fails("\\\"dec_skip\\\"", "\\\"vertex_count\\\": 7, \\\"dec_skip\\\"", true,
                        WEFT_ERROR_TOPOLOGY_MISMATCH);
    expect_create_fails("\\\"dec_skip\\\"", "\\\"requires_collider\\\": true, \\\"dec_skip\\\"", false,
                        WEFT_ERROR_NO_COLLIDER);
    expect_create_fails("\\\"prior\\\": \\\"", "\\\"prior\\\": \\\"x", true, WEFT_ERROR_BAD_METADATA);
    expect_create_fails("\\\"D\\\": ", "\\\"D\\\": 1", true, WEFT_ERROR_TENSOR_SHAPE);
}

static void bad_state_and_collider(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    weft_garment_def d = garment_def(&g, m, 1);
    weft_garment *gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (!gar) {
        weft_model_destroy(m);
        weft_context_destroy(ctx);
        golden_free(&g);
        return;
    }
    size_t n = (size_t)g.V * 3;
    float *before = malloc(n * sizeof(float));
    memcpy(before, weft_garment_positions(gar), n * sizeof(float));
    /* step without the collider of t+1 */
    CHECK_RESULT(weft_garment_step(gar), WEFT_ERROR_NO_COLLIDER);
    /* NaN state is refused and leaves the state as it was */
    float *bad = malloc(n * sizeof(float));
    memcpy(bad, frame(&g.gt, 2), n * sizeof(float));
    bad[7] = NAN;
    CHECK_RESULT(weft_garment_set_state(gar, bad, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(before, weft_garment_positions(gar), n * sizeof(float)) == 0);
    /* NaN collider */
    float *badc = malloc((size_t)g.Vc * 3 * sizeof(float));
    memcpy(badc, frame(&g.cpos, 2), (size_t)g.Vc * 3 * sizeof(float));
    badc[0] = INFINITY;
    CHECK_RESULT(weft_garment_set_collider(gar, badc), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_garment_step(gar), WEFT_ERROR_NO_COLLIDER);
    CHECK(memcmp(before, weft_garment_positions(gar), n * sizeof(float)) == 0);
    /* a pin is honoured after the learned step: vertex 0 lands exactly on its target */
    uint32_t idx = 0;
    const float target[3] = {before[0] + 0.01f, before[1] + 0.02f, before[2] - 0.01f};
    CHECK_RESULT(weft_garment_set_pins(gar, &idx, target, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, 2)), WEFT_OK);
    CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
    CHECK(memcmp(weft_garment_positions(gar), target, sizeof target) == 0);
    CHECK_RESULT(weft_garment_set_pins(gar, NULL, NULL, 0), WEFT_OK);
    weft_garment_destroy(gar);

    /* out-of-range precision */
    d.precision = WEFT_PRECISION_COUNT;
    gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(gar == NULL);

    /* no model */
    d = garment_def(&g, NULL, 1);
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_ERROR_NO_MODEL);

    /* garment without a collider runs on cloth tokens alone */
    d = garment_def(&g, m, 1);
    d.collider_vertex_count = 0;
    d.collider_rest_positions = NULL;
    d.collider_triangles = NULL;
    d.collider_triangle_count = 0;
    gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (gar) {
        CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, 2)), WEFT_ERROR_NO_COLLIDER);
    }
    weft_garment_destroy(gar);
    free(before);
    free(bad);
    free(badc);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The shipped models bind (every tensor and config key checked) and step the golden garment. */
static void shipped_models_step(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    static const char *const files[] = {WEFT_SOURCE_DIR "/tools/train/models/game.safetensors",
                                        WEFT_SOURCE_DIR "/tools/train/models/unified.safetensors"};
    weft_context *ctx = make_ctx();
    for (size_t f = 0; f < 2; ++f) {
        weft_model *m = NULL;
        CHECK_RESULT(weft_model_load_file(ctx, files[f], &m), WEFT_OK);
        weft_garment *gar = NULL;
        weft_garment_def d = garment_def(&g, m, 1);
        if (m) {
            CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
        }
        if (gar) {
            CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, 1), frame(&g.gt, 0)), WEFT_OK);
            for (size_t t = 1; t < 6; ++t) {
                CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, t + 1)), WEFT_OK);
                CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
            }
            const float *x = weft_garment_positions(gar);
            int finite = 1;
            for (size_t i = 0; i < (size_t)g.V * 3; ++i) {
                finite &= isfinite(x[i]) != 0;
            }
            CHECK(finite);
        }
        weft_garment_destroy(gar);
        weft_model_destroy(m);
    }
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* Rolls the golden garment out for T frames from ground-truth frames (0, 1) at a precision and
 * copies each frame's positions into out (T x V x 3). False if the garment could not be made. */
static bool rollout_into(const golden *g, weft_context *ctx, const weft_model *m, weft_precision prec, uint32_t T,
                         float *out)
{
    weft_garment_def d = garment_def(g, m, 1);
    d.precision = prec;
    weft_garment *gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (!gar) {
        return false;
    }
    const size_t n = (size_t)g->V * 3;
    CHECK_RESULT(weft_garment_set_state(gar, frame(&g->gt, 1), frame(&g->gt, 0)), WEFT_OK);
    for (uint32_t t = 0; t < T; ++t) {
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g->cpos, 2 + t)), WEFT_OK);
        CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
        memcpy(out + t * n, weft_garment_positions(gar), n * sizeof(float));
    }
    weft_garment_destroy(gar);
    return true;
}

/* fp16 and int8 against fp32 on the teacher-forced frames and a 20-frame rollout, and the int8
 * path bit-identical on every ISA level this CPU runs (scalar oracle included). */
static void reduced_precision(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    static const weft_isa isas[] = {WEFT_ISA_SCALAR, WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    weft_context *ctxs[4] = {NULL};
    weft_model *models[4] = {NULL};
    uint32_t nctx = 0;
    for (int i = 0; i < 4; ++i) {
        weft_context_def cd = weft_default_context_def();
        cd.isa = isas[i];
        if (weft_context_create(&cd, &ctxs[nctx]) != WEFT_OK) {
            continue;
        }
        CHECK_RESULT(weft_model_load_file(ctxs[nctx], DATA "golden_model.safetensors", &models[nctx]), WEFT_OK);
        if (!models[nctx]) {
            weft_context_destroy(ctxs[nctx]);
            continue;
        }
        nctx++;
    }
    CHECK(nctx >= 1);
    const size_t n = (size_t)g.V * 3;
    const uint32_t T = 20;
    float *ref = malloc(n * sizeof(float) * T), *out = malloc(n * sizeof(float) * T);
    double worst[3] = {0, 0, 0};
    for (int prec = 0; prec < 3 && nctx > 0; ++prec) {
        for (uint32_t c = 0; c < nctx; ++c) {
            if (!rollout_into(&g, ctxs[c], models[c], (weft_precision)prec, T, c == 0 ? ref : out)) {
                continue;
            }
            if (c > 0 && prec == WEFT_PRECISION_INT8) {
                CHECK_MSG(memcmp(ref, out, n * T * sizeof(float)) == 0, "int8 rollout differs on isa %s",
                          weft_isa_name(weft_context_isa(ctxs[c])));
            }
        }
        /* accuracy against the PyTorch fp32 rollout (rollout.npy: frames 2..) */
        for (uint32_t t = 0; t < T && t < g.rollout.shape[0]; ++t) {
            double rel, relm;
            compare(ref + t * n, frame(&g.rollout, t), frame(&g.gt, 1), n, &rel, &relm);
            worst[prec] = fmax(worst[prec], rel);
        }
    }
    printf("20-frame rollout vs PyTorch fp32, max relative error: fp32 %.3g, fp16 %.3g, int8 %.3g (%u ISA levels "
           "bit-identical at int8)\n",
           worst[0], worst[1], worst[2], nctx);
    CHECK(worst[0] <= 1e-3);
    CHECK(worst[1] <= 2e-3);
    CHECK(worst[2] <= 2.5e-2);
    free(ref);
    free(out);
    for (uint32_t c = 0; c < nctx; ++c) {
        weft_model_destroy(models[c]);
        weft_context_destroy(ctxs[c]);
    }
    golden_free(&g);
}

/* Files written by `weft quantize` run exactly like the fp32 file at the same precision: the
 * runtime quantises with the same function, so int8 (and fp16) rollouts are bit-identical. */
static void quantized_files(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    size_t size = 0;
    void *bytes = read_file(DATA "golden_model.safetensors", &size);
    CHECK(bytes != NULL);
    weft_model *fp32 = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &fp32), WEFT_OK);
    const size_t n = (size_t)g.V * 3;
    float *a = malloc(n * sizeof(float) * 10), *b = malloc(n * sizeof(float) * 10);
    for (int fmt = 0; fmt < 2 && bytes && fp32; ++fmt) {
        weft_quant_def qd = weft_default_quant_def();
        qd.format = fmt == 0 ? WEFT_QUANT_INT8 : WEFT_QUANT_FP16;
        void *qbytes = NULL;
        size_t qsize = 0;
        CHECK_RESULT(weft_quantize_memory(ctx, &qd, bytes, size, &qbytes, &qsize, NULL), WEFT_OK);
        weft_model *qm = NULL;
        CHECK_RESULT(weft_model_load_memory(ctx, qbytes, qsize, &qm), WEFT_OK);
        if (!qm) {
            weft_quant_buffer_free(ctx, qbytes, qsize);
            continue;
        }
        CHECK(weft_model_get_info(qm).precision == (fmt == 0 ? WEFT_PRECISION_INT8 : WEFT_PRECISION_FP16));
        /* every precision runs from the quantised file; the matching one equals the fp32 file's */
        for (int prec = 0; prec < 3; ++prec) {
            rollout_into(&g, ctx, fp32, (weft_precision)prec, 10, a);
            rollout_into(&g, ctx, qm, (weft_precision)prec, 10, b);
            bool matching = (fmt == 0 && prec == WEFT_PRECISION_INT8) || (fmt == 1 && prec == WEFT_PRECISION_FP16);
            if (matching) {
                CHECK_MSG(memcmp(a, b, n * 10 * sizeof(float)) == 0, "%s file at its own precision differs from "
                          "the fp32 file", fmt == 0 ? "int8" : "fp16");
            } else {
                double rel, relm;
                compare(b + 9 * n, a + 9 * n, frame(&g.gt, 1), n, &rel, &relm);
                CHECK_MSG(rel < 3e-2, "%s file at precision %d: relative difference %.3g", fmt == 0 ? "int8" : "fp16",
                          prec, rel);
            }
        }
        weft_model_destroy(qm);
        weft_quant_buffer_free(ctx, qbytes, qsize);
    }
    free(a);
    free(b);
    free(bytes);
    weft_model_destroy(fp32);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The host's job hook: chunks run on two threads (in reverse order on the second), and the
 * result is bit-identical to the serial run at every precision. */
typedef struct hook_job {
    weft_task_fn *task;
    void *ctx;
    uint32_t count, chunk;
    int calls;
} hook_job;

static void *hook_thread(void *arg)
{
    hook_job *j = arg;
    uint32_t nchunks = (j->count + j->chunk - 1) / j->chunk;
    for (uint32_t c = nchunks; c-- > nchunks / 2;) { /* upper half, last chunk first */
        uint32_t b = c * j->chunk, e = b + j->chunk < j->count ? b + j->chunk : j->count;
        j->task(b, e, 1, j->ctx);
    }
    return NULL;
}

static int g_hook_calls;

static void two_thread_parallel_for(weft_task_fn *task, uint32_t count, uint32_t min_chunk, void *task_context,
                                    void *user)
{
    (void)user;
    g_hook_calls++;
    hook_job job = {task, task_context, count, min_chunk, 0};
    pthread_t th;
    bool threaded = pthread_create(&th, NULL, hook_thread, &job) == 0;
    uint32_t nchunks = (count + min_chunk - 1) / min_chunk;
    for (uint32_t c = 0; c < nchunks / 2; ++c) {
        uint32_t b = c * min_chunk, e = b + min_chunk < count ? b + min_chunk : count;
        task(b, e, 0, task_context);
    }
    if (threaded) {
        pthread_join(th, NULL);
    } else {
        hook_thread(&job);
    }
}

static void parallel_for_hook(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    const size_t n = (size_t)g.V * 3;
    float *serial = malloc(n * sizeof(float) * 5), *hooked = malloc(n * sizeof(float) * 5);
    for (int prec = 0; prec < 3; ++prec) {
        for (int use_hook = 0; use_hook < 2; ++use_hook) {
            weft_context_def cd = weft_default_context_def();
            if (use_hook) {
                cd.parallel_for = two_thread_parallel_for;
                cd.max_workers = 2;
            }
            weft_context *ctx = NULL;
            CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
            weft_model *m = NULL;
            CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
            int calls_before = g_hook_calls;
            if (m) {
                rollout_into(&g, ctx, m, (weft_precision)prec, 5, use_hook ? hooked : serial);
            }
            if (use_hook) {
                CHECK_MSG(g_hook_calls > calls_before, "the hook was never called");
                CHECK_MSG(memcmp(serial, hooked, n * 5 * sizeof(float)) == 0,
                          "precision %d: parallel_for changes the result", prec);
            }
            weft_model_destroy(m);
            weft_context_destroy(ctx);
        }
    }
    free(serial);
    free(hooked);
    golden_free(&g);
}

TEST_MAIN(TEST_CASE(teacher_forced_parity), TEST_CASE(shipped_game_parity), TEST_CASE(shipped_models_step), TEST_CASE(rollout_parity), TEST_CASE(bad_model_files),
          TEST_CASE(bad_state_and_collider), TEST_CASE(reduced_precision),
          TEST_CASE(quantized_files), TEST_CASE(parallel_for_hook))
