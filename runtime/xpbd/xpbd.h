/* Internal interface of the XPBD reference simulator and the LBS baseline, above the geometry
 * module (geometry/geometry.h). Everything here works in double precision: float32 only appears
 * at the garment API boundary and in written datasets. */
#ifndef WEFT_XPBD_H
#define WEFT_XPBD_H

#include "core/core.h"
#include "garment/garment.h"
#include "geometry/geometry.h"

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
    uint32_t untangled;          /* crossings undone by untangling (summed over substeps) */
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
/* The reference with a projected body (collider_projection): the vertices whose mask byte is
 * non-zero are held to their cloth-cloth bounds after the body's projection too, so the body
 * cannot push them through the cloth around them (the lab sets it, before each step, to where
 * the body squeezed the cloth at the frame before). The mask (n bytes) is borrowed until the
 * next call; NULL clears it. Other garments: WEFT_ERROR_INVALID_ARGUMENT. */
weft_result weft__xpbd_set_bounded_projection(weft_garment *g, const uint8_t *mask);
/* The reference with a projected body: untangling. mask (n bytes, borrowed until the next call;
 * NULL clears) marks the cloth found crossing itself at the end of the frame before (the lab's
 * validator: the crossing triangles' corners and their ring). Each substep, after the body's
 * projection, every marked edge that crosses a marked triangle is undone: the crossing point
 * slides along the edge toward its neighbours on the intersection contour (the direction that
 * shortens the contour), so the edge's end on that side goes back through the triangle to the
 * other end's side, plus the self radius, as a contact on the triangle's normal (at most the self
 * radius a substep; only marked vertices move, the triangle's by its weights at the crossing).
 * The pairs between marked cloth crossing at the step's start set no bounds and no contacts, which
 * would hold the crossing. Other garments: WEFT_ERROR_INVALID_ARGUMENT. */
weft_result weft__xpbd_set_untangle(weft_garment *g, const uint8_t *mask);
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

/* Untangling's scratch and the crossings of the current frame (untangle.c). */
typedef struct xpbd_untangle {
    uint32_t n, ntri, nedge;
    uint32_t *cand_tri, *cand_edge; /* triangles and edges with a marked corner */
    uint32_t ncand_tri, ncand_edge;
    double *box;                    /* per candidate triangle: lo xyz, hi xyz */
    const uint8_t *mask;            /* the caller's marks (borrowed) */
    uint8_t *crossing;              /* per vertex: on an edge or a triangle crossing the cloth at the step's start */
    uint32_t crossing_count;
} xpbd_untangle;

weft_result xpbd_untangle_create(const weft_context *ctx, xpbd_untangle *u, uint32_t n, uint32_t ntri, uint32_t nedge);
void xpbd_untangle_destroy(const weft_context *ctx, xpbd_untangle *u);
/* The crossings among the marked cloth at positions x (the step's start); returns the vertices
 * on them. */
uint32_t xpbd_untangle_begin(xpbd_untangle *u, const geo_topo *topo, const uint32_t *tris, const uint8_t *mask,
                             const double *x);
/* One substep's projection (see weft__xpbd_set_untangle); returns the crossings worked on. w:
 * inverse masses (0 pinned). */
uint32_t xpbd_untangle_project(xpbd_untangle *u, const geo_topo *topo, const uint32_t *tris, double *x, const double *w,
                               double margin);

extern const weft_method_ops weft__xpbd_ops;
/* WEFT_METHOD_XPBD_FAST: the same solver with a game engine's collision projection. */
extern const weft_method_ops weft__xpbd_fast_ops;

/* ---------------------------------------------------------------------------------------- */
/* LBS baseline (lbs.c).                                                                      */

extern const weft_method_ops weft__lbs_ops;

#endif
