/*
 * weft/ccd.h — continuous collision detection (CCD) between two frames, the CCD post-process,
 * discrete triangle–triangle intersection checks and the collision metrics.
 *
 * Motion model: every vertex moves on a straight line between the two frames, x(t) = x0 + t (x1 - x0)
 * for t in [0, 1]. A contact is a time t at which a vertex touches a triangle (vertex–face) or two
 * edges touch (edge–edge); touching counts (closed sets).
 *
 * Guarantee: the tests are conservative. Whenever the primitives touch at some t in [0, 1], a hit is
 * reported with a time of impact toi <= the earliest contact time. A hit may also be reported when the
 * primitives come within about `min_separation` of each other without touching (a counted false
 * positive). docs/CCD.md gives the argument and the measured false-positive rates.
 *
 * Five contact types are checked between cloth and collider and within the cloth:
 *   VF       cloth vertex    – collider triangle
 *   EE       cloth edge      – collider edge
 *   FV       collider vertex – cloth triangle
 *   SELF_VF  cloth vertex    – cloth triangle not containing it
 *   SELF_EE  cloth edge      – cloth edge sharing no vertex with it
 *
 * Positions are float xyz triplets as in weft.h; all geometry inside is double precision.
 */
#ifndef WEFT_CCD_H
#define WEFT_CCD_H

#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------------------------------- */
/* Single queries                                                                             */

/* Default minimum separation (metres) of the single-query functions and of weft_ccd_world_def. */
#define WEFT_CCD_DEFAULT_MIN_SEPARATION 1e-6

/* One vertex–face query. points: 8 xyz triplets, the vertex and the triangle's three vertices at
 * t = 0, then the same four at t = 1 (the order of the public CCD benchmark). Returns 1 and sets
 * *toi (may be NULL) when they touch or come within min_separation, else 0. min_separation <= 0
 * means WEFT_CCD_DEFAULT_MIN_SEPARATION; it is raised automatically when the coordinates are so
 * large that double rounding exceeds it. Non-finite coordinates return 1 with toi = 0: separation
 * cannot be proved. */
WEFT_API int weft_ccd_vertex_face(const double points[24], double min_separation, double *toi);

/* One edge–edge query: edge a's endpoints then edge b's at t = 0, then the same at t = 1. */
WEFT_API int weft_ccd_edge_edge(const double points[24], double min_separation, double *toi);

/* Exact triangle–triangle intersection of two closed triangles (robust predicates: the decision is
 * exact for the given float/double coordinates). Triangles given as 9 doubles each. Returns 1 if
 * they share at least one point. A triangle with collinear vertices is treated as the segment it
 * spans. Non-finite input returns 1 (cannot be shown apart). */
WEFT_API int weft_ccd_triangles_intersect(const double a[9], const double b[9]);

/* ---------------------------------------------------------------------------------------- */
/* World: fixed topology (cloth and collider), buffers sized at creation, no allocation after.
 * A world is not internally locked: use it from one thread at a time. */

typedef enum weft_ccd_type {
    WEFT_CCD_VF = 0,            /* v[0] cloth vertex, v[1..3] collider triangle */
    WEFT_CCD_EE,                /* v[0..1] cloth edge, v[2..3] collider edge */
    WEFT_CCD_FV,                /* v[0] collider vertex, v[1..3] cloth triangle */
    WEFT_CCD_SELF_VF,           /* v[0] cloth vertex, v[1..3] cloth triangle */
    WEFT_CCD_SELF_EE,           /* v[0..1] cloth edge, v[2..3] cloth edge */
    WEFT_CCD_TYPE_COUNT
} weft_ccd_type;

/* Bit masks for weft_ccd_detect's `types` argument. */
#define WEFT_CCD_MASK(type) (1u << (type))
#define WEFT_CCD_MASK_COLLIDER (WEFT_CCD_MASK(WEFT_CCD_VF) | WEFT_CCD_MASK(WEFT_CCD_EE) | WEFT_CCD_MASK(WEFT_CCD_FV))
#define WEFT_CCD_MASK_SELF (WEFT_CCD_MASK(WEFT_CCD_SELF_VF) | WEFT_CCD_MASK(WEFT_CCD_SELF_EE))
#define WEFT_CCD_MASK_ALL (WEFT_CCD_MASK_COLLIDER | WEFT_CCD_MASK_SELF)

typedef struct weft_ccd_world weft_ccd_world;

typedef struct weft_ccd_world_def {
    /* Cloth mesh (required). Indices are copied. */
    const uint32_t *cloth_triangles;        /* cloth_triangle_count * 3 */
    uint32_t cloth_triangle_count;
    uint32_t cloth_vertex_count;
    /* Collider mesh (optional: counts 0). Should be closed for the inside test of the metrics. */
    const uint32_t *collider_triangles;     /* collider_triangle_count * 3 */
    uint32_t collider_triangle_count;
    uint32_t collider_vertex_count;
    /* Optional positions that fix the bounding-volume hierarchies' layout (e.g. rest shapes). NULL:
     * the layout is built from the first frame passed to any call. */
    const float *cloth_layout_positions;
    const float *collider_layout_positions;

    bool self_collision;        /* check SELF_VF / SELF_EE in postprocess and metrics (default true) */
    double min_separation;      /* eta in metres (default WEFT_CCD_DEFAULT_MIN_SEPARATION) */
    double time_margin;         /* epsilon in t_safe = max(0, t_c - epsilon) (default 0.05) */
    uint32_t max_iterations;    /* post-process passes before the fallback (default 16) */
    uint32_t max_hits;          /* hits kept for weft_ccd_hits (default 65536); counts are exact */
    /* Work bound of weft_ccd_postprocess: triangle pairs (cloth-collider and cloth-cloth whose
     * swept boxes overlap) all its passes may visit together. A pass that reaches it stops, every
     * cloth vertex is held at x0, and one more pass with a fresh allowance certifies that
     * (stats->over_budget). So a step's cost is at most about twice this many pair tests, however
     * far the cloth moved. 0 = no bound (default). */
    uint64_t max_pairs;
    uint32_t internal_cookie;   /* set by weft_default_ccd_world_def(); do not touch */
} weft_ccd_world_def;

/* One detected contact. Vertex indices refer to the cloth or the collider as listed per type. */
typedef struct weft_ccd_hit {
    uint32_t type;              /* weft_ccd_type */
    uint32_t v[4];
    double toi;                 /* conservative time of impact in [0, 1] */
} weft_ccd_hit;

typedef struct weft_ccd_report {
    uint32_t hits[WEFT_CCD_TYPE_COUNT];     /* per type */
    uint32_t hit_total;
    uint32_t hits_stored;                   /* min(hit_total, max_hits) */
    uint64_t narrow_tests;                  /* primitive pairs the narrow phase examined */
    double earliest_toi;                    /* 1 when there is no hit */
} weft_ccd_report;

typedef struct weft_ccd_postprocess_stats {
    uint32_t iterations;        /* detect passes run, including the final clean one */
    uint32_t vertices_moved;    /* cloth vertices whose end position changed */
    uint32_t vertices_carried;  /* fallback moves of cloth vertices with the collider that hit them */
    uint32_t vertices_held;     /* fallback moves of cloth vertices back to their start position */
    uint32_t unresolved_hits;   /* hits left after the fallback (0 unless the collider sweeps into held cloth) */
    bool fallback;              /* the iteration did not converge within max_iterations */
    bool held_all;              /* the fallback ran out of rounds, or the budget ran out: every
                                   cloth vertex was held at x0 */
    bool over_budget;           /* the passes reached def.max_pairs */
    uint64_t pairs_visited;     /* triangle pairs the passes visited */
} weft_ccd_postprocess_stats;

typedef struct weft_ccd_intersections {
    uint32_t cloth_cloth;       /* intersecting pairs of cloth triangles sharing no vertex */
    uint32_t cloth_collider;    /* intersecting cloth–collider triangle pairs */
} weft_ccd_intersections;

typedef struct weft_ccd_metrics {
    double collision_rate;      /* % cloth vertices inside the collider at t = 1 or crossing it */
    double self_collision_rate; /* % cloth vertices involved in SELF_VF / SELF_EE hits */
    uint32_t vertices_inside;   /* cloth vertices strictly inside the closed collider at t = 1 */
    uint32_t vertices_penetrating; /* inside, or involved in a VF / EE / FV hit */
    uint32_t vertices_self;     /* involved in a self hit */
} weft_ccd_metrics;

WEFT_API weft_ccd_world_def weft_default_ccd_world_def(void);

/* Validates the topology (indices in range, no repeated vertex in a triangle) and sizes every buffer. */
WEFT_API weft_result weft_ccd_world_create(weft_context *context, const weft_ccd_world_def *def,
                                           weft_ccd_world **out_world);
WEFT_API void weft_ccd_world_destroy(weft_ccd_world *world);

/* Finds the contacts of the given types (WEFT_CCD_MASK_*) while the cloth moves x0 -> x1 and the
 * collider c0 -> c1 (c0/c1 may be NULL when the world has no collider). The first max_hits hits are
 * kept for weft_ccd_hits(); report (may be NULL) gets the counts. */
WEFT_API weft_result weft_ccd_detect(weft_ccd_world *world, const float *x0, const float *x1, const float *c0,
                                     const float *c1, uint32_t types, weft_ccd_report *report);

/* The hits kept by the last weft_ccd_detect (valid until the next call on the world). */
WEFT_API const weft_ccd_hit *weft_ccd_hits(const weft_ccd_world *world, uint32_t *count);

/* Cloth vertices known to start inside the collider (nonzero entries of `inside`, cloth vertex
 * count long; NULL clears): until the next call, detection and the post-process skip every
 * cloth-collider pair with one of them (VF and EE of their features, FV of their triangles), so
 * they can leave the collider, which the post-process would otherwise stop as a crossing. Their
 * self contacts are still resolved. x0 is then intersection-free except for these vertices, and
 * the certificate covers the rest. The garment's collider push sets this (weft.h). */
WEFT_API weft_result weft_ccd_world_let_out(weft_ccd_world *world, const uint8_t *inside);

/* The iterative post-process: detect all five types (self types when def.self_collision), move the
 * cloth vertices of every hit back along their path to t_safe = max(0, toi - time_margin), repeat
 * until clean or max_iterations; then fall back: cloth vertices hit by the collider move with it
 * (x0 plus the collider's displacement there), the others of the remaining hits are held at x0.
 * x1 is changed in place. x0 must be intersection-free (but for vertices let out, see above). The result is certified by a final clean
 * detection pass. Returns WEFT_OK, or WEFT_ERROR_NOT_CONVERGED when hits remain after the fallback
 * (stats->unresolved_hits). */
WEFT_API weft_result weft_ccd_postprocess(weft_ccd_world *world, const float *x0, float *x1, const float *c0,
                                          const float *c1, weft_ccd_postprocess_stats *stats);

/* Discrete check of one frame with exact predicates: cloth–cloth (non-adjacent) and cloth–collider
 * triangle pairs that intersect. */
WEFT_API weft_result weft_ccd_intersect_frame(weft_ccd_world *world, const float *x, const float *c,
                                              weft_ccd_intersections *out);

/* The collision metrics of one step (ClothTransformer App. G). */
WEFT_API weft_result weft_ccd_compute_metrics(weft_ccd_world *world, const float *x0, const float *x1,
                                              const float *c0, const float *c1, weft_ccd_metrics *out);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_CCD_H */
