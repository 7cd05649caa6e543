/* Shared pieces of the kernel tests: the tables to test (every SIMD level this CPU runs, plus
 * the shared body over one-lane vectors), random buffers with guard zones, and tolerance
 * checks that report the worst element. The scalar oracle is the reference throughout. */
#ifndef WEFT_TEST_KERNEL_CHECK_H
#define WEFT_TEST_KERNEL_CHECK_H

#include "test.h"

#include "kernels/kernels.h"
#include "kernels/kernels_internal.h"

#include <stdint.h>

typedef struct kc_table {
    const char *name;
    const weft_kernels *k;
} kc_table;

/* Fills out[] with the tables to test and returns how many. */
static inline int kc_tables(kc_table out[8])
{
    int n = 0;
    out[n++] = (kc_table){"generic", &weft__kernels_generic};
    static const weft_isa levels[] = {WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    for (size_t i = 0; i < sizeof levels / sizeof levels[0]; ++i) {
        const weft_kernels *k = weft_kernels_for_isa(levels[i]);
        if (k) {
            out[n++] = (kc_table){weft_isa_name(levels[i]), k};
        }
    }
    return n;
}

static inline const weft_kernels *kc_oracle(void) { return &weft__kernels_scalar; }

/* Buffer with GUARD floats of a sentinel on each side, to catch writes out of bounds. */
#define KC_GUARD 32
#define KC_SENTINEL 1234.5f

typedef struct kc_buf {
    float *base;
    float *p; /* the usable part */
    size_t n;
} kc_buf;

static inline kc_buf kc_alloc(size_t n)
{
    kc_buf b;
    b.n = n;
    b.base = (float *)malloc((n + 2 * KC_GUARD) * sizeof(float));
    if (!b.base) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    for (size_t i = 0; i < n + 2 * KC_GUARD; ++i) {
        b.base[i] = KC_SENTINEL;
    }
    b.p = b.base + KC_GUARD;
    return b;
}

static inline void kc_free(kc_buf *b)
{
    free(b->base);
    b->base = b->p = NULL;
}

static inline bool kc_guards_intact(const kc_buf *b)
{
    for (size_t i = 0; i < KC_GUARD; ++i) {
        if (b->base[i] != KC_SENTINEL || b->p[b->n + i] != KC_SENTINEL) {
            return false;
        }
    }
    return true;
}

static inline void kc_fill(test_rng *r, float *x, size_t n, float lo, float hi)
{
    for (size_t i = 0; i < n; ++i) {
        x[i] = test_rng_float(r, lo, hi);
    }
}

/* Worst violation of |got - want| <= atol + rtol * scale[i] (scale NULL: |want|), over n
 * elements at stride 1. Returns the worst ratio error / allowed (pass when <= 1) and its index. */
static inline double kc_worst(const float *got, const float *want, const float *scale, size_t n, double atol,
                              double rtol, size_t *where)
{
    double worst = 0.0;
    size_t at = 0;
    for (size_t i = 0; i < n; ++i) {
        const double g = got[i], w = want[i];
        const double s = scale ? scale[i] : fabs(w);
        const double allowed = atol + rtol * s;
        double ratio;
        if (isnan(g) || isnan(w)) {
            ratio = (isnan(g) && isnan(w)) ? 0.0 : INFINITY;
        } else if (isinf(g) || isinf(w)) {
            ratio = g == w ? 0.0 : INFINITY;
        } else {
            ratio = fabs(g - w) / allowed;
        }
        if (ratio > worst) {
            worst = ratio;
            at = i;
        }
    }
    if (where) {
        *where = at;
    }
    return worst;
}

/* CHECK that got matches want within tolerance, naming the table and the case. */
#define KC_CHECK_CLOSE(tbl, what, got, want, scale, n, atol, rtol)                                          \
    do {                                                                                                  \
        size_t at_;                                                                                       \
        const double w_ = kc_worst((got), (want), (scale), (n), (atol), (rtol), &at_);                    \
        CHECK_MSG(w_ <= 1.0, "[%s] %s: element %zu got %.9g want %.9g (error %.3g x allowed)", (tbl),     \
                  (what), at_, (double)(got)[at_], (double)(want)[at_], w_);                               \
    } while (0)

#endif
