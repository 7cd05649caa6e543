/* Collider cropping (runtime/model/crop.c and weft_garment_def.collider_crop_*):
 *   - the box rule keeps exactly the triangles of the model's training rule (model.py crop_mask),
 *     in index order, on random scenes;
 *   - the cells rule keeps a subset of the box rule and drops what lies in the box but far from
 *     every part of the garment;
 *   - the cap keeps the triangles nearest to a garment vertex, ties to the lower index, and
 *     agrees with a brute-force ranking on random scenes;
 *   - the sample cap keeps cropped triangles only, spread evenly (one per Morton block of the
 *     stride), reports the triangles each stands for, and is a no-op when the crop is under it;
 *   - through a garment: the margin and the cap change the kept token count as expected, bad
 *     values are rejected with nothing created, the step allocates nothing, and a capped int8
 *     garment gives the same bits at every kernel ISA the CPU has (either cap); a sample cap above
 *     the crop gives the uncapped garment's bits. */
#include "model/crop.h"
#include "sheet_floor_scene.h"
#include "test.h"
#include "weft.h"

#include <stdbool.h>
#include <stdint.h>

#define GAME WEFT_SOURCE_DIR "/tools/train/models/game.safetensors"

static weft_context *ctx_make(weft_isa isa)
{
    weft_context_def cd = weft_default_context_def();
    cd.isa = isa;
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        return NULL;
    }
    return ctx;
}

/* The training rule, written out independently: triangle box at t+1 overlaps the garment box
 * grown by the margin. */
static bool box_rule(const float *x, uint32_t n, const float *c, const uint32_t *tri, float margin)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; ++i) {
        for (int d = 0; d < 3; ++d) {
            lo[d] = fminf(lo[d], x[3 * i + d]);
            hi[d] = fmaxf(hi[d], x[3 * i + d]);
        }
    }
    /* Evaluate with the same float steps as the runtime: lo - margin and hi + margin once. */
    bool keep = true;
    for (int d = 0; d < 3; ++d) {
        const float glo = lo[d] - margin, ghi = hi[d] + margin;
        float tl = fminf(fminf(c[3 * tri[0] + d], c[3 * tri[1] + d]), c[3 * tri[2] + d]);
        float th = fmaxf(fmaxf(c[3 * tri[0] + d], c[3 * tri[1] + d]), c[3 * tri[2] + d]);
        keep = keep && tl <= ghi && th >= glo;
    }
    return keep;
}

static void random_scene(test_rng *r, float *x, uint32_t n, float *c, uint32_t nc, uint32_t *tris, uint32_t nt)
{
    for (uint32_t i = 0; i < 3 * n; ++i) {
        x[i] = test_rng_float(r, -0.3f, 0.3f);
    }
    for (uint32_t i = 0; i < nc; ++i) {
        const float cx = test_rng_float(r, -1.0f, 1.0f), cy = test_rng_float(r, -1.0f, 1.0f),
                    cz = test_rng_float(r, -1.0f, 1.0f);
        c[3 * i] = cx;
        c[3 * i + 1] = cy;
        c[3 * i + 2] = cz;
    }
    for (uint32_t t = 0; t < nt; ++t) {
        for (int k = 0; k < 3; ++k) {
            tris[3 * t + k] = test_rng_u32(r) % nc;
        }
    }
}

static void test_box_matches_training_rule(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    CHECK(ctx != NULL);
    enum { N = 40, NC = 300, NT = 500 };
    static float x[3 * N], c[3 * NC];
    static uint32_t tris[3 * NT];
    test_rng r = {0x9e3779b97f4a7c15ull};
    weft_crop crop;
    CHECK_RESULT(weft__crop_init(ctx, &crop, 0.15f, WEFT_COLLIDER_CROP_BOX, 0, WEFT_COLLIDER_CAP_NEAREST, N, NT, NC, NULL, NULL), WEFT_OK);
    uint32_t total = 0;
    for (int scene = 0; scene < 20; ++scene) {
        random_scene(&r, x, N, c, NC, tris, NT);
        uint32_t kept = weft__crop_select(&crop, x, N, c, tris);
        uint32_t j = 0;
        bool same = true;
        for (uint32_t t = 0; t < NT; ++t) {
            if (box_rule(x, N, c, tris + 3 * t, 0.15f)) {
                same = same && j < kept && crop.kept[j] == t;
                j++;
            }
        }
        CHECK_MSG(same && j == kept, "scene %d: %u kept, the training rule keeps %u", scene, kept, j);
        total += kept;
    }
    CHECK(total > 0 && total < 20u * NT); /* the scenes exercise both outcomes */
    weft__crop_free(ctx, &crop);
    weft_context_destroy(ctx);
}

/* A garment of two small patches at opposite corners of its box; a collider triangle in the
 * empty middle is in the box (kept by BOX) but far from both patches (dropped by CELLS). */
static void test_cells_drop_the_empty_middle(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    CHECK(ctx != NULL);
    float x[3 * 8];
    for (int i = 0; i < 4; ++i) {
        const float dx = 0.02f * (float)(i & 1), dy = 0.02f * (float)(i >> 1);
        x[3 * i] = dx, x[3 * i + 1] = dy, x[3 * i + 2] = 0.0f;                     /* patch at the origin */
        x[12 + 3 * i] = 1.0f + dx, x[13 + 3 * i] = 1.0f + dy, x[14 + 3 * i] = 1.0f; /* patch at (1, 1, 1) */
    }
    /* Triangles: 0 next to patch A, 1 in the middle of the box, 2 next to patch B, 3 outside the box. */
    const float c[] = {0.0f,  0.0f,  0.05f, 0.02f, 0.0f,  0.05f, 0.0f,  0.02f, 0.05f, /* 0 */
                       0.5f,  0.5f,  0.5f,  0.52f, 0.5f,  0.5f,  0.5f,  0.52f, 0.5f,  /* 1 */
                       1.0f,  1.0f,  0.95f, 1.02f, 1.0f,  0.95f, 1.0f,  1.02f, 0.95f, /* 2 */
                       3.0f,  3.0f,  3.0f,  3.02f, 3.0f,  3.0f,  3.0f,  3.02f, 3.0f}; /* 3 */
    const uint32_t tris[] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
    weft_crop box, cells;
    CHECK_RESULT(weft__crop_init(ctx, &box, 0.1f, WEFT_COLLIDER_CROP_BOX, 0, WEFT_COLLIDER_CAP_NEAREST, 8, 4, 12, NULL, NULL), WEFT_OK);
    CHECK_RESULT(weft__crop_init(ctx, &cells, 0.1f, WEFT_COLLIDER_CROP_CELLS, 0, WEFT_COLLIDER_CAP_NEAREST, 8, 4, 12, NULL, NULL), WEFT_OK);
    CHECK_EQ_INT(weft__crop_select(&box, x, 8, c, tris), 3);
    CHECK(box.kept[0] == 0 && box.kept[1] == 1 && box.kept[2] == 2);
    CHECK_EQ_INT(weft__crop_select(&cells, x, 8, c, tris), 2);
    CHECK(cells.kept[0] == 0 && cells.kept[1] == 2);
    weft__crop_free(ctx, &box);
    weft__crop_free(ctx, &cells);

    /* Random scenes: CELLS is always a subset of BOX. */
    enum { N = 60, NC = 200, NT = 400 };
    static float rx[3 * N], rc[3 * NC];
    static uint32_t rt[3 * NT];
    test_rng r = {12345};
    CHECK_RESULT(weft__crop_init(ctx, &box, 0.12f, WEFT_COLLIDER_CROP_BOX, 0, WEFT_COLLIDER_CAP_NEAREST, N, NT, NC, NULL, NULL), WEFT_OK);
    CHECK_RESULT(weft__crop_init(ctx, &cells, 0.12f, WEFT_COLLIDER_CROP_CELLS, 0, WEFT_COLLIDER_CAP_NEAREST, N, NT, NC, NULL, NULL), WEFT_OK);
    uint32_t fewer = 0;
    for (int scene = 0; scene < 20; ++scene) {
        random_scene(&r, rx, N, rc, NC, rt, NT);
        const uint32_t nb = weft__crop_select(&box, rx, N, rc, rt);
        const uint32_t ncl = weft__crop_select(&cells, rx, N, rc, rt);
        uint32_t j = 0;
        for (uint32_t i = 0; i < ncl; ++i) {
            while (j < nb && box.kept[j] < cells.kept[i]) {
                j++;
            }
            CHECK_MSG(j < nb && box.kept[j] == cells.kept[i], "scene %d: cells kept %u, box did not", scene,
                      cells.kept[i]);
        }
        fewer += ncl < nb;
    }
    CHECK(fewer > 0);
    weft__crop_free(ctx, &box);
    weft__crop_free(ctx, &cells);
    weft_context_destroy(ctx);
}

/* The cap keeps the nearest triangles; equal distances go to the lower index. */
static void test_cap_nearest_then_index(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    CHECK(ctx != NULL);
    /* Garment: a small square at the origin (z = 0). Triangles: small ones stacked along +z at
     * heights h[t]; 2 and 4 share a height, as do 0 and 5. */
    const float x[] = {0, 0, 0, 0.05f, 0, 0, 0, 0.05f, 0, 0.05f, 0.05f, 0};
    const float h[] = {0.08f, 0.02f, 0.05f, 0.11f, 0.05f, 0.08f, 0.5f};
    enum { NT = 7 };
    float c[NT * 9];
    uint32_t tris[NT * 3];
    for (uint32_t t = 0; t < NT; ++t) {
        const float v[9] = {0.01f, 0.01f, h[t], 0.03f, 0.01f, h[t], 0.01f, 0.03f, h[t]};
        memcpy(c + 9 * t, v, sizeof v);
        for (int k = 0; k < 3; ++k) {
            tris[3 * t + k] = 3 * t + (uint32_t)k;
        }
    }
    static const struct {
        uint32_t cap, count;
        uint32_t kept[6];
    } cases[] = {
        {1, 1, {1}}, {2, 2, {1, 2}}, {3, 3, {1, 2, 4}}, {4, 4, {0, 1, 2, 4}}, {5, 5, {0, 1, 2, 4, 5}},
        {6, 6, {0, 1, 2, 3, 4, 5}}, /* triangle 6 is beyond the margin: never kept */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        for (int rule = 0; rule < 2; ++rule) {
            weft_crop crop;
            CHECK_RESULT(weft__crop_init(ctx, &crop, 0.15f, (weft_collider_crop)rule,
                                         cases[i].cap, WEFT_COLLIDER_CAP_NEAREST, 4, NT, 3 * NT, NULL, NULL), WEFT_OK);
            const uint32_t n = weft__crop_select(&crop, x, 4, c, tris);
            bool same = n == cases[i].count;
            for (uint32_t k = 0; same && k < n; ++k) {
                same = crop.kept[k] == cases[i].kept[k];
            }
            CHECK_MSG(same, "cap %u rule %d: %u kept, first %u", cases[i].cap, rule, n, n ? crop.kept[0] : 0);
            weft__crop_free(ctx, &crop);
        }
    }
    weft_context_destroy(ctx);
}

/* The cap against a brute-force ranking: a jittered 20 x 20 sheet (2 cm spacing), 600 small
 * triangles within 3.4 cm of it (the distance is exact up to a quarter margin, 3.75 cm) and 100
 * farther away, 12 cm above; the kept set is the `cap` smallest (distance to the nearest
 * vertex, index), the distance computed as the runtime does, and no far triangle is kept. */
static void test_cap_matches_brute_force(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    CHECK(ctx != NULL);
    enum { N = 400, NT = 700, CAP = 250 };
    static float x[3 * N], c[9 * NT], key_d2[NT];
    static uint32_t tris[3 * NT], order[NT];
    test_rng r = {777};
    for (int scene = 0; scene < 5; ++scene) {
        for (uint32_t i = 0; i < N; ++i) {
            x[3 * i] = 0.02f * (float)(i % 20) + test_rng_float(&r, -0.005f, 0.005f);
            x[3 * i + 1] = test_rng_float(&r, -0.005f, 0.005f);
            x[3 * i + 2] = 0.02f * (float)(i / 20) + test_rng_float(&r, -0.005f, 0.005f);
        }
        for (uint32_t t = 0; t < NT; ++t) {
            const bool far = t >= 600;
            const float cx = test_rng_float(&r, -0.01f, 0.38f), cy = far ? 0.12f : test_rng_float(&r, -0.02f, 0.02f),
                        cz = test_rng_float(&r, -0.01f, 0.38f);
            const float v[9] = {cx, cy, cz, cx + 0.01f, cy, cz, cx, cy + 0.004f, cz + 0.01f};
            memcpy(c + 9 * t, v, sizeof v);
            for (int k = 0; k < 3; ++k) {
                tris[3 * t + k] = 3 * t + (uint32_t)k;
            }
        }
        weft_crop crop;
        CHECK_RESULT(weft__crop_init(ctx, &crop, 0.15f, WEFT_COLLIDER_CROP_BOX, CAP, WEFT_COLLIDER_CAP_NEAREST, N, NT, 3 * NT, NULL, NULL), WEFT_OK);
        const uint32_t n = weft__crop_select(&crop, x, N, c, tris);
        CHECK_EQ_INT(n, CAP);
        /* Brute force over every triangle (all are in the grown box). */
        for (uint32_t t = 0; t < NT; ++t) {
            float at[3];
            for (int d = 0; d < 3; ++d) {
                const float s01 = c[9 * t + d] + c[9 * t + 3 + d];
                at[d] = (s01 + c[9 * t + 6 + d]) / 3.0f;
            }
            float best = INFINITY;
            for (uint32_t v = 0; v < N; ++v) {
                const float dx = x[3 * v] - at[0], dy = x[3 * v + 1] - at[1], dz = x[3 * v + 2] - at[2];
                const float sx = dx * dx;
                const float sy = dy * dy;
                const float sz = dz * dz;
                const float s = sx + sy + sz;
                best = s < best ? s : best;
            }
            key_d2[t] = best;
            order[t] = t;
        }
        for (uint32_t a = 1; a < NT; ++a) { /* insertion sort by (distance, index) */
            const uint32_t v = order[a];
            uint32_t b = a;
            while (b > 0 && (key_d2[order[b - 1]] > key_d2[v])) {
                order[b] = order[b - 1];
                b--;
            }
            order[b] = v;
        }
        static uint8_t want[NT];
        memset(want, 0, sizeof want);
        for (uint32_t k = 0; k < CAP; ++k) {
            want[order[k]] = 1;
        }
        uint32_t agree = 0;
        for (uint32_t k = 0; k < n; ++k) {
            agree += want[crop.kept[k]];
            CHECK(k == 0 || crop.kept[k] > crop.kept[k - 1]); /* ascending */
        }
        CHECK_MSG(agree == CAP, "scene %d: %u of %u kept triangles are the brute-force nearest", scene, agree, CAP);
        weft__crop_free(ctx, &crop);
    }
    weft_context_destroy(ctx);
}

/* The sample cap on a 64 x 64 grid of small triangles in the plane y = 0, the collider at rest
 * (ascending index is row-major): every cap keeps that many triangles of the crop, in ascending
 * order, with represented = cropped / kept; a cap of 64 keeps one triangle in each 8 x 8 block
 * (a Morton block of 64 positions is one 8 x 8 block here, and the first 64 ranks stride the
 * curve by 64); a garment over one quarter of the grid crops it, and the sample stays inside. */
static void test_cap_sample_even(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    CHECK(ctx != NULL);
    enum { G = 64, NT = G * G };
    static float c[9 * NT];
    static uint32_t tris[3 * NT];
    for (uint32_t t = 0; t < NT; ++t) {
        const float x0 = 0.01f * (float)(t % G), z0 = 0.01f * (float)(t / G);
        const float v[9] = {x0, 0.0f, z0, x0 + 0.008f, 0.0f, z0, x0, 0.0f, z0 + 0.008f};
        memcpy(c + 9 * t, v, sizeof v);
        for (int k = 0; k < 3; ++k) {
            tris[3 * t + k] = 3 * t + (uint32_t)k;
        }
    }
    /* a garment spanning the whole grid: the box crop keeps every triangle */
    const float whole[] = {0.0f, 0.0f, 0.0f, 0.64f, 0.0f, 0.64f};
    static const uint32_t caps[] = {1, 64, 1000, NT - 1, NT, NT + 5};
    for (size_t i = 0; i < sizeof caps / sizeof caps[0]; ++i) {
        weft_crop crop;
        CHECK_RESULT(weft__crop_init(ctx, &crop, 0.05f, WEFT_COLLIDER_CROP_BOX, caps[i], WEFT_COLLIDER_CAP_SAMPLE, 2,
                                     NT, 3 * NT, c, tris),
                     WEFT_OK);
        const uint32_t want = caps[i] < NT ? caps[i] : NT;
        const uint32_t n = weft__crop_select(&crop, whole, 2, c, tris);
        CHECK_MSG(n == want, "cap %u: %u kept", caps[i], n);
        bool ascending = true;
        for (uint32_t k = 1; k < n; ++k) {
            ascending = ascending && crop.kept[k] > crop.kept[k - 1];
        }
        CHECK(ascending);
        CHECK_MSG(crop.represented == (float)NT / (float)want, "cap %u: represented %g", caps[i],
                  (double)crop.represented);
        if (caps[i] == 64) {
            uint32_t per_block[64] = {0};
            for (uint32_t k = 0; k < n; ++k) {
                const uint32_t t = crop.kept[k];
                per_block[(t / G) / 8 * 8 + (t % G) / 8]++;
            }
            bool one_each = true;
            for (int b = 0; b < 64; ++b) {
                one_each = one_each && per_block[b] == 1;
            }
            CHECK_MSG(one_each, "cap 64: not one triangle in each 8 x 8 block");
        }
        /* a garment over x, z <= 0.245 (margin 5 cm): the box keeps the 30 x 30 triangles x0, z0 <= 0.29 */
        const float quarter[] = {0.0f, 0.0f, 0.0f, 0.245f, 0.0f, 0.245f};
        const uint32_t nq = weft__crop_select(&crop, quarter, 2, c, tris);
        const uint32_t inq = 30 * 30;
        bool inside = true;
        for (uint32_t k = 0; k < nq; ++k) {
            inside = inside && crop.kept[k] % G < 30 && crop.kept[k] / G < 30;
        }
        CHECK_MSG(inside && nq == (caps[i] < inq ? caps[i] : inq), "cap %u over a quarter: %u kept", caps[i], nq);
        CHECK(crop.represented == (caps[i] < inq ? (float)inq / (float)caps[i] : 1.0f));
        weft__crop_free(ctx, &crop);
    }
    weft_context_destroy(ctx);
}

/* ---------------------------------------------------------------------------------------- */
/* Through a garment                                                                          */

typedef sheet_floor scene;

/* The sheet at y = 0 over the floor 0.05 m below it (722 floor triangles capped to 600): a margin
 * decides how much of the floor is in the garment's box. */
static void scene_make(scene *s)
{
    sheet_floor_make(s, 0.0f, -0.05f);
}

static weft_garment_def scene_def(const scene *s, const weft_model *m)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = WEFT_METHOD_MODEL;
    d.model = m;
    d.ccd.enabled = false;
    d.rest_positions = s->rest;
    d.vertex_count = s->nv;
    d.triangles = s->tris;
    d.triangle_count = s->nt;
    d.collider_rest_positions = s->floor;
    d.collider_vertex_count = s->nf;
    d.collider_triangles = s->ftris;
    d.collider_triangle_count = s->nft;
    return d;
}

/* Tokens of the first step, or UINT32_MAX when the garment could not step. */
static uint32_t first_tokens(weft_context *ctx, const scene *s, const weft_garment_def *d)
{
    weft_garment *g = NULL;
    uint32_t n = UINT32_MAX;
    if (weft_garment_create(ctx, d, &g) == WEFT_OK && weft_garment_set_collider(g, s->floor) == WEFT_OK &&
        weft_garment_step(g) == WEFT_OK) {
        n = weft_garment_stats(g).collider_tokens;
    }
    weft_garment_destroy(g);
    return n;
}

/* Floor triangles whose box overlaps the sheet's box grown by margin (the sheet at rest). */
static uint32_t expected_box(const scene *s, float margin)
{
    uint32_t n = 0;
    for (uint32_t t = 0; t < s->nft; ++t) {
        n += box_rule(s->rest, s->nv, s->floor, s->ftris + 3 * t, margin);
    }
    return n;
}

static void test_garment_token_counts(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
    if (!m) {
        weft_context_destroy(ctx);
        return;
    }
    static scene s;
    scene_make(&s);
    weft_garment_def d = scene_def(&s, m);
    const uint32_t own = first_tokens(ctx, &s, &d);
    CHECK_EQ_INT(own, expected_box(&s, 0.15f)); /* the shipped models' crop_margin */
    d.collider_crop_margin = 0.15f;
    CHECK_EQ_INT(first_tokens(ctx, &s, &d), own);
    d.collider_crop_margin = 0.06f;
    const uint32_t small = first_tokens(ctx, &s, &d);
    CHECK_EQ_INT(small, expected_box(&s, 0.06f));
    d.collider_crop_margin = 0.5f;
    const uint32_t large = first_tokens(ctx, &s, &d);
    CHECK_EQ_INT(large, expected_box(&s, 0.5f));
    CHECK_MSG(small < own && own < large, "tokens at 6 / 15 / 50 cm: %u %u %u", small, own, large);
    /* The cap bounds the count, and is a no-op above what the crop keeps. */
    d.collider_crop_margin = 0.0f;
    d.max_collider_tokens = 7;
    CHECK_EQ_INT(first_tokens(ctx, &s, &d), 7);
    d.max_collider_tokens = own + 100;
    CHECK_EQ_INT(first_tokens(ctx, &s, &d), own);
    d.collider_cap = WEFT_COLLIDER_CAP_SAMPLE;
    CHECK_EQ_INT(first_tokens(ctx, &s, &d), own);
    d.max_collider_tokens = 7;
    CHECK_EQ_INT(first_tokens(ctx, &s, &d), 7);
    d.collider_cap = WEFT_COLLIDER_CAP_NEAREST;
    /* Cells on a flat sheet: every cell is occupied, so nothing in the box is far from it. */
    d.max_collider_tokens = 0;
    d.collider_crop = WEFT_COLLIDER_CROP_CELLS;
    const uint32_t cells = first_tokens(ctx, &s, &d);
    CHECK_MSG(cells > 0 && cells <= own, "cells %u, box %u", cells, own);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
}

static void test_bad_values_rejected(void)
{
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
    if (!m) {
        weft_context_destroy(ctx);
        return;
    }
    static scene s;
    scene_make(&s);
    const float bad[] = {NAN, -0.01f, -INFINITY, INFINITY};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        for (int method = 0; method < 2; ++method) {
            weft_garment_def d = scene_def(&s, m);
            d.method = method ? WEFT_METHOD_XPBD : WEFT_METHOD_MODEL; /* validated for every method */
            d.collider_crop_margin = bad[i];
            weft_garment *g = (weft_garment *)&s; /* a sentinel that must survive */
            CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_ERROR_INVALID_ARGUMENT);
            CHECK(g == (weft_garment *)&s);
            CHECK(strstr(weft_last_error(), "collider_crop_margin") != NULL);
        }
    }
    weft_garment_def d = scene_def(&s, m);
    d.collider_crop = WEFT_COLLIDER_CROP_COUNT;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL && strstr(weft_last_error(), "collider_crop") != NULL);
    d = scene_def(&s, m);
    d.collider_cap = WEFT_COLLIDER_CAP_COUNT;
    CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL && strstr(weft_last_error(), "collider_cap") != NULL);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
}

/* Counting allocator: the step must not allocate, whatever the crop. */
static size_t g_allocs;
static void *count_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    g_allocs++;
    size_t rounded = (size + alignment - 1) / alignment * alignment;
    return aligned_alloc(alignment, rounded ? rounded : alignment);
}
static void count_free(void *ptr, size_t size, void *user)
{
    (void)size;
    (void)user;
    free(ptr);
}

static void test_step_allocates_nothing(void)
{
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
    if (!m) {
        weft_context_destroy(ctx);
        return;
    }
    static scene s;
    scene_make(&s);
    for (int rule = 0; rule < 4; ++rule) {
        weft_garment_def d = scene_def(&s, m);
        d.collider_crop = (weft_collider_crop)(rule & 1);
        d.collider_cap = rule & 2 ? WEFT_COLLIDER_CAP_SAMPLE : WEFT_COLLIDER_CAP_NEAREST;
        d.collider_crop_margin = 0.1f;
        d.max_collider_tokens = 20;
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_OK);
        const size_t before = g_allocs;
        for (int f = 0; g && f < 3; ++f) {
            CHECK_RESULT(weft_garment_set_collider(g, s.floor), WEFT_OK);
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        }
        CHECK_EQ_INT(g_allocs - before, 0);
        CHECK(g && weft_garment_stats(g).collider_tokens == 20);
        weft_garment_destroy(g);
    }
    weft_model_destroy(m);
    weft_context_destroy(ctx);
}

/* int8 is bit-exact across ISAs; with a cap and the cells rule it must stay so (the kept set is
 * chosen by exact integer keys in scalar code). */
static void capped_int8_same_bits(weft_collider_cap cap)
{
    static scene s;
    scene_make(&s);
    static float ref[3 * 64];
    bool have_ref = false;
    const weft_isa isas[] = {WEFT_ISA_SCALAR, WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    for (size_t k = 0; k < sizeof isas / sizeof isas[0]; ++k) {
        weft_context *ctx = ctx_make(isas[k]);
        if (!ctx) {
            weft_context_destroy(ctx);
            continue; /* not on this CPU */
        }
        weft_model *m = NULL;
        CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
        weft_garment_def d = scene_def(&s, m);
        d.precision = WEFT_PRECISION_INT8;
        d.collider_crop = WEFT_COLLIDER_CROP_CELLS;
        d.collider_crop_margin = 0.12f;
        d.max_collider_tokens = 25;
        d.collider_cap = cap;
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_OK);
        for (int f = 0; g && f < 3; ++f) {
            CHECK_RESULT(weft_garment_set_collider(g, s.floor), WEFT_OK);
            CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        }
        if (g) {
            const float *x = weft_garment_positions(g);
            if (!have_ref) {
                memcpy(ref, x, sizeof ref);
                have_ref = true;
            } else {
                CHECK_MSG(memcmp(ref, x, sizeof ref) == 0, "cap %d: isa %s differs from the first", (int)cap,
                          weft_isa_name(isas[k]));
            }
        }
        weft_garment_destroy(g);
        weft_model_destroy(m);
        weft_context_destroy(ctx);
    }
    CHECK(have_ref);
}

static void test_capped_int8_same_bits_every_isa(void)
{
    capped_int8_same_bits(WEFT_COLLIDER_CAP_NEAREST);
    capped_int8_same_bits(WEFT_COLLIDER_CAP_SAMPLE);
}

/* A sample cap the crop never reaches weighs nothing: the uncapped garment's bits, int8 and fp32. */
static void test_sample_cap_above_crop_is_uncapped(void)
{
    static scene s;
    scene_make(&s);
    weft_context *ctx = ctx_make(WEFT_ISA_AUTO);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
    for (int p = 0; m && p < 2; ++p) {
        float out[2][3 * 64];
        for (int v = 0; v < 2; ++v) {
            weft_garment_def d = scene_def(&s, m);
            d.precision = p ? WEFT_PRECISION_INT8 : WEFT_PRECISION_FP32;
            d.max_collider_tokens = v ? s.nft : 0;
            d.collider_cap = WEFT_COLLIDER_CAP_SAMPLE;
            weft_garment *g = NULL;
            CHECK_RESULT(weft_garment_create(ctx, &d, &g), WEFT_OK);
            for (int f = 0; g && f < 3; ++f) {
                CHECK_RESULT(weft_garment_set_collider(g, s.floor), WEFT_OK);
                CHECK_RESULT(weft_garment_step(g), WEFT_OK);
            }
            memcpy(out[v], g ? weft_garment_positions(g) : s.rest, sizeof out[v]);
            weft_garment_destroy(g);
        }
        CHECK_MSG(memcmp(out[0], out[1], sizeof out[0]) == 0, "precision %d: a cap above the crop changed bits", p);
    }
    weft_model_destroy(m);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_box_matches_training_rule), TEST_CASE(test_cells_drop_the_empty_middle),
          TEST_CASE(test_cap_nearest_then_index), TEST_CASE(test_cap_matches_brute_force),
          TEST_CASE(test_garment_token_counts),
          TEST_CASE(test_bad_values_rejected), TEST_CASE(test_step_allocates_nothing),
          TEST_CASE(test_capped_int8_same_bits_every_isa), TEST_CASE(test_cap_sample_even),
          TEST_CASE(test_sample_cap_above_crop_is_uncapped))
