/* Body parts: which collider triangles each garment vertex collides with.
 *
 * A skinned body that overlaps itself (a forearm sunk into the chest, a hand inside a thigh)
 * has cloth caught between two surfaces that both claim it. Held by both, the cloth is carried
 * off with whichever moves away; pushed out of the nearest, it goes through the other. Game
 * cloth avoids this by colliding each garment region only with the body shapes it belongs to;
 * weft does the same with a partition of the collider's triangles that the host gives
 * (weft_garment_def.collision.triangle_parts, e.g. the dominant bone of each triangle from
 * weft_body_triangle_parts).
 *
 * At creation each garment vertex gets a 32-bit mask of parts: those of the collider triangles
 * within collision.part_margin of its nearest collider point in the initial state, and every
 * part adjacent to one of those on the collider mesh (sharing a vertex), so that cloth sliding
 * across a joint still meets the next part. Every collision stage (the collider push, the
 * contact-aware strain limit, the fast XPBD projection, the reference XPBD's contacts and the
 * CCD post-process) then skips the pairs of a vertex and a triangle of a part outside its mask.
 * Work is made once here; the per-frame cost is one AND per candidate pair. */
#include "garment/garment.h"
#include "geometry/geometry.h"

#include <math.h>
#include <string.h>

typedef struct part_query {
    const weft_garment *g;
    const double *pos; /* collider rest positions, doubles */
    const double *p;
    double best;       /* squared distance to the nearest triangle so far */
    double limit;      /* second pass: squared distance bound */
    uint32_t mask;     /* second pass: parts found */
} part_query;

static double tri_d2(const part_query *q, uint32_t t)
{
    const uint32_t *tri = q->g->collider_triangles + 3 * (size_t)t;
    double bary[3];
    return geo_point_triangle_sq(q->p, q->pos + 3 * (size_t)tri[0], q->pos + 3 * (size_t)tri[1],
                                q->pos + 3 * (size_t)tri[2], bary);
}

static bool visit_nearest(uint32_t t, void *user)
{
    part_query *q = user;
    const double d2 = tri_d2(q, t);
    q->best = d2 < q->best ? d2 : q->best;
    return true;
}

static bool visit_within(uint32_t t, void *user)
{
    part_query *q = user;
    if (tri_d2(q, t) <= q->limit) {
        q->mask |= q->g->ctri_bits[t];
    }
    return true;
}

weft_result weft__parts_create(weft_garment *g, const uint8_t *parts, float margin, bool neighbours)
{
    if (!parts) {
        return WEFT_OK;
    }
    const weft_context *ctx = g->ctx;
    const uint32_t nt = g->collider_triangle_count, nc = g->collider_vertex_count, nv = g->vertex_count;
    g->ctri_bits = weft__alloc(ctx, (size_t)nt * sizeof(uint32_t));
    g->cvert_bits = weft__alloc(ctx, (size_t)nc * sizeof(uint32_t));
    g->part_mask = weft__alloc(ctx, (size_t)nv * sizeof(uint32_t));
    double *pos = weft__alloc(ctx, (size_t)nc * 3 * sizeof(double));
    geo_bvh tree;
    memset(&tree, 0, sizeof tree);
    weft_result r = g->ctri_bits && g->cvert_bits && g->part_mask && pos ? WEFT_OK : WEFT_ERROR_OUT_OF_MEMORY;
    if (r == WEFT_OK) {
        r = geo_bvh_create(ctx, &tree, g->collider_triangles, nt, 3);
    }
    if (r != WEFT_OK) {
        weft__free(ctx, pos, (size_t)nc * 3 * sizeof(double));
        weft__parts_destroy(g);
        return r;
    }
    uint32_t adjacent[32] = {0};
    memset(g->cvert_bits, 0, (size_t)nc * sizeof(uint32_t));
    for (uint32_t t = 0; t < nt; ++t) {
        g->ctri_bits[t] = 1u << parts[t];
        for (int k = 0; k < 3; ++k) {
            g->cvert_bits[g->collider_triangles[3 * (size_t)t + k]] |= g->ctri_bits[t];
        }
    }
    for (uint32_t u = 0; u < nc; ++u) { /* parts meeting at a collider vertex are adjacent */
        for (uint32_t bits = g->cvert_bits[u]; bits; bits &= bits - 1) {
            adjacent[__builtin_ctz(bits)] |= g->cvert_bits[u];
        }
    }
    for (size_t i = 0; i < (size_t)nc * 3; ++i) {
        pos[i] = g->collider_rest[i];
    }
    geo_bvh_build(&tree, pos);
    geo_bvh_refit(&tree, pos, NULL, 0.0); /* build orders the primitives; refit makes the boxes */
    const geo_bvh_node *root = &tree.nodes[0];
    double diag2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        diag2 += (root->hi[k] - root->lo[k]) * (root->hi[k] - root->lo[k]);
    }
    for (uint32_t v = 0; v < nv; ++v) {
        double p[3];
        for (int k = 0; k < 3; ++k) {
            p[k] = g->x[3 * (size_t)v + k];
        }
        part_query q = {.g = g, .pos = pos, .p = p, .best = INFINITY};
        /* the nearest triangle: boxes growing from 5 cm until one holds a triangle and the
         * nearest found lies within the box (then no triangle outside it is nearer) */
        double dist = 0.0;
        for (double reach = 0.05;; reach *= 2.0) {
            double lo[3], hi[3], out2 = 0.0;
            for (int k = 0; k < 3; ++k) {
                lo[k] = p[k] - reach;
                hi[k] = p[k] + reach;
                const double o = p[k] < root->lo[k] ? root->lo[k] - p[k] : (p[k] > root->hi[k] ? p[k] - root->hi[k] : 0.0);
                out2 += o * o;
            }
            geo_bvh_query(&tree, lo, hi, visit_nearest, &q);
            if (q.best <= reach * reach || reach * reach > 4.0 * (diag2 + out2)) {
                dist = sqrt(q.best);
                break;
            }
        }
        if (!isfinite(dist)) { /* no triangle at all: cannot happen on a valid collider */
            g->part_mask[v] = UINT32_MAX;
            continue;
        }
        const double within = dist + (double)margin;
        q.limit = within * within;
        q.mask = 0;
        double lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
            lo[k] = p[k] - within;
            hi[k] = p[k] + within;
        }
        geo_bvh_query(&tree, lo, hi, visit_within, &q);
        uint32_t mask = q.mask;
        for (uint32_t bits = neighbours ? q.mask : 0u; bits; bits &= bits - 1) {
            mask |= adjacent[__builtin_ctz(bits)];
        }
        g->part_mask[v] = mask;
    }
    geo_bvh_destroy(ctx, &tree);
    weft__free(ctx, pos, (size_t)nc * 3 * sizeof(double));
    return WEFT_OK;
}

void weft__parts_destroy(weft_garment *g)
{
    weft__free(g->ctx, g->ctri_bits, (size_t)g->collider_triangle_count * sizeof(uint32_t));
    weft__free(g->ctx, g->cvert_bits, (size_t)g->collider_vertex_count * sizeof(uint32_t));
    weft__free(g->ctx, g->part_mask, (size_t)g->vertex_count * sizeof(uint32_t));
    g->ctri_bits = NULL;
    g->cvert_bits = NULL;
    g->part_mask = NULL;
}
