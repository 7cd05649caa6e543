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
    /* Twelve named accumulators, not an array: gcc 12 keeps an array (or copies loop-carried
     * intrinsic results) in memory or extra registers every step, which would make the probe
     * measure moves instead of the instruction. The one-instruction statement below is how the
     * int8 GEMM tiles issue it too. */
    __m512i a0 = _mm512_set1_epi32(0), a1 = _mm512_set1_epi32(1), a2 = _mm512_set1_epi32(2), a3 = _mm512_set1_epi32(3);
    __m512i a4 = _mm512_set1_epi32(4), a5 = _mm512_set1_epi32(5), a6 = _mm512_set1_epi32(6), a7 = _mm512_set1_epi32(7);
    __m512i a8 = _mm512_set1_epi32(8), a9 = _mm512_set1_epi32(9), a10 = _mm512_set1_epi32(10), a11 = _mm512_set1_epi32(11);
    const __m512i u = _mm512_set1_epi8(3), s = _mm512_set1_epi8(-2);
#if defined(__GNUC__) && !defined(__clang__)
#define PEAK_DP(c) __asm__("vpdpbusd %2, %1, %0" : "+v"(c) : "v"(u), "v"(s))
#else
#define PEAK_DP(c) ((c) = _mm512_dpbusd_epi32((c), u, s))
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
    __m512i t = _mm512_add_epi32(_mm512_add_epi32(a0, a1), _mm512_add_epi32(a2, a3));
    t = _mm512_add_epi32(t, _mm512_add_epi32(_mm512_add_epi32(a4, a5), _mm512_add_epi32(a6, a7)));
    t = _mm512_add_epi32(t, _mm512_add_epi32(_mm512_add_epi32(a8, a9), _mm512_add_epi32(a10, a11)));
    weft__peak_isink_avx512 = _mm512_reduce_add_epi32(t);
    return iters * C * 64u;
}
