#define _POSIX_C_SOURCE 200809L

#include "support_peaks.h"

#include "kernels/kernels_internal.h"

#include <string.h>
#include <time.h>

double bench_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

double bench_cpu_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

double bench_peak_rate(peak_fn *fn, double min_time)
{
    double best = 0;
    for (int round = 0; round < 3; ++round) {
        uint64_t macs = 0;
        const double t0 = bench_cpu_now_s();
        double t;
        do {
            macs += fn(1u << 16);
            t = bench_cpu_now_s() - t0;
        } while (t < min_time);
        best = (double)macs / t > best ? (double)macs / t : best;
    }
    return best;
}

void bench_variant_peaks(const char *variant, peak_fn **dot, peak_fn **fma)
{
    *dot = NULL;
    *fma = weft__peak_fma_scalar;
#if defined(__x86_64__)
    if (strcmp(variant, "avx512-vnni") == 0) {
        *dot = weft__peak_dot_avx512;
        *fma = weft__peak_fma_avx512;
    } else if (strcmp(variant, "avx-vnni") == 0) {
        *dot = weft__peak_dot_avxvnni;
        *fma = weft__peak_fma_avx2;
    } else if (strcmp(variant, "avx2-maddubs") == 0) {
        *dot = weft__peak_dot_avx2;
        *fma = weft__peak_fma_avx2;
    }
#endif
#if defined(__aarch64__)
    if (strcmp(variant, "neon-sdot") == 0) {
        *dot = weft__peak_dot_neon;
        *fma = weft__peak_fma_neon;
    }
#endif
}
