/* A user's skinned character as the collider (character.h). */
#include "character.h"
#include "wear.h"
#include "core/core.h"

#if WEFT_RENDER_HAVE_ASSETS
#include "gltf.h"
#endif

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAX_PARTS 32u
#define MAX_MEDIAN_DISTANCE 0.10
#define MAX_INSIDE_SHARE 0.05

struct weft_sample_character {
#if WEFT_RENDER_HAVE_ASSETS
    weft_skinned_asset *asset;
#endif
    uint8_t *parts;
    uint32_t part_count;
    float *blended;             /* joint_count * 16: the last pose's skinning matrices */
    uint32_t garment_count;     /* the bound garment */
    uint32_t *garment_joints;   /* garment_count * 4 */
    float *garment_weights;     /* garment_count * 4 */
    const float *garment_rest;  /* the caller's, kept while bound */
};

uint32_t weft_sample_nearest_point(const float *points, uint32_t count, const float p[3], double *out_d2)
{
    double best = INFINITY;
    uint32_t nearest = 0;
    for (uint32_t v = 0; v < count; ++v) {
        const float *q = points + 3 * (size_t)v;
        const double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
        const double d = dx * dx + dy * dy + dz * dz;
        if (d < best) {
            best = d, nearest = v;
        }
    }
    *out_d2 = best;
    return nearest;
}

#if WEFT_RENDER_HAVE_ASSETS

/* Each triangle's dominant joint, joints merged into their parents until at most MAX_PARTS are
 * used, numbered in joint order. */
static weft_result make_parts(weft_sample_character *c)
{
    const weft_skinned_asset *a = c->asset;
    const uint32_t nj = a->joint_count;
    uint32_t *owner = malloc((size_t)a->triangle_count * sizeof *owner);
    uint32_t *count = calloc(nj, sizeof *count);
    uint32_t *merged = malloc(nj * sizeof *merged);
    c->parts = malloc(a->triangle_count);
    if (!owner || !count || !merged || !c->parts) {
        free(owner), free(count), free(merged);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "character: out of memory");
    }
    for (uint32_t t = 0; t < a->triangle_count; ++t) {
        float sum[WEFT_SKIN_MAX_JOINTS];
        uint32_t touched[12], nt = 0;
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = a->triangles[3 * (size_t)t + (size_t)k];
            for (int i = 0; i < 4; ++i) {
                const uint32_t j = a->joint_indices[4 * (size_t)v + (size_t)i];
                bool seen = false;
                for (uint32_t q = 0; q < nt; ++q) {
                    seen |= touched[q] == j;
                }
                if (!seen) {
                    touched[nt++] = j;
                    sum[j] = 0.0f;
                }
                sum[j] += a->joint_weights[4 * (size_t)v + (size_t)i];
            }
        }
        uint32_t best = touched[0];
        for (uint32_t q = 1; q < nt; ++q) {
            const uint32_t j = touched[q];
            best = sum[j] > sum[best] || (sum[j] == sum[best] && j < best) ? j : best;
        }
        owner[t] = best;
        count[best]++;
    }
    for (uint32_t j = 0; j < nj; ++j) {
        merged[j] = j;
    }
    for (;;) {
        uint32_t used = 0, smallest = UINT32_MAX;
        for (uint32_t j = 0; j < nj; ++j) {
            if (count[j] > 0) {
                used++;
                /* only joints with a parent can merge; the smallest (then the last) goes first */
                if (c->asset->parents[j] >= 0 && (smallest == UINT32_MAX || count[j] <= count[smallest])) {
                    smallest = j;
                }
            }
        }
        if (used <= MAX_PARTS || smallest == UINT32_MAX) {
            break;
        }
        uint32_t parent = (uint32_t)c->asset->parents[smallest];
        while (merged[parent] != parent) {
            parent = merged[parent]; /* a parent merged earlier: its part now */
        }
        count[parent] += count[smallest];
        count[smallest] = 0;
        for (uint32_t j = 0; j < nj; ++j) {
            merged[j] = merged[j] == smallest ? parent : merged[j];
        }
    }
    /* joints whose parent chain never merged them into a used joint stay their own part */
    uint32_t id_of[WEFT_SKIN_MAX_JOINTS];
    uint32_t ids = 0;
    for (uint32_t j = 0; j < nj; ++j) {
        id_of[j] = UINT32_MAX;
    }
    for (uint32_t j = 0; j < nj; ++j) {
        if (count[j] > 0) {
            id_of[j] = ids++;
        }
    }
    weft_result r = WEFT_OK;
    if (ids > MAX_PARTS) {
        r = weft__fail(WEFT_ERROR_FORMAT, "character: %u body parts remain after merging joints (at most %u; several "
                       "root joints?)", ids, MAX_PARTS);
    }
    for (uint32_t t = 0; r == WEFT_OK && t < a->triangle_count; ++t) {
        uint32_t j = owner[t];
        while (merged[j] != j) {
            j = merged[j];
        }
        c->parts[t] = (uint8_t)id_of[j];
    }
    c->part_count = ids;
    free(owner), free(count), free(merged);
    return r;
}

weft_result weft_sample_character_load(weft_context *context, const char *path, weft_sample_character **out)
{
    if (!context || !path || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sample_character_load: context, path and out are required");
    }
    weft_sample_character *c = calloc(1, sizeof *c);
    if (!c) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "character: out of memory");
    }
    weft_result r = weft_skinned_load_file(context, path, 60.0f, &c->asset);
    if (r == WEFT_OK) {
        const weft_skinned_asset *a = c->asset;
        float lo = INFINITY, hi = -INFINITY;
        for (uint32_t v = 0; v < a->vertex_count; ++v) {
            lo = fminf(lo, a->positions[3 * (size_t)v + 1]);
            hi = fmaxf(hi, a->positions[3 * (size_t)v + 1]);
        }
        if (!(hi - lo >= 0.3f && hi - lo <= 3.0f)) {
            r = weft__fail(WEFT_ERROR_FORMAT,
                           "character '%s': %.3g units tall along Y; weft needs metres with Y up, a character 0.3 to 3 m "
                           "tall (a file in centimetres, or Z up, must be converted first)",
                           path, (double)(hi - lo));
        }
    }
    r = r != WEFT_OK ? r : make_parts(c);
    if (r == WEFT_OK) {
        c->blended = malloc((size_t)c->asset->joint_count * 16 * sizeof(float));
        r = c->blended ? WEFT_OK : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "character: out of memory");
    }
    if (r != WEFT_OK) {
        weft_sample_character_destroy(c);
        return r;
    }
    for (uint32_t j = 0; j < c->asset->joint_count; ++j) {
        float *m = c->blended + 16 * (size_t)j;
        memset(m, 0, 16 * sizeof(float));
        m[0] = m[5] = m[10] = m[15] = 1.0f;
    }
    *out = c;
    return WEFT_OK;
}

void weft_sample_character_destroy(weft_sample_character *c)
{
    if (!c) {
        return;
    }
    weft_skinned_asset_destroy(c->asset);
    free(c->parts);
    free(c->blended);
    free(c->garment_joints);
    free(c->garment_weights);
    free(c);
}

uint32_t weft_sample_character_vertex_count(const weft_sample_character *c) { return c->asset->vertex_count; }
uint32_t weft_sample_character_triangle_count(const weft_sample_character *c) { return c->asset->triangle_count; }
const float *weft_sample_character_bind_vertices(const weft_sample_character *c) { return c->asset->positions; }
const uint32_t *weft_sample_character_triangles(const weft_sample_character *c) { return c->asset->triangles; }
uint32_t weft_sample_character_joint_count(const weft_sample_character *c) { return c->asset->joint_count; }
uint32_t weft_sample_character_frame_count(const weft_sample_character *c) { return c->asset->frame_count; }

const uint8_t *weft_sample_character_parts(const weft_sample_character *c, uint32_t *part_count)
{
    if (part_count) {
        *part_count = c->part_count;
    }
    return c->parts;
}

double weft_sample_character_duration(const weft_sample_character *c)
{
    return (double)(c->asset->frame_count - 1) / (double)c->asset->fps;
}

/* Column-major 3x3 part of m (with scale s per column) -> unit quaternion x y z w. */
static void rotation_of(const float *m, const double s[3], double q[4])
{
    double r[3][3]; /* r[row][col] */
    for (int col = 0; col < 3; ++col) {
        for (int row = 0; row < 3; ++row) {
            r[row][col] = m[4 * col + row] / s[col];
        }
    }
    const double tr = r[0][0] + r[1][1] + r[2][2];
    if (tr > 0.0) {
        double k = 0.5 / sqrt(tr + 1.0);
        q[3] = 0.25 / k, q[0] = (r[2][1] - r[1][2]) * k, q[1] = (r[0][2] - r[2][0]) * k, q[2] = (r[1][0] - r[0][1]) * k;
    } else if (r[0][0] > r[1][1] && r[0][0] > r[2][2]) {
        double k = 2.0 * sqrt(fmax(1.0 + r[0][0] - r[1][1] - r[2][2], 1e-12));
        q[3] = (r[2][1] - r[1][2]) / k, q[0] = 0.25 * k, q[1] = (r[0][1] + r[1][0]) / k, q[2] = (r[0][2] + r[2][0]) / k;
    } else if (r[1][1] > r[2][2]) {
        double k = 2.0 * sqrt(fmax(1.0 + r[1][1] - r[0][0] - r[2][2], 1e-12));
        q[3] = (r[0][2] - r[2][0]) / k, q[0] = (r[0][1] + r[1][0]) / k, q[1] = 0.25 * k, q[2] = (r[1][2] + r[2][1]) / k;
    } else {
        double k = 2.0 * sqrt(fmax(1.0 + r[2][2] - r[0][0] - r[1][1], 1e-12));
        q[3] = (r[1][0] - r[0][1]) / k, q[0] = (r[0][2] + r[2][0]) / k, q[1] = (r[1][2] + r[2][1]) / k, q[2] = 0.25 * k;
    }
    const double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) {
        q[k] /= n > 0.0 ? n : 1.0;
    }
}

/* The identity blended into m by u: rotation slerped from the identity, scale and translation
 * interpolated. */
static void blend_from_identity(const float *m, double u, float *out)
{
    double s[3];
    for (int col = 0; col < 3; ++col) {
        s[col] = sqrt((double)m[4 * col] * m[4 * col] + (double)m[4 * col + 1] * m[4 * col + 1] +
                      (double)m[4 * col + 2] * m[4 * col + 2]);
        s[col] = s[col] > 1e-12 ? s[col] : 1.0;
    }
    double q[4];
    rotation_of(m, s, q);
    if (q[3] < 0.0) {
        for (int k = 0; k < 4; ++k) {
            q[k] = -q[k];
        }
    }
    /* slerp (0,0,0,1) -> q */
    const double angle = acos(fmin(1.0, q[3]));
    double a = 1.0 - u, b = u;
    if (angle > 1e-6) {
        a = sin((1.0 - u) * angle) / sin(angle);
        b = sin(u * angle) / sin(angle);
    }
    const double x = b * q[0], y = b * q[1], z = b * q[2], w = a + b * q[3];
    const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                            {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                            {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    for (int col = 0; col < 3; ++col) {
        const double sc = 1.0 + u * (s[col] - 1.0);
        for (int row = 0; row < 3; ++row) {
            out[4 * col + row] = (float)(r[row][col] * sc);
        }
        out[4 * col + 3] = 0.0f;
    }
    for (int row = 0; row < 3; ++row) {
        out[12 + row] = (float)(u * m[12 + row]);
    }
    out[15] = 1.0f;
}

static void skin_point(const float *mats, const uint32_t *joints, const float *weights, const float *p, float *out)
{
    double acc[3] = {0.0, 0.0, 0.0};
    for (int i = 0; i < 4; ++i) {
        const float w = weights[i];
        if (w == 0.0f) {
            continue;
        }
        const float *m = mats + 16 * (size_t)joints[i];
        for (int row = 0; row < 3; ++row) {
            acc[row] += (double)w * ((double)m[row] * p[0] + (double)m[4 + row] * p[1] + (double)m[8 + row] * p[2] +
                                     (double)m[12 + row]);
        }
    }
    for (int row = 0; row < 3; ++row) {
        out[row] = (float)acc[row];
    }
}

weft_result weft_sample_character_pose(weft_sample_character *c, double t, double u, float *out_vertices)
{
    if (!c || !out_vertices || !isfinite(t) || !(u >= 0.0 && u <= 1.0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sample_character_pose: a character, finite t, u in [0, 1]");
    }
    const weft_skinned_asset *a = c->asset;
    double f = floor(t * a->fps + 0.5);
    f = f < 0.0 ? 0.0 : f > a->frame_count - 1 ? a->frame_count - 1 : f;
    const float *mats = a->skin_matrices + (size_t)f * a->joint_count * 16;
    for (uint32_t j = 0; j < a->joint_count; ++j) {
        if (u >= 1.0) {
            memcpy(c->blended + 16 * (size_t)j, mats + 16 * (size_t)j, 16 * sizeof(float));
        } else {
            blend_from_identity(mats + 16 * (size_t)j, u, c->blended + 16 * (size_t)j);
        }
    }
    for (uint32_t v = 0; v < a->vertex_count; ++v) {
        skin_point(c->blended, a->joint_indices + 4 * (size_t)v, a->joint_weights + 4 * (size_t)v,
                   a->positions + 3 * (size_t)v, out_vertices + 3 * (size_t)v);
    }
    return WEFT_OK;
}

static int compare_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

weft_result weft_sample_character_bind(weft_sample_character *c, const float *garment, uint32_t n)
{
    if (!c || !garment || n == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sample_character_bind: a character and a garment");
    }
    const weft_skinned_asset *a = c->asset;
    uint32_t *joints = malloc((size_t)n * 4 * sizeof *joints);
    float *weights = malloc((size_t)n * 4 * sizeof *weights);
    double *dist = malloc((size_t)n * sizeof *dist);
    weft_wear *wear = NULL;
    weft_result r = joints && weights && dist ? WEFT_OK : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "character: out of memory");
    for (uint32_t i = 0; r == WEFT_OK && i < n; ++i) {
        const float *p = garment + 3 * (size_t)i;
        double best = INFINITY;
        const uint32_t nearest = weft_sample_nearest_point(a->positions, a->vertex_count, p, &best);
        memcpy(joints + 4 * (size_t)i, a->joint_indices + 4 * (size_t)nearest, 4 * sizeof *joints);
        memcpy(weights + 4 * (size_t)i, a->joint_weights + 4 * (size_t)nearest, 4 * sizeof *weights);
        dist[i] = sqrt(best);
    }
    if (r == WEFT_OK) {
        qsort(dist, n, sizeof *dist, compare_double);
        if (!(dist[n / 2] <= MAX_MEDIAN_DISTANCE)) {
            r = weft__fail(WEFT_ERROR_FORMAT,
                           "garment: its median distance to the character is %.1f cm (at most %.0f cm): it is not fitted "
                           "to this character's bind pose",
                           100.0 * dist[n / 2], 100.0 * MAX_MEDIAN_DISTANCE);
        }
    }
    if (r == WEFT_OK) {
        r = weft_wear_create(a->triangles, a->triangle_count, a->vertex_count, n, &wear);
    }
    if (r == WEFT_OK) {
        weft_wear_frame f;
        r = weft_wear_measure(wear, a->positions, garment, garment, 1.0f, &f);
        if (r == WEFT_OK && f.inside_body > MAX_INSIDE_SHARE) {
            r = weft__fail(WEFT_ERROR_FORMAT,
                           "garment: %.1f %% of its vertices are inside the character in the bind pose (at most %.0f %%): "
                           "fit it over the character's bind pose",
                           100.0 * f.inside_body, 100.0 * MAX_INSIDE_SHARE);
        }
    }
    weft_wear_destroy(wear);
    free(dist);
    if (r != WEFT_OK) {
        free(joints);
        free(weights);
        return r;
    }
    free(c->garment_joints);
    free(c->garment_weights);
    c->garment_joints = joints;
    c->garment_weights = weights;
    c->garment_count = n;
    c->garment_rest = garment;
    return WEFT_OK;
}

weft_result weft_sample_character_skin_garment(const weft_sample_character *c, float *out)
{
    if (!c || !out || !c->garment_rest) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_sample_character_skin_garment: no garment is bound");
    }
    for (uint32_t i = 0; i < c->garment_count; ++i) {
        skin_point(c->blended, c->garment_joints + 4 * (size_t)i, c->garment_weights + 4 * (size_t)i,
                   c->garment_rest + 3 * (size_t)i, out + 3 * (size_t)i);
    }
    return WEFT_OK;
}

#else /* no weft_assets: no importer */

weft_result weft_sample_character_load(weft_context *context, const char *path, weft_sample_character **out)
{
    (void)context, (void)path, (void)out;
    return weft__fail(WEFT_ERROR_UNSUPPORTED, "this build has no weft_assets (glTF/FBX import)");
}
void weft_sample_character_destroy(weft_sample_character *c) { free(c); }

#endif
