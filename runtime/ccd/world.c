/* The CCD world: fixed cloth/collider topology, bounding-volume hierarchies over swept boxes
 * (layout built once, refitted per call), the five contact types, the iterative post-process,
 * the discrete intersection check and the App. G metrics. Every buffer is sized at creation. */
#include "ccd/ccd_internal.h"
#include "garment/garment.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LEAF_SIZE 4u
/* Node pairs pending in a traversal. Median splits bound the depth d by 33 for any 32-bit count;
 * depth-first order keeps at most about 4 d pairs pending, far below this. */
#define STACK_SIZE 512u

typedef struct box {
    float lo[3], hi[3];
} box;

typedef struct node {
    box b;
    uint32_t first; /* leaf: first slot; internal: left child (right child is first + 1) */
    uint32_t count; /* leaf: slot count; internal: 0 */
} node;

typedef struct tree {
    uint32_t prims, arity; /* arity: vertices per primitive (1, 2 or 3) */
    const uint32_t *verts; /* prims * arity vertex indices, NULL for vertex trees */
    uint32_t node_count;
    node *nodes;           /* capacity 2 * prims */
    uint32_t *order;       /* slot -> primitive */
    box *slot_box;         /* per slot, refreshed by refit */
    uint8_t *node_dirty;   /* per node: a primitive below has a dirty vertex (incremental passes) */
    uint8_t *slot_dirty;   /* per slot: the primitive has a dirty vertex */
    bool built;
} tree;

struct weft_ccd_world {
    weft_context *ctx;
    uint32_t nv, nt, ne;     /* cloth vertices, triangles, edges */
    uint32_t cv, ct, ce;     /* collider vertices, triangles, edges */
    uint32_t *tris, *ctris;
    /* Feature ownership: every vertex and every edge belongs to exactly one triangle (the first that
     * lists it). Bits 0-2: corner k is owned; bits 3-5: edge (k, k+1) is owned. A triangle pair then
     * yields each vertex–triangle and edge–edge pair exactly once, so one tree per mesh suffices. */
    uint8_t *own, *cown;
    tree cloth_t, col_t;
    box *vbox, *cbox;        /* per-vertex swept boxes */
    float *centroids;        /* build scratch: 3 * max primitive count */
    double eta, margin;
    uint32_t max_iterations, max_hits;
    uint64_t pair_budget;    /* triangle pairs one post-process may visit (0: no bound) */
    bool self;
    weft_ccd_hit *hits;
    uint32_t hits_stored;
    float *tmin;             /* per cloth vertex: smallest t_safe of this pass */
    uint8_t *flag_a, *flag_b;
    uint8_t *dirty, *next_dirty; /* per cloth vertex: re-test its pairs in the next pass */
    float *carry;                /* fallback: collider displacement a cloth vertex is carried by */
    uint8_t *carry_flag;
    uint8_t *leaving;            /* per cloth vertex: inside the collider at x0, its collider hits ignored */
    bool any_leaving;
    /* Body parts (weft__ccd_world_set_parts), NULL without: a collider pair counts only for the
     * cloth vertices whose mask holds the collider triangle's part. Not owned. */
    const uint32_t *part_mask, *ctri_bits;
    /* Per cloth vertex, NULL without (weft__ccd_world_set_self_exempt): cloth–cloth pairs of a
     * triangle with an exempt vertex are not tested. Not owned. */
    const uint8_t *self_exempt;
    float shift[3];              /* broad-phase frame: mean cloth displacement of the last full pass */
};

/* ---- allocation helpers ----------------------------------------------------------------- */

typedef struct alloc_list {
    void **ptr[40];
    size_t size[40];
    int n;
} alloc_list;

static void want(alloc_list *l, void *pptr, size_t size)
{
    l->ptr[l->n] = (void **)pptr;
    l->size[l->n] = size;
    l->n++;
}

/* ---- boxes and trees -------------------------------------------------------------------- */

static inline bool overlap(const box *a, const box *b)
{
    return a->lo[0] <= b->hi[0] && b->lo[0] <= a->hi[0] && a->lo[1] <= b->hi[1] && b->lo[1] <= a->hi[1] &&
           a->lo[2] <= b->hi[2] && b->lo[2] <= a->hi[2];
}

static inline float fmin2(float a, float b) { return a < b ? a : b; }
static inline float fmax2(float a, float b) { return a > b ? a : b; }

static inline void box_union(box *a, const box *b)
{
    for (int k = 0; k < 3; ++k) {
        a->lo[k] = fmin2(a->lo[k], b->lo[k]);
        a->hi[k] = fmax2(a->hi[k], b->hi[k]);
    }
}

/* Boxes of the paths x0 -> x1 - shift. Contact is invariant under a translation applied to every
 * vertex, so the broad phase may run in a frame moving with the cloth's mean displacement `shift`
 * (NULL: none), where neighbours that move together have small boxes. The relative margin covers
 * the float rounding of x1 - shift. */
static void vertex_boxes(box *out, const float *x0, const float *x1, uint32_t n, float pad, const float *shift)
{
    float sh[3] = {0.0f, 0.0f, 0.0f};
    if (shift) {
        sh[0] = shift[0], sh[1] = shift[1], sh[2] = shift[2];
    }
    for (uint32_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            float a = x0[3 * (size_t)i + k], b = x1[3 * (size_t)i + k] - sh[k];
            float m = pad + 2e-7f * (fabsf(b) + fabsf(sh[k]));
            out[i].lo[k] = fmin2(a, b) - m;
            out[i].hi[k] = fmax2(a, b) + m;
        }
    }
}

static inline void prim_box(const tree *t, uint32_t prim, const box *vb, box *out)
{
    if (t->arity == 1) {
        *out = vb[prim];
        return;
    }
    const uint32_t *v = t->verts + (size_t)prim * t->arity;
    *out = vb[v[0]];
    for (uint32_t k = 1; k < t->arity; ++k) {
        box_union(out, &vb[v[k]]);
    }
}

/* Quickselect: order[lo..hi) partitioned so that the element at mid has its sorted centroid rank. */
static void select_median(uint32_t *order, const float *cent, int axis, uint32_t lo, uint32_t hi, uint32_t mid)
{
    while (hi - lo > 1) {
        float pivot = cent[3 * (size_t)order[lo + (hi - lo) / 2] + axis];
        uint32_t i = lo, j = hi - 1;
        while (i <= j) {
            while (cent[3 * (size_t)order[i] + axis] < pivot) {
                i++;
            }
            while (cent[3 * (size_t)order[j] + axis] > pivot) {
                j--;
            }
            if (i <= j) {
                uint32_t tmp = order[i];
                order[i] = order[j];
                order[j] = tmp;
                i++;
                if (j == 0) {
                    break;
                }
                j--;
            }
        }
        if (mid <= j) {
            hi = j + 1;
        } else if (mid >= i) {
            lo = i;
        } else {
            return;
        }
    }
}

/* Top-down median split on the longest centroid axis. pos: vertex positions of the layout. */
static void tree_build(tree *t, const float *pos, float *cent)
{
    for (uint32_t p = 0; p < t->prims; ++p) {
        float c[3] = {0, 0, 0};
        for (uint32_t k = 0; k < t->arity; ++k) {
            uint32_t v = t->arity == 1 ? p : t->verts[(size_t)p * t->arity + k];
            for (int d = 0; d < 3; ++d) {
                c[d] += pos[3 * (size_t)v + d];
            }
        }
        for (int d = 0; d < 3; ++d) {
            cent[3 * (size_t)p + d] = c[d] / (float)t->arity;
        }
        t->order[p] = p;
    }
    t->node_count = 1;
    t->nodes[0].first = 0;
    t->nodes[0].count = t->prims;
    uint32_t stack[128];
    uint32_t sp = 0;
    stack[sp++] = 0;
    while (sp) {
        uint32_t ni = stack[--sp];
        uint32_t first = t->nodes[ni].first, count = t->nodes[ni].count;
        if (count <= LEAF_SIZE || sp + 2 > 128) {
            continue;
        }
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (uint32_t s = first; s < first + count; ++s) {
            const float *c = cent + 3 * (size_t)t->order[s];
            for (int d = 0; d < 3; ++d) {
                lo[d] = fminf(lo[d], c[d]);
                hi[d] = fmaxf(hi[d], c[d]);
            }
        }
        int axis = 0;
        for (int d = 1; d < 3; ++d) {
            if (hi[d] - lo[d] > hi[axis] - lo[axis]) {
                axis = d;
            }
        }
        uint32_t half = count / 2;
        if (hi[axis] > lo[axis]) {
            select_median(t->order, cent, axis, first, first + count, first + half);
        }
        uint32_t c = t->node_count;
        t->node_count += 2;
        t->nodes[c] = (node){.first = first, .count = half};
        t->nodes[c + 1] = (node){.first = first + half, .count = count - half};
        t->nodes[ni].first = c;
        t->nodes[ni].count = 0;
        stack[sp++] = c;
        stack[sp++] = c + 1;
    }
    t->built = true;
}

/* Children always come after their parent, so one reverse pass refits. */
static void tree_refit(tree *t, const box *vb)
{
    for (uint32_t s = 0; s < t->prims; ++s) {
        prim_box(t, t->order[s], vb, &t->slot_box[s]);
    }
    for (uint32_t i = t->node_count; i-- > 0;) {
        node *n = &t->nodes[i];
        if (n->count) {
            n->b = t->slot_box[n->first];
            for (uint32_t s = n->first + 1; s < n->first + n->count; ++s) {
                box_union(&n->b, &t->slot_box[s]);
            }
        } else {
            n->b = t->nodes[n->first].b;
            box_union(&n->b, &t->nodes[n->first + 1].b);
        }
    }
}

/* Marks the nodes above primitives that have a dirty vertex (children come after parents). */
static void tree_mark_dirty(tree *t, const uint8_t *vdirty)
{
    for (uint32_t i = t->node_count; i-- > 0;) {
        node *n = &t->nodes[i];
        uint8_t d = 0;
        if (n->count) {
            for (uint32_t s = n->first; s < n->first + n->count; ++s) {
                uint32_t p = t->order[s];
                uint8_t ds = 0;
                if (t->arity == 1) {
                    ds = vdirty[p];
                } else {
                    for (uint32_t k = 0; k < t->arity; ++k) {
                        ds |= vdirty[t->verts[(size_t)p * t->arity + k]];
                    }
                }
                t->slot_dirty[s] = ds;
                d |= ds;
            }
        } else {
            d = t->node_dirty[n->first] | t->node_dirty[n->first + 1];
        }
        t->node_dirty[i] = d;
    }
}

typedef void pair_fn(void *ctx, uint32_t a, uint32_t b);

static inline float box_extent(const box *b) { return (b->hi[0] - b->lo[0]) + (b->hi[1] - b->lo[1]) + (b->hi[2] - b->lo[2]); }

/* All primitive pairs (a from A, b from B) whose boxes overlap. With A == B each unordered pair of
 * distinct primitives is visited once. With filter, pairs where neither primitive has a dirty
 * vertex are skipped at every level (their narrow tests would all be skipped anyway). */
static void traverse(const tree *A, const tree *B, pair_fn *fn, void *ctx, bool filter, const bool *stop)
{
    if (A->prims == 0 || B->prims == 0) {
        return;
    }
    /* With filter, node pairs where neither side has a dirty primitive are skipped; trees without
     * dirty bits (the collider) never have any. */
    const uint8_t *da = A->node_dirty, *db = B->node_dirty, *sa = A->slot_dirty, *sb = B->slot_dirty;
    bool self = A == B;
    uint32_t stack[2 * STACK_SIZE];
    uint32_t sp = 0;
    stack[sp++] = 0;
    stack[sp++] = 0;
    while (sp && !(stop && *stop)) {
        uint32_t j = stack[--sp], i = stack[--sp];
        const node *na = &A->nodes[i], *nb = &B->nodes[j];
        if (filter && !da[i] && !db[j]) {
            continue;
        }
        if (self && i == j) {
            if (na->count) {
                for (uint32_t s = na->first; s < na->first + na->count; ++s) {
                    for (uint32_t r = s + 1; r < na->first + na->count; ++r) {
                        if (filter && !sa[s] && !sa[r]) {
                            continue;
                        }
                        if (overlap(&A->slot_box[s], &A->slot_box[r])) {
                            fn(ctx, A->order[s], A->order[r]);
                        }
                    }
                }
            } else if (sp + 6 <= 2 * STACK_SIZE) {
                uint32_t c = na->first;
                stack[sp++] = c;
                stack[sp++] = c;
                stack[sp++] = c + 1;
                stack[sp++] = c + 1;
                stack[sp++] = c;
                stack[sp++] = c + 1;
            }
            continue;
        }
        if (!overlap(&na->b, &nb->b)) {
            continue;
        }
        if (na->count && nb->count) {
            for (uint32_t s = na->first; s < na->first + na->count; ++s) {
                for (uint32_t r = nb->first; r < nb->first + nb->count; ++r) {
                    if (filter && !sa[s] && !sb[r]) {
                        continue;
                    }
                    if (overlap(&A->slot_box[s], &B->slot_box[r])) {
                        fn(ctx, A->order[s], B->order[r]);
                    }
                }
            }
            continue;
        }
        if (sp + 4 > 2 * STACK_SIZE) {
            continue; /* cannot happen with median splits (depth <= 32) */
        }
        bool down_a = nb->count || (!na->count && box_extent(&na->b) >= box_extent(&nb->b));
        if (down_a) {
            stack[sp++] = na->first;
            stack[sp++] = j;
            stack[sp++] = na->first + 1;
            stack[sp++] = j;
        } else {
            stack[sp++] = i;
            stack[sp++] = nb->first;
            stack[sp++] = i;
            stack[sp++] = nb->first + 1;
        }
    }
}

/* ---- creation ---------------------------------------------------------------------------- */

weft_ccd_world_def weft_default_ccd_world_def(void)
{
    weft_ccd_world_def def = {0};
    def.self_collision = true;
    def.min_separation = WEFT_CCD_DEFAULT_MIN_SEPARATION;
    def.time_margin = 0.05;
    def.max_iterations = 16;
    def.max_hits = 65536;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

typedef struct edge_key {
    uint64_t key;   /* (lo << 32) | hi */
    uint32_t where; /* 3 * triangle + k */
} edge_key;

static int cmp_edge(const void *a, const void *b)
{
    const edge_key *x = a, *y = b;
    if (x->key != y->key) {
        return x->key < y->key ? -1 : 1;
    }
    return x->where < y->where ? -1 : (x->where > y->where ? 1 : 0);
}

/* Ownership masks (see weft_ccd_world). Returns false when scratch memory is unavailable. */
static bool ownership(const weft_context *ctx, const uint32_t *tris, uint32_t nt, uint32_t nv, uint8_t *own,
                      uint32_t *edge_count)
{
    size_t n = (size_t)nt * 3;
    edge_key *keys = weft__alloc(ctx, n * sizeof *keys);
    uint8_t *seen = weft__alloc(ctx, nv);
    if (!keys || !seen) {
        weft__free(ctx, keys, n * sizeof *keys);
        weft__free(ctx, seen, nv);
        return false;
    }
    memset(own, 0, nt);
    for (uint32_t t = 0; t < nt; ++t) {
        for (int k = 0; k < 3; ++k) {
            uint32_t a = tris[3 * (size_t)t + k], b = tris[3 * (size_t)t + (k + 1) % 3];
            if (!seen[a]) {
                seen[a] = 1;
                own[t] |= (uint8_t)(1u << k);
            }
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            keys[3 * (size_t)t + k] = (edge_key){((uint64_t)lo << 32) | hi, 3 * t + (uint32_t)k};
        }
    }
    qsort(keys, n, sizeof *keys, cmp_edge);
    uint32_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        if (i == 0 || keys[i].key != keys[i - 1].key) {
            own[keys[i].where / 3] |= (uint8_t)(8u << (keys[i].where % 3));
            m++;
        }
    }
    *edge_count = m;
    weft__free(ctx, keys, n * sizeof *keys);
    weft__free(ctx, seen, nv);
    return true;
}

static weft_result check_tris(const char *what, const uint32_t *tris, uint32_t nt, uint32_t nv)
{
    for (uint32_t t = 0; t < nt; ++t) {
        const uint32_t *v = tris + 3 * (size_t)t;
        if (v[0] >= nv || v[1] >= nv || v[2] >= nv) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "weft_ccd_world_create: %s triangle %u has an index >= %u", what,
                              t, nv);
        }
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "weft_ccd_world_create: %s triangle %u repeats a vertex", what,
                              t);
        }
    }
    return WEFT_OK;
}

static void tree_setup(alloc_list *l, tree *t, uint32_t prims, uint32_t arity)
{
    t->prims = prims;
    t->arity = arity;
    if (prims == 0) {
        return;
    }
    want(l, &t->nodes, 2 * (size_t)prims * sizeof(node));
    want(l, &t->order, (size_t)prims * sizeof(uint32_t));
    want(l, &t->slot_box, (size_t)prims * sizeof(box));
    want(l, &t->node_dirty, 2 * (size_t)prims);
    want(l, &t->slot_dirty, (size_t)prims);
}

static void free_world(weft_ccd_world *w, alloc_list *l)
{
    for (int i = 0; i < l->n; ++i) {
        weft__free(w->ctx, *l->ptr[i], l->size[i]);
    }
    weft__free(w->ctx, w, sizeof *w);
}

static void world_allocs(weft_ccd_world *w, alloc_list *l)
{
    l->n = 0;
    want(l, &w->tris, (size_t)w->nt * 3 * sizeof(uint32_t));
    want(l, &w->own, (size_t)w->nt);
    want(l, &w->vbox, (size_t)w->nv * sizeof(box));
    want(l, &w->tmin, (size_t)w->nv * sizeof(float));
    want(l, &w->flag_a, (size_t)w->nv);
    want(l, &w->flag_b, (size_t)w->nv);
    want(l, &w->dirty, (size_t)w->nv);
    want(l, &w->next_dirty, (size_t)w->nv);
    want(l, &w->carry, (size_t)w->nv * 3 * sizeof(float));
    want(l, &w->carry_flag, (size_t)w->nv);
    want(l, &w->leaving, (size_t)w->nv);
    want(l, &w->hits, (size_t)(w->max_hits ? w->max_hits : 1) * sizeof(weft_ccd_hit));
    uint32_t maxp = w->nv;
    maxp = w->nt > maxp ? w->nt : maxp;
    maxp = w->ct > maxp ? w->ct : maxp;
    want(l, &w->centroids, (size_t)maxp * 3 * sizeof(float));
    tree_setup(l, &w->cloth_t, w->nt, 3);
    if (w->cv > 0) {
        want(l, &w->ctris, (size_t)w->ct * 3 * sizeof(uint32_t));
        want(l, &w->cown, (size_t)w->ct);
        want(l, &w->cbox, (size_t)w->cv * sizeof(box));
        tree_setup(l, &w->col_t, w->ct, 3);
    }
}

weft_result weft_ccd_world_create(weft_context *context, const weft_ccd_world_def *def, weft_ccd_world **out_world)
{
    if (!context || !def || !out_world) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_world_create: context, def and out_world are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_ccd_world_create: def was not initialised with weft_default_ccd_world_def()");
    }
    if (!def->cloth_triangles || def->cloth_triangle_count == 0 || def->cloth_vertex_count < 3) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_ccd_world_create: cloth_triangles (at least one) and cloth_vertex_count >= 3 are required");
    }
    if ((def->collider_vertex_count > 0) != (def->collider_triangle_count > 0) ||
        (def->collider_triangle_count > 0 && !def->collider_triangles)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_ccd_world_create: a collider needs both vertices and triangles (or neither)");
    }
    if (!(def->min_separation >= 0.0 && def->min_separation <= 1e3) || !(def->time_margin >= 0.0) ||
        !(def->time_margin <= 1.0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_ccd_world_create: min_separation must be in [0, 1000] metres, time_margin in [0, 1]");
    }
    if (def->max_iterations == 0 || def->max_iterations > 10000) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_world_create: max_iterations %u outside [1, 10000]",
                          def->max_iterations);
    }
    if (def->cloth_triangle_count > UINT32_MAX / 3 || def->collider_triangle_count > UINT32_MAX / 3) {
        return weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "weft_ccd_world_create: too many triangles");
    }
    weft_result r = check_tris("cloth", def->cloth_triangles, def->cloth_triangle_count, def->cloth_vertex_count);
    if (r == WEFT_OK && def->collider_triangle_count > 0) {
        r = check_tris("collider", def->collider_triangles, def->collider_triangle_count, def->collider_vertex_count);
    }
    if (r != WEFT_OK) {
        return r;
    }
    if ((def->cloth_layout_positions &&
         !weft__all_finite(def->cloth_layout_positions, (size_t)def->cloth_vertex_count * 3)) ||
        (def->collider_layout_positions && def->collider_vertex_count > 0 &&
         !weft__all_finite(def->collider_layout_positions, (size_t)def->collider_vertex_count * 3))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_ccd_world_create: layout positions contain NaN or infinity");
    }

    weft_ccd_world *w = weft__alloc(context, sizeof *w);
    if (!w) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    w->ctx = context;
    w->nv = def->cloth_vertex_count;
    w->nt = def->cloth_triangle_count;
    w->cv = def->collider_vertex_count;
    w->ct = def->collider_triangle_count;
    w->eta = def->min_separation > 0.0 ? def->min_separation : WEFT_CCD_DEFAULT_MIN_SEPARATION;
    w->margin = def->time_margin;
    w->max_iterations = def->max_iterations;
    w->max_hits = def->max_hits;
    w->pair_budget = def->max_pairs;
    w->self = def->self_collision;
    alloc_list l;
    world_allocs(w, &l);
    bool ok = true;
    for (int i = 0; i < l.n && ok; ++i) {
        *l.ptr[i] = weft__alloc(context, l.size[i]);
        ok = *l.ptr[i] != NULL;
    }
    if (!ok) {
        free_world(w, &l);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memset(w->leaving, 0, w->nv);
    w->any_leaving = false;
    memcpy(w->tris, def->cloth_triangles, (size_t)w->nt * 3 * sizeof(uint32_t));
    w->cloth_t.verts = w->tris;
    ok = ownership(context, w->tris, w->nt, w->nv, w->own, &w->ne);
    if (ok && w->cv > 0) {
        memcpy(w->ctris, def->collider_triangles, (size_t)w->ct * 3 * sizeof(uint32_t));
        w->col_t.verts = w->ctris;
        ok = ownership(context, w->ctris, w->ct, w->cv, w->cown, &w->ce);
    }
    if (!ok) {
        free_world(w, &l);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    if (def->cloth_layout_positions) {
        tree_build(&w->cloth_t, def->cloth_layout_positions, w->centroids);
    }
    if (w->cv > 0 && def->collider_layout_positions) {
        tree_build(&w->col_t, def->collider_layout_positions, w->centroids);
    }
    *out_world = w;
    return WEFT_OK;
}

void weft_ccd_world_destroy(weft_ccd_world *w)
{
    if (!w) {
        return;
    }
    alloc_list l;
    world_allocs(w, &l);
    free_world(w, &l);
}

/* ---- detection --------------------------------------------------------------------------- */

typedef struct detect_ctx detect_ctx;
typedef void hit_fn(detect_ctx *d, const weft_ccd_hit *hit);

struct detect_ctx {
    weft_ccd_world *w;
    const float *x0, *x1, *c0, *c1;
    weft_ccd_report rep;
    hit_fn *on_hit;
    bool filter; /* incremental pass: only pairs with a dirty cloth vertex */
    uint32_t types;
    uint64_t pairs, pair_limit; /* triangle pairs visited so far; the bound (0: none) */
    bool over;                  /* pairs reached pair_limit: the pass stopped early */
    ccd_narrow_stats ns;
};

static inline void load(double *dst, const float *a, const float *b, uint32_t v)
{
    dst[0] = a[3 * (size_t)v];
    dst[1] = a[3 * (size_t)v + 1];
    dst[2] = a[3 * (size_t)v + 2];
    dst[12] = b[3 * (size_t)v];
    dst[13] = b[3 * (size_t)v + 1];
    dst[14] = b[3 * (size_t)v + 2];
}

static void report_hit(detect_ctx *d, uint32_t type, const uint32_t v[4], double toi)
{
    d->rep.hits[type]++;
    d->rep.hit_total++;
    if (toi < d->rep.earliest_toi) {
        d->rep.earliest_toi = toi;
    }
    weft_ccd_hit h = {.type = type, .v = {v[0], v[1], v[2], v[3]}, .toi = toi};
    d->on_hit(d, &h);
}

/* Relative-motion box filter: the swept boxes of the broad phase include the motion both primitives
 * share, so neighbours moving together overlap. Along each axis the gap between A's and B's boxes
 * at t = 0 changes by at most the spread of their displacements, so the pair is separated for all t
 * when the gap at t = 0 exceeds that (plus a rounding margin). points: 8 xyz (t = 0, then t = 1),
 * the first na belong to A. */
static bool separated_in_relative_motion(const double *P, int na, double eta)
{
    for (int k = 0; k < 3; ++k) {
        double loA = INFINITY, hiA = -INFINITY, loB = INFINITY, hiB = -INFINITY;
        double dloA = INFINITY, dhiA = -INFINITY, dloB = INFINITY, dhiB = -INFINITY, mag = 0.0;
        for (int i = 0; i < 4; ++i) {
            double x = P[3 * i + k], dx = P[12 + 3 * i + k] - x;
            double ax = fabs(x) + fabs(P[12 + 3 * i + k]);
            mag = ax > mag ? ax : mag;
            if (i < na) {
                loA = x < loA ? x : loA;
                hiA = x > hiA ? x : hiA;
                dloA = dx < dloA ? dx : dloA;
                dhiA = dx > dhiA ? dx : dhiA;
            } else {
                loB = x < loB ? x : loB;
                hiB = x > hiB ? x : hiB;
                dloB = dx < dloB ? dx : dloB;
                dhiB = dx > dhiB ? dx : dhiB;
            }
        }
        double margin = eta + 1e-12 * mag;
        double gap = loB - hiA, drift = dloB - dhiA; /* B above A along k */
        if (gap > margin && gap + drift > margin) {
            return true;
        }
        gap = loA - hiB, drift = dloA - dhiB; /* A above B */
        if (gap > margin && gap + drift > margin) {
            return true;
        }
    }
    return false;
}

/* The four points: `first` vertices from mesh A (positions a0 -> a1), the rest from mesh B. */
static void narrow(detect_ctx *d, uint32_t type, const uint32_t v[4], int first, const float *a0, const float *a1,
                   const float *b0, const float *b1, bool vf)
{
    if (d->filter) {
        /* Cloth vertices of the pair: the first `first` for cloth-first types, the rest for FV. */
        const uint8_t *dirty = d->w->dirty;
        bool any = false;
        int lo = type == WEFT_CCD_FV ? 1 : 0, hi = type == WEFT_CCD_FV ? 4 : (type >= WEFT_CCD_SELF_VF ? 4 : first);
        for (int i = lo; i < hi; ++i) {
            any = any || dirty[v[i]];
        }
        if (!any) {
            return; /* unchanged trajectories: the last pass found this pair clean */
        }
    }
    double P[24];
    for (int i = 0; i < 4; ++i) {
        if (i < first) {
            load(P + 3 * i, a0, a1, v[i]);
        } else {
            load(P + 3 * i, b0, b1, v[i]);
        }
    }
    if (separated_in_relative_motion(P, type == WEFT_CCD_EE || type == WEFT_CCD_SELF_EE ? 2 : 1, d->w->eta)) {
        return;
    }
    d->rep.narrow_tests++;
    double toi;
    bool hit = vf ? ccd_vf(P, d->w->eta, &toi, &d->ns) : ccd_ee(P, d->w->eta, &toi, &d->ns);
    if (hit) {
        report_hit(d, type, v, toi);
    }
}

/* One more triangle pair; at the budget the traversal stops (d->over). */
static inline void count_pair(detect_ctx *d)
{
    ++d->pairs;
    d->over = d->pair_limit && d->pairs >= d->pair_limit;
}

static inline box tri_box(const uint32_t *t, const box *vb)
{
    box b = vb[t[0]];
    box_union(&b, &vb[t[1]]);
    box_union(&b, &vb[t[2]]);
    return b;
}

static inline bool has_vertex(const uint32_t *t, uint32_t v) { return t[0] == v || t[1] == v || t[2] == v; }

/* A cloth triangle pair with a vertex the caller exempts from the cloth-cloth test. */
static inline bool self_exempt(const weft_ccd_world *w, const uint32_t *a, const uint32_t *b)
{
    const uint8_t *e = w->self_exempt;
    return e && (e[a[0]] | e[a[1]] | e[a[2]] | e[b[0]] | e[b[1]] | e[b[2]]);
}

/* Cloth triangle ta against collider triangle tb: VF for the cloth corners ta owns, FV for the
 * collider corners tb owns, EE for the edges both own. */
static void pair_cloth_collider(void *ctx, uint32_t ta, uint32_t tb)
{
    detect_ctx *d = ctx;
    count_pair(d);
    const weft_ccd_world *w = d->w;
    const uint32_t *A = w->tris + 3 * (size_t)ta, *B = w->ctris + 3 * (size_t)tb;
    uint8_t ma = w->own[ta], mb = w->cown[tb];
    if (w->any_leaving) {
        /* Cloth that starts inside the collider is let out: any pair with one of its vertices is
         * skipped (an FV pair involves the whole triangle; VF and EE only the owned features). */
        const uint8_t *lv = w->leaving;
        if (lv[A[0]] | lv[A[1]] | lv[A[2]]) {
            for (int k = 0; k < 3; ++k) {
                if (lv[A[k]]) {
                    ma &= (uint8_t)~(1u << k);                 /* its corner */
                    ma &= (uint8_t)~(1u << (3 + k));           /* edge (k, k+1) */
                    ma &= (uint8_t)~(1u << (3 + (k + 2) % 3)); /* edge (k-1, k) */
                }
            }
            mb &= 0x38u; /* collider corners (FV) against this triangle: skipped; its edges stay */
        }
    }
    if (w->part_mask) {
        /* Cloth collides with the body parts it belongs to only: corners and edges of cloth
         * vertices whose mask lacks this triangle's part are skipped, and the collider's
         * corners against a cloth triangle none of whose vertices has it. */
        const uint32_t bits = w->ctri_bits[tb];
        const bool hit0 = w->part_mask[A[0]] & bits, hit1 = w->part_mask[A[1]] & bits, hit2 = w->part_mask[A[2]] & bits;
        if (!(hit0 | hit1 | hit2)) {
            return;
        }
        const bool hit[3] = {hit0, hit1, hit2};
        for (int k = 0; k < 3; ++k) {
            if (!hit[k]) {
                ma &= (uint8_t)~(1u << k);
                ma &= (uint8_t)~(1u << (3 + k));
                ma &= (uint8_t)~(1u << (3 + (k + 2) % 3));
            }
        }
    }
    if (d->types & WEFT_CCD_MASK(WEFT_CCD_VF)) {
        box bb = tri_box(B, w->cbox);
        for (int k = 0; k < 3; ++k) {
            if ((ma >> k & 1u) && overlap(&w->vbox[A[k]], &bb)) {
                uint32_t v[4] = {A[k], B[0], B[1], B[2]};
                narrow(d, WEFT_CCD_VF, v, 1, d->x0, d->x1, d->c0, d->c1, true);
            }
        }
    }
    if (d->types & WEFT_CCD_MASK(WEFT_CCD_FV)) {
        box ba = tri_box(A, w->vbox);
        for (int k = 0; k < 3; ++k) {
            if ((mb >> k & 1u) && overlap(&w->cbox[B[k]], &ba)) {
                uint32_t v[4] = {B[k], A[0], A[1], A[2]};
                narrow(d, WEFT_CCD_FV, v, 1, d->c0, d->c1, d->x0, d->x1, true);
            }
        }
    }
    if ((d->types & WEFT_CCD_MASK(WEFT_CCD_EE)) && (ma >> 3) && (mb >> 3)) {
        for (int i = 0; i < 3; ++i) {
            if (!(ma >> (3 + i) & 1u)) {
                continue;
            }
            uint32_t a0 = A[i], a1 = A[(i + 1) % 3];
            box ea = w->vbox[a0];
            box_union(&ea, &w->vbox[a1]);
            for (int j = 0; j < 3; ++j) {
                if (!(mb >> (3 + j) & 1u)) {
                    continue;
                }
                uint32_t b0 = B[j], b1 = B[(j + 1) % 3];
                box eb = w->cbox[b0];
                box_union(&eb, &w->cbox[b1]);
                if (overlap(&ea, &eb)) {
                    uint32_t v[4] = {a0 < a1 ? a0 : a1, a0 < a1 ? a1 : a0, b0 < b1 ? b0 : b1, b0 < b1 ? b1 : b0};
                    narrow(d, WEFT_CCD_EE, v, 2, d->x0, d->x1, d->c0, d->c1, false);
                }
            }
        }
    }
}

/* Two distinct cloth triangles: SELF_VF both ways for owned corners, SELF_EE for owned edges;
 * adjacent primitives (shared vertices) are skipped. */
static void pair_cloth_cloth(void *ctx, uint32_t ta, uint32_t tb)
{
    detect_ctx *d = ctx;
    count_pair(d);
    const weft_ccd_world *w = d->w;
    const uint32_t *T[2] = {w->tris + 3 * (size_t)ta, w->tris + 3 * (size_t)tb};
    if (self_exempt(w, T[0], T[1])) {
        return;
    }
    uint8_t m[2] = {w->own[ta], w->own[tb]};
    if (d->types & WEFT_CCD_MASK(WEFT_CCD_SELF_VF)) {
        for (int side = 0; side < 2; ++side) {
            const uint32_t *P = T[side], *F = T[1 - side];
            if (!(m[side] & 7u)) {
                continue;
            }
            box bf = tri_box(F, w->vbox);
            for (int k = 0; k < 3; ++k) {
                if ((m[side] >> k & 1u) && !has_vertex(F, P[k]) && overlap(&w->vbox[P[k]], &bf)) {
                    uint32_t v[4] = {P[k], F[0], F[1], F[2]};
                    narrow(d, WEFT_CCD_SELF_VF, v, 4, d->x0, d->x1, d->x0, d->x1, true);
                }
            }
        }
    }
    if ((d->types & WEFT_CCD_MASK(WEFT_CCD_SELF_EE)) && (m[0] >> 3) && (m[1] >> 3)) {
        const uint32_t *A = T[0], *B = T[1];
        for (int i = 0; i < 3; ++i) {
            if (!(m[0] >> (3 + i) & 1u)) {
                continue;
            }
            uint32_t a0 = A[i], a1 = A[(i + 1) % 3];
            box ea = w->vbox[a0];
            box_union(&ea, &w->vbox[a1]);
            for (int j = 0; j < 3; ++j) {
                if (!(m[1] >> (3 + j) & 1u)) {
                    continue;
                }
                uint32_t b0 = B[j], b1 = B[(j + 1) % 3];
                if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1) {
                    continue;
                }
                box eb = w->vbox[b0];
                box_union(&eb, &w->vbox[b1]);
                if (overlap(&ea, &eb)) {
                    uint32_t v[4] = {a0 < a1 ? a0 : a1, a0 < a1 ? a1 : a0, b0 < b1 ? b0 : b1, b0 < b1 ? b1 : b0};
                    narrow(d, WEFT_CCD_SELF_EE, v, 4, d->x0, d->x1, d->x0, d->x1, false);
                }
            }
        }
    }
}

/* Builds missing layouts and refits the trees `types` needs. An incremental pass keeps the shift
 * and the collider boxes (the collider has not changed) and refits only the cloth. */
static void prepare(weft_ccd_world *w, const float *x0, const float *x1, const float *c0, const float *c1,
                    uint32_t types, bool incremental)
{
    float pad = (float)(0.5 * w->eta);
    if (!w->cloth_t.built) {
        tree_build(&w->cloth_t, x0, w->centroids);
    }
    if (!incremental) {
        double sum[3] = {0.0, 0.0, 0.0};
        for (uint32_t i = 0; i < w->nv; ++i) {
            for (int k = 0; k < 3; ++k) {
                sum[k] += (double)x1[3 * (size_t)i + k] - (double)x0[3 * (size_t)i + k];
            }
        }
        for (int k = 0; k < 3; ++k) {
            double m = sum[k] / (double)w->nv;
            w->shift[k] = fabs(m) < 1e30 ? (float)m : 0.0f; /* out of float range: no shift */
        }
    }
    vertex_boxes(w->vbox, x0, x1, w->nv, pad, w->shift);
    bool col = w->cv > 0 && (types & WEFT_CCD_MASK_COLLIDER) && c0 && c1 && !incremental;
    if (col) {
        if (!w->col_t.built) {
            tree_build(&w->col_t, c0, w->centroids);
        }
        vertex_boxes(w->cbox, c0, c1, w->cv, pad, w->shift);
    }
    tree_refit(&w->cloth_t, w->vbox);
    if (col) {
        tree_refit(&w->col_t, w->cbox);
    }
}

/* One detection pass. Incremental passes (d->filter) test only pairs with a dirty vertex. */
static void run_detect(weft_ccd_world *w, detect_ctx *d, uint32_t types)
{
    memset(&d->rep, 0, sizeof d->rep);
    d->rep.earliest_toi = 1.0;
    prepare(w, d->x0, d->x1, d->c0, d->c1, types, d->filter);
    if (d->filter) {
        tree_mark_dirty(&w->cloth_t, w->dirty);
    }
    d->types = types;
    bool f = d->filter;
    bool col = w->cv > 0 && d->c0 && d->c1;
    if (col && (types & WEFT_CCD_MASK_COLLIDER)) {
        traverse(&w->cloth_t, &w->col_t, pair_cloth_collider, d, f, &d->over);
    }
    if (types & WEFT_CCD_MASK_SELF) {
        traverse(&w->cloth_t, &w->cloth_t, pair_cloth_cloth, d, f, &d->over);
    }
}

static weft_result check_frames(const weft_ccd_world *w, const char *fn, const float *x0, const float *x1,
                                const float *c0, const float *c1, bool need_collider)
{
    if (!x0 || !x1) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: cloth positions are required", fn);
    }
    if (need_collider && w->cv > 0 && (!c0 || !c1)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: the world has a collider: its positions are required", fn);
    }
    size_t n = (size_t)w->nv * 3;
    if (!weft__all_finite(x0, n) || !weft__all_finite(x1, n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: cloth positions contain NaN or infinity", fn);
    }
    if (w->cv > 0 && c0 && c1 &&
        (!weft__all_finite(c0, (size_t)w->cv * 3) || !weft__all_finite(c1, (size_t)w->cv * 3))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: collider positions contain NaN or infinity", fn);
    }
    return WEFT_OK;
}

static void store_hit(detect_ctx *d, const weft_ccd_hit *h)
{
    weft_ccd_world *w = d->w;
    if (w->hits_stored < w->max_hits) {
        w->hits[w->hits_stored++] = *h;
    }
}

weft_result weft_ccd_detect(weft_ccd_world *w, const float *x0, const float *x1, const float *c0, const float *c1,
                            uint32_t types, weft_ccd_report *report)
{
    if (!w) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_detect: world is NULL");
    }
    if (types & ~(uint32_t)WEFT_CCD_MASK_ALL) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_detect: types 0x%x has unknown bits", types);
    }
    weft_result r = check_frames(w, "weft_ccd_detect", x0, x1, c0, c1, (types & WEFT_CCD_MASK_COLLIDER) != 0);
    if (r != WEFT_OK) {
        return r;
    }
    detect_ctx d = {.w = w, .x0 = x0, .x1 = x1, .c0 = c0, .c1 = c1, .on_hit = store_hit};
    w->hits_stored = 0;
    run_detect(w, &d, types);
    d.rep.hits_stored = w->hits_stored;
    if (report) {
        *report = d.rep;
    }
    return WEFT_OK;
}

weft_result weft_ccd_world_let_out(weft_ccd_world *w, const uint8_t *inside)
{
    if (!w) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_world_let_out: world is NULL");
    }
    w->any_leaving = false;
    for (uint32_t v = 0; v < w->nv; ++v) {
        w->leaving[v] = inside && inside[v] ? 1 : 0;
        w->any_leaving = w->any_leaving || w->leaving[v];
    }
    return WEFT_OK;
}

void weft__ccd_world_set_self_exempt(weft_ccd_world *w, const uint8_t *exempt) { w->self_exempt = exempt; }

void weft__ccd_world_set_parts(weft_ccd_world *w, const uint32_t *cloth_masks, const uint32_t *collider_tri_bits)
{
    w->part_mask = cloth_masks && collider_tri_bits ? cloth_masks : NULL;
    w->ctri_bits = w->part_mask ? collider_tri_bits : NULL;
}

const weft_ccd_hit *weft_ccd_hits(const weft_ccd_world *w, uint32_t *count)
{
    if (count) {
        *count = w ? w->hits_stored : 0;
    }
    return w ? w->hits : NULL;
}

/* ---- post-process ------------------------------------------------------------------------ */

/* Cloth vertices of a hit (collider vertices are kinematic and never moved). */
static int cloth_vertices(const weft_ccd_hit *h, uint32_t out[4])
{
    switch (h->type) {
    case WEFT_CCD_VF:
        out[0] = h->v[0];
        return 1;
    case WEFT_CCD_EE:
        out[0] = h->v[0];
        out[1] = h->v[1];
        return 2;
    case WEFT_CCD_FV:
        out[0] = h->v[1];
        out[1] = h->v[2];
        out[2] = h->v[3];
        return 3;
    default:
        for (int i = 0; i < 4; ++i) {
            out[i] = h->v[i];
        }
        return 4;
    }
}

static void min_tsafe(detect_ctx *d, const weft_ccd_hit *h)
{
    uint32_t v[4];
    int n = cloth_vertices(h, v);
    double ts = h->toi - d->w->margin;
    float tsf = ts > 0.0 ? (float)ts : 0.0f;
    for (int i = 0; i < n; ++i) {
        if (tsf < d->w->tmin[v[i]]) {
            d->w->tmin[v[i]] = tsf;
        }
        d->w->next_dirty[v[i]] = 1;
    }
}

static void mark_a(detect_ctx *d, const weft_ccd_hit *h)
{
    uint32_t v[4];
    int n = cloth_vertices(h, v);
    for (int i = 0; i < n; ++i) {
        d->w->flag_a[v[i]] = 1;
        d->w->next_dirty[v[i]] = 1;
    }
}

/* Fallback marking: cloth vertices of collider hits are carried by the mean displacement of the
 * collider vertices of the hit (so they keep their place relative to the collider); cloth vertices
 * of self hits only are held. */
static void mark_fallback(detect_ctx *d, const weft_ccd_hit *h)
{
    weft_ccd_world *w = d->w;
    uint32_t v[4];
    int n = cloth_vertices(h, v);
    float disp[3] = {0.0f, 0.0f, 0.0f};
    bool col = h->type == WEFT_CCD_VF || h->type == WEFT_CCD_EE || h->type == WEFT_CCD_FV;
    if (col) {
        int first = h->type == WEFT_CCD_VF ? 1 : (h->type == WEFT_CCD_EE ? 2 : 0);
        int last = h->type == WEFT_CCD_FV ? 1 : 4;
        for (int i = first; i < last; ++i) {
            for (int k = 0; k < 3; ++k) {
                size_t j = 3 * (size_t)h->v[i] + k;
                disp[k] += (d->c1[j] - d->c0[j]) / (float)(last - first);
            }
        }
    }
    for (int i = 0; i < n; ++i) {
        w->flag_a[v[i]] = 1;
        w->next_dirty[v[i]] = 1;
        if (col) {
            memcpy(w->carry + 3 * (size_t)v[i], disp, sizeof disp);
            w->carry_flag[v[i]] = 1;
        }
    }
}

/* The vertices of this pass's hits are the ones whose pairs the next pass re-tests. */
static void promote_dirty(weft_ccd_world *w)
{
    memcpy(w->dirty, w->next_dirty, w->nv);
    memset(w->next_dirty, 0, w->nv);
}

/* Over the pair budget, or out of fallback rounds: every cloth vertex back at x0 (the cloth does not
 * move this step), then one detection with a fresh allowance of the budget. A cloth at rest at
 * an intersection-free x0 has no self hits; only the collider's own motion can still hit it.
 * Returns the hits left (1 when even that pass ran out of budget). */
static uint32_t hold_all(weft_ccd_world *w, detect_ctx *d, const float *x0, float *x1, uint32_t types,
                         weft_ccd_postprocess_stats *st)
{
    for (uint32_t v = 0; v < w->nv; ++v) {
        float *b = x1 + 3 * (size_t)v;
        const float *a = x0 + 3 * (size_t)v;
        if (b[0] != a[0] || b[1] != a[1] || b[2] != a[2]) {
            memcpy(b, a, 3 * sizeof(float));
            w->flag_b[v] = 1;
            st->vertices_held++;
        }
    }
    st->fallback = true;
    st->held_all = true;
    d->on_hit = mark_a;
    d->filter = false;
    st->pairs_visited += d->pairs;
    d->pairs = 0;
    d->over = false;
    memset(w->flag_a, 0, w->nv);
    run_detect(w, d, types);
    st->iterations++;
    st->pairs_visited += d->pairs;
    d->pairs = 0;
    return d->over ? (d->rep.hit_total ? d->rep.hit_total : 1u) : d->rep.hit_total;
}

weft_result weft_ccd_postprocess(weft_ccd_world *w, const float *x0, float *x1, const float *c0, const float *c1,
                                 weft_ccd_postprocess_stats *stats)
{
    if (!w) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_postprocess: world is NULL");
    }
    weft_result r = check_frames(w, "weft_ccd_postprocess", x0, x1, c0, c1, true);
    if (r != WEFT_OK) {
        return r;
    }
    uint32_t types = WEFT_CCD_MASK_COLLIDER | (w->self ? WEFT_CCD_MASK_SELF : 0u);
    weft_ccd_postprocess_stats st = {0};
    detect_ctx d = {.w = w, .x0 = x0, .x1 = x1, .c0 = c0, .c1 = c1, .on_hit = min_tsafe,
                    .pair_limit = w->pair_budget};
    memset(w->flag_b, 0, w->nv); /* moved */
    memset(w->next_dirty, 0, w->nv);
    /* Every pass draws on one allowance of pair_budget triangle pairs; a pass that exhausts it
     * stops, and hold_all ends the step: the work of a step is bounded whatever the motion. */
    bool clean = false, over = false;
    /* Pass 1 tests every pair. Later passes re-test only pairs with a vertex from the previous
     * pass's hits: every other pair has the same trajectories as when it was last found clean. */
    for (uint32_t it = 0; it < w->max_iterations; ++it) {
        for (uint32_t v = 0; v < w->nv; ++v) {
            w->tmin[v] = 1.0f;
        }
        d.filter = it > 0;
        run_detect(w, &d, types);
        st.iterations++;
        if (d.over) {
            over = true;
            break;
        }
        if (d.rep.hit_total == 0) {
            clean = true;
            break;
        }
        uint32_t changed = 0;
        for (uint32_t v = 0; v < w->nv; ++v) {
            float s = w->tmin[v];
            if (s < 1.0f) {
                for (int k = 0; k < 3; ++k) {
                    size_t i = 3 * (size_t)v + k;
                    float moved = x0[i] + s * (x1[i] - x0[i]);
                    changed += moved != x1[i];
                    w->flag_b[v] |= moved != x1[i];
                    x1[i] = moved;
                }
            }
        }
        promote_dirty(w);
        if (changed == 0) {
            /* Every hit vertex is already back at its start: the next pass would find the same
             * hits and move nothing again (a collider moving into cloth at rest), so the passes
             * left could only repeat this one. The fallback below resolves these. */
            break;
        }
    }
    if (!clean && !over && w->cv > 0 && c0 && c1) {
        /* Fallback, stage 1: vertices hit by the collider move with it (x0 + its displacement),
         * vertices in self hits only stay at x0. A collider pushing cloth it reached is resolved
         * here; the final clean pass still certifies the result. */
        st.fallback = true;
        d.on_hit = mark_fallback;
        d.filter = true;
        for (uint32_t round = 0; round < w->max_iterations && !clean; ++round) {
            memset(w->flag_a, 0, w->nv);
            memset(w->carry_flag, 0, w->nv);
            run_detect(w, &d, types);
            st.iterations++;
            if (d.over) {
                over = true;
                break;
            }
            if (d.rep.hit_total == 0) {
                clean = true;
                break;
            }
            uint32_t newly = 0;
            for (uint32_t v = 0; v < w->nv; ++v) {
                if (!w->flag_a[v]) {
                    continue;
                }
                const float *a = x0 + 3 * (size_t)v;
                const float *cd = w->carry + 3 * (size_t)v;
                float *b = x1 + 3 * (size_t)v;
                float target[3] = {a[0], a[1], a[2]};
                if (w->carry_flag[v]) {
                    target[0] += cd[0], target[1] += cd[1], target[2] += cd[2];
                }
                if (b[0] != target[0] || b[1] != target[1] || b[2] != target[2]) {
                    memcpy(b, target, sizeof target);
                    w->flag_b[v] = 1;
                    st.vertices_carried += w->carry_flag[v];
                    st.vertices_held += !w->carry_flag[v];
                    newly++;
                }
            }
            promote_dirty(w);
            if (newly == 0) {
                break;
            }
        }
    }
    if (!clean && !over) {
        /* Fallback, stage 2: hold the vertices of the remaining hits at their start positions,
         * for at most max_iterations rounds (each holds at least one more vertex or stops); the
         * hits that survive are those the collider's own motion causes, which cloth motion alone
         * cannot undo. Out of rounds, hold_all below. */
        st.fallback = true;
        d.on_hit = mark_a;
        d.filter = true;
        bool settled = false;
        for (uint32_t round = 0; round < w->max_iterations; ++round) {
            memset(w->flag_a, 0, w->nv);
            run_detect(w, &d, types);
            st.iterations++;
            if (d.over) {
                over = true;
                break;
            }
            if (d.rep.hit_total == 0) {
                settled = true;
                break;
            }
            uint32_t newly = 0;
            for (uint32_t v = 0; v < w->nv; ++v) {
                if (!w->flag_a[v]) {
                    continue;
                }
                const float *a = x0 + 3 * (size_t)v;
                float *b = x1 + 3 * (size_t)v;
                if (b[0] != a[0] || b[1] != a[1] || b[2] != a[2]) {
                    b[0] = a[0];
                    b[1] = a[1];
                    b[2] = a[2];
                    w->flag_b[v] = 1;
                    st.vertices_held++;
                    newly++;
                }
            }
            promote_dirty(w);
            if (newly == 0) {
                st.unresolved_hits = d.rep.hit_total;
                settled = true;
                break;
            }
        }
        if (!settled && !over) {
            st.unresolved_hits = hold_all(w, &d, x0, x1, types, &st);
        }
    }
    if (over) {
        st.over_budget = true;
        st.unresolved_hits = hold_all(w, &d, x0, x1, types, &st);
    }
    st.pairs_visited += d.pairs; /* hold_all counted its own and the passes' before it */
    for (uint32_t v = 0; v < w->nv; ++v) {
        st.vertices_moved += w->flag_b[v];
    }
    if (stats) {
        *stats = st;
    }
    if (st.unresolved_hits) {
        return weft__fail(WEFT_ERROR_NOT_CONVERGED,
                          "weft_ccd_postprocess: %u hits remain after holding cloth vertices (collider motion)",
                          st.unresolved_hits);
    }
    return WEFT_OK;
}

/* ---- discrete intersections ---------------------------------------------------------------- */

typedef struct isect_ctx {
    const weft_ccd_world *w;
    const float *x, *c;
    uint32_t count;
    uint8_t *mark; /* weft__ccd_intersect_mark: every pair, exempt or not; their corners marked */
} isect_ctx;

static void load_tri(double out[9], const float *pos, const uint32_t *t)
{
    for (int k = 0; k < 3; ++k) {
        for (int d = 0; d < 3; ++d) {
            out[3 * k + d] = pos[3 * (size_t)t[k] + d];
        }
    }
}

static void pair_isect_self(void *ctx, uint32_t ta, uint32_t tb)
{
    isect_ctx *ic = ctx;
    const uint32_t *a = ic->w->tris + 3 * (size_t)ta, *b = ic->w->tris + 3 * (size_t)tb;
    if (!ic->mark && self_exempt(ic->w, a, b)) {
        return;
    }
    int shared = 0, sa = -1, sb = -1;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            if (a[i] == b[j]) {
                shared++;
                sa = i;
                sb = j;
            }
        }
    }
    if (shared >= 2) {
        return; /* neighbours across an edge always touch there */
    }
    double A[9], B[9];
    load_tri(A, ic->x, a);
    load_tri(B, ic->x, b);
    bool hit;
    if (shared == 1) {
        /* Sharing one corner: they intersect elsewhere iff the edge opposite the shared corner of one
         * meets the other triangle (collinear "triangles" act as segments). */
        const double *oa0 = A + 3 * ((sa + 1) % 3), *oa1 = A + 3 * ((sa + 2) % 3);
        const double *ob0 = B + 3 * ((sb + 1) % 3), *ob1 = B + 3 * ((sb + 2) % 3);
        hit = ccd_tri_tri(oa0, oa1, oa1, B, B + 3, B + 6) || ccd_tri_tri(ob0, ob1, ob1, A, A + 3, A + 6);
    } else {
        hit = ccd_tri_tri(A, A + 3, A + 6, B, B + 3, B + 6);
    }
    ic->count += hit;
    if (hit && ic->mark) {
        for (int k = 0; k < 3; ++k) {
            ic->mark[a[k]] = ic->mark[b[k]] = 1;
        }
    }
}

static void pair_isect_col(void *ctx, uint32_t ta, uint32_t tb)
{
    isect_ctx *ic = ctx;
    double A[9], B[9];
    const uint32_t *a = ic->w->tris + 3 * (size_t)ta;
    if (ic->w->part_mask && !((ic->w->part_mask[a[0]] & ic->w->part_mask[a[1]] & ic->w->part_mask[a[2]]) &
                              ic->w->ctri_bits[tb])) {
        return; /* body parts: a corner does not collide with this triangle's part (as the sweeps'
                 * edge-edge pairs, which need both ends of a cloth edge) */
    }
    load_tri(A, ic->x, a);
    load_tri(B, ic->c, ic->w->ctris + 3 * (size_t)tb);
    ic->count += ccd_tri_tri(A, A + 3, A + 6, B, B + 3, B + 6);
}

/* The cloth's tree at ic->x, then its triangle pairs against each other: the intersecting count. */
static uint32_t cloth_self_isect(weft_ccd_world *w, isect_ctx *ic)
{
    if (!w->cloth_t.built) {
        tree_build(&w->cloth_t, ic->x, w->centroids);
    }
    vertex_boxes(w->vbox, ic->x, ic->x, w->nv, 0.0f, NULL);
    tree_refit(&w->cloth_t, w->vbox);
    ic->count = 0;
    traverse(&w->cloth_t, &w->cloth_t, pair_isect_self, ic, false, NULL);
    return ic->count;
}

weft_result weft_ccd_intersect_frame(weft_ccd_world *w, const float *x, const float *c, weft_ccd_intersections *out)
{
    if (!w || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_intersect_frame: world and out are required");
    }
    weft_result r = check_frames(w, "weft_ccd_intersect_frame", x, x, c, c, true);
    if (r != WEFT_OK) {
        return r;
    }
    isect_ctx ic = {.w = w, .x = x, .c = c};
    out->cloth_cloth = cloth_self_isect(w, &ic);
    out->cloth_collider = 0;
    if (w->cv > 0) {
        if (!w->col_t.built) {
            tree_build(&w->col_t, c, w->centroids);
        }
        vertex_boxes(w->cbox, c, c, w->cv, 0.0f, NULL);
        tree_refit(&w->col_t, w->cbox);
        ic.count = 0;
        traverse(&w->cloth_t, &w->col_t, pair_isect_col, &ic, false, NULL);
        out->cloth_collider = ic.count;
    }
    return WEFT_OK;
}

uint32_t weft__ccd_intersect_mark(weft_ccd_world *w, const float *x, uint8_t *mark)
{
    isect_ctx ic = {.w = w, .x = x, .mark = mark};
    return cloth_self_isect(w, &ic);
}

/* ---- metrics ------------------------------------------------------------------------------- */

/* Whether the segment p + t dir, t in [0, reach], can touch box b (slab test). The box is grown
 * by a micrometre plus a relative 1e-6 so rounding never drops a triangle the exact crossing test
 * would count: the traversal may only visit more, never fewer. */
static bool segment_meets_box(const double p[3], const double dir[3], double reach, const box *b)
{
    double t0 = 0.0, t1 = reach;
    for (int k = 0; k < 3; ++k) {
        double lo = b->lo[k], hi = b->hi[k];
        double grow = 1e-6 + 1e-6 * (fabs(lo) + fabs(hi));
        lo -= grow;
        hi += grow;
        if (dir[k] == 0.0) {
            if (p[k] < lo || p[k] > hi) {
                return false;
            }
            continue;
        }
        double inv = 1.0 / dir[k];
        double ta = (lo - p[k]) * inv, tb = (hi - p[k]) * inv;
        if (ta > tb) {
            double tmp = ta;
            ta = tb;
            tb = tmp;
        }
        t0 = ta > t0 ? ta : t0;
        t1 = tb < t1 ? tb : t1;
        if (t0 > t1) {
            return false;
        }
    }
    return true;
}

/* Ray parity against the collider triangles at c (boxes of that frame already in col_t): 1 inside,
 * 0 outside, -1 when the segment p -> p + reach dir grazes an edge, a vertex or starts on the
 * surface (try another direction). The traversal follows
 * the segment through the tree (slab tests), not its bounding box: a long diagonal segment's box
 * covers most of the body and made this test visit nearly every triangle per vertex. */
static int ray_parity(const weft_ccd_world *w, const float *c, const double p[3], const double dir[3], double reach)
{
    const double q[3] = {p[0] + reach * dir[0], p[1] + reach * dir[1], p[2] + reach * dir[2]};
    const tree *t = &w->col_t;
    uint32_t stack[128];
    uint32_t sp = 0;
    stack[sp++] = 0;
    int crossings = 0;
    while (sp) {
        const node *n = &t->nodes[stack[--sp]];
        if (!segment_meets_box(p, dir, reach, &n->b)) {
            continue;
        }
        if (n->count) {
            for (uint32_t s = n->first; s < n->first + n->count; ++s) {
                if (!segment_meets_box(p, dir, reach, &t->slot_box[s])) {
                    continue;
                }
                double T[9];
                load_tri(T, c, w->ctris + 3 * (size_t)t->order[s]);
                int x = ccd_segment_crosses_triangle_strict(p, q, T, T + 3, T + 6);
                if (x < 0) {
                    return -1;
                }
                crossings += x;
            }
        } else if (sp + 2 <= 128) {
            stack[sp++] = n->first;
            stack[sp++] = n->first + 1;
        }
    }
    return crossings & 1;
}

weft_result weft_ccd_compute_metrics(weft_ccd_world *w, const float *x0, const float *x1, const float *c0,
                                     const float *c1, weft_ccd_metrics *out)
{
    if (!w || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_ccd_compute_metrics: world and out are required");
    }
    weft_result r = check_frames(w, "weft_ccd_compute_metrics", x0, x1, c0, c1, true);
    if (r != WEFT_OK) {
        return r;
    }
    weft_ccd_metrics m = {0};
    detect_ctx d = {.w = w, .x0 = x0, .x1 = x1, .c0 = c0, .c1 = c1, .on_hit = mark_a};
    memset(w->flag_a, 0, w->nv);
    run_detect(w, &d, WEFT_CCD_MASK_SELF);
    for (uint32_t v = 0; v < w->nv; ++v) {
        m.vertices_self += w->flag_a[v];
    }
    if (w->cv > 0) {
        memset(w->flag_a, 0, w->nv);
        run_detect(w, &d, WEFT_CCD_MASK_COLLIDER);
        /* Inside test at t = 1 against the collider's frame-1 boxes. */
        vertex_boxes(w->cbox, c1, c1, w->cv, 0.0f, NULL);
        tree_refit(&w->col_t, w->cbox);
        const box *root = &w->col_t.nodes[0].b;
        double ext = 0.0;
        for (int k = 0; k < 3; ++k) {
            ext += (double)root->hi[k] - (double)root->lo[k];
        }
        static const double dirs[6][3] = {{0.9271, 0.2873, 0.2406},  {-0.3161, 0.9173, 0.2420},
                                          {0.1903, -0.3413, 0.9205}, {-0.8813, -0.3797, 0.2812},
                                          {0.2519, 0.2143, -0.9437}, {0.5711, -0.7891, -0.2261}};
        for (uint32_t v = 0; v < w->nv; ++v) {
            double p[3] = {x1[3 * (size_t)v], x1[3 * (size_t)v + 1], x1[3 * (size_t)v + 2]};
            bool in_box = true;
            for (int k = 0; k < 3; ++k) {
                in_box = in_box && p[k] >= root->lo[k] && p[k] <= root->hi[k];
            }
            if (!in_box) {
                continue;
            }
            for (int k = 0; k < 6; ++k) {
                int par = ray_parity(w, c1, p, dirs[k], 2.0 * ext + 1.0);
                if (par >= 0) {
                    if (par == 1) {
                        m.vertices_inside++;
                        w->flag_a[v] = 1;
                    }
                    break;
                }
            }
        }
        for (uint32_t v = 0; v < w->nv; ++v) {
            m.vertices_penetrating += w->flag_a[v];
        }
    }
    m.collision_rate = 100.0 * (double)m.vertices_penetrating / (double)w->nv;
    m.self_collision_rate = 100.0 * (double)m.vertices_self / (double)w->nv;
    *out = m;
    return WEFT_OK;
}

/* ---- garment hook ------------------------------------------------------------------------- */

weft_result weft__ccd_garment_create(weft_garment *g)
{
    g->ccd_state = NULL;
    if (!g->ccd) {
        return WEFT_OK;
    }
    weft_ccd_world_def def = weft_default_ccd_world_def();
    def.cloth_triangles = g->triangles;
    def.cloth_triangle_count = g->triangle_count;
    def.cloth_vertex_count = g->vertex_count;
    def.cloth_layout_positions = g->rest;
    if (g->collider_vertex_count > 0) {
        def.collider_triangles = g->collider_triangles;
        def.collider_triangle_count = g->collider_triangle_count;
        def.collider_vertex_count = g->collider_vertex_count;
        def.collider_layout_positions = g->collider_rest;
    }
    def.max_hits = 1;
    def.max_iterations = g->ccd_iterations;
    def.max_pairs = (uint64_t)WEFT_CCD_PAIRS_PER_TRIANGLE * g->triangle_count + WEFT_CCD_PAIRS_FLOOR;
    weft_ccd_world *w = NULL;
    weft_result r = weft_ccd_world_create(g->ctx, &def, &w);
    if (r != WEFT_OK) {
        return r;
    }
    weft__ccd_world_set_parts(w, g->part_mask, g->ctri_bits);
    g->ccd_input = weft__alloc(g->ctx, (size_t)g->vertex_count * 3 * sizeof(float));
    if (!g->ccd_input) {
        weft_ccd_world_destroy(w);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    g->ccd_state = w;
    return WEFT_OK;
}

void weft__ccd_garment_destroy(weft_garment *g)
{
    weft_ccd_world_destroy(g->ccd_state);
    g->ccd_state = NULL;
    weft__free(g->ctx, g->ccd_input, (size_t)g->vertex_count * 3 * sizeof(float));
    g->ccd_input = NULL;
}

void weft__ccd_postprocess_garment(weft_garment *g)
{
    weft_ccd_world *w = g->ccd_state;
    g->stats.ccd_iterations = 0;
    g->stats.ccd_vertices_moved = 0;
    g->stats.ccd_fallback = false;
    g->stats.ccd_over_budget = false;
    if (!w || !weft__all_finite(g->x_next, (size_t)g->vertex_count * 3)) {
        return;
    }
    const float *c0 = g->collider_vertex_count ? g->collider_prev : NULL;
    const float *c1 = g->collider_vertex_count ? g->collider_next : NULL;
    weft_ccd_postprocess_stats st = {0};
    memcpy(g->ccd_input, g->x_next, (size_t)g->vertex_count * 3 * sizeof(float));
    if (weft_ccd_postprocess(w, g->x, g->x_next, c0, c1, &st) == WEFT_OK || st.iterations > 0) {
        if (st.over_budget) {
            /* Out of its work bound, CCD would hold the whole garment where it was while the body
             * moves on (a garment left behind, frame after frame, where a body overlaps itself).
             * The step keeps the stages' result uncertified instead, and says so. */
            memcpy(g->x_next, g->ccd_input, (size_t)g->vertex_count * 3 * sizeof(float));
        }
        g->stats.ccd_iterations = st.iterations;
        g->stats.ccd_vertices_moved = st.vertices_moved;
        g->stats.ccd_fallback = st.fallback;
        g->stats.ccd_over_budget = st.over_budget;
    }
}
