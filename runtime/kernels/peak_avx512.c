/* Peak-throughput probes for AVX-512: fp32 FMA on 16 independent zmm chains, and the int8 dot
 * product with AVX512-VNNI vpdpbusd (64 u8 x s8 products per instruction) on 12 chains. */
#include "kernels/kernels_internal.h"

#include <immintrin.h>

volatile float weft__peak_sink_avx512;
volatile int weft__peak_isink_avx512;

uint64_t weft__peak_fma_avx512(uint64_t iters)
{
    enum { C = 16 };
    __m512 a[C];
    for (int j = 0; j < C; ++j) {
        a[j] = _mm512_set1_ps(1.0f + 0.01f * (float)j);
    }
    const __m512 m = _mm512_set1_ps(0.999999f), c = _mm512_set1_ps(1e-7f);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 16
        for (int j = 0; j < C; ++j) {
            a[j] = _mm512_fmadd_ps(a[j], m, c);
        }
    }
    __m512 s = a[0];
    for (int j = 1; j < C; ++j) {
        s = _mm512_add_ps(s, a[j]);
    }
    weft__peak_sink_avx512 = _mm512_reduce_add_ps(s);
    return iters * C * 16u;
}

uint64_t weft__peak_dot_avx512(uint64_t iters)
{
    enum { C = 12 };
    __m512i acc[C];
    for (int j = 0; j < C; ++j) {
        acc[j] = _mm512_set1_epi32(j);
    }
    const __m512i u = _mm512_set1_epi8(3), s = _mm512_set1_epi8(-2);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 12
        for (int j = 0; j < C; ++j) {
            acc[j] = _mm512_dpbusd_epi32(acc[j], u, s);
        }
    }
    __m512i t = acc[0];
    for (int j = 1; j < C; ++j) {
        t = _mm512_add_epi32(t, acc[j]);
    }
    weft__peak_isink_avx512 = _mm512_reduce_add_epi32(t);
    return iters * C * 64u;
}
