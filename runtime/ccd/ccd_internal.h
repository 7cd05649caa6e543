/* Internal pieces of the CCD concept shared by its files: the double-precision narrow phase, exact
 * predicates, the bounding-volume hierarchy and the garment hook. */
#ifndef WEFT_CCD_INTERNAL_H
#define WEFT_CCD_INTERNAL_H

#include "core/core.h"
#include "weft/ccd.h"

/* ---- narrow phase (narrow.c) ------------------------------------------------------------ */

/* Per-query counters, for the benchmark and the false-positive accounting. */
typedef struct ccd_narrow_stats {
    uint64_t queries;
    uint64_t bands;          /* time intervals where the coplanarity cubic may vanish */
    uint64_t distance_evals; /* conservative-advancement distance evaluations */
    uint64_t capped;         /* queries reported after the advancement cap (conservative hits) */
} ccd_narrow_stats;

/* points: 8 xyz (t = 0 then t = 1). Returns true on a (possibly conservative) hit, *toi set. */
bool ccd_vf(const double points[24], double eta, double *toi, ccd_narrow_stats *stats);
bool ccd_ee(const double points[24], double eta, double *toi, ccd_narrow_stats *stats);

/* ---- exact predicates (predicates.c) ---------------------------------------------------- */

/* Sign (-1, 0, 1) of det(b - a, c - a, d - a), exact for any finite doubles. */
int ccd_orient3d(const double a[3], const double b[3], const double c[3], const double d[3]);
/* Sign of the 2D orientation of (a, b, c) using coordinates i and j, exact. */
int ccd_orient2d(const double a[3], const double b[3], const double c[3], int i, int j);
/* Exact intersection of two closed triangles (9 doubles each; collinear triangles act as segments). */
bool ccd_tri_tri(const double *a0, const double *a1, const double *a2, const double *b0, const double *b1,
                 const double *b2);
/* Exact: does the closed segment pq cross the closed triangle abc (non-degenerate)? Returns 1 yes,
 * 0 no, -1 undecided because the configuration is degenerate for ray casting (touches an edge,
 * a vertex, or lies in the plane). */
int ccd_segment_crosses_triangle_strict(const double p[3], const double q[3], const double a[3], const double b[3],
                                        const double c[3]);

/* Body parts for the cloth-collider pairs (garment/parts.c): cloth_masks (one per cloth
 * vertex) and collider_tri_bits (1 << part, one per collider triangle) are kept, not copied;
 * NULL clears. weft_ccd_intersect_frame then skips a cloth-collider triangle pair unless all
 * the cloth triangle's corners have the collider triangle's part (the lab's validator certifies
 * ground truth on self-intersecting bodies this way); the metrics ignore them. */
void weft__ccd_world_set_parts(weft_ccd_world *w, const uint32_t *cloth_masks, const uint32_t *collider_tri_bits);
/* Per cloth vertex (not copied; NULL: none): cloth–cloth pairs of triangles with an exempt vertex
 * are neither swept nor intersected (simgen on real motion: cloth where the body overlaps itself). */
void weft__ccd_world_set_self_exempt(weft_ccd_world *w, const uint8_t *exempt);
/* Every pair of cloth triangles sharing no edge that intersects at x, exempt or not: sets mark to 1
 * at their corners (the caller clears it) and returns the pair count. x must be finite. */
uint32_t weft__ccd_intersect_mark(weft_ccd_world *w, const float *x, uint8_t *mark);

/* ---- garment hook (world.c) ------------------------------------------------------------- */

/* The garment's CCD work bound: triangle pairs all passes of one step may visit, per cloth
 * triangle (weft_ccd_world_def.max_pairs). docs/CCD.md, *Work bound*. */
#define WEFT_CCD_PAIRS_PER_TRIANGLE 64u
/* Plus this many for any garment: a small patch against a finely meshed collider meets many
 * collider triangles per cloth triangle. */
#define WEFT_CCD_PAIRS_FLOOR 16384u

struct weft_garment;
/* Allocates the garment's CCD state when g->ccd is set (called from weft_garment_create). */
weft_result weft__ccd_garment_create(struct weft_garment *g);
void weft__ccd_garment_destroy(struct weft_garment *g);
/* Post-processes g->x_next against g->x (cloth) and g->collider_prev -> g->collider_next, filling
 * g->stats.ccd_*. Leaves non-finite output alone (the step's NaN check rejects it). */
void weft__ccd_postprocess_garment(struct weft_garment *g);

#endif
