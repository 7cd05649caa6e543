/* The one kernel body shared by every SIMD level. A twin file (kernels_avx2.c, ...) includes
 * its simd_*.h vector layer, defines WEFT_KTABLE (the name of the table to emit), then includes
 * this file. Everything here is static, so each twin gets its own copy compiled for its ISA.
 *
 * Vector layer contract (see simd_avx512.h): V / VM types, VW lanes, WEFT_MR x WEFT_NRV GEMM
 * register tile, loads/stores with zero-filled tails (v_load_n / v_store_n never touch memory
 * past n floats), arithmetic, compare masks, v_sel, v_pow2i, horizontal v_hsum / v_hmax, and an
 * in-register VW x VW v_transpose.
 *
 * Vector transcendentals (worst errors against double-precision libm, measured by
 * tests/kernels/test_rowwise.c on every level; docs/KERNELS.md has the table):
 *   v_exp      sigmoid built on it within 2.3e-7 relative on [-80, 0]; exactly 0 below -87.33
 *              (so a masked -inf gives 0), saturates at exp(88.376) instead of +inf. NaN inputs
 *              are not propagated (they clamp); callers validate inputs at the API boundary.
 *   v_sincos   within 8.9e-8 absolute for |x| <= 1000 (Cody-Waite reduction with FMA); beyond
 *              8192 the caller falls back to libm per lane.
 *   gelu/silu  x * sigmoid(.); sigmoid takes 1 / (1 + exp(-t)) with v_rcp (a reciprocal estimate
 *              refined by Newton steps where the ISA has one, else a divide). */
#ifndef WEFT_KTABLE
#error "define WEFT_KTABLE and include a simd_*.h before kernels_body.h"
#endif

#include "kernels/kernels.h"
#include "kernels/kernels_internal.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#define WEFT_NR (WEFT_NRV * VW) /* GEMM tile width in floats */
#define WEFT_KC 256u            /* K block: a packed W panel is KC x NR floats */
#define WEFT_INLINE static inline __attribute__((always_inline))
/* Fully unroll a loop with a constant trip count, so register tiles stay in registers. */
#if defined(__clang__)
#define WEFT_UNROLL _Pragma("clang loop unroll(full)")
#else
#define WEFT_UNROLL _Pragma("GCC unroll 16")
#endif

/* ---------------------------------------------------------------------------------------- */
/* Transcendentals                                                                           */

WEFT_INLINE V v_exp(V x)
{
    const V lo = v_set1(-87.33654f), hi = v_set1(88.37626f);
    const VM under = m_lt(x, lo);
    x = v_min(v_max(x, lo), hi);
    const V n = v_round(v_mul(x, v_set1(1.44269504088896341f)));
    /* r = x - n ln2 in two steps: the high part of ln2 has few bits, so n * hi is exact. */
    V r = v_fma(n, v_set1(-0.693359375f), x);
    r = v_fma(n, v_set1(2.12194440e-4f), r);
    V p = v_set1(1.9875691500e-4f);
    p = v_fma(p, r, v_set1(1.3981999507e-3f));
    p = v_fma(p, r, v_set1(8.3334519073e-3f));
    p = v_fma(p, r, v_set1(4.1665795894e-2f));
    p = v_fma(p, r, v_set1(1.6666665459e-1f));
    p = v_fma(p, r, v_set1(5.0000001201e-1f));
    p = v_fma(p, v_mul(r, r), v_add(r, v_set1(1.0f)));
    return v_sel(under, v_zero(), v_mul(p, v_pow2i(n)));
}

/* 1 / (1 + exp(-t)); the denominator is in [1, 2.4e38], where v_rcp is accurate. */
WEFT_INLINE V v_sigmoid(V t) { return v_rcp(v_add(v_set1(1.0f), v_exp(v_neg(t)))); }

WEFT_INLINE V v_silu(V x) { return v_mul(x, v_sigmoid(x)); }

/* tanh-approximate GELU: 0.5 x (1 + tanh(u)) == x * sigmoid(2u), which avoids the cancellation
 * of 1 + tanh(u) for negative u. */
WEFT_INLINE V v_gelu(V x)
{
    const V x3 = v_mul(v_mul(x, x), x);
    const V u2 = v_mul(v_fma(x3, v_set1(0.044715f), x), v_set1(2.0f * 0.7978845608028654f));
    return v_mul(x, v_sigmoid(u2));
}

WEFT_INLINE V v_act(V v, weft_activation act)
{
    switch (act) {
    case WEFT_ACT_RELU:
        return v_max(v, v_zero());
    case WEFT_ACT_GELU:
        return v_gelu(v);
    case WEFT_ACT_SILU:
        return v_silu(v);
    case WEFT_ACT_NONE:
    default:
        return v;
    }
}

/* sin and cos of |x| <= 8192: reduce by multiples of pi/2, evaluate both minimax polynomials on
 * [-pi/4, pi/4] and pick/negate by quadrant. */
WEFT_INLINE void v_sincos(V x, V *s_out, V *c_out)
{
    const V q = v_round(v_mul(x, v_set1(0.636619772367581343f)));
    V r = v_fma(q, v_set1(-1.57079625129699707031f), x);
    r = v_fma(q, v_set1(-7.54978941586159635335e-8f), r);
    r = v_fma(q, v_set1(-5.39030252995776476554e-15f), r);
    const V z = v_mul(r, r);
    V s = v_set1(-1.9515295891e-4f);
    s = v_fma(s, z, v_set1(8.3321608736e-3f));
    s = v_fma(s, z, v_set1(-1.6666654611e-1f));
    s = v_fma(v_mul(s, z), r, r);
    V c = v_set1(2.443315711809948e-5f);
    c = v_fma(c, z, v_set1(-1.388731625493765e-3f));
    c = v_fma(c, z, v_set1(4.166664568298827e-2f));
    c = v_fma(v_mul(c, z), z, v_fma(z, v_set1(-0.5f), v_set1(1.0f)));
    /* quadrant = q mod 4, computed in floats (exact for |q| < 2^22) */
    const V quad = v_sub(q, v_mul(v_floor(v_mul(q, v_set1(0.25f))), v_set1(4.0f)));
    const VM q1 = m_eq(quad, v_set1(1.0f)), q2 = m_eq(quad, v_set1(2.0f)), q3 = m_eq(quad, v_set1(3.0f));
    const VM odd = m_or(q1, q3);
    const V sx = v_sel(odd, c, s), cx = v_sel(odd, s, c);
    *s_out = v_sel(m_or(q2, q3), v_neg(sx), sx);
    *c_out = v_sel(m_or(q1, q2), v_neg(cx), cx);
}

/* ---------------------------------------------------------------------------------------- */
/* GEMM micro-kernel: C[r][0..nb) (+)= A[r][0..kc) . B[0..kc)[0..nb) for r < ROWS, with B rows
 * at stride ldb. The accumulators stay in registers for the whole K loop.                      */

/* C = act((acc + [C]) * scale + [bias]) */
typedef struct tile_epilogue {
    const float *bias;   /* added when non-NULL (already offset to the tile's first column) */
    bool add_c;          /* add what C holds (accumulate, or a partial sum from an earlier K block) */
    float scale;         /* 1 except for attention scores */
    bool apply_act;      /* last K block: apply the activation */
    weft_activation act;
} tile_epilogue;

static inline size_t lanes_left(size_t nb, size_t j)
{
    return nb > j * VW ? nb - j * VW : 0;
}

/* x = act(x) over n floats, four vectors per step: one activation is a long dependency chain
 * (about 30 operations), and four independent chains in flight keep the FP pipes busy. */
static void act_span(float *x, size_t n, weft_activation act)
{
    size_t j = 0;
    for (; j + 4 * VW <= n; j += 4 * VW) {
        const V a = v_act(v_load(x + j), act), b = v_act(v_load(x + j + VW), act);
        const V c = v_act(v_load(x + j + 2 * VW), act), d = v_act(v_load(x + j + 3 * VW), act);
        v_store(x + j, a);
        v_store(x + j + VW, b);
        v_store(x + j + 2 * VW, c);
        v_store(x + j + 3 * VW, d);
    }
    for (; j + VW <= n; j += VW) {
        v_store(x + j, v_act(v_load(x + j), act));
    }
    if (j < n) {
        v_store_n(x + j, v_act(v_load_n(x + j, n - j), act), n - j);
    }
}

/* The activation over a just-stored tile (still in L1). Kept out of the unrolled tile body:
 * inlining a transcendental per accumulator would multiply the code size of every tile. */
static __attribute__((noinline)) void act_tile(float *C, size_t ldc, size_t rows, size_t nb, weft_activation act)
{
    if (ldc == nb) {
        act_span(C, rows * nb, act); /* contiguous rows: one span */
        return;
    }
    for (size_t i = 0; i < rows; ++i) {
        act_span(C + i * ldc, nb, act);
    }
}

/* FULL: all NR columns of B may be read and of C written. Otherwise B and C are masked to nb. */
WEFT_INLINE void tile_body(const int ROWS, const bool FULL, size_t kc, const float *A, size_t lda, const float *B,
                           size_t ldb, float *C, size_t ldc, size_t nb, const tile_epilogue *e)
{
    V acc[WEFT_MR][WEFT_NRV];
WEFT_UNROLL
    for (int i = 0; i < ROWS; ++i) {
WEFT_UNROLL
        for (int j = 0; j < WEFT_NRV; ++j) {
            acc[i][j] = v_zero();
        }
    }
    for (size_t k = 0; k < kc; ++k) {
        V b[WEFT_NRV];
WEFT_UNROLL
        for (int j = 0; j < WEFT_NRV; ++j) {
            b[j] = FULL ? v_load(B + j * VW) : v_load_n(B + j * VW, lanes_left(nb, (size_t)j));
        }
WEFT_UNROLL
        for (int i = 0; i < ROWS; ++i) {
            const V a = v_set1(A[(size_t)i * lda + k]);
WEFT_UNROLL
            for (int j = 0; j < WEFT_NRV; ++j) {
                acc[i][j] = v_fma(a, b[j], acc[i][j]);
            }
        }
        B += ldb;
    }
WEFT_UNROLL
    for (int i = 0; i < ROWS; ++i) {
        float *c = C + (size_t)i * ldc;
WEFT_UNROLL
        for (int j = 0; j < WEFT_NRV; ++j) {
            const size_t n = FULL ? (size_t)VW : lanes_left(nb, (size_t)j);
            if (n == 0) {
                continue;
            }
            V v = acc[i][j];
            if (e->add_c) {
                v = v_add(v, FULL ? v_load(c + j * VW) : v_load_n(c + j * VW, n));
            }
            if (e->scale != 1.0f) {
                v = v_mul(v, v_set1(e->scale));
            }
            if (e->bias) {
                v = v_add(v, FULL ? v_load(e->bias + j * VW) : v_load_n(e->bias + j * VW, n));
            }
            if (FULL) {
                v_store(c + j * VW, v);
            } else {
                v_store_n(c + j * VW, v, n);
            }
        }
    }
    if (e->apply_act) {
        act_tile(C, ldc, (size_t)ROWS, nb, e->act);
    }
}

#define WEFT_DEF_TILE(R)                                                                                  \
    static void tile_##R(bool full, size_t kc, const float *A, size_t lda, const float *B, size_t ldb,   \
                         float *C, size_t ldc, size_t nb, const tile_epilogue *e)                          \
    {                                                                                                     \
        if (full) {                                                                                       \
            tile_body(R, true, kc, A, lda, B, ldb, C, ldc, nb, e);                                        \
        } else {                                                                                          \
            tile_body(R, false, kc, A, lda, B, ldb, C, ldc, nb, e);                                       \
        }                                                                                                 \
    }
WEFT_DEF_TILE(1)
WEFT_DEF_TILE(2)
WEFT_DEF_TILE(4)
#if WEFT_MR > 8
WEFT_DEF_TILE(8)
#endif
static void tile_full_rows(bool full, size_t kc, const float *A, size_t lda, const float *B, size_t ldb, float *C,
                           size_t ldc, size_t nb, const tile_epilogue *e)
{
    if (full) {
        tile_body(WEFT_MR, true, kc, A, lda, B, ldb, C, ldc, nb, e);
    } else {
        tile_body(WEFT_MR, false, kc, A, lda, B, ldb, C, ldc, nb, e);
    }
}

/* Rows [0, M) against one column block [0, nb <= NR): whole MR tiles, then the remaining rows
 * in chunks of 8 / 4 / 2 / 1 (fewer instantiations than one per row count). */
static void tile_rows(size_t M, size_t kc, const float *A, size_t lda, const float *B, size_t ldb, float *C,
                      size_t ldc, size_t nb, const tile_epilogue *e)
{
    const bool full = nb == WEFT_NR;
    size_t m = 0;
    for (; m + WEFT_MR <= M; m += WEFT_MR) {
        tile_full_rows(full, kc, A + m * lda, lda, B, ldb, C + m * ldc, ldc, nb, e);
    }
#if WEFT_MR > 8
    if (M - m >= 8) {
        tile_8(full, kc, A + m * lda, lda, B, ldb, C + m * ldc, ldc, nb, e);
        m += 8;
    }
#endif
    if (M - m >= 4) {
        tile_4(full, kc, A + m * lda, lda, B, ldb, C + m * ldc, ldc, nb, e);
        m += 4;
    }
    if (M - m >= 2) {
        tile_2(full, kc, A + m * lda, lda, B, ldb, C + m * ldc, ldc, nb, e);
        m += 2;
    }
    if (M - m >= 1) {
        tile_1(full, kc, A + m * lda, lda, B, ldb, C + m * ldc, ldc, nb, e);
    }
}

/* ---------------------------------------------------------------------------------------- */
/* GEMM                                                                                      */

/* dst[c * ldd + r] = src[r * lds + c] for r < rows, c < cols: VW x VW blocks through an
 * in-register transpose, scalar edges. */
static void transpose_block(const float *src, size_t lds, size_t rows, size_t cols, float *dst, size_t ldd)
{
    size_t r0 = 0;
    for (; r0 + VW <= rows; r0 += VW) {
        size_t c0 = 0;
        for (; c0 + VW <= cols; c0 += VW) {
            V t[VW];
WEFT_UNROLL
            for (int i = 0; i < VW; ++i) {
                t[i] = v_load(src + (r0 + (size_t)i) * lds + c0);
            }
            v_transpose(t);
WEFT_UNROLL
            for (int i = 0; i < VW; ++i) {
                v_store(dst + (c0 + (size_t)i) * ldd + r0, t[i]);
            }
        }
        for (; c0 < cols; ++c0) {
            for (size_t i = 0; i < VW; ++i) {
                dst[c0 * ldd + r0 + i] = src[(r0 + i) * lds + c0];
            }
        }
    }
    for (; r0 < rows; ++r0) {
        for (size_t c = 0; c < cols; ++c) {
            dst[c * ldd + r0] = src[r0 * lds + c];
        }
    }
}

/* Wp[k][j] = W[j][k] for j < nb (zero beyond), k < kc: one NR-wide panel of W^T. */
static void pack_panel(const float *W, size_t ldw, size_t nb, size_t kc, float *Wp)
{
    transpose_block(W, ldw, nb, kc, Wp, WEFT_NR);
    if (nb < WEFT_NR) {
        for (size_t k = 0; k < kc; ++k) {
            memset(Wp + k * WEFT_NR + nb, 0, (WEFT_NR - nb) * sizeof(float));
        }
    }
}

static float act_one(float v, weft_activation act)
{
    V x = v_set1(v);
    x = v_act(x, act);
    float out[VW];
    v_store(out, x);
    return out[0];
}

/* out[i * os] = act(dot(x, X[i]) + bias[i * bs] (+ out[i * os])) for i < count: the dot-product
 * form of GEMM for when one side has very few rows (GEMV, or a 1..4-wide output layer). GR rows
 * of X are in flight, so each x vector is loaded once per GR FMAs and X streams through once; the
 * GR partial-sum vectors are reduced VW at a time with the in-register transpose, giving VW
 * outputs in one vector for a vector epilogue. */
#define WEFT_GR (VW >= 8 ? VW : 8)
static void dot_rows(const float *x, const float *X, size_t ldx, size_t count, size_t K, float *out, size_t os,
                     const float *bias, size_t bs, weft_activation act, bool accumulate)
{
    size_t i = 0;
    for (; i + WEFT_GR <= count; i += WEFT_GR) {
        V s[WEFT_GR];
        const float *xr = X + i * ldx;
        WEFT_UNROLL
        for (int r = 0; r < WEFT_GR; ++r) {
            s[r] = v_zero();
        }
        size_t k = 0;
        for (; k + VW <= K; k += VW) {
            const V xv = v_load(x + k);
            WEFT_UNROLL
            for (int r = 0; r < WEFT_GR; ++r) {
                s[r] = v_fma(xv, v_load(xr + (size_t)r * ldx + k), s[r]);
            }
        }
        if (k < K) {
            const V xv = v_load_n(x + k, K - k);
            WEFT_UNROLL
            for (int r = 0; r < WEFT_GR; ++r) {
                s[r] = v_fma(xv, v_load_n(xr + (size_t)r * ldx + k, K - k), s[r]);
            }
        }
        WEFT_UNROLL
        for (int g = 0; g < WEFT_GR; g += VW) {
            v_transpose(s + g); /* lane j of s[g + i] <- lane i of s[g + j] */
            V y = s[g];
            WEFT_UNROLL
            for (int t = 1; t < VW; ++t) {
                y = v_add(y, s[g + t]);
            }
            const size_t o = i + (size_t)g;
            if (os == 1 && bs == 1) {
                if (bias) {
                    y = v_add(y, v_load(bias + o));
                }
                if (accumulate) {
                    y = v_add(y, v_load(out + o));
                }
                v_store(out + o, v_act(y, act));
            } else {
                /* strided output (a column of C): go through a lane buffer */
                float t[VW];
                for (size_t u = 0; u < VW; ++u) {
                    t[u] = (bias ? bias[(o + u) * bs] : 0.0f) + (accumulate ? out[(o + u) * os] : 0.0f);
                }
                y = v_act(v_add(y, v_load(t)), act);
                v_store(t, y);
                for (size_t u = 0; u < VW; ++u) {
                    out[(o + u) * os] = t[u];
                }
            }
        }
    }
    for (; i < count; ++i) {
        const float *xr = X + i * ldx;
        V sv = v_zero();
        size_t k = 0;
        for (; k + VW <= K; k += VW) {
            sv = v_fma(v_load(x + k), v_load(xr + k), sv);
        }
        if (k < K) {
            sv = v_fma(v_load_n(x + k, K - k), v_load_n(xr + k, K - k), sv);
        }
        const float y = v_hsum(sv) + (bias ? bias[i * bs] : 0.0f) + (accumulate ? out[i * os] : 0.0f);
        out[i * os] = act_one(y, act);
    }
}

/* Narrow output (N <= NP <= 4): GR / NP rows of A against all NP rows of W per pass, so A streams
 * through once. Accumulator r pairs A row r / NP with W row r % NP (rows of W past N repeat the
 * last one and their lanes are dropped); the transposed reduction yields one output per lane. */
WEFT_INLINE void narrow_body(const int NP, uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda,
                             const float *W, uint32_t ldw, const float *bias, float *C, uint32_t ldc,
                             weft_activation act, bool accumulate, uint32_t *rows_done)
{
    const int RA = WEFT_GR / NP;
    const float *wr[4];
    for (int n = 0; n < NP; ++n) {
        wr[n] = W + (size_t)((uint32_t)n < N ? (uint32_t)n : N - 1) * ldw;
    }
    uint32_t m = 0;
    for (; m + (uint32_t)RA <= M; m += (uint32_t)RA) {
        const float *ar = A + (size_t)m * lda;
        V s[WEFT_GR];
        WEFT_UNROLL
        for (int r = 0; r < WEFT_GR; ++r) {
            s[r] = v_zero();
        }
        size_t k = 0;
        for (; k + VW <= K; k += VW) {
            V wv[4];
            WEFT_UNROLL
            for (int n = 0; n < NP; ++n) {
                wv[n] = v_load(wr[n] + k);
            }
            WEFT_UNROLL
            for (int a = 0; a < RA; ++a) {
                const V av = v_load(ar + (size_t)a * lda + k);
                WEFT_UNROLL
                for (int n = 0; n < NP; ++n) {
                    s[a * NP + n] = v_fma(av, wv[n], s[a * NP + n]);
                }
            }
        }
        if (k < K) {
            V wv[4];
            WEFT_UNROLL
            for (int n = 0; n < NP; ++n) {
                wv[n] = v_load_n(wr[n] + k, K - k);
            }
            WEFT_UNROLL
            for (int a = 0; a < RA; ++a) {
                const V av = v_load_n(ar + (size_t)a * lda + k, K - k);
                WEFT_UNROLL
                for (int n = 0; n < NP; ++n) {
                    s[a * NP + n] = v_fma(av, wv[n], s[a * NP + n]);
                }
            }
        }
        WEFT_UNROLL
        for (int g = 0; g < WEFT_GR; g += VW) {
            v_transpose(s + g);
            V y = s[g];
            WEFT_UNROLL
            for (int t = 1; t < VW; ++t) {
                y = v_add(y, s[g + t]);
            }
            float t[VW];
            for (int u = 0; u < VW; ++u) {
                const int r = g + u, n = r % NP;
                const size_t at = (size_t)(m + (uint32_t)(r / NP)) * ldc + (size_t)n;
                t[u] = (uint32_t)n < N ? (bias ? bias[n] : 0.0f) + (accumulate ? C[at] : 0.0f) : 0.0f;
            }
            v_store(t, v_act(v_add(y, v_load(t)), act));
            for (int u = 0; u < VW; ++u) {
                const int r = g + u, n = r % NP;
                if ((uint32_t)n < N) {
                    C[(size_t)(m + (uint32_t)(r / NP)) * ldc + (size_t)n] = t[u];
                }
            }
        }
    }
    *rows_done = m;
}

static void gemm(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const float *W, uint32_t ldw,
                 const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    if (M == 0 || N == 0) {
        return;
    }
    if (M < 4) {
        /* GEMV: each row of A against all of W */
        for (uint32_t m = 0; m < M; ++m) {
            dot_rows(A + (size_t)m * lda, W, ldw, N, K, C + (size_t)m * ldc, 1, bias, 1, act, accumulate);
        }
        return;
    }
    if (N <= 4) {
        /* a narrow output layer: a register tile would be mostly padding, so take each row of W
         * against all of A instead (C's column n at stride ldc) */
        uint32_t done = 0;
        if (N == 1) {
            narrow_body(1, M, N, K, A, lda, W, ldw, bias, C, ldc, act, accumulate, &done);
        } else if (N == 2) {
            narrow_body(2, M, N, K, A, lda, W, ldw, bias, C, ldc, act, accumulate, &done);
        } else {
            narrow_body(4, M, N, K, A, lda, W, ldw, bias, C, ldc, act, accumulate, &done);
        }
        /* the last few rows, one dot product each */
        for (uint32_t n = 0; n < N; ++n) {
            dot_rows(W + (size_t)n * ldw, A + (size_t)done * lda, lda, M - done, K, C + (size_t)done * ldc + n, ldc,
                     bias ? bias + n : NULL, 0, act, accumulate);
        }
        return;
    }
    /* One packed panel of W^T on the stack (32 KiB on AVX-512): no allocation, and the panel is
     * reused by every row tile of A while it sits in L1/L2. */
    _Alignas(64) float wp[WEFT_KC * WEFT_NR];
    uint32_t k0 = 0;
    do {
        const size_t kc = K - k0 < WEFT_KC ? K - k0 : WEFT_KC;
        const bool first = k0 == 0, last = k0 + kc == K;
        for (uint32_t n0 = 0; n0 < N; n0 += WEFT_NR) {
            const size_t nb = N - n0 < WEFT_NR ? N - n0 : WEFT_NR;
            pack_panel(W + (size_t)n0 * ldw + k0, ldw, nb, kc, wp);
            const tile_epilogue e = {
                .bias = first && bias ? bias + n0 : NULL,
                .add_c = !first || accumulate,
                .scale = 1.0f,
                .apply_act = last && act != WEFT_ACT_NONE,
                .act = act,
            };
            tile_rows(M, kc, A + k0, lda, wp, WEFT_NR, C + n0, ldc, nb, &e);
        }
        k0 += (uint32_t)kc;
    } while (k0 < K);
}

/* ---------------------------------------------------------------------------------------- */
/* Row-wise and elementwise kernels                                                          */

/* x[j] = softmax(x) over cols entries. A row whose every entry is -inf becomes zeros. */
static void softmax_row(float *x, size_t cols)
{
    const V ninf = v_set1(-INFINITY);
    V mv = ninf;
    size_t j = 0;
    for (; j + VW <= cols; j += VW) {
        mv = v_max(mv, v_load(x + j));
    }
    if (j < cols) {
        mv = v_max(mv, v_sel(m_first(cols - j), v_load_n(x + j, cols - j), ninf));
    }
    const float mx = v_hmax(mv);
    if (mx == -INFINITY) {
        memset(x, 0, cols * sizeof *x);
        return;
    }
    const V vmx = v_set1(mx);
    V sv = v_zero();
    for (j = 0; j + VW <= cols; j += VW) {
        const V e = v_exp(v_sub(v_load(x + j), vmx));
        v_store(x + j, e);
        sv = v_add(sv, e);
    }
    if (j < cols) {
        const size_t n = cols - j;
        const V e = v_sel(m_first(n), v_exp(v_sub(v_load_n(x + j, n), vmx)), v_zero());
        v_store_n(x + j, e, n);
        sv = v_add(sv, e);
    }
    const V inv = v_set1(1.0f / v_hsum(sv));
    for (j = 0; j + VW <= cols; j += VW) {
        v_store(x + j, v_mul(v_load(x + j), inv));
    }
    if (j < cols) {
        v_store_n(x + j, v_mul(v_load_n(x + j, cols - j), inv), cols - j);
    }
}

static void softmax_rows(float *X, uint32_t rows, uint32_t cols, uint32_t ldx)
{
    for (uint32_t r = 0; r < rows; ++r) {
        softmax_row(X + (size_t)r * ldx, cols);
    }
}

/* Sum of x[0..n), two accumulators to halve the add latency chain. */
static float row_sum(const float *x, size_t n)
{
    V s0 = v_zero(), s1 = v_zero();
    size_t j = 0;
    for (; j + 2 * VW <= n; j += 2 * VW) {
        s0 = v_add(s0, v_load(x + j));
        s1 = v_add(s1, v_load(x + j + VW));
    }
    for (; j + VW <= n; j += VW) {
        s0 = v_add(s0, v_load(x + j));
    }
    if (j < n) {
        s1 = v_add(s1, v_load_n(x + j, n - j));
    }
    return v_hsum(v_add(s0, s1));
}

/* Sum of (x - c)^2 over x[0..n) (c = 0 gives the sum of squares). */
static float row_sqdev(const float *x, size_t n, float c)
{
    const V vc = v_set1(c);
    V s0 = v_zero(), s1 = v_zero();
    size_t j = 0;
    for (; j + 2 * VW <= n; j += 2 * VW) {
        const V d0 = v_sub(v_load(x + j), vc), d1 = v_sub(v_load(x + j + VW), vc);
        s0 = v_fma(d0, d0, s0);
        s1 = v_fma(d1, d1, s1);
    }
    for (; j + VW <= n; j += VW) {
        const V d = v_sub(v_load(x + j), vc);
        s0 = v_fma(d, d, s0);
    }
    if (j < n) {
        const V d = v_sel(m_first(n - j), v_sub(v_load_n(x + j, n - j), vc), v_zero());
        s1 = v_fma(d, d, s1);
    }
    return v_hsum(v_add(s0, s1));
}

/* y = (x - shift) * mul * gamma + beta (gamma/beta optional) */
static void row_affine(const float *x, float *y, size_t n, float shift, float mul, const float *gamma,
                       const float *beta)
{
    const V vs = v_set1(shift), vm = v_set1(mul);
    size_t j = 0;
    for (; j < n; j += VW) {
        const size_t c = n - j < VW ? n - j : VW;
        const bool full = c == VW;
        V v = v_mul(v_sub(full ? v_load(x + j) : v_load_n(x + j, c), vs), vm);
        if (gamma) {
            v = v_mul(v, full ? v_load(gamma + j) : v_load_n(gamma + j, c));
        }
        if (beta) {
            v = v_add(v, full ? v_load(beta + j) : v_load_n(beta + j, c));
        }
        if (full) {
            v_store(y + j, v);
        } else {
            v_store_n(y + j, v, c);
        }
    }
}

static void layernorm(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                      const float *beta, float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        const float mean = row_sum(x, cols) / (float)cols;
        const float var = row_sqdev(x, cols, mean) / (float)cols;
        row_affine(x, Y + (size_t)r * ld, cols, mean, 1.0f / sqrtf(var + eps), gamma, beta);
    }
}

static void rmsnorm(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                    float eps)
{
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = X + (size_t)r * ld;
        const float ms = row_sqdev(x, cols, 0.0f) / (float)cols;
        row_affine(x, Y + (size_t)r * ld, cols, 0.0f, 1.0f / sqrtf(ms + eps), gamma, NULL);
    }
}

static void gelu(float *x, size_t n) { act_span(x, n, WEFT_ACT_GELU); }

static void silu(float *x, size_t n) { act_span(x, n, WEFT_ACT_SILU); }

static void swiglu(const float *gate, const float *up, float *out, size_t n)
{
    size_t i = 0;
    for (; i + VW <= n; i += VW) {
        v_store(out + i, v_mul(v_silu(v_load(gate + i)), v_load(up + i)));
    }
    if (i < n) {
        const size_t c = n - i;
        v_store_n(out + i, v_mul(v_silu(v_load_n(gate + i, c)), v_load_n(up + i, c)), c);
    }
}

/* ---------------------------------------------------------------------------------------- */
/* Sinusoidal embedding                                                                      */

static void posembed(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq, float *out,
                     uint32_t ldo)
{
    enum { CH = 64 }; /* arguments per chunk; a multiple of every VW */
    _Alignas(64) float arg[CH], sn[CH], cs[CH];
    const size_t per_point = (size_t)dims * nfreq;
    for (uint32_t i = 0; i < n; ++i) {
        const float *xi = x + (size_t)i * dims;
        float *o = out + (size_t)i * ldo;
        for (size_t a0 = 0; a0 < per_point; a0 += CH) {
            const size_t cnt = per_point - a0 < CH ? per_point - a0 : CH;
            for (size_t t = 0; t < cnt; ++t) {
                const size_t a = a0 + t;
                arg[t] = xi[a / nfreq] * freq[a % nfreq];
            }
            for (size_t t = 0; t < cnt; t += VW) {
                const size_t c = cnt - t < VW ? cnt - t : VW;
                const V v = v_load_n(arg + t, c);
                V s, co;
                if (v_hmax(v_abs(v)) <= 8192.0f) {
                    v_sincos(v, &s, &co);
                    v_store(sn + t, s);
                    v_store(cs + t, co);
                } else {
                    for (size_t u = t; u < t + c; ++u) {
                        sn[u] = sinf(arg[u]);
                        cs[u] = cosf(arg[u]);
                    }
                }
            }
            float *oo = o + a0 * 2;
            for (size_t t = 0; t < cnt; ++t) {
                oo[2 * t] = sn[t];
                oo[2 * t + 1] = cs[t];
            }
        }
    }
}

/* ---------------------------------------------------------------------------------------- */
/* CSR aggregation                                                                           */

static void csr_aggregate(const uint32_t *rowptr, const uint32_t *col, uint32_t rows, const float *X, uint32_t ldx,
                          uint32_t dim, float *out, uint32_t ldo, bool mean)
{
    enum { BV = 8 }; /* vectors of one row kept in registers across all neighbours */
    for (uint32_t r = 0; r < rows; ++r) {
        const uint32_t b = rowptr[r], e = rowptr[r + 1];
        const V scale = v_set1(mean && e > b ? 1.0f / (float)(e - b) : 1.0f);
        float *o = out + (size_t)r * ldo;
        size_t j = 0;
        for (; j + BV * VW <= dim; j += BV * VW) {
            V acc[BV];
WEFT_UNROLL
            for (int v = 0; v < BV; ++v) {
                acc[v] = v_zero();
            }
            for (uint32_t p = b; p < e; ++p) {
                const float *xr = X + (size_t)col[p] * ldx + j;
WEFT_UNROLL
                for (int v = 0; v < BV; ++v) {
                    acc[v] = v_add(acc[v], v_load(xr + v * VW));
                }
            }
WEFT_UNROLL
            for (int v = 0; v < BV; ++v) {
                v_store(o + j + v * VW, v_mul(acc[v], scale));
            }
        }
        for (; j < dim; j += VW) {
            const size_t c = dim - j < VW ? dim - j : VW;
            V acc = v_zero();
            for (uint32_t p = b; p < e; ++p) {
                acc = v_add(acc, v_load_n(X + (size_t)col[p] * ldx + j, c));
            }
            v_store_n(o + j, v_mul(acc, scale), c);
        }
    }
}

/* ---------------------------------------------------------------------------------------- */
/* Attention                                                                                 */

/* Kt[d][k] = K[k][d] for d < dc, k < nk; columns nk..nkp are zero. */
static void transpose_keys(const float *K, size_t ldk, size_t nk, size_t dc, float *Kt, size_t nkp)
{
    for (size_t d = 0; d < dc; ++d) {
        memset(Kt + d * nkp + nk, 0, (nkp - nk) * sizeof(float));
    }
    transpose_block(K, ldk, nk, dc, Kt, nkp);
}

/* One row of one key block of the online softmax. s holds scaled scores for kc keys, to which
 * bias (may be NULL) is added; on return it holds exp(s - m_new) (0 where masked). m and l are the
 * row's running max and sum; returns the factor the row's earlier output must be multiplied by. */
static float online_softmax_row(float *s, size_t kc, const uint8_t *mask, const float *bias, float *m, float *l)
{
    const V ninf = v_set1(-INFINITY);
    if (bias) {
        for (size_t j = 0; j < kc; ++j) {
            s[j] += bias[j];
        }
    }
    if (mask) {
        for (size_t j = 0; j < kc; ++j) {
            s[j] = mask[j] ? s[j] : -INFINITY;
        }
    }
    V mv = ninf;
    size_t j = 0;
    for (; j + VW <= kc; j += VW) {
        mv = v_max(mv, v_load(s + j));
    }
    if (j < kc) {
        mv = v_max(mv, v_sel(m_first(kc - j), v_load_n(s + j, kc - j), ninf));
    }
    const float m_old = *m, bm = v_hmax(mv);
    const float m_new = bm > m_old ? bm : m_old;
    if (m_new == -INFINITY) {
        /* nothing visible yet in this row: contributes nothing */
        memset(s, 0, kc * sizeof *s);
        return 1.0f;
    }
    const V vm = v_set1(m_new);
    V sum = v_zero();
    for (j = 0; j + VW <= kc; j += VW) {
        const V e = v_exp(v_sub(v_load(s + j), vm));
        v_store(s + j, e);
        sum = v_add(sum, e);
    }
    if (j < kc) {
        const size_t n = kc - j;
        const V e = v_sel(m_first(n), v_exp(v_sub(v_load_n(s + j, n), vm)), v_zero());
        v_store_n(s + j, e, n);
        sum = v_add(sum, e);
    }
    const float alpha = m_old == -INFINITY ? 0.0f : expf(m_old - m_new);
    *l = *l * alpha + v_hsum(sum);
    *m = m_new;
    return alpha;
}

static void scale_row(float *x, size_t n, float f)
{
    const V vf = v_set1(f);
    size_t j = 0;
    for (; j + VW <= n; j += VW) {
        v_store(x + j, v_mul(v_load(x + j), vf));
    }
    if (j < n) {
        v_store_n(x + j, v_mul(v_load_n(x + j, n - j), vf), n - j);
    }
}

/* Per head: keys transposed once; then per block of queries, per block of keys: S = Q K^T on
 * register tiles, online softmax, O (+)= P V on register tiles straight into `out`; finally each
 * row is divided by its softmax sum. Memory use is independent of nk beyond the transposed keys. */
static void attention(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *Vv, uint32_t ldv,
                      uint32_t nq, uint32_t nk, uint32_t heads, uint32_t dh, float scale, const uint8_t *mask,
                      const float *key_bias, float *out, uint32_t ldo, float *scratch)
{
    if (nq == 0 || heads == 0 || dh == 0) {
        return;
    }
    if (nk == 0) {
        for (uint32_t q = 0; q < nq; ++q) {
            memset(out + (size_t)q * ldo, 0, (size_t)heads * dh * sizeof(float));
        }
        return;
    }
    const size_t nkp = weft__attn_pad(nk), kbp = weft__attn_kbp(nk), qb = weft__attn_qb(nq);
    float *S = scratch;
    float *row_m = S + qb * kbp;
    float *row_l = row_m + qb;
    float *Kt = row_l + qb;
    const bool kt_per_head = dh <= WEFT__ATTN_DB; /* one chunk: transpose once per head */
    const tile_epilogue plain = {.bias = NULL, .add_c = false, .scale = 1.0f, .apply_act = false};
    const tile_epilogue accum = {.bias = NULL, .add_c = true, .scale = 1.0f, .apply_act = false};
    /* scores: the scale is applied once the last chunk of dh is in */
    const tile_epilogue score_only = {.bias = NULL, .add_c = false, .scale = scale, .apply_act = false};
    const tile_epilogue score_last = {.bias = NULL, .add_c = true, .scale = scale, .apply_act = false};

    for (uint32_t h = 0; h < heads; ++h) {
        const size_t off = (size_t)h * dh;
        if (kt_per_head) {
            transpose_keys(K + off, ldk, nk, dh, Kt, nkp);
        }
        for (uint32_t q0 = 0; q0 < nq; q0 += (uint32_t)qb) {
            const size_t rows = nq - q0 < qb ? nq - q0 : qb;
            const float *Qb = Q + (size_t)q0 * ldq + off;
            float *Ob = out + (size_t)q0 * ldo + off;
            for (size_t r = 0; r < rows; ++r) {
                row_m[r] = -INFINITY;
                row_l[r] = 0.0f;
            }
            for (size_t k0 = 0; k0 < nk; k0 += WEFT__ATTN_KB) {
                const size_t kc = nk - k0 < WEFT__ATTN_KB ? nk - k0 : WEFT__ATTN_KB;
                const size_t kcp = (kc + 15u) & ~(size_t)15u; /* within the zero-padded Kt row */
                /* S = Q_blk . K_blk^T, accumulated over chunks of dh */
                for (size_t d0 = 0; d0 < dh; d0 += WEFT__ATTN_DB) {
                    const size_t dc = dh - d0 < WEFT__ATTN_DB ? dh - d0 : WEFT__ATTN_DB;
                    if (!kt_per_head) {
                        transpose_keys(K + off + d0, ldk, nk, dc, Kt, nkp);
                    }
                    for (size_t n0 = 0; n0 < kcp; n0 += WEFT_NR) {
                        const size_t nb = kcp - n0 < WEFT_NR ? kcp - n0 : WEFT_NR;
                        const bool last = d0 + dc == dh;
                        const tile_epilogue *e = d0 ? (last ? &score_last : &accum) : (last ? &score_only : &plain);
                        tile_rows(rows, dc, Qb + d0, ldq, Kt + k0 + n0, nkp, S + n0, kbp, nb, e);
                    }
                }
                for (size_t r = 0; r < rows; ++r) {
                    const float alpha = online_softmax_row(
                        S + r * kbp, kc, mask ? mask + (size_t)(q0 + r) * nk + k0 : NULL,
                        key_bias ? key_bias + k0 : NULL, &row_m[r], &row_l[r]);
                    if (k0 > 0 && alpha != 1.0f) {
                        scale_row(Ob + r * ldo, dh, alpha);
                    }
                }
                /* O_blk (+)= P . V_blk */
                for (size_t n0 = 0; n0 < dh; n0 += WEFT_NR) {
                    const size_t nb = dh - n0 < WEFT_NR ? dh - n0 : WEFT_NR;
                    tile_rows(rows, kc, S, kbp, Vv + k0 * ldv + off + n0, ldv, Ob + n0, ldo, nb,
                              k0 ? &accum : &plain);
                }
            }
            for (size_t r = 0; r < rows; ++r) {
                /* a row with every key masked has l = 0 and already holds zeros */
                if (row_l[r] > 0.0f) {
                    scale_row(Ob + r * ldo, dh, 1.0f / row_l[r]);
                }
            }
        }
    }
}

const weft_kernels WEFT_KTABLE = {
#if defined(WEFT_KTABLE_ISA)
    .isa = WEFT_KTABLE_ISA,
#else
    .isa = WEFT_ISA_SCALAR,
#endif
    .gemm = gemm,
    .softmax_rows = softmax_rows,
    .layernorm = layernorm,
    .rmsnorm = rmsnorm,
    .gelu = gelu,
    .silu = silu,
    .swiglu = swiglu,
    .posembed = posembed,
    .csr_aggregate = csr_aggregate,
    .attention = attention,
};
