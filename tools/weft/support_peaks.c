#define _POSIX_C_SOURCE 200809L

#include "support_peaks.h"

#include "kernels/kernels_internal.h"
#include "kernels/qkernels.h"

#include <math.h>
#include <stdlib.h>

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

bench_gemm_probe bench_probe_gemm(const weft_qkernels *q, const weft_kernels *k, uint32_t M, uint32_t N, uint32_t K,
                             double min_time)
{
    bench_gemm_probe out = {NAN, NAN, NAN, NAN};
    const uint32_t Np = weft_q8_pad_n(N), Kp = weft_q8_pad_k(K);
    float *X = malloc((size_t)M * K * sizeof(float)), *W = malloc((size_t)N * K * sizeof(float));
    float *C = malloc((size_t)M * N * sizeof(float)), *bias = calloc(N, sizeof(float));
    float *qs = malloc(M * sizeof(float)), *scale = malloc(N * sizeof(float)), *ps = malloc(Np * sizeof(float));
    int8_t *Q = malloc((size_t)M * Kp), *wq = malloc((size_t)N * K), *packed = malloc((size_t)Np * Kp);
    int32_t *ws = malloc(Np * sizeof(int32_t));
    if (X && W && C && bias && qs && scale && ps && Q && wq && packed && ws) {
        uint32_t seed = 7;
        for (size_t i = 0; i < (size_t)M * K; ++i) {
            seed = seed * 1664525u + 1013904223u;
            X[i] = (float)(seed >> 8) / 16777216.0f - 0.5f;
        }
        for (size_t i = 0; i < (size_t)N * K; ++i) {
            seed = seed * 1664525u + 1013904223u;
            W[i] = (float)(seed >> 8) / 16777216.0f - 0.5f;
        }
        weft_q8_quantize_weights(W, N, K, wq, scale);
        weft_q8_pack(wq, scale, N, K, packed, ps, ws);
        const weft_q8_weights w8 = {N, K, Np, Kp, packed, ps, ws};
        const double macs = (double)M * N * K;
        double secs[4];
        for (int which = 0; which < 4; ++which) {
            double best = INFINITY;
            for (int round = 0; round < 3; ++round) {
                uint64_t calls = 0;
                const double t0 = bench_cpu_now_s();
                double t;
                do {
                    if (which == 0 || which == 2) {
                        q->quantize_rows(X, M, K, K, Q, Kp, qs);
                    }
                    if (which == 0 || which == 3) {
                        q->gemm_q8(M, Q, Kp, qs, &w8, bias, C, N, WEFT_ACT_NONE, false);
                    }
                    if (which == 1) {
                        k->gemm(M, N, K, X, K, W, K, bias, C, N, WEFT_ACT_NONE, false);
                    }
                    calls++;
                    t = bench_cpu_now_s() - t0;
                } while (t < min_time);
                best = fmin(best, t / (double)calls);
            }
            secs[which] = best;
        }
        out.i8_gmacs = macs / secs[0] * 1e-9;
        out.f32_gmacs = macs / secs[1] * 1e-9;
        out.dot_gmacs = macs / secs[3] * 1e-9;
        out.quantize_share = secs[2] / (secs[2] + secs[3]);
    }
    free(X); free(W); free(C); free(bias); free(qs); free(scale); free(ps); free(Q); free(wq); free(packed); free(ws);
    return out;
}

