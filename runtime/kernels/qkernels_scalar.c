/* Plain-C oracle for the int8 / fp16 / deterministic kernels. Written independently of the
 * SIMD body, element by element, following the documented orders (canonical 16-lane sums,
 * in-order fma chains, the qk_exp polynomial) so every ISA variant must match it bit for bit. */
#include "kernels/qkernels.h"

#include <math.h>
#include <string.h>

static float o_exp(float x)
{
    if (x < -87.0f) {
        return 0.0f;
    }
    if (x > 88.0f) {
        x = 88.0f;
    }
    float n = nearbyintf(x * 1.44269504088896341f);
    float r = fmaf(n, -0.693359375f, x);
    r = fmaf(n, 2.12194440e-4f, r);
    float p = 1.0f / 720.0f;
    p = fmaf(p, r, 1.0f / 120.0f);
    p = fmaf(p, r, 1.0f / 24.0f);
    p = fmaf(p, r, 1.0f / 6.0f);
    p = fmaf(p, r, 0.5f);
    p = fmaf(p, r, 1.0f);
    p = fmaf(p, r, 1.0f);
    return p * ldexpf(1.0f, (int)n);
}

static void o_sincos(float x, float *s_out, float *c_out)
{
    float n = nearbyintf(x * 0.636619772367581343f);
    float r = fmaf(n, -1.57079637050628662f, x);
    r = fmaf(n, 4.37113900018624283e-8f, r);
    float r2 = r * r;
    float ps = -1.0f / 5040.0f;
    ps = fmaf(ps, r2, 1.0f / 120.0f);
    ps = fmaf(ps, r2, -1.0f / 6.0f);
    float sn = fmaf(ps * r2, r, r);
    float pc = 1.0f / 40320.0f;
    pc = fmaf(pc, r2, -1.0f / 720.0f);
    pc = fmaf(pc, r2, 1.0f / 24.0f);
    pc = fmaf(pc, r2, -0.5f);
    float cs = fmaf(pc, r2, 1.0f);
    float q = n - floorf(n * 0.25f) * 4.0f;
    if (q == 1.0f) {
        *s_out = cs, *c_out = -sn;
    } else if (q == 2.0f) {
        *s_out = -sn, *c_out = -cs;
    } else if (q == 3.0f) {
        *s_out = -cs, *c_out = sn;
    } else {
        *s_out = sn, *c_out = cs;
    }
}

static void o_posembed(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq, float *out,
                       uint32_t ldo)
{
    for (uint32_t i = 0; i < n; ++i) {
        for (uint32_t d = 0; d < dims; ++d) {
            for (uint32_t f = 0; f < nfreq; ++f) {
                float *o = out + (size_t)i * ldo + ((size_t)d * nfreq + f) * 2;
                o_sincos(x[(size_t)i * dims + d] * freq[f], &o[0], &o[1]);
            }
        }
    }
}

static float o_act(float x, weft_activation act)
{
    switch (act) {
    case WEFT_ACT_RELU:
        return x > 0.0f ? x : 0.0f;
    case WEFT_ACT_GELU: {
        float t = fmaf(x * x, 0.044715f, 1.0f);
        float u2 = (x * t) * 1.59576912160573071f;
        return x / (1.0f + o_exp(-u2));
    }
    case WEFT_ACT_SILU:
        return x / (1.0f + o_exp(-x));
    default:
        return x;
    }
}

/* partial[k mod 16] accumulates x[k] in order; missing tail lanes add +0.0f; fixed tree. */
static float o_tree(float *p)
{
    for (int w = 8; w >= 1; w /= 2) {
        for (int j = 0; j < w; ++j) {
            p[j] = p[j] + p[j + w];
        }
    }
    return p[0];
}

static float o_sum(const float *x, size_t n)
{
    float p[16] = {0};
    for (size_t k = 0; k < n; k += 16) {
        for (int j = 0; j < 16; ++j) {
            p[j] = p[j] + (k + (size_t)j < n ? x[k + (size_t)j] : 0.0f);
        }
    }
    return o_tree(p);
}

static float o_sumsq(const float *x, size_t n, float c)
{
    float p[16] = {0};
    for (size_t k = 0; k < n; k += 16) {
        for (int j = 0; j < 16; ++j) {
            float d = k + (size_t)j < n ? x[k + (size_t)j] - c : 0.0f;
            p[j] = fmaf(d, d, p[j]);
        }
    }
    return o_tree(p);
}

static float o_affine(float y, const float *gamma, const float *beta, size_t i)
{
    if (gamma && beta) {
        return fmaf(y, gamma[i], beta[i]);
    }
    if (gamma) {
        return y * gamma[i];
    }
    if (beta) {
        return y + beta[i];
    }
    return y;
}

static void o_layernorm(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                        const float *beta, float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float mean = o_sum(x, cols) / (float)cols;
        float var = o_sumsq(x, cols, mean) / (float)cols;
        float rstd = 1.0f / sqrtf(var + eps);
        for (uint32_t i = 0; i < cols; ++i) {
            y[i] = o_affine((x[i] - mean) * rstd, gamma, beta, i);
        }
    }
}

static void o_rmsnorm(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                      float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float rs = 1.0f / sqrtf(o_sumsq(x, cols, 0.0f) / (float)cols + eps);
        for (uint32_t i = 0; i < cols; ++i) {
            y[i] = o_affine(x[i] * rs, gamma, NULL, i);
        }
    }
}

static void o_softmax(float *X, uint32_t rows, uint32_t cols, uint32_t ldx)
{
    for (uint32_t r = 0; r < rows; ++r) {
        float *x = X + (size_t)r * ldx;
        float m = -INFINITY;
        for (uint32_t i = 0; i < cols; ++i) {
            m = x[i] > m ? x[i] : m;
        }
        if (m == -INFINITY) {
            memset(x, 0, cols * sizeof(float));
            continue;
        }
        for (uint32_t i = 0; i < cols; ++i) {
            x[i] = o_exp(x[i] - m);
        }
        float inv = 1.0f / o_sum(x, cols);
        for (uint32_t i = 0; i < cols; ++i) {
            x[i] = x[i] * inv;
        }
    }
}

static void o_activate(float *x, size_t n, weft_activation act)
{
    if (act == WEFT_ACT_NONE) {
        return;
    }
    for (size_t i = 0; i < n; ++i) {
        x[i] = o_act(x[i], act);
    }
}

static void o_swiglu(const float *gate, const float *up, float *out, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        out[i] = o_act(gate[i], WEFT_ACT_SILU) * up[i];
    }
}

static float o_finish(float acc, const float *bias, uint32_t n, const float *c_old, weft_activation act)
{
    if (bias) {
        acc = acc + bias[n];
    }
    if (c_old) {
        acc = acc + *c_old;
    }
    return o_act(acc, act);
}

static void o_gemm_det(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const float *B, uint32_t ldb,
                       const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    for (uint32_t m = 0; m < M; ++m) {
        for (uint32_t n = 0; n < N; ++n) {
            float acc = 0.0f;
            for (uint32_t k = 0; k < K; ++k) {
                acc = fmaf(A[(size_t)m * lda + k], B[(size_t)k * ldb + n], acc);
            }
            float *c = C + (size_t)m * ldc + n;
            *c = o_finish(acc, bias, n, accumulate ? c : NULL, act);
        }
    }
}

static void o_gemm_f16(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const uint16_t *B,
                       uint32_t ldb, const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    for (uint32_t m = 0; m < M; ++m) {
        for (uint32_t n = 0; n < N; ++n) {
            float acc = 0.0f;
            for (uint32_t k = 0; k < K; ++k) {
                acc = fmaf(A[(size_t)m * lda + k], weft_f16_to_f32(B[(size_t)k * ldb + n]), acc);
            }
            float *c = C + (size_t)m * ldc + n;
            *c = o_finish(acc, bias, n, accumulate ? c : NULL, act);
        }
    }
}

static void o_quantize_rows(const float *X, uint32_t M, uint32_t K, uint32_t ldx, int8_t *Q, uint32_t ldq,
                            float *scales)
{
    uint32_t Kp = weft_q8_pad_k(K);
    for (uint32_t m = 0; m < M; ++m) {
        const float *x = X + (size_t)m * ldx;
        int8_t *q = Q + (size_t)m * ldq;
        float amax = 0.0f;
        for (uint32_t i = 0; i < K; ++i) {
            float a = fabsf(x[i]);
            amax = amax > a ? amax : a;
        }
        float inv = amax > 0.0f ? 127.0f / amax : 0.0f;
        scales[m] = amax / 127.0f;
        for (uint32_t i = 0; i < K; ++i) {
            float v = nearbyintf(x[i] * inv);
            v = v > 127.0f ? 127.0f : (v < -127.0f ? -127.0f : v);
            q[i] = (int8_t)(int)v;
        }
        memset(q + K, 0, Kp - K);
    }
}

/* Reads the packed layout back element by element: channel c, k -> block byte offset. */
static int8_t o_weight(const weft_q8_weights *W, uint32_t c, uint32_t k)
{
    size_t block = c / WEFT_Q8_NB, lane = c % WEFT_Q8_NB;
    return W->packed[block * WEFT_Q8_NB * W->Kp + (k / WEFT_Q8_KB) * WEFT_Q8_NB * WEFT_Q8_KB + lane * WEFT_Q8_KB +
                     k % WEFT_Q8_KB];
}

static void o_gemm_q8(uint32_t M, const int8_t *Q, uint32_t ldq, const float *qscale, const weft_q8_weights *W,
                      const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    for (uint32_t m = 0; m < M; ++m) {
        for (uint32_t n = 0; n < W->N; ++n) {
            int32_t acc = 0;
            for (uint32_t k = 0; k < W->K; ++k) {
                acc += (int32_t)Q[(size_t)m * ldq + k] * (int32_t)o_weight(W, n, k);
            }
            float s = qscale[m] * W->scale[n];
            float y = (float)acc * s;
            float *c = C + (size_t)m * ldc + n;
            *c = o_finish(y, bias, n, accumulate ? c : NULL, act);
        }
    }
}

/* Per head and query: the score row in scratch, then the softmax oracle, then P V in key order. */
static void o_attention(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *V, uint32_t ldv,
                        uint32_t nq, uint32_t nk, uint32_t H, uint32_t dh, float scale, const uint8_t *mask,
                        const float *key_bias, float *out, uint32_t ldo, float *scratch)
{
    for (uint32_t h = 0; h < H; ++h) {
        const size_t hc = (size_t)h * dh;
        for (uint32_t i = 0; i < nq; ++i) {
            for (uint32_t j = 0; j < nk; ++j) {
                float acc = 0.0f;
                for (uint32_t d = 0; d < dh; ++d) {
                    acc = fmaf(Q[(size_t)i * ldq + hc + d], K[(size_t)j * ldk + hc + d], acc);
                }
                scratch[j] = acc * scale;
            }
            /* the bias in a pass of its own, as the SIMD kernels add it: never fused with the scale */
            for (uint32_t j = 0; key_bias && j < nk; ++j) {
                scratch[j] += key_bias[j];
            }
            for (uint32_t j = 0; mask && j < nk; ++j) {
                scratch[j] = mask[(size_t)i * nk + j] ? scratch[j] : -INFINITY;
            }
            o_softmax(scratch, 1, nk, nk);
            for (uint32_t d = 0; d < dh; ++d) {
                float acc = 0.0f;
                for (uint32_t j = 0; j < nk; ++j) {
                    acc = fmaf(scratch[j], V[(size_t)j * ldv + hc + d], acc);
                }
                out[(size_t)i * ldo + hc + d] = acc;
            }
        }
    }
}

const weft_qkernels weft__qkernels_scalar = {
    .isa = WEFT_ISA_SCALAR,
    .variant = "scalar",
    .quantize_rows = o_quantize_rows,
    .gemm_q8 = o_gemm_q8,
    .gemm_det = o_gemm_det,
    .gemm_f16 = o_gemm_f16,
    .layernorm_det = o_layernorm,
    .rmsnorm_det = o_rmsnorm,
    .softmax_rows_det = o_softmax,
    .activate_det = o_activate,
    .swiglu_det = o_swiglu,
    .posembed_det = o_posembed,
    .attention_det = o_attention,
};
