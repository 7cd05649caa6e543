/* How a worn garment sits on its body, frame by frame: the measures the render sample, `weft
 * render` and the stability suite report for real motion, and simgen's real-motion acceptance
 * checks (docs/WEAR.md, *Wear measures*).
 *
 *   off_body           share of garment vertices farther than a distance (10 cm; 25 cm for skirts
 *                      and dresses) from the same garment skinned to the body; a clip loses the
 *                      garment when any frame is over 1 %.
 *   inside_body        share of garment vertices inside the body volume. The body of a real
 *                      character overlaps itself, so "inside" is the winding number of the body
 *                      surface around the point (>= 1), which counts a point inside two
 *                      overlapping parts once and is exact for any closed, outward-wound body.
 *   body_self_overlap  share of body vertices inside the body once moved 2 mm out along their
 *                      normal: how much of the character is buried in another of its parts.
 *   inside_clear       share of garment vertices inside the body with no buried body vertex
 *                      (as body_self_overlap counts them) within 5 cm: cloth inside the body
 *                      where the body does not overlap itself, which no rule about overlapping
 *                      parts explains.
 *
 * The winding number is counted along a vertical ray from each point: every body triangle whose
 * XZ projection holds the point and which lies above it adds +1 when it faces up (the ray
 * leaves the body there) and -1 when it faces down. Triangles are binned once per frame on a
 * grid over their XZ bounds; nothing is allocated after creation. */
#ifndef WEFT_WEAR_H
#define WEFT_WEAR_H

#include "weft.h"
#include "weft/body.h"

/* The worn-garment recipe (docs/WEAR.md): the max distance to the skinned garment (T-shirts,
 * skirts, dresses), the collider push and the depth it reaches, and for the learned model a strain
 * limit and a collider token cap. The game methods wear garments with it, and simgen's reference
 * on real motion with the same max distance, push and floor. */
#define WEFT_WORN_TETHER_CM 8.0f
#define WEFT_WORN_TETHER_SKIRT_CM 16.0f
#define WEFT_WORN_TETHER_DRESS_CM 12.0f
#define WEFT_WORN_PUSH_CM 0.5f
#define WEFT_WORN_PUSH_DEPTH_CM 6.0f
#define WEFT_WORN_STRAIN_PCT 10.0f
#define WEFT_WORN_COLLIDER_TOKENS 1024u

/* The max distance of simgen's reference on real motion (the ground truth), in cm:
 * WEFT_WORN_TETHER_CM for a T-shirt; 0 (none) for a skirt or dress, which hangs from its waistband
 * instead (docs/REFSIM.md, Real motion). The game-facing recipe (weft_sample_worn_def, the
 * stability suite's reference rows) keeps the max distance for every garment. */
static inline float weft_wear_reference_tether_cm(weft_cloth_kind kind)
{
    return kind == WEFT_CLOTH_SKIRT || kind == WEFT_CLOTH_DRESS ? 0.0f : WEFT_WORN_TETHER_CM;
}

/* Whether simgen's reference on real motion holds the cloth the body squeezed at the frame before
 * to its cloth-cloth bounds after the body's projection (weft__xpbd_set_bounded_projection): a
 * skirt or dress, whose layers the legs and arms press together; not a T-shirt, of which it kept
 * fewer frames (docs/REFSIM.md, Real motion, has the measurements). */
static inline bool weft_wear_reference_holds_squeeze(weft_cloth_kind kind)
{
    return kind == WEFT_CLOTH_SKIRT || kind == WEFT_CLOTH_DRESS;
}

typedef struct weft_wear weft_wear;

typedef struct weft_wear_frame {
    double off_body;            /* share, 0..1 */
    double inside_body;         /* share, 0..1 */
    double body_self_overlap;   /* share, 0..1 */
    double inside_clear;        /* share, 0..1 (<= inside_body) */
} weft_wear_frame;

/* body_triangles: the body's closed, outward-wound mesh; garment_vertex_count: the garment
 * drawn. Fails with WEFT_ERROR_INVALID_ARGUMENT on zero counts or NULL triangles. */
weft_result weft_wear_create(const uint32_t *body_triangles, uint32_t body_triangle_count, uint32_t body_vertex_count,
                             uint32_t garment_vertex_count, weft_wear **out);
void weft_wear_destroy(weft_wear *w);
/* One frame: body positions, garment positions, the garment skinned to the body, and the
 * off-body distance in metres. */
weft_result weft_wear_measure(weft_wear *w, const float *body, const float *garment, const float *skinned,
                              float off_distance, weft_wear_frame *out);

/* A memo of the body's self-overlap (the buried vertices body_self_overlap and inside_clear read)
 * per frame of one motion, for measuring several garments or methods on the same body frames: the
 * body is measured once per frame instead of once per garment. It holds one bit per body vertex and
 * frame. */
typedef struct weft_wear_memo weft_wear_memo;
/* Fails with WEFT_ERROR_INVALID_ARGUMENT on zero counts. */
weft_result weft_wear_memo_create(uint32_t body_vertex_count, uint32_t frames, weft_wear_memo **out);
void weft_wear_memo_destroy(weft_wear_memo *m);
/* weft_wear_measure, with the body's buried vertices of frame `frame` (< the memo's frames) read
 * from the memo when it holds that frame of this very body (a 64-bit checksum of the positions'
 * bits; else they are measured and stored there): the same figures as weft_wear_measure. A memo
 * of another body vertex count or a frame past its end fails with WEFT_ERROR_INVALID_ARGUMENT. */
weft_result weft_wear_measure_memo(weft_wear *w, weft_wear_memo *memo, uint32_t frame, const float *body,
                                   const float *garment, const float *skinned, float off_distance, weft_wear_frame *out);

/* After weft_wear_measure on this body: for each point, 1 when within 5 cm of a body vertex that
 * another part of the body reaches within `reach` metres (the vertex moved `reach` out along its
 * normal is inside the body: parts that overlap or nearly touch), else 0. Changes nothing the
 * measure returned. */
weft_result weft_wear_near_overlap(weft_wear *w, const float *body, float reach, const float *points, uint32_t count,
                                   uint8_t *out);

/* The summary of a clip: per-frame figures fed one at a time. */
typedef struct weft_wear_summary {
    uint32_t frames;
    uint32_t frames_off;        /* frames with off_body over 1 % */
    double off_body_max;
    double inside_mean, inside_max;
    double overlap_mean, overlap_max;
    double inside_clear_mean, inside_clear_max;
} weft_wear_summary;
void weft_wear_summary_add(weft_wear_summary *s, const weft_wear_frame *f);

/* p-th percentile (0..100) of n values, sorted in place (nearest rank). */
double weft_wear_percentile(double *values, uint32_t n, double p);

#endif
