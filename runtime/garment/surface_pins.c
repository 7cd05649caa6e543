/* Surface pins: points bound to a collider's surface, carried by it (weft.h). The binding is the
 * one the LBS method and the tethers use (runtime/geometry/skin.c, geo_skin): each point on its nearest
 * collider triangles at rest, as barycentric foot points and offsets in the triangles' frames;
 * each frame it is evaluated on the posed collider. Nothing is allocated after creation. */
#include "core/core.h"
#include "geometry/geometry.h"

#include <math.h>
#include <string.h>

struct weft_surface_pins {
    weft_context *ctx;
    uint32_t count;
    uint32_t collider_vertex_count, collider_triangle_count;
    uint32_t *indices;      /* the garment vertices */
    uint32_t *triangles;    /* the collider's, copied */
    geo_skin *skin;
};

weft_surface_pins_def weft_default_surface_pins_def(void)
{
    weft_surface_pins_def d;
    memset(&d, 0, sizeof d);
    d.internal_cookie = WEFT_DEF_COOKIE;
    return d;
}

void weft_surface_pins_destroy(weft_surface_pins *p)
{
    if (!p) {
        return;
    }
    weft_context *ctx = p->ctx;
    if (p->skin) {
        geo_skin_destroy(ctx, p->skin);
    }
    weft__free(ctx, p->indices, (size_t)p->count * sizeof(uint32_t));
    weft__free(ctx, p->triangles, (size_t)p->collider_triangle_count * 3 * sizeof(uint32_t));
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
    bool any_area = false;
    for (uint32_t t = 0; t < def->collider_triangle_count && !any_area; ++t) {
        const uint32_t *tri = def->collider_triangles + 3 * (size_t)t;
        const float *a = def->collider_rest_positions + 3 * (size_t)tri[0];
        const float *b = def->collider_rest_positions + 3 * (size_t)tri[1];
        const float *c = def->collider_rest_positions + 3 * (size_t)tri[2];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        any_area = n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.0;
    }
    if (!any_area) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_surface_pins_create: every collider triangle is degenerate");
    }
    weft_surface_pins *p = weft__alloc(ctx, sizeof *p);
    if (!p) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_surface_pins_create: out of memory");
    }
    memset(p, 0, sizeof *p);
    p->ctx = ctx;
    p->count = def->count;
    p->collider_vertex_count = def->collider_vertex_count;
    p->collider_triangle_count = def->collider_triangle_count;
    p->indices = weft__alloc(ctx, (size_t)p->count * sizeof(uint32_t));
    p->triangles = weft__alloc(ctx, (size_t)p->collider_triangle_count * 3 * sizeof(uint32_t));
    if (!p->indices || !p->triangles) {
        weft_surface_pins_destroy(p);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_surface_pins_create: out of memory");
    }
    memcpy(p->indices, def->vertex_indices, (size_t)p->count * sizeof(uint32_t));
    memcpy(p->triangles, def->collider_triangles, (size_t)p->collider_triangle_count * 3 * sizeof(uint32_t));
    weft_result r = geo_skin_create_points(ctx, def->rest_points, def->count, def->collider_rest_positions,
                                        def->collider_vertex_count, p->triangles, p->collider_triangle_count,
                                        "weft_surface_pins_create", &p->skin);
    if (r != WEFT_OK) {
        p->skin = NULL;
        weft_surface_pins_destroy(p);
        return r == WEFT_ERROR_OUT_OF_MEMORY ? weft__fail(r, "weft_surface_pins_create: out of memory") : r;
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
    weft_result r = geo_skin_eval(p->skin, p->triangles, collider_positions, "weft_surface_pins_targets", out_targets);
    if (r != WEFT_OK) {
        return r;
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
