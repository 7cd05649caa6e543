/* Independent penetration validator: shares only the geometry kernels and the BVH with the
 * solver, never its contact or bound logic. A frame pair passes when no swept
 * vertex-triangle or edge-edge pair comes closer than WEFT_SIM_VALIDATOR_TOLERANCE over the
 * linear motion between the frames, and no two triangles intersect at the later frame. */
#include "weft/sim.h"
#include "xpbd/xpbd.h"

#include <string.h>

struct weft_sim_validator {
    weft_context *ctx;
    uint32_t n, nt, nc, nct;
    uint32_t *tris, *ctris;
    xtopo topo, ctopo;
    double *x0, *x1, *c0, *c1;
    xbvh bvh_tri, bvh_edge, bvh_ctri, bvh_cedge;
};

typedef struct vctx {
    weft_sim_validator *v;
    uint32_t query;
    weft_sim_validation *out;
} vctx;

/* Sweeps one primitive pair over the frame: the first `na` of the 4 points are vertices ia of
 * the mesh at a0 -> a1, the rest vertices ib of the mesh at b0 -> b1. Vertex-triangle when
 * na == 1, edge-edge when na == 2. */
static void sweep(vctx *c, const double *a0, const double *a1, const uint32_t *ia, int na, const double *b0,
                  const double *b1, const uint32_t *ib)
{
    const double *p[4];
    double dp[12];
    for (int i = 0; i < 4; ++i) {
        const double *x0 = i < na ? a0 : b0, *x1 = i < na ? a1 : b1;
        size_t idx = 3 * (size_t)(i < na ? ia[i] : ib[i - na]);
        p[i] = x0 + idx;
        for (int k = 0; k < 3; ++k) {
            dp[3 * i + k] = x1[idx + k] - x0[idx + k];
        }
    }
    c->out->pairs_tested++;
    c->out->ccd_hits += na == 1 ? xg_accd_point_triangle(p, dp, WEFT_SIM_VALIDATOR_TOLERANCE)
                                : xg_accd_edge_edge(p, dp, WEFT_SIM_VALIDATOR_TOLERANCE);
}

static bool v_self_vt(uint32_t t, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    const uint32_t *tri = v->tris + 3 * (size_t)t;
    uint32_t p = c->query;
    if (tri[0] == p || tri[1] == p || tri[2] == p) {
        return true;
    }
    sweep(c, v->x0, v->x1, &p, 1, v->x0, v->x1, tri);
    return true;
}

static bool v_self_ee(uint32_t e2, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    if (e2 <= c->query) {
        return true;
    }
    const uint32_t *ea = v->topo.edges + 2 * (size_t)c->query, *eb = v->topo.edges + 2 * (size_t)e2;
    if (ea[0] == eb[0] || ea[0] == eb[1] || ea[1] == eb[0] || ea[1] == eb[1]) {
        return true;
    }
    sweep(c, v->x0, v->x1, ea, 2, v->x0, v->x1, eb);
    return true;
}

static bool v_vt_collider(uint32_t t, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    const uint32_t *tri = v->ctris + 3 * (size_t)t;
    uint32_t p = c->query;
    sweep(c, v->x0, v->x1, &p, 1, v->c0, v->c1, tri);
    return true;
}

static bool v_tv_collider(uint32_t t, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    const uint32_t *tri = v->tris + 3 * (size_t)t;
    uint32_t u = c->query;
    sweep(c, v->c0, v->c1, &u, 1, v->x0, v->x1, tri);
    return true;
}

static bool v_ee_collider(uint32_t ce, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    const uint32_t *ea = v->topo.edges + 2 * (size_t)c->query, *eb = v->ctopo.edges + 2 * (size_t)ce;
    sweep(c, v->x0, v->x1, ea, 2, v->c0, v->c1, eb);
    return true;
}

static bool v_tt_self(uint32_t t2, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    if (t2 <= c->query) {
        return true;
    }
    const uint32_t *a = v->tris + 3 * (size_t)c->query, *b = v->tris + 3 * (size_t)t2;
    for (int i = 0; i < 3; ++i) {
        if (a[i] == b[0] || a[i] == b[1] || a[i] == b[2]) {
            return true;
        }
    }
    const double *x = v->x1;
    c->out->intersection_hits +=
        xg_triangles_intersect(x + 3 * (size_t)a[0], x + 3 * (size_t)a[1], x + 3 * (size_t)a[2], x + 3 * (size_t)b[0],
                               x + 3 * (size_t)b[1], x + 3 * (size_t)b[2]);
    return true;
}

static bool v_tt_collider(uint32_t t2, void *user)
{
    vctx *c = user;
    weft_sim_validator *v = c->v;
    const uint32_t *a = v->tris + 3 * (size_t)c->query, *b = v->ctris + 3 * (size_t)t2;
    const double *x = v->x1, *y = v->c1;
    c->out->intersection_hits +=
        xg_triangles_intersect(x + 3 * (size_t)a[0], x + 3 * (size_t)a[1], x + 3 * (size_t)a[2], y + 3 * (size_t)b[0],
                               y + 3 * (size_t)b[1], y + 3 * (size_t)b[2]);
    return true;
}

void weft_sim_validator_destroy(weft_sim_validator *v)
{
    if (!v) {
        return;
    }
    const weft_context *ctx = v->ctx;
    xbvh_destroy(ctx, &v->bvh_tri);
    xbvh_destroy(ctx, &v->bvh_edge);
    xbvh_destroy(ctx, &v->bvh_ctri);
    xbvh_destroy(ctx, &v->bvh_cedge);
    xtopo_destroy(ctx, &v->topo);
    xtopo_destroy(ctx, &v->ctopo);
    weft__free(ctx, v->x0, 3 * (size_t)v->n * sizeof(double));
    weft__free(ctx, v->x1, 3 * (size_t)v->n * sizeof(double));
    weft__free(ctx, v->c0, 3 * (size_t)v->nc * sizeof(double));
    weft__free(ctx, v->c1, 3 * (size_t)v->nc * sizeof(double));
    weft__free(ctx, v->tris, 3 * (size_t)v->nt * sizeof(uint32_t));
    weft__free(ctx, v->ctris, 3 * (size_t)v->nct * sizeof(uint32_t));
    weft__free(ctx, v, sizeof *v);
}

weft_result weft_sim_validator_create(weft_context *ctx, const uint32_t *cloth_triangles, uint32_t cloth_triangle_count,
                                      uint32_t cloth_vertex_count, const uint32_t *collider_triangles,
                                      uint32_t collider_triangle_count, uint32_t collider_vertex_count,
                                      weft_sim_validator **out)
{
    if (!ctx || !cloth_triangles || !out || cloth_triangle_count == 0 || cloth_vertex_count < 3 ||
        (collider_vertex_count > 0 && (!collider_triangles || collider_triangle_count == 0))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_sim_validator_create: cloth triangles are required, and collider triangles when the "
                          "collider has vertices");
    }
    for (size_t i = 0; i < 3 * (size_t)cloth_triangle_count; ++i) {
        if (cloth_triangles[i] >= cloth_vertex_count) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "weft_sim_validator_create: cloth triangle %zu index out of range",
                              i / 3);
        }
    }
    for (size_t i = 0; i < 3 * (size_t)collider_triangle_count && collider_vertex_count > 0; ++i) {
        if (collider_triangles[i] >= collider_vertex_count) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH,
                              "weft_sim_validator_create: collider triangle %zu index out of range", i / 3);
        }
    }
    weft_sim_validator *v = weft__alloc(ctx, sizeof *v);
    if (!v) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    v->ctx = ctx;
    v->n = cloth_vertex_count;
    v->nt = cloth_triangle_count;
    v->nc = collider_vertex_count;
    v->nct = collider_vertex_count > 0 ? collider_triangle_count : 0;
    v->tris = weft__alloc(ctx, 3 * (size_t)v->nt * sizeof(uint32_t));
    v->ctris = weft__alloc(ctx, 3 * (size_t)(v->nct ? v->nct : 1) * sizeof(uint32_t));
    v->x0 = weft__alloc(ctx, 3 * (size_t)v->n * sizeof(double));
    v->x1 = weft__alloc(ctx, 3 * (size_t)v->n * sizeof(double));
    v->c0 = weft__alloc(ctx, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(double));
    v->c1 = weft__alloc(ctx, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(double));
    if (!v->tris || !v->ctris || !v->x0 || !v->x1 || !v->c0 || !v->c1) {
        weft_sim_validator_destroy(v);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(v->tris, cloth_triangles, 3 * (size_t)v->nt * sizeof(uint32_t));
    if (v->nct) {
        memcpy(v->ctris, collider_triangles, 3 * (size_t)v->nct * sizeof(uint32_t));
    }
    weft_result r = xtopo_create(ctx, &v->topo, v->tris, v->nt, v->n, NULL);
    if (r == WEFT_OK && v->nct) {
        r = xtopo_create(ctx, &v->ctopo, v->ctris, v->nct, v->nc, NULL);
    }
    if (r == WEFT_OK) {
        r = xbvh_create(ctx, &v->bvh_tri, v->tris, v->nt, 3);
    }
    if (r == WEFT_OK) {
        r = xbvh_create(ctx, &v->bvh_edge, v->topo.edges, v->topo.edge_count, 2);
    }
    if (r == WEFT_OK && v->nct) {
        r = xbvh_create(ctx, &v->bvh_ctri, v->ctris, v->nct, 3);
    }
    if (r == WEFT_OK && v->nct) {
        r = xbvh_create(ctx, &v->bvh_cedge, v->ctopo.edges, v->ctopo.edge_count, 2);
    }
    if (r != WEFT_OK) {
        weft_sim_validator_destroy(v);
        return r;
    }
    *out = v;
    return WEFT_OK;
}

static void swept_box(const double *p0, const double *p1, double lo[3], double hi[3])
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = (p0[k] < p1[k] ? p0[k] : p1[k]) - WEFT_SIM_VALIDATOR_TOLERANCE;
        hi[k] = (p0[k] > p1[k] ? p0[k] : p1[k]) + WEFT_SIM_VALIDATOR_TOLERANCE;
    }
}

static void swept_edge_box(const double *a0, const double *a1, const double *b0, const double *b1, double lo[3],
                           double hi[3])
{
    double l2[3], h2[3];
    swept_box(a0, a1, lo, hi);
    swept_box(b0, b1, l2, h2);
    for (int k = 0; k < 3; ++k) {
        lo[k] = lo[k] < l2[k] ? lo[k] : l2[k];
        hi[k] = hi[k] > h2[k] ? hi[k] : h2[k];
    }
}

weft_result weft_sim_validator_check(weft_sim_validator *v, const float *cloth0, const float *cloth1,
                                     const float *collider0, const float *collider1, weft_sim_validation *out)
{
    if (!v || !cloth0 || !cloth1 || !out || (v->nc > 0 && (!collider0 || !collider1))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_sim_validator_check: both cloth frames are required, and both collider frames when "
                          "the validator has a collider");
    }
    if (!weft__all_finite(cloth0, 3 * (size_t)v->n) || !weft__all_finite(cloth1, 3 * (size_t)v->n) ||
        (v->nc > 0 && (!weft__all_finite(collider0, 3 * (size_t)v->nc) || !weft__all_finite(collider1, 3 * (size_t)v->nc)))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_sim_validator_check: positions contain NaN or infinity");
    }
    for (size_t i = 0; i < 3 * (size_t)v->n; ++i) {
        v->x0[i] = cloth0[i];
        v->x1[i] = cloth1[i];
    }
    for (size_t i = 0; i < 3 * (size_t)v->nc; ++i) {
        v->c0[i] = collider0[i];
        v->c1[i] = collider1[i];
    }
    weft_sim_validation res = {0};
    vctx c = {.v = v, .out = &res};
    double lo[3], hi[3];
    /* Cloth trees are rebuilt at the later frame (the cloth may have deformed a lot since
     * creation) and refit to the swept boxes. */
    xbvh_build(&v->bvh_tri, v->x1);
    xbvh_refit(&v->bvh_tri, v->x0, v->x1, WEFT_SIM_VALIDATOR_TOLERANCE);
    xbvh_build(&v->bvh_edge, v->x1);
    xbvh_refit(&v->bvh_edge, v->x0, v->x1, WEFT_SIM_VALIDATOR_TOLERANCE);
    for (uint32_t p = 0; p < v->n; ++p) {
        c.query = p;
        swept_box(v->x0 + 3 * (size_t)p, v->x1 + 3 * (size_t)p, lo, hi);
        xbvh_query(&v->bvh_tri, lo, hi, v_self_vt, &c);
    }
    for (uint32_t e = 0; e < v->topo.edge_count; ++e) {
        const uint32_t *ed = v->topo.edges + 2 * (size_t)e;
        c.query = e;
        swept_edge_box(v->x0 + 3 * (size_t)ed[0], v->x1 + 3 * (size_t)ed[0], v->x0 + 3 * (size_t)ed[1],
                       v->x1 + 3 * (size_t)ed[1], lo, hi);
        xbvh_query(&v->bvh_edge, lo, hi, v_self_ee, &c);
    }
    for (uint32_t t = 0; t < v->nt; ++t) {
        const uint32_t *tri = v->tris + 3 * (size_t)t;
        c.query = t;
        for (int k = 0; k < 3; ++k) {
            double a = v->x1[3 * (size_t)tri[0] + k], b = v->x1[3 * (size_t)tri[1] + k], d = v->x1[3 * (size_t)tri[2] + k];
            lo[k] = (a < b ? (a < d ? a : d) : (b < d ? b : d));
            hi[k] = (a > b ? (a > d ? a : d) : (b > d ? b : d));
        }
        xbvh_query(&v->bvh_tri, lo, hi, v_tt_self, &c);
    }
    if (v->nct > 0) {
        xbvh_build(&v->bvh_ctri, v->c1);
        xbvh_refit(&v->bvh_ctri, v->c0, v->c1, WEFT_SIM_VALIDATOR_TOLERANCE);
        xbvh_build(&v->bvh_cedge, v->c1);
        xbvh_refit(&v->bvh_cedge, v->c0, v->c1, WEFT_SIM_VALIDATOR_TOLERANCE);
        for (uint32_t p = 0; p < v->n; ++p) {
            c.query = p;
            swept_box(v->x0 + 3 * (size_t)p, v->x1 + 3 * (size_t)p, lo, hi);
            xbvh_query(&v->bvh_ctri, lo, hi, v_vt_collider, &c);
        }
        const xbvh_node *root = &v->bvh_tri.nodes[0];
        for (uint32_t u = 0; u < v->nc; ++u) {
            swept_box(v->c0 + 3 * (size_t)u, v->c1 + 3 * (size_t)u, lo, hi);
            if (lo[0] > root->hi[0] || hi[0] < root->lo[0] || lo[1] > root->hi[1] || hi[1] < root->lo[1] ||
                lo[2] > root->hi[2] || hi[2] < root->lo[2]) {
                continue;
            }
            c.query = u;
            xbvh_query(&v->bvh_tri, lo, hi, v_tv_collider, &c);
        }
        for (uint32_t e = 0; e < v->topo.edge_count; ++e) {
            const uint32_t *ed = v->topo.edges + 2 * (size_t)e;
            c.query = e;
            swept_edge_box(v->x0 + 3 * (size_t)ed[0], v->x1 + 3 * (size_t)ed[0], v->x0 + 3 * (size_t)ed[1],
                           v->x1 + 3 * (size_t)ed[1], lo, hi);
            xbvh_query(&v->bvh_cedge, lo, hi, v_ee_collider, &c);
        }
        for (uint32_t t = 0; t < v->nt; ++t) {
            const uint32_t *tri = v->tris + 3 * (size_t)t;
            c.query = t;
            for (int k = 0; k < 3; ++k) {
                double a = v->x1[3 * (size_t)tri[0] + k], b = v->x1[3 * (size_t)tri[1] + k],
                       d = v->x1[3 * (size_t)tri[2] + k];
                lo[k] = (a < b ? (a < d ? a : d) : (b < d ? b : d));
                hi[k] = (a > b ? (a > d ? a : d) : (b > d ? b : d));
            }
            xbvh_query(&v->bvh_ctri, lo, hi, v_tt_collider, &c);
        }
    }
    *out = res;
    return WEFT_OK;
}
