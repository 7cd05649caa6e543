/* A garment that changes level while it runs (include/weft/lod.h).
 *
 * It owns one weft_garment of the current level. Every frame the state at t (positions and
 * collider) is copied into a small ring, sized at creation for the longest latent history of
 * the table's model levels. A switch creates the garment of the new level, replays the recorded
 * frames through the model's encoder/transformer so its latent window matches a model that had
 * run all along (the outputs of those replay steps are discarded), then installs x_t, x_{t-1},
 * the colliders and the pins. Without that the first step after a switch sees a window filled
 * with copies of one frame, and an inertial method without x_{t-1} would lose the velocity:
 * both show as a pop.
 *
 * Resolution levels simulate a coarser mesh of the same garment (def.sim_meshes) and draw the
 * garment's own mesh through a mesh map; the "drawn" state (positions at t and t-1 on the
 * garment's mesh) is what the API shows, what the ring records and what a switch carries. A
 * switch onto a coarse mesh starts it from the drawn state mapped down, and fades the detail the
 * coarse mesh cannot hold (drawn - up(down(drawn))) out over a few frames.
 *
 * Pins name drawn vertices. At a coarse level they are carried onto the coarse mesh by nearest
 * vertices in rest space (coarse_pins): each pinned drawn vertex pins its nearest coarse vertex,
 * and a coarse vertex whose nearest drawn vertex is pinned is pinned too, at the drawn target
 * plus the rest-space offset between the two. */
#include "lod/lod_internal.h"
#include "garment/garment.h"
#include "model/model.h"
#include "model/transformer.h"

#include <math.h>
#include <string.h>

typedef struct lod_frame {
    uint64_t frame;                     /* absolute frame index; valid only when used */
    bool used;
    float *x;                           /* positions at that frame, vertex_count * 3 */
    float *c;                           /* collider at that frame, collider_vertex_count * 3 */
} lod_frame;

typedef struct lod_mesh {
    float *rest;
    uint32_t *tris;
    uint32_t V, T;
    weft_mesh_map *up;                  /* this mesh -> the drawn mesh */
    weft_mesh_map *down;                /* the drawn mesh -> this mesh */
    uint32_t *near_sim;                 /* per drawn vertex: the nearest vertex of this mesh (rest) */
    uint32_t *near_drawn;               /* per vertex of this mesh: the nearest drawn vertex (rest) */
} lod_mesh;

struct weft_lod_garment {
    weft_context *ctx;
    const weft_lod_table *table;
    const weft_model **models;
    uint32_t model_count;
    uint32_t level;
    weft_garment *g;
    uint64_t frame_base;                /* absolute frame = frame_base + g->stats.frame */
    uint32_t N, C;                      /* garment and collider vertex counts */

    lod_frame *ring;
    uint32_t ring_cap, ring_next;
    float *ring_store;
    size_t ring_store_floats;
    uint64_t last_recorded;
    bool any_recorded;

    float *rest;                        /* the drawn mesh (copied) */
    uint32_t *tris;
    uint32_t T;
    lod_mesh meshes[WEFT_LOD_MAX_SIM_MESHES];
    uint32_t mesh_count;
    int mesh;                           /* simulated mesh: -1 the drawn one, else meshes[mesh] */
    float *drawn_x, *drawn_prev;        /* drawn state at t, t-1 when mesh >= 0 */
    float *blend;                       /* detail to fade out after a switch onto a coarse mesh */
    uint32_t blend_frames, blend_left;
    float *scratch;                     /* largest sim mesh's vertex count * 3 */
    size_t scratch_floats;
    uint64_t drawn_frame;               /* g->stats.frame the drawn state was last made for */

    /* Pins at a coarse level (allocated only with sim meshes): the drawn pins as the host gave
     * them, a drawn vertex -> pin slot lookup (UINT32_MAX: none), and the coarse pins made of them. */
    uint32_t *pin_idx, *pin_slot, pin_count;
    float *pin_tgt;
    uint32_t *sim_pin_idx;
    float *sim_pin_tgt, *sim_pin_w;     /* largest sim mesh's vertex count (* 3) */
};

weft_lod_garment_def weft_default_lod_garment_def(void)
{
    weft_lod_garment_def def;
    memset(&def, 0, sizeof def);
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

/* The model a level runs: matching metadata name, preferring one stored at the level's precision. */
static const weft_model *find_model(const weft_model *const *models, uint32_t count, const weft_lod_level *lv)
{
    const weft_model *any = NULL;
    for (uint32_t i = 0; i < count; ++i) {
        if (!models[i]) {
            continue;
        }
        weft_model_info info = weft_model_get_info(models[i]);
        if (!info.name || strcmp(info.name, lv->model) != 0) {
            continue;
        }
        if (info.precision == lv->precision) {
            return models[i];
        }
        if (!any) {
            any = models[i];
        }
    }
    return any;
}

/* Latent frames a model keeps (its config "history"); 1 for anything without one. */
static uint32_t model_history(const weft_model *m)
{
    uint32_t h = 1;
    if (m && weft__model_config_find(m, "history") && weft__model_config_u32(m, "history", 1, 64, &h) != WEFT_OK) {
        h = 1;
    }
    weft__clear_error();
    return h;
}

/* A garment of level lv starting at x0; collider_rest is where LBS binds. */
static weft_result make_garment(weft_lod_garment *lg, const weft_lod_level *lv, const float *rest, uint32_t nv,
                                const uint32_t *tris, uint32_t tri_count, const float *collider_rest,
                                const uint32_t *ctris, uint32_t ctri_count, const float *x0, weft_garment **out)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = lv->method;
    d.ccd.enabled = lv->ccd;
    if (lv->method == WEFT_METHOD_MODEL) {
        d.model = find_model(lg->models, lg->model_count, lv);
        d.precision = lv->precision;
        d.collider_crop_margin = (float)(lv->crop_cm / 100.0);
        d.collider_crop = lv->collider_crop;
        d.max_collider_tokens = lv->max_collider_tokens;
        if (!d.model) {
            return weft__fail(WEFT_ERROR_NO_MODEL, "lod level '%s': no model named '%s' among the %u given", lv->name,
                              lv->model, lg->model_count);
        }
    }
    if (lv->method == WEFT_METHOD_XPBD) {
        d.substeps = lv->substeps;
    }
    d.tethers.distance = (float)(lv->tether_cm / 100.0);
    d.strain.limit = (float)(lv->strain_limit_pct / 100.0);
    d.strain.contact = (float)(lv->strain_contact_cm / 100.0);
    d.collision.push = (float)(lv->push_cm / 100.0);
    d.rest_positions = rest;
    d.vertex_count = nv;
    d.triangles = tris;
    d.triangle_count = tri_count;
    d.collider_rest_positions = collider_rest;
    d.collider_vertex_count = lg->C;
    d.collider_triangles = ctris;
    d.collider_triangle_count = ctri_count;
    d.initial_positions = x0;
    return weft_garment_create(lg->ctx, &d, out);
}

/* The mesh a level simulates: -1 (the drawn mesh) at resolution 1, else the given mesh whose
 * vertex share is nearest the level's resolution, within a factor of 1.5; -2 when there is none. */
static int mesh_for(const weft_lod_garment *lg, const weft_lod_level *lv)
{
    if (lv->resolution >= 1.0) {
        return -1;
    }
    int best = -2;
    double best_gap = log(1.5) + 1e-9;
    for (uint32_t i = 0; i < lg->mesh_count; ++i) {
        double gap = fabs(log((double)lg->meshes[i].V / lg->N / lv->resolution));
        if (gap <= best_gap) {
            best_gap = gap;
            best = (int)i;
        }
    }
    return best;
}

static weft_result no_mesh(const weft_lod_garment *lg, const weft_lod_level *lv, const char *fn)
{
    return weft__fail(WEFT_ERROR_UNSUPPORTED,
                      "%s: level '%s' simulates at resolution %g (about %.0f vertices) and none of the %u sim meshes "
                      "given is within a factor of 1.5 of that",
                      fn, lv->name, lv->resolution, lv->resolution * lg->N, lg->mesh_count);
}

/* The drawn state at t and t-1. */
static const float *drawn_x(const weft_lod_garment *lg) { return lg->mesh >= 0 ? lg->drawn_x : lg->g->x; }
static const float *drawn_prev(const weft_lod_garment *lg) { return lg->mesh >= 0 ? lg->drawn_prev : lg->g->x_prev; }

/* drawn_x from the coarse garment's positions, plus what is left of the blend; pinned drawn
 * vertices at their targets, as at the drawn level (the map alone leaves them where the coarse
 * triangles around them are, which sag where the coarse pins end). */
static weft_result update_drawn(weft_lod_garment *lg)
{
    weft_result r = weft_mesh_map_apply(lg->meshes[lg->mesh].up, lg->g->x, lg->drawn_x);
    if (r != WEFT_OK) {
        return r;
    }
    if (lg->blend_left > 0) {
        const float w = (float)lg->blend_left / (float)lg->blend_frames; /* blend_left <= blend_frames */
        for (size_t i = 0; i < (size_t)lg->N * 3; ++i) {
            lg->drawn_x[i] += w * lg->blend[i];
        }
    }
    for (uint32_t k = 0; k < lg->pin_count; ++k) {
        memcpy(lg->drawn_x + 3 * (size_t)lg->pin_idx[k], lg->pin_tgt + 3 * (size_t)k, 3 * sizeof(float));
    }
    return WEFT_OK;
}

/* A mesh map whose `to` points follow the `from` surface. */
static weft_result make_map(weft_context *ctx, const float *from, uint32_t from_n, const uint32_t *from_tris,
                            uint32_t from_t, const float *to, uint32_t to_n, weft_mesh_map **out)
{
    weft_mesh_map_def d = weft_default_mesh_map_def();
    d.from_rest_positions = from;
    d.from_vertex_count = from_n;
    d.from_triangles = from_tris;
    d.from_triangle_count = from_t;
    d.to_rest_positions = to;
    d.to_vertex_count = to_n;
    return weft_mesh_map_create(ctx, &d, out);
}

/* For each of n points of `from` (xyz), the index of the nearest of the m points of `to`.
 * Brute force at creation: 4k x 1k vertices is a few milliseconds. */
static void nearest_points(const float *from, uint32_t n, const float *to, uint32_t m, uint32_t *out)
{
    for (uint32_t i = 0; i < n; ++i) {
        const float *p = from + 3 * (size_t)i;
        float best = INFINITY;
        out[i] = 0;
        for (uint32_t j = 0; j < m; ++j) {
            const float *q = to + 3 * (size_t)j;
            const float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
            const float d = dx * dx + dy * dy + dz * dz;
            if (d < best) {
                best = d;
                out[i] = j;
            }
        }
    }
}

/* The drawn pins (validated) carried onto coarse mesh m: writes lg->sim_pin_idx/tgt, returns the
 * count. A coarse vertex reached by several drawn pins takes the mean of their targets. */
static uint32_t coarse_pins(weft_lod_garment *lg, const lod_mesh *m, const uint32_t *idx, const float *tgt,
                            uint32_t count)
{
    float *acc = lg->sim_pin_tgt, *w = lg->sim_pin_w;
    memset(w, 0, (size_t)m->V * sizeof(float));
    for (uint32_t k = 0; k < count; ++k) {
        const uint32_t j = idx[k], i = m->near_sim[j];
        if (w[i] == 0.0f) {
            acc[3 * (size_t)i] = acc[3 * (size_t)i + 1] = acc[3 * (size_t)i + 2] = 0.0f;
        }
        for (int c = 0; c < 3; ++c) {
            acc[3 * (size_t)i + c] += tgt[3 * (size_t)k + c] + m->rest[3 * (size_t)i + c] - lg->rest[3 * (size_t)j + c];
        }
        w[i] += 1.0f;
        lg->pin_slot[j] = k;
    }
    uint32_t n = 0;
    for (uint32_t i = 0; i < m->V; ++i) {
        const uint32_t j = m->near_drawn[i], k = lg->pin_slot[j];
        if (w[i] == 0.0f && k != UINT32_MAX) {
            for (int c = 0; c < 3; ++c) {
                acc[3 * (size_t)i + c] = tgt[3 * (size_t)k + c] + m->rest[3 * (size_t)i + c] - lg->rest[3 * (size_t)j + c];
            }
            w[i] = 1.0f;
        }
        if (w[i] > 0.0f) {
            lg->sim_pin_idx[n] = i;
            for (int c = 0; c < 3; ++c) {
                lg->sim_pin_tgt[3 * (size_t)n + c] = acc[3 * (size_t)i + c] / w[i]; /* n <= i: in place */
            }
            n++;
        }
    }
    for (uint32_t k = 0; k < count; ++k) {
        lg->pin_slot[idx[k]] = UINT32_MAX;
    }
    return n;
}

static void free_lod(weft_lod_garment *lg)
{
    const weft_context *ctx = lg->ctx;
    weft_garment_destroy(lg->g);
    for (uint32_t i = 0; i < lg->mesh_count; ++i) {
        lod_mesh *m = &lg->meshes[i];
        weft_mesh_map_destroy(m->up);
        weft_mesh_map_destroy(m->down);
        weft__free(ctx, m->rest, (size_t)m->V * 3 * sizeof(float));
        weft__free(ctx, m->tris, (size_t)m->T * 3 * sizeof(uint32_t));
        weft__free(ctx, m->near_sim, (size_t)lg->N * sizeof(uint32_t));
        weft__free(ctx, m->near_drawn, (size_t)m->V * sizeof(uint32_t));
    }
    weft__free(ctx, lg->pin_idx, (size_t)lg->N * sizeof(uint32_t));
    weft__free(ctx, lg->pin_slot, (size_t)lg->N * sizeof(uint32_t));
    weft__free(ctx, lg->pin_tgt, (size_t)lg->N * 3 * sizeof(float));
    weft__free(ctx, lg->sim_pin_idx, lg->scratch_floats / 3 * sizeof(uint32_t));
    weft__free(ctx, lg->sim_pin_tgt, lg->scratch_floats * sizeof(float));
    weft__free(ctx, lg->sim_pin_w, lg->scratch_floats / 3 * sizeof(float));
    const size_t nx = (size_t)lg->N * 3 * sizeof(float);
    weft__free(ctx, lg->drawn_x, nx);
    weft__free(ctx, lg->drawn_prev, nx);
    weft__free(ctx, lg->blend, nx);
    weft__free(ctx, lg->scratch, lg->scratch_floats * sizeof(float));
    weft__free(ctx, lg->rest, nx);
    weft__free(ctx, lg->tris, (size_t)lg->T * 3 * sizeof(uint32_t));
    weft__free(ctx, lg->ring_store, lg->ring_store_floats * sizeof(float));
    weft__free(ctx, lg->ring, (size_t)lg->ring_cap * sizeof *lg->ring);
    weft__free(ctx, (void *)lg->models, (size_t)lg->model_count * sizeof *lg->models);
    weft__free(ctx, lg, sizeof *lg);
}

weft_result weft_lod_garment_create(weft_context *ctx, const weft_lod_garment_def *def, weft_lod_garment **out)
{
    if (!ctx || !def || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: context, def and out are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_lod_garment_create: def was not initialised with weft_default_lod_garment_def()");
    }
    if (!def->table || def->level >= def->table->count) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: level %u outside the table (%u levels)",
                          def->level, def->table ? def->table->count : 0);
    }
    if (def->model_count > 0 && !def->models) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: model_count %u but models is NULL",
                          def->model_count);
    }
    if (def->history_frames > 64) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: history_frames %u over 64",
                          def->history_frames);
    }
    if (!def->rest_positions || def->vertex_count == 0 || !def->triangles || def->triangle_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_lod_garment_create: rest_positions and triangles are required");
    }
    if (def->sim_mesh_count > WEFT_LOD_MAX_SIM_MESHES || (def->sim_mesh_count > 0 && !def->sim_meshes)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_lod_garment_create: sim_mesh_count %u (at most %u, and sim_meshes must be given)",
                          def->sim_mesh_count, WEFT_LOD_MAX_SIM_MESHES);
    }
    if (def->resolution_blend_frames > 1000) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: resolution_blend_frames %u over 1000",
                          def->resolution_blend_frames);
    }
    /* Ring length: the longest model history among levels we can run. */
    uint32_t h = def->history_frames;
    if (h == 0) {
        h = 1;
        for (uint32_t i = 0; i < def->table->count; ++i) {
            const weft_lod_level *lv = &def->table->levels[i];
            if (lv->method == WEFT_METHOD_MODEL) {
                uint32_t hm = model_history(find_model(def->models, def->model_count, lv));
                h = hm > h ? hm : h;
            }
        }
    }
    weft_lod_garment *lg = weft__alloc(ctx, sizeof *lg);
    if (!lg) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    lg->ctx = ctx;
    lg->table = def->table;
    lg->level = def->level;
    lg->N = def->vertex_count;
    lg->C = def->collider_vertex_count;
    lg->model_count = def->model_count;
    lg->T = def->triangle_count;
    lg->mesh = -1;
    lg->blend_frames = def->resolution_blend_frames;
    const size_t nx = (size_t)lg->N * 3 * sizeof(float);
    lg->rest = weft__alloc(ctx, nx);
    lg->tris = weft__alloc(ctx, (size_t)lg->T * 3 * sizeof(uint32_t));
    bool ok = lg->rest && lg->tris;
    if (ok) {
        memcpy(lg->rest, def->rest_positions, nx);
        memcpy(lg->tris, def->triangles, (size_t)lg->T * 3 * sizeof(uint32_t));
    }
    if (ok && def->sim_mesh_count > 0) {
        lg->drawn_x = weft__alloc(ctx, nx);
        lg->drawn_prev = weft__alloc(ctx, nx);
        lg->blend = weft__alloc(ctx, nx);
        ok = lg->drawn_x && lg->drawn_prev && lg->blend;
    }
    weft_result mr = WEFT_OK;
    for (uint32_t i = 0; ok && mr == WEFT_OK && i < def->sim_mesh_count; ++i) {
        const weft_lod_mesh *src = &def->sim_meshes[i];
        lod_mesh *m = &lg->meshes[i];
        if (!src->rest_positions || !src->triangles || src->vertex_count < 3 || src->triangle_count == 0) {
            mr = weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                            "weft_lod_garment_create: sim_meshes[%u] needs rest positions, at least 3 vertices and "
                            "a triangle", i);
            break;
        }
        m->V = src->vertex_count;
        m->T = src->triangle_count;
        m->rest = weft__alloc(ctx, (size_t)m->V * 3 * sizeof(float));
        m->tris = weft__alloc(ctx, (size_t)m->T * 3 * sizeof(uint32_t));
        lg->mesh_count = i + 1;
        if (!m->rest || !m->tris) {
            ok = false;
            break;
        }
        memcpy(m->rest, src->rest_positions, (size_t)m->V * 3 * sizeof(float));
        memcpy(m->tris, src->triangles, (size_t)m->T * 3 * sizeof(uint32_t));
        /* Both maps validate their meshes (indices, finite values, zero-area triangles). */
        mr = make_map(ctx, m->rest, m->V, m->tris, m->T, lg->rest, lg->N, &m->up);
        if (mr == WEFT_OK) {
            mr = make_map(ctx, lg->rest, lg->N, lg->tris, lg->T, m->rest, m->V, &m->down);
        }
        if (mr != WEFT_OK) {
            weft__fail(mr, "weft_lod_garment_create: sim_meshes[%u]: %s", i, weft_last_error());
            break;
        }
        m->near_sim = weft__alloc(ctx, (size_t)lg->N * sizeof(uint32_t));
        m->near_drawn = weft__alloc(ctx, (size_t)m->V * sizeof(uint32_t));
        if (!m->near_sim || !m->near_drawn) {
            ok = false;
            break;
        }
        nearest_points(lg->rest, lg->N, m->rest, m->V, m->near_sim);
        nearest_points(m->rest, m->V, lg->rest, lg->N, m->near_drawn);
    }
    for (uint32_t i = 0; i < lg->mesh_count; ++i) {
        size_t f = (size_t)lg->meshes[i].V * 3;
        lg->scratch_floats = f > lg->scratch_floats ? f : lg->scratch_floats;
    }
    if (ok && mr == WEFT_OK && lg->scratch_floats > 0) {
        lg->scratch = weft__alloc(ctx, lg->scratch_floats * sizeof(float));
        lg->pin_idx = weft__alloc(ctx, (size_t)lg->N * sizeof(uint32_t));
        lg->pin_slot = weft__alloc(ctx, (size_t)lg->N * sizeof(uint32_t));
        lg->pin_tgt = weft__alloc(ctx, (size_t)lg->N * 3 * sizeof(float));
        lg->sim_pin_idx = weft__alloc(ctx, lg->scratch_floats / 3 * sizeof(uint32_t));
        lg->sim_pin_tgt = weft__alloc(ctx, lg->scratch_floats * sizeof(float));
        lg->sim_pin_w = weft__alloc(ctx, lg->scratch_floats / 3 * sizeof(float));
        ok = lg->scratch && lg->pin_idx && lg->pin_slot && lg->pin_tgt && lg->sim_pin_idx && lg->sim_pin_tgt &&
             lg->sim_pin_w;
        for (uint32_t i = 0; ok && i < lg->N; ++i) {
            lg->pin_slot[i] = UINT32_MAX;
        }
    }
    if (mr == WEFT_OK && !ok) {
        mr = WEFT_ERROR_OUT_OF_MEMORY;
    }
    if (mr != WEFT_OK) {
        free_lod(lg);
        return mr;
    }
    if (def->model_count > 0) {
        lg->models = weft__alloc(ctx, (size_t)def->model_count * sizeof *lg->models);
        ok = lg->models != NULL;
        if (ok) {
            memcpy((void *)lg->models, def->models, (size_t)def->model_count * sizeof *lg->models);
        }
    }
    /* A window of h latents is rebuilt from h - 1 replayed frames, each needing x_{k-1}; one more
     * slot covers a switch made after this frame's set_collider already recorded frame t. */
    if (ok && h > 1) {
        lg->ring_cap = h + 1;
        size_t per = ((size_t)lg->N + lg->C) * 3;
        lg->ring_store_floats = per * lg->ring_cap;
        lg->ring = weft__alloc(ctx, (size_t)lg->ring_cap * sizeof *lg->ring);
        lg->ring_store = weft__alloc(ctx, lg->ring_store_floats * sizeof(float));
        ok = lg->ring && lg->ring_store;
        for (uint32_t i = 0; ok && i < lg->ring_cap; ++i) {
            lg->ring[i].x = lg->ring_store + per * i;
            lg->ring[i].c = lg->ring[i].x + (size_t)lg->N * 3;
        }
    }
    if (!ok) {
        free_lod(lg);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    const weft_lod_level *lv = &def->table->levels[def->level];
    const int mesh = mesh_for(lg, lv);
    if (mesh == -2) {
        weft_result r = no_mesh(lg, lv, "weft_lod_garment_create");
        free_lod(lg);
        return r;
    }
    const float *x0 = def->initial_positions ? def->initial_positions : def->rest_positions;
    weft_result r;
    if (mesh < 0) {
        r = make_garment(lg, lv, lg->rest, lg->N, lg->tris, lg->T, def->collider_rest_positions,
                         def->collider_triangles, def->collider_triangle_count, x0, &lg->g);
    } else {
        /* The coarse garment starts at the initial state mapped down, the drawn one at it exactly. */
        lod_mesh *m = &lg->meshes[mesh];
        r = weft_mesh_map_apply(m->down, x0, lg->scratch);
        if (r == WEFT_OK) {
            r = make_garment(lg, lv, m->rest, m->V, m->tris, m->T, def->collider_rest_positions,
                             def->collider_triangles, def->collider_triangle_count, lg->scratch, &lg->g);
        }
        if (r == WEFT_OK) {
            lg->mesh = mesh;
            memcpy(lg->drawn_x, x0, nx);
            memcpy(lg->drawn_prev, x0, nx);
            r = update_drawn(lg); /* what the coarse mesh can show of x0: no blend at creation */
        }
    }
    if (r != WEFT_OK) {
        free_lod(lg);
        return r;
    }
    *out = lg;
    return WEFT_OK;
}

void weft_lod_garment_destroy(weft_lod_garment *lg)
{
    if (lg) {
        free_lod(lg);
    }
}

static uint64_t current_frame(const weft_lod_garment *lg) { return lg->frame_base + lg->g->stats.frame; }

/* Copies the state at t into the ring once per frame. */
static void record(weft_lod_garment *lg)
{
    uint64_t f = current_frame(lg);
    if (lg->ring_cap == 0 || (lg->any_recorded && lg->last_recorded == f)) {
        return;
    }
    if (lg->any_recorded && f < lg->last_recorded) {
        /* The current garment's state was replaced behind our back (weft_garment_set_state on
         * weft_lod_garment_current): the recorded frames no longer lead to this state. */
        for (uint32_t i = 0; i < lg->ring_cap; ++i) {
            lg->ring[i].used = false;
        }
    }
    lod_frame *e = &lg->ring[lg->ring_next];
    e->frame = f;
    e->used = true;
    memcpy(e->x, drawn_x(lg), (size_t)lg->N * 3 * sizeof(float));
    if (lg->C > 0) {
        memcpy(e->c, lg->g->collider_prev, (size_t)lg->C * 3 * sizeof(float));
    }
    lg->ring_next = (lg->ring_next + 1) % lg->ring_cap;
    lg->last_recorded = f;
    lg->any_recorded = true;
}

static const lod_frame *ring_find(const weft_lod_garment *lg, uint64_t frame)
{
    for (uint32_t i = 0; i < lg->ring_cap; ++i) {
        if (lg->ring[i].used && lg->ring[i].frame == frame) {
            return &lg->ring[i];
        }
    }
    return NULL;
}

weft_result weft_lod_garment_set_collider(weft_lod_garment *lg, const float *collider_positions)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_collider: garment is NULL");
    }
    weft_result r = weft_garment_set_collider(lg->g, collider_positions);
    if (r == WEFT_OK) {
        record(lg);
    }
    return r;
}

weft_result weft_lod_garment_set_pins(weft_lod_garment *lg, const uint32_t *vertex_indices,
                                      const float *target_positions, uint32_t count)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_pins: garment is NULL");
    }
    if (lg->mesh < 0) {
        return weft_garment_set_pins(lg->g, vertex_indices, target_positions, count);
    }
    /* A coarse level: the garment's own checks, on the drawn mesh's vertex count, before anything changes. */
    if (count > 0 && (!vertex_indices || !target_positions)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_pins: indices and targets are required");
    }
    if (count > lg->N) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_lod_garment_set_pins: %u pins for %u vertices", count, lg->N);
    }
    for (uint32_t i = 0; i < count; ++i) {
        if (vertex_indices[i] >= lg->N) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                              "weft_lod_garment_set_pins: pin %u index %u >= vertex count %u", i, vertex_indices[i],
                              lg->N);
        }
    }
    if (!weft__all_finite(target_positions, (size_t)count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_lod_garment_set_pins: targets contain NaN or infinity");
    }
    const uint32_t n = coarse_pins(lg, &lg->meshes[lg->mesh], vertex_indices, target_positions, count);
    weft_result r = weft_garment_set_pins(lg->g, lg->sim_pin_idx, lg->sim_pin_tgt, n);
    if (r == WEFT_OK && count > 0) {
        memcpy(lg->pin_idx, vertex_indices, (size_t)count * sizeof(uint32_t));
        memcpy(lg->pin_tgt, target_positions, (size_t)count * 3 * sizeof(float));
    }
    lg->pin_count = r == WEFT_OK ? count : lg->pin_count;
    return r;
}

/* At a resolution level: the coarse garment gets the state mapped down, the drawn one keeps it
 * exactly and fades out what the coarse mesh cannot show. */
static weft_result set_state_coarse(weft_lod_garment *lg, const float *positions, const float *prev_positions)
{
    if (!positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_state: positions are required");
    }
    const float *prev = prev_positions ? prev_positions : positions;
    const size_t nx = (size_t)lg->N * 3;
    if (!weft__all_finite(positions, nx) || !weft__all_finite(prev, nx)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_lod_garment_set_state: positions contain NaN or infinity");
    }
    const lod_mesh *m = &lg->meshes[lg->mesh];
    /* x_t mapped into the scratch, x_{t-1} into the garment's x_next (set_state does not read it). */
    weft_result r = weft_mesh_map_apply(m->down, positions, lg->scratch);
    if (r == WEFT_OK) {
        r = weft_mesh_map_apply(m->down, prev, lg->g->x_next);
    }
    if (r == WEFT_OK) {
        r = weft_mesh_map_apply(m->up, lg->scratch, lg->blend);
    }
    if (r != WEFT_OK) {
        return r;
    }
    r = weft_garment_set_state(lg->g, lg->scratch, lg->g->x_next);
    if (r != WEFT_OK) {
        return r;
    }
    for (size_t i = 0; i < nx; ++i) {
        lg->blend[i] = positions[i] - lg->blend[i];
    }
    memcpy(lg->drawn_prev, prev, nx * sizeof(float));
    lg->blend_left = lg->blend_frames;
    if (lg->blend_frames > 0) {
        memcpy(lg->drawn_x, positions, nx * sizeof(float));
        return WEFT_OK;
    }
    return update_drawn(lg);
}

weft_result weft_lod_garment_set_state(weft_lod_garment *lg, const float *positions, const float *prev_positions)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_state: garment is NULL");
    }
    const uint64_t before = current_frame(lg);
    weft_result r;
    if (lg->mesh < 0) {
        r = weft_garment_set_state(lg->g, positions, prev_positions);
    } else {
        r = set_state_coarse(lg, positions, prev_positions);
    }
    lg->drawn_frame = lg->g->stats.frame;
    if (r == WEFT_OK) {
        /* The garment's frame count restarts at 0: keep absolute frames increasing, and drop
         * the frames recorded before the teleport. */
        lg->frame_base = before + 1;
        for (uint32_t i = 0; i < lg->ring_cap; ++i) {
            lg->ring[i].used = false;
        }
        lg->any_recorded = false;
    }
    return r;
}

weft_result weft_lod_garment_step(weft_lod_garment *lg)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_step: garment is NULL");
    }
    if (lg->C > 0 && !lg->g->collider_next_set) {
        return weft_garment_step(lg->g); /* reports the missing collider; nothing to record */
    }
    record(lg);
    weft_result r = weft_garment_step(lg->g);
    return r == WEFT_OK ? weft_lod_garment_sync(lg) : r;
}

weft_result weft_lod_garment_sync(weft_lod_garment *lg)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_sync: garment is NULL");
    }
    if (lg->mesh < 0 || lg->g->stats.frame == lg->drawn_frame) {
        return WEFT_OK;
    }
    float *t = lg->drawn_prev;
    lg->drawn_prev = lg->drawn_x;
    lg->drawn_x = t;
    lg->blend_left -= lg->blend_left > 0;
    weft_result r = update_drawn(lg);
    if (r == WEFT_OK) {
        lg->drawn_frame = lg->g->stats.frame;
    }
    return r;
}

/* Replays recorded frames k0..t-1 through ng's method so its latent window is what it would be
 * had it run them. Only the method's own history changes; ng's state is overwritten afterwards. */
static weft_result warm(const weft_lod_garment *lg, weft_garment *ng, uint32_t history, int mesh)
{
    const weft_garment *old = lg->g;
    const uint64_t t = current_frame(lg);
    if (history < 2 || t == 0 || lg->ring_cap == 0) {
        return WEFT_OK;
    }
    const size_t nx = (size_t)lg->N * 3 * sizeof(float), nc = (size_t)lg->C * 3 * sizeof(float);
    /* The earliest start whose every input is recorded: frame k needs x_k, x_{k-1}, c_k, c_{k+1}. */
    uint64_t k0 = t > history - 1 ? t - (history - 1) : 0;
    for (; k0 < t; ++k0) {
        bool complete = true;
        for (uint64_t k = k0; k < t && complete; ++k) {
            complete = ring_find(lg, k) && (k == 0 || ring_find(lg, k - 1)) && (k + 1 == t || ring_find(lg, k + 1));
        }
        if (complete) {
            break;
        }
    }
    for (uint64_t k = k0; k < t; ++k) {
        const lod_frame *fk = ring_find(lg, k);
        const lod_frame *fp = k > 0 ? ring_find(lg, k - 1) : fk; /* frame 0 starts at rest velocity */
        if (mesh < 0) {
            memcpy(ng->x, fk->x, nx);
            memcpy(ng->x_prev, fp->x, nx);
        } else {
            weft_result r = weft_mesh_map_apply(lg->meshes[mesh].down, fk->x, ng->x);
            if (r == WEFT_OK) {
                r = weft_mesh_map_apply(lg->meshes[mesh].down, fp->x, ng->x_prev);
            }
            if (r != WEFT_OK) {
                return r;
            }
        }
        if (lg->C > 0) {
            memcpy(ng->collider_prev, fk->c, nc);
            memcpy(ng->collider_next, k + 1 == t ? old->collider_prev : ring_find(lg, k + 1)->c, nc);
        }
        weft_result r = ng->ops->step(ng);
        if (r != WEFT_OK) {
            return r;
        }
    }
    return WEFT_OK;
}

weft_result weft_lod_garment_switch(weft_lod_garment *lg, uint32_t level)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_switch: garment is NULL");
    }
    if (level >= lg->table->count) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_switch: level %u outside the table (%u levels)",
                          level, lg->table->count);
    }
    if (level == lg->level) {
        return WEFT_OK;
    }
    const weft_lod_level *lv = &lg->table->levels[level];
    weft_garment *old = lg->g;
    const int mesh = mesh_for(lg, lv);
    if (mesh == -2) {
        return no_mesh(lg, lv, "weft_lod_garment_switch");
    }
    /* LBS, tethers and the model's skinned prior bind the garment to the collider at creation:
     * bind to the pose of now, not the rest pose, or the cloth would snap back to where it was
     * designed (LBS, tethers) or follow the wrong part of the body (the prior). */
    const bool skin_prior = lv->method == WEFT_METHOD_MODEL &&
                            weft__ct_binds_collider(find_model(lg->models, lg->model_count, lv));
    const bool binds = lv->method == WEFT_METHOD_LBS || lv->tether_cm > 0.0 || skin_prior;
    const float *bind = binds && lg->C > 0 ? old->collider_prev : old->collider_rest;
    /* The drawn state carries over: exactly onto the drawn mesh, mapped down onto a coarse one. */
    const float *X = drawn_x(lg), *Xp = drawn_prev(lg);
    const lod_mesh *m = mesh >= 0 ? &lg->meshes[mesh] : NULL;
    weft_garment *ng = NULL;
    weft_result r = m ? weft_mesh_map_apply(m->down, X, lg->scratch) : WEFT_OK;
    if (r == WEFT_OK) {
        r = m ? make_garment(lg, lv, m->rest, m->V, m->tris, m->T, bind, old->collider_triangles,
                             old->collider_triangle_count, lg->scratch, &ng)
              : make_garment(lg, lv, lg->rest, lg->N, lg->tris, lg->T, bind, old->collider_triangles,
                             old->collider_triangle_count, X, &ng);
    }
    if (r != WEFT_OK) {
        return r;
    }
    if (lv->method == WEFT_METHOD_MODEL) {
        r = warm(lg, ng, model_history(ng->model), mesh);
    }
    const size_t nx = (size_t)lg->N * 3 * sizeof(float), nc = (size_t)lg->C * 3 * sizeof(float);
    if (r == WEFT_OK && m) {
        r = weft_mesh_map_apply(m->down, X, ng->x);
        if (r == WEFT_OK) {
            r = weft_mesh_map_apply(m->down, Xp, ng->x_prev);
        }
        if (r == WEFT_OK) {
            r = weft_mesh_map_apply(m->up, ng->x, lg->blend); /* what the coarse mesh shows of X */
        }
    } else if (r == WEFT_OK) {
        memcpy(ng->x, X, nx);
        memcpy(ng->x_prev, Xp, nx);
    }
    if (r != WEFT_OK) {
        weft_garment_destroy(ng);
        return r;
    }
    if (m) {
        /* Nothing fails past this point. The drawn state stays X; the difference fades out. */
        for (size_t i = 0; i < (size_t)lg->N * 3; ++i) {
            lg->blend[i] = X[i] - lg->blend[i];
        }
        if (Xp != lg->drawn_prev) {
            memcpy(lg->drawn_prev, Xp, nx);
        }
        if (X != lg->drawn_x) {
            memcpy(lg->drawn_x, X, nx);
        }
        lg->blend_left = lg->blend_frames;
        if (lg->blend_frames == 0) {
            weft_mesh_map_apply(m->up, ng->x, lg->drawn_x); /* succeeded just above */
        }
    } else {
        lg->blend_left = 0;
    }
    if (lg->C > 0) {
        memcpy(ng->collider_prev, old->collider_prev, nc);
        if (old->collider_next_set) {
            memcpy(ng->collider_next, old->collider_next, nc);
            ng->collider_next_set = true;
        }
    }
    /* The drawn pins carry over: kept by the garment at the drawn level, by lg at a coarse one;
     * onto a coarse mesh they are carried by coarse_pins. */
    const uint32_t *pin_idx = lg->mesh < 0 ? old->pin_indices : lg->pin_idx;
    const float *pin_tgt = lg->mesh < 0 ? old->pin_targets : lg->pin_tgt;
    const uint32_t pin_count = lg->mesh < 0 ? old->pin_count : lg->pin_count;
    if (m) {
        ng->pin_count = coarse_pins(lg, m, pin_idx, pin_tgt, pin_count);
        memcpy(ng->pin_indices, lg->sim_pin_idx, (size_t)ng->pin_count * sizeof(uint32_t));
        memcpy(ng->pin_targets, lg->sim_pin_tgt, (size_t)ng->pin_count * 3 * sizeof(float));
        if (lg->mesh < 0 && pin_count > 0) {
            memcpy(lg->pin_idx, pin_idx, (size_t)pin_count * sizeof(uint32_t));
            memcpy(lg->pin_tgt, pin_tgt, (size_t)pin_count * 3 * sizeof(float));
        }
        lg->pin_count = pin_count;
    } else if (pin_count > 0) {
        memcpy(ng->pin_indices, pin_idx, (size_t)pin_count * sizeof(uint32_t));
        memcpy(ng->pin_targets, pin_tgt, (size_t)pin_count * 3 * sizeof(float));
        ng->pin_count = pin_count;
    }
    lg->frame_base += old->stats.frame;
    ng->stats = (weft_step_stats){0};
    weft_garment_destroy(old);
    lg->g = ng;
    lg->level = level;
    lg->mesh = mesh;
    lg->drawn_frame = ng->stats.frame;
    return WEFT_OK;
}

uint32_t weft_lod_garment_level(const weft_lod_garment *lg) { return lg ? lg->level : 0; }

const float *weft_lod_garment_positions(const weft_lod_garment *lg) { return lg ? drawn_x(lg) : NULL; }

uint32_t weft_lod_garment_vertex_count(const weft_lod_garment *lg) { return lg ? lg->N : 0; }

weft_garment *weft_lod_garment_current(weft_lod_garment *lg) { return lg ? lg->g : NULL; }
