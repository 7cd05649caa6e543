/* The geometry module's AABB tree (runtime/geometry/bvh.c): a query reports every primitive
 * whose box meets the query box, and the index-limited query (used for each unordered self pair
 * once) reports exactly those with a higher index, in the same order, so switching between them
 * cannot change the solver's contact order. The self traversal reports every pair of primitives
 * whose boxes meet exactly once. The nearest-primitive search finds the least (distance, index)
 * triangle that brute force finds, for trees of one leaf up to hundreds, after a build, after a
 * refit to moved positions and after a rebuild. */
#include "test.h"
#include "geometry/geometry.h"

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

/* NV points in the cube [0, scale)^3 and NE edges between random pairs of them, numbered in no
 * spatial order. */
static void random_edges(uint64_t *st, double scale, double *pos, uint32_t *edges)
{
    for (int i = 0; i < 3 * NV; ++i) {
        pos[i] = rnd(st);
    }
    for (int e = 0; e < NE; ++e) {
        uint32_t a = (uint32_t)(rnd(st) * NV), b = (uint32_t)(rnd(st) * NV);
        edges[2 * e] = a;
        edges[2 * e + 1] = b == a ? (a + 1) % NV : b;
    }
    for (int i = 0; i < 3 * NV; ++i) {
        pos[i] *= scale;
    }
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
    random_edges(&st, 1.0, pos, edges);
    geo_bvh bvh;
    CHECK_RESULT(geo_bvh_create(ctx, &bvh, edges, NE, 2), WEFT_OK);
    geo_bvh_build(&bvh, pos);
    geo_bvh_refit(&bvh, pos, NULL, 0.0);
    uint32_t nonempty = 0;
    for (int q = 0; q < NQ; ++q) {
        double c[3] = {rnd(&st), rnd(&st), rnd(&st)}, r = 0.02 + 0.2 * rnd(&st);
        double lo[3] = {c[0] - r, c[1] - r, c[2] - r}, hi[3] = {c[0] + r, c[1] + r, c[2] + r};
        uint32_t above = (uint32_t)(rnd(&st) * NE);
        hits all = {0}, upper = {0};
        CHECK(geo_bvh_query(&bvh, lo, hi, record, &all));
        CHECK(geo_bvh_query_above(&bvh, lo, hi, above, record, &upper));
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
    geo_bvh_destroy(ctx, &bvh);
    weft_context_destroy(ctx);
}

/* Pair flags over NE x NE, counted by the self traversal. */
static void count_pair(uint32_t a, uint32_t b, void *user)
{
    uint8_t *seen = user;
    const uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
    if (seen[(size_t)lo * NE + hi] < 255) {
        seen[(size_t)lo * NE + hi]++;
    }
    if (a == b) {
        seen[(size_t)lo * NE + hi] = 255; /* a primitive paired with itself: always wrong */
    }
}

static void test_self_pairs_cover_meeting_boxes(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    static double pos[3 * NV];
    static uint32_t edges[2 * NE];
    uint64_t st = 777;
    random_edges(&st, 0.5, pos, edges); /* in a smaller cube, so that many boxes meet */
    geo_bvh bvh;
    CHECK_RESULT(geo_bvh_create(ctx, &bvh, edges, NE, 2), WEFT_OK);
    geo_bvh_build(&bvh, pos);
    const double pad = 0.01;
    geo_bvh_refit(&bvh, pos, NULL, pad);
    uint8_t *seen = calloc((size_t)NE * NE, 1);
    CHECK(seen != NULL);
    geo_bvh_self_pairs(&bvh, count_pair, seen);
    uint32_t meeting = 0;
    for (uint32_t a = 0; a < NE; ++a) {
        for (uint32_t b = a + 1; b < NE; ++b) {
            /* the boxes grown by the refit's pad on each side meet */
            double lo[3], hi[3];
            for (int k = 0; k < 3; ++k) {
                const double p = pos[3 * edges[2 * a] + k], q = pos[3 * edges[2 * a + 1] + k];
                lo[k] = (p < q ? p : q) - 2.0 * pad;
                hi[k] = (p > q ? p : q) + 2.0 * pad;
            }
            const uint8_t n = seen[(size_t)a * NE + b];
            CHECK_MSG(n <= 1, "pair (%u, %u) reported %u times", a, b, n);
            if (box_meets(pos, edges + 2 * b, lo, hi)) {
                meeting++;
                CHECK_MSG(n == 1, "pair (%u, %u) meets but was not reported", a, b);
            }
        }
    }
    CHECK(meeting > NE); /* the traversal is exercised */
    free(seen);
    geo_bvh_destroy(ctx, &bvh);
    weft_context_destroy(ctx);
}

typedef struct nearest_hit {
    const double *pos, *p;
    const uint32_t *tris;
    double d2;
    uint32_t tri;
} nearest_hit;

/* The least (distance, index): the same answer in any visit order. */
static bool visit_nearest(uint32_t t, void *user)
{
    nearest_hit *h = user;
    const uint32_t *v = h->tris + 3 * (size_t)t;
    double bary[3];
    const double d2 = geo_point_triangle_sq(h->p, h->pos + 3 * (size_t)v[0], h->pos + 3 * (size_t)v[1],
                                            h->pos + 3 * (size_t)v[2], bary);
    if (d2 < h->d2 || (d2 == h->d2 && h->tri != UINT32_MAX && t < h->tri)) {
        h->d2 = d2;
        h->tri = t;
    }
    return true;
}

/* Searches q with a bound of r^2 on the tree as it is, and checks the brute-force answer. */
static void check_nearest(const geo_bvh *bvh, const double *pos, const uint32_t *tris, uint32_t nt, const double q[3],
                          double r, uint32_t *found)
{
    nearest_hit tree = {.pos = pos, .p = q, .tris = tris, .d2 = r * r, .tri = UINT32_MAX};
    CHECK(geo_bvh_nearest(bvh, q, &tree.d2, visit_nearest, &tree));
    nearest_hit brute = {.pos = pos, .p = q, .tris = tris, .d2 = r * r, .tri = UINT32_MAX};
    for (uint32_t t = 0; t < nt; ++t) {
        visit_nearest(t, &brute);
    }
    CHECK_MSG(tree.tri == brute.tri && tree.d2 == brute.d2, "nearest: tree %u (%g), brute force %u (%g)", tree.tri,
              tree.d2, brute.tri, brute.d2);
    *found += brute.tri != UINT32_MAX;
}

static void test_nearest_matches_brute_force(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    enum { NT = 600 };
    static double pos[3 * NV], moved[3 * NV];
    static uint32_t tris[3 * NT];
    static const uint32_t counts[] = {1, 3, 4, 5, 8, 9, 17, 100, NT};
    uint64_t st = 4242;
    uint32_t found = 0;
    for (size_t c = 0; c < sizeof counts / sizeof counts[0]; ++c) {
        const uint32_t nt = counts[c];
        for (int i = 0; i < 3 * NV; ++i) {
            pos[i] = rnd(&st);
            moved[i] = pos[i] + 0.05 * (rnd(&st) - 0.5);
        }
        for (uint32_t t = 0; t < nt; ++t) { /* small triangles: a random vertex and two near it */
            const uint32_t a = (uint32_t)(rnd(&st) * (NV - 2));
            tris[3 * t] = a, tris[3 * t + 1] = a + 1, tris[3 * t + 2] = a + 2;
        }
        geo_bvh bvh;
        CHECK_RESULT(geo_bvh_create(ctx, &bvh, tris, nt, 3), WEFT_OK);
        geo_bvh_build(&bvh, pos);
        geo_bvh_refit(&bvh, pos, NULL, 0.0);
        for (int step = 0; step < 2; ++step) {
            const double *now = step ? moved : pos;
            if (step) {
                geo_bvh_refit(&bvh, moved, NULL, 0.0);
            }
            for (int k = 0; k < 40; ++k) {
                const double q[3] = {1.2 * rnd(&st) - 0.1, 1.2 * rnd(&st) - 0.1, 1.2 * rnd(&st) - 0.1};
                check_nearest(&bvh, now, tris, nt, q, k % 4 == 0 ? 0.05 : 2.0, &found);
            }
        }
        geo_bvh_build(&bvh, moved); /* a rebuild on the moved positions */
        geo_bvh_refit(&bvh, moved, NULL, 0.0);
        for (int k = 0; k < 20; ++k) {
            const double q[3] = {rnd(&st), rnd(&st), rnd(&st)};
            check_nearest(&bvh, moved, tris, nt, q, 2.0, &found);
        }
        geo_bvh_destroy(ctx, &bvh);
    }
    CHECK(found > 250); /* most searches find a triangle within their bound */
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_query_above_matches_filtered_query), TEST_CASE(test_self_pairs_cover_meeting_boxes),
          TEST_CASE(test_nearest_matches_brute_force))
