/* The shared body built with the one-lane plain-C vector layer and a plain int8 tile. Never
 * dispatched to; tested against the oracle on every machine so the body's tiling, tails and
 * canonical reductions are checked even where no SIMD twin runs. */
#include "kernels/simd_scalar.h"

#include "kernels/qkernels.h"

#include <stdint.h>

static inline V v_load_h(const uint16_t *p) { return weft_f16_to_f32(*p); }
static inline V v_load_h_n(const uint16_t *p, size_t n) { return n ? weft_f16_to_f32(*p) : 0.0f; }

static inline void q8_block(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t kgroups,
                            const int32_t *wsum, float out[4][32], uint32_t col)
{
    (void)wsum;
    for (uint32_t r = 0; r < rows; ++r) {
        for (uint32_t c = 0; c < 16; ++c) {
            int32_t acc = 0;
            for (uint32_t g = 0; g < kgroups; ++g) {
                for (uint32_t j = 0; j < 4; ++j) {
                    acc += (int32_t)Q[(size_t)r * ldq + 4 * g + j] * (int32_t)block[(size_t)g * 64 + c * 4 + j];
                }
            }
            out[r][col + c] = (float)acc;
        }
    }
}

static inline void q8_tile(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t nblocks,
                           uint32_t Kp, uint32_t kgroups, const int32_t *wsum, float out[4][32])
{
    for (uint32_t b = 0; b < nblocks; ++b) {
        q8_block(Q, ldq, rows, block + (size_t)b * Kp * 16, kgroups, wsum + 16 * b, out, 16 * b);
    }
}

#define QK_TABLE weft__qkernels_generic
#define QK_ISA WEFT_ISA_SCALAR
#define QK_VARIANT "generic-body"
#include "kernels/qkernels_body.h"
