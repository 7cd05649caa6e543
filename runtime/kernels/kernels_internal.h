/* Internals shared by the kernel tables: the per-ISA tables, the attention tiling that
 * weft_attention_scratch() sizes for, and the peak-throughput probes used by `weft bench kernels`. */
#ifndef WEFT_KERNELS_INTERNAL_H
#define WEFT_KERNELS_INTERNAL_H

#include "kernels/kernels.h"

extern const weft_kernels weft__kernels_scalar;
#if defined(__x86_64__)
extern const weft_kernels weft__kernels_avx2;
extern const weft_kernels weft__kernels_avx512;
#endif
#if defined(__aarch64__)
extern const weft_kernels weft__kernels_neon;
#endif
/* The shared SIMD body compiled with one-lane plain C vectors: never dispatched to, but tested
 * against the oracle on every machine so the body's tiling and tails are checked everywhere. */
extern const weft_kernels weft__kernels_generic;

/* Attention tiling (what weft_attention_scratch sizes for). Queries go in blocks of
 * weft__attn_qb rows; keys in blocks of WEFT__ATTN_KB, with an online softmax (running row max
 * and sum) so the score tile stays qb x KB whatever nk is. The head's keys are transposed once
 * per head in chunks of WEFT__ATTN_DB dimensions. Score and key rows are padded to a multiple of
 * 16 floats (one zmm), avoiding strides that alias in L1. */
#define WEFT__ATTN_DB 64u
#define WEFT__ATTN_KB 256u
#define WEFT__ATTN_QB 48u /* a multiple of every ISA's GEMM tile rows (12, 6, 8, 4) */
static inline size_t weft__attn_pad(uint32_t nk)
{
    size_t p = ((size_t)nk + 15u) & ~(size_t)15u;
    /* a row stride of a multiple of 2 KiB maps every row to the same few L1 sets */
    return p && (p & 511u) == 0 ? p + 16u : p;
}
static inline size_t weft__attn_qb(uint32_t nq) { return nq < WEFT__ATTN_QB ? (nq ? nq : 1u) : WEFT__ATTN_QB; }
static inline size_t weft__attn_kbp(uint32_t nk) { return weft__attn_pad(nk < WEFT__ATTN_KB ? nk : WEFT__ATTN_KB); }

/* Peak probes: run `iters` iterations of a register-resident loop and return the number of
 * multiply-accumulates performed (fp32 FMA lanes, or int8 products for the dot probes). Only
 * the probes of the running architecture exist; call one only when its features are present
 * (weft_cpu_features_get). */
uint64_t weft__peak_fma_scalar(uint64_t iters);  /* scalar multiply + add (two roundings) */
#if defined(__x86_64__)
uint64_t weft__peak_fma_avx2(uint64_t iters);
uint64_t weft__peak_fma_avx512(uint64_t iters);
uint64_t weft__peak_dot_avx2(uint64_t iters);    /* vpmaddubsw + vpmaddwd + vpaddd */
uint64_t weft__peak_dot_avxvnni(uint64_t iters); /* AVX-VNNI vpdpbusd on ymm */
uint64_t weft__peak_dot_avx512(uint64_t iters);  /* AVX512-VNNI vpdpbusd on zmm */
#endif
#if defined(__aarch64__)
uint64_t weft__peak_fma_neon(uint64_t iters);
uint64_t weft__peak_dot_neon(uint64_t iters);    /* sdot (needs asimddp) */
#endif

#endif
