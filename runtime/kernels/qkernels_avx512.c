/* AVX-512 twin of the int8 / fp16 / deterministic kernels: vpdpbusd (AVX512-VNNI) on 16
 * channels x 4 k per instruction. The activations' sign bit is flipped to make them unsigned
 * (a + 128); the 128 * sum(w) this adds is subtracted once per output. */
#include "kernels/simd_avx512.h"

#include "kernels/qkernels.h"

#include <stdint.h>
#include <string.h>

static inline V v_load_h(const uint16_t *p) { return _mm512_cvtph_ps(_mm256_loadu_si256((const __m256i *)p)); }
static inline V v_load_h_n(const uint16_t *p, size_t n)
{
    return _mm512_cvtph_ps(_mm256_maskz_loadu_epi16((__mmask16)m_first(n), p));
}

/* 4 rows x 32 channels (two blocks): 8 accumulators, each broadcast feeds two vpdpbusd. */
static inline void q8_tile(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t nblocks,
                           uint32_t Kp, uint32_t kgroups, const int32_t *wsum, float out[4][32])
{
    const int8_t *a[4];
    for (uint32_t r = 0; r < 4; ++r) {
        a[r] = Q + (size_t)(r < rows ? r : 0) * ldq; /* missing rows repeat row 0; results unused */
    }
    const int8_t *b1 = nblocks > 1 ? block + (size_t)Kp * 16 : block; /* one block: computed twice */
    const __m512i flip = _mm512_set1_epi8((char)0x80);
    __m512i c00 = _mm512_setzero_si512(), c01 = c00, c10 = c00, c11 = c00, c20 = c00, c21 = c00, c30 = c00,
            c31 = c00;
    for (uint32_t g = 0; g < kgroups; ++g) {
        __m512i w0 = _mm512_loadu_si512((const void *)(block + (size_t)g * 64));
        __m512i w1 = _mm512_loadu_si512((const void *)(b1 + (size_t)g * 64));
        int32_t x0, x1, x2, x3;
        memcpy(&x0, a[0] + 4 * g, 4);
        memcpy(&x1, a[1] + 4 * g, 4);
        memcpy(&x2, a[2] + 4 * g, 4);
        memcpy(&x3, a[3] + 4 * g, 4);
        __m512i u0 = _mm512_xor_si512(_mm512_set1_epi32(x0), flip);
        __m512i u1 = _mm512_xor_si512(_mm512_set1_epi32(x1), flip);
        __m512i u2 = _mm512_xor_si512(_mm512_set1_epi32(x2), flip);
        __m512i u3 = _mm512_xor_si512(_mm512_set1_epi32(x3), flip);
        c00 = _mm512_dpbusd_epi32(c00, u0, w0);
        c01 = _mm512_dpbusd_epi32(c01, u0, w1);
        c10 = _mm512_dpbusd_epi32(c10, u1, w0);
        c11 = _mm512_dpbusd_epi32(c11, u1, w1);
        c20 = _mm512_dpbusd_epi32(c20, u2, w0);
        c21 = _mm512_dpbusd_epi32(c21, u2, w1);
        c30 = _mm512_dpbusd_epi32(c30, u3, w0);
        c31 = _mm512_dpbusd_epi32(c31, u3, w1);
    }
    const __m512i k0 = _mm512_slli_epi32(_mm512_loadu_si512((const void *)wsum), 7);
    const __m512i k1 = nblocks > 1 ? _mm512_slli_epi32(_mm512_loadu_si512((const void *)(wsum + 16)), 7) : k0;
    _mm512_storeu_ps(out[0], _mm512_cvtepi32_ps(_mm512_sub_epi32(c00, k0)));
    _mm512_storeu_ps(out[0] + 16, _mm512_cvtepi32_ps(_mm512_sub_epi32(c01, k1)));
    _mm512_storeu_ps(out[1], _mm512_cvtepi32_ps(_mm512_sub_epi32(c10, k0)));
    _mm512_storeu_ps(out[1] + 16, _mm512_cvtepi32_ps(_mm512_sub_epi32(c11, k1)));
    _mm512_storeu_ps(out[2], _mm512_cvtepi32_ps(_mm512_sub_epi32(c20, k0)));
    _mm512_storeu_ps(out[2] + 16, _mm512_cvtepi32_ps(_mm512_sub_epi32(c21, k1)));
    _mm512_storeu_ps(out[3], _mm512_cvtepi32_ps(_mm512_sub_epi32(c30, k0)));
    _mm512_storeu_ps(out[3] + 16, _mm512_cvtepi32_ps(_mm512_sub_epi32(c31, k1)));
}

#define QK_TABLE weft__qkernels_avx512
#define QK_ISA WEFT_ISA_AVX512
#define QK_VARIANT "avx512-vnni"
#include "kernels/qkernels_body.h"
