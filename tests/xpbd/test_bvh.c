/* The solver's AABB tree: a query reports every primitive whose box meets the query box, and
 * the index-limited query (used for each unordered self pair once) reports exactly those
 * with a higher index, in the same order, so switching between them cannot change the
 * solver's contact order. */
#include "test.h"
#include "xpbd/xpbd.h"

#include <stdlib.h>

enum { NV = 900, NE = 700, NQ = 200, MAX_HITS = NE };

typedef struct hits {
    uint32_t prim[MAX_HITS];
    uint32_t count;
} hits;

static bool record(uint32_t prim, void *user)
{
    hits *h = user;
    if (h->count < MAX_HITS) {
        h->prim[h->count] = prim;
    }
    h->count++;
    return true;
}

/* Deterministic values in [0, 1). */
static double rnd(uint64_t *st)
{
    *st = *st * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*st >> 11) / 9007199254740992.0;
}

static bool box_meets(const double *pos, const uint32_t *e, const double lo[3], const double hi[3])
{
    for (int a = 0; a < 3; ++a) {
        double mn = pos[3 * e[0] + a] < pos[3 * e[1] + a] ? pos[3 * e[0] + a] : pos[3 * e[1] + a];
        double mx = pos[3 * e[0] + a] > pos[3 * e[1] + a] ? pos[3 * e[0] + a] : pos[3 * e[1] + a];
        if (mn > hi[a] || mx < lo[a]) {
            return false;
        }
    }
    return true;
}

static void test_query_above_matches_filtered_query(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    static double pos[3 * NV];
    static uint32_t edges[2 * NE];
    uint64_t st = 12345;
    for (int i = 0; i < 3 * NV; ++i) {
        pos[i] = rnd(&st);
    }
    /* Short random edges, numbered in no spatial order. */
    for (int e = 0; e < NE; ++e) {
        uint32_t a = (uint32_t)(rnd(&st) * NV);
        uint32_t b = (uint32_t)(rnd(&st) * NV);
        edges[2 * e] = a;
        edges[2 * e + 1] = b == a ? (a + 1) % NV : b;
    }
    xbvh bvh;
    CHECK_RESULT(xbvh_create(ctx, &bvh, edges, NE, 2), WEFT_OK);
    xbvh_build(&bvh, pos);
    xbvh_refit(&bvh, pos, NULL, 0.0);
    uint32_t nonempty = 0;
    for (int q = 0; q < NQ; ++q) {
        double c[3] = {rnd(&st), rnd(&st), rnd(&st)}, r = 0.02 + 0.2 * rnd(&st);
        double lo[3] = {c[0] - r, c[1] - r, c[2] - r}, hi[3] = {c[0] + r, c[1] + r, c[2] + r};
        uint32_t above = (uint32_t)(rnd(&st) * NE);
        hits all = {0}, upper = {0};
        CHECK(xbvh_query(&bvh, lo, hi, record, &all));
        CHECK(xbvh_query_above(&bvh, lo, hi, above, record, &upper));
        CHECK(all.count <= MAX_HITS && upper.count <= all.count);
        /* Every primitive whose own box meets the query box is reported, once. */
        uint32_t truth = 0, found = 0;
        for (uint32_t e = 0; e < NE; ++e) {
            if (!box_meets(pos, edges + 2 * e, lo, hi)) {
                continue;
            }
            truth++;
            uint32_t seen = 0;
            for (uint32_t k = 0; k < all.count; ++k) {
                seen += all.prim[k] == e;
            }
            found += seen == 1;
        }
        CHECK_EQ_INT(found, truth);
        nonempty += truth > 0;
        /* The limited query is the full one with lower indices removed, order kept. */
        uint32_t j = 0;
        for (uint32_t k = 0; k < all.count; ++k) {
            if (all.prim[k] > above) {
                CHECK(j < upper.count && upper.prim[j] == all.prim[k]);
                j++;
            }
        }
        CHECK_EQ_INT(j, upper.count);
    }
    CHECK(nonempty > NQ / 2); /* the queries do exercise the tree */
    xbvh_destroy(ctx, &bvh);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_query_above_matches_filtered_query))
