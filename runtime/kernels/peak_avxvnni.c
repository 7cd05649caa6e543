/* Peak-throughput probe for AVX-VNNI: the VEX-encoded vpdpbusd on ymm (32 u8 x s8 products
 * per instruction), 12 independent chains. */
#include "kernels/kernels_internal.h"

#include <immintrin.h>

volatile int weft__peak_isink_avxvnni;

uint64_t weft__peak_dot_avxvnni(uint64_t iters)
{
    enum { C = 12 };
    /* Twelve named accumulators, not an array: gcc 12 keeps an array (or copies loop-carried
     * intrinsic results) in memory or extra registers every step, which would make the probe
     * measure moves instead of the instruction. The one-instruction statement below is how the
     * int8 GEMM tiles issue it too. */
    __m256i a0 = _mm256_set1_epi32(0), a1 = _mm256_set1_epi32(1), a2 = _mm256_set1_epi32(2), a3 = _mm256_set1_epi32(3);
    __m256i a4 = _mm256_set1_epi32(4), a5 = _mm256_set1_epi32(5), a6 = _mm256_set1_epi32(6), a7 = _mm256_set1_epi32(7);
    __m256i a8 = _mm256_set1_epi32(8), a9 = _mm256_set1_epi32(9), a10 = _mm256_set1_epi32(10), a11 = _mm256_set1_epi32(11);
    const __m256i u = _mm256_set1_epi8(3), s = _mm256_set1_epi8(-2);
#if defined(__GNUC__) && !defined(__clang__)
#define PEAK_DP(c) __asm__("%{vex%} vpdpbusd %2, %1, %0" : "+x"(c) : "x"(u), "x"(s))
#else
#define PEAK_DP(c) ((c) = _mm256_dpbusd_avx_epi32((c), u, s))
#endif
    for (uint64_t i = 0; i < iters; ++i) {
        PEAK_DP(a0);
        PEAK_DP(a1);
        PEAK_DP(a2);
        PEAK_DP(a3);
        PEAK_DP(a4);
        PEAK_DP(a5);
        PEAK_DP(a6);
        PEAK_DP(a7);
        PEAK_DP(a8);
        PEAK_DP(a9);
        PEAK_DP(a10);
        PEAK_DP(a11);
    }
#undef PEAK_DP
    __m256i t = _mm256_add_epi32(_mm256_add_epi32(a0, a1), _mm256_add_epi32(a2, a3));
    t = _mm256_add_epi32(t, _mm256_add_epi32(_mm256_add_epi32(a4, a5), _mm256_add_epi32(a6, a7)));
    t = _mm256_add_epi32(t, _mm256_add_epi32(_mm256_add_epi32(a8, a9), _mm256_add_epi32(a10, a11)));
    weft__peak_isink_avxvnni = _mm256_cvtsi256_si32(t);
    return iters * C * 32u;
}
