/* Procedural garments fitted to the avatar, and cloth sheets. Every garment is one
 * parameterisation meshed at the density asked for, so resolutions describe the same cloth:
 *   skirt, dress   a tube (angle x height) whose radius follows the body's outer hull plus
 *                  clearance and flares below the hips; a structured grid.
 *   T-shirt        the level set {body distance = clearance + ease} of the torso and upper
 *                  arms, polygonised with surface nets, opened at the hem, neck and sleeves.
 *   sheets         a square grid, and a wavy-outlined disc meshed in concentric rings. */
#include "body/body_internal.h"
#include "body/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI_F 3.14159265358979f

static const char *const g_kind_names[WEFT_CLOTH_COUNT] = {"tshirt", "skirt", "dress", "sheet", "sheet_irregular"};
static const char *const g_res_names[WEFT_CLOTH_RES_COUNT] = {"1k", "4k", "16k", "40k"};
static const uint32_t g_res_counts[WEFT_CLOTH_RES_COUNT] = {1000, 4000, 16000, 40000};

const char *weft_cloth_kind_name(weft_cloth_kind kind)
{
    return (unsigned)kind < WEFT_CLOTH_COUNT ? g_kind_names[kind] : NULL;
}

weft_result weft_cloth_kind_from_name(const char *name, weft_cloth_kind *out_kind)
{
    if (!name || !out_kind) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_cloth_kind_from_name: NULL argument");
    }
    for (int k = 0; k < WEFT_CLOTH_COUNT; ++k) {
        if (strcmp(name, g_kind_names[k]) == 0) {
            *out_kind = (weft_cloth_kind)k;
            return WEFT_OK;
        }
    }
    return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "unknown cloth kind '%s' (tshirt, skirt, dress, sheet, sheet_irregular)", name);
}

const char *weft_cloth_resolution_name(weft_cloth_resolution res)
{
    return (unsigned)res < WEFT_CLOTH_RES_COUNT ? g_res_names[res] : NULL;
}

weft_result weft_cloth_resolution_from_name(const char *name, weft_cloth_resolution *out_res)
{
    if (!name || !out_res) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_cloth_resolution_from_name: NULL argument");
    }
    for (int k = 0; k < WEFT_CLOTH_RES_COUNT; ++k) {
        if (strcmp(name, g_res_names[k]) == 0) {
            *out_res = (weft_cloth_resolution)k;
            return WEFT_OK;
        }
    }
    return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "unknown resolution '%s' (1k, 4k, 16k, 40k)", name);
}

weft_cloth_def weft_default_cloth_def(weft_cloth_kind kind)
{
    weft_cloth_def def;
    memset(&def, 0, sizeof def);
    def.kind = kind;
    def.resolution = WEFT_CLOTH_RES_4K;
    def.clearance = 0.01f;
    def.ease = 0.01f;
    def.size = 1.0f;
    def.height = 1.0f;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

void weft_cloth_destroy(weft_cloth_mesh *m)
{
    if (!m) {
        return;
    }
    weft_context *ctx = m->context;
    weft__free(ctx, m->positions, (size_t)m->vertex_count * 3 * sizeof(float));
    weft__free(ctx, m->uvs, (size_t)m->vertex_count * 2 * sizeof(float));
    weft__free(ctx, m->weights, (size_t)m->vertex_count * WEFT_BODY_JOINTS * sizeof(float));
    weft__free(ctx, m->triangles, (size_t)m->triangle_count * 3 * sizeof(uint32_t));
    weft__free(ctx, m, sizeof *m);
}

static weft_result alloc_cloth(weft_context *ctx, weft_cloth_kind kind, uint32_t nv, uint32_t nt, bool weights,
                               weft_cloth_mesh **out)
{
    weft_cloth_mesh *m = weft__alloc(ctx, sizeof *m);
    if (!m) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    m->context = ctx;
    m->kind = kind;
    m->vertex_count = nv;
    m->triangle_count = nt;
    m->positions = weft__alloc(ctx, (size_t)nv * 3 * sizeof(float));
    m->uvs = weft__alloc(ctx, (size_t)nv * 2 * sizeof(float));
    m->triangles = weft__alloc(ctx, (size_t)nt * 3 * sizeof(uint32_t));
    if (weights) {
        m->weights = weft__alloc(ctx, (size_t)nv * WEFT_BODY_JOINTS * sizeof(float));
    }
    if (!m->positions || !m->uvs || !m->triangles || (weights && !m->weights)) {
        weft_cloth_destroy(m);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *out = m;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Sheets                                                                                     */

/* Makes every triangle counter-clockwise seen from +Y. */
static void orient_up(weft_cloth_mesh *m)
{
    for (uint32_t f = 0; f < m->triangle_count; ++f) {
        uint32_t *t = m->triangles + 3 * f;
        const float *a = m->positions + 3 * t[0], *b = m->positions + 3 * t[1], *c = m->positions + 3 * t[2];
        float ny = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]);
        if (ny < 0) {
            uint32_t tmp = t[1];
            t[1] = t[2];
            t[2] = tmp;
        }
    }
}

static weft_result make_sheet(weft_context *ctx, const weft_cloth_def *def, uint32_t target, weft_cloth_mesh **out)
{
    uint32_t n = (uint32_t)lroundf(sqrtf((float)target));
    n = n < 4 ? 4 : n;
    weft_cloth_mesh *m;
    weft_result r = alloc_cloth(ctx, WEFT_CLOTH_SHEET, n * n, 2 * (n - 1) * (n - 1), false, &m);
    if (r != WEFT_OK) {
        return r;
    }
    const float s = def->size;
    for (uint32_t j = 0; j < n; ++j) {
        for (uint32_t i = 0; i < n; ++i) {
            uint32_t v = j * n + i;
            float u = s * (float)i / (float)(n - 1), w = s * (float)j / (float)(n - 1);
            m->positions[3 * v + 0] = u - 0.5f * s;
            m->positions[3 * v + 1] = def->height;
            m->positions[3 * v + 2] = w - 0.5f * s;
            m->uvs[2 * v + 0] = u;
            m->uvs[2 * v + 1] = w;
        }
    }
    uint32_t t = 0;
    for (uint32_t j = 0; j + 1 < n; ++j) {
        for (uint32_t i = 0; i + 1 < n; ++i) {
            uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            /* Alternate the diagonal so the sheet has no preferred shear direction. */
            uint32_t tri[6];
            if ((i + j) & 1) {
                uint32_t x[6] = {a, b, d, a, d, c};
                memcpy(tri, x, sizeof tri);
            } else {
                uint32_t x[6] = {a, b, c, b, d, c};
                memcpy(tri, x, sizeof tri);
            }
            memcpy(m->triangles + 3 * t, tri, sizeof tri);
            t += 2;
        }
    }
    orient_up(m);
    *out = m;
    return WEFT_OK;
}

/* Outline radius factor of the irregular sheet at angle a. */
static float wavy(float a)
{
    return 1.0f + 0.12f * sinf(3.0f * a) + 0.08f * cosf(5.0f * a + 0.4f) + 0.04f * sinf(7.0f * a + 1.1f);
}

static weft_result make_irregular_sheet(weft_context *ctx, const weft_cloth_def *def, uint32_t target, weft_cloth_mesh **out)
{
    /* Rings k = 1..n of 6k vertices around a centre: 1 + 3n(n+1) vertices. */
    uint32_t n = 1;
    while (1 + 3 * (n + 1) * (n + 2) <= target) {
        n++;
    }
    uint32_t nv = 1 + 3 * n * (n + 1), nt = 6 * n * n;
    weft_cloth_mesh *m;
    weft_result r = alloc_cloth(ctx, WEFT_CLOTH_SHEET_IRREGULAR, nv, nt, false, &m);
    if (r != WEFT_OK) {
        return r;
    }
    const float radius = 0.5f * def->size;
    m->positions[0] = 0, m->positions[1] = def->height, m->positions[2] = 0;
    uint32_t v = 1;
    for (uint32_t k = 1; k <= n; ++k) {
        for (uint32_t i = 0; i < 6 * k; ++i) {
            /* A small per-ring twist makes the connectivity irregular as well. */
            float a = 2.0f * PI_F * ((float)i + 0.5f * (float)(k & 1)) / (float)(6 * k);
            float rr = radius * wavy(a) * (float)k / (float)n;
            m->positions[3 * v + 0] = rr * cosf(a);
            m->positions[3 * v + 1] = def->height;
            m->positions[3 * v + 2] = rr * sinf(a);
            v++;
        }
    }
    for (uint32_t i = 0; i < nv; ++i) {
        m->uvs[2 * i + 0] = m->positions[3 * i + 0] + radius * 1.3f;
        m->uvs[2 * i + 1] = m->positions[3 * i + 2] + radius * 1.3f;
    }
    /* Zip consecutive rings by angle: advance on the ring whose next vertex comes first. */
    uint32_t t = 0;
    for (uint32_t k = 1; k <= n; ++k) {
        uint32_t inner_n = k == 1 ? 1 : 6 * (k - 1), outer_n = 6 * k;
        uint32_t inner0 = k == 1 ? 0 : 1 + 3 * (k - 1) * (k - 2), outer0 = 1 + 3 * k * (k - 1);
        if (k == 1) {
            for (uint32_t i = 0; i < 6; ++i) {
                uint32_t tri[3] = {0, outer0 + i, outer0 + (i + 1) % 6};
                memcpy(m->triangles + 3 * t++, tri, sizeof tri);
            }
            continue;
        }
        uint32_t i = 0, o = 0;
        while (i < inner_n || o < outer_n) {
            float ai = 2.0f * PI_F * ((float)(i + 1) + 0.5f * (float)((k - 1) & 1)) / (float)inner_n;
            float ao = 2.0f * PI_F * ((float)(o + 1) + 0.5f * (float)(k & 1)) / (float)outer_n;
            bool step_outer = i >= inner_n || (o < outer_n && ao <= ai);
            uint32_t tri[3];
            if (step_outer) {
                tri[0] = inner0 + i % inner_n, tri[1] = outer0 + o % outer_n, tri[2] = outer0 + (o + 1) % outer_n;
                o++;
            } else {
                tri[0] = inner0 + i % inner_n, tri[1] = outer0 + o % outer_n, tri[2] = inner0 + (i + 1) % inner_n;
                i++;
            }
            memcpy(m->triangles + 3 * t++, tri, sizeof tri);
        }
    }
    m->triangle_count = t;
    orient_up(m);
    *out = m;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Fitting helpers                                                                            */

#define J_BIT(j) (1u << (j))
#define MASK_TORSO (J_BIT(0) | J_BIT(3) | J_BIT(6) | J_BIT(9) | J_BIT(13) | J_BIT(14))
#define MASK_SHIRT (MASK_TORSO | J_BIT(16) | J_BIT(17))
#define MASK_LOWER (J_BIT(0) | J_BIT(3) | J_BIT(6) | J_BIT(9) | J_BIT(1) | J_BIT(2) | J_BIT(4) | J_BIT(5))

/* Weights of each garment vertex from the nearest body vertex among those driven mostly by
 * the joints in `mask` (a skirt must not follow the hand hanging next to it). Brute force
 * over a coarse grid of body vertices; runs once per garment. */
static weft_result transfer_weights(const weft_body *body, uint32_t mask, weft_cloth_mesh *m)
{
    const uint32_t nb = body->vertex_count;
    const float *bv = body->shaped_vertices, *bw = body->weights;
    weft_context *ctx = m->context;
    uint32_t *cand = weft__alloc(ctx, (size_t)nb * sizeof(uint32_t));
    if (!cand) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    uint32_t nc = 0;
    for (uint32_t i = 0; i < nb; ++i) {
        uint32_t arg = 0;
        for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
            arg = bw[(size_t)i * WEFT_BODY_JOINTS + j] > bw[(size_t)i * WEFT_BODY_JOINTS + arg] ? j : arg;
        }
        if (mask & J_BIT(arg)) {
            cand[nc++] = i;
        }
    }
    for (uint32_t v = 0; v < m->vertex_count; ++v) {
        const float *p = m->positions + 3 * v;
        float best = 1e30f;
        uint32_t bi = cand[0];
        for (uint32_t c = 0; c < nc; ++c) {
            const float *q = bv + 3 * cand[c];
            float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
            float d = dx * dx + dy * dy + dz * dz;
            if (d < best) {
                best = d;
                bi = cand[c];
            }
        }
        memcpy(m->weights + (size_t)v * WEFT_BODY_JOINTS, bw + (size_t)bi * WEFT_BODY_JOINTS, WEFT_BODY_JOINTS * sizeof(float));
    }
    weft__free(ctx, cand, (size_t)nb * sizeof(uint32_t));
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Tube garments: skirt and dress                                                             */

#define HULL_ANGLES 128
#define HULL_LEVELS 96

typedef struct tube_spec {
    float y_top, y_bottom, y_flare; /* flare starts below y_flare */
    float flare;                    /* radius gained per metre below y_flare */
    float zc;                       /* axis z */
} tube_spec;

/* Outer hull radius of the masked body at (angle, y), plus offset: march in from outside. */
static float hull_radius(const weft_avatar_shape *s, float angle, float y, float zc, float offset)
{
    float ca = cosf(angle), sa = sinf(angle);
    /* 5 mm steps from outside, then bisection to 0.1 mm. Parts are thicker than a step. */
    float r = 0.8f, step = 0.005f;
    for (; r > 0.0f; r -= step) {
        float p[3] = {r * ca, y, zc + r * sa};
        if (weft__avatar_field_masked(s, p, MASK_LOWER) < offset) {
            break;
        }
    }
    if (r <= 0.0f) {
        return 0.0f;
    }
    float in = r, out = r + step;
    while (out - in > 1e-4f) {
        float mid = 0.5f * (in + out);
        float p[3] = {mid * ca, y, zc + mid * sa};
        if (weft__avatar_field_masked(s, p, MASK_LOWER) < offset) {
            in = mid;
        } else {
            out = mid;
        }
    }
    return out;
}

static weft_result make_tube(weft_context *ctx, const weft_cloth_def *def, const weft_body *body, uint32_t target,
                             weft_cloth_mesh **out)
{
    const weft_avatar_shape *s = body->avatar;
    const float *J = s->bind_joints;
    const float L = s->def.height / 1.70f;
    tube_spec t;
    t.zc = J[3 * WEFT_JOINT_PELVIS + 2];
    if (def->kind == WEFT_CLOTH_SKIRT) {
        t.y_top = J[3 * WEFT_JOINT_SPINE1 + 1];
        t.y_bottom = J[3 * WEFT_JOINT_LEFT_KNEE + 1] + 0.10f * L;
        t.flare = 0.45f;
    } else {
        t.y_top = J[3 * WEFT_JOINT_SPINE3 + 1] - 0.01f * L;
        t.y_bottom = J[3 * WEFT_JOINT_LEFT_KNEE + 1] - 0.12f * L;
        t.flare = 0.40f;
    }
    t.y_flare = J[3 * WEFT_JOINT_LEFT_HIP + 1] + 0.02f * L;
    const float offset = def->clearance + def->ease;

    /* The radius field on a fixed (angle, height) lattice, shared by all resolutions. */
    size_t lattice_bytes = (size_t)HULL_ANGLES * HULL_LEVELS * sizeof(float);
    float *rad = weft__alloc(ctx, lattice_bytes);
    float *tmp = weft__alloc(ctx, lattice_bytes);
    if (!rad || !tmp) {
        weft__free(ctx, rad, lattice_bytes);
        weft__free(ctx, tmp, lattice_bytes);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (int b = 0; b < HULL_LEVELS; ++b) {
        float y = t.y_bottom + (t.y_top - t.y_bottom) * (float)b / (float)(HULL_LEVELS - 1);
        for (int a = 0; a < HULL_ANGLES; ++a) {
            rad[b * HULL_ANGLES + a] = hull_radius(s, 2.0f * PI_F * (float)a / HULL_ANGLES, y, t.zc, offset);
        }
    }
    /* Below the flare line the cloth hangs as a cone from the hull at that line, never inside
     * the hull: taking the running maximum downwards from the line, plus the flare. */
    int b_flare = (int)floorf((t.y_flare - t.y_bottom) / (t.y_top - t.y_bottom) * (HULL_LEVELS - 1));
    b_flare = b_flare < 0 ? 0 : b_flare >= HULL_LEVELS ? HULL_LEVELS - 1 : b_flare;
    for (int b = b_flare - 1; b >= 0; --b) {
        float drop = (float)(b_flare - b) * (t.y_top - t.y_bottom) / (float)(HULL_LEVELS - 1);
        for (int a = 0; a < HULL_ANGLES; ++a) {
            float cone = rad[b_flare * HULL_ANGLES + a] + t.flare * drop;
            float r = rad[b * HULL_ANGLES + a];
            rad[b * HULL_ANGLES + a] = r > cone ? r : cone;
        }
    }
    /* Smooth around the circumference (the hull has creases between the legs) and keep the
     * result outside the hull: only ever raise. */
    for (int pass = 0; pass < 6; ++pass) {
        for (int b = 0; b < HULL_LEVELS; ++b) {
            for (int a = 0; a < HULL_ANGLES; ++a) {
                const float *row = rad + b * HULL_ANGLES;
                float avg = 0.25f * row[(a + HULL_ANGLES - 1) % HULL_ANGLES] + 0.5f * row[a] + 0.25f * row[(a + 1) % HULL_ANGLES];
                tmp[b * HULL_ANGLES + a] = avg > row[a] ? avg : row[a];
            }
        }
        memcpy(rad, tmp, lattice_bytes);
    }
    weft__free(ctx, tmp, lattice_bytes);

    /* The hull ignores the arms. Where an arm comes within the offset of the tube (thick
     * arms next to a dress's top), lower the top below it; arms lower down (hands by a wide
     * skirt) cannot be avoided and are reported. */
    int top_row = HULL_LEVELS - 1;
    for (int b = HULL_LEVELS - 1; b >= 0; --b) {
        float y = t.y_bottom + (t.y_top - t.y_bottom) * (float)b / (float)(HULL_LEVELS - 1);
        bool clear = true;
        for (int a = 0; a < HULL_ANGLES && clear; ++a) {
            float ang = 2.0f * PI_F * (float)a / HULL_ANGLES, rr = rad[b * HULL_ANGLES + a];
            float p[3] = {rr * cosf(ang), y, t.zc + rr * sinf(ang)};
            clear = weft__avatar_field(s, p, NULL) >= 0.75f * offset;
        }
        if (!clear) {
            if (b < (HULL_LEVELS * 2) / 3) {
                weft__free(ctx, rad, lattice_bytes);
                return weft__fail(WEFT_ERROR_UNSUPPORTED, "%s: the arms or hands of this body cross the garment at y = %.2f m",
                                  g_kind_names[def->kind], (double)y);
            }
            top_row = b - 2;
        }
    }
    const float top_fraction = (float)top_row / (float)(HULL_LEVELS - 1);
    t.y_top = t.y_bottom + (t.y_top - t.y_bottom) * top_fraction;

    /* Mesh density: square-ish cells from the mean circumference and the length. */
    double circ = 0;
    for (int i = 0; i < HULL_ANGLES * HULL_LEVELS; ++i) {
        circ += rad[i];
    }
    circ = 2.0 * 3.14159265358979 * circ / (HULL_ANGLES * HULL_LEVELS);
    float length = t.y_top - t.y_bottom;
    uint32_t na = (uint32_t)lround(sqrt((double)target * circ / length));
    na = na < 8 ? 8 : na;
    uint32_t ny = (uint32_t)lround((double)target / na);
    ny = ny < 3 ? 3 : ny;
    weft_cloth_mesh *m;
    weft_result r = alloc_cloth(ctx, def->kind, na * ny, 2 * na * (ny - 1), true, &m);
    if (r != WEFT_OK) {
        weft__free(ctx, rad, lattice_bytes);
        return r;
    }
    for (uint32_t j = 0; j < ny; ++j) {
        float fy = (float)j / (float)(ny - 1);
        float y = t.y_bottom + length * fy;
        float lb = fy * top_fraction * (HULL_LEVELS - 1);
        int b0 = (int)lb;
        b0 = b0 >= HULL_LEVELS - 1 ? HULL_LEVELS - 2 : b0;
        float wb = lb - (float)b0;
        for (uint32_t i = 0; i < na; ++i) {
            /* Rows are staggered by half a column to make near-equilateral triangles. */
            float fa = ((float)i + 0.5f * (float)(j & 1)) / (float)na;
            float la = fa * HULL_ANGLES;
            int a0 = (int)la % HULL_ANGLES, a1 = (a0 + 1) % HULL_ANGLES;
            float wa = la - floorf(la);
            float rr = (1 - wb) * ((1 - wa) * rad[b0 * HULL_ANGLES + a0] + wa * rad[b0 * HULL_ANGLES + a1]) +
                       wb * ((1 - wa) * rad[(b0 + 1) * HULL_ANGLES + a0] + wa * rad[(b0 + 1) * HULL_ANGLES + a1]);
            float ang = 2.0f * PI_F * fa;
            uint32_t v = j * na + i;
            m->positions[3 * v + 0] = rr * cosf(ang);
            m->positions[3 * v + 1] = y;
            m->positions[3 * v + 2] = t.zc + rr * sinf(ang);
            m->uvs[2 * v + 0] = (float)circ * fa;
            m->uvs[2 * v + 1] = y - t.y_bottom;
        }
    }
    weft__free(ctx, rad, lattice_bytes);
    uint32_t tc = 0;
    for (uint32_t j = 0; j + 1 < ny; ++j) {
        for (uint32_t i = 0; i < na; ++i) {
            uint32_t a = j * na + i, c = j * na + (i + 1) % na;
            uint32_t b = (j + 1) * na + i, d = (j + 1) * na + (i + 1) % na;
            /* Outward = d/dy x d/dangle. With staggered rows, even rows lean one way. */
            uint32_t tri[6];
            if ((j & 1) == 0) {
                uint32_t x[6] = {a, b, c, c, b, d};
                memcpy(tri, x, sizeof tri);
            } else {
                uint32_t x[6] = {a, b, d, a, d, c};
                memcpy(tri, x, sizeof tri);
            }
            memcpy(m->triangles + 3 * tc, tri, sizeof tri);
            tc += 2;
        }
    }
    r = transfer_weights(body, MASK_LOWER, m);
    if (r != WEFT_OK) {
        weft_cloth_destroy(m);
        return r;
    }
    *out = m;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* T-shirt                                                                                    */

typedef struct shirt_spec {
    const weft_avatar_shape *shape;
    float offset;
    float hem_y;
    float neck_axis[2];  /* x, z of the neck hole axis */
    float neck_radius, neck_y;
    float sleeve_origin[2][3], sleeve_dir[2][3], sleeve_length, sleeve_radius;
} shirt_spec;

static float shirt_field(const void *user, const float *p)
{
    const shirt_spec *s = user;
    return weft__avatar_field_masked(s->shape, p, MASK_SHIRT) - s->offset;
}

/* Which opening a point lies beyond: 0 none, 1 hem, 2 neck, 3/4 sleeves. */
static int shirt_cut(const shirt_spec *s, const float *p)
{
    if (p[1] < s->hem_y) {
        return 1;
    }
    float dx = p[0] - s->neck_axis[0], dz = p[2] - s->neck_axis[1];
    if (p[1] > s->neck_y && dx * dx + dz * dz < s->neck_radius * s->neck_radius) {
        return 2;
    }

    for (int k = 0; k < 2; ++k) {
        const float *o = s->sleeve_origin[k], *d = s->sleeve_dir[k];
        float v[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
        float along = v[0] * d[0] + v[1] * d[1] + v[2] * d[2];
        float across2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - along * along;
        /* Only the sleeve tube itself, not the torso below the armpit. */
        if (along > s->sleeve_length && across2 < s->sleeve_radius * s->sleeve_radius) {
            return 3 + k;
        }
    }
    return 0;
}

/* Moves p onto the surface of opening `which` (a plane or the neck cylinder). */
static void snap_to_cut(const shirt_spec *s, int which, float *p)
{
    if (which == 1) {
        p[1] = s->hem_y;
    } else if (which == 2) {
        float dx = p[0] - s->neck_axis[0], dz = p[2] - s->neck_axis[1];
        float l = sqrtf(dx * dx + dz * dz);
        if (l > 1e-6f) {
            p[0] = s->neck_axis[0] + dx / l * s->neck_radius;
            p[2] = s->neck_axis[1] + dz / l * s->neck_radius;
        }
    } else if (which >= 3) {
        const float *o = s->sleeve_origin[which - 3], *d = s->sleeve_dir[which - 3];
        float along = (p[0] - o[0]) * d[0] + (p[1] - o[1]) * d[1] + (p[2] - o[2]) * d[2];
        for (int k = 0; k < 3; ++k) {
            p[k] -= (along - s->sleeve_length) * d[k];
        }
    }
}

/* The opening nearest a boundary point (by distance to each cut surface). */
static int nearest_cut(const shirt_spec *s, const float *p)
{
    float best = fabsf(p[1] - s->hem_y);
    int which = 1;
    float dx = p[0] - s->neck_axis[0], dz = p[2] - s->neck_axis[1];
    float dn = fabsf(sqrtf(dx * dx + dz * dz) - s->neck_radius) + (p[1] < s->neck_y ? s->neck_y - p[1] : 0.0f);
    if (dn < best) {
        best = dn;
        which = 2;
    }
    for (int k = 0; k < 2; ++k) {
        const float *o = s->sleeve_origin[k], *d = s->sleeve_dir[k];
        float along = (p[0] - o[0]) * d[0] + (p[1] - o[1]) * d[1] + (p[2] - o[2]) * d[2];
        if (fabsf(along - s->sleeve_length) < best) {
            best = fabsf(along - s->sleeve_length);
            which = 3 + k;
        }
    }
    return which;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Marks the vertices on boundary edges, stores each live triangle's number of boundary
 * edges in `ear`, and counts the ears (triangles with 2+ boundary edges). */
static weft_result boundary_info(const weft_context *ctx, const weft__mesh *m, const uint8_t *alive, uint8_t *on_boundary,
                                 uint8_t *ear, uint32_t *ears)
{
    size_t ne = (size_t)m->nt * 3;
    uint64_t *keys = weft__alloc(ctx, (ne ? ne : 1) * sizeof(uint64_t));
    if (!keys) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    size_t k = 0;
    for (uint32_t f = 0; f < m->nt; ++f) {
        if (!alive[f]) {
            continue;
        }
        for (int e = 0; e < 3; ++e) {
            uint64_t a = m->t[3 * f + e], b = m->t[3 * f + (e + 1) % 3];
            keys[k++] = a < b ? (a << 32) | b : (b << 32) | a;
        }
    }
    qsort(keys, k, sizeof(uint64_t), cmp_u64);
    memset(on_boundary, 0, m->nv);
    *ears = 0;
    for (uint32_t f = 0; f < m->nt; ++f) {
        ear[f] = 0;
        if (!alive[f]) {
            continue;
        }
        int boundary_edges = 0;
        for (int e = 0; e < 3; ++e) {
            uint64_t a = m->t[3 * f + e], b = m->t[3 * f + (e + 1) % 3];
            uint64_t key = a < b ? (a << 32) | b : (b << 32) | a;
            /* count occurrences with a binary search for the first match */
            size_t lo = 0, hi = k;
            while (lo < hi) {
                size_t mid = (lo + hi) / 2;
                if (keys[mid] < key) {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            size_t n = 0;
            while (lo + n < k && keys[lo + n] == key) {
                n++;
            }
            if (n == 1) {
                boundary_edges++;
                on_boundary[a] = on_boundary[b] = 1;
            }
        }
        ear[f] = (uint8_t)boundary_edges;
        if (boundary_edges >= 2) {
            (*ears)++;
        }
    }
    weft__free(ctx, keys, (ne ? ne : 1) * sizeof(uint64_t));
    return WEFT_OK;
}

/* Keeps the live triangles and the vertices they use, renumbered in order of first use.
 * flags (may be NULL) is carried along with the vertices. */
static weft_result compact_mesh(const weft_context *ctx, weft__mesh *m, const uint8_t *alive, uint32_t *remap, uint8_t *flags)
{
    size_t vbytes = (size_t)m->nv * 3 * sizeof(float);
    float *old = weft__alloc(ctx, vbytes ? vbytes : 1);
    uint8_t *old_flags = flags ? weft__alloc(ctx, m->nv ? m->nv : 1) : NULL;
    if (!old || (flags && !old_flags)) {
        weft__free(ctx, old, vbytes ? vbytes : 1);
        weft__free(ctx, old_flags, m->nv ? m->nv : 1);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(old, m->v, vbytes);
    if (flags) {
        memcpy(old_flags, flags, m->nv);
    }
    for (uint32_t i = 0; i < m->nv; ++i) {
        remap[i] = UINT32_MAX;
    }
    uint32_t nv = 0, nt = 0;
    for (uint32_t f = 0; f < m->nt; ++f) {
        if (!alive[f]) {
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            uint32_t v = m->t[3 * f + c];
            if (remap[v] == UINT32_MAX) {
                remap[v] = nv;
                memcpy(m->v + 3 * nv, old + 3 * v, 3 * sizeof(float));
                if (flags) {
                    flags[nv] = old_flags[v];
                }
                nv++;
            }
            m->t[3 * nt + c] = remap[v];
        }
        nt++;
    }
    weft__free(ctx, old, vbytes ? vbytes : 1);
    weft__free(ctx, old_flags, m->nv ? m->nv : 1);
    m->nv = nv;
    m->nt = nt;
    return WEFT_OK;
}

static weft_result make_tshirt(weft_context *ctx, const weft_cloth_def *def, const weft_body *body, uint32_t target,
                               weft_cloth_mesh **out)
{
    const weft_avatar_shape *sh = body->avatar;
    const float *J = sh->bind_joints;
    const float L = sh->def.height / 1.70f;
    shirt_spec s;
    memset(&s, 0, sizeof s);
    s.shape = sh;
    s.offset = def->clearance + def->ease;
    s.hem_y = J[3 * WEFT_JOINT_PELVIS + 1] - 0.02f * L;
    s.neck_axis[0] = J[3 * WEFT_JOINT_NECK + 0];
    s.neck_axis[1] = J[3 * WEFT_JOINT_NECK + 2] + 0.01f * L;
    s.neck_radius = 0.095f * L * (0.7f + 0.3f * sh->def.girth);
    s.neck_y = J[3 * WEFT_JOINT_SPINE3 + 1] + 0.6f * (J[3 * WEFT_JOINT_NECK + 1] - J[3 * WEFT_JOINT_SPINE3 + 1]);
    float upper_arm = 0;
    for (int k = 0; k < 2; ++k) {
        const float *a = J + 3 * (WEFT_JOINT_LEFT_SHOULDER + k), *b = J + 3 * (WEFT_JOINT_LEFT_ELBOW + k);
        float d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        upper_arm = l;
        for (int c = 0; c < 3; ++c) {
            s.sleeve_origin[k][c] = a[c];
            s.sleeve_dir[k][c] = d[c] / l;
        }
    }
    s.sleeve_length = 0.6f * upper_arm;
    s.sleeve_radius = 0.10f * L * sh->def.girth + s.offset;

    /* Bounds of the shirt region. */
    float lo[3] = {1e9f, s.hem_y - 0.05f, 1e9f}, hi[3] = {-1e9f, -1e9f, -1e9f};
    for (uint32_t i = 0; i < sh->part_count; ++i) {
        const weft_avatar_part *p = &sh->parts[i];
        if (!(MASK_SHIRT & J_BIT(p->joint))) {
            continue;
        }
        float r = fmaxf(p->ra, p->rb) * p->smax + s.offset + 0.02f;
        for (int a = 0; a < 3; ++a) {
            lo[a] = fminf(lo[a], fminf(p->a[a], p->b[a]) - r);
            hi[a] = fmaxf(hi[a], fmaxf(p->a[a], p->b[a]) + r);
        }
    }
    lo[1] = s.hem_y - 0.05f;
    /* Surface nets count ~ area / h^2 and the openings remove a little: aim from the area. */
    const float area = 1.25f * L * L * (0.6f + 0.4f * sh->def.girth);
    float h = sqrtf(area / (float)target);
    weft__mesh m;
    weft_result r = WEFT_OK;
    uint8_t *alive = NULL, *onb = NULL, *ear = NULL;
    uint32_t *remap = NULL;
    size_t cap_t = 0, cap_v = 0;
    for (int attempt = 0; attempt < 2; ++attempt) {
        float glo[3] = {lo[0] - 2 * h - 0.37f * h, lo[1], lo[2] - 2 * h}, ghi[3] = {hi[0] + 2 * h, hi[1] + 2 * h, hi[2] + 2 * h};
        weft__mesh_init(&m, ctx);
        r = weft__surface_nets(&m, shirt_field, &s, glo, ghi, h);
        if (r != WEFT_OK) {
            weft__mesh_free(&m);
            return r;
        }
        weft__project_to_field(&m, shirt_field, &s, h, 6);
        /* Count the vertices that survive the cuts and correct the spacing once. */
        uint32_t kept = 0;
        for (uint32_t i = 0; i < m.nv; ++i) {
            kept += shirt_cut(&s, m.v + 3 * i) == 0;
        }
        float ratio = sqrtf((float)kept / (float)target);
        if (attempt == 0 && (ratio > 1.06f || ratio < 0.94f)) {
            weft__mesh_free(&m);
            h *= ratio;
            continue;
        }
        break;
    }
    weft__adjacency adj;
    r = weft__adjacency_build(ctx, &m, &adj);
    if (r != WEFT_OK) {
        weft__mesh_free(&m);
        return r;
    }
    weft__relax(&m, &adj, shirt_field, &s, h, 3);
    weft__adjacency_free(ctx, &adj);

    cap_t = m.nt;
    cap_v = m.nv;
    alive = weft__alloc(ctx, cap_t);
    ear = weft__alloc(ctx, cap_t);
    onb = weft__alloc(ctx, cap_v);
    remap = weft__alloc(ctx, cap_v * sizeof(uint32_t));
    if (!alive || !ear || !onb || !remap) {
        r = WEFT_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    /* Open the garment: drop triangles whose centroid is beyond a cut. */
    for (uint32_t f = 0; f < m.nt; ++f) {
        float c[3];
        for (int a = 0; a < 3; ++a) {
            c[a] = (m.v[3 * m.t[3 * f] + a] + m.v[3 * m.t[3 * f + 1] + a] + m.v[3 * m.t[3 * f + 2] + a]) / 3.0f;
        }
        alive[f] = shirt_cut(&s, c) == 0;
        /* Keep out of the parts the shirt's surface ignores (on a thick neck the chin comes
         * down to the collar): the neck opening widens there. */
        for (int k = 0; k < 3 && alive[f]; ++k) {
            alive[f] = weft__avatar_field(sh, m.v + 3 * m.t[3 * f + k], NULL) >= 0.75f * s.offset;
        }
    }
    /* Trim ears (triangles hanging on by one edge) so the openings have clean rims. */
    for (int pass = 0; pass < 16; ++pass) {
        uint32_t ears = 0;
        r = boundary_info(ctx, &m, alive, onb, ear, &ears);
        if (r != WEFT_OK) {
            goto done;
        }
        if (ears == 0) {
            break;
        }
        for (uint32_t f = 0; f < m.nt; ++f) {
            if (ear[f] >= 2) {
                alive[f] = 0;
            }
        }
    }
    r = compact_mesh(ctx, &m, alive, remap, onb);
    if (r != WEFT_OK) {
        goto done;
    }
    r = weft__adjacency_build(ctx, &m, &adj);
    if (r != WEFT_OK) {
        goto done;
    }
    /* Rims: onto their opening's surface and the shirt surface, evened out along the rim;
     * then the interior relaxes around the fixed rims, removing slivers next to them. */
    for (int it = 0; it < 6; ++it) {
        for (uint32_t i = 0; i < m.nv; ++i) {
            if (!onb[i]) {
                continue;
            }
            float *p = m.v + 3 * i;
            if (it > 0) {
                float c[3] = {0, 0, 0};
                int n = 0;
                for (uint32_t k = adj.offsets[i]; k < adj.offsets[i + 1]; ++k) {
                    uint32_t q = adj.neighbours[k];
                    if (onb[q]) {
                        for (int a = 0; a < 3; ++a) {
                            c[a] += m.v[3 * q + a];
                        }
                        n++;
                    }
                }
                if (n == 2) {
                    for (int a = 0; a < 3; ++a) {
                        p[a] = 0.5f * p[a] + 0.25f * c[a];
                    }
                }
            }
            /* Halfway towards the opening's surface each pass, so that rims straighten
             * without flattening the triangles that span them. */
            int which = nearest_cut(&s, p);
            float target_p[3] = {p[0], p[1], p[2]};
            snap_to_cut(&s, which, target_p);
            /* Rims made by the keep-out test stay where they are (smoothed along the rim). */
            if (weft__avatar_field(sh, target_p, NULL) >= s.offset) {
                for (int a = 0; a < 3; ++a) {
                    p[a] = 0.5f * (p[a] + target_p[a]);
                }
            }
            for (int k = 0; k < 3; ++k) {
                float g[3], e = 0.05f * h, v = shirt_field(&s, p);
                for (int a = 0; a < 3; ++a) {
                    float q[3] = {p[0], p[1], p[2]};
                    q[a] += e;
                    float fp = shirt_field(&s, q);
                    q[a] -= 2 * e;
                    g[a] = (fp - shirt_field(&s, q)) / (2 * e);
                }
                float g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
                if (g2 > 1e-12f) {
                    for (int a = 0; a < 3; ++a) {
                        p[a] -= v * g[a] / g2;
                    }
                }
            }
        }
        weft__relax_free_vertices(&m, &adj, shirt_field, &s, h, 1, onb);
    }
    weft__adjacency_free(ctx, &adj);

    /* Shave slivers along the rims: a thin triangle standing on a rim edge with its apex
     * inside is removed, and the apex joins the rim (a manifold-preserving step). At most one
     * triangle per vertex per pass so no vertex gets two rim gaps. */
    for (uint32_t f = 0; f < m.nt; ++f) {
        alive[f] = 1;
    }
    for (int pass = 0; pass < 12; ++pass) {
        uint32_t ears = 0, shaved = 0;
        r = boundary_info(ctx, &m, alive, onb, ear, &ears);
        if (r != WEFT_OK) {
            goto done;
        }
        memset(remap, 0, (size_t)m.nv * sizeof(uint32_t)); /* claimed flags */
        for (uint32_t f = 0; f < m.nt; ++f) {
            const uint32_t *t = m.t + 3 * f;
            if (!alive[f] || remap[t[0]] || remap[t[1]] || remap[t[2]]) {
                continue;
            }
            if (ear[f] >= 2) { /* shaving can leave ears behind: trim them too */
                alive[f] = 0;
                remap[t[0]] = remap[t[1]] = remap[t[2]] = 1;
                shaved++;
                continue;
            }
            if (ear[f] != 1 || onb[t[0]] + onb[t[1]] + onb[t[2]] != 2) {
                continue;
            }
            float min_cos = -1.0f; /* largest cosine = smallest angle */
            for (int c = 0; c < 3; ++c) {
                const float *p0 = m.v + 3 * t[c], *p1 = m.v + 3 * t[(c + 1) % 3], *p2 = m.v + 3 * t[(c + 2) % 3];
                float u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]}, w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
                float cs = (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) /
                           sqrtf((u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]));
                min_cos = cs > min_cos ? cs : min_cos;
            }
            if (min_cos > 0.978f) { /* below 12 degrees */
                alive[f] = 0;
                remap[t[0]] = remap[t[1]] = remap[t[2]] = 1;
                shaved++;
            }
        }
        if (shaved == 0) {
            break;
        }
    }
    r = compact_mesh(ctx, &m, alive, remap, NULL);
    if (r != WEFT_OK) {
        goto done;
    }
    uint32_t nv = m.nv, nt = m.nt;
    weft_cloth_mesh *cm;
    r = alloc_cloth(ctx, WEFT_CLOTH_TSHIRT, nv, nt, true, &cm);
    if (r != WEFT_OK) {
        goto done;
    }
    for (uint32_t i = 0; i < nv; ++i) {
        float *p = cm->positions + 3 * i;
        memcpy(p, m.v + 3 * i, 3 * sizeof(float));
        /* Pattern coordinates: arc length around the torso axis and height. */
        float ang = atan2f(p[0], p[2] - s.neck_axis[1]);
        cm->uvs[2 * i + 0] = 0.25f * L * (ang + PI_F);
        cm->uvs[2 * i + 1] = p[1] - s.hem_y;
    }
    memcpy(cm->triangles, m.t, (size_t)nt * 3 * sizeof(uint32_t));
    r = transfer_weights(body, MASK_SHIRT, cm);
    if (r != WEFT_OK) {
        weft_cloth_destroy(cm);
        goto done;
    }
    *out = cm;
done:
    weft__free(ctx, alive, cap_t);
    weft__free(ctx, ear, cap_t);
    weft__free(ctx, onb, cap_v);
    weft__free(ctx, remap, cap_v * sizeof(uint32_t));
    weft__mesh_free(&m);
    return r;
}

/* ---------------------------------------------------------------------------------------- */

weft_result weft_cloth_create(weft_context *context, const weft_cloth_def *def, const weft_body *body,
                              weft_cloth_mesh **out_mesh)
{
    if (!context || !def || !out_mesh) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_cloth_create: NULL argument");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: not made by weft_default_cloth_def()");
    }
    if ((unsigned)def->kind >= WEFT_CLOTH_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: kind %d out of range", (int)def->kind);
    }
    if (def->target_vertices == 0 && (unsigned)def->resolution >= WEFT_CLOTH_RES_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: resolution %d out of range", (int)def->resolution);
    }
    if (def->target_vertices != 0 && (def->target_vertices < 200 || def->target_vertices > 200000)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: target_vertices %u outside [200, 200000]",
                          def->target_vertices);
    }
    if (!isfinite(def->clearance) || !isfinite(def->ease) || !isfinite(def->size) || !isfinite(def->height)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "cloth def: clearance, ease, size or height is not finite");
    }
    if (def->clearance < 0.002f || def->clearance > 0.1f || def->ease < 0.0f || def->ease > 0.1f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: clearance %g outside [0.002, 0.1] or ease %g outside [0, 0.1]",
                          (double)def->clearance, (double)def->ease);
    }
    if (def->size < 0.05f || def->size > 20.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "cloth def: size %g outside [0.05, 20]", (double)def->size);
    }
    uint32_t target = def->target_vertices ? def->target_vertices : g_res_counts[def->resolution];
    switch (def->kind) {
    case WEFT_CLOTH_SHEET:
        return make_sheet(context, def, target, out_mesh);
    case WEFT_CLOTH_SHEET_IRREGULAR:
        return make_irregular_sheet(context, def, target, out_mesh);
    case WEFT_CLOTH_TSHIRT:
    case WEFT_CLOTH_SKIRT:
    case WEFT_CLOTH_DRESS:
    default:
        break;
    }
    if (!body || !body->avatar) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "cloth def: a %s is fitted to a body made by weft_avatar_create",
                          g_kind_names[def->kind]);
    }
    return def->kind == WEFT_CLOTH_TSHIRT ? make_tshirt(context, def, body, target, out_mesh)
                                          : make_tube(context, def, body, target, out_mesh);
}
