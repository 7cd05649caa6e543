/* AVX2 + FMA vector layer for kernels_body.h: 8 fp32 lanes, maskload/maskstore tails. */
#ifndef WEFT_SIMD_AVX2_H
#define WEFT_SIMD_AVX2_H

#include <immintrin.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef __m256 V;
typedef __m256 VM; /* all-ones / all-zeros lanes */
#define VW 8
/* GEMM register tile: 6 rows x 2 vectors = 12 of the 16 ymm as accumulators. */
#define WEFT_MR 6
#define WEFT_NRV 2

static inline V v_zero(void) { return _mm256_setzero_ps(); }
static inline V v_set1(float x) { return _mm256_set1_ps(x); }
static inline V v_load(const float *p) { return _mm256_loadu_ps(p); }
static inline void v_store(float *p, V v) { _mm256_storeu_ps(p, v); }
static inline __m256i m_first_i(size_t n)
{
    const int c = n >= VW ? VW : (int)n;
    return _mm256_cmpgt_epi32(_mm256_set1_epi32(c), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}
static inline VM m_first(size_t n) { return _mm256_castsi256_ps(m_first_i(n)); }
/* Lanes >= n read as zero; masked lanes never fault. */
static inline V v_load_n(const float *p, size_t n) { return _mm256_maskload_ps(p, m_first_i(n)); }
static inline void v_store_n(float *p, V v, size_t n) { _mm256_maskstore_ps(p, m_first_i(n), v); }
static inline V v_add(V a, V b) { return _mm256_add_ps(a, b); }
static inline V v_sub(V a, V b) { return _mm256_sub_ps(a, b); }
static inline V v_mul(V a, V b) { return _mm256_mul_ps(a, b); }
static inline V v_div(V a, V b) { return _mm256_div_ps(a, b); }
/* 1/x: 12-bit estimate plus two Newton steps (about 1 ulp), cheaper than a divide. */
static inline V v_rcp(V x)
{
    const V one = _mm256_set1_ps(1.0f);
    V r = _mm256_rcp_ps(x);
    r = _mm256_fmadd_ps(r, _mm256_fnmadd_ps(x, r, one), r);
    return _mm256_fmadd_ps(r, _mm256_fnmadd_ps(x, r, one), r);
}
static inline V v_fma(V a, V b, V c) { return _mm256_fmadd_ps(a, b, c); }
static inline V v_max(V a, V b) { return _mm256_max_ps(a, b); }
static inline V v_min(V a, V b) { return _mm256_min_ps(a, b); }
static inline V v_abs(V a) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
static inline V v_neg(V a) { return _mm256_xor_ps(a, _mm256_set1_ps(-0.0f)); }
static inline V v_round(V a) { return _mm256_round_ps(a, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC); }
static inline V v_floor(V a) { return _mm256_round_ps(a, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC); }
static inline V v_pow2i(V n)
{
    __m256i e = _mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127));
    return _mm256_castsi256_ps(_mm256_slli_epi32(e, 23));
}
static inline VM m_lt(V a, V b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
static inline VM m_eq(V a, V b) { return _mm256_cmp_ps(a, b, _CMP_EQ_OQ); }
static inline VM m_or(VM a, VM b) { return _mm256_or_ps(a, b); }
static inline V v_sel(VM m, V if_true, V if_false) { return _mm256_blendv_ps(if_false, if_true, m); }
static inline float v_hsum(V a)
{
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    s = _mm_add_ss(s, _mm_movehdup_ps(s));
    return _mm_cvtss_f32(s);
}
static inline float v_hmax(V a)
{
    __m128 s = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
    s = _mm_max_ps(s, _mm_movehl_ps(s, s));
    s = _mm_max_ss(s, _mm_movehdup_ps(s));
    return _mm_cvtss_f32(s);
}

/* In-register 8x8 transpose: r[i] lane j <- r[j] lane i. */
static inline void v_transpose(V r[VW])
{
    V t[8], u[8];
    for (int i = 0; i < 4; ++i) {
        t[2 * i] = _mm256_unpacklo_ps(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm256_unpackhi_ps(r[2 * i], r[2 * i + 1]);
    }
    for (int g = 0; g < 2; ++g) {
        u[4 * g + 0] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], 0x44);
        u[4 * g + 1] = _mm256_shuffle_ps(t[4 * g], t[4 * g + 2], 0xee);
        u[4 * g + 2] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], 0x44);
        u[4 * g + 3] = _mm256_shuffle_ps(t[4 * g + 1], t[4 * g + 3], 0xee);
    }
    for (int c = 0; c < 4; ++c) {
        r[c] = _mm256_permute2f128_ps(u[c], u[4 + c], 0x20);
        r[4 + c] = _mm256_permute2f128_ps(u[c], u[4 + c], 0x31);
    }
}

/* Integral values in [-127, 127] to int8, n <= 8 lanes (the int8 kernels' activation store; the
 * same bytes as converting lane by lane). */
#define QK_HAVE_STORE_I8 1
static inline void qk_store_i8(int8_t *q, V v, size_t n)
{
    const __m256i w = _mm256_cvtps_epi32(v);
    const __m128i h = _mm_packs_epi32(_mm256_castsi256_si128(w), _mm256_extracti128_si256(w, 1));
    const __m128i b = _mm_packs_epi16(h, h);
    if (n >= 8) {
        _mm_storel_epi64((__m128i *)q, b);
    } else {
        int8_t t[16];
        _mm_storeu_si128((__m128i *)t, b);
        memcpy(q, t, n);
    }
}

#endif
