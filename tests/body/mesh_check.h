/* Independent geometric checks for procedural meshes (used by the body and wardrobe tests):
 * triangle-triangle intersection through a uniform grid, point-to-mesh distances. */
#ifndef WEFT_TEST_MESH_CHECK_H
#define WEFT_TEST_MESH_CHECK_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

static inline void mc_sub(const float *a, const float *b, double *o)
{
    o[0] = (double)a[0] - b[0], o[1] = (double)a[1] - b[1], o[2] = (double)a[2] - b[2];
}
static inline void mc_cross(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double mc_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Segment pq crosses the interior of triangle abc (Moller-Trumbore, strict bounds). */
static inline int mc_segment_hits_triangle(const float *p, const float *q, const float *a, const float *b, const float *c)
{
    double d[3], e1[3], e2[3], s[3], h[3], qv[3];
    mc_sub(q, p, d);
    mc_sub(b, a, e1);
    mc_sub(c, a, e2);
    mc_cross(d, e2, h);
    double det = mc_dot(e1, h);
    if (fabs(det) < 1e-18) {
        return 0;
    }
    double inv = 1.0 / det;
    mc_sub(p, a, s);
    double u = mc_dot(s, h) * inv;
    if (u <= 1e-9 || u >= 1 - 1e-9) {
        return 0;
    }
    mc_cross(s, e1, qv);
    double v = mc_dot(d, qv) * inv;
    if (v <= 1e-9 || u + v >= 1 - 1e-9) {
        return 0;
    }
    double t = mc_dot(e2, qv) * inv;
    return t > 1e-9 && t < 1 - 1e-9;
}

static inline int mc_triangles_intersect(const float *v, const uint32_t *ta, const uint32_t *tb)
{
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            if (ta[i] == tb[j]) {
                return 0; /* neighbours share a vertex; they touch by construction */
            }
        }
    }
    for (int e = 0; e < 3; ++e) {
        if (mc_segment_hits_triangle(v + 3 * ta[e], v + 3 * ta[(e + 1) % 3], v + 3 * tb[0], v + 3 * tb[1], v + 3 * tb[2]) ||
            mc_segment_hits_triangle(v + 3 * tb[e], v + 3 * tb[(e + 1) % 3], v + 3 * ta[0], v + 3 * ta[1], v + 3 * ta[2])) {
            return 1;
        }
    }
    return 0;
}

typedef struct mc_grid {
    float lo[3], cell;
    int n[3];
    uint32_t *start, *items; /* CSR: cell -> triangle ids */
} mc_grid;

static inline int mc_clampi(int x, int lo, int hi) { return x < lo ? lo : x > hi ? hi : x; }

static inline void mc_tri_range(const mc_grid *g, const float *v, const uint32_t *t, float pad, int *lo, int *hi)
{
    for (int a = 0; a < 3; ++a) {
        float mn = v[3 * t[0] + a], mx = mn;
        for (int k = 1; k < 3; ++k) {
            float x = v[3 * t[k] + a];
            mn = x < mn ? x : mn;
            mx = x > mx ? x : mx;
        }
        lo[a] = mc_clampi((int)floorf((mn - pad - g->lo[a]) / g->cell), 0, g->n[a] - 1);
        hi[a] = mc_clampi((int)floorf((mx + pad - g->lo[a]) / g->cell), 0, g->n[a] - 1);
    }
}

static inline void mc_grid_build(mc_grid *g, const float *v, uint32_t nv, const uint32_t *t, uint32_t nt, float cell)
{
    float hi[3] = {-1e30f, -1e30f, -1e30f};
    for (int a = 0; a < 3; ++a) {
        g->lo[a] = 1e30f;
    }
    for (uint32_t i = 0; i < nv; ++i) {
        for (int a = 0; a < 3; ++a) {
            g->lo[a] = v[3 * i + a] < g->lo[a] ? v[3 * i + a] : g->lo[a];
            hi[a] = v[3 * i + a] > hi[a] ? v[3 * i + a] : hi[a];
        }
    }
    g->cell = cell;
    for (int a = 0; a < 3; ++a) {
        g->n[a] = (int)((hi[a] - g->lo[a]) / cell) + 1;
    }
    size_t cells = (size_t)g->n[0] * g->n[1] * g->n[2];
    g->start = calloc(cells + 1, sizeof(uint32_t));
    for (int pass = 0; pass < 2; ++pass) {
        uint32_t *fill = pass ? calloc(cells, sizeof(uint32_t)) : NULL;
        for (uint32_t f = 0; f < nt; ++f) {
            int lo[3], hi2[3];
            mc_tri_range(g, v, t + 3 * f, 0.0f, lo, hi2);
            for (int z = lo[2]; z <= hi2[2]; ++z) {
                for (int y = lo[1]; y <= hi2[1]; ++y) {
                    for (int x = lo[0]; x <= hi2[0]; ++x) {
                        size_t c = (size_t)x + (size_t)g->n[0] * ((size_t)y + (size_t)g->n[1] * (size_t)z);
                        if (pass == 0) {
                            g->start[c + 1]++;
                        } else {
                            g->items[g->start[c] + fill[c]++] = f;
                        }
                    }
                }
            }
        }
        if (pass == 0) {
            for (size_t c = 0; c < cells; ++c) {
                g->start[c + 1] += g->start[c];
            }
            g->items = malloc((g->start[cells] + 1) * sizeof(uint32_t));
        }
        free(fill);
    }
}

static inline void mc_grid_free(mc_grid *g)
{
    free(g->start);
    free(g->items);
}

/* Number of intersecting pairs of non-adjacent triangles. */
static inline uint32_t mc_count_self_intersections(const float *v, uint32_t nv, const uint32_t *t, uint32_t nt, float cell)
{
    mc_grid g;
    mc_grid_build(&g, v, nv, t, nt, cell);
    uint32_t hits = 0;
    size_t cells = (size_t)g.n[0] * g.n[1] * g.n[2];
    for (size_t c = 0; c < cells; ++c) {
        for (uint32_t i = g.start[c]; i < g.start[c + 1]; ++i) {
            for (uint32_t j = i + 1; j < g.start[c + 1]; ++j) {
                uint32_t a = g.items[i], b = g.items[j];
                if (mc_triangles_intersect(v, t + 3 * a, t + 3 * b)) {
                    hits++;
                }
            }
        }
    }
    mc_grid_free(&g);
    return hits;
}

/* Squared distance from p to triangle abc (Ericson's closest-point regions). */
static inline double mc_point_triangle_d2(const float *pf, const float *af, const float *bf, const float *cf)
{
    double p[3] = {pf[0], pf[1], pf[2]}, a[3] = {af[0], af[1], af[2]}, b[3] = {bf[0], bf[1], bf[2]}, c[3] = {cf[0], cf[1], cf[2]};
    double ab[3], ac[3], ap[3], r[3];
    for (int k = 0; k < 3; ++k) {
        ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    }
    double d1 = mc_dot(ab, ap), d2 = mc_dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        for (int k = 0; k < 3; ++k) r[k] = a[k];
    } else {
        double bp[3], cp[3];
        for (int k = 0; k < 3; ++k) bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
        double d3 = mc_dot(ab, bp), d4 = mc_dot(ac, bp), d5 = mc_dot(ab, cp), d6 = mc_dot(ac, cp);
        double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3) {
            for (int k = 0; k < 3; ++k) r[k] = b[k];
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            double w = d1 / (d1 - d3);
            for (int k = 0; k < 3; ++k) r[k] = a[k] + w * ab[k];
        } else if (d6 >= 0 && d5 <= d6) {
            for (int k = 0; k < 3; ++k) r[k] = c[k];
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            double w = d2 / (d2 - d6);
            for (int k = 0; k < 3; ++k) r[k] = a[k] + w * ac[k];
        } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
            double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            for (int k = 0; k < 3; ++k) r[k] = b[k] + w * (c[k] - b[k]);
        } else {
            double den = 1.0 / (va + vb + vc);
            double v = vb * den, w = vc * den;
            for (int k = 0; k < 3; ++k) r[k] = a[k] + ab[k] * v + ac[k] * w;
        }
    }
    double dd = 0;
    for (int k = 0; k < 3; ++k) dd += (p[k] - r[k]) * (p[k] - r[k]);
    return dd;
}

/* Signed distance of p to a closed mesh: unsigned distance to the nearest triangle within
 * `radius` (grid lookup, capped at radius), negative when a +X ray from p crosses the mesh an
 * odd number of times (crossings counted in the grid row the ray runs through, each in the
 * cell that holds the crossing point, so no triangle counts twice). */
static inline double mc_signed_distance(const mc_grid *g, const float *v, const uint32_t *t, uint32_t nt, const float *p,
                                        float radius)
{
    (void)nt;
    double best = (double)radius * radius;
    int lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        lo[a] = mc_clampi((int)floorf((p[a] - radius - g->lo[a]) / g->cell), 0, g->n[a] - 1);
        hi[a] = mc_clampi((int)floorf((p[a] + radius - g->lo[a]) / g->cell), 0, g->n[a] - 1);
    }
    for (int z = lo[2]; z <= hi[2]; ++z) {
        for (int y = lo[1]; y <= hi[1]; ++y) {
            for (int x = lo[0]; x <= hi[0]; ++x) {
                size_t c = (size_t)x + (size_t)g->n[0] * ((size_t)y + (size_t)g->n[1] * (size_t)z);
                for (uint32_t i = g->start[c]; i < g->start[c + 1]; ++i) {
                    const uint32_t *tr = t + 3 * g->items[i];
                    double d2 = mc_point_triangle_d2(p, v + 3 * tr[0], v + 3 * tr[1], v + 3 * tr[2]);
                    best = d2 < best ? d2 : best;
                }
            }
        }
    }
    float q[3] = {p[0], p[1] + 1.234e-6f, p[2] + 0.713e-6f};
    int cy = (int)floorf((q[1] - g->lo[1]) / g->cell), cz = (int)floorf((q[2] - g->lo[2]) / g->cell);
    int crossings = 0;
    if (cy >= 0 && cy < g->n[1] && cz >= 0 && cz < g->n[2]) {
        int cx0 = mc_clampi((int)floorf((q[0] - g->lo[0]) / g->cell), 0, g->n[0] - 1);
        float far[3] = {q[0] + 1000.0f, q[1], q[2]};
        for (int x = cx0; x < g->n[0]; ++x) {
            size_t c = (size_t)x + (size_t)g->n[0] * ((size_t)cy + (size_t)g->n[1] * (size_t)cz);
            for (uint32_t i = g->start[c]; i < g->start[c + 1]; ++i) {
                const uint32_t *tr = t + 3 * g->items[i];
                if (!mc_segment_hits_triangle(q, far, v + 3 * tr[0], v + 3 * tr[1], v + 3 * tr[2])) {
                    continue;
                }
                /* Where along X the ray meets the triangle's plane. */
                double e1[3], e2[3], n[3], w[3];
                mc_sub(v + 3 * tr[1], v + 3 * tr[0], e1);
                mc_sub(v + 3 * tr[2], v + 3 * tr[0], e2);
                mc_cross(e1, e2, n);
                mc_sub(v + 3 * tr[0], q, w);
                double hit_x = q[0] + mc_dot(n, w) / n[0];
                int hx = mc_clampi((int)floor((hit_x - g->lo[0]) / g->cell), 0, g->n[0] - 1);
                if (hx == x || (x == cx0 && hx < cx0)) {
                    crossings++;
                }
            }
        }
    }
    double d = sqrt(best);
    return (crossings & 1) ? -d : d;
}

#endif
