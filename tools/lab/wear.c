/* Wear measures of a garment on its body (wear.h). */
#include "weft/wear.h"
#include "core/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define WEAR_GRID 128
#define WEAR_CLEAR_M 0.05f    /* inside_clear: no buried body vertex within this distance */
#define WEAR_HASH 4096u       /* buckets of the buried vertices' hash grid (cells of WEAR_CLEAR_M) */

struct weft_wear {
    const uint32_t *tris;
    uint32_t nt, nbv, ngv;
    float lo[2], inv_cell[2];
    uint32_t *cell_start;     /* WEAR_GRID^2 + 1 */
    uint32_t *cell_tris;      /* capacity entries */
    size_t capacity;
    float *normals;           /* nbv * 3: area-weighted vertex normals (self overlap) */
    float *probe;             /* nbv * 3 */
    uint32_t *hash_start;     /* WEAR_HASH + 1: buried body vertices by cell (inside_clear) */
    uint32_t *hash_verts;     /* nbv */
    uint8_t *buried;          /* nbv */
};

weft_result weft_wear_create(const uint32_t *body_triangles, uint32_t body_triangle_count, uint32_t body_vertex_count,
                             uint32_t garment_vertex_count, weft_wear **out)
{
    if (!body_triangles || body_triangle_count == 0 || body_vertex_count == 0 || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_wear_create: a body mesh is required");
    }
    weft_wear *w = calloc(1, sizeof *w);
    if (!w) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    w->tris = body_triangles;
    w->nt = body_triangle_count;
    w->nbv = body_vertex_count;
    w->ngv = garment_vertex_count;
    w->capacity = (size_t)body_triangle_count * 4;
    w->cell_start = malloc(((size_t)WEAR_GRID * WEAR_GRID + 1) * sizeof(uint32_t));
    w->cell_tris = malloc(w->capacity * sizeof(uint32_t));
    w->normals = malloc((size_t)body_vertex_count * 3 * sizeof(float));
    w->probe = malloc((size_t)body_vertex_count * 3 * sizeof(float));
    w->hash_start = malloc((WEAR_HASH + 1) * sizeof(uint32_t));
    w->hash_verts = malloc((size_t)body_vertex_count * sizeof(uint32_t));
    w->buried = malloc(body_vertex_count);
    if (!w->cell_start || !w->cell_tris || !w->normals || !w->probe || !w->hash_start || !w->hash_verts ||
        !w->buried) {
        weft_wear_destroy(w);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *out = w;
    return WEFT_OK;
}

void weft_wear_destroy(weft_wear *w)
{
    if (w) {
        free(w->cell_start);
        free(w->cell_tris);
        free(w->normals);
        free(w->probe);
        free(w->hash_start);
        free(w->hash_verts);
        free(w->buried);
        free(w);
    }
}

struct weft_wear_memo {
    uint32_t nbv, frames, words;  /* words: 64-bit words of one frame's bits */
    uint64_t *sum;                /* frames: checksum of the body positions measured (0: none yet) */
    uint32_t *count;              /* frames: buried vertices */
    uint64_t *bits;               /* frames * words: the buried vertices */
};

weft_result weft_wear_memo_create(uint32_t body_vertex_count, uint32_t frames, weft_wear_memo **out)
{
    if (body_vertex_count == 0 || frames == 0 || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_wear_memo_create: a body vertex count and frames are required");
    }
    weft_wear_memo *m = calloc(1, sizeof *m);
    if (!m) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    m->nbv = body_vertex_count;
    m->frames = frames;
    m->words = (body_vertex_count + 63) / 64;
    m->sum = calloc(frames, sizeof(uint64_t));
    m->count = calloc(frames, sizeof(uint32_t));
    m->bits = calloc((size_t)frames * m->words, sizeof(uint64_t));
    if (!m->sum || !m->count || !m->bits) {
        weft_wear_memo_destroy(m);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *out = m;
    return WEFT_OK;
}

void weft_wear_memo_destroy(weft_wear_memo *m)
{
    if (m) {
        free(m->sum);
        free(m->count);
        free(m->bits);
        free(m);
    }
}

/* A 64-bit checksum of the positions' bits (never 0, the memo's "none yet"). */
static uint64_t body_sum(const float *body, uint32_t nbv)
{
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (size_t i = 0; i < (size_t)nbv * 3; ++i) {
        uint32_t b;
        memcpy(&b, body + i, sizeof b);
        h = (h ^ b) * 0x100000001b3ull;
        h ^= h >> 29;
    }
    return h ? h : 1;
}

static void cell_range(const weft_wear *w, float lo0, float hi0, float lo1, float hi1, int r[4])
{
    const float a[4] = {lo0, hi0, lo1, hi1};
    for (int k = 0; k < 4; ++k) {
        const int axis = k / 2;
        float c = (a[k] - w->lo[axis]) * w->inv_cell[axis];
        int i = (int)floorf(c);
        r[k] = i < 0 ? 0 : (i >= WEAR_GRID ? WEAR_GRID - 1 : i);
    }
}

/* Bins the body's triangles by their XZ bounds. */
static weft_result bin(weft_wear *w, const float *body)
{
    float lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t i = 0; i < (size_t)w->nbv * 3; ++i) {
        if (!isfinite(body[i])) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_wear_measure: body position %zu is not finite", i / 3);
        }
    }
    for (uint32_t v = 0; v < w->nbv; ++v) {
        for (int a = 0; a < 2; ++a) {
            const float c = body[3 * (size_t)v + 2 * a]; /* x, then z */
            lo[a] = c < lo[a] ? c : lo[a];
            hi[a] = c > hi[a] ? c : hi[a];
        }
    }
    for (int a = 0; a < 2; ++a) {
        if (!(hi[a] >= lo[a]) || !isfinite(lo[a]) || !isfinite(hi[a])) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_wear_measure: body positions are not finite");
        }
        const float span = hi[a] - lo[a] > 1e-6f ? hi[a] - lo[a] : 1e-6f;
        w->lo[a] = lo[a];
        w->inv_cell[a] = (float)WEAR_GRID / span * 0.9999f;
    }
    const size_t cells = (size_t)WEAR_GRID * WEAR_GRID;
    memset(w->cell_start, 0, (cells + 1) * sizeof(uint32_t));
    size_t total = 0;
    for (int pass = 0; pass < 2; ++pass) {
        for (uint32_t t = 0; t < w->nt; ++t) {
            const uint32_t *tri = w->tris + 3 * (size_t)t;
            float tlo[2] = {INFINITY, INFINITY}, thi[2] = {-INFINITY, -INFINITY};
            for (int k = 0; k < 3; ++k) {
                for (int a = 0; a < 2; ++a) {
                    const float c = body[3 * (size_t)tri[k] + 2 * a];
                    tlo[a] = c < tlo[a] ? c : tlo[a];
                    thi[a] = c > thi[a] ? c : thi[a];
                }
            }
            int r[4];
            cell_range(w, tlo[0], thi[0], tlo[1], thi[1], r);
            for (int i = r[0]; i <= r[1]; ++i) {
                for (int j = r[2]; j <= r[3]; ++j) {
                    const size_t c = (size_t)i * WEAR_GRID + (size_t)j;
                    if (pass == 0) {
                        w->cell_start[c + 1]++;
                        total++;
                    } else {
                        w->cell_tris[w->cell_start[c]++] = t;
                    }
                }
            }
        }
        if (pass == 0) {
            if (total > w->capacity) { /* grows only when a frame needs more than any before */
                uint32_t *grown = realloc(w->cell_tris, total * sizeof(uint32_t));
                if (!grown) {
                    return WEFT_ERROR_OUT_OF_MEMORY;
                }
                w->cell_tris = grown;
                w->capacity = total;
            }
            for (size_t c = 0; c < cells; ++c) {
                w->cell_start[c + 1] += w->cell_start[c];
            }
        }
    }
    for (size_t c = cells; c > 0; --c) { /* the fill advanced each start to the next cell's */
        w->cell_start[c] = w->cell_start[c - 1];
    }
    w->cell_start[0] = 0;
    return WEFT_OK;
}

/* Winding number of the body around p, counted along the ray +Y. */
static int winding(const weft_wear *w, const float *body, const float *p)
{
    int r[4];
    cell_range(w, p[0], p[0], p[2], p[2], r);
    if (p[0] < w->lo[0] || p[2] < w->lo[1]) {
        return 0;
    }
    const size_t c = (size_t)r[0] * WEAR_GRID + (size_t)r[2];
    int wn = 0;
    for (uint32_t s = w->cell_start[c]; s < w->cell_start[c + 1]; ++s) {
        const uint32_t *tri = w->tris + 3 * (size_t)w->cell_tris[s];
        const float *a = body + 3 * (size_t)tri[0], *b = body + 3 * (size_t)tri[1], *d = body + 3 * (size_t)tri[2];
        /* 2D (x, z) barycentrics of p; the triangle's signed XZ area decides which way it faces */
        const double ax = a[0] - p[0], az = a[2] - p[2], bx = b[0] - p[0], bz = b[2] - p[2], dx = d[0] - p[0],
                     dz = d[2] - p[2];
        const double w0 = bx * dz - bz * dx, w1 = dx * az - dz * ax, w2 = ax * bz - az * bx;
        const double area = w0 + w1 + w2;
        if (area == 0.0) {
            continue; /* vertical triangle: the ray grazes it */
        }
        /* strictly inside (a ray through an edge or a corner has probability zero for the
         * positions measured here) */
        const bool in = area > 0.0 ? (w0 > 0.0 && w1 > 0.0 && w2 > 0.0) : (w0 < 0.0 && w1 < 0.0 && w2 < 0.0);
        if (!in) {
            continue;
        }
        const double y = (w0 * a[1] + w1 * b[1] + w2 * d[1]) / area;
        if (y <= p[1]) {
            continue;
        }
        /* counter-clockwise seen from outside: the normal's Y is -(signed XZ area) in this
         * (x, z) order, so a negative area faces up and the ray leaves the body there */
        wn += area < 0.0 ? 1 : -1;
    }
    return wn;
}

/* The hash bucket of integer cell (i, j, k). */
static uint32_t hash_cell(int32_t i, int32_t j, int32_t k)
{
    const uint32_t h = (uint32_t)i * 73856093u ^ (uint32_t)j * 19349663u ^ (uint32_t)k * 83492791u;
    return h % WEAR_HASH;
}

static void cell_of(const float *p, int32_t c[3])
{
    for (int a = 0; a < 3; ++a) {
        c[a] = (int32_t)floorf(p[a] / WEAR_CLEAR_M);
    }
}

/* The buried body vertices (w->buried) into the hash grid. */
static void hash_buried(weft_wear *w, const float *body)
{
    memset(w->hash_start, 0, (WEAR_HASH + 1) * sizeof(uint32_t));
    for (int pass = 0; pass < 2; ++pass) {
        for (uint32_t v = 0; v < w->nbv; ++v) {
            if (!w->buried[v]) {
                continue;
            }
            int32_t c[3];
            cell_of(body + 3 * (size_t)v, c);
            const uint32_t h = hash_cell(c[0], c[1], c[2]);
            if (pass == 0) {
                w->hash_start[h + 1]++;
            } else {
                w->hash_verts[w->hash_start[h]++] = v;
            }
        }
        if (pass == 0) {
            for (uint32_t h = 0; h < WEAR_HASH; ++h) {
                w->hash_start[h + 1] += w->hash_start[h];
            }
        }
    }
    for (uint32_t h = WEAR_HASH; h > 0; --h) {
        w->hash_start[h] = w->hash_start[h - 1];
    }
    w->hash_start[0] = 0;
}

/* Whether a buried body vertex lies within WEAR_CLEAR_M of p. */
static bool near_buried(const weft_wear *w, const float *body, const float *p)
{
    int32_t c[3];
    cell_of(p, c);
    const float r2 = WEAR_CLEAR_M * WEAR_CLEAR_M;
    for (int32_t di = -1; di <= 1; ++di) {
        for (int32_t dj = -1; dj <= 1; ++dj) {
            for (int32_t dk = -1; dk <= 1; ++dk) {
                const uint32_t h = hash_cell(c[0] + di, c[1] + dj, c[2] + dk);
                for (uint32_t s = w->hash_start[h]; s < w->hash_start[h + 1]; ++s) {
                    const float *q = body + 3 * (size_t)w->hash_verts[s];
                    const float e[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
                    if (e[0] * e[0] + e[1] * e[1] + e[2] * e[2] <= r2) {
                        return true;
                    }
                }
            }
        }
    }
    return false;
}

/* Marks the body vertices another part of the body reaches within `reach` along the vertex normal
 * (w->normals, of this body) and hashes them; returns how many. With a memo, the marks of frame
 * `frame` come from it when it holds this body there, else they are stored in it. */
static uint32_t mark_buried(weft_wear *w, const float *body, float reach, weft_wear_memo *memo, uint32_t frame)
{
    uint64_t sum = 0, *bits = NULL;
    if (memo) {
        sum = body_sum(body, w->nbv);
        bits = memo->bits + (size_t)frame * memo->words;
        if (memo->sum[frame] == sum) {
            for (uint32_t v = 0; v < w->nbv; ++v) {
                w->buried[v] = (uint8_t)(bits[v / 64] >> (v % 64) & 1u);
            }
            hash_buried(w, body);
            return memo->count[frame];
        }
    }
    uint32_t buried = 0;
    for (uint32_t v = 0; v < w->nbv; ++v) {
        const float *n = w->normals + 3 * (size_t)v, *p = body + 3 * (size_t)v;
        const float len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const float s = len > 0.0f ? reach / len : 0.0f;
        const float q[3] = {p[0] + s * n[0], p[1] + s * n[1], p[2] + s * n[2]};
        w->buried[v] = winding(w, body, q) > 0;
        buried += w->buried[v];
    }
    if (memo) {
        memset(bits, 0, memo->words * sizeof(uint64_t));
        for (uint32_t v = 0; v < w->nbv; ++v) {
            bits[v / 64] |= (uint64_t)w->buried[v] << (v % 64);
        }
        memo->sum[frame] = sum;
        memo->count[frame] = buried;
    }
    hash_buried(w, body);
    return buried;
}

weft_result weft_wear_near_overlap(weft_wear *w, const float *body, float reach, const float *points, uint32_t count,
                                   uint8_t *out)
{
    if (!w || !body || !points || !out || !(reach >= 0.0f && reach <= 0.1f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_wear_near_overlap: all arrays are required and reach in [0, 0.1] m");
    }
    (void)mark_buried(w, body, reach, NULL, 0); /* the normals are weft_wear_measure's, of this body */
    for (uint32_t i = 0; i < count; ++i) {
        out[i] = near_buried(w, body, points + 3 * (size_t)i);
    }
    return WEFT_OK;
}

weft_result weft_wear_measure(weft_wear *w, const float *body, const float *garment, const float *skinned,
                              float off_distance, weft_wear_frame *out)
{
    return weft_wear_measure_memo(w, NULL, 0, body, garment, skinned, off_distance, out);
}

weft_result weft_wear_measure_memo(weft_wear *w, weft_wear_memo *memo, uint32_t frame, const float *body,
                                   const float *garment, const float *skinned, float off_distance, weft_wear_frame *out)
{
    if (!w || !body || !garment || !skinned || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_wear_measure: every array is required");
    }
    if (memo && (memo->nbv != w->nbv || frame >= memo->frames)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_wear_measure_memo: frame %u of a memo of %u frames of %u body vertices (this body: %u)",
                          frame, memo->frames, memo->nbv, w->nbv);
    }
    weft_result r = bin(w, body);
    if (r != WEFT_OK) {
        return r;
    }
    uint32_t off = 0, inside = 0, clear = 0;
    memset(w->normals, 0, (size_t)w->nbv * 3 * sizeof(float));
    for (uint32_t t = 0; t < w->nt; ++t) {
        const uint32_t *tri = w->tris + 3 * (size_t)t;
        const float *a = body + 3 * (size_t)tri[0], *b = body + 3 * (size_t)tri[1], *c = body + 3 * (size_t)tri[2];
        const float u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const float n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        for (int k = 0; k < 3; ++k) {
            for (int j = 0; j < 3; ++j) {
                w->normals[3 * (size_t)tri[k] + j] += n[j];
            }
        }
    }
    const uint32_t buried = mark_buried(w, body, 0.002f, memo, frame);
    const float d2 = off_distance * off_distance;
    for (uint32_t i = 0; i < w->ngv; ++i) {
        const float *x = garment + 3 * (size_t)i, *s = skinned + 3 * (size_t)i;
        const float e[3] = {x[0] - s[0], x[1] - s[1], x[2] - s[2]};
        off += e[0] * e[0] + e[1] * e[1] + e[2] * e[2] > d2;
        if (winding(w, body, x) > 0) {
            inside++;
            clear += !near_buried(w, body, x);
        }
    }
    out->off_body = w->ngv ? (double)off / w->ngv : 0.0;
    out->inside_body = w->ngv ? (double)inside / w->ngv : 0.0;
    out->body_self_overlap = (double)buried / w->nbv;
    out->inside_clear = w->ngv ? (double)clear / w->ngv : 0.0;
    return WEFT_OK;
}

void weft_wear_summary_add(weft_wear_summary *s, const weft_wear_frame *f)
{
    s->frames++;
    s->frames_off += f->off_body > 0.01;
    s->off_body_max = f->off_body > s->off_body_max ? f->off_body : s->off_body_max;
    s->inside_mean += (f->inside_body - s->inside_mean) / s->frames;
    s->inside_max = f->inside_body > s->inside_max ? f->inside_body : s->inside_max;
    s->overlap_mean += (f->body_self_overlap - s->overlap_mean) / s->frames;
    s->overlap_max = f->body_self_overlap > s->overlap_max ? f->body_self_overlap : s->overlap_max;
    s->inside_clear_mean += (f->inside_clear - s->inside_clear_mean) / s->frames;
    s->inside_clear_max = f->inside_clear > s->inside_clear_max ? f->inside_clear : s->inside_clear_max;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

double weft_wear_percentile(double *values, uint32_t n, double p)
{
    if (n == 0) {
        return NAN;
    }
    qsort(values, n, sizeof *values, cmp_double);
    double rank = ceil(p / 100.0 * n);
    uint32_t i = rank < 1.0 ? 0 : (uint32_t)rank - 1;
    return values[i < n ? i : n - 1];
}
