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

weft_result weft__near_create(weft_garment *g)
{
    const bool fast = g->method == WEFT_METHOD_XPBD_FAST; /* its collider projection (xpbd_solver.c) */
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

void weft__push(weft_garment *g)
{
    uint32_t pushed = 0, far = 0;
    if (!g->near_skip) {
        return;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        g->near_skip[g->pin_indices[k]] |= 2; /* pinned vertices keep their targets */
    }
    const double thick = g->push_thickness, depth = g->push_depth;
    const double radius = thick > depth ? thick : depth;
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        if (g->near_skip[v]) {
            continue;
        }
        float *x = g->x_next + 3 * (size_t)v;
        const double p[3] = {x[0], x[1], x[2]};
        weft_near_hit hit;
        const bool found = weft__near_nearest_in(g, p, radius, g->near_last[v], weft__part_mask(g, v), &hit);
        g->near_last[v] = hit.tri; /* UINT32_MAX when nothing is that near */
        if (!found) {
            continue;
        }
        double out[3];
        bool inside;
        const bool has_out = weft__near_outward(g, p, &hit, out, &inside);
        const double dist = sqrt(hit.d2);
        if ((inside ? dist > depth : dist >= thick) || !has_out) {
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
    g->stats.push_from_far_side = far;
}
