/* Peak-throughput probe for AVX-VNNI: the VEX-encoded vpdpbusd on ymm (32 u8 x s8 products
 * per instruction), 12 independent chains. */
#include "kernels/kernels_internal.h"

#include <immintrin.h>

volatile int weft__peak_isink_avxvnni;

uint64_t weft__peak_dot_avxvnni(uint64_t iters)
{
    enum { C = 12 };
    __m256i acc[C];
    for (int j = 0; j < C; ++j) {
        acc[j] = _mm256_set1_epi32(j);
    }
    const __m256i u = _mm256_set1_epi8(3), s = _mm256_set1_epi8(-2);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 12
        for (int j = 0; j < C; ++j) {
            acc[j] = _mm256_dpbusd_avx_epi32(acc[j], u, s);
        }
    }
    __m256i t = acc[0];
    for (int j = 1; j < C; ++j) {
        t = _mm256_add_epi32(t, acc[j]);
    }
    weft__peak_isink_avxvnni = _mm256_cvtsi256_si32(t);
    return iters * C * 32u;
}
