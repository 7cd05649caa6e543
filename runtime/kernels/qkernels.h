/* Reduced-precision and deterministic kernels: the int8 and fp16 paths.
 *
 * Bit-exactness. Every kernel in this table gives bit-identical results on every ISA (scalar,
 * AVX2, AVX-VNNI, AVX-512 VNNI, NEON), so lockstep games on mixed hardware see the same cloth:
 *   - int8 dot products accumulate in int32, which is exact in any order;
 *   - fp32 work never reduces across SIMD lanes except through one canonical 16-lane order
 *     (element k goes to partial sum k mod 16, partials are added in a fixed tree) that the
 *     scalar oracle follows too;
 *   - matrix products run lanes along the output columns and accumulate k in order with fused
 *     multiply-add, so each output is the same fma chain on every ISA;
 *   - exp is one polynomial evaluated with the same operations in the same order;
 *   - epilogues are written as separate statements (no compiler contraction): y = acc * s, y += b.
 *
 * int8 scheme: weights symmetric per output channel in [-127, 127] (round to nearest even),
 * activations symmetric per row quantised on the fly, y = (float)acc * (s_row * s_col) + bias. */
#ifndef WEFT_QKERNELS_H
#define WEFT_QKERNELS_H

#include "kernels/kernels.h"

#define WEFT_Q8_NB 16u /* output channels per packed weight block */
#define WEFT_Q8_KB 4u  /* k values per 32-bit group (one vpdpbusd / sdot lane) */

/* int8 weights in the packed layout every ISA reads: blocks of 16 output channels; inside a
 * block, for each group of 4 k values, 16 channels x 4 bytes (64 bytes, one zmm). N is padded
 * to a multiple of 16 with zero channels, K to a multiple of 4 with zeros. */
typedef struct weft_q8_weights {
    uint32_t N, K;      /* logical sizes */
    uint32_t Np, Kp;    /* padded sizes */
    const int8_t *packed;   /* Np * Kp bytes */
    const float *scale;     /* Np per-channel scales (0 in padding) */
    const int32_t *wsum;    /* Np sums of each channel's weights (for the unsigned-offset form) */
} weft_q8_weights;

static inline uint32_t weft_q8_pad_n(uint32_t n) { return (n + WEFT_Q8_NB - 1) / WEFT_Q8_NB * WEFT_Q8_NB; }
static inline uint32_t weft_q8_pad_k(uint32_t k) { return (k + WEFT_Q8_KB - 1) / WEFT_Q8_KB * WEFT_Q8_KB; }

/* Quantises W[N][K] (fp32, row stride K) per output channel: scale = absmax / 127,
 * q = round_half_even(w / scale) clamped to [-127, 127]. All-zero rows get scale 0.
 * Returns false if W has a NaN or infinity. */
bool weft_q8_quantize_weights(const float *W, uint32_t N, uint32_t K, int8_t *Wq, float *scale);

/* Packs Wq[N][K] into the block layout above. packed: weft_q8_pad_n(N) * weft_q8_pad_k(K) bytes;
 * scale_out and wsum: weft_q8_pad_n(N) entries. */
void weft_q8_pack(const int8_t *Wq, const float *scale, uint32_t N, uint32_t K, int8_t *packed, float *scale_out,
                  int32_t *wsum);

/* fp16 <-> fp32 (IEEE binary16, round to nearest even; NaN stays NaN, overflow gives inf). */
uint16_t weft_f32_to_f16(float x);
float weft_f16_to_f32(uint16_t h);

typedef struct weft_qkernels {
    weft_isa isa;
    const char *variant; /* e.g. "avx512-vnni", "avx2-maddubs", "neon-sdot", "scalar" */

    /* Per-row int8 quantisation of X[M][K]: Q[m][0..Kp) (zeros past K), scales[m] = absmax/127.
     * Q's row stride ldq >= weft_q8_pad_k(K). */
    void (*quantize_rows)(const float *X, uint32_t M, uint32_t K, uint32_t ldx, int8_t *Q, uint32_t ldq,
                          float *scales);

    /* C[M][N] = act((float)(Q . Wq^T) * (qscale[m] * W.scale[n]) + bias[n] (+ C when accumulate)).
     * bias may be NULL. */
    void (*gemm_q8)(uint32_t M, const int8_t *Q, uint32_t ldq, const float *qscale, const weft_q8_weights *W,
                    const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate);

    /* C[M][N] = act(A[M][K] . B[K][N] + bias (+ C when accumulate)), B row-major [K][N]:
     * the deterministic fp32 product (lanes along N, k accumulated in order by fma). */
    void (*gemm_det)(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const float *B, uint32_t ldb,
                     const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate);

    /* Same with fp16 B (converted exactly to fp32 in registers; fp32 accumulation). */
    void (*gemm_f16)(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const uint16_t *B,
                     uint32_t ldb, const float *bias, float *C, uint32_t ldc, weft_activation act, bool accumulate);

    /* Deterministic row operations (same contracts as the fp32 table's kernels). */
    void (*layernorm_det)(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                          const float *beta, float eps);
    void (*rmsnorm_det)(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld, const float *gamma,
                        float eps);
    void (*softmax_rows_det)(float *X, uint32_t rows, uint32_t cols, uint32_t ldx);
    /* In place over n floats: WEFT_ACT_NONE does nothing. */
    void (*activate_det)(float *x, size_t n, weft_activation act);
    /* out[i] = silu(gate[i]) * up[i]. */
    void (*swiglu_det)(const float *gate, const float *up, float *out, size_t n);
    /* Sinusoidal embedding with the fp32 table's layout (kernels.h: posembed), computed with one
     * fixed range reduction and polynomial, so it too is identical on every ISA. */
    void (*posembed_det)(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq, float *out,
                         uint32_t ldo);

    /* Deterministic multi-head attention, bit-identical to composing the kernels above per head
     * (head h uses columns [h dh, (h + 1) dh) of Q, K, V and out):
     *   s[i][j] = (fma chain over d = 0..dh-1 in order of Q[i][d] K[j][d], from 0) * scale
     *             + key_bias[j] (key_bias may be NULL: no addition; log w weighs key j as w
     *             copies of it would), -inf where mask[i * nk + j] == 0 (mask may be NULL);
     *   p = softmax_rows_det(s) (a fully masked row gives p = 0);
     *   out[i][d] = fma chain over j = 0..nk-1 in order of p[i][j] V[j][d], from 0.
     * Lanes run along 16 or 32 queries at a time, so the per-query chains are those of the
     * composed form; no transposes, no nq x nk score matrix.
     * scratch: weft_qk_attention_scratch(nk, dh) floats. */
    void (*attention_det)(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *V, uint32_t ldv,
                          uint32_t nq, uint32_t nk, uint32_t H, uint32_t dh, float scale, const uint8_t *mask,
                          const float *key_bias, float *out, uint32_t ldo, float *scratch);
} weft_qkernels;

/* The most queries per block of attention_det (its lanes), and the floats of scratch it needs. */
#define WEFT_QK_ATT_QB 32u
static inline size_t weft_qk_attention_scratch(uint32_t nk, uint32_t dh)
{
    return (size_t)WEFT_QK_ATT_QB * ((size_t)nk + 16u + 2u * dh);
}

/* The table for a level (the best int8 variant the CPU has within it); NULL if unavailable. */
const weft_qkernels *weft_qkernels_for_isa(weft_isa isa);

/* Every variant this build and CPU can run (for tests and benchmarks); returns the count. */
uint32_t weft_qkernels_variants(const weft_qkernels **out, uint32_t capacity);

#endif
