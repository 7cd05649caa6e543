/* Peak throughput probes for benchmarks: the register-resident fp32 FMA and int8 dot-product
 * loops of runtime/kernels (peak_*.c), timed, and the pair that matches an int8 kernel variant. */
#ifndef WEFT_SUPPORT_PEAKS_H
#define WEFT_SUPPORT_PEAKS_H

#include <stdint.h>

/* A probe: runs `iters` iterations and returns the multiply-accumulates it performed. */
typedef uint64_t peak_fn(uint64_t iters);

/* Monotonic seconds. */
double bench_now_s(void);
/* CPU seconds of the calling thread (on a shared machine: only this thread's own work). */
double bench_cpu_now_s(void);

/* Multiply-accumulates per thread-CPU second of a probe: best of 3 rounds of at least min_time
 * seconds. */
double bench_peak_rate(peak_fn *fn, double min_time);

/* The int8 dot-product probe (NULL when the variant has none, e.g. "scalar") and the fp32 FMA
 * probe of the ISA level that a weft_qkernels variant ("avx512-vnni", "avx-vnni",
 * "avx2-maddubs", "neon-sdot", "scalar") runs at. */
void bench_variant_peaks(const char *variant, peak_fn **dot, peak_fn **fma);

/* The int8 GEMM (per-row quantisation of X, then gemm_q8, no activation) and the fp32 gemm of
 * one shape, M x K -> N, on pseudo-random data: GMAC/s of the thread's CPU time, best of 3 rounds
 * of at least min_time seconds each; also gemm_q8 alone on the quantised rows, and the share of
 * the quantisation in the int8 time when both are timed apart. NaN where an allocation failed. */
typedef struct bench_gemm_probe {
    double i8_gmacs, f32_gmacs;
    double dot_gmacs;      /* gemm_q8 alone */
    double quantize_share; /* quantize_rows / (quantize_rows + gemm_q8) */
} bench_gemm_probe;
struct weft_qkernels;
struct weft_kernels;
bench_gemm_probe bench_probe_gemm(const struct weft_qkernels *q, const struct weft_kernels *k, uint32_t M, uint32_t N,
                                  uint32_t K, double min_time);

#endif
