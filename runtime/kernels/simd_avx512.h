/* AVX-512 vector layer for kernels_body.h: 16 fp32 lanes, opmask tails. */
#ifndef WEFT_SIMD_AVX512_H
#define WEFT_SIMD_AVX512_H

#include <immintrin.h>
#include <stddef.h>

typedef __m512 V;
typedef __mmask16 VM;
#define VW 16
/* GEMM register tile: 12 rows x 2 vectors = 24 of the 32 zmm as accumulators. */
#define WEFT_MR 12
#define WEFT_NRV 2

static inline V v_zero(void) { return _mm512_setzero_ps(); }
static inline V v_set1(float x) { return _mm512_set1_ps(x); }
static inline V v_load(const float *p) { return _mm512_loadu_ps(p); }
static inline void v_store(float *p, V v) { _mm512_storeu_ps(p, v); }
static inline VM m_first(size_t n) { return n >= VW ? (VM)0xffffu : (VM)((1u << n) - 1u); }
/* Lanes >= n read as zero and are never touched in memory. */
static inline V v_load_n(const float *p, size_t n) { return _mm512_maskz_loadu_ps(m_first(n), p); }
static inline void v_store_n(float *p, V v, size_t n) { _mm512_mask_storeu_ps(p, m_first(n), v); }
static inline V v_add(V a, V b) { return _mm512_add_ps(a, b); }
static inline V v_sub(V a, V b) { return _mm512_sub_ps(a, b); }
static inline V v_mul(V a, V b) { return _mm512_mul_ps(a, b); }
static inline V v_div(V a, V b) { return _mm512_div_ps(a, b); }
/* 1/x: 14-bit estimate plus one Newton step (about 2^-28 relative), far cheaper than a divide. */
static inline V v_rcp(V x)
{
    const V r = _mm512_rcp14_ps(x);
    return _mm512_fmadd_ps(r, _mm512_fnmadd_ps(x, r, _mm512_set1_ps(1.0f)), r);
}
static inline V v_fma(V a, V b, V c) { return _mm512_fmadd_ps(a, b, c); } /* a*b + c */
static inline V v_max(V a, V b) { return _mm512_max_ps(a, b); }
static inline V v_min(V a, V b) { return _mm512_min_ps(a, b); }
static inline V v_abs(V a) { return _mm512_abs_ps(a); }
static inline V v_neg(V a) { return _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a), _mm512_set1_epi32((int)0x80000000u))); }
static inline V v_round(V a) { return _mm512_roundscale_ps(a, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC); }
static inline V v_floor(V a) { return _mm512_roundscale_ps(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
/* 2^n for integer-valued n in [-126, 127]. */
static inline V v_pow2i(V n)
{
    __m512i e = _mm512_add_epi32(_mm512_cvtps_epi32(n), _mm512_set1_epi32(127));
    return _mm512_castsi512_ps(_mm512_slli_epi32(e, 23));
}
static inline VM m_lt(V a, V b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
static inline VM m_eq(V a, V b) { return _mm512_cmp_ps_mask(a, b, _CMP_EQ_OQ); }
static inline VM m_or(VM a, VM b) { return (VM)(a | b); }
static inline V v_sel(VM m, V if_true, V if_false) { return _mm512_mask_blend_ps(m, if_false, if_true); }
static inline float v_hsum(V a) { return _mm512_reduce_add_ps(a); }
static inline float v_hmax(V a) { return _mm512_reduce_max_ps(a); }

/* In-register 16x16 transpose: r[i] lane j <- r[j] lane i. Pairs, then quads (as doubles), then
 * 128-bit lanes in two shuffle rounds. */
static inline void v_transpose(V r[VW])
{
    V t[16], u[16];
    for (int i = 0; i < 8; ++i) {
        t[2 * i] = _mm512_unpacklo_ps(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm512_unpackhi_ps(r[2 * i], r[2 * i + 1]);
    }
    for (int g = 0; g < 4; ++g) {
        const __m512d a = _mm512_castps_pd(t[4 * g]), b = _mm512_castps_pd(t[4 * g + 1]);
        const __m512d c = _mm512_castps_pd(t[4 * g + 2]), d = _mm512_castps_pd(t[4 * g + 3]);
        u[4 * g + 0] = _mm512_castpd_ps(_mm512_unpacklo_pd(a, c));
        u[4 * g + 1] = _mm512_castpd_ps(_mm512_unpackhi_pd(a, c));
        u[4 * g + 2] = _mm512_castpd_ps(_mm512_unpacklo_pd(b, d));
        u[4 * g + 3] = _mm512_castpd_ps(_mm512_unpackhi_pd(b, d));
    }
    /* u[4g + c] lane L holds rows 4g..4g+3 of column 4L + c */
    for (int c = 0; c < 4; ++c) {
        const V b0 = _mm512_shuffle_f32x4(u[c], u[4 + c], 0x88), b1 = _mm512_shuffle_f32x4(u[c], u[4 + c], 0xdd);
        const V b2 = _mm512_shuffle_f32x4(u[8 + c], u[12 + c], 0x88), b3 = _mm512_shuffle_f32x4(u[8 + c], u[12 + c], 0xdd);
        r[c] = _mm512_shuffle_f32x4(b0, b2, 0x88);
        r[8 + c] = _mm512_shuffle_f32x4(b0, b2, 0xdd);
        r[4 + c] = _mm512_shuffle_f32x4(b1, b3, 0x88);
        r[12 + c] = _mm512_shuffle_f32x4(b1, b3, 0xdd);
    }
}

#endif
