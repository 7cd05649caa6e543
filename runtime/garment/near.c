/* Collider proximity for the garment's post-step stages, and the collider push.
 *
 * One tree over the collider triangles, built on the rest collider and refitted to the collider
 * at t+1 once per step, answers "nearest collider point within r" for the contact-aware strain
 * limit (strain.c) and for the push below.
 *
 * The push moves every vertex of x_next that is inside the collider by at most push_depth, or in
 * front of it by less than push_thickness, to push_thickness in front of the nearest surface
 * point. Inside and outside are told by the angle-weighted pseudonormal of the nearest feature
 * (face, edge or vertex; Baerentzen and Aanaes 2005), which gives the right sign on a closed mesh
 * where a face normal alone fails at edges and corners. A learned step whose output dips into
 * the body thus ends outside it, and CCD's back-off, which can only hold cloth back along its own
 * path, starts from a frame the body does not cut. docs/CCD.md, *Collider push*. */
#include "garment/garment.h"
#include "geometry/geometry.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

/* Edge-across table and vertex-to-triangle lists, for the pseudonormals. Made once. */
static weft_result make_adjacency(weft_garment *g)
{
    const uint32_t nt = g->collider_triangle_count, nc = g->collider_vertex_count;
    const size_t n = (size_t)nt * 3;
    uint64_t *keys = weft__alloc(g->ctx, n * 2 * sizeof *keys); /* (edge key, slot) pairs */
    g->near_across = weft__alloc(g->ctx, n * sizeof(uint32_t));
    g->near_vt_start = weft__alloc(g->ctx, ((size_t)nc + 1) * sizeof(uint32_t));
    g->near_vt = weft__alloc(g->ctx, n * sizeof(uint32_t));
    if (!keys || !g->near_across || !g->near_vt_start || !g->near_vt) {
        weft__free(g->ctx, keys, n * 2 * sizeof *keys);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    const uint32_t *tri = g->collider_triangles;
    for (size_t i = 0; i < n; ++i) {
        uint32_t a = tri[i], b = tri[i - i % 3 + (i % 3 + 1) % 3];
        keys[2 * i] = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
        keys[2 * i + 1] = i;
        g->near_across[i] = UINT32_MAX;
    }
    qsort(keys, n, 2 * sizeof *keys, cmp_u64); /* sorts by key; the slot rides along */
    for (size_t i = 0; i < n;) {
        size_t j = i;
        while (j < n && keys[2 * j] == keys[2 * i]) {
            ++j;
        }
        if (j - i == 2) { /* a manifold edge; border and non-manifold edges keep UINT32_MAX */
            uint32_t s0 = (uint32_t)keys[2 * i + 1], s1 = (uint32_t)keys[2 * i + 3];
            g->near_across[s0] = s1 / 3;
            g->near_across[s1] = s0 / 3;
        }
        i = j;
    }
    weft__free(g->ctx, keys, n * 2 * sizeof *keys);
    memset(g->near_vt_start, 0, ((size_t)nc + 1) * sizeof(uint32_t));
    for (size_t i = 0; i < n; ++i) {
        g->near_vt_start[tri[i] + 1]++;
    }
    for (uint32_t v = 0; v < nc; ++v) {
        g->near_vt_start[v + 1] += g->near_vt_start[v];
    }
    for (size_t i = 0; i < n; ++i) { /* fill, then shift the starts back */
        g->near_vt[g->near_vt_start[tri[i]]++] = (uint32_t)(i / 3);
    }
    for (uint32_t v = nc; v > 0; --v) {
        g->near_vt_start[v] = g->near_vt_start[v - 1];
    }
    g->near_vt_start[0] = 0;
    return WEFT_OK;
}

/* Clearance clusters: the subtrees of near_tree six levels down (or shallower leaves), at most
 * 64, each a patch of the collider that stays together as the body moves. */
enum { CLUSTER_DEPTH = 6, CLUSTER_MAX = 64 };

static uint32_t gather_clusters(const geo_bvh *t, uint32_t node, uint32_t depth, uint32_t *out, uint32_t k)
{
    if (t->nodes[node].count > 0 || depth == CLUSTER_DEPTH) {
        out[k] = node;
        return k + 1;
    }
    k = gather_clusters(t, t->nodes[node].left, depth + 1, out, k);
    return gather_clusters(t, t->nodes[node].left + 1, depth + 1, out, k);
}

static void mark_cluster(const geo_bvh *t, uint32_t node, uint8_t id, uint8_t *ktri)
{
    const geo_bvh_node *nd = &t->nodes[node];
    if (nd->count > 0) {
        for (uint32_t i = nd->left; i < nd->left + nd->count; ++i) {
            ktri[t->order[i]] = id;
        }
        return;
    }
    mark_cluster(t, nd->left, id, ktri);
    mark_cluster(t, nd->left + 1, id, ktri);
}

static weft_result make_clusters(weft_garment *g)
{
    const uint32_t nt = g->collider_triangle_count, nc = g->collider_vertex_count;
    uint32_t nodes[CLUSTER_MAX];
    const uint32_t k = gather_clusters(g->near_tree, 0, 0, nodes, 0);
    g->near_kcount = k;
    g->near_knode = weft__alloc(g->ctx, k * sizeof(uint32_t));
    g->near_ktri = weft__alloc(g->ctx, nt);
    g->near_kvert = weft__alloc(g->ctx, (size_t)nc * sizeof(uint64_t));
    g->near_kinv = weft__alloc(g->ctx, k * sizeof(double));
    g->near_kmove = weft__alloc(g->ctx, (size_t)k * 4 * sizeof(double));
    g->near_kreach = weft__alloc(g->ctx, (size_t)k * (k + 1) * sizeof(float));
    g->near_kbox = weft__alloc(g->ctx, 6 * CLUSTER_MAX * sizeof(float));
    if (!g->near_knode || !g->near_ktri || !g->near_kvert || !g->near_kinv || !g->near_kmove || !g->near_kreach ||
        !g->near_kbox) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(g->near_knode, nodes, k * sizeof(uint32_t));
    for (uint32_t c = 0; c < k; ++c) {
        mark_cluster(g->near_tree, nodes[c], (uint8_t)c, g->near_ktri);
    }
    for (uint32_t c = k; c < CLUSTER_MAX; ++c) { /* unused box slots: empty, infinitely far */
        for (int a = 0; a < 3; ++a) {
            g->near_kbox[a * CLUSTER_MAX + c] = INFINITY;
            g->near_kbox[(3 + a) * CLUSTER_MAX + c] = -INFINITY;
        }
    }
    memset(g->near_kvert, 0, (size_t)nc * sizeof(uint64_t));
    for (uint32_t t = 0; t < nt; ++t) {
        for (int j = 0; j < 3; ++j) {
            g->near_kvert[g->collider_triangles[3 * (size_t)t + j]] |= UINT64_C(1) << g->near_ktri[t];
        }
    }
    for (uint32_t c = 0; c < k; ++c) {
        g->near_kinv[c] = 0.0;
    }
    for (uint32_t v = 0; v < nc; ++v) {
        for (uint64_t m = g->near_kvert[v]; m; m &= m - 1) {
            g->near_kinv[__builtin_ctzll(m)] += 1.0;
        }
    }
    for (uint32_t c = 0; c < k; ++c) {
        g->near_kinv[c] = g->near_kinv[c] > 0.0 ? 1.0 / g->near_kinv[c] : 0.0;
    }
    return WEFT_OK;
}

bool weft__near_alloc_state(weft_garment *g)
{
    g->near_cref = g->near_at = g->near_clear = NULL;
    g->near_kmask = NULL;
    g->near_home = NULL;
    g->near_primed = false;
    if (!g->near_skip) {
        return true;
    }
    const size_t nv = g->vertex_count;
    g->near_cref = weft__alloc(g->ctx, (size_t)g->collider_vertex_count * 3 * sizeof(float));
    g->near_at = weft__alloc(g->ctx, nv * 3 * sizeof(float));
    g->near_clear = weft__alloc(g->ctx, nv * 2 * sizeof(float));
    g->near_kmask = weft__alloc(g->ctx, nv * sizeof(uint64_t));
    g->near_home = weft__alloc(g->ctx, nv);
    if (!g->near_cref || !g->near_at || !g->near_clear || !g->near_kmask || !g->near_home) {
        return false;
    }
    memset(g->near_clear, 0, nv * 2 * sizeof(float));
    return true;
}

void weft__near_free_state(weft_garment *g)
{
    const size_t nv = g->vertex_count;
    weft__free(g->ctx, g->near_cref, (size_t)g->collider_vertex_count * 3 * sizeof(float));
    weft__free(g->ctx, g->near_at, nv * 3 * sizeof(float));
    weft__free(g->ctx, g->near_clear, nv * 2 * sizeof(float));
    weft__free(g->ctx, g->near_kmask, nv * sizeof(uint64_t));
    weft__free(g->ctx, g->near_home, nv);
    g->near_cref = g->near_at = g->near_clear = NULL;
    g->near_kmask = NULL;
    g->near_home = NULL;
}

weft_result weft__near_create(weft_garment *g)
{
    /* the fast method's collider projection, or the reference's when it projects (xpbd_solver.c) */
    const bool fast = g->method == WEFT_METHOD_XPBD_FAST || g->collider_projection;
    const bool want = g->strain_contact > 0.0f || g->push_thickness > 0.0f || fast;
    if (!want || g->collider_vertex_count == 0) {
        return WEFT_OK;
    }
    const size_t nc3 = (size_t)g->collider_vertex_count * 3;
    g->near_cpos = weft__alloc(g->ctx, nc3 * sizeof(double));
    g->near_tree = weft__alloc(g->ctx, sizeof *g->near_tree);
    if (!g->near_cpos || !g->near_tree) {
        weft__near_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(g->near_tree, 0, sizeof *g->near_tree);
    weft_result r = geo_bvh_create(g->ctx, g->near_tree, g->collider_triangles, g->collider_triangle_count, 3);
    if (r != WEFT_OK) {
        weft__free(g->ctx, g->near_tree, sizeof *g->near_tree);
        g->near_tree = NULL;
        weft__near_destroy(g);
        return r;
    }
    /* Built once on the rest collider; each step refits it to the moved one. */
    for (size_t i = 0; i < nc3; ++i) {
        g->near_cpos[i] = g->collider_rest[i];
    }
    geo_bvh_build(g->near_tree, g->near_cpos);
    if (fast && g->push_thickness <= 0.0f && (r = make_adjacency(g)) != WEFT_OK) { /* the pseudonormals */
        weft__near_destroy(g);
        return r;
    }
    if (g->push_thickness > 0.0f) {
        g->near_skip = weft__alloc(g->ctx, g->vertex_count);
        g->near_last = weft__alloc(g->ctx, (size_t)g->vertex_count * sizeof(uint32_t));
        r = g->near_skip && g->near_last ? make_adjacency(g) : WEFT_ERROR_OUT_OF_MEMORY;
        if (r != WEFT_OK) {
            weft__near_destroy(g);
            return r;
        }
        for (uint32_t v = 0; v < g->vertex_count; ++v) {
            g->near_skip[v] = g->tether_radius && g->tether_radius[v] == 0.0f; /* glued for good */
            g->near_last[v] = UINT32_MAX;
        }
        if ((r = make_clusters(g)) != WEFT_OK) {
            weft__near_destroy(g);
            return r;
        }
        if (g->ccd) {
            g->near_inside = weft__alloc(g->ctx, g->vertex_count);
            if (!g->near_inside) {
                weft__near_destroy(g);
                return WEFT_ERROR_OUT_OF_MEMORY;
            }
        }
    }
    return WEFT_OK;
}

void weft__near_destroy(weft_garment *g)
{
    const size_t nt3 = (size_t)g->collider_triangle_count * 3;
    if (g->near_tree) {
        geo_bvh_destroy(g->ctx, g->near_tree);
        weft__free(g->ctx, g->near_tree, sizeof *g->near_tree);
    }
    weft__free(g->ctx, g->near_cpos, (size_t)g->collider_vertex_count * 3 * sizeof(double));
    weft__free(g->ctx, g->near_across, nt3 * sizeof(uint32_t));
    weft__free(g->ctx, g->near_vt_start, ((size_t)g->collider_vertex_count + 1) * sizeof(uint32_t));
    weft__free(g->ctx, g->near_vt, nt3 * sizeof(uint32_t));
    weft__free(g->ctx, g->near_skip, g->vertex_count);
    weft__free(g->ctx, g->near_inside, g->vertex_count);
    weft__free(g->ctx, g->near_last, (size_t)g->vertex_count * sizeof(uint32_t));
    const size_t k = g->near_kcount;
    weft__free(g->ctx, g->near_knode, k * sizeof(uint32_t));
    weft__free(g->ctx, g->near_ktri, g->collider_triangle_count);
    weft__free(g->ctx, g->near_kvert, (size_t)g->collider_vertex_count * sizeof(uint64_t));
    weft__free(g->ctx, g->near_kinv, k * sizeof(double));
    weft__free(g->ctx, g->near_kmove, k * 4 * sizeof(double));
    weft__free(g->ctx, g->near_kreach, k * (k + 1) * sizeof(float));
    weft__free(g->ctx, g->near_kbox, 6 * CLUSTER_MAX * sizeof(float));
    g->near_kcount = 0;
    g->near_knode = NULL;
    g->near_ktri = NULL;
    g->near_kvert = NULL;
    g->near_kinv = NULL;
    g->near_kmove = NULL;
    g->near_kreach = NULL;
    g->near_kbox = NULL;
    g->near_tree = NULL;
    g->near_cpos = NULL;
    g->near_across = NULL;
    g->near_vt_start = NULL;
    g->near_vt = NULL;
    g->near_skip = NULL;
    g->near_inside = NULL;
    g->near_last = NULL;
}

static void refit_to(weft_garment *g, const float *c)
{
    const size_t nc3 = (size_t)g->collider_vertex_count * 3;
    for (size_t i = 0; i < nc3; ++i) {
        g->near_cpos[i] = c[i];
    }
    geo_bvh_refit(g->near_tree, g->near_cpos, NULL, 0.0);
}

void weft__near_refit(weft_garment *g)
{
    if (g->near_tree) {
        refit_to(g, g->collider_next);
    }
}

typedef struct near_query {
    const weft_garment *g;
    const double *p;
    weft_near_hit *hit;
    uint32_t mask; /* parts looked at (UINT32_MAX: all) */
} near_query;

static bool visit_near(uint32_t t, void *user)
{
    near_query *q = user;
    if (q->g->ctri_bits && !(q->g->ctri_bits[t] & q->mask)) {
        return true; /* a body part this vertex does not collide with */
    }
    const uint32_t *tri = q->g->collider_triangles + 3 * (size_t)t;
    const double *c = q->g->near_cpos;
    double bary[3];
    double d2 = geo_point_triangle_sq(q->p, c + 3 * (size_t)tri[0], c + 3 * (size_t)tri[1], c + 3 * (size_t)tri[2], bary);
    /* the least (distance, triangle index): the same answer in any visit order */
    if (d2 < q->hit->d2 || (d2 == q->hit->d2 && q->hit->tri != UINT32_MAX && t < q->hit->tri)) {
        q->hit->d2 = d2;
        q->hit->tri = t;
        memcpy(q->hit->bary, bary, sizeof bary);
    }
    return true;
}

bool weft__near_nearest(const weft_garment *g, const double p[3], double radius, uint32_t seed, weft_near_hit *hit)
{
    return weft__near_nearest_in(g, p, radius, seed, UINT32_MAX, hit);
}

bool weft__near_nearest_in(const weft_garment *g, const double p[3], double radius, uint32_t seed, uint32_t mask,
                           weft_near_hit *hit)
{
    hit->d2 = radius * radius;
    hit->tri = UINT32_MAX;
    near_query q = {.g = g, .p = p, .hit = hit, .mask = mask};
    if (seed != UINT32_MAX) {
        visit_near(seed, &q); /* last step's nearest triangle bounds the search from the start */
    }
    geo_bvh_nearest(g->near_tree, p, &hit->d2, visit_near, &q);
    if (hit->tri == UINT32_MAX) {
        return false;
    }
    const uint32_t *tri = g->collider_triangles + 3 * (size_t)hit->tri;
    for (int k = 0; k < 3; ++k) {
        hit->point[k] = 0.0;
        for (int j = 0; j < 3; ++j) {
            hit->point[k] += hit->bary[j] * g->near_cpos[3 * (size_t)tri[j] + k];
        }
    }
    return true;
}

/* Area-free unit face normal of collider triangle t at t+1 (zero for a collapsed one). */
static void face_normal(const weft_garment *g, uint32_t t, double n[3])
{
    const uint32_t *tri = g->collider_triangles + 3 * (size_t)t;
    const double *a = g->near_cpos + 3 * (size_t)tri[0], *b = g->near_cpos + 3 * (size_t)tri[1],
                 *c = g->near_cpos + 3 * (size_t)tri[2];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = u[1] * w[2] - u[2] * w[1];
    n[1] = u[2] * w[0] - u[0] * w[2];
    n[2] = u[0] * w[1] - u[1] * w[0];
    const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double inv = len > 1e-30 ? 1.0 / len : 0.0;
    for (int k = 0; k < 3; ++k) {
        n[k] *= inv;
    }
}

/* Interior angle of triangle t at its corner vertex v. */
static double corner_angle(const weft_garment *g, uint32_t t, uint32_t v)
{
    const uint32_t *tri = g->collider_triangles + 3 * (size_t)t;
    const int i = tri[0] == v ? 0 : (tri[1] == v ? 1 : 2);
    const double *o = g->near_cpos + 3 * (size_t)v, *a = g->near_cpos + 3 * (size_t)tri[(i + 1) % 3],
                 *b = g->near_cpos + 3 * (size_t)tri[(i + 2) % 3];
    const double u[3] = {a[0] - o[0], a[1] - o[1], a[2] - o[2]}, w[3] = {b[0] - o[0], b[1] - o[1], b[2] - o[2]};
    const double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]), u[0] * w[0] + u[1] * w[1] + u[2] * w[2]);
}

/* The pseudonormal of the feature the nearest point lies on (not normalised). */
static void feature_normal(const weft_garment *g, const weft_near_hit *hit, double n[3])
{
    const uint32_t *tri = g->collider_triangles + 3 * (size_t)hit->tri;
    const int zeros = (hit->bary[0] == 0.0) + (hit->bary[1] == 0.0) + (hit->bary[2] == 0.0);
    face_normal(g, hit->tri, n);
    if (zeros == 1) { /* on the edge opposite the zero weight: add the triangle across */
        const int z = hit->bary[0] == 0.0 ? 0 : (hit->bary[1] == 0.0 ? 1 : 2);
        const uint32_t across = g->near_across[3 * (size_t)hit->tri + (z + 1) % 3]; /* edge (z+1, z+2) */
        if (across != UINT32_MAX) {
            double m[3];
            face_normal(g, across, m);
            for (int k = 0; k < 3; ++k) {
                n[k] += m[k];
            }
        }
    } else if (zeros == 2) { /* at a corner: every triangle around it, weighted by its angle there */
        const uint32_t v = tri[hit->bary[0] != 0.0 ? 0 : (hit->bary[1] != 0.0 ? 1 : 2)];
        n[0] = n[1] = n[2] = 0.0;
        for (uint32_t s = g->near_vt_start[v]; s < g->near_vt_start[v + 1]; ++s) {
            double m[3];
            face_normal(g, g->near_vt[s], m);
            const double a = corner_angle(g, g->near_vt[s], v);
            for (int k = 0; k < 3; ++k) {
                n[k] += a * m[k];
            }
        }
    }
}

void weft__near_move_to(weft_garment *g, const double *c)
{
    memcpy(g->near_cpos, c, (size_t)g->collider_vertex_count * 3 * sizeof(double));
    geo_bvh_refit(g->near_tree, g->near_cpos, NULL, 0.0);
}

/* Which side of the surface p is on: (p - nearest point) . pseudonormal, negative inside; n gets
 * the pseudonormal. */
static double side_of(const weft_garment *g, const double p[3], const weft_near_hit *hit, double n[3])
{
    feature_normal(g, hit, n);
    double side = 0.0;
    for (int k = 0; k < 3; ++k) {
        side += (p[k] - hit->point[k]) * n[k];
    }
    return side;
}

bool weft__near_outward(const weft_garment *g, const double p[3], const weft_near_hit *hit, double out[3],
                        bool *inside)
{
    double n[3];
    *inside = side_of(g, p, hit, n) < 0.0;
    const double dist = sqrt(hit->d2);
    if (dist > 1e-12) {
        const double s = (*inside ? -1.0 : 1.0) / dist;
        for (int k = 0; k < 3; ++k) {
            out[k] = (p[k] - hit->point[k]) * s;
        }
        return true;
    }
    const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 1e-30)) {
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        out[k] = n[k] / len;
    }
    return true;
}

/* True when p is inside the collider within radius of its surface (hit: the nearest point). */
static bool inside_near(const weft_garment *g, const double p[3], double radius, uint32_t seed, uint32_t mask,
                        weft_near_hit *hit)
{
    double n[3];
    return weft__near_nearest_in(g, p, radius, seed, mask, hit) && side_of(g, p, hit, n) < 0.0;
}

uint32_t weft__near_mark_inside(weft_garment *g)
{
    if (!g->near_inside) {
        return 0;
    }
    refit_to(g, g->collider_prev); /* the collider at t, where x is */
    uint32_t count = 0;
    weft_near_hit hit;
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        const float *x = g->x + 3 * (size_t)v;
        const double p[3] = {x[0], x[1], x[2]};
        g->near_inside[v] = inside_near(g, p, g->push_depth, g->near_last[v], weft__part_mask(g, v), &hit);
        g->near_last[v] = hit.tri;
        count += g->near_inside[v];
    }
    return count;
}

/* Clearance. A vertex found outside the collider at distance d stays outside and farther than
 * d - (how far it moved) - (how far the surface moved) from it, both moves taken relative to
 * one common translation (distances do not change under one). Each step the clusters' mean move
 * r_k and their spread m_k about it (the largest |move - r_k| of their vertices) bound the
 * surface's move relative to the vertex's home cluster h: m_k + |r_k - r_h| for a triangle of
 * cluster k. A vertex keeps two lower bounds, on its distance to its near clusters (those within
 * d + CLEAR_MARGIN when it was found) and to all others, lowers both by that step's bound, and is
 * searched again only when one falls to the push thickness: before that no collider point is
 * near enough to push it, so skipping the search changes nothing. */
#define CLEAR_MARGIN 0.01
#define CLEAR_ROUND 1e-6 /* metres given away each step for rounding */
#define CLEAR_BEYOND 0.02 /* the push searches this much farther than it pushes from */

/* The shift of a vertex whose side is not known (nothing within the search's radius) or that is
 * deep inside: it needs no push while farther than push_depth, so its bounds are kept less
 * push_depth - push_thickness and tested against push_thickness as the others'. */
#define HOME_SHIFTED 0x80u

static double clear_shift(const weft_garment *g, uint32_t v)
{
    const double s = (double)g->push_depth - (double)g->push_thickness;
    return (g->near_home[v] & HOME_SHIFTED) && s > 0.0 ? s : 0.0;
}

/* The clusters' moves since the last push (near_kmove); then near_cref takes the collider at t+1. */
static void cluster_moves(weft_garment *g)
{
    const uint32_t k = g->near_kcount, nc = g->collider_vertex_count;
    double *mv = g->near_kmove;
    memset(mv, 0, (size_t)k * 4 * sizeof(double));
    for (uint32_t v = 0; v < nc; ++v) {
        const double *c = g->near_cpos + 3 * (size_t)v;
        const float *c0 = g->near_cref + 3 * (size_t)v;
        const double d[3] = {c[0] - c0[0], c[1] - c0[1], c[2] - c0[2]};
        for (uint64_t m = g->near_kvert[v]; m; m &= m - 1) {
            double *r = mv + 4 * (size_t)__builtin_ctzll(m);
            r[0] += d[0], r[1] += d[1], r[2] += d[2];
        }
    }
    for (uint32_t c = 0; c < k; ++c) {
        for (int j = 0; j < 3; ++j) {
            mv[4 * (size_t)c + j] *= g->near_kinv[c];
        }
    }
    for (uint32_t v = 0; v < nc; ++v) {
        const double *c = g->near_cpos + 3 * (size_t)v;
        float *c0 = g->near_cref + 3 * (size_t)v;
        const double d[3] = {c[0] - c0[0], c[1] - c0[1], c[2] - c0[2]};
        for (uint64_t m = g->near_kvert[v]; m; m &= m - 1) {
            double *r = mv + 4 * (size_t)__builtin_ctzll(m);
            double e[3];
            geo_sub(e, d, r);
            const double e2 = geo_dot(e, e);
            r[3] = e2 > r[3] ? e2 : r[3];
        }
        c0[0] = (float)c[0], c0[1] = (float)c[1], c0[2] = (float)c[2];
    }
    for (uint32_t c = 0; c < k; ++c) {
        mv[4 * (size_t)c + 3] = sqrt(mv[4 * (size_t)c + 3]);
    }
}

/* Row h of near_kreach: how far each cluster's surface moved relative to home cluster h's mean
 * move (its spread plus the difference of the means), and the row's largest. Made only for the
 * homes of the vertices that have a clearance to lower this step. */
static void reach_row(weft_garment *g, uint32_t h)
{
    const uint32_t k = g->near_kcount;
    const double *mv = g->near_kmove;
    float *row = g->near_kreach + (size_t)h * (k + 1);
    double most = 0.0;
    for (uint32_t c = 0; c < k; ++c) {
        double d[3];
        geo_sub(d, mv + 4 * (size_t)c, mv + 4 * (size_t)h);
        const double reach = mv[4 * (size_t)c + 3] + geo_len(d) + CLEAR_ROUND;
        row[c] = (float)reach;
        most = reach > most ? reach : most;
    }
    row[k] = (float)most;
}

/* The squared box distances of one vertex this step (cluster_d2), kept for its set_clear. */
typedef struct box_d2 {
    bool have;
    float d2[CLUSTER_MAX];
} box_d2;

static double rest_clearance(const weft_garment *g, uint64_t mask, const double p[3], box_d2 *bd);

/* True when v's clearance, lowered by this step's moves, still keeps it farther than thick
 * from the collider (no search needed). */
static bool still_clear(weft_garment *g, uint32_t v, const double p[3], double thick, box_d2 *bd)
{
    float *cl = g->near_clear + 2 * (size_t)v;
    if (!(cl[0] > 0.0f)) {
        return false;
    }
    const uint32_t k = g->near_kcount, h = g->near_home[v] & (CLUSTER_MAX - 1);
    const double *r = g->near_kmove + 4 * (size_t)h;
    float *at = g->near_at + 3 * (size_t)v;
    const double moved[3] = {p[0] - at[0] - r[0], p[1] - at[1] - r[1], p[2] - at[2] - r[2]};
    const double self = geo_len(moved) + CLEAR_ROUND;
    const float *row = g->near_kreach + (size_t)h * (k + 1);
    double near = 0.0;
    for (uint64_t m = g->near_kmask[v]; m; m &= m - 1) {
        const double reach = row[__builtin_ctzll(m)];
        near = reach > near ? reach : near;
    }
    double a = (double)cl[0] - self - near;
    double b = (double)cl[1] - self - row[k];
    if (a > thick && !(b > thick)) {
        b = rest_clearance(g, g->near_kmask[v], p, bd) - clear_shift(g, v); /* the far clusters' boxes, now */
    } else if (!(a > thick)) {
        a = b = rest_clearance(g, 0, p, bd) - clear_shift(g, v); /* every cluster's box, now */
    }
    at[0] = (float)p[0], at[1] = (float)p[1], at[2] = (float)p[2];
    if (a > thick && b > thick) {
        cl[0] = (float)a; /* rounds to nearest: CLEAR_ROUND covers it */
        cl[1] = (float)b;
        return true;
    }
    cl[0] = 0.0f;
    return false;
}

/* The clusters' boxes at t+1 in near_kbox (lo x, y, z, hi x, y, z; CLUSTER_MAX each), rounded
 * outward to float. */
static void cluster_boxes(weft_garment *g)
{
    float *b = g->near_kbox; /* slots past near_kcount stay the empty boxes make_clusters set */
    for (uint32_t c = 0; c < g->near_kcount; ++c) {
        const geo_bvh_node *nd = &g->near_tree->nodes[g->near_knode[c]];
        for (int a = 0; a < 3; ++a) {
            float lo = (float)nd->lo[a], hi = (float)nd->hi[a];
            lo = (double)lo > nd->lo[a] ? nextafterf(lo, -INFINITY) : lo;
            hi = (double)hi < nd->hi[a] ? nextafterf(hi, INFINITY) : hi;
            b[a * CLUSTER_MAX + c] = lo;
            b[(3 + a) * CLUSTER_MAX + c] = hi;
        }
    }
}

/* Squared distances from p to every cluster's box. */
static void cluster_d2(const weft_garment *g, const double p[3], float d2[CLUSTER_MAX])
{
    const float *b = g->near_kbox; /* all CLUSTER_MAX slots: a fixed count the compiler vectorises */
    const float px = (float)p[0], py = (float)p[1], pz = (float)p[2]; /* p is a float position */
    for (uint32_t c = 0; c < CLUSTER_MAX; ++c) {
        float ex = b[c] - px, ey = b[CLUSTER_MAX + c] - py, ez = b[2 * CLUSTER_MAX + c] - pz;
        const float fx = px - b[3 * CLUSTER_MAX + c], fy = py - b[4 * CLUSTER_MAX + c], fz = pz - b[5 * CLUSTER_MAX + c];
        ex = ex > fx ? ex : fx, ey = ey > fy ? ey : fy, ez = ez > fz ? ez : fz;
        ex = ex > 0.0f ? ex : 0.0f, ey = ey > 0.0f ? ey : 0.0f, ez = ez > 0.0f ? ez : 0.0f;
        d2[c] = ex * ex + ey * ey + ez * ez;
    }
}

/* The distance from p to the boxes of the clusters not in mask, less rounding; +inf if none. */
static double rest_clearance(const weft_garment *g, uint64_t mask, const double p[3], box_d2 *bd)
{
    if (!bd->have) {
        cluster_d2(g, p, bd->d2);
        bd->have = true;
    }
    float rest2 = INFINITY;
    for (uint32_t c = 0; c < g->near_kcount; ++c) {
        rest2 = !(mask >> c & 1u) && bd->d2[c] < rest2 ? bd->d2[c] : rest2;
    }
    return sqrt((double)rest2) - CLEAR_ROUND;
}

/* v is at least dist from the collider at p (outside, or else `shifted`): its clearance from
 * here; home is the cluster of its nearest triangle, or UINT32_MAX for the nearest box's. */
static void set_clear(weft_garment *g, uint32_t v, const double p[3], double dist, uint32_t home, bool shifted,
                      box_d2 *bd)
{
    if (!bd->have) {
        cluster_d2(g, p, bd->d2);
        bd->have = true;
    }
    const float *d2 = bd->d2;
    const float reach = (float)(dist + CLEAR_MARGIN), reach2 = reach * reach;
    float rest2 = INFINITY, least = INFINITY;
    uint64_t mask = 0;
    uint32_t nearest = 0;
    for (uint32_t c = 0; c < g->near_kcount; ++c) {
        if (d2[c] < reach2) {
            mask |= UINT64_C(1) << c;
        } else {
            rest2 = d2[c] < rest2 ? d2[c] : rest2;
        }
        if (d2[c] < least) {
            least = d2[c], nearest = c;
        }
    }
    g->near_home[v] = (uint8_t)((home == UINT32_MAX ? nearest : home) | (shifted ? HOME_SHIFTED : 0u));
    const double shift = clear_shift(g, v);
    float *cl = g->near_clear + 2 * (size_t)v, *at = g->near_at + 3 * (size_t)v;
    cl[0] = (float)(dist - shift - CLEAR_ROUND); /* <= 0 (search again) unless it clears push_thickness */
    cl[1] = (float)(sqrt((double)rest2) - shift - CLEAR_ROUND); /* +inf when every cluster is near */
    g->near_kmask[v] = mask;
    at[0] = (float)p[0], at[1] = (float)p[1], at[2] = (float)p[2];
}

void weft__push(weft_garment *g)
{
    uint32_t pushed = 0, far = 0, searched = 0;
    if (!g->near_skip) {
        return;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        g->near_skip[g->pin_indices[k]] |= 2; /* pinned vertices keep their targets */
    }
    const bool primed = g->near_primed;
    cluster_boxes(g);
    if (primed) {
        cluster_moves(g);
        uint64_t homes = 0; /* the reach rows this step needs */
        for (uint32_t v = 0; v < g->vertex_count; ++v) {
            homes |= g->near_clear[2 * (size_t)v] > 0.0f ? UINT64_C(1) << (g->near_home[v] & (CLUSTER_MAX - 1)) : 0;
        }
        for (; homes; homes &= homes - 1) {
            reach_row(g, (uint32_t)__builtin_ctzll(homes));
        }
    } else {
        for (size_t i = 0; i < (size_t)g->collider_vertex_count * 3; ++i) {
            g->near_cref[i] = (float)g->near_cpos[i];
        }
        g->near_primed = true;
    }
    const double thick = g->push_thickness, depth = g->push_depth;
    const double radius = (thick > depth ? thick : depth) + CLEAR_BEYOND;
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        if (g->near_skip[v]) {
            g->near_clear[2 * (size_t)v] = 0.0f;
            continue;
        }
        float *x = g->x_next + 3 * (size_t)v;
        const double p[3] = {x[0], x[1], x[2]};
        box_d2 bd;
        bd.have = false;
        if (primed && !g->near_search_all && still_clear(g, v, p, thick, &bd)) {
            continue;
        }
        ++searched;
        weft_near_hit hit;
        const bool found = weft__near_nearest_in(g, p, radius, g->near_last[v], weft__part_mask(g, v), &hit);
        g->near_last[v] = hit.tri; /* UINT32_MAX when nothing is that near */
        g->near_clear[2 * (size_t)v] = 0.0f;
        if (!found) { /* farther than radius, on either side */
            set_clear(g, v, p, radius, UINT32_MAX, true, &bd);
            continue;
        }
        double out[3];
        bool inside;
        const bool has_out = weft__near_outward(g, p, &hit, out, &inside);
        const double dist = sqrt(hit.d2);
        if (inside ? dist > depth : dist >= thick) {
            set_clear(g, v, p, dist, g->near_ktri[hit.tri], inside, &bd);
            continue;
        }
        if (!has_out) {
            continue;
        }
        /* A vertex that entered through the far side moved outward relative to this surface
         * point (its motion less the collider's there) by at least the collider's thickness less
         * its depth, which is more than its depth; pushing it out here would take it through.
         * One that came in through this side moved inward. */
        if (inside && !(g->near_inside && g->near_inside[v])) { /* cloth inside at t may go either way */
            const float *x0 = g->x + 3 * (size_t)v;
            const uint32_t *tri = g->collider_triangles + 3 * (size_t)hit.tri;
            double along = 0.0;
            for (int k = 0; k < 3; ++k) {
                double c0 = 0.0;
                for (int j = 0; j < 3; ++j) {
                    c0 += hit.bary[j] * g->collider_prev[3 * (size_t)tri[j] + k];
                }
                along += (((double)x[k] - x0[k]) - (hit.point[k] - c0)) * out[k];
            }
            if (along > dist) {
                ++far;
                continue;
            }
        }
        for (int k = 0; k < 3; ++k) {
            x[k] = (float)(hit.point[k] + thick * out[k]);
        }
        ++pushed;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        g->near_skip[g->pin_indices[k]] &= 1;
    }
    g->stats.pushed_vertices = pushed;
    g->stats.push_searched = searched;
    g->stats.push_from_far_side = far;
}
