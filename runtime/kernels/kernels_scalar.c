/* Scalar oracles: the reference every SIMD twin is tested against, and the fallback level.
 * Written for clarity, in the most direct order of operations; no shared code with the SIMD
 * body so that a mistake there cannot hide by being repeated here. */
#include "kernels/kernels.h"
#include "kernels/kernels_internal.h"

#include <math.h>
#include <string.h>

static float act_scalar(float v, weft_activation act)
{
    switch (act) {
    case WEFT_ACT_RELU:
        return v > 0.0f ? v : 0.0f;
    case WEFT_ACT_GELU: {
        const float u = 0.7978845608028654f * (v + 0.044715f * v * v * v);
        return 0.5f * v * (1.0f + tanhf(u));
    }
    case WEFT_ACT_SILU:
        return v / (1.0f + expf(-v));
    case WEFT_ACT_NONE:
    default:
        return v;
    }
}

static void gemm_scalar(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const float *W,
                        uint32_t ldw, const float *bias, float *C, uint32_t ldc, weft_activation act,
                        bool accumulate)
{
    for (uint32_t m = 0; m < M; ++m) {
        const float *a = A + (size_t)m * lda;
        float *c = C + (size_t)m * ldc;
        for (uint32_t n = 0; n < N; ++n) {
            const float *w = W + (size_t)n * ldw;
            float s = 0.0f;
            for (uint32_t k = 0; k < K; ++k) {
                s += a[k] * w[k];
            }
            if (bias) {
                s += bias[n];
            }
            if (accumulate) {
                s += c[n];
            }
            c[n] = act_scalar(s, act);
        }
    }
}

static void softmax_row_scalar(float *x, uint32_t cols)
{
    float mx = -INFINITY;
    for (uint32_t j = 0; j < cols; ++j) {
        mx = x[j] > mx ? x[j] : mx;
    }
    if (mx == -INFINITY) {
        /* Every entry masked out: no distribution exists; zeros keep NaN out of the output. */
        memset(x, 0, (size_t)cols * sizeof *x);
        return;
    }
    float sum = 0.0f;
    for (uint32_t j = 0; j < cols; ++j) {
        x[j] = expf(x[j] - mx);
        sum += x[j];
    }
    const float inv = 1.0f / sum;
    for (uint32_t j = 0; j < cols; ++j) {
        x[j] *= inv;
    }
}

static void softmax_rows_scalar(float *X, uint32_t rows, uint32_t cols, uint32_t ldx)
{
    for (uint32_t r = 0; r < rows; ++r) {
        softmax_row_scalar(X + (size_t)r * ldx, cols);
    }
}

static void layernorm_scalar(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld,
                             const float *gamma, const float *beta, float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float mean = 0.0f;
        for (uint32_t j = 0; j < cols; ++j) {
            mean += x[j];
        }
        mean /= (float)cols;
        float var = 0.0f;
        for (uint32_t j = 0; j < cols; ++j) {
            const float d = x[j] - mean;
            var += d * d;
        }
        var /= (float)cols;
        const float inv = 1.0f / sqrtf(var + eps);
        for (uint32_t j = 0; j < cols; ++j) {
            float v = (x[j] - mean) * inv;
            if (gamma) {
                v *= gamma[j];
            }
            if (beta) {
                v += beta[j];
            }
            y[j] = v;
        }
    }
}

static void rmsnorm_scalar(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld,
                           const float *gamma, float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float ss = 0.0f;
        for (uint32_t j = 0; j < cols; ++j) {
            ss += x[j] * x[j];
        }
        const float inv = 1.0f / sqrtf(ss / (float)cols + eps);
        for (uint32_t j = 0; j < cols; ++j) {
            y[j] = x[j] * inv * (gamma ? gamma[j] : 1.0f);
        }
    }
}

static void gelu_scalar(float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        x[i] = act_scalar(x[i], WEFT_ACT_GELU);
    }
}

static void silu_scalar(float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        x[i] = act_scalar(x[i], WEFT_ACT_SILU);
    }
}

static void swiglu_scalar(const float *gate, const float *up, float *out, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        const float g = gate[i];
        out[i] = g / (1.0f + expf(-g)) * up[i];
    }
}

static void posembed_scalar(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq,
                            float *out, uint32_t ldo)
{
    for (uint32_t i = 0; i < n; ++i) {
        for (uint32_t d = 0; d < dims; ++d) {
            for (uint32_t f = 0; f < nfreq; ++f) {
                const float arg = x[(size_t)i * dims + d] * freq[f];
                float *o = out + (size_t)i * ldo + ((size_t)d * nfreq + f) * 2;
                o[0] = sinf(arg);
                o[1] = cosf(arg);
            }
        }
    }
}

static void csr_aggregate_scalar(const uint32_t *rowptr, const uint32_t *col, uint32_t rows, const float *X,
                                 uint32_t ldx, uint32_t dim, float *out, uint32_t ldo, bool mean)
{
    for (uint32_t r = 0; r < rows; ++r) {
        float *o = out + (size_t)r * ldo;
        for (uint32_t j = 0; j < dim; ++j) {
            o[j] = 0.0f;
        }
        const uint32_t b = rowptr[r], e = rowptr[r + 1];
        for (uint32_t p = b; p < e; ++p) {
            const float *x = X + (size_t)col[p] * ldx;
            for (uint32_t j = 0; j < dim; ++j) {
                o[j] += x[j];
            }
        }
        if (mean && e > b) {
            const float inv = 1.0f / (float)(e - b);
            for (uint32_t j = 0; j < dim; ++j) {
                o[j] *= inv;
            }
        }
    }
}

static void attention_scalar(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *V,
                             uint32_t ldv, uint32_t nq, uint32_t nk, uint32_t heads, uint32_t dh, float scale,
                             const uint8_t *mask, const float *key_bias, float *out, uint32_t ldo, float *scratch)
{
    float *s = scratch; /* one row of scores */
    for (uint32_t h = 0; h < heads; ++h) {
        const size_t off = (size_t)h * dh;
        for (uint32_t q = 0; q < nq; ++q) {
            const float *qv = Q + (size_t)q * ldq + off;
            const uint8_t *mrow = mask ? mask + (size_t)q * nk : NULL;
            for (uint32_t k = 0; k < nk; ++k) {
                if (mrow && !mrow[k]) {
                    s[k] = -INFINITY;
                    continue;
                }
                const float *kv = K + (size_t)k * ldk + off;
                float d = 0.0f;
                for (uint32_t j = 0; j < dh; ++j) {
                    d += qv[j] * kv[j];
                }
                s[k] = d * scale;
            }
            for (uint32_t k = 0; key_bias && k < nk; ++k) {
                s[k] += key_bias[k]; /* -inf (masked) stays -inf */
            }
            softmax_row_scalar(s, nk);
            float *o = out + (size_t)q * ldo + off;
            for (uint32_t j = 0; j < dh; ++j) {
                o[j] = 0.0f;
            }
            for (uint32_t k = 0; k < nk; ++k) {
                const float *vv = V + (size_t)k * ldv + off;
                for (uint32_t j = 0; j < dh; ++j) {
                    o[j] += s[k] * vv[j];
                }
            }
        }
    }
}

const weft_kernels weft__kernels_scalar = {
    .isa = WEFT_ISA_SCALAR,
    .gemm = gemm_scalar,
    .softmax_rows = softmax_rows_scalar,
    .layernorm = layernorm_scalar,
    .rmsnorm = rmsnorm_scalar,
    .gelu = gelu_scalar,
    .silu = silu_scalar,
    .swiglu = swiglu_scalar,
    .posembed = posembed_scalar,
    .csr_aggregate = csr_aggregate_scalar,
    .attention = attention_scalar,
};
