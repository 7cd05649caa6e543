/* weft_garments_step: every garment ends bit-identical to stepping it alone with
 * weft_garment_step (fp32, fp16, int8; int8 also across ISA levels), mixed methods and
 * precisions in one call, failures confined to the failing garment, and no allocation after
 * the first call. */
#include "model_data.h"
#include "test.h"
#include "weft.h"

#include <stdbool.h>
#include <stdint.h>

#define GAME WEFT_SOURCE_DIR "/tools/train/models/game.safetensors"

typedef struct fixture {
    float *rest, *cpos, *gt;
    uint32_t *faces, *cfaces;
    size_t V, F, T, Tg, Fc;
    uint32_t Vc;
} fixture;

static bool fixture_load(fixture *f)
{
    size_t a, b, c, d, e;
    memset(f, 0, sizeof *f);
    f->rest = load_npy("rest", &a, &f->V);
    f->faces = load_npy("faces", &b, &f->F);
    f->cpos = load_npy("c_pos", &c, &f->T);
    f->gt = load_npy("gt_pos", &d, &f->Tg);
    f->cfaces = load_npy("cfaces", &e, &f->Fc);
    bool ok = f->rest && f->faces && f->cpos && f->gt && f->cfaces;
    if (ok) {
        f->Vc = (uint32_t)(c / f->T / 3);
    }
    CHECK_MSG(ok, "golden tensors missing");
    return ok;
}

static void fixture_free(fixture *f)
{
    free(f->rest);
    free(f->faces);
    free(f->cpos);
    free(f->gt);
    free(f->cfaces);
}

static const float *gt_frame(const fixture *f, size_t t) { return f->gt + (t % f->Tg) * f->V * 3; }
static const float *c_frame(const fixture *f, size_t t) { return f->cpos + (t % f->T) * f->Vc * 3; }

/* Garment k starts from ground-truth frame 1 + 2k (so every character differs). */
static weft_garment *make(weft_context *ctx, const fixture *f, const weft_model *m, weft_method method,
                          weft_precision prec, uint32_t k, bool ccd)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.model = method == WEFT_METHOD_MODEL ? m : NULL;
    d.precision = prec;
    d.ccd.enabled = ccd;
    d.rest_positions = f->rest;
    d.vertex_count = (uint32_t)f->V;
    d.triangles = f->faces;
    d.triangle_count = (uint32_t)f->F;
    d.collider_rest_positions = c_frame(f, 1 + 2 * k);
    d.collider_vertex_count = f->Vc;
    d.collider_triangles = f->cfaces;
    d.collider_triangle_count = (uint32_t)f->Fc;
    d.substeps = 2;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_OK);
    if (g) {
        CHECK_RESULT(weft_garment_set_state(g, gt_frame(f, 1 + 2 * k), gt_frame(f, 2 * k)), WEFT_OK);
    }
    return g;
}

static void set_colliders(weft_garment *const *gs, uint32_t n, const fixture *f, uint32_t t)
{
    for (uint32_t k = 0; k < n; ++k) {
        CHECK_RESULT(weft_garment_set_collider(gs[k], c_frame(f, 2 + 2 * k + t)), WEFT_OK);
    }
}

static bool same_positions(const weft_garment *a, const weft_garment *b)
{
    const size_t n = (size_t)weft_garment_vertex_count(a) * 3;
    return n == (size_t)weft_garment_vertex_count(b) * 3 &&
           memcmp(weft_garment_positions(a), weft_garment_positions(b), n * sizeof(float)) == 0;
}

/* Counting allocator: after the first batched call, nothing is allocated. */
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

#define CHARS 6u
#define STEPS 3u
#define MAX_CHARS 12u

/* A job hook that runs the chunks last to first on the calling thread: the split and the order
 * must not change any bit. */
static uint32_t g_hook_chunks;
static void reverse_parallel_for(weft_task_fn *task, uint32_t count, uint32_t min_chunk, void *task_context,
                                 void *user)
{
    (void)user;
    const uint32_t chunks = (count + min_chunk - 1) / min_chunk;
    for (uint32_t c = chunks; c-- > 0;) {
        const uint32_t end = (c + 1) * min_chunk < count ? (c + 1) * min_chunk : count;
        task(c * min_chunk, end, c % 4, task_context);
        g_hook_chunks++;
    }
}

/* A crowd of CHARS characters of one model at one precision, interleaved with an LBS garment
 * and a character at another precision, against twins stepped alone. */
static void crowd_matches_alone_n(const char *model_path, weft_isa isa, weft_precision prec, weft_precision other,
                                  uint32_t chars, bool hook, const char *what)
{
    fixture f;
    if (!fixture_load(&f)) {
        return;
    }
    weft_context_def cd = weft_default_context_def();
    cd.isa = isa;
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    if (hook) {
        cd.parallel_for = reverse_parallel_for;
        cd.max_workers = 4;
    }
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fixture_free(&f); /* the level is not available on this CPU */
        return;
    }
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, model_path, &m), WEFT_OK);
    weft_garment *crowd[MAX_CHARS + 2] = {NULL}, *alone[MAX_CHARS + 2] = {NULL};
    /* [c0, lbs, c1, c2, other-precision, c3, c4, ...]: model groups interleave with others */
    uint32_t n = 0;
    for (uint32_t k = 0; m && k < chars + 2; ++k) {
        weft_method method = k == 1 ? WEFT_METHOD_LBS : WEFT_METHOD_MODEL;
        weft_precision p = k == 4 ? other : prec;
        crowd[k] = make(ctx, &f, m, method, p, k, true);
        alone[k] = make(ctx, &f, m, method, p, k, true);
        n += crowd[k] && alone[k];
    }
    if (n == chars + 2) {
        size_t allocs_after_first = 0;
        for (uint32_t t = 0; t < STEPS; ++t) {
            set_colliders(crowd, n, &f, t);
            set_colliders(alone, n, &f, t);
            CHECK_RESULT(weft_garments_step(crowd, n), WEFT_OK);
            if (t == 0) {
                allocs_after_first = g_allocs;
            }
            for (uint32_t k = 0; k < n; ++k) {
                CHECK_RESULT(weft_garment_step(alone[k]), WEFT_OK);
            }
            for (uint32_t k = 0; k < n; ++k) {
                CHECK_MSG(same_positions(crowd[k], alone[k]), "%s: step %u character %u differs from stepping alone",
                          what, t, k);
                CHECK_EQ_INT(weft_garment_stats(crowd[k]).frame, t + 1);
            }
        }
        CHECK_MSG(g_allocs == allocs_after_first, "%s: %zu allocations after the first batched call", what,
                  g_allocs - allocs_after_first);
        printf("%s: %u garments x %u steps bit-identical to stepping alone\n", what, n, STEPS);
    }
    for (uint32_t k = 0; k < chars + 2; ++k) {
        weft_garment_destroy(crowd[k]);
        weft_garment_destroy(alone[k]);
    }
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    fixture_free(&f);
}

static void crowd_matches_alone(const char *model_path, weft_isa isa, weft_precision prec, weft_precision other,
                                const char *what)
{
    crowd_matches_alone_n(model_path, isa, prec, other, CHARS, false, what);
}

/* Through a job hook: 8 characters of 32 window rows stack to 256 rows, so the stacked linears
 * are split into chunks too. */
static void with_parallel_for(void)
{
    g_hook_chunks = 0;
    crowd_matches_alone_n(DATA "golden_model.safetensors", WEFT_ISA_AUTO, WEFT_PRECISION_FP32, WEFT_PRECISION_INT8,
                          8, true, "fp32 golden through parallel_for");
    crowd_matches_alone_n(DATA "golden_model.safetensors", WEFT_ISA_AUTO, WEFT_PRECISION_INT8, WEFT_PRECISION_FP32,
                          8, true, "int8 golden through parallel_for");
    CHECK(g_hook_chunks > 0);
}

static void fp32_history2(void)
{
    crowd_matches_alone(DATA "golden_model.safetensors", WEFT_ISA_AUTO, WEFT_PRECISION_FP32, WEFT_PRECISION_INT8,
                        "fp32 golden (history 2)");
}

static void fp32_game(void)
{
    crowd_matches_alone(GAME, WEFT_ISA_AUTO, WEFT_PRECISION_FP32, WEFT_PRECISION_FP16, "fp32 game (history 1)");
}

static void fp16_and_int8(void)
{
    crowd_matches_alone(DATA "golden_model.safetensors", WEFT_ISA_AUTO, WEFT_PRECISION_FP16, WEFT_PRECISION_FP32,
                        "fp16 golden");
    crowd_matches_alone(DATA "golden_model.safetensors", WEFT_ISA_AUTO, WEFT_PRECISION_INT8, WEFT_PRECISION_FP32,
                        "int8 golden");
    crowd_matches_alone(GAME, WEFT_ISA_AUTO, WEFT_PRECISION_INT8, WEFT_PRECISION_FP32, "int8 game");
}

/* The batched int8 crowd gives the same bits on every ISA level this CPU runs. */
static void int8_batched_across_isas(void)
{
    fixture f;
    if (!fixture_load(&f)) {
        return;
    }
    static const weft_isa isas[] = {WEFT_ISA_SCALAR, WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    const size_t n3 = f.V * 3;
    float *first = calloc(CHARS * n3, sizeof(float));
    uint32_t levels = 0;
    for (int i = 0; first && i < 4; ++i) {
        weft_context_def cd = weft_default_context_def();
        cd.isa = isas[i];
        weft_context *ctx = NULL;
        if (weft_context_create(&cd, &ctx) != WEFT_OK) {
            continue;
        }
        weft_model *m = NULL;
        CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
        weft_garment *gs[CHARS] = {NULL};
        uint32_t n = 0;
        for (uint32_t k = 0; m && k < CHARS; ++k) {
            gs[k] = make(ctx, &f, m, WEFT_METHOD_MODEL, WEFT_PRECISION_INT8, k, false);
            n += gs[k] != NULL;
        }
        if (n == CHARS) {
            for (uint32_t t = 0; t < STEPS; ++t) {
                set_colliders(gs, n, &f, t);
                CHECK_RESULT(weft_garments_step(gs, n), WEFT_OK);
            }
            for (uint32_t k = 0; k < n; ++k) {
                if (levels == 0) {
                    memcpy(first + k * n3, weft_garment_positions(gs[k]), n3 * sizeof(float));
                } else {
                    CHECK_MSG(memcmp(first + k * n3, weft_garment_positions(gs[k]), n3 * sizeof(float)) == 0,
                              "int8 crowd on %s differs from the first level, character %u", weft_isa_name(isas[i]),
                              k);
                }
            }
            levels++;
        }
        for (uint32_t k = 0; k < CHARS; ++k) {
            weft_garment_destroy(gs[k]);
        }
        weft_model_destroy(m);
        weft_context_destroy(ctx);
    }
    CHECK(levels >= 1);
    printf("int8 crowd bit-identical on %u ISA levels\n", levels);
    free(first);
    fixture_free(&f);
}

/* Bad calls fail before stepping anything; a failing garment keeps its state while the others
 * advance, and the result names its index. */
static void failures_are_confined(void)
{
    fixture f;
    if (!fixture_load(&f)) {
        return;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    weft_model *m = NULL;
    if (ctx) {
        CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    }
    weft_garment *gs[4] = {NULL};
    uint32_t n = 0;
    for (uint32_t k = 0; m && k < 4; ++k) {
        gs[k] = make(ctx, &f, m, WEFT_METHOD_MODEL, WEFT_PRECISION_FP32, k, true);
        n += gs[k] != NULL;
    }
    if (n == 4) {
        CHECK_RESULT(weft_garments_step(NULL, 4), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK_RESULT(weft_garments_step(gs, 0), WEFT_ERROR_INVALID_ARGUMENT);
        weft_garment *dup[3] = {gs[0], gs[1], gs[0]};
        set_colliders(gs, 4, &f, 0);
        CHECK_RESULT(weft_garments_step(dup, 3), WEFT_ERROR_INVALID_ARGUMENT);
        weft_garment *with_null[2] = {gs[0], NULL};
        CHECK_RESULT(weft_garments_step(with_null, 2), WEFT_ERROR_INVALID_ARGUMENT);
        for (uint32_t k = 0; k < 4; ++k) {
            CHECK_EQ_INT(weft_garment_stats(gs[k]).frame, 0); /* nothing stepped */
        }
        /* Garment 2 has no collider for this frame: it fails, the others step. */
        CHECK_RESULT(weft_garments_step(gs, 4), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gs[0], c_frame(&f, 3)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gs[1], c_frame(&f, 5)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gs[3], c_frame(&f, 9)), WEFT_OK);
        const size_t n3 = f.V * 3;
        float *before = malloc(n3 * sizeof(float));
        if (before) {
            memcpy(before, weft_garment_positions(gs[2]), n3 * sizeof(float));
            CHECK_RESULT(weft_garments_step(gs, 4), WEFT_ERROR_NO_COLLIDER);
            CHECK_MSG(strstr(weft_last_error(), "garments[2]") != NULL, "message: %s", weft_last_error());
            CHECK(memcmp(before, weft_garment_positions(gs[2]), n3 * sizeof(float)) == 0);
            free(before);
        }
        CHECK_EQ_INT(weft_garment_stats(gs[0]).frame, 2);
        CHECK_EQ_INT(weft_garment_stats(gs[1]).frame, 2);
        CHECK_EQ_INT(weft_garment_stats(gs[2]).frame, 1);
        CHECK_EQ_INT(weft_garment_stats(gs[3]).frame, 2);

        /* Two failures: the model group (led by index 0) is stepped before the LBS garment at
         * index 1, yet the result names the lowest failing index. */
        weft_garment *lbs = make(ctx, &f, NULL, WEFT_METHOD_LBS, WEFT_PRECISION_FP32, 0, true);
        if (lbs) {
            weft_garment *mixed[3] = {gs[0], lbs, gs[2]};
            CHECK_RESULT(weft_garment_set_collider(gs[0], c_frame(&f, 4)), WEFT_OK);
            CHECK_RESULT(weft_garments_step(mixed, 3), WEFT_ERROR_NO_COLLIDER);
            CHECK_MSG(strstr(weft_last_error(), "garments[1]") != NULL, "message: %s", weft_last_error());
            CHECK_EQ_INT(weft_garment_stats(gs[0]).frame, 3);
            weft_garment_destroy(lbs);
        }
    }
    for (uint32_t k = 0; k < 4; ++k) {
        weft_garment_destroy(gs[k]);
    }
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    fixture_free(&f);
}

TEST_MAIN(TEST_CASE(fp32_history2), TEST_CASE(fp32_game), TEST_CASE(fp16_and_int8), TEST_CASE(int8_batched_across_isas),
          TEST_CASE(with_parallel_for), TEST_CASE(failures_are_confined))
