/* The fused deterministic attention (attention_det), the model-shaped int8 / fp16 / fp32 det
 * GEMMs and the posembed batching: every variant this CPU runs must match the scalar oracle bit for bit, the
 * attention must equal its documented composition (per head: in-order Q K^T, scale, key bias, mask,
 * softmax_rows_det, in-order P V) on every variant, and the oracle must be accurate against a
 * double-precision reference. */
#include "test.h"
#include "kernels/qkernels.h"

#include <stdint.h>

static const weft_qkernels *g_variants[8];
static uint32_t g_nvariants;

static void load_variants(void)
{
    g_nvariants = weft_qkernels_variants(g_variants, 8);
    if (g_nvariants > 8) {
        g_nvariants = 8;
    }
}

static float *rand_floats(test_rng *rng, size_t n, float lo, float hi)
{
    float *x = malloc(n * sizeof(float) + 64);
    for (size_t i = 0; i < n; ++i) {
        x[i] = test_rng_float(rng, lo, hi);
    }
    return x;
}

/* The composed form, built from the table's own kernels (the model's int8 path before the
 * fused kernel): keys transposed per head, gemm_det, scale / mask, softmax_rows_det, gemm_det. */
static void composed_attention(const weft_qkernels *q, const float *Q, uint32_t ld, const float *K, const float *V,
                               uint32_t nq, uint32_t nk, uint32_t H, uint32_t dh, float scale, const uint8_t *mask,
                               const float *bias, float *out, uint32_t ldo)
{
    float *kt = malloc(((size_t)dh * nk + 1) * sizeof(float));
    float *s = malloc(((size_t)nq * nk + 1) * sizeof(float));
    for (uint32_t h = 0; h < H; ++h) {
        for (uint32_t d = 0; d < dh; ++d) {
            for (uint32_t j = 0; j < nk; ++j) {
                kt[(size_t)d * nk + j] = K[(size_t)j * ld + h * dh + d];
            }
        }
        q->gemm_det(nq, nk, dh, Q + h * dh, ld, kt, nk, NULL, s, nk, WEFT_ACT_NONE, false);
        for (size_t i = 0; i < (size_t)nq * nk; ++i) {
            s[i] *= scale;
        }
        for (size_t i = 0; bias && i < (size_t)nq * nk; ++i) { /* a pass of its own: never fused */
            s[i] += bias[i % nk];
        }
        for (size_t i = 0; mask && i < (size_t)nq * nk; ++i) {
            s[i] = mask[i] ? s[i] : -INFINITY;
        }
        q->softmax_rows_det(s, nq, nk, nk);
        q->gemm_det(nq, dh, nk, s, nk, V + h * dh, ld, NULL, out + h * dh, ldo, WEFT_ACT_NONE, false);
    }
    free(kt);
    free(s);
}

typedef struct att_case {
    uint32_t nq, nk, H, dh;
    int mask; /* 0 none, 1 random with a fully masked query, 2 block-causal */
} att_case;

static void test_attention_bit_exact_and_composed(void)
{
    load_variants();
    static const att_case cases[] = {
        {1, 1, 1, 1, 0},   {5, 7, 2, 3, 0},    {16, 16, 4, 12, 0}, {17, 33, 4, 12, 1}, {32, 1000, 4, 12, 0},
        {40, 37, 4, 24, 2}, {3, 0, 2, 4, 0},   {64, 129, 4, 24, 0}, {33, 64, 3, 5, 1},  {128, 128, 4, 12, 2},
        {70, 19, 2, 17, 0}, {1056, 32, 4, 12, 0}, {16, 2080, 4, 12, 1}, /* the garment encoder: 16 queries */
    };
    test_rng rng = {4242};
    int mismatches = 0, not_composed = 0, guard_hits = 0;
    double worst = 0;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        const att_case a = cases[c];
        const uint32_t D = a.H * a.dh, ld = D + 3, ldo = D + 5;
        float *Q = rand_floats(&rng, (size_t)a.nq * ld, -2.0f, 2.0f);
        float *K = rand_floats(&rng, (size_t)a.nk * ld + 1, -2.0f, 2.0f);
        float *V = rand_floats(&rng, (size_t)a.nk * ld + 1, -1.0f, 1.0f);
        uint8_t *mask = NULL;
        if (a.mask) {
            mask = malloc((size_t)a.nq * a.nk + 1);
            for (uint32_t i = 0; i < a.nq; ++i) {
                for (uint32_t j = 0; j < a.nk; ++j) {
                    mask[(size_t)i * a.nk + j] =
                        a.mask == 1 ? (uint8_t)(test_rng_u32(&rng) % 3 != 0) : (uint8_t)(j / 8 <= i / 8);
                }
            }
            if (a.mask == 1 && a.nq > 2) {
                memset(mask + 2 * (size_t)a.nk, 0, a.nk); /* query 2 sees nothing */
            }
        }
        /* every other case weighs its keys (key_bias in [-2, 2], as log w of w in [0.14, 7.4]) */
        float *bias = c % 2 ? rand_floats(&rng, (size_t)a.nk + 1, -2.0f, 2.0f) : NULL;
        const float scale = 1.0f / sqrtf((float)a.dh);
        const size_t on = (size_t)a.nq * ldo;
        float *ref = malloc((on + 1) * sizeof(float)), *out = malloc((on + 1) * sizeof(float));
        float *comp = malloc((on + 1) * sizeof(float));
        float *scratch = malloc(weft_qk_attention_scratch(a.nk, a.dh) * sizeof(float));
        for (size_t i = 0; i < on; ++i) {
            ref[i] = 1234.5f;
        }
        g_variants[0]->attention_det(Q, ld, K, ld, V, ld, a.nq, a.nk, a.H, a.dh, scale, mask, bias, ref, ldo, scratch);
        for (uint32_t i = 0; i < a.nq; ++i) { /* columns past the heads are never written */
            for (uint32_t d = D; d < ldo; ++d) {
                guard_hits += ref[(size_t)i * ldo + d] != 1234.5f;
            }
        }
        /* oracle accuracy against double precision */
        for (uint32_t h = 0; h < a.H; ++h) {
            for (uint32_t i = 0; i < a.nq; ++i) {
                double m = -INFINITY, sum = 0;
                double *p = malloc(((size_t)a.nk + 1) * sizeof(double));
                for (uint32_t j = 0; j < a.nk; ++j) {
                    double s = 0;
                    for (uint32_t d = 0; d < a.dh; ++d) {
                        s += (double)Q[(size_t)i * ld + h * a.dh + d] * K[(size_t)j * ld + h * a.dh + d];
                    }
                    p[j] = mask && !mask[(size_t)i * a.nk + j] ? -INFINITY : s * scale + (bias ? bias[j] : 0.0);
                    m = fmax(m, p[j]);
                }
                for (uint32_t j = 0; j < a.nk; ++j) {
                    p[j] = m == -INFINITY ? 0.0 : exp(p[j] - m);
                    sum += p[j];
                }
                for (uint32_t d = 0; d < a.dh; ++d) {
                    double o = 0;
                    for (uint32_t j = 0; j < a.nk; ++j) {
                        o += sum > 0 ? p[j] / sum * V[(size_t)j * ld + h * a.dh + d] : 0.0;
                    }
                    worst = fmax(worst, fabs(o - ref[(size_t)i * ldo + h * a.dh + d]));
                }
                free(p);
            }
        }
        for (uint32_t v = 0; v < g_nvariants; ++v) {
            const weft_qkernels *q = g_variants[v];
            memset(out, 0, on * sizeof(float));
            q->attention_det(Q, ld, K, ld, V, ld, a.nq, a.nk, a.H, a.dh, scale, mask, bias, out, ldo, scratch);
            memcpy(comp, out, on * sizeof(float));
            composed_attention(q, Q, ld, K, V, a.nq, a.nk, a.H, a.dh, scale, mask, bias, comp, ldo);
            for (uint32_t i = 0; i < a.nq; ++i) {
                const size_t row = (size_t)i * ldo;
                if (v > 0 && memcmp(out + row, ref + row, D * sizeof(float)) != 0) {
                    mismatches++;
                    fprintf(stderr, "attention mismatch: %s case %zu query %u\n", q->variant, c, i);
                }
                if (memcmp(out + row, comp + row, D * sizeof(float)) != 0) {
                    not_composed++;
                    fprintf(stderr, "attention differs from its composition: %s case %zu query %u\n", q->variant,
                            c, i);
                }
            }
        }
        if (a.mask == 1 && a.nq > 2) {
            for (uint32_t d = 0; d < D; ++d) {
                CHECK(ref[2 * (size_t)ldo + d] == 0.0f);
            }
        }
        free(Q); free(K); free(V); free(mask); free(bias); free(ref); free(out); free(comp); free(scratch);
    }
    printf("attention_det: %u variants, oracle worst abs error vs double %.3g\n", g_nvariants, worst);
    CHECK_EQ_INT(mismatches, 0);
    CHECK_EQ_INT(not_composed, 0);
    CHECK_EQ_INT(guard_hits, 0);
    CHECK(worst < 2e-5);
}

/* The model's int8 GEMM shapes (collider MLP 121 -> 48, GNN 96 -> 48, 192 -> 96, narrow heads)
 * with every activation and the residual form: bit-identical to the oracle on every variant. */
static void test_q8_gemm_model_shapes(void)
{
    load_variants();
    static const uint32_t shapes[][3] = {{1003, 121, 48}, {257, 96, 48}, {131, 192, 96}, {67, 48, 48},
                                         {29, 157, 96},   {13, 48, 3},   {9, 96, 192},  {50, 64, 64}};
    test_rng rng = {77};
    int mismatches = 0;
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; ++s) {
        const uint32_t M = shapes[s][0], K = shapes[s][1], N = shapes[s][2];
        const uint32_t Np = weft_q8_pad_n(N), Kp = weft_q8_pad_k(K);
        float *W = rand_floats(&rng, (size_t)N * K, -1.0f, 1.0f);
        int8_t *Wq = malloc((size_t)N * K), *packed = malloc((size_t)Np * Kp);
        float *wscale = malloc(N * sizeof(float)), *pscale = malloc(Np * sizeof(float));
        int32_t *wsum = malloc(Np * sizeof(int32_t));
        CHECK(weft_q8_quantize_weights(W, N, K, Wq, wscale));
        weft_q8_pack(Wq, wscale, N, K, packed, pscale, wsum);
        const weft_q8_weights w = {N, K, Np, Kp, packed, pscale, wsum};
        float *X = rand_floats(&rng, (size_t)M * K, -4.0f, 4.0f);
        for (uint32_t k = 0; k < K; ++k) {
            X[k] = 0.0f; /* an all-zero row: scale 0 */
        }
        float *bias = rand_floats(&rng, N, -0.3f, 0.3f);
        float *init = rand_floats(&rng, (size_t)M * N, -1.0f, 1.0f);
        int8_t *Qr = malloc((size_t)M * Kp), *Qv = malloc((size_t)M * Kp);
        float *sr = malloc(M * sizeof(float)), *sv = malloc(M * sizeof(float));
        float *Cr = malloc((size_t)M * N * sizeof(float)), *Cv = malloc((size_t)M * N * sizeof(float));
        g_variants[0]->quantize_rows(X, M, K, K, Qr, Kp, sr);
        for (int act = 0; act < 4; ++act) {
            const bool accumulate = act == 3;
            memcpy(Cr, init, (size_t)M * N * sizeof(float));
            g_variants[0]->gemm_q8(M, Qr, Kp, sr, &w, act == 1 ? NULL : bias, Cr, N, (weft_activation)act, accumulate);
            for (uint32_t v = 1; v < g_nvariants; ++v) {
                const weft_qkernels *q = g_variants[v];
                q->quantize_rows(X, M, K, K, Qv, Kp, sv);
                if (memcmp(Qv, Qr, (size_t)M * Kp) != 0 || memcmp(sv, sr, M * sizeof(float)) != 0) {
                    mismatches++;
                    fprintf(stderr, "quantize_rows mismatch: %s %ux%u\n", q->variant, M, K);
                }
                memcpy(Cv, init, (size_t)M * N * sizeof(float));
                q->gemm_q8(M, Qr, Kp, sr, &w, act == 1 ? NULL : bias, Cv, N, (weft_activation)act, accumulate);
                if (memcmp(Cv, Cr, (size_t)M * N * sizeof(float)) != 0) {
                    mismatches++;
                    fprintf(stderr, "gemm_q8 mismatch: %s %ux%ux%u act %d\n", q->variant, M, K, N, act);
                }
            }
        }
        free(W); free(Wq); free(packed); free(wscale); free(pscale); free(wsum); free(X); free(bias);
        free(init); free(Qr); free(Qv); free(sr); free(sv); free(Cr); free(Cv);
    }
    CHECK_EQ_INT(mismatches, 0);
}

/* The deterministic fp32 and fp16-weight products at the same shapes with a row stride wider than
 * K (the 3-vector column panels, their row remainders and the columns past them). */
static void test_det_gemm_model_shapes(void)
{
    load_variants();
    static const uint32_t shapes[][3] = {{1003, 121, 48}, {257, 96, 48}, {131, 192, 96}, {67, 48, 48},
                                         {29, 157, 96},   {13, 48, 3},   {9, 96, 192},  {50, 64, 64}, {7, 33, 50}};
    test_rng rng = {78};
    int mismatches = 0;
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; ++s) {
        const uint32_t M = shapes[s][0], K = shapes[s][1], N = shapes[s][2], lda = K + 7, ldc = N + 2;
        float *A = rand_floats(&rng, (size_t)M * lda, -2.0f, 2.0f);
        float *B = rand_floats(&rng, (size_t)K * N, -1.0f, 1.0f);
        uint16_t *Bh = malloc((size_t)K * N * sizeof(uint16_t));
        for (size_t i = 0; i < (size_t)K * N; ++i) {
            Bh[i] = weft_f32_to_f16(B[i]);
        }
        float *bias = rand_floats(&rng, N, -0.3f, 0.3f);
        const size_t cn = (size_t)M * ldc;
        float *init = rand_floats(&rng, cn, -1.0f, 1.0f);
        float *R = malloc(cn * sizeof(float)), *T = malloc(cn * sizeof(float));
        for (int act = 0; act < 4; ++act) {
            const bool accumulate = act == 0;
            for (int h = 0; h < 2; ++h) {
                memcpy(R, init, cn * sizeof(float));
                if (h) {
                    g_variants[0]->gemm_f16(M, N, K, A, lda, Bh, N, bias, R, ldc, (weft_activation)act, accumulate);
                } else {
                    g_variants[0]->gemm_det(M, N, K, A, lda, B, N, bias, R, ldc, (weft_activation)act, accumulate);
                }
                for (uint32_t v = 1; v < g_nvariants; ++v) {
                    memcpy(T, init, cn * sizeof(float));
                    if (h) {
                        g_variants[v]->gemm_f16(M, N, K, A, lda, Bh, N, bias, T, ldc, (weft_activation)act,
                                                accumulate);
                    } else {
                        g_variants[v]->gemm_det(M, N, K, A, lda, B, N, bias, T, ldc, (weft_activation)act,
                                                accumulate);
                    }
                    if (memcmp(T, R, cn * sizeof(float)) != 0) { /* also the untouched columns past N */
                        mismatches++;
                        fprintf(stderr, "%s mismatch: %s %ux%ux%u act %d\n", h ? "gemm_f16" : "gemm_det",
                                g_variants[v]->variant, M, K, N, act);
                    }
                }
            }
        }
        free(A); free(B); free(Bh); free(bias); free(init); free(R); free(T);
    }
    CHECK_EQ_INT(mismatches, 0);
}

/* posembed_det packs several points per vector when a point has few arguments (the collider's
 * 3 corners x 3 coordinates x 6 frequencies), splits a point that has more than 64, and may take
 * an in-register path when the rows are packed (ldo = 2 dims nfreq): every layout must give the
 * oracle's bits, and nothing outside each row's 2 x dims x nfreq floats is written. */
static void test_posembed_layouts(void)
{
    load_variants();
    static const uint32_t shapes[][3] = {{3, 3, 6}, {1, 3, 6}, {1056, 3, 6}, {5, 3, 8}, {7, 3, 25}, {4, 1, 70},
                                         {9, 2, 1}, {6, 3, 16}, {2, 17, 3}, {3, 3, 17}};
    test_rng rng = {5};
    int mismatches = 0, guard_hits = 0;
    for (size_t s = 0; s < 2 * (sizeof shapes / sizeof shapes[0]); ++s) {
        const uint32_t n = shapes[s / 2][0], dims = shapes[s / 2][1], nfreq = shapes[s / 2][2];
        const uint32_t ld = dims * nfreq * 2 + (s % 2 ? 0 : 5); /* padded rows, and packed rows */
        float *x = rand_floats(&rng, (size_t)n * dims, -1.5f, 1.5f);
        float *freq = rand_floats(&rng, nfreq, 0.5f, 60.0f);
        float *ref = malloc((size_t)n * ld * sizeof(float)), *out = malloc((size_t)n * ld * sizeof(float));
        for (uint32_t v = 0; v < g_nvariants; ++v) {
            float *dst = v == 0 ? ref : out;
            for (size_t i = 0; i < (size_t)n * ld; ++i) {
                dst[i] = -7.0f;
            }
            g_variants[v]->posembed_det(x, n, dims, freq, nfreq, dst, ld);
            for (uint32_t i = 0; i < n; ++i) {
                for (uint32_t k = dims * nfreq * 2; k < ld; ++k) {
                    guard_hits += dst[(size_t)i * ld + k] != -7.0f;
                }
            }
            if (v > 0 && memcmp(out, ref, (size_t)n * ld * sizeof(float)) != 0) {
                mismatches++;
                fprintf(stderr, "posembed mismatch: %s n=%u dims=%u nfreq=%u\n", g_variants[v]->variant, n, dims,
                        nfreq);
            }
        }
        free(x); free(freq); free(ref); free(out);
    }
    CHECK_EQ_INT(mismatches, 0);
    CHECK_EQ_INT(guard_hits, 0);
}

TEST_MAIN(TEST_CASE(test_attention_bit_exact_and_composed), TEST_CASE(test_q8_gemm_model_shapes),
          TEST_CASE(test_det_gemm_model_shapes), TEST_CASE(test_posembed_layouts))
