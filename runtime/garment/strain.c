/* Strain limiting of a step's output (every method): edges longer than (1 + limit) x rest are
 * shortened by Gauss-Seidel sweeps, each endpoint moving by its share (pinned vertices and those
 * glued by radius-0 tethers do not move). Learned steps and tether clamps move vertices one by one,
 * so neighbours can end a step far apart; this restores the cloth's near-inextensibility cheaply
 * (a few sweeps over the edges, no allocation) before CCD, which then works on a sane mesh.
 * Contact-aware (strain_contact > 0): a vertex near the collider at t+1 keeps only the part of
 * its correction that does not point into the collider (it slides along the surface or leaves
 * it). Without it, the hanging part of a sheet draped over an object drags the part lying on it
 * into the object (docs/MODEL.md). */
#include "garment/garment.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

weft_result weft__strain_create(weft_garment *g)
{
    size_t n = (size_t)g->triangle_count * 3;
    uint64_t *keys = weft__alloc(g->ctx, n * sizeof *keys);
    if (!keys) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t i = 0; i < n; ++i) {
        uint32_t a = g->triangles[i], b = g->triangles[i - i % 3 + (i % 3 + 1) % 3];
        keys[i] = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
    }
    qsort(keys, n, sizeof *keys, cmp_u64);
    uint32_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        m += i == 0 || keys[i] != keys[i - 1];
    }
    g->strain_edge_count = m; /* before the allocations: a failure frees them at their sizes */
    g->strain_edges = weft__alloc(g->ctx, (size_t)m * 2 * sizeof(uint32_t));
    g->strain_rest = weft__alloc(g->ctx, (size_t)m * sizeof(float));
    g->strain_fixed = weft__alloc(g->ctx, g->vertex_count);
    g->strain_moved = weft__alloc(g->ctx, (size_t)g->vertex_count * sizeof(uint32_t));
    g->strain_hot = weft__alloc(g->ctx, m);
    if (!g->strain_edges || !g->strain_rest || !g->strain_fixed || !g->strain_moved || !g->strain_hot) {
        weft__free(g->ctx, keys, n * sizeof *keys);
        weft__strain_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    if (g->strain_contact > 0.0f && g->collider_vertex_count > 0) {
        g->strain_normal = weft__alloc(g->ctx, (size_t)g->vertex_count * 3 * sizeof(float));
        if (!g->strain_normal) {
            weft__free(g->ctx, keys, n * sizeof *keys);
            weft__strain_destroy(g);
            return WEFT_ERROR_OUT_OF_MEMORY;
        }
    }
    for (uint32_t i = 0; i < g->vertex_count; ++i) {
        g->strain_fixed[i] = g->tether_radius && g->tether_radius[i] == 0.0f; /* glued for good */
    }
    uint32_t e = 0;
    for (size_t i = 0; i < n; ++i) {
        if (i > 0 && keys[i] == keys[i - 1]) {
            continue;
        }
        uint32_t a = (uint32_t)(keys[i] >> 32), b = (uint32_t)keys[i];
        const float *p = g->rest + 3 * (size_t)a, *q = g->rest + 3 * (size_t)b;
        float d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        g->strain_edges[2 * e] = a;
        g->strain_edges[2 * e + 1] = b;
        g->strain_rest[e] = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        e++;
    }
    weft__free(g->ctx, keys, n * sizeof *keys);
    return WEFT_OK;
}

void weft__strain_destroy(weft_garment *g)
{
    weft__free(g->ctx, g->strain_edges, (size_t)g->strain_edge_count * 2 * sizeof(uint32_t));
    weft__free(g->ctx, g->strain_rest, (size_t)g->strain_edge_count * sizeof(float));
    weft__free(g->ctx, g->strain_fixed, g->vertex_count);
    weft__free(g->ctx, g->strain_moved, (size_t)g->vertex_count * sizeof(uint32_t));
    weft__free(g->ctx, g->strain_hot, g->strain_edge_count);
    weft__free(g->ctx, g->strain_normal, (size_t)g->vertex_count * 3 * sizeof(float));
    g->strain_normal = NULL;
    g->strain_edges = NULL;
    g->strain_rest = NULL;
    g->strain_fixed = NULL;
    g->strain_moved = NULL;
    g->strain_hot = NULL;
    g->strain_edge_count = 0;
}

/* Unit direction from the nearest collider point to p; when p lies on the surface, the face
 * normal of the triangle's winding (outward on the closed colliders weft builds). False when it
 * is undefined. */
static bool away_direction(const weft_garment *g, const double p[3], const weft_near_hit *q, float n[3])
{
    const uint32_t *tri = g->collider_triangles + 3 * (size_t)q->tri;
    const double *a = g->near_cpos + 3 * (size_t)tri[0], *b = g->near_cpos + 3 * (size_t)tri[1],
                 *c = g->near_cpos + 3 * (size_t)tri[2];
    double d[3], len2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        d[k] = p[k] - (q->bary[0] * a[k] + q->bary[1] * b[k] + q->bary[2] * c[k]);
        len2 += d[k] * d[k];
    }
    if (len2 < 1e-16) {
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        d[0] = u[1] * w[2] - u[2] * w[1];
        d[1] = u[2] * w[0] - u[0] * w[2];
        d[2] = u[0] * w[1] - u[1] * w[0];
        len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if (len2 < 1e-30) {
            return false;
        }
    }
    const double inv = 1.0 / sqrt(len2);
    for (int k = 0; k < 3; ++k) {
        n[k] = (float)(d[k] * inv);
    }
    return true;
}

/* Sets bit 4 on the vertices of x_next within strain_contact of the collider at t+1, with the
 * direction away from the nearest collider point in strain_normal (the tree is at t+1 already). */
static void mark_contacts(weft_garment *g)
{
    weft_near_hit hit;
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        const float *x = g->x_next + 3 * (size_t)v;
        const double p[3] = {x[0], x[1], x[2]};
        const uint32_t seed = g->near_last ? g->near_last[v] : UINT32_MAX; /* the push's last answer */
        if (weft__near_nearest_in(g, p, g->strain_contact, seed, weft__part_mask(g, v), &hit) &&
            away_direction(g, p, &hit, g->strain_normal + 3 * (size_t)v)) {
            g->strain_fixed[v] |= 4;
        }
    }
}

static inline void drop_inward(float dx[3], const float n[3])
{
    const float into = dx[0] * n[0] + dx[1] * n[1] + dx[2] * n[2];
    if (into < 0.0f) {
        for (int k = 0; k < 3; ++k) {
            dx[k] -= into * n[k];
        }
    }
}

void weft__strain_limit(weft_garment *g)
{
    /* Bit 0: glued by a radius-0 tether (set at creation); bit 1: pinned this step. */
    uint8_t *fixed = g->strain_fixed;
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        fixed[g->pin_indices[k]] |= 2;
    }
    if (g->strain_normal) {
        mark_contacts(g);
    }
    const float grow = 1.0f + g->strain_limit;
    float *x = g->x_next;
    uint32_t over = 0;
    /* After the first sweep an edge is measured again only if it was over when last measured or
     * an end has moved since (moved[v]: 1 + the last sweep that moved v): any other edge has the
     * length it was found within the cap at, so the sweeps do exactly what measuring every edge
     * would, at the cost of the edges near the ones still over. */
    uint32_t *moved = g->strain_moved;
    uint8_t *hot = g->strain_hot;
    memset(moved, 0, (size_t)g->vertex_count * sizeof *moved);
    for (uint32_t sweep = 0; sweep < g->strain_iterations; ++sweep) {
        uint32_t n = 0;
        for (uint32_t e = 0; e < g->strain_edge_count; ++e) {
            uint32_t a = g->strain_edges[2 * e], b = g->strain_edges[2 * e + 1];
            if (sweep > 0 && !hot[e] && moved[a] < sweep && moved[b] < sweep) {
                continue;
            }
            float *p = x + 3 * (size_t)a, *q = x + 3 * (size_t)b;
            float d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            float cap = grow * g->strain_rest[e];
            hot[e] = len > cap;
            if (!(len > cap)) {
                continue;
            }
            n++;
            /* Pinned and glued ends stay put. */
            float wa = fixed[a] & 3 ? 0.0f : 1.0f, wb = fixed[b] & 3 ? 0.0f : 1.0f;
            if (wa + wb == 0.0f) {
                continue;
            }
            float s = (len - cap) / (len * (wa + wb)); /* len > cap >= 0 */
            float dp[3], dq[3];
            for (int k = 0; k < 3; ++k) {
                dp[k] = wa * s * d[k];
                dq[k] = -wb * s * d[k];
            }
            /* An end touching the collider keeps only the part of its move that does not go
             * into it: it may slide along the surface or leave it. */
            if (fixed[a] & 4) {
                drop_inward(dp, g->strain_normal + 3 * (size_t)a);
            }
            if (fixed[b] & 4) {
                drop_inward(dq, g->strain_normal + 3 * (size_t)b);
            }
            for (int k = 0; k < 3; ++k) {
                p[k] += dp[k];
                q[k] += dq[k];
            }
            moved[a] = moved[b] = sweep + 1;
        }
        if (sweep == 0) {
            over = n;
        }
        if (n == 0) {
            break;
        }
    }
    for (uint32_t v = 0; g->strain_normal && v < g->vertex_count; ++v) {
        fixed[v] &= 3;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        fixed[g->pin_indices[k]] &= 1;
    }
    g->stats.strain_limited_edges = over;
}
