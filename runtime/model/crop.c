/* Collider cropping for the learned model (runtime/model/crop.h). */
#include "model/crop.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CROP_CELLS (WEFT_CROP_GRID_MAX * WEFT_CROP_GRID_MAX * WEFT_CROP_GRID_MAX)
#define CROP_FINE_CELLS (WEFT_CROP_FINE_MAX * WEFT_CROP_FINE_MAX * WEFT_CROP_FINE_MAX)

static int cmp_u64(const void *a, const void *b)
{
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Spreads the low 10 bits of v to every third bit. */
static uint32_t morton_spread(uint32_t v)
{
    v &= 1023u;
    v = (v | v << 16) & 0x030000ffu;
    v = (v | v << 8) & 0x0300f00fu;
    v = (v | v << 4) & 0x030c30c3u;
    v = (v | v << 2) & 0x09249249u;
    return v;
}

static uint32_t bit_reverse(uint32_t v, uint32_t bits)
{
    uint32_t r = 0;
    for (uint32_t b = 0; b < bits; ++b) {
        r = r << 1 | (v >> b & 1u);
    }
    return r;
}

/* Centroid of triangle `tri` over `pos`, in separate statements (no fused multiply-add may
 * change it on any target: the keys built from it must be the same on every ISA). */
static void tri_centroid(const float *pos, const uint32_t *tri, float out[3])
{
    for (int d = 0; d < 3; ++d) {
        const float s01 = pos[3 * (size_t)tri[0] + d] + pos[3 * (size_t)tri[1] + d];
        out[d] = (s01 + pos[3 * (size_t)tri[2] + d]) / 3.0f;
    }
}

/* The sample cap's order: rest centroids along a Morton curve (10 bits an axis over their box,
 * ties by index), then that list read in bit-reversed position order. `keys` is scratch for
 * triangle_count entries. */
static void sample_order(weft_crop *c, const float *rest, const uint32_t *tris, uint64_t *keys)
{
    const uint32_t m = c->triangle_count;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t t = 0; t < m; ++t) {
        float at[3];
        tri_centroid(rest, tris + 3 * (size_t)t, at);
        for (int d = 0; d < 3; ++d) {
            lo[d] = at[d] < lo[d] ? at[d] : lo[d];
            hi[d] = at[d] > hi[d] ? at[d] : hi[d];
        }
    }
    for (uint32_t t = 0; t < m; ++t) {
        float at[3];
        tri_centroid(rest, tris + 3 * (size_t)t, at);
        uint32_t code = 0;
        for (int d = 0; d < 3; ++d) {
            const float extent = hi[d] - lo[d];
            const float f = extent > 0.0f ? (at[d] - lo[d]) / extent * 1023.0f : 0.0f;
            const uint32_t q = !(f >= 0.0f) ? 0u : f >= 1023.0f ? 1023u : (uint32_t)f; /* NaN: 0 */
            code |= morton_spread(q) << d;
        }
        keys[t] = (uint64_t)code << 32 | t;
    }
    qsort(keys, m, sizeof *keys, cmp_u64);
    uint32_t bits = 0;
    while (bits < 32 && ((uint64_t)1 << bits) < m) {
        bits++;
    }
    uint32_t r = 0;
    for (uint64_t i = 0; i < ((uint64_t)1 << bits) && r < m; ++i) {
        const uint32_t p = bit_reverse((uint32_t)i, bits);
        if (p < m) {
            c->by_rank[r++] = (uint32_t)(keys[p] & 0xffffffffu);
        }
    }
}

weft_result weft__crop_init(weft_context *ctx, weft_crop *crop, float margin, weft_collider_crop rule,
                            uint32_t max_tokens, weft_collider_cap cap, uint32_t vertex_count,
                            uint32_t triangle_count, uint32_t collider_vertex_count, const float *rest,
                            const uint32_t *triangles)
{
    memset(crop, 0, sizeof *crop);
    crop->margin = margin;
    crop->rule = rule;
    crop->max_tokens = max_tokens;
    crop->represented = 1.0f;
    crop->vertex_count = vertex_count;
    crop->triangle_count = triangle_count;
    crop->collider_vertex_count = collider_vertex_count;
    if (triangle_count == 0) {
        return WEFT_OK;
    }
    bool ok = (crop->kept = weft__alloc(ctx, (size_t)triangle_count * sizeof(uint32_t))) != NULL &&
              (crop->side = weft__alloc(ctx, collider_vertex_count ? collider_vertex_count : 1)) != NULL;
    if (ok && rule == WEFT_COLLIDER_CROP_CELLS) {
        ok = (crop->cells = weft__alloc(ctx, (size_t)CROP_CELLS * 6 * sizeof(float))) != NULL;
    }
    if (ok && max_tokens > 0 && max_tokens < triangle_count && cap == WEFT_COLLIDER_CAP_SAMPLE) {
        uint64_t *keys = weft__alloc(ctx, (size_t)triangle_count * sizeof(uint64_t));
        ok = keys && (crop->by_rank = weft__alloc(ctx, (size_t)triangle_count * sizeof(uint32_t))) != NULL &&
             (crop->mark = weft__alloc(ctx, (size_t)triangle_count)) != NULL;
        if (ok) {
            memset(crop->mark, 0, triangle_count);
            sample_order(crop, rest, triangles, keys);
        }
        weft__free(ctx, keys, (size_t)triangle_count * sizeof(uint64_t));
    } else if (ok && max_tokens > 0 && max_tokens < triangle_count) {
        ok = (crop->keys = weft__alloc(ctx, (size_t)triangle_count * sizeof(uint64_t))) != NULL &&
             (crop->fine_start = weft__alloc(ctx, ((size_t)CROP_FINE_CELLS + 1) * sizeof(uint32_t))) != NULL &&
             (crop->fine_order = weft__alloc(ctx, (size_t)vertex_count * sizeof(uint32_t))) != NULL;
    }
    if (!ok) {
        weft__crop_free(ctx, crop);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    return WEFT_OK;
}

void weft__crop_free(const weft_context *ctx, weft_crop *crop)
{
    weft__free(ctx, crop->kept, (size_t)crop->triangle_count * sizeof(uint32_t));
    weft__free(ctx, crop->side, crop->collider_vertex_count ? crop->collider_vertex_count : 1);
    weft__free(ctx, crop->keys, (size_t)crop->triangle_count * sizeof(uint64_t));
    weft__free(ctx, crop->cells, (size_t)CROP_CELLS * 6 * sizeof(float));
    weft__free(ctx, crop->fine_start, ((size_t)CROP_FINE_CELLS + 1) * sizeof(uint32_t));
    weft__free(ctx, crop->fine_order, (size_t)crop->vertex_count * sizeof(uint32_t));
    weft__free(ctx, crop->by_rank, (size_t)crop->triangle_count * sizeof(uint32_t));
    weft__free(ctx, crop->mark, crop->triangle_count);
    memset(crop, 0, sizeof *crop);
}

/* Cell of coordinate v along axis d, clamped to the grid (NaN lands in cell 0). */
static uint32_t cell_of(const weft_crop *c, int d, float v)
{
    float f = (v - c->origin[d]) / c->cell[d];
    if (!(f >= 0.0f)) {
        return 0;
    }
    return f >= (float)c->dims[d] ? c->dims[d] - 1 : (uint32_t)f;
}

static uint32_t fine_cell_of(const weft_crop *c, int d, float v)
{
    float f = (v - c->fine_origin[d]) / c->fine_cell[d];
    if (!(f >= 0.0f)) {
        return 0;
    }
    return f >= (float)c->fine_dims[d] ? c->fine_dims[d] - 1 : (uint32_t)f;
}

static size_t fine_index(const weft_crop *c, const float p[3])
{
    return ((size_t)fine_cell_of(c, 2, p[2]) * c->fine_dims[1] + fine_cell_of(c, 1, p[1])) * c->fine_dims[0] +
           fine_cell_of(c, 0, p[0]);
}

/* Bins the garment's vertices: tight box per cell over the garment's (ungrown) box. Cells are at
 * least one margin wide, so every cell whose tight box lies within a margin of a point is in the
 * point's cell or one of its neighbours. */
static void build_grid(weft_crop *c, const float *x, uint32_t n, const float lo[3], const float hi[3])
{
    for (int d = 0; d < 3; ++d) {
        const float extent = hi[d] - lo[d];
        const float q = extent / c->margin;
        c->dims[d] = !(q >= 1.0f) ? 1u : q >= (float)WEFT_CROP_GRID_MAX ? WEFT_CROP_GRID_MAX : (uint32_t)q;
        c->origin[d] = lo[d];
        c->cell[d] = extent > 0.0f ? extent / (float)c->dims[d] : c->margin;
    }
    const uint32_t total = c->dims[0] * c->dims[1] * c->dims[2];
    for (uint32_t i = 0; i < total; ++i) {
        float *b = c->cells + 6 * (size_t)i;
        b[0] = b[1] = b[2] = INFINITY;
        b[3] = b[4] = b[5] = -INFINITY;
    }
    for (uint32_t v = 0; v < n; ++v) {
        const float *p = x + 3 * (size_t)v;
        const uint32_t i = cell_of(c, 0, p[0]), j = cell_of(c, 1, p[1]), k = cell_of(c, 2, p[2]);
        float *b = c->cells + 6 * (((size_t)k * c->dims[1] + j) * c->dims[0] + i);
        for (int d = 0; d < 3; ++d) {
            b[d] = p[d] < b[d] ? p[d] : b[d];
            b[3 + d] = p[d] > b[3 + d] ? p[d] : b[3 + d];
        }
    }
}

/* Whether an occupied cell's tight box grown by the margin overlaps the triangle box [tl, th].
 * Only cells within a margin of the triangle box can: at most 3 per axis for small triangles. */
static bool near_cells(const weft_crop *c, const float tl[3], const float th[3])
{
    const float m = c->margin;
    uint32_t a[3], b[3];
    for (int d = 0; d < 3; ++d) {
        a[d] = cell_of(c, d, tl[d] - m);
        b[d] = cell_of(c, d, th[d] + m);
    }
    for (uint32_t k = a[2]; k <= b[2]; ++k) {
        for (uint32_t j = a[1]; j <= b[1]; ++j) {
            for (uint32_t i = a[0]; i <= b[0]; ++i) {
                const float *q = c->cells + 6 * (((size_t)k * c->dims[1] + j) * c->dims[0] + i);
                bool overlap = q[0] <= q[3]; /* occupied */
                for (int d = 0; d < 3 && overlap; ++d) {
                    overlap = tl[d] <= q[3 + d] + m && th[d] >= q[d] - m;
                }
                if (overlap) {
                    return true;
                }
            }
        }
    }
    return false;
}

/* Fine grid for the cap's nearest-vertex search: cells of at least a quarter margin (at most
 * WEFT_CROP_FINE_MAX per axis) over the garment's box, vertices listed per cell (counting sort,
 * so the lists of cells adjacent along x are adjacent too). */
static void build_fine(weft_crop *c, const float *x, uint32_t n, const float lo[3], const float hi[3])
{
    const float h = 0.25f * c->margin;
    for (int d = 0; d < 3; ++d) {
        const float extent = hi[d] - lo[d];
        const float q = extent / h;
        c->fine_dims[d] = !(q >= 1.0f) ? 1u : q >= (float)WEFT_CROP_FINE_MAX ? WEFT_CROP_FINE_MAX : (uint32_t)q;
        c->fine_origin[d] = lo[d];
        /* At least h even along a thin axis (one cell): the 3 x 3 x 3 search relies on it. */
        const float w = extent / (float)c->fine_dims[d];
        c->fine_cell[d] = w > h ? w : h;
    }
    const uint32_t total = c->fine_dims[0] * c->fine_dims[1] * c->fine_dims[2];
    uint32_t *start = c->fine_start;
    memset(start, 0, ((size_t)total + 1) * sizeof *start);
    for (uint32_t v = 0; v < n; ++v) {
        start[fine_index(c, x + 3 * (size_t)v) + 1]++;
    }
    for (uint32_t i = 0; i < total; ++i) {
        start[i + 1] += start[i];
    }
    for (uint32_t v = 0; v < n; ++v) { /* start[i] walks to the end of cell i ... */
        c->fine_order[start[fine_index(c, x + 3 * (size_t)v)]++] = v;
    }
    for (uint32_t i = total; i > 0; --i) { /* ... and is moved back to its beginning */
        start[i] = start[i - 1];
    }
    start[0] = 0;
}

/* Squared distance from p to the nearest garment vertex among the 3 x 3 x 3 fine cells around
 * p's cell. Cells are at least a quarter margin (h) wide on every axis, so every vertex within h
 * of p is in that block: the key is exact up to h, and beyond h it is the block's nearest (an
 * upper bound, still above every exact key), +inf for an empty block. Searching wider for the
 * far triangles would cost more than the tokens the cap saves (most of an avatar's triangles in
 * a T-shirt's box are far from the cloth). */
static float nearest_vertex_d2(const weft_crop *c, const float *x, const float p[3])
{
    uint32_t a[3], b[3];
    for (int d = 0; d < 3; ++d) {
        const uint32_t at = fine_cell_of(c, d, p[d]);
        a[d] = at > 0 ? at - 1 : 0;
        b[d] = at + 1 < c->fine_dims[d] ? at + 1 : at;
    }
    float best = INFINITY;
    for (uint32_t k = a[2]; k <= b[2]; ++k) {
        for (uint32_t j = a[1]; j <= b[1]; ++j) {
            const size_t row = ((size_t)k * c->fine_dims[1] + j) * c->fine_dims[0];
            /* the block's cells along x are contiguous, and so are their vertex lists */
            for (uint32_t e = c->fine_start[row + a[0]]; e < c->fine_start[row + b[0] + 1]; ++e) {
                const float *v = x + 3 * (size_t)c->fine_order[e];
                /* Separate statements: no fused multiply-add may change the key on any target. */
                const float dx = v[0] - p[0], dy = v[1] - p[1], dz = v[2] - p[2];
                const float sx = dx * dx;
                const float sy = dy * dy;
                const float sz = dz * dz;
                const float s = sx + sy + sz;
                best = s < best ? s : best;
            }
        }
    }
    return best;
}

/* The key of rank `need` (1-based) among keys[0..n), all distinct: most significant byte first. */
static uint64_t kth_key(const uint64_t *keys, uint32_t n, uint32_t need)
{
    uint64_t prefix = 0, mask = 0;
    for (int shift = 56; shift >= 0; shift -= 8) {
        uint32_t hist[256] = {0};
        for (uint32_t i = 0; i < n; ++i) {
            if ((keys[i] & mask) == prefix) {
                hist[(keys[i] >> shift) & 255u]++;
            }
        }
        uint32_t b = 0;
        while (hist[b] < need) {
            need -= hist[b];
            b++;
        }
        prefix |= (uint64_t)b << shift;
        mask |= (uint64_t)255u << shift;
    }
    return prefix;
}

uint32_t weft__crop_select(weft_crop *c, const float *x, uint32_t n, const float *cn, const uint32_t *tris)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; ++i) {
        for (int d = 0; d < 3; ++d) {
            float v = x[3 * (size_t)i + d];
            lo[d] = v < lo[d] ? v : lo[d];
            hi[d] = v > hi[d] ? v : hi[d];
        }
    }
    const bool cells = c->rule == WEFT_COLLIDER_CROP_CELLS;
    if (cells) {
        build_grid(c, x, n, lo, hi);
    }
    float glo[3], ghi[3];
    for (int d = 0; d < 3; ++d) {
        glo[d] = lo[d] - c->margin;
        ghi[d] = hi[d] + c->margin;
    }
    /* The box test by vertex: a triangle's box misses the grown box on an axis exactly when its
     * three corners are all below it or all above it (min <= hi fails iff every corner > hi), so
     * one byte of side bits a collider vertex and an AND of three bytes a triangle decide it. */
    for (uint32_t v = 0; v < c->collider_vertex_count; ++v) {
        const float *p = cn + 3 * (size_t)v;
        c->side[v] = (uint8_t)((p[0] < glo[0]) | (p[0] > ghi[0]) << 1 | (p[1] < glo[1]) << 2 | (p[1] > ghi[1]) << 3 |
                               (p[2] < glo[2]) << 4 | (p[2] > ghi[2]) << 5);
    }
    uint32_t kept = 0;
    for (uint32_t t = 0; t < c->triangle_count; ++t) {
        const uint32_t *tri = tris + 3 * (size_t)t;
        if (c->side[tri[0]] & c->side[tri[1]] & c->side[tri[2]]) {
            continue;
        }
        if (cells) {
            const float *p[3] = {cn + 3 * (size_t)tri[0], cn + 3 * (size_t)tri[1], cn + 3 * (size_t)tri[2]};
            float tl[3], th[3];
            for (int d = 0; d < 3; ++d) {
                const float a = p[0][d], b = p[1][d], e = p[2][d];
                const float lo2 = a < b ? a : b, hi2 = a < b ? b : a;
                tl[d] = e < lo2 ? e : lo2;
                th[d] = e > hi2 ? e : hi2;
            }
            if (!near_cells(c, tl, th)) {
                continue;
            }
        }
        c->kept[kept++] = t;
    }
    c->represented = 1.0f;
    if (c->by_rank && kept > c->max_tokens) {
        /* Sample: the max_tokens cropped triangles of lowest rank, listed in index order. */
        for (uint32_t k = 0; k < kept; ++k) {
            c->mark[c->kept[k]] = 1;
        }
        for (uint32_t r = 0, taken = 0; taken < c->max_tokens; ++r) {
            const uint32_t t = c->by_rank[r];
            if (c->mark[t]) {
                c->mark[t] = 2;
                taken++;
            }
        }
        uint32_t w = 0;
        for (uint32_t k = 0; k < kept; ++k) {
            const uint32_t t = c->kept[k];
            if (c->mark[t] == 2) {
                c->kept[w++] = t;
            }
            c->mark[t] = 0;
        }
        c->represented = (float)kept / (float)w;
        return w;
    }
    if (!c->keys || kept <= c->max_tokens) {
        return kept;
    }
    /* Over the cap: rank by the centroid's distance to the nearest garment vertex. */
    build_fine(c, x, n, lo, hi);
    for (uint32_t k = 0; k < kept; ++k) {
        float at[3];
        tri_centroid(cn, tris + 3 * (size_t)c->kept[k], at);
        const float d2 = nearest_vertex_d2(c, x, at);
        uint32_t bits;
        memcpy(&bits, &d2, sizeof bits); /* non-negative floats order as their bit patterns */
        c->keys[k] = (uint64_t)bits << 32 | c->kept[k];
    }
    const uint64_t last = kth_key(c->keys, kept, c->max_tokens);
    uint32_t w = 0;
    for (uint32_t k = 0; k < kept; ++k) {
        if (c->keys[k] <= last) {
            c->kept[w++] = c->kept[k];
        }
    }
    return w;
}
