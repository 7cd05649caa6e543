/* NEON twin: sdot (signed x signed, 4 channels x 4 k per instruction), four per block. Needs
 * the dot-product extension; CPUs without it use the scalar table (same bits). */
#include "kernels/simd_neon.h"

#include "kernels/qkernels.h"

#include <stdint.h>
#include <string.h>

static inline V v_load_h(const uint16_t *p) { return vcvt_f32_f16(vreinterpret_f16_u16(vld1_u16(p))); }
static inline V v_load_h_n(const uint16_t *p, size_t n)
{
    uint16_t t[4] = {0};
    memcpy(t, p, (n < 4 ? n : 4) * sizeof(uint16_t));
    return v_load_h(t);
}

static inline void q8_block(const int8_t *Q, uint32_t ldq, uint32_t rows, const int8_t *block, uint32_t kgroups,
                            const int32_t *wsum, float out[4][32], uint32_t col)
{
    (void)wsum;
    int32x4_t acc[4][4];
    for (uint32_t r = 0; r < 4; ++r) {
        for (int i = 0; i < 4; ++i) {
            acc[r][i] = vdupq_n_s32(0);
        }
    }
    const int8_t *a[4];
    for (uint32_t r = 0; r < 4; ++r) {
        a[r] = Q + (size_t)(r < rows ? r : 0) * ldq;
    }
    for (uint32_t g = 0; g < kgroups; ++g) {
        const int8_t *b = block + (size_t)g * 64;
        int8x16_t w0 = vld1q_s8(b), w1 = vld1q_s8(b + 16), w2 = vld1q_s8(b + 32), w3 = vld1q_s8(b + 48);
        for (uint32_t r = 0; r < 4; ++r) {
            int32_t x;
            memcpy(&x, a[r] + 4 * g, 4);
            int8x16_t av = vreinterpretq_s8_s32(vdupq_n_s32(x));
            acc[r][0] = vdotq_s32(acc[r][0], w0, av);
            acc[r][1] = vdotq_s32(acc[r][1], w1, av);
            acc[r][2] = vdotq_s32(acc[r][2], w2, av);
            acc[r][3] = vdotq_s32(acc[r][3], w3, av);
        }
    }
    for (uint32_t r = 0; r < 4; ++r) {
        for (int i = 0; i < 4; ++i) {
            vst1q_f32(out[r] + col + 4 * i, vcvtq_f32_s32(acc[r][i]));
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

#define QK_TABLE weft__qkernels_neon
#define QK_ISA WEFT_ISA_NEON
#define QK_VARIANT "neon-sdot"
#define QK_ATT_ACC 24 /* 32 vector registers */
#include "kernels/qkernels_body.h"
