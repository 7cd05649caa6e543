/* Multi-head attention of every SIMD level against the scalar oracle: many queries x few keys
 * (decoder) and few queries x many keys (encoder), awkward nq/nk/heads/dh (tile tails, head
 * widths above the transposed-key chunk), strided Q/K/V/out, byte masks with fully masked rows,
 * key biases (and log w on a key against w copies of it), and the scratch size from weft_attention_scratch() (guarded: overruns are caught).
 *
 * Tolerance: outputs are convex combinations of V rows (|V| <= 1), so an absolute bound fits:
 * ATTN_ATOL covers score rounding over dh terms and the vector exp. */
#include "kernel_check.h"

#define ATTN_ATOL 2e-5

typedef struct attn_case {
    uint32_t nq, nk, heads, dh;
    uint32_t pad; /* extra floats per row of Q, K, V and out */
    int mask;     /* 0 none, 1 random, 2 random with every 3rd row fully masked,
                     3 random with even rows masked on their first 300 keys */
} attn_case;

static void run_case(const kc_table *t, const attn_case *c, test_rng *rng)
{
    const uint32_t w = c->heads * c->dh;
    const uint32_t ldq = w + c->pad, ldk = w + 2 * c->pad, ldv = w + c->pad / 2, ldo = w + c->pad;
    const size_t nQ = (size_t)c->nq * ldq, nK = (size_t)c->nk * ldk, nV = (size_t)c->nk * ldv;
    const size_t nO = (size_t)c->nq * ldo;
    kc_buf Q = kc_alloc(nQ), K = kc_alloc(nK), V = kc_alloc(nV), Oref = kc_alloc(nO), Ogot = kc_alloc(nO);
    kc_buf scratch = kc_alloc(weft_attention_scratch(c->nq, c->nk));
    kc_buf scratch_ref = kc_alloc(weft_attention_scratch(c->nq, c->nk));
    kc_fill(rng, Q.p, nQ, -1.0f, 1.0f);
    kc_fill(rng, K.p, nK, -1.0f, 1.0f);
    kc_fill(rng, V.p, nV, -1.0f, 1.0f);
    for (size_t i = 0; i < nO; ++i) {
        Oref.p[i] = Ogot.p[i] = KC_SENTINEL;
    }
    uint8_t *mask = NULL;
    if (c->mask) {
        mask = (uint8_t *)malloc((size_t)c->nq * c->nk);
        CHECK(mask != NULL);
        if (!mask) {
            return;
        }
        for (uint32_t q = 0; q < c->nq; ++q) {
            for (uint32_t k = 0; k < c->nk; ++k) {
                uint8_t visible = (c->mask == 2 && q % 3 == 1) ? 0 : (test_rng_u32(rng) % 4 != 0);
                if (c->mask == 3 && q % 2 == 0) {
                    visible = k >= 300; /* whole leading key blocks masked, later ones visible */
                }
                mask[(size_t)q * c->nk + k] = visible;
            }
        }
    }
    /* odd paddings also weigh the keys: key_bias in [-2, 2] */
    float *bias = NULL;
    if (c->pad % 2 && c->nk > 0) {
        bias = (float *)malloc((size_t)c->nk * sizeof(float));
        CHECK(bias != NULL);
        for (uint32_t k = 0; bias && k < c->nk; ++k) {
            bias[k] = test_rng_float(rng, -2.0f, 2.0f);
        }
    }
    const float scale = 1.0f / sqrtf((float)c->dh);
    kc_oracle()->attention(Q.p, ldq, K.p, ldk, V.p, ldv, c->nq, c->nk, c->heads, c->dh, scale, mask, bias, Oref.p, ldo,
                           scratch_ref.p);
    t->k->attention(Q.p, ldq, K.p, ldk, V.p, ldv, c->nq, c->nk, c->heads, c->dh, scale, mask, bias, Ogot.p, ldo, scratch.p);

    char what[160];
    snprintf(what, sizeof what, "attention nq=%u nk=%u heads=%u dh=%u pad=%u mask=%d bias=%d", c->nq, c->nk,
             c->heads, c->dh, c->pad, c->mask, bias != NULL);
    bool pad_ok = true, masked_zero = true;
    for (uint32_t q = 0; q < c->nq; ++q) {
        const float *g = Ogot.p + (size_t)q * ldo;
        KC_CHECK_CLOSE(t->name, what, g, Oref.p + (size_t)q * ldo, NULL, w, ATTN_ATOL, 0.0);
        for (uint32_t j = w; j < ldo; ++j) {
            pad_ok = pad_ok && g[j] == KC_SENTINEL;
        }
        bool all_masked = c->nk == 0 || mask != NULL;
        for (uint32_t k = 0; mask && k < c->nk; ++k) {
            all_masked = all_masked && !mask[(size_t)q * c->nk + k];
        }
        for (uint32_t j = 0; all_masked && j < w; ++j) {
            masked_zero = masked_zero && g[j] == 0.0f;
        }
    }
    CHECK_MSG(pad_ok, "[%s] %s: padding of out overwritten", t->name, what);
    CHECK_MSG(masked_zero, "[%s] %s: a fully masked row is not zero", t->name, what);
    CHECK_MSG(kc_guards_intact(&Ogot), "[%s] %s: write outside out", t->name, what);
    CHECK_MSG(kc_guards_intact(&scratch), "[%s] %s: scratch overrun", t->name, what);
    free(mask);
    free(bias);
    kc_buf *all[] = {&Q, &K, &V, &Oref, &Ogot, &scratch, &scratch_ref};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; ++i) {
        kc_free(all[i]);
    }
}

static void test_attention_awkward_sizes(void)
{
    static const uint32_t nqs[] = {1, 3, 17, 33, 100};
    static const uint32_t nks[] = {1, 3, 17, 31, 33, 257};
    static const uint32_t hs[] = {1, 3};
    static const uint32_t dhs[] = {1, 3, 16, 17, 32, 33, 65};
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {0xabcdef12345ull};
    unsigned variant = 0;
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t a = 0; a < sizeof nqs / sizeof nqs[0]; ++a) {
            for (size_t b = 0; b < sizeof nks / sizeof nks[0]; ++b) {
                for (size_t c = 0; c < sizeof hs / sizeof hs[0]; ++c) {
                    for (size_t d = 0; d < sizeof dhs / sizeof dhs[0]; ++d) {
                        variant++;
                        /* the one-lane generic body is slow; half the grid still covers its paths */
                        if (tabs[ti].k == &weft__kernels_generic && variant % 2) {
                            continue;
                        }
                        const attn_case ac = {.nq = nqs[a], .nk = nks[b], .heads = hs[c], .dh = dhs[d],
                                              .pad = variant % 4, .mask = (int)(variant % 3)};
                        run_case(&tabs[ti], &ac, &rng);
                    }
                }
            }
        }
    }
}

/* The model's two regimes at full size: decoder (4096 queries x 64 latent keys) and encoder
 * (64 latent queries x 4096 vertex keys), 4 heads of 32. */
static void test_attention_model_shapes(void)
{
    const attn_case cases[] = {
        {.nq = 4096, .nk = 64, .heads = 4, .dh = 32, .pad = 0, .mask = 0},
        {.nq = 64, .nk = 4096, .heads = 4, .dh = 32, .pad = 0, .mask = 1},
        {.nq = 5, .nk = 3000, .heads = 2, .dh = 24, .pad = 3, .mask = 2},
        {.nq = 30, .nk = 700, .heads = 3, .dh = 20, .pad = 1, .mask = 3},
    };
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {4242};
    for (int ti = 0; ti < nt; ++ti) {
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
            /* the one-lane generic body is slow at full size and adds no coverage there */
            if (tabs[ti].k == &weft__kernels_generic && cases[i].nq * cases[i].nk > 100000u) {
                continue;
            }
            run_case(&tabs[ti], &cases[i], &rng);
        }
    }
}

/* No keys at all: every output row is zero, and nothing is read from K or V. */
static void test_attention_no_keys(void)
{
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    for (int ti = 0; ti < nt; ++ti) {
        float out[2 * 8];
        for (size_t i = 0; i < 16; ++i) {
            out[i] = 5.0f;
        }
        float scratch[64];
        const float q[16] = {1.0f};
        tabs[ti].k->attention(q, 8, NULL, 8, NULL, 8, 2, 0, 2, 4, 0.5f, NULL, NULL, out, 8, scratch);
        bool zero = true;
        for (size_t i = 0; i < 16; ++i) {
            zero = zero && out[i] == 0.0f;
        }
        CHECK_MSG(zero, "[%s] attention with nk = 0 must give zeros", tabs[ti].name);
        CHECK(weft_attention_scratch(2, 0) <= 64);
    }
}

/* key_bias = log w weighs a key as w copies of it: 64 queries over 300 keys, each key k of the
 * first 100 given w = 1 + k % 4 by its bias, against the same keys written out w times. */
static void test_attention_key_weight_is_copies(void)
{
    enum { NQ = 64, NK = 300, H = 4, DH = 16, D = H * DH };
    kc_table tabs[8];
    const int nt = kc_tables(tabs);
    test_rng rng = {77};
    float *Q = malloc(sizeof(float) * NQ * D), *K = malloc(sizeof(float) * NK * D), *V = malloc(sizeof(float) * NK * D);
    float *K2 = malloc(sizeof(float) * 4 * NK * D), *V2 = malloc(sizeof(float) * 4 * NK * D);
    float *bias = malloc(sizeof(float) * NK), *a = malloc(sizeof(float) * NQ * D), *b = malloc(sizeof(float) * NQ * D);
    float *scratch = malloc(sizeof(float) * weft_attention_scratch(NQ, 4 * NK));
    CHECK(Q && K && V && K2 && V2 && bias && a && b && scratch);
    if (Q && K && V && K2 && V2 && bias && a && b && scratch) {
        kc_fill(&rng, Q, NQ * D, -1.0f, 1.0f);
        kc_fill(&rng, K, NK * D, -1.0f, 1.0f);
        kc_fill(&rng, V, NK * D, -1.0f, 1.0f);
        uint32_t n2 = 0;
        for (uint32_t k = 0; k < NK; ++k) {
            const uint32_t w = k < 100 ? 1 + k % 4 : 1;
            bias[k] = logf((float)w);
            for (uint32_t c = 0; c < w; ++c, ++n2) {
                memcpy(K2 + (size_t)n2 * D, K + (size_t)k * D, sizeof(float) * D);
                memcpy(V2 + (size_t)n2 * D, V + (size_t)k * D, sizeof(float) * D);
            }
        }
        const float scale = 0.25f;
        for (int ti = 0; ti < nt; ++ti) {
            tabs[ti].k->attention(Q, D, K, D, V, D, NQ, NK, H, DH, scale, NULL, bias, a, D, scratch);
            tabs[ti].k->attention(Q, D, K2, D, V2, D, NQ, n2, H, DH, scale, NULL, NULL, b, D, scratch);
            double worst = 0;
            for (size_t i = 0; i < (size_t)NQ * D; ++i) {
                const double e = fabs((double)a[i] - b[i]);
                worst = e > worst ? e : worst;
            }
            CHECK_MSG(worst <= ATTN_ATOL, "[%s] a key weighted w by log w differs from w copies by %g", tabs[ti].name,
                      worst);
        }
    }
    free(Q); free(K); free(V); free(K2); free(V2); free(bias); free(a); free(b); free(scratch);
}

/* Callers size one buffer for their largest shape; that must cover every smaller one. */
static void test_attention_scratch_monotonic(void)
{
    bool ok = true;
    for (uint32_t nq = 1; nq < 200; nq += 7) {
        for (uint32_t nk = 0; nk < 5000; nk += 13) {
            const size_t s = weft_attention_scratch(nq, nk);
            ok = ok && s <= weft_attention_scratch(nq + 1, nk) && s <= weft_attention_scratch(nq, nk + 1);
        }
    }
    CHECK(ok);
}

TEST_MAIN(TEST_CASE(test_attention_scratch_monotonic), TEST_CASE(test_attention_awkward_sizes), TEST_CASE(test_attention_model_shapes),
          TEST_CASE(test_attention_no_keys), TEST_CASE(test_attention_key_weight_is_copies))
