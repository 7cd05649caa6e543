/* fp32 compute kernels. Each has a plain-C oracle (kernels_scalar.c) and per-ISA twins built
 * from one shared body; a weft_kernels table per ISA is filled once and chosen at run time.
 *
 * Layouts: row-major; a matrix X[rows][cols] with leading dimension ldx >= cols (in floats).
 * Linear layers store weights as W[N][K] (PyTorch nn.Linear layout): y = x W^T + b. */
#ifndef WEFT_KERNELS_H
#define WEFT_KERNELS_H

#include "weft.h"

typedef enum weft_activation {
    WEFT_ACT_NONE = 0,
    WEFT_ACT_RELU,
    WEFT_ACT_GELU,      /* tanh approximation (matches torch.nn.GELU(approximate='tanh')) */
    WEFT_ACT_SILU,
} weft_activation;

typedef struct weft_kernels {
    weft_isa isa;

    /* C[M][N] = act(A[M][K] . W[N][K]^T + bias[N]) (+ C when accumulate; act applies after the
     * add). bias may be NULL. M == 1 is the GEMV case and must be fast too. C must not overlap
     * A or W. Uses up to 32 KiB of stack (one packed panel of W) and allocates nothing. */
    void (*gemm)(uint32_t M, uint32_t N, uint32_t K, const float *A, uint32_t lda, const float *W,
                 uint32_t ldw, const float *bias, float *C, uint32_t ldc, weft_activation act,
                 bool accumulate);

    /* Row-wise softmax in place over `cols` entries of each of `rows` rows (max-subtracted). */
    void (*softmax_rows)(float *X, uint32_t rows, uint32_t cols, uint32_t ldx);

    /* Y = (X - mean) / sqrt(var + eps) * gamma + beta per row (gamma/beta may be NULL). Y may be X. */
    void (*layernorm)(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld,
                      const float *gamma, const float *beta, float eps);
    /* Y = X / sqrt(mean(X^2) + eps) * gamma per row. Y may be X. */
    void (*rmsnorm)(const float *X, float *Y, uint32_t rows, uint32_t cols, uint32_t ld,
                    const float *gamma, float eps);

    /* Elementwise, in place over n floats. */
    void (*gelu)(float *x, size_t n);
    void (*silu)(float *x, size_t n);
    /* out[i] = silu(gate[i]) * up[i]; out may alias gate or up. */
    void (*swiglu)(const float *gate, const float *up, float *out, size_t n);

    /* Sinusoidal embedding of `n` points of `dims` coordinates each:
     * out[i][ (d*F + f)*2 + 0 ] = sin(x[i][d] * freq[f]), [..+1] = cos(...), F = nfreq.
     * Row i has dims*nfreq*2 floats at stride ldo. */
    void (*posembed)(const float *x, uint32_t n, uint32_t dims, const float *freq, uint32_t nfreq,
                     float *out, uint32_t ldo);

    /* Graph aggregation over a CSR adjacency: out[r] = sum (or mean) of X[col[j]] for
     * j in [rowptr[r], rowptr[r+1]). Rows with no neighbours give zeros. */
    void (*csr_aggregate)(const uint32_t *rowptr, const uint32_t *col, uint32_t rows, const float *X,
                          uint32_t ldx, uint32_t dim, float *out, uint32_t ldo, bool mean);

    /* Multi-head scaled dot-product attention, one head at a time:
     * out[q][h*dh + :] = softmax(Q[q][h*dh:] . K[k][h*dh:] * scale + key_bias[k]) . V[k][h*dh:].
     * Q is nq x (H*dh) with stride ldq, K and V are nk x (H*dh) with strides ldk, ldv.
     * mask (may be NULL): nq x nk bytes, 0 = masked out; a fully masked row yields zeros.
     * key_bias (may be NULL: all 0): nk finite floats added to every query's score of key k after
     * the scale, in every head; log w weighs key k as w copies of it would.
     * scratch: at least weft_attention_scratch(nq, nk) floats. Shapes the model uses range from
     * many queries x few keys (decoder) to few queries x many keys (encoder). */
    void (*attention)(const float *Q, uint32_t ldq, const float *K, uint32_t ldk, const float *V,
                      uint32_t ldv, uint32_t nq, uint32_t nk, uint32_t heads, uint32_t dh, float scale,
                      const uint8_t *mask, const float *key_bias, float *out, uint32_t ldo, float *scratch);
} weft_kernels;

/* Floats of scratch the attention kernel needs (the same for every level). Non-decreasing in
 * nq and in nk, so a buffer sized for the largest shape serves every smaller one. */
size_t weft_attention_scratch(uint32_t nq, uint32_t nk);

/* The table for a level; NULL if this build or CPU lacks it. */
const weft_kernels *weft_kernels_for_isa(weft_isa isa);

#endif
