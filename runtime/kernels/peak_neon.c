/* Peak-throughput probes for AArch64: fp32 FMA on 16 independent q-register chains, and the
 * int8 dot product (sdot, 16 s8 x s8 products per instruction) on 12 chains. The caller runs
 * the dot probe only when HWCAP reports asimddp. */
#include "kernels/kernels_internal.h"

#include <arm_neon.h>

volatile float weft__peak_sink_neon;
volatile int weft__peak_isink_neon;

uint64_t weft__peak_fma_neon(uint64_t iters)
{
    enum { C = 16 };
    float32x4_t a[C];
    for (int j = 0; j < C; ++j) {
        a[j] = vdupq_n_f32(1.0f + 0.01f * (float)j);
    }
    const float32x4_t m = vdupq_n_f32(0.999999f), c = vdupq_n_f32(1e-7f);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 16
        for (int j = 0; j < C; ++j) {
            a[j] = vfmaq_f32(c, a[j], m);
        }
    }
    float32x4_t s = a[0];
    for (int j = 1; j < C; ++j) {
        s = vaddq_f32(s, a[j]);
    }
    weft__peak_sink_neon = vaddvq_f32(s);
    return iters * C * 4u;
}

uint64_t weft__peak_dot_neon(uint64_t iters)
{
    enum { C = 12 };
    int32x4_t acc[C];
    for (int j = 0; j < C; ++j) {
        acc[j] = vdupq_n_s32(j);
    }
    const int8x16_t a = vdupq_n_s8(3), b = vdupq_n_s8(-2);
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 12
        for (int j = 0; j < C; ++j) {
            acc[j] = vdotq_s32(acc[j], a, b);
        }
    }
    int32x4_t t = acc[0];
    for (int j = 1; j < C; ++j) {
        t = vaddq_s32(t, acc[j]);
    }
    weft__peak_isink_neon = vaddvq_s32(t);
    return iters * C * 16u;
}
