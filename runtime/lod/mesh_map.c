/* Mesh maps (weft/lod.h): the points of one mesh bound to the triangles of another in rest space
 * with the skin binding of runtime/geometry/skin.c, so a fine garment follows a coarse simulated
 * one (or a coarse mesh samples a fine state). */
#include "weft/lod.h"
#include "garment/garment.h"
#include "geometry/geometry.h"

#include <string.h>

struct weft_mesh_map {
    weft_context *ctx;
    geo_skin *skin;
    uint32_t from_vertex_count, from_triangle_count, to_vertex_count;
    uint32_t *from_triangles;   /* from_triangle_count * 3 */
    float *scratch;             /* to_vertex_count * 3: the result before it is known to be whole */
};

weft_mesh_map_def weft_default_mesh_map_def(void)
{
    weft_mesh_map_def def = {0};
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

void weft_mesh_map_destroy(weft_mesh_map *m)
{
    if (!m) {
        return;
    }
    geo_skin_destroy(m->ctx, m->skin);
    weft__free(m->ctx, m->from_triangles, (size_t)m->from_triangle_count * 3 * sizeof(uint32_t));
    weft__free(m->ctx, m->scratch, (size_t)m->to_vertex_count * 3 * sizeof(float));
    weft__free(m->ctx, m, sizeof *m);
}

weft_result weft_mesh_map_create(weft_context *context, const weft_mesh_map_def *def, weft_mesh_map **out_map)
{
    if (!context || !def || !out_map) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_mesh_map_create: context, def and out_map are required");
    }
    *out_map = NULL;
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_mesh_map_create: def was not initialised with weft_default_mesh_map_def()");
    }
    if (!def->from_rest_positions || !def->from_triangles || def->from_vertex_count < 3 ||
        def->from_triangle_count == 0 || !def->to_rest_positions || def->to_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_mesh_map_create: a `from` mesh (positions, at least one triangle) and `to` points "
                          "are required");
    }
    weft_result r = weft__check_mesh("weft_mesh_map_create: from mesh", def->from_rest_positions,
                                     def->from_vertex_count, def->from_triangles, def->from_triangle_count);
    if (r != WEFT_OK) {
        return r;
    }
    if (!weft__all_finite(def->to_rest_positions, (size_t)def->to_vertex_count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_mesh_map_create: to_rest_positions contain NaN or infinity");
    }
    weft_mesh_map *m = weft__alloc(context, sizeof *m);
    if (!m) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(m, 0, sizeof *m);
    m->ctx = context;
    m->from_vertex_count = def->from_vertex_count;
    m->from_triangle_count = def->from_triangle_count;
    m->to_vertex_count = def->to_vertex_count;
    m->from_triangles = weft__alloc(context, (size_t)def->from_triangle_count * 3 * sizeof(uint32_t));
    m->scratch = weft__alloc(context, (size_t)def->to_vertex_count * 3 * sizeof(float));
    if (!m->from_triangles || !m->scratch) {
        weft_mesh_map_destroy(m);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(m->from_triangles, def->from_triangles, (size_t)def->from_triangle_count * 3 * sizeof(uint32_t));
    r = geo_skin_create_points(context, def->to_rest_positions, def->to_vertex_count, def->from_rest_positions,
                            def->from_vertex_count, m->from_triangles, m->from_triangle_count,
                            "weft_mesh_map_create", &m->skin);
    if (r != WEFT_OK) {
        weft_mesh_map_destroy(m);
        return r;
    }
    *out_map = m;
    return WEFT_OK;
}

weft_result weft_mesh_map_apply(weft_mesh_map *m, const float *from_positions, float *to_positions)
{
    if (!m || !from_positions || !to_positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_mesh_map_apply: map, from_positions and to_positions are "
                                                       "required");
    }
    if (!weft__all_finite(from_positions, (size_t)m->from_vertex_count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_mesh_map_apply: from_positions contain NaN or infinity");
    }
    weft_result r = geo_skin_eval(m->skin, m->from_triangles, from_positions, "weft_mesh_map_apply", m->scratch);
    if (r != WEFT_OK) {
        return r;
    }
    memcpy(to_positions, m->scratch, (size_t)m->to_vertex_count * 3 * sizeof(float));
    return WEFT_OK;
}

uint32_t weft_mesh_map_from_vertex_count(const weft_mesh_map *m) { return m ? m->from_vertex_count : 0; }

uint32_t weft_mesh_map_to_vertex_count(const weft_mesh_map *m) { return m ? m->to_vertex_count : 0; }
