/* Internal interface of the XPBD reference simulator, the LBS baseline and the validator.
 * Everything here works in double precision: float32 only appears at the garment API
 * boundary and in written datasets. */
#ifndef WEFT_XPBD_H
#define WEFT_XPBD_H

#include "core/core.h"
#include "garment/garment.h"

#include <math.h>

/* ---------------------------------------------------------------------------------------- */
/* Small double-precision vector operations.                                                 */

static inline void xv_sub(double *o, const double *a, const double *b)
{
    o[0] = a[0] - b[0];
    o[1] = a[1] - b[1];
    o[2] = a[2] - b[2];
}
static inline double xv_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline void xv_cross(double *o, const double *a, const double *b)
{
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    o[0] = x;
    o[1] = y;
    o[2] = z;
}
static inline double xv_len(const double *a) { return sqrt(xv_dot(a, a)); }
static inline void xv_axpy(double *y, double a, const double *x)
{
    y[0] += a * x[0];
    y[1] += a * x[1];
    y[2] += a * x[2];
}

/* ---------------------------------------------------------------------------------------- */
/* Geometry kernels (xpbd_geom.c).                                                           */

/* Squared distance from p to triangle (a, b, c); bary receives the closest point's weights. */
double xg_point_triangle_sq(const double *p, const double *a, const double *b, const double *c, double bary[3]);
/* Squared distance between segments p0-p1 and q0-q1; s, t are the closest points' parameters. */
double xg_segment_segment_sq(const double *p0, const double *p1, const double *q0, const double *q1, double *s,
                             double *t);

/* ---------------------------------------------------------------------------------------- */
/* Bounding volume hierarchy over primitives of 1-3 vertices (xpbd_bvh.c). Built once per
 * topology; refit moves the boxes without allocating.                                       */

typedef struct xbvh_node {
    double lo[3], hi[3];
    uint32_t left;   /* child index, or first primitive slot when count > 0 */
    uint32_t count;  /* primitives in a leaf; 0 for interior nodes (right child = left + 1) */
    uint32_t max_prim; /* largest primitive index below (set by refit) */
} xbvh_node;

typedef struct xbvh {
    uint32_t prim_count, node_count, arity;
    const uint32_t *prim_verts;  /* prim_count * arity, not owned */
    uint32_t *order;             /* leaf slot -> primitive */
    xbvh_node *nodes;
    uint32_t *build_stack;
} xbvh;

weft_result xbvh_create(const weft_context *ctx, xbvh *bvh, const uint32_t *prim_verts, uint32_t prim_count,
                        uint32_t arity);
void xbvh_destroy(const weft_context *ctx, xbvh *bvh);
/* Rebuilds the hierarchy for the current positions (no allocation). */
void xbvh_build(xbvh *bvh, const double *pos);
/* Recomputes boxes: union over pos0 and (if not NULL) pos1, inflated by pad. */
void xbvh_refit(xbvh *bvh, const double *pos0, const double *pos1, double pad);
/* Calls fn(prim, user) for every primitive whose box overlaps [lo, hi]. Returns false if fn
 * asked to stop. */
typedef bool xbvh_visit_fn(uint32_t prim, void *user);
bool xbvh_query(const xbvh *bvh, const double lo[3], const double hi[3], xbvh_visit_fn *fn, void *user);
/* The same, for primitives with an index above `above` only (each unordered pair once):
 * subtrees holding no such primitive are skipped. The visit order is xbvh_query's. */
bool xbvh_query_above(const xbvh *bvh, const double lo[3], const double hi[3], uint32_t above, xbvh_visit_fn *fn,
                      void *user);
/* Calls fn(a, b, user) once for every unordered pair of distinct primitives whose leaves' boxes
 * overlap (two primitives of one leaf always; callers test the primitives' own boxes). One
 * traversal of the tree against itself: far fewer node visits than a query per primitive. */
typedef void xbvh_pair_fn(uint32_t a, uint32_t b, void *user);
void xbvh_self_pairs(const xbvh *bvh, xbvh_pair_fn *fn, void *user);

/* ---------------------------------------------------------------------------------------- */
/* Cloth topology shared by the solver and the validator (xpbd_topo.c).                      */

typedef struct xtopo {
    uint32_t vertex_count, triangle_count, edge_count, hinge_count;
    const uint32_t *tris;        /* not owned */
    uint32_t *edges;             /* edge_count * 2, i < j */
    uint32_t *hinges;            /* hinge_count * 4: edge (x0, x1), wing of the first triangle, wing of the second */
    uint32_t *edge_tri;          /* edge_count * 2: incident triangles (UINT32_MAX if boundary) */
} xtopo;

/* Fails with WEFT_ERROR_DEGENERATE_MESH on an edge shared by more than two triangles or on
 * duplicate triangles. what = NULL accepts non-manifold meshes (colliders: only the edge
 * list is used; edges of more than two triangles get no hinge). */
weft_result xtopo_create(const weft_context *ctx, xtopo *topo, const uint32_t *tris, uint32_t triangle_count,
                         uint32_t vertex_count, const char *what);
void xtopo_destroy(const weft_context *ctx, xtopo *topo);

/* ---------------------------------------------------------------------------------------- */
/* The XPBD solver (xpbd_solver.c).                                                          */

typedef struct xpbd_params {
    double youngs_modulus;       /* Pa (GIPC cloth: 1e6) */
    double poisson_ratio;        /* 0.49 */
    double thickness;            /* m, 1e-3 */
    double areal_density;        /* kg/m^2, 0.2 */
    double compression_scale;    /* stretch stiffness factor in compression, 1e-2 */
    double shear_scale;          /* shear stiffness / stretch stiffness, 0.03 */
    double friction;             /* Coulomb mu, 0.4 */
    double gravity;              /* m/s^2 along -Y, 9.81 */
    double self_radius;          /* cloth-cloth contact thickness, m */
    double collider_radius;      /* cloth-collider contact thickness, m */
    double query_radius;         /* proximity query radius r_q, m */
    double bound_gamma;          /* conservative bound fraction (< 0.5) */
    uint32_t detect_window;      /* most substeps between proximity passes (re-detection also on any clamp) */
    bool self_collision;
} xpbd_params;

xpbd_params xpbd_default_params(void);

typedef struct xpbd_frame_stats {
    uint32_t substeps;
    uint32_t detections;         /* proximity passes */
    uint32_t pair_rebuilds;      /* candidate-pair lists rebuilt from the trees */
    uint32_t contacts;           /* active contact projections in the frame (summed over substeps) */
    uint32_t contacts_dropped;   /* candidate pairs beyond the contact capacity (bounds still hold) */
    uint32_t tight_passes;       /* passes whose self contacts overflowed and were swept again by their final bounds */
    uint32_t clamped;            /* vertex truncations to their conservative bound (summed) */
    double min_self_distance;    /* smallest cloth-cloth proximity seen (query radius if none) */
    double min_collider_distance;
    double max_strain;           /* largest |Fu| - 1 or |Fv| - 1 at the end of the frame */
    double elastic_energy;       /* J at the end of the frame */
} xpbd_frame_stats;

/* Parameters of an XPBD garment; must be called before the first step (it rebuilds the
 * compliances). Fails with WEFT_ERROR_INVALID_ARGUMENT when the garment is not XPBD or a
 * value is out of range. */
weft_result weft__xpbd_configure(weft_garment *g, const xpbd_params *params);
/* Undoes the last step (the garment goes back to positions x_t with x_prev before them, and
 * the solver to its exact double state) and makes the next step chord-safe: one proximity
 * pass for the whole frame, so every vertex stays inside its bound around the frame-start
 * position and the straight path between the two output frames is collision-free as well.
 * Used when the validator rejects a frame whose substep path was clean but whose chord was
 * not (a vertex sliding around a sharp edge). Stickier than the normal step. The caller sets
 * the collider at t+1 and the pins again before stepping. */
weft_result weft__xpbd_retry_chord_safe(weft_garment *g, const float *x_t, const float *x_prev,
                                        const float *collider_t);
/* Records the cloth positions along the substep path of every following step into buffer
 * ((capacity_substeps + 1) x n x 3 floats: state 0 is the frame start, state k the end of
 * substep k), for the validator's path check. NULL stops recording. A step with more
 * substeps than the capacity records nothing. */
weft_result weft__xpbd_record_substeps(weft_garment *g, float *buffer, uint32_t capacity_substeps);
/* States recorded by the last step (S + 1, or 0 when it recorded nothing). */
uint32_t weft__xpbd_recorded_states(const weft_garment *g);
/* The solver's double state (positions and velocities at t, 3 n each), so a long run can be
 * checkpointed and continued exactly. Export fails before the first step after a set_state;
 * import wants values that round to the garment's float positions (set them first with
 * weft_garment_set_state) and leaves the garment untouched otherwise. */
weft_result weft__xpbd_export_state(const weft_garment *g, double *x, double *v);
weft_result weft__xpbd_import_state(weft_garment *g, const double *x, const double *v);
/* Drops what the solver carries between frames besides its state (the candidate pair lists and
 * the collider's tree), so the next step runs as on a new garment with the same state: a run
 * that calls this at its checkpoints matches one continued from them, bit for bit. */
void weft__xpbd_forget_caches(weft_garment *g);
/* Statistics of the last step of an XPBD garment (zeros for other methods). */
xpbd_frame_stats weft__xpbd_last_stats(const weft_garment *g);

/* Constraint functions exposed for finite-difference tests. Each returns C and writes the
 * gradient for its vertices (3 per vertex). */
double xpbd_membrane_eval(const double *x0, const double *x1, const double *x2, const double coef[6], int which,
                          double grad[9]);
/* which: 0 = warp stretch C_u, 1 = weft stretch C_v, 2 = shear C_s; coef = (a0,a1,a2,b0,b1,b2)
 * such that Fu = sum a_i x_i and Fv = sum b_i x_i. */
bool xpbd_membrane_coefficients(const double *r0, const double *r1, const double *r2, double coef[6],
                                double *area);
/* Signed dihedral angle of hinge (x0, x1 | x2, x3); grad receives d theta / d x (12 values).
 * Returns false for a degenerate hinge (zero-area wing), leaving grad zeroed. */
bool xpbd_dihedral_eval(const double *x0, const double *x1, const double *x2, const double *x3, double *theta,
                        double grad[12]);

extern const weft_method_ops weft__xpbd_ops;
/* WEFT_METHOD_XPBD_FAST: the same solver with a game engine's collision projection. */
extern const weft_method_ops weft__xpbd_fast_ops;

/* ---------------------------------------------------------------------------------------- */
/* LBS baseline (lbs.c).                                                                      */

extern const weft_method_ops weft__lbs_ops;

/* The binding behind it: every garment vertex of g->x bound to its nearest collider triangles
 * of g->collider_rest (rigid-invariant frames). `who` prefixes error messages. */
typedef struct xskin xskin;
weft_result xskin_create(const weft_garment *g, const char *who, xskin **out);
/* The same binding for any points onto any triangle surface (surface_vertex_count * 3 positions). */
weft_result xskin_create_points(const weft_context *ctx, const float *points, uint32_t point_count,
                                const float *surface, uint32_t surface_vertex_count, const uint32_t *triangles,
                                uint32_t triangle_count, const char *who, xskin **out);
void xskin_destroy(const weft_context *ctx, xskin *skin);
/* Bound positions for collider vertex positions c (vertex_count * 3 into out_pos); fails only
 * when every triangle bound to a vertex has collapsed. */
weft_result xskin_eval(const xskin *skin, const uint32_t *collider_triangles, const float *c, const char *who,
                       float *out_pos);

#endif
