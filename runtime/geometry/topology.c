/* Edges, hinges and edge-triangle incidence of a triangle mesh. */
#include "geometry/geometry.h"

#include <stdlib.h>

typedef struct half_edge {
    uint32_t lo, hi, tri, slot;
} half_edge;

static int cmp_half_edge(const void *pa, const void *pb)
{
    const half_edge *a = pa, *b = pb;
    if (a->lo != b->lo) {
        return a->lo < b->lo ? -1 : 1;
    }
    if (a->hi != b->hi) {
        return a->hi < b->hi ? -1 : 1;
    }
    return a->tri < b->tri ? -1 : (a->tri > b->tri);
}

void geo_topo_destroy(const weft_context *ctx, geo_topo *topo)
{
    weft__free(ctx, topo->edges, (size_t)topo->edge_count * 2 * sizeof(uint32_t));
    weft__free(ctx, topo->edge_tri, (size_t)topo->edge_count * 2 * sizeof(uint32_t));
    weft__free(ctx, topo->hinges, (size_t)topo->hinge_count * 4 * sizeof(uint32_t));
    *topo = (geo_topo){0};
}

weft_result geo_topo_create(const weft_context *ctx, geo_topo *topo, const uint32_t *tris, uint32_t triangle_count,
                         uint32_t vertex_count, const char *what)
{
    *topo = (geo_topo){0};
    topo->tris = tris;
    topo->vertex_count = vertex_count;
    topo->triangle_count = triangle_count;
    size_t nh = (size_t)triangle_count * 3;
    half_edge *he = weft__alloc(ctx, nh * sizeof *he);
    if (!he) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t t = 0; t < triangle_count; ++t) {
        for (uint32_t k = 0; k < 3; ++k) {
            uint32_t a = tris[3 * (size_t)t + k], b = tris[3 * (size_t)t + (k + 1) % 3];
            he[3 * (size_t)t + k] = (half_edge){a < b ? a : b, a < b ? b : a, t, k};
        }
    }
    qsort(he, nh, sizeof *he, cmp_half_edge);
    uint32_t edges = 0, hinges = 0;
    for (size_t i = 0; i < nh;) {
        size_t j = i + 1;
        while (j < nh && he[j].lo == he[i].lo && he[j].hi == he[i].hi) {
            ++j;
        }
        if (j - i > 2 && what) {
            uint32_t lo = he[i].lo, hi = he[i].hi;
            weft__free(ctx, he, nh * sizeof *he);
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH,
                              "%s: non-manifold edge (%u, %u) is shared by %zu triangles (at most 2 allowed)", what, lo,
                              hi, j - i);
        }
        edges++;
        if (j - i == 2) {
            const uint32_t *ta = tris + 3 * (size_t)he[i].tri, *tb = tris + 3 * (size_t)he[i + 1].tri;
            if (what && ta[(he[i].slot + 2) % 3] == tb[(he[i + 1].slot + 2) % 3]) {
                uint32_t t0 = he[i].tri, t1 = he[i + 1].tri;
                weft__free(ctx, he, nh * sizeof *he);
                return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: triangles %u and %u are duplicates", what, t0, t1);
            }
            hinges++;
        }
        i = j;
    }
    topo->edge_count = edges;
    topo->hinge_count = hinges;
    topo->edges = weft__alloc(ctx, (size_t)edges * 2 * sizeof(uint32_t));
    topo->edge_tri = weft__alloc(ctx, (size_t)edges * 2 * sizeof(uint32_t));
    topo->hinges = weft__alloc(ctx, (size_t)(hinges ? hinges : 1) * 4 * sizeof(uint32_t));
    if (!topo->edges || !topo->edge_tri || !topo->hinges) {
        weft__free(ctx, he, nh * sizeof *he);
        geo_topo_destroy(ctx, topo);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    uint32_t e = 0, h = 0;
    for (size_t i = 0; i < nh;) {
        size_t j = i + 1;
        while (j < nh && he[j].lo == he[i].lo && he[j].hi == he[i].hi) {
            ++j;
        }
        topo->edges[2 * e] = he[i].lo;
        topo->edges[2 * e + 1] = he[i].hi;
        topo->edge_tri[2 * e] = he[i].tri;
        topo->edge_tri[2 * e + 1] = j - i == 2 ? he[i + 1].tri : UINT32_MAX;
        if (j - i == 2 && h < hinges) {
            /* The hinge edge follows the first triangle's winding; the wing of the second
             * triangle is its vertex off the edge (its winding does not matter). */
            const uint32_t *ta = tris + 3 * (size_t)he[i].tri, *tb = tris + 3 * (size_t)he[i + 1].tri;
            uint32_t k = he[i].slot;
            uint32_t *hg = topo->hinges + 4 * (size_t)h;
            hg[0] = ta[k];
            hg[1] = ta[(k + 1) % 3];
            hg[2] = ta[(k + 2) % 3];
            hg[3] = tb[(he[i + 1].slot + 2) % 3];
            h++;
        }
        e++;
        i = j;
    }
    weft__free(ctx, he, nh * sizeof *he);
    return WEFT_OK;
}
