/* The garment instance shared by every method, and the interface a method implements.
 * The per-frame path is: set_collider -> step -> method->step writes next positions ->
 * optional CCD post-process -> rotate state buffers. Nothing here allocates after creation. */
#ifndef WEFT_GARMENT_H
#define WEFT_GARMENT_H

#include "core/core.h"

#include <math.h>
#include <stdatomic.h>

typedef struct weft_method_ops weft_method_ops;

/* A shared asset (weft_garment_asset_create): `proto` is a garment made from the def, never
 * stepped itself; instances copy it and own only their state (see instance_of below). */
struct weft_garment_asset {
    weft_context *ctx;
    struct weft_garment *proto;
    _Atomic uint32_t instances;
    _Atomic int busy;                   /* an instance is inside a step (its scratch in use) */
};

struct weft_garment {
    weft_context *ctx;
    /* The asset this garment is an instance of, or NULL for a garment of its own. An instance
     * owns x, x_prev, x_next, the collider at t and t+1, the pins and its method state; every
     * other pointer below is the asset's. */
    struct weft_garment_asset *asset;
    const weft_method_ops *ops;
    void *method_state;                 /* owned by the method */
    const weft_model *model;
    weft_method method;
    weft_precision precision;
    uint32_t substeps;
    uint32_t substeps_max;              /* XPBD: fast-collider frames get up to this many (>= substeps) */
    bool collider_projection;           /* XPBD: the collider as a projection, not bounded contacts */
    bool ccd;
    uint32_t ccd_iterations;            /* CCD back-off passes before the fallback */
    float crop_margin;                  /* model collider crop: metres, 0 = the model's own */
    weft_collider_crop crop_rule;
    uint32_t max_collider_tokens;       /* 0: no cap */
    weft_collider_cap collider_cap;
    void *ccd_state;                    /* runtime/ccd world when ccd is set (weft__ccd_garment_create) */
    float *ccd_input;                   /* vertex_count * 3: x_next as CCD got it, restored when CCD
                                         * runs out of its work bound */

    /* The garment bound to the collider (runtime/geometry/skin.c binding), made at creation when the
     * garment has tethers or a cut distance; NULL otherwise. */
    struct geo_skin *skin;
    float *tether_radius;               /* vertex_count radii (uniform ones expanded); NULL: no tethers */
    float *tether_target;               /* vertex_count * 3 scratch: skinned positions at t+1 */
    /* This step's garment skinned by `skin` onto collider_next, when the method computed it on the
     * way (the learned model's skinned prior, LBS: they share `skin`); the tethers take it instead
     * of evaluating the binding again. Every weft__garment_finish_step consumes and clears it. */
    const float *skinned_next;
    /* Long-range attachments (attach.c), when the def enables them. The asset's: the rest edge
     * graph (CSR) and the slack. The instance's: each vertex's anchor and limit for the pins in
     * pin_indices (found again by set_pins when the list changes) and the search's scratch. */
    float attach_slack;
    uint32_t *attach_start;             /* vertex_count + 1; NULL: attachments off */
    uint32_t *attach_next;              /* the neighbours of each vertex */
    float *attach_length;               /* their rest distances */
    uint32_t *attach_pin;               /* vertex_count: pin slot of the anchor, UINT32_MAX: none */
    float *attach_limit;                /* vertex_count: (1 + slack) x rest path length */
    uint32_t *attach_heap, *attach_where; /* vertex_count each: the search's heap and positions */
    float cut_distance;                 /* collider jump that resets the cloth (metres); 0: off */
    bool cut_pending;                   /* weft_garments_step: cut in this call's first pass */

    float strain_limit;                 /* 0: off (runtime/garment/strain.c) */
    uint32_t strain_iterations;
    uint32_t strain_edge_count;
    uint32_t *strain_edges;             /* unique edges, 2 per edge */
    float *strain_rest;                 /* rest length per edge */
    uint8_t *strain_fixed;              /* vertex_count: 1 glued (radius-0 tether), | 2 pinned this step,
                                         * | 4 near the collider this step (contact-aware limit) */
    uint32_t *strain_moved;             /* vertex_count, edge_count: the sweeps' scratch */
    uint8_t *strain_hot;
    float strain_contact;               /* contact-aware limit distance, metres; 0: off */
    float *strain_normal;               /* vertex_count * 3: away from the collider, where bit 4 is set */

    float push_thickness;               /* collider push (near.c): metres kept in front; 0: off */
    bool ground;                        /* collision.ground: the floor y = ground_height */
    float ground_height;
    float push_depth;                   /* deepest penetration pushed out, metres */

    /* Collider proximity (near.c), made when the contact-aware limit, the push or the fast XPBD
     * method needs it. */
    double *near_cpos;                  /* collider_vertex_count * 3: the collider at t+1, for the tree */
    struct geo_bvh *near_tree;          /* collider triangles (runtime/geometry/bvh.c); NULL: off */
    uint32_t *near_across;              /* push: per triangle edge (k, k+1), the triangle across or UINT32_MAX */
    uint32_t *near_vt_start, *near_vt;  /* push: triangles around each collider vertex (CSR) */
    uint8_t *near_skip;                 /* push: vertex_count, 1 glued, | 2 pinned this step */
    uint8_t *near_inside;               /* push with CCD: vertex_count, inside the collider at t */
    uint32_t *near_last;                /* push: per vertex, its last nearest collider triangle (a seed) */
    /* The push's clearance (near.c, *Clearance*): the collider's triangles in up to 64 clusters
     * (subtrees of near_tree), whose motion each step bounds how near a vertex can have come. */
    uint32_t near_kcount;               /* clusters */
    uint32_t *near_knode;               /* near_kcount: the cluster's node in near_tree */
    uint8_t *near_ktri;                 /* collider_triangle_count: the triangle's cluster */
    uint64_t *near_kvert;               /* collider_vertex_count: the clusters of the triangles around it */
    double *near_kinv;                  /* near_kcount: 1 / the cluster's vertex count */
    double *near_kmove;                 /* scratch: near_kcount x 4 (mean move, spread about it) */
    float *near_kreach;                 /* scratch: near_kcount x (near_kcount + 1): cluster k's reach
                                         * seen from cluster h (row h, made each step for the homes
                                         * in use), and row h's largest */
    float *near_kbox;                   /* scratch: the clusters' boxes at t+1, 6 x 64 (SoA) */
    /* ... and each instance's own (weft__near_alloc_state). */
    float *near_cref;                   /* collider_vertex_count * 3: the collider at the last push */
    float *near_at;                     /* vertex_count * 3: each vertex at the last push */
    float *near_clear;                  /* vertex_count * 2: lower bounds on the distance to the
                                         * near clusters and to the rest; 0: query */
    uint64_t *near_kmask;               /* vertex_count: its near clusters */
    uint8_t *near_home;                 /* vertex_count: the cluster of its nearest triangle */
    bool near_primed;                   /* near_cref holds the collider of a push */
    bool near_search_all;               /* every vertex searched every step: the clearance's oracle */

    /* Body parts (parts.c); all NULL when the def gave no collision.triangle_parts. */
    uint32_t *part_mask;                /* vertex_count: the parts each cloth vertex collides with */
    uint32_t *ctri_bits;                /* collider_triangle_count: 1 << the triangle's part */
    uint32_t *cvert_bits;               /* collider_vertex_count: the parts of the triangles around it */

    uint32_t vertex_count, triangle_count;
    float *rest;                        /* vertex_count * 3 */
    uint32_t *triangles;                /* triangle_count * 3 */

    uint32_t collider_vertex_count, collider_triangle_count;
    float *collider_rest;               /* collider_vertex_count * 3 */
    uint32_t *collider_triangles;
    float *collider_prev;               /* collider at t (the current frame) */
    float *collider_next;               /* collider at t+1, set by weft_garment_set_collider */
    bool collider_next_set;

    float *x;                           /* positions at t */
    float *x_prev;                      /* positions at t-1 */
    float *x_next;                      /* scratch the method writes t+1 into */

    uint32_t pin_count;
    uint32_t *pin_indices;              /* capacity vertex_count */
    float *pin_targets;                 /* capacity vertex_count * 3 */

    weft_step_stats stats;
};

struct weft_method_ops {
    const char *name;
    bool supports_pins; /* solves with pins; otherwise the garment sets them after the step */
    /* Allocate method_state and precompute everything constant for this garment. */
    weft_result (*create)(weft_garment *g);
    void (*destroy)(weft_garment *g);
    /* Make an instance's method state from the asset's prototype: what stays constant and the
     * step scratch shared with `proto`, the state its own. NULL: create() runs for the instance
     * (the XPBD methods, whose solver state is most of what they hold). destroy() must then free
     * only what the instance owns (g->asset is set). */
    weft_result (*instance)(const weft_garment *proto, weft_garment *g);
    /* Clear any frame history (called after weft_garment_set_state). May be NULL. */
    void (*reset)(weft_garment *g);
    /* Write positions at t+1 into g->x_next from g->x, g->x_prev, the colliders and the pins.
     * Must not change g->x or g->x_prev; on failure the garment is left as it was. */
    weft_result (*step)(weft_garment *g);
};

/* An instance's hold on its asset's scratch for one call (no-op for a garment of its own):
 * false, with WEFT_ERROR_BUSY reported for `who`, when another instance holds it. */
bool weft__garment_enter(weft_garment *g, const char *who);
void weft__garment_leave(weft_garment *g);

/* The tail of every step, single or batched, once the method wrote g->x_next: NaN check,
 * tethers, CCD post-process, buffer rotation, frame count. On failure the state is unchanged.
 * The caller sets stats.step_ms. */
weft_result weft__garment_finish_step(weft_garment *g);

/* A collider that moved farther than cut_distance since the last frame (a teleport, a cut in the
 * animation) is a cut: the garment is reset to its skinned positions on the collider of t+1, at
 * rest, the method's history cleared, and no method step runs. Returns true when it did so
 * (stats.collider_cut; the caller sets step_ms); *r gets a failure of the skinning. */
bool weft__garment_cut(weft_garment *g, weft_result *r);

/* The skin binding (geometry.h) of the garment's current positions g->x to its collider's rest
 * shape: LBS, the tethers, cuts and the skinned prior carry the garment with it. */
weft_result weft__garment_skin_create(const weft_garment *g, const char *who, struct geo_skin **out);
/* Positions (count xyz triplets) finite and within +-WEFT_MAX_COORDINATE; `what` names them. */
weft_result weft__check_positions(const char *what, const float *positions, size_t count);
/* Every vertex in a triangle, no edge of more than two triangles, no duplicate triangles. */
weft_result weft__check_cloth_topology(const weft_context *ctx, const char *what, const uint32_t *triangles,
                                       uint32_t triangle_count, uint32_t vertex_count);

/* Strain limiting (strain.c): edges and rest lengths made once; the limit applied to x_next. */
weft_result weft__strain_create(weft_garment *g);
void weft__strain_destroy(weft_garment *g);
void weft__strain_limit(weft_garment *g);

/* Moves x onto the sphere of `radius` (>= 0) around c when it lies farther out; returns whether it
 * moved. The max-distance clamp of the tethers and the attachments. */
static inline bool weft__clamp_to_sphere(float *x, const float *c, float radius)
{
    const float d[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    const float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > radius)) {
        return false;
    }
    const float s = radius / len; /* len > radius >= 0, so len > 0 */
    for (int k = 0; k < 3; ++k) {
        x[k] = c[k] + d[k] * s;
    }
    return true;
}

/* Long-range attachments (attach.c). create builds the asset's edge graph (g->rest, triangles);
 * alloc_state/free_state the instance's anchors and scratch (nothing when attachments are off);
 * anchor finds every vertex's anchor among pin_indices[0, pin_count); clamp applies the limit to
 * x_next and returns how many vertices moved. */
weft_result weft__attach_create(weft_garment *g);
void weft__attach_destroy(weft_garment *g);
bool weft__attach_alloc_state(weft_garment *g);
void weft__attach_free_state(weft_garment *g);
/* The push's per-instance clearance state (near.c); no-ops when the push is off. */
bool weft__near_alloc_state(weft_garment *g);
void weft__near_free_state(weft_garment *g);
void weft__attach_anchor(weft_garment *g);
uint32_t weft__attach_clamp(weft_garment *g);

/* Collider proximity and push (near.c). create makes the tree when strain_contact or
 * push_thickness asks for it; refit moves it to the collider at t+1 (once per step). */
typedef struct weft_near_hit {
    uint32_t tri;                       /* nearest collider triangle */
    double bary[3], point[3], d2;       /* its nearest point (weights, position) and squared distance */
} weft_near_hit;
weft_result weft__near_create(weft_garment *g);
void weft__near_destroy(weft_garment *g);
void weft__near_refit(weft_garment *g);
/* Push with CCD: flags the vertices of x inside the collider at t (within push_depth) in
 * near_inside, with the tree refitted to the collider at t; returns their count. Call before
 * weft__near_refit. */
uint32_t weft__near_mark_inside(weft_garment *g);
/* Nearest collider point to p within radius, over every part; false when there is none. seed: a triangle likely
 * to be near (the last answer for this vertex), which narrows the search, or UINT32_MAX. */
bool weft__near_nearest(const weft_garment *g, const double p[3], double radius, uint32_t seed, weft_near_hit *hit);
/* The same among the collider triangles of the parts in mask only (weft__part_mask). */
bool weft__near_nearest_in(const weft_garment *g, const double p[3], double radius, uint32_t seed, uint32_t mask,
                           weft_near_hit *hit);
/* Moves the tree to collider positions c (collider_vertex_count * 3 doubles): the fast XPBD
 * method's collider at each substep. weft__near_refit moves it back to t+1. */
void weft__near_move_to(weft_garment *g, const double *c);
/* Whether p is inside the collider, by the pseudonormal of its nearest point's feature (face,
 * edge or corner; exact on a closed collider), and the outward unit direction: from the surface
 * point to p, flipped when inside; on the surface itself, the pseudonormal. False when there is
 * no direction (p on a collapsed feature). */
bool weft__near_outward(const weft_garment *g, const double p[3], const weft_near_hit *hit, double out[3],
                        bool *inside);
/* Moves x_next vertices inside the collider (up to push_depth) or closer than push_thickness
 * to push_thickness in front of it; sets stats.pushed_vertices and push_from_far_side. */
void weft__push(weft_garment *g);

/* Body parts (parts.c): the masks made from the initial state x and the collider at rest;
 * nothing is made when parts is NULL. */
weft_result weft__parts_create(weft_garment *g, const uint8_t *parts, float margin, bool neighbours);
void weft__parts_destroy(weft_garment *g);
/* The parts cloth vertex v collides with (every part when the garment has no partition). */
static inline uint32_t weft__part_mask(const weft_garment *g, uint32_t v)
{
    return g->part_mask ? g->part_mask[v] : UINT32_MAX;
}
/* Whether cloth vertex v collides with collider triangle t. */
static inline bool weft__part_hits(const weft_garment *g, uint32_t v, uint32_t t)
{
    return !g->part_mask || (g->part_mask[v] & g->ctri_bits[t]) != 0;
}

/* Indices in range, finite positions, no zero-area triangles; `what` names the mesh in errors. */
weft_result weft__check_mesh(const char *what, const float *positions, uint32_t vertex_count,
                             const uint32_t *triangles, uint32_t triangle_count);

/* The implementation of a method, or NULL when this build has none. */
const weft_method_ops *weft__method_ops(weft_method method);

#endif
