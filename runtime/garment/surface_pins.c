/* Surface pins: points bound to a collider's surface, carried by it (weft.h). At creation each
 * point takes its nearest collider triangle at rest, its barycentric foot point there and its
 * offset in the triangle's frame (edge, bitangent, normal); each frame it is that foot point on
 * the posed triangle plus the offset in the posed frame. Nothing is allocated after creation. */
#include "core/core.h"

#include <math.h>
#include <string.h>

struct weft_surface_pins {
    weft_context *ctx;
    uint32_t count;
    uint32_t collider_vertex_count;
    uint32_t *indices;      /* the garment vertices */
    uint32_t *corners;      /* count * 3: collider vertices of each point's triangle */
    float *bary;            /* count * 3 */
    float *offset;          /* count * 3: along edge, bitangent, normal */
};

weft_surface_pins_def weft_default_surface_pins_def(void)
{
    weft_surface_pins_def d;
    memset(&d, 0, sizeof d);
    d.internal_cookie = WEFT_DEF_COOKIE;
    return d;
}

/* Orthonormal frame of (a, b, c): edge a->b, bitangent, normal; false when degenerate. */
static bool frame(const double a[3], const double b[3], const double c[3], double e[3], double t[3], double n[3])
{
    double u[3], w[3];
    for (int k = 0; k < 3; ++k) {
        u[k] = b[k] - a[k];
        w[k] = c[k] - a[k];
    }
    n[0] = u[1] * w[2] - u[2] * w[1];
    n[1] = u[2] * w[0] - u[0] * w[2];
    n[2] = u[0] * w[1] - u[1] * w[0];
    const double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (!(ln > 0.0) || !(lu > 0.0)) {
        memset(e, 0, 3 * sizeof *e), memset(t, 0, 3 * sizeof *t), memset(n, 0, 3 * sizeof *n);
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        n[k] /= ln;
        e[k] = u[k] / lu;
    }
    t[0] = n[1] * e[2] - n[2] * e[1];
    t[1] = n[2] * e[0] - n[0] * e[2];
    t[2] = n[0] * e[1] - n[1] * e[0];
    return true;
}

/* Closest point of triangle (a, b, c) to p as barycentric weights; returns the squared distance. */
static double closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double w[3])
{
    double ab[3], ac[3], ap[3];
    for (int k = 0; k < 3; ++k) {
        ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    }
#define DOT(x, y) ((x)[0] * (y)[0] + (x)[1] * (y)[1] + (x)[2] * (y)[2])
    const double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    double u = 0.0, v = 0.0; /* weights of b and c */
    if (d1 <= 0.0 && d2 <= 0.0) {
        u = 0.0, v = 0.0;
    } else {
        double bp[3], cp[3];
        for (int k = 0; k < 3; ++k) {
            bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
        }
        const double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
        const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0.0 && d4 <= d3) {
            u = 1.0, v = 0.0;
        } else if (d6 >= 0.0 && d5 <= d6) {
            u = 0.0, v = 1.0;
        } else if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
            u = d1 / (d1 - d3), v = 0.0;
        } else if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
            u = 0.0, v = d2 / (d2 - d6);
        } else if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
            v = (d4 - d3) / ((d4 - d3) + (d5 - d6)), u = 1.0 - v;
        } else {
            const double denom = 1.0 / (va + vb + vc);
            u = vb * denom, v = vc * denom;
        }
    }
#undef DOT
    w[0] = 1.0 - u - v, w[1] = u, w[2] = v;
    double d = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double q = w[0] * a[k] + w[1] * b[k] + w[2] * c[k] - p[k];
        d += q * q;
    }
    return d;
}

static void corner(const float *pos, uint32_t i, double out[3])
{
    out[0] = pos[3 * (size_t)i], out[1] = pos[3 * (size_t)i + 1], out[2] = pos[3 * (size_t)i + 2];
}

void weft_surface_pins_destroy(weft_surface_pins *p)
{
    if (!p) {
        return;
    }
    weft_context *ctx = p->ctx;
    weft__free(ctx, p->indices, (size_t)p->count * sizeof(uint32_t));
    weft__free(ctx, p->corners, (size_t)p->count * 3 * sizeof(uint32_t));
    weft__free(ctx, p->bary, (size_t)p->count * 3 * sizeof(float));
    weft__free(ctx, p->offset, (size_t)p->count * 3 * sizeof(float));
    weft__free(ctx, p, sizeof *p);
}

weft_result weft_surface_pins_create(weft_context *ctx, const weft_surface_pins_def *def, weft_surface_pins **out)
{
    if (!ctx || !def || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_create: context, def and out are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_surface_pins_create: def was not initialised with weft_default_surface_pins_def()");
    }
    if (!def->collider_rest_positions || !def->collider_triangles || def->collider_vertex_count == 0 ||
        def->collider_triangle_count == 0 || !def->rest_points || !def->vertex_indices || def->count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_create: a collider (positions, triangles) and "
                          "at least one point (rest_points, vertex_indices) are required");
    }
    const size_t nc3 = (size_t)def->collider_vertex_count * 3;
    size_t bad = weft__first_outside(def->collider_rest_positions, nc3);
    if (bad != SIZE_MAX) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_surface_pins_create: collider_rest_positions[%zu] is not finite "
                          "or beyond %g m", bad, (double)WEFT_MAX_COORDINATE);
    }
    bad = weft__first_outside(def->rest_points, (size_t)def->count * 3);
    if (bad != SIZE_MAX) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_surface_pins_create: rest_points[%zu] is not finite or beyond %g m",
                          bad, (double)WEFT_MAX_COORDINATE);
    }
    for (size_t i = 0; i < (size_t)def->collider_triangle_count * 3; ++i) {
        if (def->collider_triangles[i] >= def->collider_vertex_count) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_create: collider triangle %zu names vertex "
                              "%u of %u", i / 3, def->collider_triangles[i], def->collider_vertex_count);
        }
    }
    weft_surface_pins *p = weft__alloc(ctx, sizeof *p);
    if (!p) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_surface_pins_create: out of memory");
    }
    memset(p, 0, sizeof *p);
    p->ctx = ctx;
    p->count = def->count;
    p->collider_vertex_count = def->collider_vertex_count;
    p->indices = weft__alloc(ctx, (size_t)p->count * sizeof(uint32_t));
    p->corners = weft__alloc(ctx, (size_t)p->count * 3 * sizeof(uint32_t));
    p->bary = weft__alloc(ctx, (size_t)p->count * 3 * sizeof(float));
    p->offset = weft__alloc(ctx, (size_t)p->count * 3 * sizeof(float));
    if (!p->indices || !p->corners || !p->bary || !p->offset) {
        weft_surface_pins_destroy(p);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_surface_pins_create: out of memory");
    }
    memcpy(p->indices, def->vertex_indices, (size_t)p->count * sizeof(uint32_t));
    const float *cpos = def->collider_rest_positions;
    for (uint32_t i = 0; i < p->count; ++i) {
        const double x[3] = {def->rest_points[3 * (size_t)i], def->rest_points[3 * (size_t)i + 1],
                             def->rest_points[3 * (size_t)i + 2]};
        double best = INFINITY, w_best[3] = {1.0, 0.0, 0.0};
        uint32_t t_best = UINT32_MAX;
        for (uint32_t t = 0; t < def->collider_triangle_count; ++t) {
            const uint32_t *tri = def->collider_triangles + 3 * (size_t)t;
            double a[3], b[3], c[3], e[3], bt[3], n[3], w[3];
            corner(cpos, tri[0], a), corner(cpos, tri[1], b), corner(cpos, tri[2], c);
            if (!frame(a, b, c, e, bt, n)) {
                continue; /* a degenerate triangle carries no frame */
            }
            const double d = closest_on_triangle(x, a, b, c, w);
            if (d < best) {
                best = d, t_best = t;
                memcpy(w_best, w, sizeof w);
            }
        }
        if (t_best == UINT32_MAX) {
            weft_surface_pins_destroy(p);
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_create: every collider triangle is degenerate");
        }
        const uint32_t *tri = def->collider_triangles + 3 * (size_t)t_best;
        double a[3], b[3], c[3], e[3], bt[3], n[3], q[3], d[3];
        corner(cpos, tri[0], a), corner(cpos, tri[1], b), corner(cpos, tri[2], c);
        frame(a, b, c, e, bt, n);
        for (int k = 0; k < 3; ++k) {
            q[k] = w_best[0] * a[k] + w_best[1] * b[k] + w_best[2] * c[k];
            d[k] = x[k] - q[k];
            p->corners[3 * (size_t)i + (size_t)k] = tri[k];
            p->bary[3 * (size_t)i + (size_t)k] = (float)w_best[k];
        }
        p->offset[3 * (size_t)i + 0] = (float)(d[0] * e[0] + d[1] * e[1] + d[2] * e[2]);
        p->offset[3 * (size_t)i + 1] = (float)(d[0] * bt[0] + d[1] * bt[1] + d[2] * bt[2]);
        p->offset[3 * (size_t)i + 2] = (float)(d[0] * n[0] + d[1] * n[1] + d[2] * n[2]);
    }
    *out = p;
    return WEFT_OK;
}

uint32_t weft_surface_pins_count(const weft_surface_pins *p) { return p ? p->count : 0; }
const uint32_t *weft_surface_pins_indices(const weft_surface_pins *p) { return p ? p->indices : NULL; }

weft_result weft_surface_pins_targets(const weft_surface_pins *p, const float *collider_positions, float *out_targets)
{
    if (!p || !collider_positions || !out_targets) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_targets: pins, collider positions and "
                          "out_targets are required");
    }
    for (uint32_t i = 0; i < p->count; ++i) {
        const uint32_t *tri = p->corners + 3 * (size_t)i;
        double a[3], b[3], c[3], e[3], bt[3], n[3];
        corner(collider_positions, tri[0], a), corner(collider_positions, tri[1], b), corner(collider_positions, tri[2], c);
        frame(a, b, c, e, bt, n); /* a triangle collapsed this frame: the foot point alone */
        const float *w = p->bary + 3 * (size_t)i, *o = p->offset + 3 * (size_t)i;
        for (int k = 0; k < 3; ++k) {
            const double v = w[0] * a[k] + w[1] * b[k] + w[2] * c[k] + o[0] * e[k] + o[1] * bt[k] + o[2] * n[k];
            out_targets[3 * (size_t)i + (size_t)k] = (float)v;
        }
    }
    const size_t bad = weft__first_outside(out_targets, (size_t)p->count * 3);
    if (bad != SIZE_MAX) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_surface_pins_targets: target %zu is not finite or beyond %g m "
                          "(a non-finite collider?)", bad / 3, (double)WEFT_MAX_COORDINATE);
    }
    return WEFT_OK;
}

uint32_t weft_mesh_top_ring(const float *positions, uint32_t vertex_count, float band, uint32_t *out_indices,
                            uint32_t capacity)
{
    if (!positions || vertex_count == 0 || !(band >= 0.0f) || !isfinite(band)) {
        return 0;
    }
    float top = -INFINITY;
    for (uint32_t i = 0; i < vertex_count; ++i) {
        top = fmaxf(top, positions[3 * (size_t)i + 1]);
    }
    uint32_t n = 0;
    for (uint32_t i = 0; i < vertex_count; ++i) {
        if (positions[3 * (size_t)i + 1] >= top - band) {
            if (out_indices && n < capacity) {
                out_indices[n] = i;
            }
            n++;
        }
    }
    return n;
}
