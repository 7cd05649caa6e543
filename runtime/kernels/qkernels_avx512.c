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

static inline void q8_tile(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t kgroups,
                           const int32_t *wsum, float out[4][16])
{
    const int8_t *a[4];
    for (uint32_t r = 0; r < 4; ++r) {
        a[r] = Q + (size_t)(r < rows ? r : 0) * ldq; /* missing rows repeat row 0; results unused */
    }
    const __m512i flip = _mm512_set1_epi8((char)0x80);
    __m512i acc0 = _mm512_setzero_si512(), acc1 = acc0, acc2 = acc0, acc3 = acc0;
    for (uint32_t g = 0; g < kgroups; ++g) {
        __m512i w = _mm512_loadu_si512((const void *)(block + (size_t)g * 64));
        int32_t x0, x1, x2, x3;
        memcpy(&x0, a[0] + 4 * g, 4);
        memcpy(&x1, a[1] + 4 * g, 4);
        memcpy(&x2, a[2] + 4 * g, 4);
        memcpy(&x3, a[3] + 4 * g, 4);
        acc0 = _mm512_dpbusd_epi32(acc0, _mm512_xor_si512(_mm512_set1_epi32(x0), flip), w);
        acc1 = _mm512_dpbusd_epi32(acc1, _mm512_xor_si512(_mm512_set1_epi32(x1), flip), w);
        acc2 = _mm512_dpbusd_epi32(acc2, _mm512_xor_si512(_mm512_set1_epi32(x2), flip), w);
        acc3 = _mm512_dpbusd_epi32(acc3, _mm512_xor_si512(_mm512_set1_epi32(x3), flip), w);
    }
    const __m512i corr = _mm512_slli_epi32(_mm512_loadu_si512((const void *)wsum), 7);
    _mm512_storeu_ps(out[0], _mm512_cvtepi32_ps(_mm512_sub_epi32(acc0, corr)));
    _mm512_storeu_ps(out[1], _mm512_cvtepi32_ps(_mm512_sub_epi32(acc1, corr)));
    _mm512_storeu_ps(out[2], _mm512_cvtepi32_ps(_mm512_sub_epi32(acc2, corr)));
    _mm512_storeu_ps(out[3], _mm512_cvtepi32_ps(_mm512_sub_epi32(acc3, corr)));
}

#define QK_TABLE weft__qkernels_avx512
#define QK_ISA WEFT_ISA_AVX512
#define QK_VARIANT "avx512-vnni"
#include "kernels/qkernels_body.h"
