/* AArch64 Advanced SIMD vector layer for kernels_body.h: 4 fp32 lanes. NEON has no masked
 * loads, so partial vectors go through a small stack copy (never reading past the data). */
#ifndef WEFT_SIMD_NEON_H
#define WEFT_SIMD_NEON_H

#include <arm_neon.h>
#include <stddef.h>
#include <string.h>

typedef float32x4_t V;
typedef uint32x4_t VM;
#define VW 4
/* GEMM register tile: 8 rows x 3 vectors = 24 of the 32 q registers as accumulators. */
#define WEFT_MR 8
#define WEFT_NRV 3

static inline V v_zero(void) { return vdupq_n_f32(0.0f); }
static inline V v_set1(float x) { return vdupq_n_f32(x); }
static inline V v_load(const float *p) { return vld1q_f32(p); }
static inline void v_store(float *p, V v) { vst1q_f32(p, v); }
static inline VM m_first(size_t n)
{
    static const uint32_t idx[4] = {0, 1, 2, 3};
    return vcltq_u32(vld1q_u32(idx), vdupq_n_u32(n >= VW ? VW : (uint32_t)n));
}
static inline V v_load_n(const float *p, size_t n)
{
    float t[VW] = {0.0f, 0.0f, 0.0f, 0.0f};
    memcpy(t, p, (n < VW ? n : VW) * sizeof(float));
    return vld1q_f32(t);
}
static inline void v_store_n(float *p, V v, size_t n)
{
    float t[VW];
    vst1q_f32(t, v);
    memcpy(p, t, (n < VW ? n : VW) * sizeof(float));
}
static inline V v_add(V a, V b) { return vaddq_f32(a, b); }
static inline V v_sub(V a, V b) { return vsubq_f32(a, b); }
static inline V v_mul(V a, V b) { return vmulq_f32(a, b); }
static inline V v_div(V a, V b) { return vdivq_f32(a, b); }
static inline V v_rcp(V x) { return vdivq_f32(vdupq_n_f32(1.0f), x); }
static inline V v_fma(V a, V b, V c) { return vfmaq_f32(c, a, b); }
static inline V v_max(V a, V b) { return vmaxq_f32(a, b); }
static inline V v_min(V a, V b) { return vminq_f32(a, b); }
static inline V v_abs(V a) { return vabsq_f32(a); }
static inline V v_neg(V a) { return vnegq_f32(a); }
static inline V v_round(V a) { return vrndnq_f32(a); }
static inline V v_floor(V a) { return vrndmq_f32(a); }
static inline V v_pow2i(V n)
{
    int32x4_t e = vaddq_s32(vcvtnq_s32_f32(n), vdupq_n_s32(127));
    return vreinterpretq_f32_s32(vshlq_n_s32(e, 23));
}
static inline VM m_lt(V a, V b) { return vcltq_f32(a, b); }
static inline VM m_eq(V a, V b) { return vceqq_f32(a, b); }
static inline VM m_or(VM a, VM b) { return vorrq_u32(a, b); }
static inline V v_sel(VM m, V if_true, V if_false) { return vbslq_f32(m, if_true, if_false); }
static inline float v_hsum(V a) { return vaddvq_f32(a); }
static inline float v_hmax(V a) { return vmaxvq_f32(a); }

/* In-register 4x4 transpose: r[i] lane j <- r[j] lane i. */
static inline void v_transpose(V r[VW])
{
    const V t0 = vtrn1q_f32(r[0], r[1]), t1 = vtrn2q_f32(r[0], r[1]);
    const V t2 = vtrn1q_f32(r[2], r[3]), t3 = vtrn2q_f32(r[2], r[3]);
    r[0] = vreinterpretq_f32_f64(vtrn1q_f64(vreinterpretq_f64_f32(t0), vreinterpretq_f64_f32(t2)));
    r[2] = vreinterpretq_f32_f64(vtrn2q_f64(vreinterpretq_f64_f32(t0), vreinterpretq_f64_f32(t2)));
    r[1] = vreinterpretq_f32_f64(vtrn1q_f64(vreinterpretq_f64_f32(t1), vreinterpretq_f64_f32(t3)));
    r[3] = vreinterpretq_f32_f64(vtrn2q_f64(vreinterpretq_f64_f32(t1), vreinterpretq_f64_f32(t3)));
}

#endif
