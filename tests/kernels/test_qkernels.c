/* int8 / fp16 / deterministic kernels: every variant this CPU runs must match the scalar oracle
 * bit for bit (the lockstep guarantee), and the oracle must be accurate against fp32/double
 * references within the stated bounds. */
#include "test.h"
#include "kernels/qkernels.h"

#include <stdint.h>

static const uint32_t g_sizes[] = {1, 3, 4, 16, 17, 31, 33, 64, 257};
#define NSIZES (sizeof g_sizes / sizeof g_sizes[0])

static float *rand_floats(test_rng *rng, size_t n, float lo, float hi)
{
    float *x = malloc(n * sizeof(float) + 64);
    for (size_t i = 0; i < n; ++i) {
        x[i] = test_rng_float(rng, lo, hi);
    }
    return x;
}

static const weft_qkernels *g_variants[8];
static uint32_t g_nvariants;

static void load_variants(void)
{
    g_nvariants = weft_qkernels_variants(g_variants, 8);
    if (g_nvariants > 8) {
        g_nvariants = 8;
    }
}

static void test_variants_present(void)
{
    load_variants();
    CHECK(g_nvariants >= 2);
    CHECK(strcmp(g_variants[0]->variant, "scalar") == 0);
    for (uint32_t v = 0; v < g_nvariants; ++v) {
        printf("variant: %s\n", g_variants[v]->variant);
    }
    CHECK(weft_qkernels_for_isa(WEFT_ISA_SCALAR) == g_variants[0]);
}

static void test_f16_conversion(void)
{
    /* Every half survives half -> float -> half (NaNs stay NaN). */
    int bad = 0;
    for (uint32_t h = 0; h < 65536; ++h) {
        float f = weft_f16_to_f32((uint16_t)h);
        uint16_t back = weft_f32_to_f16(f);
        bool is_nan = ((h >> 10) & 0x1f) == 0x1f && (h & 0x3ff);
        if (is_nan ? !isnan(f) || ((back & 0x7c00) != 0x7c00 || !(back & 0x3ff)) : back != h) {
            bad++;
        }
    }
    CHECK_EQ_INT(bad, 0);
    /* Rounding: the result is a nearest half, ties to even. */
    test_rng rng = {0x1234567};
    int not_nearest = 0;
    for (int i = 0; i < 200000; ++i) {
        float x = test_rng_float(&rng, -70000.0f, 70000.0f) * powf(2.0f, (float)(int)(test_rng_u32(&rng) % 40) - 30);
        uint16_t h = weft_f32_to_f16(x);
        float y = weft_f16_to_f32(h);
        if (isinf(y)) {
            not_nearest += fabsf(x) < 65520.0f;
            continue;
        }
        float up = weft_f16_to_f32((uint16_t)(h + 1)), down = weft_f16_to_f32((uint16_t)(h - 1));
        double e = fabs((double)x - y);
        if ((h & 0x7fff) != 0x7bff && !isinf(up) && e > fabs((double)x - up)) {
            not_nearest++;
        }
        if ((h & 0x7fff) != 0 && e > fabs((double)x - down)) {
            not_nearest++;
        }
    }
    CHECK_EQ_INT(not_nearest, 0);
    CHECK(weft_f32_to_f16(1.0f) == 0x3c00);
    CHECK(weft_f32_to_f16(65504.0f) == 0x7bff);
    CHECK(weft_f32_to_f16(65520.0f) == 0x7c00);
    CHECK(weft_f32_to_f16(-0.0f) == 0x8000);
    CHECK(weft_f32_to_f16(5.9604645e-8f) == 0x0001); /* smallest subnormal */
    CHECK(weft_f32_to_f16(2.9802322e-8f) == 0x0000); /* exactly half of it: tie to even */
}

static void test_weight_quantisation(void)
{
    test_rng rng = {99};
    const uint32_t N = 37, K = 53;
    float *W = rand_floats(&rng, (size_t)N * K, -2.0f, 2.0f);
    for (uint32_t k = 0; k < K; ++k) {
        W[5 * K + k] = 0.0f; /* an all-zero channel */
    }
    int8_t *Wq = malloc((size_t)N * K);
    float scale[37];
    CHECK(weft_q8_quantize_weights(W, N, K, Wq, scale));
    CHECK(scale[5] == 0.0f);
    int out_of_bound = 0, hits127 = 0;
    for (uint32_t n = 0; n < N; ++n) {
        for (uint32_t k = 0; k < K; ++k) {
            int q = Wq[n * K + k];
            out_of_bound += q < -127 || q > 127;
            hits127 += q == 127 || q == -127;
            if (scale[n] > 0.0f) {
                out_of_bound += fabsf(W[n * K + k] - (float)q * scale[n]) > 0.5001f * scale[n];
            }
        }
    }
    CHECK_EQ_INT(out_of_bound, 0);
    CHECK(hits127 >= (int)N - 1); /* every non-zero channel reaches its absmax */
    W[3] = NAN;
    CHECK(!weft_q8_quantize_weights(W, N, K, Wq, scale));
    /* Round half to even: 2.5 / (127/127) -> 2, 3.5 -> 4. */
    float w2[4] = {127.0f, 2.5f, 3.5f, -2.5f};
    int8_t q2[4];
    float s2;
    CHECK(weft_q8_quantize_weights(w2, 1, 4, q2, &s2));
    CHECK(q2[1] == 2 && q2[2] == 4 && q2[3] == -2);
    free(W);
    free(Wq);
}

typedef struct q8_fixture {
    weft_q8_weights w;
    int8_t *packed;
    float *scale;
    int32_t *wsum;
} q8_fixture;

static q8_fixture make_weights(test_rng *rng, uint32_t N, uint32_t K, float **W_out)
{
    q8_fixture f;
    float *W = rand_floats(rng, (size_t)N * K, -1.0f, 1.0f);
    int8_t *Wq = malloc((size_t)N * K);
    float *scale = malloc(N * sizeof(float));
    weft_q8_quantize_weights(W, N, K, Wq, scale);
    uint32_t Np = weft_q8_pad_n(N), Kp = weft_q8_pad_k(K);
    f.packed = malloc((size_t)Np * Kp);
    f.scale = malloc(Np * sizeof(float));
    f.wsum = malloc(Np * sizeof(int32_t));
    weft_q8_pack(Wq, scale, N, K, f.packed, f.scale, f.wsum);
    f.w = (weft_q8_weights){N, K, Np, Kp, f.packed, f.scale, f.wsum};
    free(Wq);
    free(scale);
    *W_out = W;
    return f;
}

static void free_weights(q8_fixture *f)
{
    free(f->packed);
    free(f->scale);
    free(f->wsum);
}

static void test_q8_gemm_bit_exact_and_accurate(void)
{
    load_variants();
    test_rng rng = {7};
    const weft_qkernels *ref = g_variants[0];
    int mismatches = 0, inaccurate = 0, cases = 0;
    for (size_t a = 0; a < NSIZES; ++a) {
        for (size_t b = 0; b < NSIZES; b += 2) {
            for (size_t c = 0; c < NSIZES; c += 3) {
                uint32_t M = g_sizes[a], N = g_sizes[b], K = g_sizes[c];
                float *W;
                q8_fixture f = make_weights(&rng, N, K, &W);
                float *X = rand_floats(&rng, (size_t)M * K, -3.0f, 3.0f);
                float *bias = rand_floats(&rng, N, -0.5f, 0.5f);
                uint32_t Kp = weft_q8_pad_k(K);
                int8_t *Q0 = malloc((size_t)M * Kp), *Q1 = malloc((size_t)M * Kp);
                float *s0 = malloc(M * sizeof(float)), *s1 = malloc(M * sizeof(float));
                float *C0 = malloc((size_t)M * N * sizeof(float)), *C1 = malloc((size_t)M * N * sizeof(float));
                weft_activation act = (weft_activation)((a + b + c) % 4);
                bool accumulate = (a + b + c) % 3 == 1;
                float *init = rand_floats(&rng, (size_t)M * N, -1.0f, 1.0f);
                memcpy(C0, init, (size_t)M * N * sizeof(float));
                ref->quantize_rows(X, M, K, K, Q0, Kp, s0);
                ref->gemm_q8(M, Q0, Kp, s0, &f.w, bias, C0, N, act, accumulate);
                /* accuracy of the scheme (no activation): against the fp32 product */
                if (act == WEFT_ACT_NONE && !accumulate) {
                    for (uint32_t m = 0; m < M; ++m) {
                        double sx = 0;
                        for (uint32_t k = 0; k < K; ++k) {
                            sx = fmax(sx, fabs(X[m * K + k]) / 127.0);
                        }
                        for (uint32_t n = 0; n < N; ++n) {
                            double exact = bias[n], bound = 1e-6, sw = 0;
                            for (uint32_t k = 0; k < K; ++k) {
                                sw = fmax(sw, fabs(W[n * K + k]) / 127.0);
                            }
                            for (uint32_t k = 0; k < K; ++k) {
                                exact += (double)X[m * K + k] * W[n * K + k];
                                /* each operand is within half a step of its int8 value */
                                bound += fabs(X[m * K + k]) * sw / 2 + fabs(W[n * K + k]) * sx / 2 + sx * sw / 4;
                            }
                            inaccurate += fabs(C0[m * N + n] - exact) > bound * 1.001 + 1e-5 * fabs(exact);
                        }
                    }
                }
                for (uint32_t v = 1; v < g_nvariants; ++v) {
                    memset(Q1, 0x55, (size_t)M * Kp);
                    memcpy(C1, init, (size_t)M * N * sizeof(float));
                    g_variants[v]->quantize_rows(X, M, K, K, Q1, Kp, s1);
                    g_variants[v]->gemm_q8(M, Q1, Kp, s1, &f.w, bias, C1, N, act, accumulate);
                    bool same = memcmp(Q0, Q1, (size_t)M * Kp) == 0 && memcmp(s0, s1, M * sizeof(float)) == 0 &&
                                memcmp(C0, C1, (size_t)M * N * sizeof(float)) == 0;
                    if (!same) {
                        mismatches++;
                        fprintf(stderr, "q8 mismatch: %s M=%u N=%u K=%u act=%d\n", g_variants[v]->variant, M, N, K,
                                (int)act);
                    }
                }
                cases++;
                free(Q0); free(Q1); free(s0); free(s1); free(C0); free(C1); free(X); free(bias); free(W); free(init);
                free_weights(&f);
            }
        }
    }
    CHECK(cases > 50);
    CHECK_EQ_INT(mismatches, 0);
    CHECK_EQ_INT(inaccurate, 0);
}

static void test_quantize_rows_edge_cases(void)
{
    load_variants();
    float X[2 * 5] = {0, 0, 0, 0, 0, 1.0f, -2.0f, 0.5f, 2.0f, -1e-30f};
    for (uint32_t v = 0; v < g_nvariants; ++v) {
        int8_t Q[2 * 8];
        float s[2];
        memset(Q, 0x7f, sizeof Q);
        g_variants[v]->quantize_rows(X, 2, 5, 5, Q, 8, s);
        CHECK(s[0] == 0.0f);
        for (int i = 0; i < 8; ++i) {
            CHECK(Q[i] == 0); /* zero row and the K padding */
        }
        CHECK(Q[8 + 1] == -127 && Q[8 + 3] == 127 && Q[8 + 4] == 0 && Q[8 + 5] == 0);
        CHECK(Q[8 + 2] == 32); /* 0.5 * 63.5 = 31.75 -> 32 */
    }
}

static void test_det_gemm_and_f16_bit_exact(void)
{
    load_variants();
    test_rng rng = {11};
    const weft_qkernels *ref = g_variants[0];
    int mismatches = 0, inaccurate = 0;
    for (size_t a = 0; a < NSIZES; a += 2) {
        for (size_t b = 0; b < NSIZES; ++b) {
            for (size_t c = 0; c < NSIZES; c += 2) {
                uint32_t M = g_sizes[a], N = g_sizes[b], K = g_sizes[c];
                float *A = rand_floats(&rng, (size_t)M * K, -1.0f, 1.0f);
                float *B = rand_floats(&rng, (size_t)K * N, -1.0f, 1.0f);
                uint16_t *Bh = malloc((size_t)K * N * sizeof(uint16_t));
                for (size_t i = 0; i < (size_t)K * N; ++i) {
                    Bh[i] = weft_f32_to_f16(B[i]);
                }
                float *bias = rand_floats(&rng, N, -1.0f, 1.0f);
                float *init = rand_floats(&rng, (size_t)M * N, -1.0f, 1.0f);
                size_t bytes = (size_t)M * N * sizeof(float);
                float *C0 = malloc(bytes), *C1 = malloc(bytes), *H0 = malloc(bytes), *H1 = malloc(bytes);
                weft_activation act = (weft_activation)((a + b) % 4);
                bool accumulate = (b + c) % 2 == 1;
                memcpy(C0, init, bytes);
                memcpy(H0, init, bytes);
                ref->gemm_det(M, N, K, A, K, B, N, bias, C0, N, act, accumulate);
                ref->gemm_f16(M, N, K, A, K, Bh, N, bias, H0, N, act, accumulate);
                if (act == WEFT_ACT_NONE && !accumulate) {
                    for (uint32_t m = 0; m < M; ++m) {
                        for (uint32_t n = 0; n < N; ++n) {
                            double e = bias[n];
                            for (uint32_t k = 0; k < K; ++k) {
                                e += (double)A[m * K + k] * B[k * N + n];
                            }
                            inaccurate += fabs(C0[m * N + n] - e) > 1e-5 * (K + 1);
                            inaccurate += fabs(H0[m * N + n] - e) > 5e-4 * (K + 1); /* fp16 rounding of B */
                        }
                    }
                }
                for (uint32_t v = 1; v < g_nvariants; ++v) {
                    memcpy(C1, init, bytes);
                    memcpy(H1, init, bytes);
                    g_variants[v]->gemm_det(M, N, K, A, K, B, N, bias, C1, N, act, accumulate);
                    g_variants[v]->gemm_f16(M, N, K, A, K, Bh, N, bias, H1, N, act, accumulate);
                    if (memcmp(C0, C1, bytes) != 0 || memcmp(H0, H1, bytes) != 0) {
                        mismatches++;
                        fprintf(stderr, "det/f16 gemm mismatch: %s M=%u N=%u K=%u\n", g_variants[v]->variant, M, N, K);
                    }
                }
                free(A); free(B); free(Bh); free(bias); free(init); free(C0); free(C1); free(H0); free(H1);
            }
        }
    }
    CHECK_EQ_INT(mismatches, 0);
    CHECK_EQ_INT(inaccurate, 0);
}

static double gelu_ref(double x) { return 0.5 * x * (1.0 + tanh(0.7978845608028654 * (x + 0.044715 * x * x * x))); }

static void test_row_kernels_bit_exact_and_accurate(void)
{
    load_variants();
    test_rng rng = {23};
    const weft_qkernels *ref = g_variants[0];
    int mismatches = 0;
    double worst_ln = 0, worst_sm = 0, worst_act = 0;
    for (size_t a = 0; a < NSIZES; ++a) {
        uint32_t rows = 3, cols = g_sizes[a], ld = cols + 5;
        size_t n = (size_t)rows * ld;
        float *X = rand_floats(&rng, n, -6.0f, 6.0f);
        float *g = rand_floats(&rng, cols, 0.5f, 1.5f), *bta = rand_floats(&rng, cols, -0.5f, 0.5f);
        if (cols > 2) {
            X[ld + 1] = -INFINITY; /* a masked logit in row 1 */
        }
        float *masked = malloc(cols * sizeof(float));
        for (uint32_t i = 0; i < cols; ++i) {
            masked[i] = -INFINITY;
        }
        float *R[5], *T[5];
        for (int k = 0; k < 5; ++k) {
            R[k] = malloc(n * sizeof(float));
            T[k] = malloc(n * sizeof(float));
        }
        /* oracle */
        for (int k = 0; k < 5; ++k) {
            memcpy(R[k], X, n * sizeof(float));
        }
        for (uint32_t i = 0; i < cols; ++i) {
            R[0][i] = X[i] == -INFINITY ? 0.0f : X[i];
        }
        ref->layernorm_det(R[0], R[0], rows, cols, ld, g, bta, 1e-5f);
        ref->rmsnorm_det(R[1], R[1], rows, cols, ld, g, 1e-6f);
        memcpy(R[2] + 2 * ld, masked, cols * sizeof(float)); /* fully masked row 2 */
        ref->softmax_rows_det(R[2], rows, cols, ld);
        ref->activate_det(R[3], cols, WEFT_ACT_GELU);
        ref->swiglu_det(X + 2 * ld, X + 2 * ld, R[4], cols);
        /* accuracy of the oracle (row 2 has no masked entries) */
        for (uint32_t i = 0; i < cols && cols > 1; ++i) {
            double mean = 0, var = 0;
            for (uint32_t j = 0; j < cols; ++j) {
                mean += X[ld * 2 + j];
            }
            mean /= cols;
            for (uint32_t j = 0; j < cols; ++j) {
                var += (X[ld * 2 + j] - mean) * (X[ld * 2 + j] - mean);
            }
            var /= cols;
            double e = (X[ld * 2 + i] - mean) / sqrt(var + 1e-5) * g[i] + bta[i];
            worst_ln = fmax(worst_ln, fabs(R[0][ld * 2 + i] - e));
        }
        {
            double mx = -INFINITY, s = 0;
            for (uint32_t j = 0; j < cols; ++j) {
                mx = fmax(mx, X[j]);
            }
            for (uint32_t j = 0; j < cols; ++j) {
                s += exp(X[j] - mx);
            }
            for (uint32_t j = 0; j < cols; ++j) {
                worst_sm = fmax(worst_sm, fabs(R[2][j] - exp(X[j] - mx) / s));
            }
            for (uint32_t j = 0; j < cols; ++j) {
                worst_act = fmax(worst_act, fabs(R[3][j] - gelu_ref(X[j])) / fmax(1.0, fabs(X[j])));
                CHECK(R[2][2 * ld + j] == 0.0f);
            }
        }
        for (uint32_t v = 1; v < g_nvariants; ++v) {
            const weft_qkernels *q = g_variants[v];
            for (int k = 0; k < 5; ++k) {
                memcpy(T[k], X, n * sizeof(float));
            }
            for (uint32_t i = 0; i < cols; ++i) {
                T[0][i] = X[i] == -INFINITY ? 0.0f : X[i];
            }
            q->layernorm_det(T[0], T[0], rows, cols, ld, g, bta, 1e-5f);
            q->rmsnorm_det(T[1], T[1], rows, cols, ld, g, 1e-6f);
            memcpy(T[2] + 2 * ld, masked, cols * sizeof(float));
            q->softmax_rows_det(T[2], rows, cols, ld);
            q->activate_det(T[3], cols, WEFT_ACT_GELU);
            q->swiglu_det(X + 2 * ld, X + 2 * ld, T[4], cols);
            for (int k = 0; k < 5; ++k) {
                size_t len = k >= 3 ? cols : n;
                if (memcmp(R[k], T[k], len * sizeof(float)) != 0) {
                    mismatches++;
                    fprintf(stderr, "row kernel %d mismatch: %s cols=%u\n", k, q->variant, cols);
                }
            }
        }
        for (int k = 0; k < 5; ++k) {
            free(R[k]);
            free(T[k]);
        }
        free(X); free(g); free(bta); free(masked);
    }
    CHECK_EQ_INT(mismatches, 0);
    printf("oracle accuracy: layernorm %.3g, softmax %.3g, gelu (rel) %.3g\n", worst_ln, worst_sm, worst_act);
    CHECK(worst_ln < 2e-5);
    CHECK(worst_sm < 2e-6);
    CHECK(worst_act < 2e-6);
}

/* A small int8 block (quantise -> int8 GEMM + GELU -> LayerNorm -> softmax -> fp32 det GEMM ->
 * fp16 GEMM) on fixed data: its output bits must hash to the same value on every variant and on
 * every architecture (the constant was recorded on x86-64 and is checked under qemu-aarch64). */
static uint64_t fnv1a(const void *data, size_t n, uint64_t h)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; ++i) {
        h = (h ^ p[i]) * 0x100000001b3ull;
    }
    return h;
}

static uint64_t run_block(const weft_qkernels *q)
{
    enum { M = 21, K = 45, N = 38, N2 = 19 };
    test_rng rng = {2026};
    float *X = rand_floats(&rng, (size_t)M * K, -2.0f, 2.0f);
    float *W;
    q8_fixture f = make_weights(&rng, N, K, &W);
    float *bias = rand_floats(&rng, N, -0.1f, 0.1f);
    float *g = rand_floats(&rng, N, 0.8f, 1.2f);
    float *B = rand_floats(&rng, (size_t)N * N2, -0.5f, 0.5f);
    uint16_t Bh[N * N2];
    for (int i = 0; i < N * N2; ++i) {
        Bh[i] = weft_f32_to_f16(B[i] * 0.5f);
    }
    int8_t Q[M * 48];
    float s[M], Y[M * N], Z[M * N2], Z2[M * N2];
    q->quantize_rows(X, M, K, K, Q, 48, s);
    q->gemm_q8(M, Q, 48, s, &f.w, bias, Y, N, WEFT_ACT_GELU, false);
    q->layernorm_det(Y, Y, M, N, N, g, bias, 1e-5f);
    q->softmax_rows_det(Y, M, N, N);
    q->gemm_det(M, N2, N, Y, N, B, N2, NULL, Z, N2, WEFT_ACT_SILU, false);
    q->gemm_f16(M, N2, N, Y, N, Bh, N2, NULL, Z2, N2, WEFT_ACT_NONE, false);
    q->rmsnorm_det(Z2, Z2, M, N2, N2, NULL, 1e-6f);
    uint64_t h = fnv1a(Z, sizeof Z, 0xcbf29ce484222325ull);
    h = fnv1a(Z2, sizeof Z2, h);
    free(X); free(W); free(bias); free(g); free(B);
    free_weights(&f);
    return h;
}

static void test_block_hash_across_variants_and_architectures(void)
{
    load_variants();
    const uint64_t recorded = 0x4b3a2257835fc86eull;
    uint64_t h0 = run_block(g_variants[0]);
    printf("int8 block hash: 0x%016llx\n", (unsigned long long)h0);
    for (uint32_t v = 1; v < g_nvariants; ++v) {
        CHECK_MSG(run_block(g_variants[v]) == h0, "variant %s", g_variants[v]->variant);
    }
    CHECK_MSG(h0 == recorded, "hash 0x%016llx differs from the recorded 0x%016llx", (unsigned long long)h0,
              (unsigned long long)recorded);
}

static void test_posembed_det(void)
{
    load_variants();
    test_rng rng = {31};
    const uint32_t n = 37, dims = 3, nfreq = 19, ld = dims * nfreq * 2 + 3;
    float *x = rand_floats(&rng, (size_t)n * dims, -2.0f, 2.0f);
    float freq[19];
    for (uint32_t f = 0; f < nfreq; ++f) {
        freq[f] = powf(2.0f, (float)f * 0.35f) * 3.14159265f; /* up to ~100 rad per metre */
    }
    float *ref = calloc((size_t)n * ld, sizeof(float)), *out = calloc((size_t)n * ld, sizeof(float));
    g_variants[0]->posembed_det(x, n, dims, freq, nfreq, ref, ld);
    double worst = 0;
    for (uint32_t i = 0; i < n; ++i) {
        for (uint32_t d = 0; d < dims; ++d) {
            for (uint32_t f = 0; f < nfreq; ++f) {
                float arg = x[i * dims + d] * freq[f];
                const float *o = ref + (size_t)i * ld + (d * nfreq + f) * 2;
                worst = fmax(worst, fabs(o[0] - sin((double)arg)));
                worst = fmax(worst, fabs(o[1] - cos((double)arg)));
            }
        }
    }
    printf("posembed_det worst abs error vs libm double: %.3g\n", worst);
    CHECK(worst < 2e-6);
    for (uint32_t v = 1; v < g_nvariants; ++v) {
        memset(out, 0, (size_t)n * ld * sizeof(float));
        g_variants[v]->posembed_det(x, n, dims, freq, nfreq, out, ld);
        CHECK_MSG(memcmp(out, ref, (size_t)n * ld * sizeof(float)) == 0, "variant %s", g_variants[v]->variant);
    }
    free(x);
    free(ref);
    free(out);
}

TEST_MAIN(TEST_CASE(test_variants_present), TEST_CASE(test_f16_conversion), TEST_CASE(test_weight_quantisation),
          TEST_CASE(test_q8_gemm_bit_exact_and_accurate), TEST_CASE(test_quantize_rows_edge_cases),
          TEST_CASE(test_det_gemm_and_f16_bit_exact), TEST_CASE(test_row_kernels_bit_exact_and_accurate),
          TEST_CASE(test_block_hash_across_variants_and_architectures), TEST_CASE(test_posembed_det))
