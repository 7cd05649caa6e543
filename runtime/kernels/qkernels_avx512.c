/* AVX-512 twin of the int8 / fp16 / deterministic kernels: vpdpbusd (AVX512-VNNI) on 16
 * channels x 4 k per instruction. */
#include "kernels/simd_avx512.h"

#include "kernels/qkernels.h"

#include <stdint.h>
#include <string.h>

static inline V v_load_h(const uint16_t *p) { return _mm512_cvtph_ps(_mm256_loadu_si256((const __m256i *)p)); }
static inline V v_load_h_n(const uint16_t *p, size_t n)
{
    return _mm512_cvtph_ps(_mm256_maskz_loadu_epi16((__mmask16)m_first(n), p));
}

/* Register tile: 6 rows x up to 3 blocks (48 channels, 18 zmm accumulators), so each broadcast
 * activation word feeds up to three vpdpbusd and the narrow model layers (48 or 96 outputs) run
 * without idle blocks. The weights' sign bit is flipped in registers (w + 128, unsigned) and the
 * activations are the signed, broadcast operand; the 128 * sum(a) this adds is subtracted per
 * row. Integer arithmetic throughout: the result is exact, as in every other variant. */
#define QK_Q8_MR 6 /* Q8_TILE_NB names rows 0..5 */
#define QK_Q8_NB 3

static inline int32_t q8_rowsum(const int8_t *a, uint32_t Kp)
{
    const __m512i ones = _mm512_set1_epi8(1);
    __m512i s = _mm512_setzero_si512();
    for (uint32_t k = 0; k < Kp; k += 64) {
        const uint32_t n = Kp - k < 64 ? Kp - k : 64;
        const __mmask64 m = n == 64 ? ~(__mmask64)0 : (((__mmask64)1 << n) - 1);
        s = _mm512_dpbusd_epi32(s, ones, _mm512_maskz_loadu_epi8(m, a + k));
    }
    return _mm512_reduce_add_epi32(s);
}

/* c += dot(w as unsigned bytes, x as signed bytes) per 32-bit lane. gcc 12 at -O3 copies every
 * loop-carried vpdpbusd accumulator twice per k group (and spills some) when the intrinsic is
 * used here, which costs more than the dot products; the one-instruction statement keeps the
 * accumulators in place. Other compilers get the intrinsic. */
#if defined(__GNUC__) && !defined(__clang__)
#define Q8_DP(c, w, x) __asm__("vpdpbusd %2, %1, %0" : "+v"(c) : "v"(w), "v"(x))
#else
#define Q8_DP(c, w, x) ((c) = _mm512_dpbusd_epi32((c), (w), (x)))
#endif

/* Accumulators are named variables, not arrays, so they can live in registers. Unused blocks
 * (NB < 3) fold away. */
#define Q8_ROW(r)                                                                                       \
    {                                                                                                   \
        int32_t x;                                                                                      \
        memcpy(&x, a[r] + 4 * g, 4);                                                                    \
        const __m512i xb = _mm512_set1_epi32(x);                                                        \
        Q8_DP(c##r##0, w0, xb);                                                                         \
        if (nblk > 1) {                                                                                 \
            Q8_DP(c##r##1, w1, xb);                                                                     \
        }                                                                                               \
        if (nblk > 2) {                                                                                 \
            Q8_DP(c##r##2, w2, xb);                                                                     \
        }                                                                                               \
    }
/* Raw sums go to memory first and are corrected in a second loop: with the correction applied
 * straight from the accumulators gcc 12 copies every accumulator twice per k group. */
#define Q8_OUT(r)                                                                                       \
    {                                                                                                   \
        _mm512_storeu_si512((void *)out[r], c##r##0);                                                   \
        if (nblk > 1) {                                                                                 \
            _mm512_storeu_si512((void *)(out[r] + 16), c##r##1);                                        \
        }                                                                                               \
        if (nblk > 2) {                                                                                 \
            _mm512_storeu_si512((void *)(out[r] + 32), c##r##2);                                        \
        }                                                                                               \
    }
#define Q8_TILE_NB(NB)                                                                                  \
    static inline void q8_tile_##NB(const int8_t *const *a, const int8_t *block, uint32_t Kp, uint32_t kgroups, \
                                    const int32_t *rsum, float out[QK_Q8_MR][QK_Q8_NB * 16])             \
    {                                                                                                   \
        const int nblk = (NB);                                                                          \
        const __m512i flip = _mm512_set1_epi8((char)0x80), z = _mm512_setzero_si512();                  \
        __m512i c00 = z, c01 = z, c02 = z, c10 = z, c11 = z, c12 = z, c20 = z, c21 = z, c22 = z;        \
        __m512i c30 = z, c31 = z, c32 = z, c40 = z, c41 = z, c42 = z, c50 = z, c51 = z, c52 = z;        \
        const int8_t *b1 = block + (size_t)Kp * 16 * (nblk > 1), *b2 = block + (size_t)Kp * 32 * (nblk > 2); \
        for (uint32_t g = 0; g < kgroups; ++g) {                                                        \
            const __m512i w0 = _mm512_xor_si512(_mm512_loadu_si512((const void *)(block + (size_t)g * 64)), flip); \
            const __m512i w1 = _mm512_xor_si512(_mm512_loadu_si512((const void *)(b1 + (size_t)g * 64)), flip); \
            const __m512i w2 = _mm512_xor_si512(_mm512_loadu_si512((const void *)(b2 + (size_t)g * 64)), flip); \
            Q8_ROW(0) Q8_ROW(1) Q8_ROW(2) Q8_ROW(3) Q8_ROW(4) Q8_ROW(5)                                 \
        }                                                                                               \
        Q8_OUT(0) Q8_OUT(1) Q8_OUT(2) Q8_OUT(3) Q8_OUT(4) Q8_OUT(5)                                     \
        for (int r = 0; r < QK_Q8_MR; ++r) {                                                            \
            const __m512i k = _mm512_set1_epi32(rsum[r] * 128);                                         \
            for (int b = 0; b < nblk; ++b) {                                                            \
                float *o = out[r] + 16 * b;                                                             \
                _mm512_storeu_ps(o, _mm512_cvtepi32_ps(_mm512_sub_epi32(_mm512_loadu_si512((const void *)o), k))); \
            }                                                                                           \
        }                                                                                               \
    }

Q8_TILE_NB(1)
Q8_TILE_NB(2)
Q8_TILE_NB(3)

/* Row sums depend on the rows only: computed once per row tile by the body (q8_rowsums) and
 * reused for every block of channels. */
#define QK_Q8_ROWSUM 1
static inline void q8_rowsums(const int8_t *Q, uint32_t ldq, uint32_t rows, uint32_t Kp, int32_t *rsum)
{
    for (uint32_t r = 0; r < rows; ++r) {
        rsum[r] = q8_rowsum(Q + (size_t)r * ldq, Kp);
    }
}

static inline void q8_tile(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t nblocks,
                           uint32_t Kp, uint32_t kgroups, const int32_t *rsum, float out[QK_Q8_MR][QK_Q8_NB * 16])
{
    const int8_t *a[QK_Q8_MR];
    int32_t rs[QK_Q8_MR];
    for (uint32_t r = 0; r < QK_Q8_MR; ++r) {
        a[r] = Q + (size_t)(r < rows ? r : 0) * ldq; /* missing rows repeat row 0; results unused */
        rs[r] = rsum[r < rows ? r : 0];
    }
    if (nblocks == 3) {
        q8_tile_3(a, block, Kp, kgroups, rs, out);
    } else if (nblocks == 2) {
        q8_tile_2(a, block, Kp, kgroups, rs, out);
    } else {
        q8_tile_1(a, block, Kp, kgroups, rs, out);
    }
}

/* The canonical tree over the 16 partial sums (t[j] += t[j + w], w = 8, 4, 2, 1) in registers. */
#define QK_HAVE_TREE16 1
static inline float qk_tree16_v(const V *acc)
{
    V t = _mm512_add_ps(acc[0], _mm512_shuffle_f32x4(acc[0], acc[0], _MM_SHUFFLE(1, 0, 3, 2)));
    t = _mm512_add_ps(t, _mm512_shuffle_f32x4(t, t, _MM_SHUFFLE(2, 3, 0, 1)));
    t = _mm512_add_ps(t, _mm512_permute_ps(t, _MM_SHUFFLE(1, 0, 3, 2)));
    t = _mm512_add_ps(t, _mm512_permute_ps(t, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm512_cvtss_f32(t);
}

/* posembed with packed rows (ldo = 2 dims nfreq, as for the collider's triangle corners): lane t
 * of the flattened argument list gets x[t / nfreq] * freq[t % nfreq] by two in-register
 * permutes, and sin/cos are interleaved in registers, so nothing goes through memory. */
#define QK_HAVE_POSEMBED_PACKED 1
static inline V qk_posembed_args(const float *x, size_t nx, const float *freq, uint32_t nfreq, size_t t0)
{
    const __m512 iota = _mm512_set_ps(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
    const size_t c0 = t0 / nfreq; /* first coordinate this vector touches; it spans at most 16 */
    const __m512 xv = _mm512_maskz_loadu_ps(m_first(nx - c0), x + c0);
    const __m512 fv = _mm512_maskz_loadu_ps(m_first(nfreq), freq);
    const __m512 t = _mm512_add_ps(_mm512_set1_ps((float)t0), iota); /* exact: t0 < 2^22 */
    const __m512 nf = _mm512_set1_ps((float)nfreq);
    /* (t + 0.5) / nfreq is at least 0.5 / nfreq from an integer, far beyond the division's error */
    const __m512 q = _mm512_roundscale_ps(_mm512_div_ps(_mm512_add_ps(t, _mm512_set1_ps(0.5f)), nf),
                                          _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
    const __m512i xi = _mm512_cvtps_epi32(_mm512_sub_ps(q, _mm512_set1_ps((float)c0)));
    const __m512i fi = _mm512_cvtps_epi32(_mm512_fnmadd_ps(q, nf, t));
    return _mm512_mul_ps(_mm512_permutexvar_ps(xi, xv), _mm512_permutexvar_ps(fi, fv));
}

/* out[2 j] = s[j], out[2 j + 1] = c[j] for j < n (n <= 16). */
static inline void qk_store_sincos(float *out, V s, V c, size_t n)
{
    const __m512i lo = _mm512_set_epi32(23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1, 16, 0);
    const __m512i hi = _mm512_set_epi32(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8);
    const size_t f = 2 * n;
    _mm512_mask_storeu_ps(out, m_first(f), _mm512_permutex2var_ps(s, lo, c));
    if (f > 16) {
        _mm512_mask_storeu_ps(out + 16, m_first(f - 16), _mm512_permutex2var_ps(s, hi, c));
    }
}

/* Integral values in [-127, 127] to int8, n <= 16 lanes. */
#define QK_HAVE_STORE_I8 1
static inline void qk_store_i8(int8_t *q, V v, size_t n)
{
    _mm_mask_storeu_epi8(q, (__mmask16)m_first(n), _mm512_cvtepi32_epi8(_mm512_cvtps_epi32(v)));
}

#define QK_TABLE weft__qkernels_avx512
#define QK_ISA WEFT_ISA_AVX512
#define QK_VARIANT "avx512-vnni"
#define QK_ATT_ACC 24 /* 32 vector registers */
#define QK_ATT_WIDE /* attention_det: blocks of 32 queries (two vectors) when a call has more than 16 */
#include "kernels/qkernels_body.h"
