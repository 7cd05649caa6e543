/* The shared body of the int8 / fp16 / deterministic kernels. Each ISA file includes its
 * simd_<isa>.h vector layer, defines the few operations that need integer or half-precision
 * intrinsics, then includes this file:
 *
 *   QK_TABLE            name of the weft_qkernels table to define
 *   QK_ISA, QK_VARIANT  the table's isa and variant string
 *   q8_tile(Q, ldq, rows, block, nblocks, Kp, kgroups, wsum, out)
 *                       out[r][c] = (float)(sum_k Q[r][k] * W[c][k]) for r < rows (<= 4) and the
 *                       16 * nblocks (1 or 2) channels c of consecutive packed blocks starting at
 *                       `block` (each Kp * 16 bytes; wsum: their weight sums)
 *   v_load_h(p), v_load_h_n(p, n)   VW fp16 values converted to fp32 (lanes >= n read as 0)
 *
 * Everything here uses only lane-wise operations or the canonical 16-lane reduction, so the
 * result does not depend on VW (see qkernels.h). */
#include "kernels/qkernels.h"

#include <math.h>
#include <string.h>

#if 16 % VW != 0
#error "the canonical reduction needs VW to divide 16"
#endif
#define QK_GROUPS (16 / VW)

/* ---- deterministic exp and activations (lane-wise) ---------------------------------------- */

static inline V qk_exp(V x)
{
    const V lo = v_set1(-87.0f);
    VM underflow = m_lt(x, lo);
    x = v_min(v_max(x, lo), v_set1(88.0f));
    V n = v_round(v_mul(x, v_set1(1.44269504088896341f)));
    V r = v_fma(n, v_set1(-0.693359375f), x);
    r = v_fma(n, v_set1(2.12194440e-4f), r);
    V p = v_set1(1.0f / 720.0f);
    p = v_fma(p, r, v_set1(1.0f / 120.0f));
    p = v_fma(p, r, v_set1(1.0f / 24.0f));
    p = v_fma(p, r, v_set1(1.0f / 6.0f));
    p = v_fma(p, r, v_set1(0.5f));
    p = v_fma(p, r, v_set1(1.0f));
    p = v_fma(p, r, v_set1(1.0f));
    V y = v_mul(p, v_pow2i(n));
    return v_sel(underflow, v_zero(), y);
}

static inline V qk_act(V x, weft_activation act)
{
    switch (act) {
    case WEFT_ACT_RELU:
        return v_max(x, v_zero());
    case WEFT_ACT_GELU: {
        /* x * sigmoid(2u), u = sqrt(2/pi) (x + 0.044715 x^3): the tanh form of GELU. */
        V t = v_fma(v_mul(x, x), v_set1(0.044715f), v_set1(1.0f));
        V u2 = v_mul(v_mul(x, t), v_set1(1.59576912160573071f));
        return v_div(x, v_add(v_set1(1.0f), qk_exp(v_neg(u2))));
    }
    case WEFT_ACT_SILU:
        return v_div(x, v_add(v_set1(1.0f), qk_exp(v_neg(x))));
    case WEFT_ACT_NONE:
    default:
        return x;
    }
}

static void activate_det(float *x, size_t n, weft_activation act)
{
    if (act == WEFT_ACT_NONE) {
        return;
    }
    size_t i = 0;
    for (; i + VW <= n; i += VW) {
        v_store(x + i, qk_act(v_load(x + i), act));
    }
    if (i < n) {
        v_store_n(x + i, qk_act(v_load_n(x + i, n - i), act), n - i);
    }
}

static void swiglu_det(const float *gate, const float *up, float *out, size_t n)
{
    size_t i = 0;
    for (; i + VW <= n; i += VW) {
        v_store(out + i, v_mul(qk_act(v_load(gate + i), WEFT_ACT_SILU), v_load(up + i)));
    }
    if (i < n) {
        size_t r = n - i;
        v_store_n(out + i, v_mul(qk_act(v_load_n(gate + i, r), WEFT_ACT_SILU), v_load_n(up + i, r)), r);
    }
}

/* sin and cos of x: x = n * pi/2 + r with |r| <= pi/4 (Cody-Waite, two fma steps), minimax-style
 * Taylor polynomials on r, then the quadrant n mod 4 picks and signs them. */
static inline void qk_sincos(V x, V *s_out, V *c_out)
{
    V n = v_round(v_mul(x, v_set1(0.636619772367581343f)));
    V r = v_fma(n, v_set1(-1.57079637050628662f), x);
    r = v_fma(n, v_set1(4.37113900018624283e-8f), r);
    V r2 = v_mul(r, r);
    V ps = v_set1(-1.0f / 5040.0f);
    ps = v_fma(ps, r2, v_set1(1.0f / 120.0f));
    ps = v_fma(ps, r2, v_set1(-1.0f / 6.0f));
    V sn = v_fma(v_mul(ps, r2), r, r);
    V pc = v_set1(1.0f / 40320.0f);
    pc = v_fma(pc, r2, v_set1(-1.0f / 720.0f));
    pc = v_fma(pc, r2, v_set1(1.0f / 24.0f));
    pc = v_fma(pc, r2, v_set1(-0.5f));
    V cs = v_fma(pc, r2, v_set1(1.0f));
    V q = v_sub(n, v_mul(v_floor(v_mul(n, v_set1(0.25f))), v_set1(4.0f))); /* n mod 4, exact */
    VM q1 = m_eq(q, v_set1(1.0f)), q2 = m_eq(q, v_set1(2.0f)), q3 = m_eq(q, v_set1(3.0f));
    V s = v_sel(q1, cs, v_sel(q2, v_neg(sn), v_sel(q3, v_neg(cs), sn)));
    V c = v_sel(q1, v_neg(sn), v_sel(q2, v_neg(cs), v_sel(q3, sn, cs)));
    *s_out = s;
    *c_out = c;
}

/* sin and cos of cnt arguments (lanes are independent: any lane arrangement gives these bits). */
static inline void qk_sincos_n(const float *arg, size_t cnt, float *sbuf, float *cbuf)
{
    for (size_t t = 0; t < cnt; t += VW) {
        V sv, cv;
        qk_sincos(v_load_n(arg + t, cnt - t), &sv, &cv);
        v_store(sbuf + t, sv);
        v_store(cbuf + t, cv);
    }
}

static void posembed_det(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq, float *out,
                         uint32_t ldo)
{
    /* Lanes run along the (coordinate, frequency) arguments of as many whole points as fit in 64
     * (an argument is x * freq, one rounding, whatever lane it lands in); sin/cos are interleaved
     * on store, each point's row being contiguous. */
    enum { CH = 64 };
    float arg[CH], sbuf[CH + VW], cbuf[CH + VW];
    const uint32_t per = dims * nfreq;
    if (per == 0) {
        return;
    }
#if defined(QK_HAVE_POSEMBED_PACKED)
    const size_t total = (size_t)n * per;
    if (ldo == 2 * per && nfreq <= 16 && total < ((size_t)1 << 22)) {
        for (size_t t0 = 0; t0 < total; t0 += VW) {
            V sv, cv;
            qk_sincos(qk_posembed_args(x, (size_t)n * dims, freq, nfreq, t0), &sv, &cv);
            qk_store_sincos(out + 2 * t0, sv, cv, total - t0 < VW ? total - t0 : VW);
        }
        return;
    }
#endif
    const uint32_t pts = per <= CH ? CH / per : 1;
    for (uint32_t i0 = 0; i0 < n; i0 += pts) {
        const uint32_t np = n - i0 < pts ? n - i0 : pts;
        for (uint32_t r0 = 0; r0 < per; r0 += CH) { /* one pass unless a point has > 64 arguments */
            const uint32_t nr = per - r0 < CH ? per - r0 : CH;
            size_t t = 0;
            for (uint32_t p = 0; p < np; ++p) {
                const float *xp = x + (size_t)(i0 + p) * dims;
                uint32_t d = r0 / nfreq, f = r0 % nfreq;
                for (uint32_t r = 0; r < nr; ++r) {
                    arg[t++] = xp[d] * freq[f];
                    if (++f == nfreq) {
                        f = 0;
                        ++d;
                    }
                }
            }
            qk_sincos_n(arg, t, sbuf, cbuf);
            for (uint32_t p = 0; p < np; ++p) {
                float *o = out + (size_t)(i0 + p) * ldo + (size_t)r0 * 2;
                const float *sp = sbuf + (size_t)p * nr, *cp = cbuf + (size_t)p * nr;
                for (uint32_t r = 0; r < nr; ++r) {
                    o[2 * r] = sp[r];
                    o[2 * r + 1] = cp[r];
                }
            }
        }
    }
}

/* ---- canonical 16-lane reductions ------------------------------------------------------------ */

static inline float qk_tree16(const V *acc)
{
#if defined(QK_HAVE_TREE16)
    return qk_tree16_v(acc); /* the same additions, in registers */
#else
    float t[16];
    for (int g = 0; g < QK_GROUPS; ++g) {
        v_store(t + g * VW, acc[g]);
    }
    for (int w = 8; w >= 1; w /= 2) {
        for (int j = 0; j < w; ++j) {
            t[j] = t[j] + t[j + w];
        }
    }
    return t[0];
#endif
}

/* Lanes past n are 0 and contribute "+ 0.0f", which the oracle mirrors. */
static inline V qk_lanes(const float *x, size_t base, int g, size_t n)
{
    size_t start = base + (size_t)g * VW;
    if (start + VW <= n) {
        return v_load(x + start);
    }
    return start < n ? v_load_n(x + start, n - start) : v_zero();
}

static inline float qk_sum(const float *x, size_t n)
{
    V acc[QK_GROUPS];
    for (int g = 0; g < QK_GROUPS; ++g) {
        acc[g] = v_zero();
    }
    for (size_t k = 0; k < n; k += 16) {
        for (int g = 0; g < QK_GROUPS; ++g) {
            acc[g] = v_add(acc[g], qk_lanes(x, k, g, n));
        }
    }
    return qk_tree16(acc);
}

/* sum of (x - c)^2 (or x^2 when c = 0), fma-accumulated per lane; tail lanes add exact zeros. */
static inline float qk_sumsq(const float *x, size_t n, float c)
{
    V acc[QK_GROUPS];
    for (int g = 0; g < QK_GROUPS; ++g) {
        acc[g] = v_zero();
    }
    const V vc = v_set1(c);
    for (size_t k = 0; k < n; k += 16) {
        for (int g = 0; g < QK_GROUPS; ++g) {
            size_t start = k + (size_t)g * VW;
            size_t left = start < n ? n - start : 0;
            V d = v_sub(qk_lanes(x, k, g, n), vc);
            d = v_sel(m_first(left), d, v_zero());
            acc[g] = v_fma(d, d, acc[g]);
        }
    }
    return qk_tree16(acc);
}

static inline float qk_absmax(const float *x, size_t n)
{
    V m = v_zero();
    size_t i = 0;
    for (; i + VW <= n; i += VW) {
        m = v_max(m, v_abs(v_load(x + i)));
    }
    if (i < n) {
        m = v_max(m, v_abs(v_load_n(x + i, n - i)));
    }
    return v_hmax(m);
}

/* ---- row kernels ------------------------------------------------------------------------------ */

/* y = (x - mean) * rstd, then y = fma(y, gamma, beta) / y * gamma / y + beta. */
static inline V qk_affine(V y, const float *gamma, const float *beta, size_t i, size_t n)
{
    if (gamma && beta) {
        return v_fma(y, v_load_n(gamma + i, n), v_load_n(beta + i, n));
    }
    if (gamma) {
        return v_mul(y, v_load_n(gamma + i, n));
    }
    if (beta) {
        return v_add(y, v_load_n(beta + i, n));
    }
    return y;
}

static void layernorm_det(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                          const float *beta, float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float mean = qk_sum(x, cols) / (float)cols;
        float var = qk_sumsq(x, cols, mean) / (float)cols;
        float rstd = 1.0f / sqrtf(var + eps);
        const V vm = v_set1(mean), vr = v_set1(rstd);
        for (size_t i = 0; i < cols; i += VW) {
            size_t n = cols - i < VW ? cols - i : VW;
            V v = v_mul(v_sub(v_load_n(x + i, n), vm), vr);
            v_store_n(y + i, qk_affine(v, gamma, beta, i, n), n);
        }
    }
}

static void rmsnorm_det(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                        float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        float *y = Y + (size_t)r * ld;
        float rs = 1.0f / sqrtf(qk_sumsq(x, cols, 0.0f) / (float)cols + eps);
        const V vr = v_set1(rs);
        for (size_t i = 0; i < cols; i += VW) {
            size_t n = cols - i < VW ? cols - i : VW;
            v_store_n(y + i, qk_affine(v_mul(v_load_n(x + i, n), vr), gamma, NULL, i, n), n);
        }
    }
}

static void softmax_rows_det(float *X, uint32_t rows, uint32_t cols, uint32_t ldx)
{
    for (uint32_t r = 0; r < rows; ++r) {
        float *x = X + (size_t)r * ldx;
        float m = -INFINITY;
        for (uint32_t i = 0; i < cols; ++i) {
            m = x[i] > m ? x[i] : m;
        }
        if (m == -INFINITY) { /* fully masked row */
            memset(x, 0, cols * sizeof(float));
            continue;
        }
        const V vm = v_set1(m);
        for (size_t i = 0; i < cols; i += VW) {
            size_t n = cols - i < VW ? cols - i : VW;
            v_store_n(x + i, qk_exp(v_sub(v_load_n(x + i, n), vm)), n);
        }
        const V inv = v_set1(1.0f / qk_sum(x, cols));
        for (size_t i = 0; i < cols; i += VW) {
            size_t n = cols - i < VW ? cols - i : VW;
            v_store_n(x + i, v_mul(v_load_n(x + i, n), inv), n);
        }
    }
}

/* ---- matrix products ---------------------------------------------------------------------- */

/* Shared epilogue order: y = acc (+ bias) (+ old C), then the activation. */
static inline V qk_epilogue(V acc, const float *bias, const float *c_old, size_t n, weft_activation act)
{
    if (bias) {
        acc = v_add(acc, n >= VW ? v_load(bias) : v_load_n(bias, n));
    }
    if (c_old) {
        acc = v_add(acc, n >= VW ? v_load(c_old) : v_load_n(c_old, n));
    }
    return qk_act(acc, act);
}

#define QK_MR 4 /* rows per int8 tile */

#if defined(__clang__)
#define QK_UNROLL _Pragma("clang loop unroll(full)")
#else
#define QK_UNROLL _Pragma("GCC unroll 16")
#endif
#define QK_NO_UNROLL /* for loops with a run-time trip count (clang rejects a full unroll of them) */

/* One template for the fp32 and fp16 B operands: lanes along N, k in order. The tile body is
 * instantiated twice, with the ISA's register-tile height (WEFT_MR rows x 2 vectors) as a
 * compile-time constant so the accumulators live in registers, and with a run-time height for
 * the last rows. Tiling does not change any result: each output is one in-order fma chain. */
#define QK_GEMM_TILE(NAME, BTYPE, LOADB, LOADB_N, ROWS, UNROLL_ROWS)                                    \
    {                                                                                                   \
        size_t w0 = N - n0 < VW ? N - n0 : VW;                                                          \
        size_t w1 = N - n0 > VW ? (N - n0 - VW < VW ? N - n0 - VW : VW) : 0;                            \
        V acc[WEFT_MR][2];                                                                              \
        QK_UNROLL for (uint32_t r = 0; r < WEFT_MR; ++r)                                                \
        {                                                                                               \
            acc[r][0] = v_zero();                                                                       \
            acc[r][1] = v_zero();                                                                       \
        }                                                                                               \
        const float *a0 = A + (size_t)m0 * lda;                                                         \
        if (w1 == VW) { /* full-width tile: plain loads, no per-k branch */                             \
            for (uint32_t k = 0; k < K; ++k) {                                                          \
                const BTYPE *b = B + (size_t)k * ldb + n0;                                              \
                const V b0 = LOADB(b), b1 = LOADB(b + VW);                                              \
                UNROLL_ROWS for (uint32_t r = 0; r < (ROWS); ++r)                                         \
                {                                                                                       \
                    const V a = v_set1(a0[(size_t)r * lda + k]);                                        \
                    acc[r][0] = v_fma(a, b0, acc[r][0]);                                                \
                    acc[r][1] = v_fma(a, b1, acc[r][1]);                                                \
                }                                                                                       \
            }                                                                                           \
        } else {                                                                                        \
            for (uint32_t k = 0; k < K; ++k) {                                                          \
                const BTYPE *b = B + (size_t)k * ldb + n0;                                              \
                V b0 = w0 == VW ? LOADB(b) : LOADB_N(b, w0);                                            \
                V b1 = w1 ? LOADB_N(b + VW, w1) : v_zero();                                             \
                UNROLL_ROWS for (uint32_t r = 0; r < (ROWS); ++r)                                         \
                {                                                                                       \
                    V a = v_set1(a0[(size_t)r * lda + k]);                                              \
                    acc[r][0] = v_fma(a, b0, acc[r][0]);                                                \
                    acc[r][1] = v_fma(a, b1, acc[r][1]);                                                \
                }                                                                                       \
            }                                                                                           \
        }                                                                                               \
        /* accumulators leave through a tile in L1: indexing them by a loop variable would keep \
         * them in memory during the k loop */                                                         \
        float tile[WEFT_MR][2 * VW];                                                                    \
        UNROLL_ROWS for (uint32_t r = 0; r < (ROWS); ++r)                                                 \
        {                                                                                               \
            v_store(tile[r], acc[r][0]);                                                                \
            v_store(tile[r] + VW, acc[r][1]);                                                           \
        }                                                                                               \
        for (uint32_t r = 0; r < (ROWS); ++r) {                                                         \
            float *c = C + (size_t)(m0 + r) * ldc + n0;                                                 \
            const float *bb = bias ? bias + n0 : NULL;                                                  \
            v_store_n(c, qk_epilogue(v_load(tile[r]), bb, accumulate ? c : NULL, w0, act), w0);         \
            if (w1) {                                                                                   \
                v_store_n(c + VW,                                                                       \
                          qk_epilogue(v_load(tile[r] + VW), bb ? bb + VW : NULL, accumulate ? c + VW : NULL, \
                                      w1, act),                                                         \
                          w1);                                                                          \
            }                                                                                           \
        }                                                                                               \
    }

/* Three full vectors of columns (48 on AVX-512: the model's narrow layers) by QK_MR3 rows, so no
 * accumulator idles on a half-empty second vector. Same chains as the tile above. */
#define QK_MR3 (WEFT_MR * 2 / 3 > 0 ? WEFT_MR * 2 / 3 : 1)
#define QK_GEMM_TILE3(BTYPE, LOADB)                                                                     \
    {                                                                                                   \
        V acc[QK_MR3][3];                                                                               \
        QK_UNROLL for (uint32_t r = 0; r < QK_MR3; ++r)                                                 \
        {                                                                                               \
            acc[r][0] = acc[r][1] = acc[r][2] = v_zero();                                               \
        }                                                                                               \
        const float *a0 = A + (size_t)m0 * lda;                                                         \
        for (uint32_t k = 0; k < K; ++k) {                                                              \
            const BTYPE *b = B + (size_t)k * ldb + n0;                                                  \
            const V b0 = LOADB(b), b1 = LOADB(b + VW), b2 = LOADB(b + 2 * VW);                          \
            QK_UNROLL for (uint32_t r = 0; r < QK_MR3; ++r)                                             \
            {                                                                                           \
                const V a = v_set1(a0[(size_t)r * lda + k]);                                            \
                acc[r][0] = v_fma(a, b0, acc[r][0]);                                                    \
                acc[r][1] = v_fma(a, b1, acc[r][1]);                                                    \
                acc[r][2] = v_fma(a, b2, acc[r][2]);                                                    \
            }                                                                                           \
        }                                                                                               \
        float tile[QK_MR3][3 * VW];                                                                     \
        QK_UNROLL for (uint32_t r = 0; r < QK_MR3; ++r)                                                 \
        {                                                                                               \
            v_store(tile[r], acc[r][0]);                                                                \
            v_store(tile[r] + VW, acc[r][1]);                                                           \
            v_store(tile[r] + 2 * VW, acc[r][2]);                                                       \
        }                                                                                               \
        for (uint32_t r = 0; r < QK_MR3; ++r) {                                                         \
            float *c = C + (size_t)(m0 + r) * ldc + n0;                                                 \
            for (uint32_t v = 0; v < 3; ++v) {                                                          \
                const float *bb = bias ? bias + n0 + v * VW : NULL;                                     \
                v_store(c + v * VW, qk_epilogue(v_load(tile[r] + v * VW), bb, accumulate ? c + v * VW : NULL, VW, \
                                                act));                                                  \
            }                                                                                           \
        }                                                                                               \
    }

#define QK_DEFINE_GEMM(NAME, BTYPE, LOADB, LOADB_N)                                                   \
    static void NAME##_wide(uint32_t m0, uint32_t n0, uint32_t K, const float *A, uint32_t lda,         \
                            const BTYPE *B, uint32_t ldb, const float *bias, float *C, uint32_t ldc,    \
                            weft_activation act, bool accumulate)                                       \
        QK_GEMM_TILE3(BTYPE, LOADB)                                                                     \
    static void NAME##_full(uint32_t m0, uint32_t n0, uint32_t N, uint32_t K, const float *A, uint32_t lda, \
                            const BTYPE *B, uint32_t ldb, const float *bias, float *C, uint32_t ldc,    \
                            weft_activation act, bool accumulate)                                       \
        QK_GEMM_TILE(NAME, BTYPE, LOADB, LOADB_N, WEFT_MR, QK_UNROLL)                                   \
    static void NAME##_rest(uint32_t rows, uint32_t m0, uint32_t n0, uint32_t N, uint32_t K,            \
                            const float *A, uint32_t lda, const BTYPE *B, uint32_t ldb, const float *bias, \
                            float *C, uint32_t ldc, weft_activation act, bool accumulate)               \
        QK_GEMM_TILE(NAME, BTYPE, LOADB, LOADB_N, rows, QK_NO_UNROLL)                                   \
    static void NAME(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const BTYPE *B,  \
                     uint32_t ldb, const float *bias, float *C, uint32_t ldc, weft_activation act,      \
                     bool accumulate)                                                                   \
    {                                                                                                   \
        uint32_t n0 = 0, mw = 0;                                                                        \
        if (N >= 3 * VW) { /* 3-vector column panels over whole row tiles; the rest below */            \
            for (; mw + QK_MR3 <= M; mw += QK_MR3) {                                                    \
                for (uint32_t nw = 0; nw + 3 * VW <= N; nw += 3 * VW) {                                 \
                    NAME##_wide(mw, nw, K, A, lda, B, ldb, bias, C, ldc, act, accumulate);              \
                }                                                                                       \
            }                                                                                           \
            n0 = N / (3 * VW) * (3 * VW);                                                               \
        }                                                                                               \
        /* rows >= mw for the 3-vector panels, every row for the columns past them */                   \
        for (uint32_t p = 0; p < 2; ++p) {                                                              \
            const uint32_t nb = p == 0 ? 0 : n0, ne = p == 0 ? n0 : N, mb = p == 0 ? mw : 0;            \
            for (uint32_t nc = nb; nc < ne; nc += 2 * VW) {                                             \
                uint32_t m0 = mb;                                                                       \
                for (; m0 + WEFT_MR <= M; m0 += WEFT_MR) {                                              \
                    NAME##_full(m0, nc, ne, K, A, lda, B, ldb, bias, C, ldc, act, accumulate);          \
                }                                                                                       \
                if (m0 < M) {                                                                           \
                    NAME##_rest(M - m0, m0, nc, ne, K, A, lda, B, ldb, bias, C, ldc, act, accumulate);  \
                }                                                                                       \
            }                                                                                           \
        }                                                                                               \
    }

QK_DEFINE_GEMM(gemm_det, float, v_load, v_load_n)
QK_DEFINE_GEMM(gemm_f16, uint16_t, v_load_h, v_load_h_n)

#ifndef QK_HAVE_STORE_I8
static inline void qk_store_i8(int8_t *q, V v, size_t n)
{
    float t[VW];
    v_store(t, v);
    for (size_t j = 0; j < n; ++j) {
        q[j] = (int8_t)(int)t[j];
    }
}
#endif

static void quantize_rows(const float *X, uint32_t M, uint32_t K, uint32_t ldx, int8_t *Q, uint32_t ldq,
                          float *scales)
{
    const uint32_t Kp = weft_q8_pad_k(K);
    /* Rows in groups: every row's absolute maximum, then their scales, then the rows. The
     * phases have no dependency between rows, so the rows' reductions and divisions overlap
     * instead of each row waiting for its own (the same operations per row: the same bits). */
    enum { G = 16 };
    for (uint32_t m0 = 0; m0 < M; m0 += G) {
        const uint32_t n = M - m0 < G ? M - m0 : G;
        float amax[G], inv[G];
        for (uint32_t r = 0; r < n; ++r) {
            amax[r] = qk_absmax(X + (size_t)(m0 + r) * ldx, K);
        }
        for (uint32_t r = 0; r < n; ++r) {
            inv[r] = amax[r] > 0.0f ? 127.0f / amax[r] : 0.0f;
            scales[m0 + r] = amax[r] / 127.0f;
        }
        const V hi = v_set1(127.0f), lo = v_set1(-127.0f);
        for (uint32_t r = 0; r < n; ++r) {
            const float *x = X + (size_t)(m0 + r) * ldx;
            int8_t *q = Q + (size_t)(m0 + r) * ldq;
            const V vinv = v_set1(inv[r]);
            uint32_t i = 0;
            for (; i + VW <= K; i += VW) {
                qk_store_i8(q + i, v_min(v_max(v_round(v_mul(v_load(x + i), vinv)), lo), hi), VW);
            }
            if (i < K) {
                const size_t rest = K - i;
                qk_store_i8(q + i, v_min(v_max(v_round(v_mul(v_load_n(x + i, rest), vinv)), lo), hi), rest);
            }
            for (uint32_t k = K; k < Kp; ++k) { /* at most 3 bytes of padding */
                q[k] = 0;
            }
        }
    }
}

/* Row tile and channel blocks per tile; an ISA file may widen them (its q8_tile then takes
 * out[QK_Q8_MR][QK_Q8_NB * 16]). */
#ifndef QK_Q8_MR
#define QK_Q8_MR 4
#define QK_Q8_NB 2
#endif
#ifndef QK_Q8_ROWSUM
static inline void q8_rowsums(const int8_t *Q, uint32_t ldq, uint32_t rows, uint32_t Kp, int32_t *rsum)
{
    (void)Q, (void)ldq, (void)rows, (void)Kp, (void)rsum;
}
#endif

static void gemm_q8(uint32_t M, const int8_t *Q, uint32_t ldq, const float *qscale, const weft_q8_weights *W,
                    const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    const uint32_t kgroups = W->Kp / WEFT_Q8_KB;
    float out[QK_Q8_MR][QK_Q8_NB * WEFT_Q8_NB];
    int32_t rsum[QK_Q8_MR];
    for (uint32_t m0 = 0; m0 < M; m0 += QK_Q8_MR) {
        const uint32_t rows = M - m0 < QK_Q8_MR ? M - m0 : QK_Q8_MR;
        const int8_t *q = Q + (size_t)m0 * ldq;
        q8_rowsums(q, ldq, rows, W->Kp, rsum);
        for (uint32_t nb = 0; nb < W->Np; nb += QK_Q8_NB * WEFT_Q8_NB) {
            const int8_t *block = W->packed + (size_t)nb * W->Kp;
            const uint32_t left = (W->Np - nb) / WEFT_Q8_NB;
            const uint32_t nblocks = left < QK_Q8_NB ? left : QK_Q8_NB;
            const uint32_t ncols = W->N - nb < nblocks * WEFT_Q8_NB ? W->N - nb : nblocks * WEFT_Q8_NB;
#if defined(QK_Q8_ROWSUM)
            q8_tile(q, ldq, rows, block, nblocks, W->Kp, kgroups, rsum, out);
#else
            q8_tile(q, ldq, rows, block, nblocks, W->Kp, kgroups, W->wsum + nb, out);
#endif
            for (uint32_t r = 0; r < rows; ++r) {
                const V sr = v_set1(qscale[m0 + r]);
                float *c = C + (size_t)(m0 + r) * ldc + nb;
                uint32_t j = 0;
                for (; j + VW <= ncols; j += VW) { /* full vectors: no masks */
                    const V y = v_mul(v_load(out[r] + j), v_mul(sr, v_load(W->scale + nb + j)));
                    v_store(c + j, qk_epilogue(y, bias ? bias + nb + j : NULL, accumulate ? c + j : NULL, VW, act));
                }
                if (j < ncols) {
                    const size_t n = ncols - j;
                    const V y = v_mul(v_load(out[r] + j), v_mul(sr, v_load(W->scale + nb + j)));
                    v_store_n(c + j, qk_epilogue(y, bias ? bias + nb + j : NULL, accumulate ? c + j : NULL, n, act),
                              n);
                }
            }
        }
    }
}

/* ---- deterministic attention ------------------------------------------------------------- */

#ifndef QK_ATT_ACC
#define QK_ATT_ACC 12 /* accumulator registers one P.V step may use (16-register ISAs) */
#endif

/* m < s ? s : m: the oracle's in-order running maximum, also for signed zeros and NaN. */
static inline V qk_max_ordered(V m, V s) { return v_sel(m_lt(m, s), s, m); }

/* Blocks of 16 queries on every ISA; an ISA with 32 vector registers (QK_ATT_WIDE) adds blocks of
 * 32, where each broadcast key or value feeds two FMAs, for calls with more than 16 queries. */
#define QK_QB 16
#define QK_ATT(name) name##_q16
#include "kernels/qkernels_attention.h"
#if defined(QK_ATT_WIDE)
#define QK_QB 32
#define QK_ATT(name) name##_q32
#include "kernels/qkernels_attention.h"
#endif

static void attention_det(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *Vm, uint32_t ldv,
                          uint32_t nq, uint32_t nk, uint32_t H, uint32_t dh, float scale, const uint8_t *mask,
                          const float *key_bias, float *out, uint32_t ldo, float *scratch)
{
#if defined(QK_ATT_WIDE)
    if (nq > 16) {
        attention_det_q32(Q, ldq, K, ldk, Vm, ldv, nq, nk, H, dh, scale, mask, key_bias, out, ldo, scratch);
        return;
    }
#endif
    attention_det_q16(Q, ldq, K, ldk, Vm, ldv, nq, nk, H, dh, scale, mask, key_bias, out, ldo, scratch);
}

const weft_qkernels QK_TABLE = {
    .isa = QK_ISA,
    .variant = QK_VARIANT,
    .quantize_rows = quantize_rows,
    .gemm_q8 = gemm_q8,
    .gemm_det = gemm_det,
    .gemm_f16 = gemm_f16,
    .layernorm_det = layernorm_det,
    .rmsnorm_det = rmsnorm_det,
    .softmax_rows_det = softmax_rows_det,
    .activate_det = activate_det,
    .swiglu_det = swiglu_det,
    .posembed_det = posembed_det,
    .attention_det = attention_det,
};
