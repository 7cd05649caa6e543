#include "garment/garment.h"
#include "weft/ccd.h"
#include "ccd/ccd_internal.h"
#include "geometry/geometry.h"
#include "model/model.h"

#include <assert.h>
#include <math.h>
#include <string.h>

weft_garment_def weft_default_garment_def(void)
{
    weft_garment_def def = {0};
    def.method = WEFT_METHOD_MODEL;
    def.precision = WEFT_PRECISION_FP32;
    def.substeps = 10;
    def.ccd.enabled = true;
    def.ccd.iterations = 16;
    def.strain.iterations = 8;
    def.attachments.slack = 0.1f;
    def.collision.push_depth = 0.02f;
    def.collision.part_margin = 0.03f;
    def.collision.part_neighbours = true;
    def.collision.cut_distance = 1.0f;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

weft_result weft__check_positions(const char *what, const float *positions, size_t vertex_count)
{
    size_t i = weft__first_outside(positions, vertex_count * 3);
    if (i == SIZE_MAX) {
        return WEFT_OK;
    }
    if (!isfinite(positions[i])) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: vertex %zu has a NaN or infinite coordinate", what, i / 3);
    }
    return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: vertex %zu has coordinate %g, beyond +-%g m (WEFT_MAX_COORDINATE)",
                      what, i / 3, (double)positions[i], (double)WEFT_MAX_COORDINATE);
}

weft_result weft__check_cloth_topology(const weft_context *ctx, const char *what, const uint32_t *triangles,
                                       uint32_t triangle_count, uint32_t vertex_count)
{
    /* Every vertex in a triangle: a vertex of no triangle has no mass, no edge and no area, and
     * the solver, the strain limit and the renderer's normals have nothing to hold it by. */
    uint8_t *used = weft__alloc(ctx, vertex_count);
    if (!used) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(used, 0, vertex_count);
    for (size_t i = 0; i < (size_t)triangle_count * 3; ++i) {
        used[triangles[i]] = 1;
    }
    uint32_t unused = UINT32_MAX;
    for (uint32_t v = 0; v < vertex_count && unused == UINT32_MAX; ++v) {
        if (!used[v]) {
            unused = v;
        }
    }
    weft__free(ctx, used, vertex_count);
    if (unused != UINT32_MAX) {
        return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: vertex %u belongs to no triangle", what, unused);
    }
    /* Non-manifold edges and duplicate triangles, as the XPBD solver's topology sees them. */
    geo_topo topo;
    weft_result r = geo_topo_create(ctx, &topo, triangles, triangle_count, vertex_count, what);
    if (r == WEFT_OK) {
        geo_topo_destroy(ctx, &topo);
    }
    return r;
}

weft_result weft__check_mesh(const char *what, const float *positions, uint32_t vertex_count,
                              const uint32_t *triangles, uint32_t triangle_count)
{
    weft_result pr = weft__check_positions(what, positions, vertex_count);
    if (pr != WEFT_OK) {
        return pr;
    }
    for (uint32_t t = 0; t < triangle_count; ++t) {
        const uint32_t *tri = triangles + 3 * (size_t)t;
        for (int k = 0; k < 3; ++k) {
            if (tri[k] >= vertex_count) {
                return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: triangle %u index %u >= vertex count %u", what, t,
                                  tri[k], vertex_count);
            }
        }
        if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: triangle %u repeats a vertex", what, t);
        }
        const float *a = positions + 3 * (size_t)tri[0];
        const float *b = positions + 3 * (size_t)tri[1];
        const float *c = positions + 3 * (size_t)tri[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        float area2 = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        float scale = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]) + (e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]);
        if (!(area2 > 1e-7f * scale)) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "%s: triangle %u has (near) zero area", what, t);
        }
    }
    return WEFT_OK;
}

/* The state: what an instance owns (weft_garment_asset_instance); the rest is its asset's. */
static void free_state(weft_garment *g)
{
    const weft_context *ctx = g->ctx;
    const size_t nv3 = (size_t)g->vertex_count * 3 * sizeof(float);
    const size_t nc3 = (size_t)g->collider_vertex_count * 3 * sizeof(float);
    weft__free(ctx, g->collider_prev, nc3);
    weft__free(ctx, g->collider_next, nc3);
    weft__free(ctx, g->x, nv3);
    weft__free(ctx, g->x_prev, nv3);
    weft__free(ctx, g->x_next, nv3);
    weft__free(ctx, g->pin_indices, (size_t)g->vertex_count * sizeof(uint32_t));
    weft__free(ctx, g->pin_targets, nv3);
    weft__attach_free_state(g);
    weft__near_free_state(g);
}

/* Allocates the state buffers free_state frees (sizes from g's counts); false when one fails. */
static bool alloc_state(weft_garment *g)
{
    const weft_context *ctx = g->ctx;
    const size_t nv3 = (size_t)g->vertex_count * 3 * sizeof(float);
    const size_t nc3 = (size_t)g->collider_vertex_count * 3 * sizeof(float);
    g->x = weft__alloc(ctx, nv3);
    g->x_prev = weft__alloc(ctx, nv3);
    g->x_next = weft__alloc(ctx, nv3);
    g->pin_indices = weft__alloc(ctx, (size_t)g->vertex_count * sizeof(uint32_t));
    g->pin_targets = weft__alloc(ctx, nv3);
    bool ok = g->x && g->x_prev && g->x_next && g->pin_indices && g->pin_targets && weft__attach_alloc_state(g) &&
              weft__near_alloc_state(g);
    if (ok && g->collider_vertex_count > 0) {
        g->collider_prev = weft__alloc(ctx, nc3);
        g->collider_next = weft__alloc(ctx, nc3);
        ok = g->collider_prev && g->collider_next;
    }
    return ok;
}

static void free_buffers(weft_garment *g)
{
    free_state(g);
    const weft_context *ctx = g->ctx;
    if (!g->asset) {
        const size_t nv3 = (size_t)g->vertex_count * 3 * sizeof(float);
        const size_t nc3 = (size_t)g->collider_vertex_count * 3 * sizeof(float);
        weft__free(ctx, g->rest, nv3);
        weft__free(ctx, g->triangles, (size_t)g->triangle_count * 3 * sizeof(uint32_t));
        weft__free(ctx, g->collider_rest, nc3);
        weft__free(ctx, g->collider_triangles, (size_t)g->collider_triangle_count * 3 * sizeof(uint32_t));
        geo_skin_destroy(ctx, g->skin);
        weft__free(ctx, g->tether_radius, (size_t)g->vertex_count * sizeof(float));
        weft__free(ctx, g->tether_target, nv3);
        weft__strain_destroy(g);
        weft__attach_destroy(g);
        weft__near_destroy(g);
        weft__parts_destroy(g);
    }
    weft__free(ctx, g, sizeof *g);
}

weft_result weft_garment_create(weft_context *context, const weft_garment_def *def, weft_garment **out_garment)
{
    if (!context || !def || !out_garment) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: context, def and out_garment are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: def was not initialised with weft_default_garment_def()");
    }
    if ((unsigned)def->method >= WEFT_METHOD_COUNT || (unsigned)def->precision >= WEFT_PRECISION_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: method or precision out of range");
    }
    if (!def->rest_positions || !def->triangles || def->vertex_count < 3 || def->triangle_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: rest_positions and triangles (at least one) are required");
    }
    if (def->collider_vertex_count > 0 && (!def->collider_rest_positions || !def->collider_triangles ||
                                           def->collider_triangle_count == 0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: a collider needs rest positions and triangles");
    }
    if (def->method == WEFT_METHOD_MODEL && !def->model) {
        return weft__fail(WEFT_ERROR_NO_MODEL, "weft_garment_create: method 'model' needs def.model (load one with "
                                               "weft_model_load_file)");
    }
    const bool xpbd = def->method == WEFT_METHOD_XPBD || def->method == WEFT_METHOD_XPBD_FAST;
    if (xpbd && (def->substeps == 0 || def->substeps > 1000)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: substeps %u outside [1, 1000]",
                          def->substeps);
    }
    if (def->method == WEFT_METHOD_XPBD && def->substeps_max != 0 &&
        (def->substeps_max < def->substeps || def->substeps_max > 4000)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: substeps_max %u must be 0 or in [substeps = %u, 4000]", def->substeps_max,
                          def->substeps);
    }
    if (def->method == WEFT_METHOD_XPBD_FAST && def->substeps_max > def->substeps) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: substeps_max %u: the fast XPBD method runs fixed substeps (use 0)",
                          def->substeps_max);
    }
    /* Checked for every method so that a level table or a host passing a bad crop hears of it
     * whatever the method of the moment. */
    if (!isfinite(def->collider_crop_margin) || def->collider_crop_margin < 0.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: collider_crop_margin %g is not a finite number >= 0 (0: the model's)",
                          (double)def->collider_crop_margin);
    }
    if ((unsigned)def->collider_cap >= WEFT_COLLIDER_CAP_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: collider_cap %u is not a weft_collider_cap",
                          (unsigned)def->collider_cap);
    }
    if ((unsigned)def->collider_crop >= WEFT_COLLIDER_CROP_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: collider_crop %u is not a weft_collider_crop",
                          (unsigned)def->collider_crop);
    }
    const bool tethers = def->tethers.distances || def->tethers.distance != 0.0f;
    if (!isfinite(def->tethers.distance) || def->tethers.distance < 0.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: tethers.distance %g is not a finite number >= 0 (0: no tethers)",
                          (double)def->tethers.distance);
    }
    for (uint32_t i = 0; def->tethers.distances && i < def->vertex_count; ++i) {
        if (!isfinite(def->tethers.distances[i]) || def->tethers.distances[i] < 0.0f) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                              "weft_garment_create: tethers.distances[%u] = %g is not a finite number >= 0", i,
                              (double)def->tethers.distances[i]);
        }
    }
    if (def->ccd.enabled && (def->ccd.iterations == 0 || def->ccd.iterations > 64)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: ccd.iterations %u outside [1, 64]",
                          def->ccd.iterations);
    }
    if (def->attachments.enabled && !(def->attachments.slack >= 0.0f && def->attachments.slack <= 10.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: attachments.slack %g is not in [0, 10]",
                          (double)def->attachments.slack);
    }
    if (!(def->strain.limit >= 0.0f && def->strain.limit <= 10.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: strain.limit %g is not in [0, 10] (0: off)", (double)def->strain.limit);
    }
    if (def->strain.limit > 0.0f && (def->strain.iterations == 0 || def->strain.iterations > 1000)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_create: strain.iterations %u outside [1, 1000]",
                          def->strain.iterations);
    }
    if (!(def->strain.contact >= 0.0f && def->strain.contact <= 1.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: strain.contact %g is not in [0, 1] metres (0: off)",
                          (double)def->strain.contact);
    }
    if (def->strain.limit > 0.0f && def->strain.contact > 0.0f && def->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "weft_garment_create: strain.contact looks for the collider, and the garment has none");
    }
    if (!(def->collision.push >= 0.0f && def->collision.push <= 0.1f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: collision.push %g is not in [0, 0.1] metres (0: off)",
                          (double)def->collision.push);
    }
    if (def->collision.push > 0.0f && !(def->collision.push_depth >= 0.0f && def->collision.push_depth <= 0.5f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: collision.push_depth %g is not in [0, 0.5] metres",
                          (double)def->collision.push_depth);
    }
    if (def->collision.ground && !(fabsf(def->collision.ground_height) <= WEFT_MAX_COORDINATE)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: collision.ground_height %g is not finite or beyond %g m",
                          (double)def->collision.ground_height, (double)WEFT_MAX_COORDINATE);
    }
    if (def->collision.push > 0.0f && def->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "weft_garment_create: collision.push pushes cloth out of the collider, and the garment has none");
    }
    if (def->collision.triangle_parts) {
        if (def->collider_vertex_count == 0) {
            return weft__fail(WEFT_ERROR_NO_COLLIDER,
                              "weft_garment_create: collision.triangle_parts partitions the collider, and the garment "
                              "has none");
        }
        if (!(def->collision.part_margin >= 0.0f && def->collision.part_margin <= 1.0f)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                              "weft_garment_create: collision.part_margin %g is not in [0, 1] metres",
                              (double)def->collision.part_margin);
        }
        for (uint32_t t = 0; t < def->collider_triangle_count; ++t) {
            if (def->collision.triangle_parts[t] > 31) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                                  "weft_garment_create: collision.triangle_parts[%u] = %u is not a part id in [0, 31]", t,
                                  (unsigned)def->collision.triangle_parts[t]);
            }
        }
    }
    if (tethers && def->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "weft_garment_create: tethers follow the collider, and the garment has none");
    }
    weft_result r = weft__check_mesh("garment rest mesh", def->rest_positions, def->vertex_count, def->triangles,
                               def->triangle_count);
    if (r == WEFT_OK) {
        /* One validation for every method, so that a host falling back from one method to
         * another never meets a mesh the second refuses. */
        r = weft__check_cloth_topology(context, "garment rest mesh", def->triangles, def->triangle_count,
                                       def->vertex_count);
    }
    if (r != WEFT_OK) {
        return r;
    }
    if (def->collider_vertex_count > 0) {
        r = weft__check_mesh("collider", def->collider_rest_positions, def->collider_vertex_count, def->collider_triangles,
                       def->collider_triangle_count);
        if (r != WEFT_OK) {
            return r;
        }
    }
    if (def->initial_positions &&
        (r = weft__check_positions("weft_garment_create: initial_positions", def->initial_positions,
                                   def->vertex_count)) != WEFT_OK) {
        return r;
    }
    if (!(def->collision.cut_distance >= 0.0f && def->collision.cut_distance <= WEFT_MAX_COORDINATE)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_create: collision.cut_distance %g is not in [0, %g] metres (0: off)",
                          (double)def->collision.cut_distance, (double)WEFT_MAX_COORDINATE);
    }
    const weft_method_ops *ops = weft__method_ops(def->method);
    if (!ops) {
        static const char *const names[] = {"model", "xpbd", "lbs", "xpbd-fast", "external"};
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_garment_create: method '%s' is not available in this build",
                          names[def->method]);
    }

    weft_garment *g = weft__alloc(context, sizeof *g);
    if (!g) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    g->ctx = context;
    g->ops = ops;
    g->model = def->model;
    g->method = def->method;
    g->precision = def->precision;
    g->substeps = def->substeps;
    g->substeps_max = def->substeps_max > def->substeps ? def->substeps_max : def->substeps;
    g->collider_projection = def->method == WEFT_METHOD_XPBD && def->collider_projection;
    g->ccd = def->ccd.enabled;
    g->ccd_iterations = def->ccd.iterations;
    g->crop_margin = def->collider_crop_margin;
    g->crop_rule = def->collider_crop;
    g->max_collider_tokens = def->max_collider_tokens;
    g->collider_cap = def->collider_cap;
    g->attach_slack = def->attachments.slack;
    g->strain_limit = def->strain.limit;
    g->strain_iterations = def->strain.iterations;
    g->strain_contact = def->strain.limit > 0.0f ? def->strain.contact : 0.0f;
    g->push_thickness = def->collision.push;
    g->ground = def->collision.ground;
    g->ground_height = def->collision.ground_height;
    g->push_depth = def->collision.push_depth;
    g->vertex_count = def->vertex_count;
    g->triangle_count = def->triangle_count;
    g->collider_vertex_count = def->collider_vertex_count;
    g->collider_triangle_count = def->collider_triangle_count;

    size_t nv3 = (size_t)def->vertex_count * 3 * sizeof(float);
    size_t nc3 = (size_t)def->collider_vertex_count * 3 * sizeof(float);
    g->rest = weft__alloc(context, nv3);
    g->triangles = weft__alloc(context, (size_t)def->triangle_count * 3 * sizeof(uint32_t));
    bool ok = g->rest && g->triangles && alloc_state(g);
    if (ok && def->collider_vertex_count > 0) {
        g->collider_rest = weft__alloc(context, nc3);
        g->collider_triangles = weft__alloc(context, (size_t)def->collider_triangle_count * 3 * sizeof(uint32_t));
        ok = g->collider_rest && g->collider_triangles;
    }
    if (!ok) {
        free_buffers(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(g->rest, def->rest_positions, nv3);
    memcpy(g->triangles, def->triangles, (size_t)def->triangle_count * 3 * sizeof(uint32_t));
    const float *start = def->initial_positions ? def->initial_positions : def->rest_positions;
    memcpy(g->x, start, nv3);
    memcpy(g->x_prev, start, nv3);
    if (def->collider_vertex_count > 0) {
        memcpy(g->collider_rest, def->collider_rest_positions, nc3);
        memcpy(g->collider_triangles, def->collider_triangles,
               (size_t)def->collider_triangle_count * 3 * sizeof(uint32_t));
        memcpy(g->collider_prev, def->collider_rest_positions, nc3);
    }
    if (tethers) {
        g->tether_radius = weft__alloc(context, (size_t)def->vertex_count * sizeof(float));
        g->tether_target = weft__alloc(context, nv3);
        if (!g->tether_radius || !g->tether_target) {
            free_buffers(g);
            return WEFT_ERROR_OUT_OF_MEMORY;
        }
        for (uint32_t i = 0; i < def->vertex_count; ++i) {
            g->tether_radius[i] = def->tethers.distances ? def->tethers.distances[i] : def->tethers.distance;
        }
    }
    if (def->attachments.enabled &&
        ((r = weft__attach_create(g)) != WEFT_OK || !weft__attach_alloc_state(g))) {
        free_buffers(g);
        return r != WEFT_OK ? r : WEFT_ERROR_OUT_OF_MEMORY;
    }
    g->cut_distance = def->collider_vertex_count > 0 ? def->collision.cut_distance : 0.0f;
    if (tethers || g->cut_distance > 0.0f) {
        r = weft__garment_skin_create(g, tethers ? "weft_garment_create: tethers" : "weft_garment_create: cut binding", &g->skin);
        if (r != WEFT_OK) {
            free_buffers(g);
            return r;
        }
    }
    if ((r = weft__parts_create(g, def->collision.triangle_parts, def->collision.part_margin,
                                     def->collision.part_neighbours)) != WEFT_OK) {
        free_buffers(g);
        return r;
    }
    if (g->strain_limit > 0.0f && (r = weft__strain_create(g)) != WEFT_OK) {
        free_buffers(g);
        return r;
    }
    if ((r = weft__near_create(g)) != WEFT_OK) {
        free_buffers(g);
        return r;
    }
    if (!weft__near_alloc_state(g)) { /* the push's clearance, made once the push is known */
        free_buffers(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    r = weft__ccd_garment_create(g);
    if (r != WEFT_OK) {
        free_buffers(g);
        return r;
    }
    r = ops->create(g);
    if (r != WEFT_OK) {
        weft__ccd_garment_destroy(g);
        free_buffers(g);
        return r;
    }
    *out_garment = g;
    return WEFT_OK;
}

void weft_garment_destroy(weft_garment *garment)
{
    if (!garment) {
        return;
    }
    garment->ops->destroy(garment);
    if (garment->asset) {
        atomic_fetch_sub(&garment->asset->instances, 1u);
    } else {
        weft__ccd_garment_destroy(garment); /* an instance's CCD world is its asset's */
    }
    free_buffers(garment);
}

/* ---- Shared assets -------------------------------------------------------------------------- */

weft_result weft_garment_asset_create(weft_context *context, const weft_garment_def *def,
                                      weft_garment_asset **out_asset)
{
    if (!context || !def || !out_asset) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_asset_create: context, def and out_asset are required");
    }
    weft_garment_asset *a = weft__alloc(context, sizeof *a);
    if (!a) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(a, 0, sizeof *a);
    a->ctx = context;
    atomic_init(&a->instances, 0u);
    atomic_init(&a->busy, 0);
    weft_result r = weft_garment_create(context, def, &a->proto);
    if (r != WEFT_OK) {
        weft__free(context, a, sizeof *a);
        return r;
    }
    *out_asset = a;
    return WEFT_OK;
}

void weft_garment_asset_destroy(weft_garment_asset *asset)
{
    if (!asset) {
        return;
    }
    assert(atomic_load(&asset->instances) == 0 && "weft_garment_asset_destroy: instances alive");
    weft_garment_destroy(asset->proto);
    weft__free(asset->ctx, asset, sizeof *asset);
}

uint32_t weft_garment_asset_instance_count(const weft_garment_asset *asset)
{
    return asset ? atomic_load(&((weft_garment_asset *)asset)->instances) : 0;
}

weft_result weft_garment_asset_instance(weft_garment_asset *asset, weft_garment **out_garment)
{
    if (!asset || !out_garment) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_asset_instance: asset and out_garment are required");
    }
    const weft_garment *p = asset->proto;
    weft_context *ctx = asset->ctx;
    weft_garment *g = weft__alloc(ctx, sizeof *g);
    if (!g) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *g = *p; /* the asset's pointers; the state below is the instance's own */
    g->asset = asset;
    g->method_state = NULL;
    g->x = g->x_prev = g->x_next = g->collider_prev = g->collider_next = g->pin_targets = NULL;
    g->pin_indices = g->attach_pin = g->attach_heap = g->attach_where = NULL;
    g->attach_limit = NULL;
    const size_t nv3 = (size_t)p->vertex_count * 3 * sizeof(float);
    const size_t nc3 = (size_t)p->collider_vertex_count * 3 * sizeof(float);
    if (!alloc_state(g)) {
        free_buffers(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    /* the prototype is never stepped: its state is the def's initial state */
    memcpy(g->x, p->x, nv3);
    memcpy(g->x_prev, p->x_prev, nv3);
    if (p->collider_vertex_count > 0) {
        memcpy(g->collider_prev, p->collider_prev, nc3);
    }
    g->collider_next_set = false;
    g->cut_pending = false;
    g->pin_count = 0;
    g->stats = (weft_step_stats){0};
    const weft_result r = g->ops->instance ? g->ops->instance(p, g) : g->ops->create(g);
    if (r != WEFT_OK) {
        free_buffers(g);
        return r;
    }
    atomic_fetch_add(&asset->instances, 1u);
    *out_garment = g;
    return WEFT_OK;
}

bool weft__garment_enter(weft_garment *g, const char *who)
{
    if (!g->asset) {
        return true;
    }
    int idle = 0;
    if (atomic_compare_exchange_strong(&g->asset->busy, &idle, 1)) {
        return true;
    }
    weft__fail(WEFT_ERROR_BUSY, "%s: another instance of this garment's asset is stepping on another thread (an "
               "asset's instances share its scratch: one at a time, or one asset per thread)", who);
    return false;
}

void weft__garment_leave(weft_garment *g)
{
    if (g->asset) {
        atomic_store(&g->asset->busy, 0);
    }
}

weft_result weft_garment_set_state(weft_garment *g, const float *positions, const float *prev_positions)
{
    if (!g || !positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_set_state: garment and positions are required");
    }
    size_t n = (size_t)g->vertex_count * 3;
    weft_result r = weft__check_positions("weft_garment_set_state: positions", positions, g->vertex_count);
    if (r == WEFT_OK && prev_positions) {
        r = weft__check_positions("weft_garment_set_state: prev_positions", prev_positions, g->vertex_count);
    }
    if (r != WEFT_OK) {
        return r;
    }
    memcpy(g->x, positions, n * sizeof(float));
    memcpy(g->x_prev, prev_positions ? prev_positions : positions, n * sizeof(float));
    g->stats = (weft_step_stats){0};
    if (g->ops->reset) {
        g->ops->reset(g);
    }
    return WEFT_OK;
}

/* Collider positions into the collider at t (current) or at t+1, after the checks both setters
 * share; `who` names the caller in messages. */
static weft_result copy_collider(weft_garment *g, const float *collider_positions, bool current, const char *who)
{
    if (!g || !collider_positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: garment and positions are required", who);
    }
    if (g->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "%s: the garment was created without a collider (def.collider_vertex_count = 0)", who);
    }
    size_t n = (size_t)g->collider_vertex_count * 3;
    weft_result r = weft__check_positions(who, collider_positions, g->collider_vertex_count);
    if (r != WEFT_OK) {
        return r;
    }
    memcpy(current ? g->collider_prev : g->collider_next, collider_positions, n * sizeof(float));
    return WEFT_OK;
}

weft_result weft_garment_set_collider(weft_garment *g, const float *collider_positions)
{
    weft_result r = copy_collider(g, collider_positions, false, "weft_garment_set_collider");
    if (r == WEFT_OK) {
        g->collider_next_set = true;
    }
    return r;
}

weft_result weft_garment_set_collider_current(weft_garment *g, const float *collider_positions)
{
    return copy_collider(g, collider_positions, true, "weft_garment_set_collider_current");
}

weft_result weft_garment_set_pins(weft_garment *g, const uint32_t *vertex_indices, const float *target_positions,
                                  uint32_t count)
{
    if (!g || (count > 0 && (!vertex_indices || !target_positions))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_set_pins: indices and targets are required");
    }
    if (count > g->vertex_count) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_garment_set_pins: %u pins for %u vertices", count,
                          g->vertex_count);
    }
    for (uint32_t i = 0; i < count; ++i) {
        if (vertex_indices[i] >= g->vertex_count) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_set_pins: pin %u index %u >= vertex count %u",
                              i, vertex_indices[i], g->vertex_count);
        }
    }
    weft_result r = weft__check_positions("weft_garment_set_pins: targets", target_positions, count);
    if (r != WEFT_OK) {
        return r;
    }
    /* the attachments' anchors follow the pinned vertex list: found again only when it changes */
    const bool moved = g->attach_pin && (count != g->pin_count ||
                                         (count > 0 && memcmp(g->pin_indices, vertex_indices,
                                                              (size_t)count * sizeof(uint32_t)) != 0));
    if (count > 0) { /* count 0 clears; the pointers may then be NULL */
        memcpy(g->pin_indices, vertex_indices, (size_t)count * sizeof(uint32_t));
        memcpy(g->pin_targets, target_positions, (size_t)count * 3 * sizeof(float));
    }
    g->pin_count = count;
    if (moved) {
        weft__attach_anchor(g);
    }
    return WEFT_OK;
}

/* Moves each vertex of x_next farther than its radius from its skinned position (tether_target)
 * back onto the sphere; pinned vertices keep their targets. Returns how many moved. */
static uint32_t clamp_tethers(weft_garment *g)
{
    uint32_t clamped = 0;
    for (uint32_t i = 0; i < g->vertex_count; ++i) {
        clamped += weft__clamp_to_sphere(g->x_next + 3 * (size_t)i, g->tether_target + 3 * (size_t)i,
                                         g->tether_radius[i]);
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        memcpy(g->x_next + 3 * (size_t)g->pin_indices[k], g->pin_targets + 3 * (size_t)k, 3 * sizeof(float));
    }
    return clamped;
}

/* The floor: vertices below it go onto it at their x, z of t (static friction); pinned vertices
 * go back to their targets. Linear in the vertices and pins. */
static uint32_t hold_on_ground(weft_garment *g)
{
    uint32_t held = 0;
    const float h = g->ground_height;
    for (uint32_t i = 0; i < g->vertex_count; ++i) {
        float *x = g->x_next + 3 * (size_t)i;
        if (x[1] < h) {
            const float *was = g->x + 3 * (size_t)i;
            x[0] = was[0], x[1] = h, x[2] = was[2];
            held++;
        }
    }
    for (uint32_t k = 0; held > 0 && k < g->pin_count; ++k) {
        memcpy(g->x_next + 3 * (size_t)g->pin_indices[k], g->pin_targets + 3 * (size_t)k, 3 * sizeof(float));
    }
    return held;
}

/* The tethers' skinned positions at t+1 (`skinned`: the method's, the same binding on the same
 * collider; NULL: evaluated here), then the clamp. */
static weft_result apply_tethers(weft_garment *g, const float *skinned)
{
    if (skinned) {
        if (skinned != g->tether_target) {
            memcpy(g->tether_target, skinned, (size_t)g->vertex_count * 3 * sizeof(float));
        }
    } else {
        weft_result r = geo_skin_eval(g->skin, g->collider_triangles, g->collider_next, "weft_garment_step: tethers",
                                      g->tether_target);
        if (r != WEFT_OK) {
            return r;
        }
    }
    g->stats.tether_vertices_clamped = clamp_tethers(g);
    return WEFT_OK;
}

weft_result weft__garment_skin_create(const weft_garment *g, const char *who, geo_skin **out)
{
    if (g->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER, "%s: needs a collider to bind the garment to", who);
    }
    return geo_skin_create_points(g->ctx, g->x, g->vertex_count, g->collider_rest, g->collider_vertex_count,
                                  g->collider_triangles, g->collider_triangle_count, who, out);
}

weft_result weft__garment_finish_step(weft_garment *g)
{
    const double t0 = weft__now_ms();
    const float *skinned = g->skinned_next;
    g->skinned_next = NULL;
    g->stats.collider_cut = false;
    size_t bad = weft__first_outside(g->x_next, (size_t)g->vertex_count * 3);
    if (bad != SIZE_MAX) {
        return weft__fail(WEFT_ERROR_NOT_FINITE,
                          "weft_garment_step: method '%s' put vertex %zu at %g (NaN, infinite or beyond +-%g m); "
                          "state kept",
                          g->ops->name, bad / 3, (double)g->x_next[bad], (double)WEFT_MAX_COORDINATE);
    }
    /* Methods that do not solve with pins (the learned step, LBS) honour them here: the pinned
     * vertices are set to their targets before tethers and the strain limit (both keep pinned
     * vertices); CCD may still hold one back where its move would cross a surface, as for XPBD. */
    if (!g->ops->supports_pins) {
        for (uint32_t k = 0; k < g->pin_count; ++k) {
            memcpy(g->x_next + 3 * (size_t)g->pin_indices[k], g->pin_targets + 3 * (size_t)k, 3 * sizeof(float));
        }
    }
    if (g->tether_radius) {
        weft_result r = apply_tethers(g, skinned);
        if (r != WEFT_OK) {
            return r;
        }
    }
    g->stats.attachment_vertices_clamped = weft__attach_clamp(g);
    if (g->near_inside && g->ccd_state) {
        /* Cloth the previous step left inside the collider may leave it: CCD skips its collider
         * contacts this step (it would stop the way out as a crossing); the push puts it outside. */
        g->stats.ccd_let_out = weft__near_mark_inside(g);
        weft_ccd_world_let_out(g->ccd_state, g->near_inside);
    }
    weft__near_refit(g); /* the collider tree at t+1, for the contact-aware limit and the push */
    if (g->strain_limit > 0.0f) {
        weft__strain_limit(g);
    }
    if (g->push_thickness > 0.0f) {
        weft__push(g); /* out of the collider, so that CCD starts from a frame the body does not cut */
    }
    if (g->tether_radius && (g->strain_limit > 0.0f || g->push_thickness > 0.0f)) {
        /* The strain limit and the push may carry a vertex past its radius again: the max distance
         * is what keeps a garment on its wearer, so it has the last word before CCD. The
         * attachments do not: a cloth swinging from its pins is held out of the body by the push,
         * which moves a vertex at most push_depth + push past its attachment. */
        g->stats.tether_vertices_clamped += clamp_tethers(g);
    }
    g->stats.ground_vertices = g->ground ? hold_on_ground(g) : 0;
    const double t1 = weft__now_ms();
    weft__ccd_postprocess_garment(g); /* sweeps x -> x_next against the collider and itself */
    if (g->ccd_state) {
        /* The max distance outranks CCD: a vertex CCD held back farther than its radius (cloth
         * caught where the body overlaps itself, which the body then drags off) is released onto
         * its sphere, uncertified for this step; the next step lets it out of the body (the push)
         * instead of holding it there. docs/CCD.md, *Tethers over CCD*. The attachments too. */
        g->stats.ccd_released = g->tether_radius ? clamp_tethers(g) : 0;
        g->stats.ccd_released += weft__attach_clamp(g);
    }
    g->stats.constraints_ms = t1 - t0;
    g->stats.ccd_ms = weft__now_ms() - t1;
    /* Rotate: t-1 <- t, t <- t+1 (pointer swaps, no copies). */
    float *old_prev = g->x_prev;
    g->x_prev = g->x;
    g->x = g->x_next;
    g->x_next = old_prev;
    if (g->collider_vertex_count > 0) {
        float *c = g->collider_prev;
        g->collider_prev = g->collider_next;
        g->collider_next = c;
        g->collider_next_set = false;
    }
    g->stats.frame++;
    return WEFT_OK;
}

bool weft__garment_cut(weft_garment *g, weft_result *r)
{
    *r = WEFT_OK;
    if (!(g->cut_distance > 0.0f)) {
        return false;
    }
    const float limit2 = g->cut_distance * g->cut_distance;
    const float *c0 = g->collider_prev, *c1 = g->collider_next;
    bool jumped = false;
    for (size_t i = 0; i < (size_t)g->collider_vertex_count && !jumped; ++i) {
        const float d[3] = {c1[3 * i] - c0[3 * i], c1[3 * i + 1] - c0[3 * i + 1], c1[3 * i + 2] - c0[3 * i + 2]};
        jumped = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > limit2;
    }
    if (!jumped) {
        return false;
    }
    *r = geo_skin_eval(g->skin, g->collider_triangles, c1, "weft_garment_step: cut", g->x_next);
    if (*r != WEFT_OK) {
        return true;
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        memcpy(g->x_next + 3 * (size_t)g->pin_indices[k], g->pin_targets + 3 * (size_t)k, 3 * sizeof(float));
    }
    size_t bad = weft__first_outside(g->x_next, (size_t)g->vertex_count * 3);
    if (bad != SIZE_MAX) {
        *r = weft__fail(WEFT_ERROR_NOT_FINITE, "weft_garment_step: cut: the skinned garment puts vertex %zu at %g; "
                        "state kept", bad / 3, (double)g->x_next[bad]);
        return true;
    }
    /* At rest on the new collider: t-1 = t = the skinned garment. */
    const size_t nv3 = (size_t)g->vertex_count * 3 * sizeof(float);
    float *old = g->x;
    g->x = g->x_next;
    g->x_next = old;
    memcpy(g->x_prev, g->x, nv3);
    float *c = g->collider_prev;
    g->collider_prev = g->collider_next;
    g->collider_next = c;
    g->collider_next_set = false;
    if (g->ops->reset) {
        g->ops->reset(g);
    }
    const uint64_t frame = g->stats.frame;
    g->stats = (weft_step_stats){0};
    g->stats.frame = frame + 1;
    g->stats.collider_cut = true;
    return true;
}

weft_result weft_garment_step(weft_garment *g)
{
    if (!g) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_step: garment is NULL");
    }
    if (g->collider_vertex_count > 0 && !g->collider_next_set) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "weft_garment_step: call weft_garment_set_collider with the collider at t+1 first");
    }
    if (!weft__garment_enter(g, "weft_garment_step")) {
        return WEFT_ERROR_BUSY;
    }
    double t0 = weft__now_ms();
    weft_result r;
    if (weft__garment_cut(g, &r)) {
        if (r == WEFT_OK) {
            g->stats.step_ms = weft__now_ms() - t0;
        }
        weft__garment_leave(g);
        return r;
    }
    r = g->ops->step(g);
    const double t1 = weft__now_ms();
    if (r == WEFT_OK) {
        r = weft__garment_finish_step(g);
    }
    weft__garment_leave(g);
    if (r == WEFT_OK) {
        g->stats.method_ms = t1 - t0;
    }
    if (r != WEFT_OK) {
        return r;
    }
    g->stats.step_ms = weft__now_ms() - t0;
    return WEFT_OK;
}

weft_result weft_garment_constrain(weft_garment *g, const float *next_positions)
{
    if (!g || !next_positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_constrain: garment and next_positions are required");
    }
    if (g->method != WEFT_METHOD_EXTERNAL) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_garment_constrain: the garment's method is '%s'; only an external garment "
                          "(WEFT_METHOD_EXTERNAL) takes its positions from the host",
                          g->ops->name);
    }
    if (g->collider_vertex_count > 0 && !g->collider_next_set) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER,
                          "weft_garment_constrain: call weft_garment_set_collider with the collider at t+1 first");
    }
    if (!weft__garment_enter(g, "weft_garment_constrain")) {
        return WEFT_ERROR_BUSY;
    }
    const double t0 = weft__now_ms();
    weft_result r;
    if (g->collider_vertex_count > 0 && weft__garment_cut(g, &r)) {
        if (r == WEFT_OK) {
            g->stats.step_ms = weft__now_ms() - t0;
        }
        weft__garment_leave(g);
        return r;
    }
    /* x_next is scratch until the rotation; a failing stage leaves x and x_prev as they were */
    memcpy(g->x_next, next_positions, (size_t)g->vertex_count * 3 * sizeof(float));
    r = weft__garment_finish_step(g);
    weft__garment_leave(g);
    if (r == WEFT_OK) {
        g->stats.method_ms = 0.0;
        g->stats.step_ms = weft__now_ms() - t0;
    }
    return r;
}

const float *weft_garment_positions(const weft_garment *g) { return g ? g->x : NULL; }

uint32_t weft_garment_vertex_count(const weft_garment *g) { return g ? g->vertex_count : 0; }

uint32_t weft_garment_pin_count(const weft_garment *g) { return g ? g->pin_count : 0; }

weft_step_stats weft_garment_stats(const weft_garment *g)
{
    weft_step_stats s = {0};
    if (g) {
        s = g->stats;
    }
    return s;
}

weft_result weft_garment_skinned_positions(const weft_garment *g, float *out)
{
    if (!g || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_garment_skinned_positions: garment and out are required");
    }
    if (!g->skin) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_garment_skinned_positions: the garment has no skin binding (no "
                          "collider, or neither tethers nor collision.cut_distance)");
    }
    weft_garment *m = (weft_garment *)g; /* the asset's scratch is held, not the garment changed */
    if (!weft__garment_enter(m, "weft_garment_skinned_positions")) {
        return WEFT_ERROR_BUSY;
    }
    const weft_result r =
        geo_skin_eval(g->skin, g->collider_triangles, g->collider_prev, "weft_garment_skinned_positions", out);
    weft__garment_leave(m);
    return r;
}

weft_garment_def weft_model_garment_def(const weft_model *model)
{
    weft_garment_def d = weft_default_garment_def();
    if (!model) {
        return d;
    }
    d.method = WEFT_METHOD_MODEL;
    d.model = model;
    d.precision = model->info.precision;
    d.strain.limit = model->deploy_set & WEFT__DEPLOY_STRAIN_LIMIT ? model->deploy_strain_limit : d.strain.limit;
    d.tethers.distance = model->deploy_set & WEFT__DEPLOY_TETHER_DISTANCE ? model->deploy_tether_distance
                                                                          : d.tethers.distance;
    d.collision.push = model->deploy_set & WEFT__DEPLOY_PUSH ? model->deploy_push : d.collision.push;
    d.ccd.enabled = model->deploy_set & WEFT__DEPLOY_CCD ? model->deploy_ccd : d.ccd.enabled;
    return d;
}
