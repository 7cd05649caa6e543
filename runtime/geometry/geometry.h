/* The geometry module: what every layer above it (garment, xpbd, model, lod, the lab) shares.
 * Small double-precision vector operations, closest points, a bounding volume hierarchy, cloth
 * topology and the skin binding. It depends on core only; nothing here knows a garment. The CCD
 * module keeps its own exact narrow phase and swept-box tree (ccd/), whose guarantees differ
 * (certified distances with slack, float boxes with dirty bits). */
#ifndef WEFT_GEOMETRY_H
#define WEFT_GEOMETRY_H

#include "core/core.h"

#include <math.h>

/* ---------------------------------------------------------------------------------------- */
/* Small double-precision vector operations.                                                 */

static inline void geo_sub(double *o, const double *a, const double *b)
{
    o[0] = a[0] - b[0];
    o[1] = a[1] - b[1];
    o[2] = a[2] - b[2];
}
static inline double geo_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline void geo_cross(double *o, const double *a, const double *b)
{
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    o[0] = x;
    o[1] = y;
    o[2] = z;
}
static inline double geo_len(const double *a) { return sqrt(geo_dot(a, a)); }
static inline void geo_axpy(double *y, double a, const double *x)
{
    y[0] += a * x[0];
    y[1] += a * x[1];
    y[2] += a * x[2];
}

/* ---------------------------------------------------------------------------------------- */
/* Geometry kernels (closest.c).                                                           */

/* Squared distance from p to triangle (a, b, c); bary receives the closest point's weights. */
double geo_point_triangle_sq(const double *p, const double *a, const double *b, const double *c, double bary[3]);
/* Squared distance between segments p0-p1 and q0-q1; s, t are the closest points' parameters. */
double geo_segment_segment_sq(const double *p0, const double *p1, const double *q0, const double *q1, double *s,
                             double *t);

/* ---------------------------------------------------------------------------------------- */
/* Bounding volume hierarchy over primitives of 1-3 vertices (bvh.c). Built once per
 * topology; refit moves the boxes without allocating.                                       */

typedef struct geo_bvh_node {
    double lo[3], hi[3];
    uint32_t left;   /* child index, or first primitive slot when count > 0 */
    uint32_t count;  /* primitives in a leaf; 0 for interior nodes (right child = left + 1) */
    uint32_t max_prim; /* largest primitive index below (set by refit) */
} geo_bvh_node;

typedef struct geo_bvh {
    uint32_t prim_count, node_count, arity;
    const uint32_t *prim_verts;  /* prim_count * arity, not owned */
    uint32_t *order;             /* leaf slot -> primitive */
    geo_bvh_node *nodes;
    uint32_t *build_stack;
} geo_bvh;

weft_result geo_bvh_create(const weft_context *ctx, geo_bvh *bvh, const uint32_t *prim_verts, uint32_t prim_count,
                        uint32_t arity);
void geo_bvh_destroy(const weft_context *ctx, geo_bvh *bvh);
/* Rebuilds the hierarchy for the current positions (no allocation). */
void geo_bvh_build(geo_bvh *bvh, const double *pos);
/* Recomputes boxes: union over pos0 and (if not NULL) pos1, inflated by pad. */
void geo_bvh_refit(geo_bvh *bvh, const double *pos0, const double *pos1, double pad);
/* Calls fn(prim, user) for every primitive whose box overlaps [lo, hi]. Returns false if fn
 * asked to stop. */
typedef bool geo_bvh_visit_fn(uint32_t prim, void *user);
bool geo_bvh_query(const geo_bvh *bvh, const double lo[3], const double hi[3], geo_bvh_visit_fn *fn, void *user);
/* The same, for primitives with an index above `above` only (each unordered pair once):
 * subtrees holding no such primitive are skipped. The visit order is geo_bvh_query's. */
bool geo_bvh_query_above(const geo_bvh *bvh, const double lo[3], const double hi[3], uint32_t above, geo_bvh_visit_fn *fn,
                      void *user);
/* Nearest-primitive search around p: calls fn(prim, user) for the primitives of every leaf whose
 * box lies within sqrt(*bound_d2) of p, nearer leaves first, re-reading *bound_d2 (which fn
 * lowers as it finds nearer primitives) before each node, so far subtrees are never opened. The
 * caller's fn decides ties; the set of primitives visited depends on the order found, so fn must
 * give an order-independent answer (e.g. the least (distance, index)). */
bool geo_bvh_nearest(const geo_bvh *bvh, const double p[3], const double *bound_d2, geo_bvh_visit_fn *fn, void *user);
/* Calls fn(a, b, user) once for every unordered pair of distinct primitives whose leaves' boxes
 * overlap (two primitives of one leaf always; callers test the primitives' own boxes). One
 * traversal of the tree against itself: far fewer node visits than a query per primitive. */
typedef void geo_bvh_pair_fn(uint32_t a, uint32_t b, void *user);
void geo_bvh_self_pairs(const geo_bvh *bvh, geo_bvh_pair_fn *fn, void *user);

/* ---------------------------------------------------------------------------------------- */
/* Cloth topology shared by the solver and the validator (topology.c).                      */

typedef struct geo_topo {
    uint32_t vertex_count, triangle_count, edge_count, hinge_count;
    const uint32_t *tris;        /* not owned */
    uint32_t *edges;             /* edge_count * 2, i < j */
    uint32_t *hinges;            /* hinge_count * 4: edge (x0, x1), wing of the first triangle, wing of the second */
    uint32_t *edge_tri;          /* edge_count * 2: incident triangles (UINT32_MAX if boundary) */
} geo_topo;

/* Fails with WEFT_ERROR_DEGENERATE_MESH on an edge shared by more than two triangles or on
 * duplicate triangles. what = NULL accepts non-manifold meshes (colliders: only the edge
 * list is used; edges of more than two triangles get no hinge). */
weft_result geo_topo_create(const weft_context *ctx, geo_topo *topo, const uint32_t *tris, uint32_t triangle_count,
                         uint32_t vertex_count, const char *what);
void geo_topo_destroy(const weft_context *ctx, geo_topo *topo);

/* The skin binding (skin.c): every point bound to its nearest triangles of a surface
 * (surface_vertex_count * 3 positions) in rigid-invariant frames, so that it follows the surface
 * as it moves. `who` prefixes error messages. */
typedef struct geo_skin geo_skin;
weft_result geo_skin_create_points(const weft_context *ctx, const float *points, uint32_t point_count,
                                const float *surface, uint32_t surface_vertex_count, const uint32_t *triangles,
                                uint32_t triangle_count, const char *who, geo_skin **out);
void geo_skin_destroy(const weft_context *ctx, geo_skin *skin);
/* Bound positions for collider vertex positions c (vertex_count * 3 into out_pos); fails only
 * when every triangle bound to a vertex has collapsed. Each bound triangle's frame is computed
 * once into the skin's scratch, so one skin is evaluated by one thread at a time. */
weft_result geo_skin_eval(const geo_skin *skin, const uint32_t *collider_triangles, const float *c, const char *who,
                       float *out_pos);
/* An evaluation reads only the positions of the collider vertices of the bound triangles. A
 * caller that keeps one evaluation stores those positions as its key (geo_skin_key_floats floats)
 * and may reuse the evaluation while geo_skin_key_matches: bitwise equal positions give a
 * bit-identical evaluation. */
uint32_t geo_skin_key_floats(const geo_skin *skin);
void geo_skin_key_store(const geo_skin *skin, const float *c, float *key);
bool geo_skin_key_matches(const geo_skin *skin, const float *c, const float *key);

#endif
