/* Collider cropping for the learned model: which collider triangles become encoder tokens.
 *
 * Each kept triangle costs a per-triangle MLP, the encoder's key/value projections and a column
 * of the encoder's cross-attention, so on an avatar the crop decides most of a step's cost
 * (docs/MODEL_BENCH.md). Rules (weft_collider_crop):
 *
 *   box    the model's own rule (tools/train/model.py crop_mask): a triangle whose box at t+1
 *          overlaps the garment's box at t grown by the margin.
 *   cells  the garment's vertices are binned into a coarse grid (cells at least one margin wide,
 *          at most WEFT_CROP_GRID_MAX per axis); a triangle is kept when its box overlaps the
 *          tight box of an occupied cell grown by the margin. A subset of `box`: a T-shirt's
 *          box also holds the head, hands and legs, its cells do not.
 *
 * An optional cap keeps at most max_tokens of the triangles the rule selected. Two ways
 * (weft_collider_cap):
 *
 *   sample   an even sample: at creation the collider's triangles are ordered by the Morton code of
 *            their rest centroid (10 bits an axis over the rest box, ties by index), and ranked in
 *            the bit-reversed order of that list (van der Corput), so any rank prefix strides
 *            evenly along the curve; a step keeps the max_tokens cropped triangles of lowest rank
 *            and sets `represented` = cropped / kept, the weight the model gives each kept token
 *            in its attention. Integer work per frame: the same set on every ISA.
 *   nearest  the ones whose
 * centroid is nearest to a garment vertex, ties broken by triangle index. The distance is exact
 * up to a quarter margin (a 3 x 3 x 3 block of a fine grid whose cells are at least that wide,
 * at most WEFT_CROP_FINE_MAX per axis); beyond, the block's nearest vertex, and triangles with
 * none in their block go last. Keys are (squared distance bits, index) compared as exact
 * integers and computed in scalar code without fused multiply-adds, so the kept set is the same
 * on every kernel ISA. The kept triangles are listed in ascending index order, the order the
 * uncropped loop visits them, so the `box` rule without a cap gives the tokens it always gave,
 * bit for bit.
 *
 * Everything is sized at creation; weft__crop_select allocates nothing. */
#ifndef WEFT_MODEL_CROP_H
#define WEFT_MODEL_CROP_H

#include "core/core.h"

#define WEFT_CROP_GRID_MAX 16u
#define WEFT_CROP_FINE_MAX 32u

typedef struct weft_crop {
    float margin;                       /* metres, > 0 */
    weft_collider_crop rule;
    uint32_t max_tokens;                /* 0: no cap */
    float represented;                  /* cropped triangles per kept one in the last selection: 1
                                         * unless the sample cap dropped some */
    /* cap sample below triangle_count: triangles by rank, and a per-triangle mark (all 0 between
     * selections) */
    uint32_t *by_rank;
    uint8_t *mark;
    uint32_t vertex_count, triangle_count, collider_vertex_count;
    uint32_t *kept;                     /* triangle_count: the last selection, ascending */
    uint8_t *side;                      /* collider_vertex_count: per axis, bit 2d set below the
                                         * grown box, bit 2d + 1 above it (the box test by bits) */
    /* rule cells: WEFT_CROP_GRID_MAX^3 x 6 tight boxes (lo, hi), and the last frame's grid */
    float *cells;
    uint32_t dims[3];
    float origin[3], cell[3];
    /* cap below triangle_count: keys (distance bits << 32 | index), and the fine grid's
     * per-cell vertex lists (WEFT_CROP_FINE_MAX^3 + 1 starts, vertex_count entries) */
    uint64_t *keys;
    uint32_t *fine_start, *fine_order;
    uint32_t fine_dims[3];
    float fine_origin[3], fine_cell[3];
} weft_crop;

/* Sizes the scratch for a garment of `vertex_count` vertices and `triangle_count` collider
 * triangles over `collider_vertex_count` vertices (`triangles` over `rest`, the collider at rest,
 * order the sample cap; only read for it). On failure nothing is held. */
weft_result weft__crop_init(weft_context *ctx, weft_crop *crop, float margin, weft_collider_crop rule,
                            uint32_t max_tokens, weft_collider_cap cap, uint32_t vertex_count,
                            uint32_t triangle_count, uint32_t collider_vertex_count, const float *rest,
                            const uint32_t *triangles);
void weft__crop_free(const weft_context *ctx, weft_crop *crop);

/* Selects the triangles of the collider at t+1 (`collider`, indexed by `triangles`; finite, as
 * weft_garment_set_collider checks) to turn into tokens for the garment at `x` (`vertex_count`
 * points); fills crop->kept and returns the count. */
uint32_t weft__crop_select(weft_crop *crop, const float *x, uint32_t vertex_count, const float *collider,
                           const uint32_t *triangles);

#endif
