/* Row-wise and elementwise kernels of every SIMD level against the scalar oracle: softmax,
 * layernorm, rmsnorm, gelu, silu, swiglu, posembed and csr_aggregate, at awkward sizes with
 * padded strides, in-place use, and special values (-inf, fully masked rows, empty CSR rows).
 * Also measures the accuracy of the vector transcendentals against double-precision libm.
 *
 * Named tolerances (|got - want| <= ATOL + RTOL * |want| unless said otherwise): */
#include "kernel_check.h"

#define SOFTMAX_ATOL 1e-7   /* probabilities in [0, 1] */
#define SOFTMAX_RTOL 2e-6
#define NORM_ATOL 2e-6      /* normalised rows are O(1); cancellation in x - mean */
#define NORM_RTOL 2e-6
#define ACT_ATOL 1e-7       /* gelu, silu, swiglu: vector exp + exact divide */
#define ACT_RTOL 2e-6
#define POSEMBED_ATOL 1e-6  /* sin/cos of |arg| up to ~1e3 (vector Cody-Waite reduction) */
#define CSR_RTOL 1e-5       /* relative to sum |x| over the neighbours */

static const uint32_t k_sizes[] = {1, 2, 3, 7, 8, 15, 16, 17, 31, 33, 64, 100, 257};
#define NSIZES (sizeof k_sizes / sizeof k_sizes[0])

static void test_softmax(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {1};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t ci = 0; ci < NSIZES; ++ci) {
            const uint32_t cols = k_sizes[ci], rows = 5, ld = cols + 3;
            const size_t n = (size_t)rows * ld;
            kc_buf ref = kc_alloc(n), got = kc_alloc(n);
            kc_fill(&rng, ref.p, n, -30.0f, 30.0f);
            for (uint32_t c = 0; c < cols; ++c) {
                ref.p[1 * ld + c] = -INFINITY;                  /* row 1: fully masked */
                if (c % 2) {
                    ref.p[2 * ld + c] = -INFINITY;              /* row 2: half masked */
                }
                ref.p[3 * ld + c] = (float)(c % 3) * 1e-3f;     /* row 3: near-uniform */
            }
            for (uint32_t r = 0; r < rows; ++r) {
                for (uint32_t c = cols; c < ld; ++c) {
                    ref.p[(size_t)r * ld + c] = KC_SENTINEL;
                }
            }
            memcpy(got.p, ref.p, n * sizeof(float));
            kc_oracle()->softmax_rows(ref.p, rows, cols, ld);
            tabs[ti].k->softmax_rows(got.p, rows, cols, ld);
            char what[64];
            snprintf(what, sizeof what, "softmax cols=%u", cols);
            KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, NULL, n, SOFTMAX_ATOL, SOFTMAX_RTOL);
            bool zeros = true, nan_free = true;
            for (uint32_t c = 0; c < cols; ++c) {
                zeros = zeros && got.p[1 * ld + c] == 0.0f;
                if (c % 2) {
                    zeros = zeros && got.p[2 * ld + c] == 0.0f;
                }
            }
            for (size_t i = 0; i < n; ++i) {
                nan_free = nan_free && !isnan(got.p[i]);
            }
            CHECK_MSG(zeros, "[%s] %s: masked entries must be exactly 0", tabs[ti].name, what);
            CHECK_MSG(nan_free, "[%s] %s: NaN in output", tabs[ti].name, what);
            CHECK(kc_guards_intact(&got));
            kc_free(&ref);
            kc_free(&got);
        }
    }
}

static void test_norms(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {2};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t ci = 0; ci < NSIZES; ++ci) {
            for (int variant = 0; variant < 4; ++variant) {
                const uint32_t cols = k_sizes[ci], rows = 4, ld = cols + (uint32_t)variant;
                const size_t n = (size_t)rows * ld;
                const bool use_gamma = variant & 1, use_beta = variant & 2, in_place = variant == 3;
                kc_buf x = kc_alloc(n), ref = kc_alloc(n), got = kc_alloc(n), g = kc_alloc(cols), b = kc_alloc(cols);
                kc_fill(&rng, x.p, n, -3.0f, 5.0f);
                kc_fill(&rng, g.p, cols, 0.5f, 1.5f);
                kc_fill(&rng, b.p, cols, -0.5f, 0.5f);
                for (size_t i = 0; i < n; ++i) {
                    ref.p[i] = got.p[i] = KC_SENTINEL;
                }
                const float *gamma = use_gamma ? g.p : NULL, *beta = use_beta ? b.p : NULL;
                char what[80];
                /* layernorm */
                kc_oracle()->layernorm(x.p, ref.p, rows, cols, ld, gamma, beta, 1e-5f);
                if (in_place) {
                    memcpy(got.p, x.p, n * sizeof(float));
                    tabs[ti].k->layernorm(got.p, got.p, rows, cols, ld, gamma, beta, 1e-5f);
                } else {
                    tabs[ti].k->layernorm(x.p, got.p, rows, cols, ld, gamma, beta, 1e-5f);
                }
                snprintf(what, sizeof what, "layernorm cols=%u variant=%d", cols, variant);
                for (uint32_t r = 0; r < rows; ++r) {
                    KC_CHECK_CLOSE(tabs[ti].name, what, got.p + (size_t)r * ld, ref.p + (size_t)r * ld, NULL, cols,
                                   NORM_ATOL, NORM_RTOL);
                }
                /* rmsnorm */
                for (size_t i = 0; i < n; ++i) {
                    ref.p[i] = got.p[i] = KC_SENTINEL;
                }
                kc_oracle()->rmsnorm(x.p, ref.p, rows, cols, ld, gamma, 1e-6f);
                if (in_place) {
                    memcpy(got.p, x.p, n * sizeof(float));
                    tabs[ti].k->rmsnorm(got.p, got.p, rows, cols, ld, gamma, 1e-6f);
                } else {
                    tabs[ti].k->rmsnorm(x.p, got.p, rows, cols, ld, gamma, 1e-6f);
                }
                snprintf(what, sizeof what, "rmsnorm cols=%u variant=%d", cols, variant);
                for (uint32_t r = 0; r < rows; ++r) {
                    KC_CHECK_CLOSE(tabs[ti].name, what, got.p + (size_t)r * ld, ref.p + (size_t)r * ld, NULL, cols,
                                   NORM_ATOL, NORM_RTOL);
                }
                if (!in_place) {
                    bool pad_ok = true;
                    for (uint32_t r = 0; r < rows; ++r) {
                        for (uint32_t c = cols; c < ld; ++c) {
                            pad_ok = pad_ok && got.p[(size_t)r * ld + c] == KC_SENTINEL;
                        }
                    }
                    CHECK_MSG(pad_ok, "[%s] %s: padding overwritten", tabs[ti].name, what);
                }
                CHECK(kc_guards_intact(&got));
                kc_buf *all[] = {&x, &ref, &got, &g, &b};
                for (size_t i = 0; i < 5; ++i) {
                    kc_free(all[i]);
                }
            }
        }
    }
}

static void test_activations(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {3};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t ci = 0; ci < NSIZES; ++ci) {
            const size_t n = k_sizes[ci] * 3u;
            kc_buf x = kc_alloc(n), up = kc_alloc(n), ref = kc_alloc(n), got = kc_alloc(n);
            kc_fill(&rng, x.p, n, -12.0f, 12.0f);
            kc_fill(&rng, up.p, n, -2.0f, 2.0f);
            if (n > 4) {
                x.p[0] = 0.0f;
                x.p[1] = -100.0f;
                x.p[2] = 100.0f;
                x.p[3] = -1e-6f;
            }
            char what[64];
            /* gelu */
            memcpy(ref.p, x.p, n * sizeof(float));
            memcpy(got.p, x.p, n * sizeof(float));
            kc_oracle()->gelu(ref.p, n);
            tabs[ti].k->gelu(got.p, n);
            snprintf(what, sizeof what, "gelu n=%zu", n);
            KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, NULL, n, ACT_ATOL, ACT_RTOL);
            CHECK(kc_guards_intact(&got));
            /* silu */
            memcpy(ref.p, x.p, n * sizeof(float));
            memcpy(got.p, x.p, n * sizeof(float));
            kc_oracle()->silu(ref.p, n);
            tabs[ti].k->silu(got.p, n);
            snprintf(what, sizeof what, "silu n=%zu", n);
            KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, NULL, n, ACT_ATOL, ACT_RTOL);
            CHECK(kc_guards_intact(&got));
            /* swiglu, out of place and aliasing gate */
            kc_oracle()->swiglu(x.p, up.p, ref.p, n);
            tabs[ti].k->swiglu(x.p, up.p, got.p, n);
            snprintf(what, sizeof what, "swiglu n=%zu", n);
            KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, NULL, n, ACT_ATOL, ACT_RTOL);
            CHECK(kc_guards_intact(&got));
            memcpy(got.p, x.p, n * sizeof(float));
            tabs[ti].k->swiglu(got.p, up.p, got.p, n);
            KC_CHECK_CLOSE(tabs[ti].name, "swiglu in place", got.p, ref.p, NULL, n, ACT_ATOL, ACT_RTOL);
            kc_buf *all[] = {&x, &up, &ref, &got};
            for (size_t i = 0; i < 4; ++i) {
                kc_free(all[i]);
            }
        }
    }
}

static void test_posembed(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {4};
    static const uint32_t dims_list[] = {1, 3, 4};
    static const uint32_t nfreq_list[] = {1, 5, 8, 16, 21};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t a = 0; a < 3; ++a) {
            for (size_t b = 0; b < 5; ++b) {
                const uint32_t dims = dims_list[a], nfreq = nfreq_list[b], n = 37;
                const uint32_t w = dims * nfreq * 2, ldo = w + 5;
                kc_buf x = kc_alloc((size_t)n * dims), f = kc_alloc(nfreq);
                kc_buf ref = kc_alloc((size_t)n * ldo), got = kc_alloc((size_t)n * ldo);
                kc_fill(&rng, x.p, (size_t)n * dims, -2.0f, 2.0f);
                for (uint32_t i = 0; i < nfreq; ++i) {
                    f.p[i] = 3.14159265f * (float)(1u << (i % 9)); /* up to 256 pi: |arg| ~ 1.6e3 */
                }
                x.p[0] = 0.0f;
                if (n * dims > 2) {
                    x.p[1] = 9000.0f; /* beyond the vector reduction range: libm fallback */
                }
                for (size_t i = 0; i < (size_t)n * ldo; ++i) {
                    ref.p[i] = got.p[i] = KC_SENTINEL;
                }
                kc_oracle()->posembed(x.p, n, dims, f.p, nfreq, ref.p, ldo);
                tabs[ti].k->posembed(x.p, n, dims, f.p, nfreq, got.p, ldo);
                char what[64];
                snprintf(what, sizeof what, "posembed dims=%u nfreq=%u", dims, nfreq);
                /* includes the padding: sentinels must match (untouched) */
                KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, NULL, (size_t)n * ldo, POSEMBED_ATOL, 0.0);
                CHECK(kc_guards_intact(&got));
                kc_buf *all[] = {&x, &f, &ref, &got};
                for (size_t i = 0; i < 4; ++i) {
                    kc_free(all[i]);
                }
            }
        }
    }
}

static void test_csr_aggregate(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {5};
    static const uint32_t dims[] = {1, 3, 16, 17, 100, 128, 129, 257};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t di = 0; di < sizeof dims / sizeof dims[0]; ++di) {
            for (int mean = 0; mean < 2; ++mean) {
                const uint32_t rows = 33, nsrc = 50, dim = dims[di], ldx = dim + 2, ldo = dim + 1;
                uint32_t rowptr[34];
                uint32_t col[33 * 9];
                rowptr[0] = 0;
                for (uint32_t r = 0; r < rows; ++r) {
                    const uint32_t deg = r % 5 == 0 ? 0 : test_rng_u32(&rng) % 9; /* some empty rows */
                    for (uint32_t j = 0; j < deg; ++j) {
                        col[rowptr[r] + j] = test_rng_u32(&rng) % nsrc;
                    }
                    rowptr[r + 1] = rowptr[r] + deg;
                }
                kc_buf X = kc_alloc((size_t)nsrc * ldx), ref = kc_alloc((size_t)rows * ldo), got = kc_alloc((size_t)rows * ldo);
                kc_buf Xa = kc_alloc((size_t)nsrc * ldx), mag = kc_alloc((size_t)rows * ldo);
                kc_fill(&rng, X.p, (size_t)nsrc * ldx, -1.0f, 1.0f);
                for (size_t i = 0; i < (size_t)nsrc * ldx; ++i) {
                    Xa.p[i] = fabsf(X.p[i]);
                }
                for (size_t i = 0; i < (size_t)rows * ldo; ++i) {
                    ref.p[i] = got.p[i] = mag.p[i] = KC_SENTINEL;
                }
                kc_oracle()->csr_aggregate(rowptr, col, rows, X.p, ldx, dim, ref.p, ldo, mean);
                kc_oracle()->csr_aggregate(rowptr, col, rows, Xa.p, ldx, dim, mag.p, ldo, mean);
                tabs[ti].k->csr_aggregate(rowptr, col, rows, X.p, ldx, dim, got.p, ldo, mean);
                char what[64];
                snprintf(what, sizeof what, "csr_aggregate dim=%u mean=%d", dim, mean);
                KC_CHECK_CLOSE(tabs[ti].name, what, got.p, ref.p, mag.p, (size_t)rows * ldo, 0.0, CSR_RTOL);
                bool empty_zero = true;
                for (uint32_t r = 0; r < rows; r += 5) {
                    for (uint32_t j = 0; j < dim; ++j) {
                        empty_zero = empty_zero && got.p[(size_t)r * ldo + j] == 0.0f;
                    }
                }
                CHECK_MSG(empty_zero, "[%s] %s: empty rows must be zero", tabs[ti].name, what);
                CHECK(kc_guards_intact(&got));
                kc_buf *all[] = {&X, &ref, &got, &Xa, &mag};
                for (size_t i = 0; i < 5; ++i) {
                    kc_free(all[i]);
                }
            }
        }
    }
}

/* Accuracy of the vector transcendentals against double precision, through the kernels that
 * use them. Prints the measured worst errors (docs/KERNELS.md quotes them). */
static void test_transcendental_accuracy(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    enum { N = 200001 };
    float *x = (float *)malloc(N * sizeof(float)), *y = (float *)malloc(N * sizeof(float));
    float *o = (float *)malloc((size_t)N * 2 * sizeof(float));
    CHECK(x && y && o);
    if (!x || !y || !o) {
        return;
    }
    for (int ti = 0; ti < nt; ++ti) {
        /* silu(x) / x = sigmoid(x) = 1 / (1 + exp(-x)) isolates the vector exp for x < 0. */
        double worst_sig = 0.0, worst_gelu = 0.0, worst_sin = 0.0;
        for (int i = 0; i < N; ++i) {
            x[i] = -80.0f + 80.0f * (float)i / (float)(N - 1);
        }
        x[N - 1] = -1e-3f;
        memcpy(y, x, N * sizeof(float));
        tabs[ti].k->silu(y, N);
        for (int i = 0; i < N; ++i) {
            const double want = 1.0 / (1.0 + exp(-(double)x[i]));
            const double got = (double)y[i] / (double)x[i];
            worst_sig = fmax(worst_sig, fabs(got - want) / want);
        }
        for (int i = 0; i < N; ++i) {
            x[i] = -8.0f + 16.0f * (float)i / (float)(N - 1);
        }
        memcpy(y, x, N * sizeof(float));
        tabs[ti].k->gelu(y, N);
        for (int i = 0; i < N; ++i) {
            const double xd = x[i];
            /* 0.5 x (1 + tanh(u)) written as x / (1 + exp(-2u)): the tanh form cancels to 0 even in
             * double for x below about -6 */
            const double want = xd / (1.0 + exp(-2.0 * 0.7978845608028654 * (xd + 0.044715 * xd * xd * xd)));
            if (fabs(want) > 1e-30) {
                worst_gelu = fmax(worst_gelu, fabs(y[i] - want) / fabs(want));
            }
        }
        const float one = 1.0f;
        for (int i = 0; i < N; ++i) {
            x[i] = -1000.0f + 2000.0f * (float)i / (float)(N - 1);
        }
        tabs[ti].k->posembed(x, N, 1, &one, 1, o, 2);
        for (int i = 0; i < N; ++i) {
            worst_sin = fmax(worst_sin, fabs(o[2 * i] - sin((double)x[i])));
            worst_sin = fmax(worst_sin, fabs(o[2 * i + 1] - cos((double)x[i])));
        }
        printf("[%s] sigmoid rel err %.3g (x in [-80,0]), gelu rel err %.3g (x in [-8,8]), sin/cos abs err %.3g "
               "(|x| <= 1000)\n",
               tabs[ti].name, worst_sig, worst_gelu, worst_sin);
        CHECK_MSG(worst_sig < 1e-6, "[%s] sigmoid relative error %.3g", tabs[ti].name, worst_sig);
        /* gelu's relative error grows with |2u| (about 46 at x = -8): one float rounding of u
         * moves exp(-2u) by |2u| * 6e-8, which no exp can undo */
        CHECK_MSG(worst_gelu < 1e-5, "[%s] gelu relative error %.3g", tabs[ti].name, worst_gelu);
        CHECK_MSG(worst_sin < 1e-6, "[%s] sin/cos absolute error %.3g", tabs[ti].name, worst_sin);
    }
    free(x);
    free(y);
    free(o);
}

TEST_MAIN(TEST_CASE(test_softmax), TEST_CASE(test_norms), TEST_CASE(test_activations), TEST_CASE(test_posembed),
          TEST_CASE(test_csr_aggregate), TEST_CASE(test_transcendental_accuracy))
