/* Independent penetration validator on top of the CCD module (runtime/ccd): it shares no code
 * with the solver's proximity passes and bounds. A motion passes when no swept vertex-face or
 * edge-edge pair of the five CCD types comes closer than WEFT_SIM_VALIDATOR_TOLERANCE, and no
 * two triangles intersect at the end of it (exact predicates). */
#include "weft/ccd.h"
#include "weft/sim.h"
#include "ccd/ccd_internal.h"
#include "core/core.h"

#include <string.h>

struct weft_sim_validator {
    weft_context *ctx;
    uint32_t n, nc;
    weft_ccd_world *world;
    float *ca, *cb; /* collider interpolated along a substep path */
    uint32_t *tris, nt; /* the cloth's triangles (weft_sim_validator_tangled's ring) */
};

void weft_sim_validator_destroy(weft_sim_validator *v)
{
    if (!v) {
        return;
    }
    const weft_context *ctx = v->ctx;
    weft_ccd_world_destroy(v->world);
    weft__free(ctx, v->ca, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(float));
    weft__free(ctx, v->cb, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(float));
    weft__free(ctx, v->tris, 3 * (size_t)v->nt * sizeof(uint32_t));
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
    v->nc = collider_vertex_count;
    v->ca = weft__alloc(ctx, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(float));
    v->cb = weft__alloc(ctx, 3 * (size_t)(v->nc ? v->nc : 1) * sizeof(float));
    v->tris = weft__alloc(ctx, 3 * (size_t)cloth_triangle_count * sizeof(uint32_t));
    if (v->tris) {
        v->nt = cloth_triangle_count;
        memcpy(v->tris, cloth_triangles, 3 * (size_t)cloth_triangle_count * sizeof(uint32_t));
    }
    if (!v->ca || !v->cb || !v->tris) {
        weft_sim_validator_destroy(v);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    weft_ccd_world_def wd = weft_default_ccd_world_def();
    wd.cloth_triangles = cloth_triangles;
    wd.cloth_triangle_count = cloth_triangle_count;
    wd.cloth_vertex_count = cloth_vertex_count;
    if (collider_vertex_count > 0) {
        wd.collider_triangles = collider_triangles;
        wd.collider_triangle_count = collider_triangle_count;
        wd.collider_vertex_count = collider_vertex_count;
    }
    wd.self_collision = true;
    wd.min_separation = WEFT_SIM_VALIDATOR_TOLERANCE;
    wd.max_hits = 1; /* counts are exact; one hit is kept to say where a rejected motion failed */
    weft_result r = weft_ccd_world_create(ctx, &wd, &v->world);
    if (r != WEFT_OK) {
        weft_sim_validator_destroy(v);
        return r;
    }
    *out = v;
    return WEFT_OK;
}

static weft_result check_args(const weft_sim_validator *v, const float *cloth0, const float *cloth1, size_t cloth_floats,
                              const float *collider0, const float *collider1, const weft_sim_validation *out,
                              const char *fn)
{
    if (!v || !cloth0 || !cloth1 || !out || (v->nc > 0 && (!collider0 || !collider1))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "%s: the cloth states are required, and both collider frames when the validator has a "
                          "collider",
                          fn);
    }
    if (!weft__all_finite(cloth0, cloth_floats) ||
        (v->nc > 0 && (!weft__all_finite(collider0, 3 * (size_t)v->nc) || !weft__all_finite(collider1, 3 * (size_t)v->nc)))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: positions contain NaN or infinity", fn);
    }
    return WEFT_OK;
}

/* One linear motion, all five CCD types. */
static weft_result sweep(weft_sim_validator *v, const float *x0, const float *x1, const float *c0, const float *c1,
                         weft_sim_validation *res)
{
    weft_ccd_report rep;
    weft_result r = weft_ccd_detect(v->world, x0, x1, v->nc ? c0 : NULL, v->nc ? c1 : NULL, WEFT_CCD_MASK_ALL, &rep);
    if (r == WEFT_OK) {
        uint32_t kept = 0;
        const weft_ccd_hit *h = weft_ccd_hits(v->world, &kept);
        if (kept > 0 && res->ccd_hits == 0) {
            res->hit = h[0];
        }
        res->ccd_hits += rep.hit_total;
        res->pairs_tested += rep.narrow_tests;
        res->motions_checked++;
    }
    return r;
}

static weft_result intersect(weft_sim_validator *v, const float *x, const float *c, weft_sim_validation *res)
{
    weft_ccd_intersections in;
    weft_result r = weft_ccd_intersect_frame(v->world, x, v->nc ? c : NULL, &in);
    if (r == WEFT_OK) {
        res->intersection_hits += in.cloth_cloth + in.cloth_collider;
    }
    return r;
}

weft_result weft_sim_validator_set_parts(weft_sim_validator *v, const uint32_t *cloth_masks,
                                        const uint32_t *collider_triangle_bits)
{
    if (!v) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_validator_set_parts: validator is NULL");
    }
    if ((cloth_masks != NULL) != (collider_triangle_bits != NULL)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_sim_validator_set_parts: give both the cloth masks and the collider triangle bits, or neither");
    }
    if (cloth_masks && v->nc == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_validator_set_parts: the validator has no collider");
    }
    weft__ccd_world_set_parts(v->world, cloth_masks, collider_triangle_bits);
    return WEFT_OK;
}

weft_result weft_sim_validator_set_self_exempt(weft_sim_validator *v, const uint8_t *exempt)
{
    if (!v) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_validator_set_self_exempt: validator is NULL");
    }
    weft__ccd_world_set_self_exempt(v->world, exempt);
    return WEFT_OK;
}

weft_result weft_sim_validator_tangled(weft_sim_validator *v, const float *cloth, const uint8_t *pinched,
                                      uint8_t *tangled, uint32_t *count, uint32_t *count_clear)
{
    if (!v || !cloth || !tangled || !count || (pinched && !count_clear)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_validator_tangled: every argument is required");
    }
    if (!weft__all_finite(cloth, 3 * (size_t)v->n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_sim_validator_tangled: positions contain NaN or infinity");
    }
    memset(tangled, 0, v->n);
    if (count_clear) {
        *count_clear = 0;
    }
    if (weft__ccd_intersect_mark(v->world, cloth, tangled) == 0) {
        *count = 0;
        return WEFT_OK;
    }
    /* One ring: a triangle with a crossing corner marks its other corners (2 marks the new ones,
     * so the ring does not spread within the pass). */
    for (uint32_t t = 0; t < v->nt; ++t) {
        const uint32_t *tri = v->tris + 3 * (size_t)t;
        if (tangled[tri[0]] == 1 || tangled[tri[1]] == 1 || tangled[tri[2]] == 1) {
            for (int k = 0; k < 3; ++k) {
                tangled[tri[k]] = tangled[tri[k]] ? tangled[tri[k]] : 2;
            }
        }
    }
    uint32_t c = 0, clear = 0;
    for (uint32_t i = 0; i < v->n; ++i) {
        c += tangled[i] == 1;
        clear += tangled[i] == 1 && pinched && !pinched[i];
        tangled[i] = tangled[i] != 0;
    }
    *count = c;
    if (count_clear) {
        *count_clear = pinched ? clear : c;
    }
    return WEFT_OK;
}

weft_result weft_sim_validator_check(weft_sim_validator *v, const float *cloth0, const float *cloth1,
                                     const float *collider0, const float *collider1, weft_sim_validation *out)
{
    weft_result r = check_args(v, cloth0, cloth1, 3 * (size_t)(v ? v->n : 0), collider0, collider1, out,
                               "weft_sim_validator_check");
    if (r != WEFT_OK) {
        return r;
    }
    if (!weft__all_finite(cloth1, 3 * (size_t)v->n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_sim_validator_check: positions contain NaN or infinity");
    }
    weft_sim_validation res = {.hit.type = WEFT_CCD_TYPE_COUNT};
    r = sweep(v, cloth0, cloth1, collider0, collider1, &res);
    if (r == WEFT_OK) {
        r = intersect(v, cloth1, collider1, &res);
    }
    if (r == WEFT_OK) {
        *out = res;
    }
    return r;
}

weft_result weft_sim_validator_check_path(weft_sim_validator *v, const float *cloth_states, uint32_t state_count,
                                          const float *collider0, const float *collider1, weft_sim_validation *out)
{
    if (v && state_count < 2) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sim_validator_check_path: needs at least two states");
    }
    const size_t stride = 3 * (size_t)(v ? v->n : 0);
    weft_result r = check_args(v, cloth_states, cloth_states, stride * state_count, collider0, collider1, out,
                               "weft_sim_validator_check_path");
    if (r != WEFT_OK) {
        return r;
    }
    weft_sim_validation res = {.hit.type = WEFT_CCD_TYPE_COUNT};
    const size_t nc3 = 3 * (size_t)v->nc;
    const uint32_t segs = state_count - 1;
    for (uint32_t k = 0; k < segs && r == WEFT_OK; ++k) {
        /* The collider moves linearly over the frame: the same interpolation as the solver's
         * substeps, so each piece is one straight motion of both meshes. */
        const float a0 = (float)k / (float)segs, a1 = (float)(k + 1) / (float)segs;
        for (size_t i = 0; i < nc3; ++i) {
            v->ca[i] = collider0[i] + a0 * (collider1[i] - collider0[i]);
            v->cb[i] = k + 1 == segs ? collider1[i] : collider0[i] + a1 * (collider1[i] - collider0[i]);
        }
        if (k == 0) {
            memcpy(v->ca, collider0, nc3 * sizeof(float));
        }
        r = sweep(v, cloth_states + k * stride, cloth_states + (k + 1) * stride, v->ca, v->cb, &res);
    }
    if (r == WEFT_OK) {
        r = intersect(v, cloth_states + segs * stride, collider1, &res);
    }
    if (r == WEFT_OK) {
        *out = res;
    }
    return r;
}
