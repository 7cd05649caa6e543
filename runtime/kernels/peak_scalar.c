/* Peak-throughput probe for the scalar level: 8 independent multiply-add chains on single
 * floats. The empty asm keeps each chain in its own scalar register, so the compiler cannot
 * merge them into vectors and the figure stays a scalar peak. */
#include "kernels/kernels_internal.h"

#if defined(__x86_64__)
#define WEFT_KEEP_SCALAR(v) __asm__("" : "+x"(v))
#elif defined(__aarch64__)
#define WEFT_KEEP_SCALAR(v) __asm__("" : "+w"(v))
#else
#define WEFT_KEEP_SCALAR(v) ((void)0)
#endif

volatile float weft__peak_sink_scalar;

uint64_t weft__peak_fma_scalar(uint64_t iters)
{
    float a[8] = {1.0f, 1.1f, 1.2f, 1.3f, 1.4f, 1.5f, 1.6f, 1.7f};
    const float m = 0.999999f, c = 1e-7f;
    for (uint64_t i = 0; i < iters; ++i) {
#pragma GCC unroll 8
        for (int j = 0; j < 8; ++j) {
            a[j] = a[j] * m + c;
            WEFT_KEEP_SCALAR(a[j]);
        }
    }
    weft__peak_sink_scalar = a[0] + a[1] + a[2] + a[3] + a[4] + a[5] + a[6] + a[7];
    return iters * 8u;
}
