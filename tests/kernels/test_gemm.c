/* GEMM of every SIMD level against the scalar oracle: awkward M/N/K (tiles, tails, the GEMV
 * path, K blocking), strides wider than the rows, bias, accumulate and every activation. Padding
 * between rows and guard zones around the buffers must stay untouched.
 *
 * Tolerance: |got - want| <= GEMM_ATOL + GEMM_RTOL * mag, where mag is the same GEMM run on the
 * absolute values (sum |a||w| + |bias| + |c|): the standard error bound of a dot product, which
 * does not blow up where the result cancels to near zero. */
#include "kernel_check.h"

#define GEMM_RTOL 1.2e-7 /* relative to mag, per term summed (K + bias + c + rounding): FLT_EPSILON */
#define GEMM_ATOL 1e-6 /* the vector exp inside GELU/SILU */

typedef struct gemm_case {
    uint32_t M, N, K;
    uint32_t pad_a, pad_w, pad_c;
    bool bias, accumulate;
    weft_activation act;
} gemm_case;

static void abs_copy(float *dst, const float *src, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        dst[i] = fabsf(src[i]);
    }
}

static void run_case(const kc_table *t, const gemm_case *c, test_rng *rng)
{
    const uint32_t lda = c->K + c->pad_a, ldw = c->K + c->pad_w, ldc = c->N + c->pad_c;
    const size_t na = (size_t)c->M * lda + 1, nw = (size_t)c->N * ldw + 1, ncc = (size_t)c->M * ldc;
    kc_buf A = kc_alloc(na), W = kc_alloc(nw), bias = kc_alloc(c->N + 1u);
    kc_buf C0 = kc_alloc(ncc), Cref = kc_alloc(ncc), Cgot = kc_alloc(ncc), mag = kc_alloc(ncc);
    kc_buf Aa = kc_alloc(na), Wa = kc_alloc(nw), ba = kc_alloc(c->N + 1u);
    kc_fill(rng, A.p, na, -1.0f, 1.0f);
    kc_fill(rng, W.p, nw, -1.0f, 1.0f);
    kc_fill(rng, bias.p, c->N + 1u, -0.5f, 0.5f);
    kc_fill(rng, C0.p, ncc, -2.0f, 2.0f);
    /* padding columns of C carry a sentinel that the kernel must preserve */
    for (uint32_t m = 0; m < c->M; ++m) {
        for (uint32_t n = c->N; n < ldc; ++n) {
            C0.p[(size_t)m * ldc + n] = KC_SENTINEL;
        }
    }
    memcpy(Cref.p, C0.p, ncc * sizeof(float));
    memcpy(Cgot.p, C0.p, ncc * sizeof(float));
    abs_copy(Aa.p, A.p, na);
    abs_copy(Wa.p, W.p, nw);
    abs_copy(ba.p, bias.p, c->N + 1u);
    abs_copy(mag.p, C0.p, ncc);

    const float *b = c->bias ? bias.p : NULL;
    kc_oracle()->gemm(c->M, c->N, c->K, A.p, lda, W.p, ldw, b, Cref.p, ldc, c->act, c->accumulate);
    t->k->gemm(c->M, c->N, c->K, A.p, lda, W.p, ldw, b, Cgot.p, ldc, c->act, c->accumulate);
    kc_oracle()->gemm(c->M, c->N, c->K, Aa.p, lda, Wa.p, ldw, c->bias ? ba.p : NULL, mag.p, ldc, WEFT_ACT_NONE,
                      c->accumulate);

    char what[160];
    snprintf(what, sizeof what, "gemm M=%u N=%u K=%u lda=%u ldw=%u ldc=%u bias=%d acc=%d act=%d", c->M, c->N, c->K,
             lda, ldw, ldc, c->bias, c->accumulate, (int)c->act);
    const double rtol = GEMM_RTOL * (double)(c->K + 4u);
    for (uint32_t m = 0; m < c->M; ++m) {
        const size_t o = (size_t)m * ldc;
        KC_CHECK_CLOSE(t->name, what, Cgot.p + o, Cref.p + o, mag.p + o, c->N, GEMM_ATOL, rtol);
        bool pad_ok = true;
        for (uint32_t n = c->N; n < ldc; ++n) {
            pad_ok = pad_ok && Cgot.p[o + n] == KC_SENTINEL;
        }
        CHECK_MSG(pad_ok, "[%s] %s: row %u padding overwritten", t->name, what, m);
    }
    CHECK_MSG(kc_guards_intact(&Cgot), "[%s] %s: write outside C", t->name, what);
    kc_buf *all[] = {&A, &W, &bias, &C0, &Cref, &Cgot, &mag, &Aa, &Wa, &ba};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; ++i) {
        kc_free(all[i]);
    }
}

static void test_gemm_awkward_sizes(void)
{
    static const uint32_t Ms[] = {1, 2, 3, 4, 5, 7, 12, 13, 17, 31, 33, 50};
    static const uint32_t Ns[] = {1, 2, 3, 4, 8, 16, 17, 31, 32, 33, 65};
    static const uint32_t Ks[] = {0, 1, 3, 16, 17, 31, 33, 64, 257, 300};
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {0x9e3779b97f4a7c15ull};
    unsigned variant = 0;
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t i = 0; i < sizeof Ms / sizeof Ms[0]; ++i) {
            for (size_t j = 0; j < sizeof Ns / sizeof Ns[0]; ++j) {
                for (size_t k = 0; k < sizeof Ks / sizeof Ks[0]; ++k) {
                    variant++;
                    const gemm_case c = {
                        .M = Ms[i], .N = Ns[j], .K = Ks[k],
                        .pad_a = variant % 3, .pad_w = (variant / 3) % 2, .pad_c = (variant / 2) % 3,
                        .bias = (variant % 2) == 0, .accumulate = (variant % 5) == 1,
                        .act = (weft_activation)(variant % 4),
                    };
                    run_case(&tabs[ti], &c, &rng);
                }
            }
        }
    }
}

/* Every epilogue combination at a shape with full tiles and tails in both directions. */
static void test_gemm_epilogues(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {12345};
    for (int ti = 0; ti < nt; ++ti) {
        for (int act = 0; act < 4; ++act) {
            for (int flags = 0; flags < 4; ++flags) {
                const uint32_t Ms[] = {1, 37};
                for (int mi = 0; mi < 2; ++mi) {
                    const gemm_case c = {.M = Ms[mi], .N = 45, .K = 70, .pad_a = 1, .pad_w = 2, .pad_c = 3,
                                         .bias = flags & 1, .accumulate = (flags >> 1) & 1,
                                         .act = (weft_activation)act};
                    run_case(&tabs[ti], &c, &rng);
                }
            }
        }
    }
}

/* The shapes the cloth model runs (scaled down in M where the oracle would be slow). */
static void test_gemm_model_shapes(void)
{
    const gemm_case cases[] = {
        {.M = 512, .N = 64, .K = 64, .bias = true, .act = WEFT_ACT_GELU},
        {.M = 300, .N = 128, .K = 128, .bias = true, .act = WEFT_ACT_NONE, .accumulate = true},
        {.M = 64, .N = 256, .K = 256, .bias = true, .act = WEFT_ACT_SILU},
        {.M = 1, .N = 256, .K = 256, .bias = true, .act = WEFT_ACT_RELU},
        {.M = 9, .N = 100, .K = 600, .bias = false, .act = WEFT_ACT_NONE},
        {.M = 1000, .N = 3, .K = 128, .bias = true, .act = WEFT_ACT_NONE, .accumulate = true, .pad_c = 2},
        {.M = 333, .N = 1, .K = 70, .bias = true, .act = WEFT_ACT_SILU},
    };
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {777};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
            run_case(&tabs[ti], &cases[i], &rng);
        }
    }
}

static void test_tables_listed(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    printf("testing:");
    for (int i = 0; i < nt; ++i) {
        printf(" %s", tabs[i].name);
        CHECK(tabs[i].k->gemm != NULL);
    }
    printf("\n");
    CHECK(nt >= 1);
}

TEST_MAIN(TEST_CASE(test_tables_listed), TEST_CASE(test_gemm_awkward_sizes), TEST_CASE(test_gemm_epilogues),
          TEST_CASE(test_gemm_model_shapes))
