/* CCD world: broad phase against brute force, the five contact types, the iterative post-process
 * on a sheet swept through a closed sphere and through itself (checked afterwards with exact
 * triangle–triangle tests), the fallback, the metrics, and no allocation after creation. */
#include "ccd/ccd_internal.h"
#include "test.h"

#include <stdint.h>

typedef struct mesh {
    float *x;
    uint32_t *t;
    uint32_t nv, nt;
} mesh;

static void mesh_free(mesh *m)
{
    free(m->x);
    free(m->t);
}

/* n x n vertex grid of side `size` in the plane y = height, centred on (cx, cz). */
static mesh sheet(uint32_t n, float size, float height, float cx, float cz)
{
    mesh m = {0};
    m.nv = n * n;
    m.nt = 2 * (n - 1) * (n - 1);
    m.x = malloc(sizeof(float) * 3 * m.nv);
    m.t = malloc(sizeof(uint32_t) * 3 * m.nt);
    for (uint32_t i = 0; i < n; ++i) {
        for (uint32_t j = 0; j < n; ++j) {
            float *p = m.x + 3 * (i * n + j);
            p[0] = cx + size * ((float)j / (float)(n - 1) - 0.5f);
            p[1] = height;
            p[2] = cz + size * ((float)i / (float)(n - 1) - 0.5f);
        }
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i + 1 < n; ++i) {
        for (uint32_t j = 0; j + 1 < n; ++j) {
            uint32_t a = i * n + j, b = a + 1, c = a + n, d = c + 1;
            uint32_t *t = m.t + 3 * k;
            t[0] = a, t[1] = c, t[2] = b;
            t[3] = b, t[4] = c, t[5] = d;
            k += 2;
        }
    }
    return m;
}

/* Closed UV sphere (poles shared), radius r at the origin. */
static mesh sphere(uint32_t rings, uint32_t segs, float r)
{
    mesh m = {0};
    m.nv = 2 + (rings - 1) * segs;
    m.nt = 2 * segs * (rings - 1);
    m.x = malloc(sizeof(float) * 3 * m.nv);
    m.t = malloc(sizeof(uint32_t) * 3 * m.nt);
    m.x[0] = 0, m.x[1] = r, m.x[2] = 0;
    m.x[3] = 0, m.x[4] = -r, m.x[5] = 0;
    for (uint32_t i = 1; i < rings; ++i) {
        double th = 3.14159265358979 * i / rings;
        for (uint32_t j = 0; j < segs; ++j) {
            double ph = 2 * 3.14159265358979 * j / segs;
            float *p = m.x + 3 * (2 + (i - 1) * segs + j);
            p[0] = (float)(r * sin(th) * cos(ph));
            p[1] = (float)(r * cos(th));
            p[2] = (float)(r * sin(th) * sin(ph));
        }
    }
    uint32_t k = 0;
#define V(i, j) (2 + ((i) - 1) * segs + ((j) % segs))
    for (uint32_t j = 0; j < segs; ++j) {
        uint32_t *t = m.t + 3 * k++;
        t[0] = 0, t[1] = V(1, j + 1), t[2] = V(1, j);
        t = m.t + 3 * k++;
        t[0] = 1, t[1] = V(rings - 1, j), t[2] = V(rings - 1, j + 1);
    }
    for (uint32_t i = 1; i + 1 < rings; ++i) {
        for (uint32_t j = 0; j < segs; ++j) {
            uint32_t *t = m.t + 3 * k++;
            t[0] = V(i, j), t[1] = V(i, j + 1), t[2] = V(i + 1, j);
            t = m.t + 3 * k++;
            t[0] = V(i, j + 1), t[1] = V(i + 1, j + 1), t[2] = V(i + 1, j);
        }
    }
#undef V
    return m;
}

typedef struct counting {
    long allocs;
} counting;

static void *c_alloc(size_t size, size_t alignment, void *user)
{
    ((counting *)user)->allocs++;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static void c_free(void *p, size_t size, void *user)
{
    (void)size;
    (void)user;
    free(p);
}

static counting g_count;

static weft_context *make_ctx(void)
{
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = c_alloc;
    cd.allocator.free = c_free;
    cd.allocator.user = &g_count;
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

static weft_ccd_world *make_world(weft_context *ctx, const mesh *cloth, const mesh *col)
{
    weft_ccd_world_def def = weft_default_ccd_world_def();
    def.cloth_triangles = cloth->t;
    def.cloth_triangle_count = cloth->nt;
    def.cloth_vertex_count = cloth->nv;
    if (col) {
        def.collider_triangles = col->t;
        def.collider_triangle_count = col->nt;
        def.collider_vertex_count = col->nv;
    }
    weft_ccd_world *w = NULL;
    CHECK_RESULT(weft_ccd_world_create(ctx, &def, &w), WEFT_OK);
    return w;
}

static void gather(double P[24], const float *a0, const float *a1, const uint32_t *va, int na, const float *b0,
                   const float *b1, const uint32_t *vb)
{
    for (int i = 0; i < 4; ++i) {
        const float *s0 = i < na ? a0 : b0, *s1 = i < na ? a1 : b1;
        uint32_t v = i < na ? va[i] : vb[i - na];
        for (int k = 0; k < 3; ++k) {
            P[3 * i + k] = s0[3 * v + k];
            P[12 + 3 * i + k] = s1[3 * v + k];
        }
    }
}

/* All-pairs counts of the five types with the same narrow phase. */
static void brute_force(const mesh *cl, const float *x0, const float *x1, const mesh *co, const float *c0,
                        const float *c1, uint32_t counts[5])
{
    memset(counts, 0, 5 * sizeof counts[0]);
    double P[24];
    for (uint32_t v = 0; v < cl->nv; ++v) {
        for (uint32_t t = 0; t < co->nt; ++t) {
            gather(P, x0, x1, &v, 1, c0, c1, co->t + 3 * t);
            counts[0] += (uint32_t)weft_ccd_vertex_face(P, 0, NULL);
        }
        for (uint32_t t = 0; t < cl->nt; ++t) {
            const uint32_t *tt = cl->t + 3 * t;
            if (tt[0] == v || tt[1] == v || tt[2] == v) {
                continue;
            }
            gather(P, x0, x1, &v, 1, x0, x1, tt);
            counts[3] += (uint32_t)weft_ccd_vertex_face(P, 0, NULL);
        }
    }
    for (uint32_t v = 0; v < co->nv; ++v) {
        for (uint32_t t = 0; t < cl->nt; ++t) {
            gather(P, c0, c1, &v, 1, x0, x1, cl->t + 3 * t);
            counts[2] += (uint32_t)weft_ccd_vertex_face(P, 0, NULL);
        }
    }
    /* Unique edges by brute force: (a < b) pairs taken from triangles, deduplicated with a scan. */
    uint32_t *ea = malloc(sizeof(uint32_t) * 6 * cl->nt), *eb = malloc(sizeof(uint32_t) * 6 * co->nt);
    uint32_t na = 0, nb = 0;
    for (int which = 0; which < 2; ++which) {
        const mesh *m = which ? co : cl;
        uint32_t *e = which ? eb : ea;
        uint32_t *n = which ? &nb : &na;
        for (uint32_t t = 0; t < m->nt; ++t) {
            for (int k = 0; k < 3; ++k) {
                uint32_t a = m->t[3 * t + k], b = m->t[3 * t + (k + 1) % 3];
                uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
                bool dup = false;
                for (uint32_t q = 0; q < *n && !dup; ++q) {
                    dup = e[2 * q] == lo && e[2 * q + 1] == hi;
                }
                if (!dup) {
                    e[2 * *n] = lo;
                    e[2 * *n + 1] = hi;
                    (*n)++;
                }
            }
        }
    }
    for (uint32_t i = 0; i < na; ++i) {
        for (uint32_t j = 0; j < nb; ++j) {
            uint32_t v[4] = {ea[2 * i], ea[2 * i + 1], eb[2 * j], eb[2 * j + 1]};
            gather(P, x0, x1, v, 2, c0, c1, v + 2);
            counts[1] += (uint32_t)weft_ccd_edge_edge(P, 0, NULL);
        }
        for (uint32_t j = i + 1; j < na; ++j) {
            uint32_t v[4] = {ea[2 * i], ea[2 * i + 1], ea[2 * j], ea[2 * j + 1]};
            if (v[0] == v[2] || v[0] == v[3] || v[1] == v[2] || v[1] == v[3]) {
                continue;
            }
            gather(P, x0, x1, v, 2, x0, x1, v + 2);
            counts[4] += (uint32_t)weft_ccd_edge_edge(P, 0, NULL);
        }
    }
    free(ea);
    free(eb);
}

/* A crumpled sheet falling through a moving sphere: every type occurs, and the BVH finds exactly
 * the pairs that all-pairs testing finds. */
static void broad_phase_matches_brute_force(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(9, 1.2f, 0.7f, 0.1f, 0.0f), co = sphere(6, 8, 0.5f);
    test_rng r = {99};
    float *x1 = malloc(sizeof(float) * 3 * cl.nv), *c1 = malloc(sizeof(float) * 3 * co.nv);
    for (uint32_t i = 0; i < 3 * cl.nv; ++i) {
        cl.x[i] += test_rng_float(&r, -0.01f, 0.01f);
        x1[i] = cl.x[i] + (i % 3 == 1 ? -0.9f : 0.0f) + test_rng_float(&r, -0.15f, 0.15f);
    }
    for (uint32_t i = 0; i < 3 * co.nv; ++i) {
        c1[i] = co.x[i] + (i % 3 == 0 ? 0.05f : 0.0f);
    }
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_report rep = {0};
    CHECK_RESULT(weft_ccd_detect(w, cl.x, x1, co.x, c1, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
    uint32_t bf[5];
    brute_force(&cl, cl.x, x1, &co, co.x, c1, bf);
    for (int k = 0; k < 5; ++k) {
        CHECK_MSG(rep.hits[k] == bf[k], "type %d: bvh %u, brute force %u", k, rep.hits[k], bf[k]);
        CHECK_MSG(bf[k] > 0, "type %d never occurs in this scene", k);
    }
    printf("hits per type (vf ee fv self-vf self-ee): %u %u %u %u %u, narrow tests %llu\n", rep.hits[0], rep.hits[1],
           rep.hits[2], rep.hits[3], rep.hits[4], (unsigned long long)rep.narrow_tests);
    uint32_t n = 0;
    const weft_ccd_hit *h = weft_ccd_hits(w, &n);
    CHECK_EQ_INT(n, rep.hit_total);
    for (uint32_t i = 0; i < n; ++i) {
        CHECK(h[i].toi >= rep.earliest_toi && h[i].toi <= 1.0);
    }
    weft_ccd_world_destroy(w);
    free(x1);
    free(c1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

static uint32_t frame_intersections(weft_ccd_world *w, const float *x, const float *c)
{
    weft_ccd_intersections in = {0};
    CHECK_RESULT(weft_ccd_intersect_frame(w, x, c, &in), WEFT_OK);
    return in.cloth_cloth + in.cloth_collider;
}

/* The post-process leaves a clean sweep and an intersection-free end frame. */
static void check_resolved(weft_ccd_world *w, const float *x0, const float *x1, const float *c0, const float *c1,
                           const weft_ccd_postprocess_stats *st, const char *what)
{
    weft_ccd_report rep = {0};
    CHECK_RESULT(weft_ccd_detect(w, x0, x1, c0, c1, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
    CHECK_MSG(rep.hit_total == 0 || st->unresolved_hits > 0, "%s: %u hits after the post-process", what,
              rep.hit_total);
    CHECK_MSG(frame_intersections(w, x1, c1) == 0, "%s: end frame intersects", what);
    printf("%s: %u passes, %u vertices moved, %u carried, %u held, fallback %d\n", what, st->iterations,
           st->vertices_moved, st->vertices_carried, st->vertices_held, (int)st->fallback);
}

/* A sheet thrown through a static sphere in one frame (full tunnelling). */
static void postprocess_through_sphere(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(24, 1.6f, 0.6f, 0.0f, 0.0f), co = sphere(16, 24, 0.5f);
    float *x1 = malloc(sizeof(float) * 3 * cl.nv);
    for (uint32_t i = 0; i < cl.nv; ++i) {
        x1[3 * i] = cl.x[3 * i];
        x1[3 * i + 1] = -0.7f;
        x1[3 * i + 2] = cl.x[3 * i + 2];
    }
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_metrics before = {0};
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, x1, co.x, co.x, &before), WEFT_OK);
    CHECK(before.collision_rate > 0.0);
    CHECK_EQ_INT(frame_intersections(w, cl.x, co.x), 0);
    CHECK(frame_intersections(w, x1, co.x) == 0); /* the end frame alone looks clean: tunnelling */
    weft_ccd_postprocess_stats st = {0};
    long allocs = g_count.allocs;
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, x1, co.x, co.x, &st), WEFT_OK);
    CHECK_EQ_INT(g_count.allocs, allocs); /* nothing allocated per frame */
    CHECK(st.vertices_moved > 0);
    check_resolved(w, cl.x, x1, co.x, co.x, &st, "sheet through sphere");
    weft_ccd_metrics after = {0};
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, x1, co.x, co.x, &after), WEFT_OK);
    CHECK(after.collision_rate == 0.0);
    printf("collision rate %.2f%% -> %.2f%%\n", before.collision_rate, after.collision_rate);
    weft_ccd_world_destroy(w);
    free(x1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

/* Two layers of one mesh pass through each other, plus the moving sphere. */
static void postprocess_self(void)
{
    weft_context *ctx = make_ctx();
    mesh a = sheet(16, 1.0f, 0.2f, 0.0f, 0.0f), b = sheet(16, 1.0f, -0.2f, 0.05f, 0.03f);
    mesh cl = {0};
    cl.nv = a.nv + b.nv;
    cl.nt = a.nt + b.nt;
    cl.x = malloc(sizeof(float) * 3 * cl.nv);
    cl.t = malloc(sizeof(uint32_t) * 3 * cl.nt);
    memcpy(cl.x, a.x, sizeof(float) * 3 * a.nv);
    memcpy(cl.x + 3 * a.nv, b.x, sizeof(float) * 3 * b.nv);
    memcpy(cl.t, a.t, sizeof(uint32_t) * 3 * a.nt);
    for (uint32_t i = 0; i < 3 * b.nt; ++i) {
        cl.t[3 * a.nt + i] = b.t[i] + a.nv;
    }
    float *x1 = malloc(sizeof(float) * 3 * cl.nv);
    test_rng r = {7};
    for (uint32_t i = 0; i < cl.nv; ++i) {
        float dy = i < a.nv ? -0.4f : 0.4f;
        x1[3 * i] = cl.x[3 * i] + test_rng_float(&r, -0.02f, 0.02f);
        x1[3 * i + 1] = cl.x[3 * i + 1] + dy + test_rng_float(&r, -0.05f, 0.05f);
        x1[3 * i + 2] = cl.x[3 * i + 2] + test_rng_float(&r, -0.02f, 0.02f);
    }
    weft_ccd_world *w = make_world(ctx, &cl, NULL);
    weft_ccd_metrics m = {0};
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, x1, NULL, NULL, &m), WEFT_OK);
    CHECK(m.self_collision_rate > 50.0);
    weft_ccd_postprocess_stats st = {0};
    weft_result res = weft_ccd_postprocess(w, cl.x, x1, NULL, NULL, &st);
    CHECK_RESULT(res, WEFT_OK);
    check_resolved(w, cl.x, x1, NULL, NULL, &st, "two layers");
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, x1, NULL, NULL, &m), WEFT_OK);
    CHECK(m.self_collision_rate == 0.0);
    weft_ccd_world_destroy(w);
    free(x1);
    mesh_free(&a);
    mesh_free(&b);
    mesh_free(&cl);
    weft_context_destroy(ctx);
}

/* Violent random motion of a sheet over a static sphere: with few passes the fallback must still
 * leave a clean, intersection-free result. */
static void postprocess_random_with_fallback(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(14, 1.4f, 0.56f, 0.0f, 0.0f), co = sphere(10, 16, 0.5f);
    weft_ccd_world_def def = weft_default_ccd_world_def();
    def.cloth_triangles = cl.t;
    def.cloth_triangle_count = cl.nt;
    def.cloth_vertex_count = cl.nv;
    def.collider_triangles = co.t;
    def.collider_triangle_count = co.nt;
    def.collider_vertex_count = co.nv;
    def.max_iterations = 2;
    weft_ccd_world *w = NULL;
    CHECK_RESULT(weft_ccd_world_create(ctx, &def, &w), WEFT_OK);
    float *x1 = malloc(sizeof(float) * 3 * cl.nv);
    test_rng r = {1234};
    for (int trial = 0; trial < 5; ++trial) {
        for (uint32_t i = 0; i < 3 * cl.nv; ++i) {
            x1[i] = cl.x[i] + test_rng_float(&r, -0.4f, 0.4f) - (i % 3 == 1 ? 0.3f : 0.0f);
        }
        weft_ccd_postprocess_stats st = {0};
        CHECK_RESULT(weft_ccd_postprocess(w, cl.x, x1, co.x, co.x, &st), WEFT_OK);
        check_resolved(w, cl.x, x1, co.x, co.x, &st, "random motion");
    }
    weft_ccd_world_destroy(w);
    free(x1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

/* The work bound: a sheet scattered 10 m at random over a sphere (a model gone wrong) makes every
 * swept box overlap every other. Unbounded, the passes visit millions of triangle pairs; with
 * max_pairs they stop, hold every vertex at x0, certify that with one more pass, and visit at
 * most twice the budget (plus the pair that trips it). Without the bound the same motion is
 * resolved and visits many times more. */
static void pair_budget_bounds_the_work(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(14, 1.4f, 0.56f, 0.0f, 0.0f), co = sphere(10, 16, 0.5f);
    weft_ccd_world_def def = weft_default_ccd_world_def();
    def.cloth_triangles = cl.t;
    def.cloth_triangle_count = cl.nt;
    def.cloth_vertex_count = cl.nv;
    def.collider_triangles = co.t;
    def.collider_triangle_count = co.nt;
    def.collider_vertex_count = co.nv;
    def.max_iterations = 4;
    def.max_pairs = 5000;
    weft_ccd_world *w = NULL, *unbounded = NULL;
    CHECK_RESULT(weft_ccd_world_create(ctx, &def, &w), WEFT_OK);
    def.max_pairs = 0;
    CHECK_RESULT(weft_ccd_world_create(ctx, &def, &unbounded), WEFT_OK);
    float *x1 = malloc(sizeof(float) * 3 * cl.nv), *x1u = malloc(sizeof(float) * 3 * cl.nv);
    test_rng r = {99};
    for (uint32_t i = 0; i < 3 * cl.nv; ++i) {
        x1[i] = cl.x[i] + test_rng_float(&r, -5.0f, 5.0f);
    }
    memcpy(x1u, x1, sizeof(float) * 3 * cl.nv);
    weft_ccd_postprocess_stats st = {0}, su = {0};
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, x1, co.x, co.x, &st), WEFT_OK);
    CHECK(st.over_budget && st.held_all && st.fallback);
    CHECK_MSG(st.pairs_visited <= 2 * 5000 + 2, "%llu pairs", (unsigned long long)st.pairs_visited);
    CHECK(memcmp(x1, cl.x, sizeof(float) * 3 * cl.nv) == 0); /* the cloth did not move */
    check_resolved(w, cl.x, x1, co.x, co.x, &st, "over budget");
    CHECK_RESULT(weft_ccd_postprocess(unbounded, cl.x, x1u, co.x, co.x, &su), WEFT_OK);
    CHECK(!su.over_budget);
    CHECK_MSG(su.pairs_visited > 10 * st.pairs_visited, "unbounded %llu, bounded %llu pairs",
              (unsigned long long)su.pairs_visited, (unsigned long long)st.pairs_visited);
    /* an ordinary motion stays within the budget and is resolved as before */
    for (uint32_t i = 0; i < 3 * cl.nv; ++i) {
        x1[i] = cl.x[i] - (i % 3 == 1 ? 0.01f : 0.0f);
    }
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, x1, co.x, co.x, &st), WEFT_OK);
    CHECK(!st.over_budget && !st.held_all);
    CHECK(st.pairs_visited > 0);
    weft_ccd_world_destroy(w);
    weft_ccd_world_destroy(unbounded);
    free(x1);
    free(x1u);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

/* A sphere rising 2 cm into a still sheet 5 mm above it: the fallback carries the touched cloth
 * with the sphere and the result is certified clean. */
static void collider_pushes_cloth(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(12, 0.5f, 0.305f, 0.0f, 0.0f), co = sphere(12, 16, 0.3f);
    float *c1 = malloc(sizeof(float) * 3 * co.nv), *x1 = malloc(sizeof(float) * 3 * cl.nv);
    for (uint32_t i = 0; i < 3 * co.nv; ++i) {
        c1[i] = co.x[i] + (i % 3 == 1 ? 0.02f : 0.0f);
    }
    memcpy(x1, cl.x, sizeof(float) * 3 * cl.nv);
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_postprocess_stats st = {0};
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, x1, co.x, c1, &st), WEFT_OK);
    CHECK(st.fallback && st.vertices_carried > 0);
    check_resolved(w, cl.x, x1, co.x, c1, &st, "sphere pushing cloth");
    weft_ccd_world_destroy(w);
    free(c1);
    free(x1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

/* Cloth that starts inside the collider: the post-process stops it on its way out (a crossing),
 * unless weft_ccd_world_let_out names it; clearing the mask restores the default. */
static void let_out_of_collider(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(6, 0.3f, 0.0f, 0.0f, 0.0f), co = sphere(12, 16, 0.5f);
    float *x1 = malloc(sizeof(float) * 3 * cl.nv), *out = malloc(sizeof(float) * 3 * cl.nv);
    uint8_t *inside = malloc(cl.nv);
    for (uint32_t i = 0; i < cl.nv; ++i) {
        x1[3 * i] = cl.x[3 * i];
        x1[3 * i + 1] = 0.7f; /* from the sphere's middle to above it */
        x1[3 * i + 2] = cl.x[3 * i + 2];
        inside[i] = 1;
    }
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_postprocess_stats st = {0};
    memcpy(out, x1, sizeof(float) * 3 * cl.nv);
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, out, co.x, co.x, &st), WEFT_OK);
    CHECK_MSG(st.vertices_moved == cl.nv, "without let_out %u of %u vertices were stopped", st.vertices_moved, cl.nv);
    CHECK_RESULT(weft_ccd_world_let_out(w, inside), WEFT_OK);
    memcpy(out, x1, sizeof(float) * 3 * cl.nv);
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, out, co.x, co.x, &st), WEFT_OK);
    CHECK_EQ_INT((int)st.vertices_moved, 0);
    CHECK(memcmp(out, x1, sizeof(float) * 3 * cl.nv) == 0);
    CHECK_RESULT(weft_ccd_world_let_out(w, NULL), WEFT_OK);
    memcpy(out, x1, sizeof(float) * 3 * cl.nv);
    CHECK_RESULT(weft_ccd_postprocess(w, cl.x, out, co.x, co.x, &st), WEFT_OK);
    CHECK_EQ_INT((int)st.vertices_moved, (int)cl.nv);
    CHECK_RESULT(weft_ccd_world_let_out(NULL, inside), WEFT_ERROR_INVALID_ARGUMENT);
    weft_ccd_world_destroy(w);
    free(inside);
    free(out);
    free(x1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

/* A sphere swept right through a still sheet: either the carried cloth ends clean (certified) or
 * the remaining hits are reported, never hidden. */
static void moving_collider_resolved_or_reported(void)
{
    weft_context *ctx = make_ctx();
    mesh cl = sheet(8, 0.6f, 0.0f, 0.0f, 0.0f), co = sphere(8, 12, 0.3f);
    float *c0 = malloc(sizeof(float) * 3 * co.nv), *c1 = malloc(sizeof(float) * 3 * co.nv);
    for (uint32_t i = 0; i < co.nv; ++i) {
        for (int k = 0; k < 3; ++k) {
            c0[3 * i + k] = co.x[3 * i + k] + (k == 1 ? 0.6f : 0.0f);
            c1[3 * i + k] = co.x[3 * i + k] + (k == 1 ? -0.6f : 0.0f);
        }
    }
    float *x1 = malloc(sizeof(float) * 3 * cl.nv);
    memcpy(x1, cl.x, sizeof(float) * 3 * cl.nv);
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_postprocess_stats st = {0};
    weft_result r = weft_ccd_postprocess(w, cl.x, x1, c0, c1, &st);
    CHECK(st.fallback);
    if (r == WEFT_OK) {
        check_resolved(w, cl.x, x1, c0, c1, &st, "sphere through a still sheet");
    } else {
        CHECK_RESULT(r, WEFT_ERROR_NOT_CONVERGED);
        CHECK(st.unresolved_hits > 0);
        weft_ccd_report rep = {0};
        CHECK_RESULT(weft_ccd_detect(w, cl.x, x1, c0, c1, WEFT_CCD_MASK_ALL, &rep), WEFT_OK);
        CHECK_EQ_INT(rep.hit_total, st.unresolved_hits);
        printf("sphere through a still sheet: %u hits reported unresolved\n", st.unresolved_hits);
    }
    weft_ccd_world_destroy(w);
    free(c0);
    free(c1);
    free(x1);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

static void metrics_inside(void)
{
    weft_context *ctx = make_ctx();
    mesh co = sphere(12, 16, 0.5f);
    mesh cl = sheet(3, 0.2f, 0.0f, 0.0f, 0.0f); /* 9 vertices around the origin: all inside */
    weft_ccd_world *w = make_world(ctx, &cl, &co);
    weft_ccd_metrics m = {0};
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, cl.x, co.x, co.x, &m), WEFT_OK);
    CHECK_EQ_INT(m.vertices_inside, 9);
    CHECK_NEAR(m.collision_rate, 100.0, 1e-9);
    for (uint32_t i = 0; i < cl.nv; ++i) {
        cl.x[3 * i + 1] = 2.0f; /* above the sphere */
    }
    cl.x[1] = 0.0f; /* one vertex back inside */
    CHECK_RESULT(weft_ccd_compute_metrics(w, cl.x, cl.x, co.x, co.x, &m), WEFT_OK);
    CHECK_EQ_INT(m.vertices_inside, 1);
    weft_ccd_world_destroy(w);
    mesh_free(&cl);
    mesh_free(&co);
    weft_context_destroy(ctx);
}

static void exact_triangle_tests(void)
{
    const double a[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    double b[9] = {0.25, 0.25, -1, 0.25, 0.25, 1, 2, 2, 0}; /* pierces a */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, b), 1);
    double c[9] = {0, 0, 1e-30, 1, 0, 1e-30, 0, 1, 1e-30}; /* parallel, just above */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, c), 0);
    double d[9] = {1, 0, 0, 2, 0, 0, 1, 1, 5}; /* touches a's corner only */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, d), 1);
    double e[9] = {0.5, 0.5, 0, 2, 0.5, 0, 0.5, 2, 0}; /* coplanar, touching on the hypotenuse */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, e), 1);
    double f[9] = {0.5000001, 0.5, 0, 2, 0.5, 0, 0.5000001, 2, 0}; /* coplanar, just apart */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, f), 0);
    double g[9] = {0.2, 0.2, 0, 0.3, 0.2, 0, 0.2, 0.3, 0}; /* coplanar, inside */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, g), 1);
    double h[9] = {-1, 0.5, 0, 2, 0.5, 0, 5, 0.5, 0}; /* collinear "triangle": a segment across a */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, h), 1);
    double s[9] = {0.1, 0.1, 0, 0.1, 0.1, 0, 0.1, 0.1, 0}; /* a point inside a */
    CHECK_EQ_INT(weft_ccd_triangles_intersect(a, s), 1);
    /* Orientation near the limit of double precision: only the exact path decides. */
    double p[3] = {0.5, 0.5, 0}, q[3] = {12, 12, 0}, r3[3] = {24, 24, 0};
    double t[3] = {0.5 + 0x1p-50, 0.5, 0};
    CHECK_EQ_INT(ccd_orient2d(p, q, r3, 0, 1), 0);
    CHECK(ccd_orient2d(p, q, t, 0, 1) != 0);
    double z[3] = {0, 0, 0x1p-1000};
    const double o[3] = {0, 0, 0}, ex[3] = {1, 0, 0}, ey[3] = {0, 1, 0};
    CHECK_EQ_INT(ccd_orient3d(o, ex, ey, z), 1);
}

TEST_MAIN(TEST_CASE(broad_phase_matches_brute_force), TEST_CASE(postprocess_through_sphere),
          TEST_CASE(postprocess_self), TEST_CASE(postprocess_random_with_fallback), TEST_CASE(pair_budget_bounds_the_work),
          TEST_CASE(collider_pushes_cloth), TEST_CASE(let_out_of_collider), TEST_CASE(moving_collider_resolved_or_reported), TEST_CASE(metrics_inside), TEST_CASE(exact_triangle_tests))
