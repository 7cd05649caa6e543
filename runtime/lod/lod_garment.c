/* A garment that changes level while it runs (include/weft/lod.h).
 *
 * It owns one weft_garment of the current level. Every frame the state at t (positions and
 * collider) is copied into a small ring, sized at creation for the longest latent history of
 * the table's model levels. A switch creates the garment of the new level, replays the recorded
 * frames through the model's encoder/transformer so its latent window matches a model that had
 * run all along (the outputs of those replay steps are discarded), then installs x_t, x_{t-1},
 * the colliders and the pins. Without that the first step after a switch sees a window filled
 * with copies of one frame, and an inertial method without x_{t-1} would lose the velocity:
 * both show as a pop. */
#include "lod/lod_internal.h"
#include "garment/garment.h"
#include "model/model.h"

#include <string.h>

typedef struct lod_frame {
    uint64_t frame;                     /* absolute frame index; valid only when used */
    bool used;
    float *x;                           /* positions at that frame, vertex_count * 3 */
    float *c;                           /* collider at that frame, collider_vertex_count * 3 */
} lod_frame;

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
static weft_result make_garment(weft_lod_garment *lg, const weft_lod_level *lv, const float *rest,
                                const uint32_t *tris, uint32_t tri_count, const float *collider_rest,
                                const uint32_t *ctris, uint32_t ctri_count, const float *x0, weft_garment **out)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = lv->method;
    d.ccd = lv->ccd;
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
    d.rest_positions = rest;
    d.vertex_count = lg->N;
    d.triangles = tris;
    d.triangle_count = tri_count;
    d.collider_rest_positions = collider_rest;
    d.collider_vertex_count = lg->C;
    d.collider_triangles = ctris;
    d.collider_triangle_count = ctri_count;
    d.initial_positions = x0;
    return weft_garment_create(lg->ctx, &d, out);
}

static void free_lod(weft_lod_garment *lg)
{
    const weft_context *ctx = lg->ctx;
    weft_garment_destroy(lg->g);
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
    if (!def->rest_positions || def->vertex_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_create: rest_positions are required");
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
    bool ok = true;
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
    weft_result r = make_garment(lg, &def->table->levels[def->level], def->rest_positions, def->triangles,
                                 def->triangle_count, def->collider_rest_positions, def->collider_triangles,
                                 def->collider_triangle_count, def->initial_positions, &lg->g);
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
    memcpy(e->x, lg->g->x, (size_t)lg->N * 3 * sizeof(float));
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
    return weft_garment_set_pins(lg->g, vertex_indices, target_positions, count);
}

weft_result weft_lod_garment_set_state(weft_lod_garment *lg, const float *positions, const float *prev_positions)
{
    if (!lg) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_lod_garment_set_state: garment is NULL");
    }
    const uint64_t before = current_frame(lg);
    weft_result r = weft_garment_set_state(lg->g, positions, prev_positions);
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
    return weft_garment_step(lg->g);
}

/* Replays recorded frames k0..t-1 through ng's method so its latent window is what it would be
 * had it run them. Only the method's own history changes; ng's state is overwritten afterwards. */
static weft_result warm(const weft_lod_garment *lg, weft_garment *ng, uint32_t history)
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
        memcpy(ng->x, fk->x, nx);
        memcpy(ng->x_prev, fp->x, nx);
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
    const weft_method_ops *ops = weft__method_ops(lv->method);
    if (old->pin_count > 0 && ops && !ops->supports_pins) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED,
                          "weft_lod_garment_switch: level '%s' (method %s) cannot honour the %u pins in use; clear "
                          "them first",
                          lv->name, ops->name, old->pin_count);
    }
    /* LBS binds the garment to the collider at creation: bind to the pose of now, not the rest
     * pose, or the cloth would snap back to where it was designed. */
    const float *bind = lv->method == WEFT_METHOD_LBS && lg->C > 0 ? old->collider_prev : old->collider_rest;
    weft_garment *ng = NULL;
    weft_result r = make_garment(lg, lv, old->rest, old->triangles, old->triangle_count, bind, old->collider_triangles,
                                 old->collider_triangle_count, old->x, &ng);
    if (r != WEFT_OK) {
        return r;
    }
    if (lv->method == WEFT_METHOD_MODEL) {
        r = warm(lg, ng, model_history(ng->model));
        if (r != WEFT_OK) {
            weft_garment_destroy(ng);
            return r;
        }
    }
    const size_t nx = (size_t)lg->N * 3 * sizeof(float), nc = (size_t)lg->C * 3 * sizeof(float);
    memcpy(ng->x, old->x, nx);
    memcpy(ng->x_prev, old->x_prev, nx);
    if (lg->C > 0) {
        memcpy(ng->collider_prev, old->collider_prev, nc);
        if (old->collider_next_set) {
            memcpy(ng->collider_next, old->collider_next, nc);
            ng->collider_next_set = true;
        }
    }
    if (old->pin_count > 0) {
        memcpy(ng->pin_indices, old->pin_indices, (size_t)old->pin_count * sizeof(uint32_t));
        memcpy(ng->pin_targets, old->pin_targets, (size_t)old->pin_count * 3 * sizeof(float));
        ng->pin_count = old->pin_count;
    }
    lg->frame_base += old->stats.frame;
    ng->stats = (weft_step_stats){0};
    weft_garment_destroy(old);
    lg->g = ng;
    lg->level = level;
    return WEFT_OK;
}

uint32_t weft_lod_garment_level(const weft_lod_garment *lg) { return lg ? lg->level : 0; }

const float *weft_lod_garment_positions(const weft_lod_garment *lg) { return lg ? lg->g->x : NULL; }

uint32_t weft_lod_garment_vertex_count(const weft_lod_garment *lg) { return lg ? lg->N : 0; }

weft_garment *weft_lod_garment_current(weft_lod_garment *lg) { return lg ? lg->g : NULL; }
