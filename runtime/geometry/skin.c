/* The skin binding (geometry.h): each point is bound at creation to its nearest surface
 * triangles (closest-point barycentrics plus an offset in the triangle's local frame) and follows
 * them every frame. Blending up to SKIN_SLOTS nearby triangles, weighted by inverse distance,
 * smooths the result across triangle borders; a rigid surface motion is reproduced exactly
 * because every binding is rigid-invariant. It carries the LBS baseline (xpbd/lbs.c), the tether
 * targets and cuts of every garment (garment.c), surface pins and mesh maps. */
#include "geometry/geometry.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SKIN_SLOTS 4

typedef struct skin_bind {
    uint32_t tri[SKIN_SLOTS];
    float bary[SKIN_SLOTS][3];
    float offset[SKIN_SLOTS][3]; /* along (t1, t2, n) of the triangle frame */
    float weight[SKIN_SLOTS];
} skin_bind;

/* The frame of one collider triangle, computed once per evaluation however many bindings use it. */
typedef struct skin_frame {
    double t1[3], t2[3], nn[3];
    bool ok;                     /* false: the triangle collapsed this frame */
} skin_frame;

struct geo_skin {
    skin_bind *bind;
    uint32_t n;
    uint32_t tri_count;          /* distinct triangles the bindings use */
    uint32_t *tris;              /* tri_count collider triangles */
    uint32_t *slot;              /* n * SKIN_SLOTS: index into tris of each binding (weight 0: unused) */
    skin_frame *frames;          /* tri_count scratch, rewritten by every geo_skin_eval */
    uint32_t vertex_count;       /* distinct collider vertices those triangles read */
    uint32_t *vertices;          /* vertex_count, ascending */
};

static int cmp_u32(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

/* Sorts v ascending and drops repeats in place; returns how many remain. */
static size_t sort_unique(uint32_t *v, size_t n)
{
    qsort(v, n, sizeof *v, cmp_u32);
    size_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        if (m == 0 || v[i] != v[m - 1]) {
            v[m++] = v[i];
        }
    }
    return m;
}

/* The distinct collider vertices of the bound triangles, ascending. */
static weft_result make_vertices(const weft_context *ctx, geo_skin *s, const uint32_t *triangles)
{
    const size_t n = (size_t)s->tri_count * 3;
    uint32_t *v = weft__alloc(ctx, (n ? n : 1) * sizeof(uint32_t));
    if (!v) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t u = 0; u < s->tri_count; ++u) {
        memcpy(v + 3 * (size_t)u, triangles + 3 * (size_t)s->tris[u], 3 * sizeof(uint32_t));
    }
    const size_t m = sort_unique(v, n);
    s->vertices = weft__alloc(ctx, (m ? m : 1) * sizeof(uint32_t));
    if (s->vertices) {
        memcpy(s->vertices, v, m * sizeof *v);
        s->vertex_count = (uint32_t)m;
    }
    weft__free(ctx, v, (n ? n : 1) * sizeof(uint32_t));
    return s->vertices ? WEFT_OK : WEFT_ERROR_OUT_OF_MEMORY;
}

/* The distinct triangles of the bindings and each binding's index among them. */
static weft_result make_frames(const weft_context *ctx, geo_skin *s, const uint32_t *triangles)
{
    const size_t slots = (size_t)s->n * SKIN_SLOTS;
    uint32_t *all = weft__alloc(ctx, (slots ? slots : 1) * sizeof(uint32_t));
    s->slot = weft__alloc(ctx, (slots ? slots : 1) * sizeof(uint32_t));
    if (!all || !s->slot) {
        weft__free(ctx, all, (slots ? slots : 1) * sizeof(uint32_t));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    size_t m = 0;
    for (uint32_t i = 0; i < s->n; ++i) {
        for (int k = 0; k < SKIN_SLOTS; ++k) {
            if (s->bind[i].weight[k] != 0.0f) {
                all[m++] = s->bind[i].tri[k];
            }
        }
    }
    const size_t u = sort_unique(all, m);
    s->tri_count = (uint32_t)u;
    s->tris = weft__alloc(ctx, (u ? u : 1) * sizeof(uint32_t));
    s->frames = weft__alloc(ctx, (u ? u : 1) * sizeof(skin_frame));
    if (!s->tris || !s->frames) {
        weft__free(ctx, all, (slots ? slots : 1) * sizeof(uint32_t));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(s->tris, all, u * sizeof *all);
    weft__free(ctx, all, (slots ? slots : 1) * sizeof(uint32_t));
    if (make_vertices(ctx, s, triangles) != WEFT_OK) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t i = 0; i < s->n; ++i) {
        for (int k = 0; k < SKIN_SLOTS; ++k) {
            uint32_t *at = &s->slot[(size_t)i * SKIN_SLOTS + k];
            *at = UINT32_MAX;
            if (s->bind[i].weight[k] != 0.0f) {
                const uint32_t *hit = bsearch(&s->bind[i].tri[k], s->tris, u, sizeof *s->tris, cmp_u32);
                *at = (uint32_t)(hit - s->tris);
            }
        }
    }
    return WEFT_OK;
}

/* Orthonormal frame (t1 along edge 0-1, n the face normal, t2 = n x t1). False if degenerate. */
static bool tri_frame(const double *a, const double *b, const double *c, double t1[3], double t2[3], double nn[3])
{
    double e1[3], e2[3];
    geo_sub(e1, b, a);
    geo_sub(e2, c, a);
    geo_cross(nn, e1, e2);
    double l1 = geo_len(e1), ln = geo_len(nn);
    if (!(l1 > 0.0) || !(ln > 0.0)) {
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        t1[k] = e1[k] / l1;
        nn[k] /= ln;
    }
    geo_cross(t2, nn, t1);
    return true;
}

typedef struct nearest_ctx {
    const double *p;
    const double *cpos;
    const uint32_t *ctris;
    uint32_t best[SKIN_SLOTS];
    double best_d[SKIN_SLOTS];
} nearest_ctx;

static bool visit_nearest(uint32_t t, void *user)
{
    nearest_ctx *nc = user;
    const uint32_t *tri = nc->ctris + 3 * (size_t)t;
    double d = sqrt(geo_point_triangle_sq(nc->p, nc->cpos + 3 * (size_t)tri[0], nc->cpos + 3 * (size_t)tri[1],
                                         nc->cpos + 3 * (size_t)tri[2], NULL));
    /* Insertion into the sorted SKIN_SLOTS best. */
    int k = SKIN_SLOTS - 1;
    if (d >= nc->best_d[k]) {
        return true;
    }
    while (k > 0 && nc->best_d[k - 1] > d) {
        nc->best_d[k] = nc->best_d[k - 1];
        nc->best[k] = nc->best[k - 1];
        --k;
    }
    nc->best_d[k] = d;
    nc->best[k] = t;
    return true;
}
weft_result geo_skin_create_points(const weft_context *ctx, const float *points, uint32_t point_count,
                                const float *surface, uint32_t surface_vertex_count, const uint32_t *triangles,
                                uint32_t triangle_count, const char *who, geo_skin **out)
{
    geo_skin *s = weft__alloc(ctx, sizeof *s);
    if (!s) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *s = (geo_skin){0}; /* a failing step below frees only what was made */
    s->n = point_count;
    size_t nc3 = (size_t)surface_vertex_count * 3;
    s->bind = weft__alloc(ctx, s->n * sizeof *s->bind);
    double *cpos = weft__alloc(ctx, nc3 * sizeof(double));
    geo_bvh bvh;
    weft_result r = geo_bvh_create(ctx, &bvh, triangles, triangle_count, 3);
    if (!s->bind || !cpos || r != WEFT_OK) {
        if (r == WEFT_OK) {
            geo_bvh_destroy(ctx, &bvh);
        }
        weft__free(ctx, cpos, nc3 * sizeof(double));
        weft__free(ctx, s->bind, s->n * sizeof *s->bind);
        weft__free(ctx, s, sizeof *s);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t i = 0; i < nc3; ++i) {
        cpos[i] = surface[i];
    }
    geo_bvh_build(&bvh, cpos);
    geo_bvh_refit(&bvh, cpos, NULL, 0.0);
    const geo_bvh_node *root = &bvh.nodes[0];
    double diag = 0.0;
    for (int k = 0; k < 3; ++k) {
        diag += (root->hi[k] - root->lo[k]) * (root->hi[k] - root->lo[k]);
    }
    diag = sqrt(diag);
    for (uint32_t i = 0; i < s->n; ++i) {
        double p[3] = {points[3 * (size_t)i], points[3 * (size_t)i + 1], points[3 * (size_t)i + 2]};
        nearest_ctx nc = {.p = p, .cpos = cpos, .ctris = triangles};
        /* Grow the search box until it holds the nearest triangle, then widen once so the
         * blend sees the neighbouring triangles too. */
        double r0 = 1e-2;
        for (;;) {
            for (int k = 0; k < SKIN_SLOTS; ++k) {
                nc.best_d[k] = DBL_MAX;
                nc.best[k] = UINT32_MAX;
            }
            double lo[3], hi[3];
            for (int k = 0; k < 3; ++k) {
                lo[k] = p[k] - r0;
                hi[k] = p[k] + r0;
            }
            geo_bvh_query(&bvh, lo, hi, visit_nearest, &nc);
            if ((nc.best_d[0] <= r0 && nc.best[SKIN_SLOTS - 1] != UINT32_MAX) || r0 > 4.0 * diag + 1.0) {
                break;
            }
            r0 *= 2.0;
        }
        skin_bind *b = &s->bind[i];
        /* Inverse-distance weights among triangles within 1.5x the nearest distance + 5 mm. */
        double cut = 1.5 * nc.best_d[0] + 5e-3, wsum = 0.0;
        for (int k = 0; k < SKIN_SLOTS; ++k) {
            b->tri[k] = nc.best[k];
            b->weight[k] = 0.0f;
            if (nc.best[k] == UINT32_MAX || nc.best_d[k] > cut) {
                b->tri[k] = nc.best[0];
                continue;
            }
            const uint32_t *tri = triangles + 3 * (size_t)nc.best[k];
            const double *a = cpos + 3 * (size_t)tri[0], *bb = cpos + 3 * (size_t)tri[1], *c = cpos + 3 * (size_t)tri[2];
            double bary[3], t1[3], t2[3], nn[3], q[3], o[3];
            geo_point_triangle_sq(p, a, bb, c, bary);
            if (!tri_frame(a, bb, c, t1, t2, nn)) {
                b->tri[k] = nc.best[0];
                continue;
            }
            for (int j = 0; j < 3; ++j) {
                q[j] = bary[0] * a[j] + bary[1] * bb[j] + bary[2] * c[j];
                o[j] = p[j] - q[j];
            }
            double wk = 1.0 / (nc.best_d[k] + 1e-3);
            for (int j = 0; j < 3; ++j) {
                b->bary[k][j] = (float)bary[j];
            }
            b->offset[k][0] = (float)geo_dot(o, t1);
            b->offset[k][1] = (float)geo_dot(o, t2);
            b->offset[k][2] = (float)geo_dot(o, nn);
            b->weight[k] = (float)wk;
            wsum += wk;
        }
        if (!(wsum > 0.0)) {
            geo_bvh_destroy(ctx, &bvh);
            weft__free(ctx, cpos, nc3 * sizeof(double));
            weft__free(ctx, s->bind, s->n * sizeof *s->bind);
            weft__free(ctx, s, sizeof *s);
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: vertex %u found no usable triangle to bind to", who,
                              i);
        }
        for (int k = 0; k < SKIN_SLOTS; ++k) {
            b->weight[k] = (float)(b->weight[k] / wsum);
        }
    }
    geo_bvh_destroy(ctx, &bvh);
    weft__free(ctx, cpos, nc3 * sizeof(double));
    if (make_frames(ctx, s, triangles) != WEFT_OK) {
        geo_skin_destroy(ctx, s);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *out = s;
    return WEFT_OK;
}

void geo_skin_destroy(const weft_context *ctx, geo_skin *s)
{
    if (s) {
        const size_t slots = (size_t)s->n * SKIN_SLOTS;
        weft__free(ctx, s->slot, (slots ? slots : 1) * sizeof(uint32_t));
        weft__free(ctx, s->tris, (s->tri_count ? s->tri_count : 1) * sizeof(uint32_t));
        weft__free(ctx, s->frames, (s->tri_count ? s->tri_count : 1) * sizeof(skin_frame));
        weft__free(ctx, s->vertices, (s->vertex_count ? s->vertex_count : 1) * sizeof(uint32_t));
        weft__free(ctx, s->bind, s->n * sizeof *s->bind);
        weft__free(ctx, s, sizeof *s);
    }
}

weft_result geo_skin_eval(const geo_skin *s, const uint32_t *collider_triangles, const float *c, const char *who, float *out_pos)
{
    /* Each triangle's frame once (many bindings share a triangle); the same values as per binding. */
    for (uint32_t u = 0; u < s->tri_count; ++u) {
        const uint32_t *tri = collider_triangles + 3 * (size_t)s->tris[u];
        double a[3], bb[3], cc[3];
        for (int j = 0; j < 3; ++j) {
            a[j] = c[3 * (size_t)tri[0] + j];
            bb[j] = c[3 * (size_t)tri[1] + j];
            cc[j] = c[3 * (size_t)tri[2] + j];
        }
        skin_frame *f = &s->frames[u];
        f->ok = tri_frame(a, bb, cc, f->t1, f->t2, f->nn);
    }
    for (uint32_t i = 0; i < s->n; ++i) {
        const skin_bind *b = &s->bind[i];
        double out[3] = {0, 0, 0}, wsum = 0.0;
        bool any = false;
        for (int k = 0; k < SKIN_SLOTS; ++k) {
            if (b->weight[k] == 0.0f) {
                continue;
            }
            const skin_frame *f = &s->frames[s->slot[(size_t)i * SKIN_SLOTS + k]];
            if (!f->ok) {
                continue; /* a collapsed collider triangle: the other bindings carry the vertex */
            }
            const uint32_t *tri = collider_triangles + 3 * (size_t)b->tri[k];
            double a[3], bb[3], cc[3];
            for (int j = 0; j < 3; ++j) {
                a[j] = c[3 * (size_t)tri[0] + j];
                bb[j] = c[3 * (size_t)tri[1] + j];
                cc[j] = c[3 * (size_t)tri[2] + j];
            }
            double w = b->weight[k];
            for (int j = 0; j < 3; ++j) {
                double q = b->bary[k][0] * a[j] + b->bary[k][1] * bb[j] + b->bary[k][2] * cc[j];
                out[j] += w * (q + b->offset[k][0] * f->t1[j] + b->offset[k][1] * f->t2[j] +
                               b->offset[k][2] * f->nn[j]);
            }
            wsum += w;
            any = true;
        }
        if (!any || !(wsum > 0.0)) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH,
                              "%s: every triangle bound to vertex %u collapsed this frame", who, i);
        }
        for (int j = 0; j < 3; ++j) {
            out_pos[3 * (size_t)i + j] = (float)(out[j] / wsum); /* renormalised if a binding was skipped */
        }
    }
    return WEFT_OK;
}

uint32_t geo_skin_key_floats(const geo_skin *s) { return 3 * s->vertex_count; }

bool geo_skin_key_matches(const geo_skin *s, const float *c, const float *key)
{
    for (uint32_t i = 0; i < s->vertex_count; ++i) {
        if (memcmp(c + 3 * (size_t)s->vertices[i], key + 3 * (size_t)i, 3 * sizeof(float)) != 0) {
            return false;
        }
    }
    return true;
}

void geo_skin_key_store(const geo_skin *s, const float *c, float *key)
{
    for (uint32_t i = 0; i < s->vertex_count; ++i) {
        memcpy(key + 3 * (size_t)i, c + 3 * (size_t)s->vertices[i], 3 * sizeof(float));
    }
}
