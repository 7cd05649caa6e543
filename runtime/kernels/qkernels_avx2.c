/* AVX2 twin without VNNI: the sign trick. |a| (unsigned) times w*sign(a) (signed) through
 * vpmaddubsw, whose int16 pair sums stay within 2*127*127 = 32258 because both sides are
 * limited to +-127, so it never saturates; vpmaddwd with ones widens to int32. */
#include "kernels/simd_avx2.h"

#include "kernels/qkernels.h"

#include <stdint.h>
#include <string.h>

static inline V v_load_h(const uint16_t *p) { return _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)p)); }

/* The canonical tree over the 16 partial sums (t[j] += t[j + w], w = 8, 4, 2, 1) in registers:
 * acc[0] holds t[0..7], acc[1] t[8..15]. */
#define QK_HAVE_TREE16 1
static inline float qk_tree16_v(const V *acc)
{
    const V t = _mm256_add_ps(acc[0], acc[1]);
    __m128 u = _mm_add_ps(_mm256_castps256_ps128(t), _mm256_extractf128_ps(t, 1));
    u = _mm_add_ps(u, _mm_permute_ps(u, _MM_SHUFFLE(1, 0, 3, 2)));
    u = _mm_add_ps(u, _mm_permute_ps(u, _MM_SHUFFLE(2, 3, 0, 1)));
    return _mm_cvtss_f32(u);
}
static inline V v_load_h_n(const uint16_t *p, size_t n)
{
    uint16_t t[8] = {0};
    memcpy(t, p, (n < 8 ? n : 8) * sizeof(uint16_t));
    return v_load_h(t);
}

static inline __m256i dot4(__m256i acc, __m256i a_bcast, __m256i w)
{
    const __m256i ones = _mm256_set1_epi16(1);
    __m256i p = _mm256_maddubs_epi16(_mm256_abs_epi8(a_bcast), _mm256_sign_epi8(w, a_bcast));
    return _mm256_add_epi32(acc, _mm256_madd_epi16(p, ones));
}

static inline void q8_block(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t kgroups,
                            const int32_t *wsum, float out[4][32], uint32_t col)
{
    (void)wsum; /* signed x signed: no offset to correct */
    __m256i acc[4][2];
    for (uint32_t r = 0; r < 4; ++r) {
        acc[r][0] = acc[r][1] = _mm256_setzero_si256();
    }
    const int8_t *a[4];
    for (uint32_t r = 0; r < 4; ++r) {
        a[r] = Q + (size_t)(r < rows ? r : 0) * ldq;
    }
    for (uint32_t g = 0; g < kgroups; ++g) {
        __m256i w0 = _mm256_loadu_si256((const __m256i *)(block + (size_t)g * 64));
        __m256i w1 = _mm256_loadu_si256((const __m256i *)(block + (size_t)g * 64 + 32));
        for (uint32_t r = 0; r < 4; ++r) {
            int32_t x;
            memcpy(&x, a[r] + 4 * g, 4);
            __m256i b = _mm256_set1_epi32(x);
            acc[r][0] = dot4(acc[r][0], b, w0);
            acc[r][1] = dot4(acc[r][1], b, w1);
        }
    }
    for (uint32_t r = 0; r < 4; ++r) {
        _mm256_storeu_ps(out[r] + col, _mm256_cvtepi32_ps(acc[r][0]));
        _mm256_storeu_ps(out[r] + col + 8, _mm256_cvtepi32_ps(acc[r][1]));
    }
}

static inline void q8_tile(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t nblocks,
                           uint32_t Kp, uint32_t kgroups, const int32_t *wsum, float out[4][32])
{
    for (uint32_t b = 0; b < nblocks; ++b) {
        q8_block(Q, ldq, rows, block + (size_t)b * Kp * 16, kgroups, wsum + 16 * b, out, 16 * b);
    }
}

#define QK_TABLE weft__qkernels_avx2
#define QK_ISA WEFT_ISA_AVX2
#define QK_VARIANT "avx2-maddubs"
#include "kernels/qkernels_body.h"
