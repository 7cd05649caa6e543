/* A user's skinned character as the collider (character.h). */
#include "character.h"
#include "weft/wear.h"
#include "core/core.h"
#include "weft/body.h"

#if WEFT_RENDER_HAVE_ASSETS
#include "gltf.h"
#endif

#include <math.h>
#include <stdio.h>
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
    float *clip_mats;           /* clip_frames * joint_count * 16: a retargeted clip's skinning
                                 * matrices (weft_sample_character_set_clip), NULL: its own animation */
    uint32_t clip_frames;
    float clip_fps;
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
    free(c->clip_mats);
    free(c);
}

uint32_t weft_sample_character_vertex_count(const weft_sample_character *c) { return c->asset->vertex_count; }
uint32_t weft_sample_character_triangle_count(const weft_sample_character *c) { return c->asset->triangle_count; }
const float *weft_sample_character_bind_vertices(const weft_sample_character *c) { return c->asset->positions; }
const uint32_t *weft_sample_character_triangles(const weft_sample_character *c) { return c->asset->triangles; }
uint32_t weft_sample_character_joint_count(const weft_sample_character *c) { return c->asset->joint_count; }
uint32_t weft_sample_character_frame_count(const weft_sample_character *c)
{
    return c->clip_mats ? c->clip_frames : c->asset->frame_count;
}

const uint8_t *weft_sample_character_parts(const weft_sample_character *c, uint32_t *part_count)
{
    if (part_count) {
        *part_count = c->part_count;
    }
    return c->parts;
}

double weft_sample_character_duration(const weft_sample_character *c)
{
    return c->clip_mats ? (double)(c->clip_frames - 1) / (double)c->clip_fps
                        : (double)(c->asset->frame_count - 1) / (double)c->asset->fps;
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

/* Unit quaternion (x, y, z, w) -> rotation matrix r[row][col]. */
static void rotation_matrix(double x, double y, double z, double w, double r[3][3])
{
    r[0][0] = 1 - 2 * (y * y + z * z), r[0][1] = 2 * (x * y - z * w), r[0][2] = 2 * (x * z + y * w);
    r[1][0] = 2 * (x * y + z * w), r[1][1] = 1 - 2 * (x * x + z * z), r[1][2] = 2 * (y * z - x * w);
    r[2][0] = 2 * (x * z - y * w), r[2][1] = 2 * (y * z + x * w), r[2][2] = 1 - 2 * (x * x + y * y);
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
    double r[3][3];
    rotation_matrix(b * q[0], b * q[1], b * q[2], a + b * q[3], r);
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
    const uint32_t frames = c->clip_mats ? c->clip_frames : a->frame_count;
    double f = floor(t * (c->clip_mats ? c->clip_fps : a->fps) + 0.5);
    f = f < 0.0 ? 0.0 : f > frames - 1 ? frames - 1 : f;
    const float *mats = (c->clip_mats ? c->clip_mats : a->skin_matrices) + (size_t)f * a->joint_count * 16;
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

/* ---- Retargeting an SMPL clip onto the character ------------------------------------------- */

typedef struct quatd {
    double x, y, z, w;
} quatd;

static quatd q_mul(quatd a, quatd b)
{
    return (quatd){a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
                   a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}

static void q_rotate(quatd q, const double v[3], double out[3])
{
    /* v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z) */
    const double u[3] = {q.x, q.y, q.z};
    const double c1[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double c2[3] = {u[1] * c1[2] - u[2] * c1[1], u[2] * c1[0] - u[0] * c1[2], u[0] * c1[1] - u[1] * c1[0]};
    for (int k = 0; k < 3; ++k) {
        out[k] = v[k] + 2.0 * (q.w * c1[k] + c2[k]);
    }
}

/* The smallest rotation taking direction a onto direction b (identity when either is zero). */
static quatd q_between(const double a[3], const double b[3])
{
    const double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    if (!(la > 1e-9) || !(lb > 1e-9)) {
        return (quatd){0, 0, 0, 1};
    }
    const double x[3] = {a[0] / la, a[1] / la, a[2] / la}, y[3] = {b[0] / lb, b[1] / lb, b[2] / lb};
    const double d = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    if (d < -1.0 + 1e-9) { /* opposite: half a turn about any axis perpendicular to x */
        double axis[3] = {0.0, -x[2], x[1]};
        if (fabs(x[0]) > 0.9) {
            axis[0] = -x[2], axis[1] = 0.0, axis[2] = x[0];
        }
        const double l = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        return (quatd){axis[0] / l, axis[1] / l, axis[2] / l, 0.0};
    }
    quatd q = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0], 1.0 + d};
    const double n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    return (quatd){q.x / n, q.y / n, q.z / n, q.w / n};
}

/* Column-major rotation part of a rigid joint transform -> quaternion. */
static quatd q_from_mat(const float *m)
{
    const double s[3] = {1.0, 1.0, 1.0};
    double q[4];
    rotation_of(m, s, q);
    return (quatd){q[0], q[1], q[2], q[3]};
}

/* The character joint a map entry names: exact, or after a namespace prefix ("rig:Hips"). */
static int32_t character_joint(const weft_skinned_asset *a, const char *name)
{
    for (uint32_t k = 0; name && name[0] && k < a->joint_count; ++k) {
        const char *n = a->joint_names[k];
        const char *colon = strrchr(n, ':');
        if (strcmp(n, name) == 0 || (colon && strcmp(colon + 1, name) == 0)) {
            return (int32_t)k;
        }
    }
    return -1;
}

/* SMPL joints the retargeting needs mapped, and each SMPL joint's child along its bone (-1: a
 * leaf, which keeps its parent's rest correction). */
static const uint32_t k_required[] = {0, 1, 2, 3, 4, 5, 16, 17, 18, 19};
static const int32_t k_bone_child[WEFT_BODY_JOINTS] = {3,  4,  5,  6,  7,  8,  9,  10, 11, 12, -1, -1,
                                                       15, 16, 17, -1, 18, 19, 20, 21, 22, 23, -1, -1};

weft_result weft_sample_character_set_clip(weft_sample_character *c, const weft_body *body, const weft_clip *clip,
                                           const char *const *joint_map)
{
    if (!c || !body || !clip || !joint_map || clip->frame_count == 0 || !(clip->fps > 0.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_sample_character_set_clip: a character, a body, a clip with frames and a joint map");
    }
    const weft_skinned_asset *a = c->asset;
    const uint32_t nj = a->joint_count;
    int32_t of_smpl[WEFT_BODY_JOINTS];
    char missing[256] = "";
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        of_smpl[j] = character_joint(a, joint_map[j]);
        if (joint_map[j] && joint_map[j][0] && of_smpl[j] < 0) {
            return weft__fail(WEFT_ERROR_FORMAT, "character joint map: '%s' (for %s) is not a joint of the character",
                              joint_map[j], weft_joint_name(j));
        }
    }
    for (size_t i = 0; i < sizeof k_required / sizeof k_required[0]; ++i) {
        if (of_smpl[k_required[i]] < 0) {
            const size_t used = strlen(missing);
            snprintf(missing + used, sizeof missing - used, "%s%s", used ? ", " : "", weft_joint_name(k_required[i]));
        }
    }
    if (missing[0]) {
        return weft__fail(WEFT_ERROR_FORMAT, "character joint map: no character joint for %s (needed to play a clip)",
                          missing);
    }
    int32_t *smpl_of = malloc(nj * sizeof *smpl_of);
    uint32_t *order = malloc(nj * sizeof *order);
    quatd *corr = malloc(nj * sizeof *corr), *delta = malloc(nj * sizeof *delta);
    double *pos = malloc(nj * 3 * sizeof *pos);
    float *mats = malloc((size_t)clip->frame_count * nj * 16 * sizeof *mats);
    if (!smpl_of || !order || !corr || !delta || !pos || !mats) {
        free(smpl_of), free(order), free(corr), free(delta), free(pos), free(mats);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_sample_character_set_clip: out of memory");
    }
    for (uint32_t k = 0; k < nj; ++k) {
        smpl_of[k] = -1;
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        if (of_smpl[j] >= 0) {
            smpl_of[of_smpl[j]] = (int32_t)j;
        }
    }
    /* parents before children */
    uint32_t n_ordered = 0;
    uint8_t *done = calloc(nj, 1);
    for (uint32_t pass = 0; done && n_ordered < nj && pass < nj; ++pass) {
        for (uint32_t k = 0; k < nj; ++k) {
            if (!done[k] && (a->parents[k] < 0 || done[a->parents[k]])) {
                done[k] = 1;
                order[n_ordered++] = k;
            }
        }
    }
    free(done);
    const float *rest = weft_body_rest_joints(body);
#define BIND_T(k, i) ((double)a->bind_matrices[16 * (size_t)(k) + 12 + (i)])
    /* Rest corrections: the character's bind bone onto SMPL's T-pose bone, times the bind rotation's
     * inverse, so that (SMPL world rotation) x corr is the joint's rotation from its bind pose. */
    for (uint32_t i = 0; i < n_ordered; ++i) {
        const uint32_t k = order[i];
        const int32_t j = smpl_of[k], p = a->parents[k];
        const int32_t cj = j >= 0 ? k_bone_child[j] : -1, ck = cj >= 0 ? of_smpl[cj] : -1;
        if (j >= 0 && ck >= 0) {
            const double dc[3] = {BIND_T(ck, 0) - BIND_T(k, 0), BIND_T(ck, 1) - BIND_T(k, 1), BIND_T(ck, 2) - BIND_T(k, 2)};
            const double ds[3] = {rest[3 * cj] - rest[3 * j], rest[3 * cj + 1] - rest[3 * j + 1],
                                  rest[3 * cj + 2] - rest[3 * j + 2]};
            corr[k] = q_between(dc, ds);
        } else {
            corr[k] = p >= 0 ? corr[p] : (quatd){0, 0, 0, 1};
        }
    }
    /* Root path scaled by the legs' ratio (the character's thigh + shin over SMPL's). */
    const int32_t lh = of_smpl[1], lk = of_smpl[4], la = of_smpl[7];
    double char_leg = 0.0, smpl_leg = 0.0;
    for (int seg = 0; seg < 2; ++seg) {
        const int32_t k0 = seg ? lk : lh, k1 = seg ? la : lk;
        const uint32_t j0 = seg ? 4 : 1, j1 = seg ? 7 : 4;
        if (k1 < 0) {
            continue;
        }
        double dc = 0.0, ds = 0.0;
        for (int i = 0; i < 3; ++i) {
            dc += (BIND_T(k1, i) - BIND_T(k0, i)) * (BIND_T(k1, i) - BIND_T(k0, i));
            ds += ((double)rest[3 * j1 + i] - rest[3 * j0 + i]) * ((double)rest[3 * j1 + i] - rest[3 * j0 + i]);
        }
        char_leg += sqrt(dc), smpl_leg += sqrt(ds);
    }
    const double scale = smpl_leg > 1e-9 ? char_leg / smpl_leg : 1.0;
    weft_result r = WEFT_OK;
    float joints[WEFT_BODY_JOINTS * 16];
    for (uint32_t f = 0; f < clip->frame_count && r == WEFT_OK; ++f) {
        weft_pose pose;
        memcpy(pose.rotations, clip->rotations + (size_t)WEFT_POSE_ROTATION_FLOATS * f, sizeof pose.rotations);
        memcpy(pose.translation, clip->translations + 3 * (size_t)f, sizeof pose.translation);
        r = weft_body_pose(body, &pose, NULL, joints);
        const double disp[3] = {joints[12] - rest[0], joints[13] - rest[1], joints[14] - rest[2]};
        for (uint32_t i = 0; i < n_ordered && r == WEFT_OK; ++i) {
            const uint32_t k = order[i];
            const int32_t j = smpl_of[k], p = a->parents[k];
            delta[k] = j >= 0 ? q_mul(q_from_mat(joints + 16 * j), corr[k]) : p >= 0 ? delta[p] : (quatd){0, 0, 0, 1};
            if (p < 0) {
                for (int e = 0; e < 3; ++e) {
                    pos[3 * k + e] = BIND_T(k, e) + scale * disp[e];
                }
            } else {
                const double off[3] = {BIND_T(k, 0) - BIND_T(p, 0), BIND_T(k, 1) - BIND_T(p, 1), BIND_T(k, 2) - BIND_T(p, 2)};
                double turned[3];
                q_rotate(delta[p], off, turned);
                for (int e = 0; e < 3; ++e) {
                    pos[3 * k + e] = pos[3 * p + e] + turned[e];
                }
            }
            /* skinning matrix: rotation delta, translation pos - delta * bind position */
            float *m = mats + ((size_t)f * nj + k) * 16;
            double R[3][3];
            rotation_matrix(delta[k].x, delta[k].y, delta[k].z, delta[k].w, R);
            const double b[3] = {BIND_T(k, 0), BIND_T(k, 1), BIND_T(k, 2)};
            for (int col = 0; col < 3; ++col) {
                for (int row = 0; row < 3; ++row) {
                    m[4 * col + row] = (float)R[row][col];
                }
                m[4 * col + 3] = 0.0f;
            }
            for (int row = 0; row < 3; ++row) {
                m[12 + row] = (float)(pos[3 * k + row] - (R[row][0] * b[0] + R[row][1] * b[1] + R[row][2] * b[2]));
            }
            m[15] = 1.0f;
        }
    }
#undef BIND_T
    free(smpl_of), free(order), free(corr), free(delta), free(pos);
    if (r != WEFT_OK || !weft__all_finite(mats, (size_t)clip->frame_count * nj * 16)) {
        free(mats);
        return r != WEFT_OK ? r : weft__fail(WEFT_ERROR_NOT_FINITE, "weft_sample_character_set_clip: non-finite pose");
    }
    free(c->clip_mats);
    c->clip_mats = mats;
    c->clip_frames = clip->frame_count;
    c->clip_fps = clip->fps;
    return WEFT_OK;
}

#else /* no weft_assets: no importer */

weft_result weft_sample_character_load(weft_context *context, const char *path, weft_sample_character **out)
{
    (void)context, (void)path, (void)out;
    return weft__fail(WEFT_ERROR_UNSUPPORTED, "this build has no weft_assets (glTF/FBX import)");
}
void weft_sample_character_destroy(weft_sample_character *c) { free(c); }
weft_result weft_sample_character_set_clip(weft_sample_character *c, const weft_body *body, const weft_clip *clip,
                                           const char *const *joint_map)
{
    (void)c, (void)body, (void)clip, (void)joint_map;
    return weft__fail(WEFT_ERROR_UNSUPPORTED, "this build has no weft_assets (glTF/FBX import)");
}

#endif
