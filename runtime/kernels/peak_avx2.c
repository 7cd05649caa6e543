/* Peak-throughput probes for AVX2: fp32 FMA on 12 independent ymm chains (more than FMA
 * latency x ports, so the loop is throughput-bound), and the pre-VNNI int8 dot product
 * (vpmaddubsw + vpmaddwd + vpaddd) on 8 independent chains. */
#include "kernels/kernels_internal.h"

#include <immintrin.h>

volatile float weft__peak_sink_avx2;
volatile int weft__peak_isink_avx2;

uint64_t weft__peak_fma_avx2(uint64_t iters)
{
    enum { C = 12 };
    __m256 a[C];
    for (int j = 0; j < C; ++j) {
        a[j] = _mm256_set1_ps(1.0f + 0.01f * (float)j);
    }
    const __m256 m = _mm256_set1_ps(0.999999f), c = _mm256_set1_ps(1e-7f);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 12
        for (int j = 0; j < C; ++j) {
            a[j] = _mm256_fmadd_ps(a[j], m, c);
        }
    }
    __m256 s = a[0];
    for (int j = 1; j < C; ++j) {
        s = _mm256_add_ps(s, a[j]);
    }
    weft__peak_sink_avx2 = _mm256_cvtss_f32(s);
    return iters * C * 8u;
}

uint64_t weft__peak_dot_avx2(uint64_t iters)
{
    enum { C = 8 };
    __m256i acc[C];
    for (int j = 0; j < C; ++j) {
        acc[j] = _mm256_set1_epi32(j);
    }
    __m256i u = _mm256_set1_epi8(3);
    const __m256i s = _mm256_set1_epi8(-2);
    const __m256i ones = _mm256_set1_epi16(1);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 8
        for (int j = 0; j < C; ++j) {
            /* u looks new to the compiler at every use, so no product is shared or hoisted */
            __asm__("" : "+x"(u));
            const __m256i p16 = _mm256_maddubs_epi16(u, s);
            acc[j] = _mm256_add_epi32(acc[j], _mm256_madd_epi16(p16, ones));
        }
    }
    __m256i t = acc[0];
    for (int j = 1; j < C; ++j) {
        t = _mm256_add_epi32(t, acc[j]);
    }
    weft__peak_isink_avx2 = _mm256_cvtsi256_si32(t);
    return iters * C * 32u;
}
