/* One-lane plain-C vector layer for kernels_body.h. It builds the shared body on any target so
 * its tiling, tails and special cases are tested against the oracle everywhere, also where no
 * SIMD twin runs. */
#ifndef WEFT_SIMD_SCALAR_H
#define WEFT_SIMD_SCALAR_H

#include <math.h>
#include <stdbool.h>
#include <stddef.h>

typedef float V;
typedef bool VM;
#define VW 1
#define WEFT_MR 4
#define WEFT_NRV 4

static inline V v_zero(void) { return 0.0f; }
static inline V v_set1(float x) { return x; }
static inline V v_load(const float *p) { return *p; }
static inline void v_store(float *p, V v) { *p = v; }
static inline VM m_first(size_t n) { return n > 0; }
static inline V v_load_n(const float *p, size_t n) { return n ? *p : 0.0f; }
static inline void v_store_n(float *p, V v, size_t n)
{
    if (n) {
        *p = v;
    }
}
static inline V v_add(V a, V b) { return a + b; }
static inline V v_sub(V a, V b) { return a - b; }
static inline V v_mul(V a, V b) { return a * b; }
static inline V v_div(V a, V b) { return a / b; }
static inline V v_rcp(V x) { return 1.0f / x; }
static inline V v_fma(V a, V b, V c) { return fmaf(a, b, c); }
static inline V v_max(V a, V b) { return a > b ? a : b; }
static inline V v_min(V a, V b) { return a < b ? a : b; }
static inline V v_abs(V a) { return fabsf(a); }
static inline V v_neg(V a) { return -a; }
static inline V v_round(V a) { return nearbyintf(a); }
static inline V v_floor(V a) { return floorf(a); }
static inline V v_pow2i(V n) { return ldexpf(1.0f, (int)n); }
static inline VM m_lt(V a, V b) { return a < b; }
static inline VM m_eq(V a, V b) { return a == b; }
static inline VM m_or(VM a, VM b) { return a || b; }
static inline V v_sel(VM m, V if_true, V if_false) { return m ? if_true : if_false; }
static inline float v_hsum(V a) { return a; }
static inline float v_hmax(V a) { return a; }

static inline void v_transpose(V r[VW]) { (void)r; }

#endif
