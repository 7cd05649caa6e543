/* Procedural geometry and kinematics for the drop and gripper scenarios. */
#include "weft/ccd.h"
#include "weft/clip_place.h"
#include "weft/wear.h"
#include "scene.h"
#include "bvh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SPI 3.14159265358979323846

void xmesh_free(xmesh *m)
{
    free(m->pos);
    free(m->tris);
    *m = (xmesh){0};
}

static bool reserve(xmesh *m, uint32_t add_v, uint32_t add_t)
{
    if (m->nv + add_v > m->cap_v) {
        uint32_t cap = (m->nv + add_v) * 2 + 16;
        float *p = realloc(m->pos, sizeof(float) * 3 * cap);
        if (!p) {
            return false;
        }
        m->pos = p;
        m->cap_v = cap;
    }
    if (m->nt + add_t > m->cap_t) {
        uint32_t cap = (m->nt + add_t) * 2 + 16;
        uint32_t *t = realloc(m->tris, sizeof(uint32_t) * 3 * cap);
        if (!t) {
            return false;
        }
        m->tris = t;
        m->cap_t = cap;
    }
    return true;
}

static uint32_t add_v(xmesh *m, double x, double y, double z)
{
    float *p = m->pos + 3 * (size_t)m->nv;
    p[0] = (float)x, p[1] = (float)y, p[2] = (float)z;
    return m->nv++;
}

static void add_t(xmesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t *t = m->tris + 3 * (size_t)m->nt++;
    t[0] = a, t[1] = b, t[2] = c;
}

bool xmesh_append(xmesh *dst, const xmesh *src)
{
    if (!reserve(dst, src->nv, src->nt)) {
        return false;
    }
    uint32_t base = dst->nv;
    memcpy(dst->pos + 3 * (size_t)dst->nv, src->pos, sizeof(float) * 3 * src->nv);
    dst->nv += src->nv;
    for (uint32_t t = 0; t < src->nt; ++t) {
        add_t(dst, src->tris[3 * t] + base, src->tris[3 * t + 1] + base, src->tris[3 * t + 2] + base);
    }
    return true;
}

uint64_t xrng_next(xrng *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

double xrng_uniform(xrng *r, double lo, double hi) { return lo + (hi - lo) * (double)(xrng_next(r) >> 11) * 0x1.0p-53; }

uint32_t xrng_below(xrng *r, uint32_t n) { return n ? (uint32_t)(xrng_next(r) % n) : 0; }

const char *xsheet_shape_name(xsheet_shape shape)
{
    static const char *const names[] = {"rectangle", "ellipse", "lshape"};
    return shape < XSHEET_COUNT ? names[shape] : "unknown";
}

static bool sheet_inside(xsheet_shape shape, double u, double v)
{
    /* u, v in [-0.5, 0.5] */
    switch (shape) {
    case XSHEET_ELLIPSE:
        return u * u + v * v <= 0.25 + 1e-9;
    case XSHEET_LSHAPE:
        return !(u > 0.02 && v > 0.02);
    default:
        return true;
    }
}

bool xsheet_make(xmesh *m, xsheet_shape shape, double sx, double sz, uint32_t target_vertices)
{
    double fill = shape == XSHEET_ELLIPSE ? SPI / 4.0 : (shape == XSHEET_LSHAPE ? 0.75 : 1.0);
    double grid = target_vertices / fill;
    /* nx / nz follows the aspect ratio so triangles stay close to right-isosceles. */
    uint32_t nx = (uint32_t)(sqrt(grid * sx / sz) + 0.5), nz = (uint32_t)(grid / (nx ? nx : 1) + 0.5);
    nx = nx < 3 ? 3 : nx;
    nz = nz < 3 ? 3 : nz;
    uint32_t *remap = malloc(sizeof(uint32_t) * nx * nz);
    xmesh full = {0};
    if (!remap || !reserve(&full, nx * nz, 2 * nx * nz)) {
        free(remap);
        xmesh_free(&full);
        return false;
    }
    for (uint32_t j = 0; j < nz; ++j) {
        for (uint32_t i = 0; i < nx; ++i) {
            add_v(&full, sx * ((double)i / (nx - 1) - 0.5), 0.0, sz * ((double)j / (nz - 1) - 0.5));
        }
    }
    *m = (xmesh){0};
    bool ok = reserve(m, nx * nz, 2 * nx * nz);
    for (uint32_t k = 0; k < nx * nz; ++k) {
        remap[k] = UINT32_MAX;
    }
    for (uint32_t j = 0; ok && j + 1 < nz; ++j) {
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t a = j * nx + i, b = a + 1, c = a + nx, d = c + 1;
            uint32_t q[6];
            if ((i + j) & 1) {
                q[0] = a, q[1] = c, q[2] = b, q[3] = b, q[4] = c, q[5] = d;
            } else {
                q[0] = a, q[1] = c, q[2] = d, q[3] = a, q[4] = d, q[5] = b;
            }
            for (int t = 0; t < 2; ++t) {
                bool in = true;
                for (int k = 0; k < 3; ++k) {
                    const float *p = full.pos + 3 * (size_t)q[3 * t + k];
                    in = in && sheet_inside(shape, p[0] / sx, p[2] / sz);
                }
                if (!in) {
                    continue;
                }
                uint32_t idx[3];
                for (int k = 0; k < 3; ++k) {
                    uint32_t o = q[3 * t + k];
                    if (remap[o] == UINT32_MAX) {
                        const float *p = full.pos + 3 * (size_t)o;
                        remap[o] = add_v(m, p[0], p[1], p[2]);
                    }
                    idx[k] = remap[o];
                }
                add_t(m, idx[0], idx[1], idx[2]);
            }
        }
    }
    free(remap);
    xmesh_free(&full);
    return ok && m->nt > 0;
}

static void rot_yaw(double yaw, double *x, double *z)
{
    double c = cos(yaw), s = sin(yaw), a = *x, b = *z;
    *x = c * a + s * b;
    *z = -s * a + c * b;
}

bool xshape_box(xmesh *m, const double c[3], const double half[3], double yaw)
{
    if (!reserve(m, 8, 12)) {
        return false;
    }
    uint32_t base = m->nv;
    for (uint32_t i = 0; i < 8; ++i) {
        double x = (i & 1) ? half[0] : -half[0], y = (i & 2) ? half[1] : -half[1], z = (i & 4) ? half[2] : -half[2];
        rot_yaw(yaw, &x, &z);
        add_v(m, c[0] + x, c[1] + y, c[2] + z);
    }
    static const uint32_t t[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    for (int i = 0; i < 12; ++i) {
        add_t(m, base + t[3 * i], base + t[3 * i + 1], base + t[3 * i + 2]);
    }
    return true;
}

/* Latitude-longitude grid closed by two poles; radius(theta, phi) from the callback. */
typedef double radius_fn(const double dir[3], void *user);

static bool latlong(xmesh *m, const double c[3], uint32_t rings, uint32_t segs, radius_fn *rf, void *user)
{
    if (!reserve(m, (rings - 1) * segs + 2, 2 * rings * segs)) {
        return false;
    }
    uint32_t base = m->nv;
    double up[3] = {0, 1, 0}, dn[3] = {0, -1, 0};
    double ru = rf(up, user), rd = rf(dn, user);
    add_v(m, c[0], c[1] + ru, c[2]);
    for (uint32_t i = 1; i < rings; ++i) {
        double th = SPI * i / rings;
        for (uint32_t j = 0; j < segs; ++j) {
            double ph = 2.0 * SPI * j / segs;
            double d[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
            double r = rf(d, user);
            add_v(m, c[0] + r * d[0], c[1] + r * d[1], c[2] + r * d[2]);
        }
    }
    uint32_t bottom = add_v(m, c[0], c[1] - rd, c[2]);
    for (uint32_t j = 0; j < segs; ++j) {
        uint32_t j1 = (j + 1) % segs;
        add_t(m, base, base + 1 + j1, base + 1 + j);
        for (uint32_t i = 1; i + 1 < rings; ++i) {
            uint32_t a = base + 1 + (i - 1) * segs + j, b = base + 1 + (i - 1) * segs + j1;
            uint32_t cc = base + 1 + i * segs + j, d = base + 1 + i * segs + j1;
            add_t(m, a, b, d);
            add_t(m, a, d, cc);
        }
        uint32_t last = base + 1 + (rings - 2) * segs;
        add_t(m, bottom, last + j, last + j1);
    }
    return true;
}

static double const_radius(const double dir[3], void *user)
{
    (void)dir;
    return *(const double *)user;
}

bool xshape_sphere(xmesh *m, const double c[3], double r, uint32_t rings, uint32_t segs)
{
    return latlong(m, c, rings, segs, const_radius, &r);
}

typedef struct blob_params {
    double r;
    double dir[4][3], amp[4], width[4];
} blob_params;

/* Radius = r (1 + sum of smooth bumps around random directions), bumps of either sign. */
static double blob_radius(const double d[3], void *user)
{
    const blob_params *b = user;
    double s = 1.0;
    for (int k = 0; k < 4; ++k) {
        double c = d[0] * b->dir[k][0] + d[1] * b->dir[k][1] + d[2] * b->dir[k][2];
        s += b->amp[k] * exp((c - 1.0) / b->width[k]);
    }
    return b->r * s;
}

bool xshape_blob(xmesh *m, const double c[3], double r, xrng *rng)
{
    blob_params b = {.r = r};
    for (int k = 0; k < 4; ++k) {
        double z = xrng_uniform(rng, -1, 1), ph = xrng_uniform(rng, 0, 2 * SPI), s = sqrt(1 - z * z);
        b.dir[k][0] = s * cos(ph), b.dir[k][1] = z, b.dir[k][2] = s * sin(ph);
        b.amp[k] = xrng_uniform(rng, -0.3, 0.5);
        b.width[k] = xrng_uniform(rng, 0.1, 0.4);
    }
    return latlong(m, c, 20, 32, blob_radius, &b);
}

bool xshape_cylinder(xmesh *m, const double c[3], double r, double half_len, int axis, uint32_t segs)
{
    if (!reserve(m, 2 * segs + 2, 4 * segs)) {
        return false;
    }
    uint32_t base = m->nv;
    /* Local frame: axis along local y; mapped so local y -> the requested axis. */
    for (int end = 0; end < 2; ++end) {
        for (uint32_t j = 0; j < segs; ++j) {
            double ph = 2.0 * SPI * j / segs;
            double l[3] = {r * cos(ph), end ? half_len : -half_len, r * sin(ph)};
            double w[3] = {l[0], l[1], l[2]};
            if (axis == 0) {
                w[0] = l[1], w[1] = l[0], w[2] = -l[2];
            } else if (axis == 2) {
                w[0] = l[0], w[1] = l[2], w[2] = -l[1];
            }
            add_v(m, c[0] + w[0], c[1] + w[1], c[2] + w[2]);
        }
    }
    double cap[2][3] = {{0, -half_len, 0}, {0, half_len, 0}};
    for (int end = 0; end < 2; ++end) {
        double *l = cap[end], w[3] = {l[0], l[1], l[2]};
        if (axis == 0) {
            w[0] = l[1], w[1] = l[0], w[2] = -l[2];
        } else if (axis == 2) {
            w[0] = l[0], w[1] = l[2], w[2] = -l[1];
        }
        add_v(m, c[0] + w[0], c[1] + w[1], c[2] + w[2]);
    }
    uint32_t cb = base + 2 * segs, ct = cb + 1;
    for (uint32_t j = 0; j < segs; ++j) {
        uint32_t j1 = (j + 1) % segs;
        uint32_t a = base + j, b = base + j1, cc = base + segs + j, d = base + segs + j1;
        add_t(m, a, cc, d);
        add_t(m, a, d, b);
        add_t(m, cb, a, b);
        add_t(m, ct, d, cc);
    }
    return true;
}

bool xshape_torus(xmesh *m, const double c[3], double R, double r, uint32_t su, uint32_t sv)
{
    if (!reserve(m, su * sv, 2 * su * sv)) {
        return false;
    }
    uint32_t base = m->nv;
    for (uint32_t i = 0; i < su; ++i) {
        double u = 2.0 * SPI * i / su;
        for (uint32_t j = 0; j < sv; ++j) {
            double v = 2.0 * SPI * j / sv;
            add_v(m, c[0] + (R + r * cos(v)) * cos(u), c[1] + r * sin(v), c[2] + (R + r * cos(v)) * sin(u));
        }
    }
    for (uint32_t i = 0; i < su; ++i) {
        for (uint32_t j = 0; j < sv; ++j) {
            uint32_t i1 = (i + 1) % su, j1 = (j + 1) % sv;
            uint32_t a = base + i * sv + j, b = base + i1 * sv + j, cc = base + i * sv + j1, d = base + i1 * sv + j1;
            add_t(m, a, cc, d);
            add_t(m, a, d, b);
        }
    }
    return true;
}

bool xshape_ground(xmesh *m, double half)
{
    if (!reserve(m, 4, 2)) {
        return false;
    }
    uint32_t a = add_v(m, -half, 0, -half), b = add_v(m, half, 0, -half), c = add_v(m, half, 0, half),
             d = add_v(m, -half, 0, half);
    add_t(m, a, d, c);
    add_t(m, a, c, b);
    return true;
}

/* ---------------------------------------------------------------------------------------- */
/* Scenarios                                                                                 */

void xscene_free(xscene *sc)
{
    xmesh_free(&sc->cloth);
    xmesh_free(&sc->collider);
    free(sc->cloth_init);
    free(sc->finger_rest);
    free(sc->grasped);
    free(sc->grasp_offset);
    free(sc->band_idx);
    free(sc->band_tri);
    free(sc->band_bary);
    free(sc->band_off);
    weft_body_destroy(sc->body);
    weft_clip_destroy(sc->clip);
    free(sc->parts);
    *sc = (xscene){0};
}

static void append_name(xscene *sc, const char *name)
{
    size_t len = strlen(sc->objects);
    snprintf(sc->objects + len, sizeof sc->objects - len, "%s%s", len ? "," : "", name);
}

/* One rigid object standing on the ground at (x, z); returns its top height. */
static double add_object(xscene *sc, xrng *r, double x, double z, bool *ok)
{
    xmesh *m = &sc->collider;
    double yaw = xrng_uniform(r, 0, SPI);
    uint32_t kind = xrng_below(r, 9);
    double top = 0.0;
    switch (kind) {
    case 0: { /* box */
        double h[3] = {xrng_uniform(r, 0.08, 0.25), xrng_uniform(r, 0.05, 0.25), xrng_uniform(r, 0.08, 0.25)};
        double c[3] = {x, h[1], z};
        *ok = *ok && xshape_box(m, c, h, yaw);
        top = 2 * h[1];
        append_name(sc, "box");
        break;
    }
    case 1: { /* sphere */
        double rad = xrng_uniform(r, 0.08, 0.22), c[3] = {x, rad, z};
        *ok = *ok && xshape_sphere(m, c, rad, 16, 24);
        top = 2 * rad;
        append_name(sc, "sphere");
        break;
    }
    case 2: { /* upright cylinder */
        double rad = xrng_uniform(r, 0.05, 0.18), hl = xrng_uniform(r, 0.08, 0.25), c[3] = {x, hl, z};
        *ok = *ok && xshape_cylinder(m, c, rad, hl, 1, 24);
        top = 2 * hl;
        append_name(sc, "cylinder");
        break;
    }
    case 3: { /* torus lying flat: concave */
        double R = xrng_uniform(r, 0.12, 0.22), rr = xrng_uniform(r, 0.03, 0.06), c[3] = {x, rr, z};
        *ok = *ok && xshape_torus(m, c, R, rr, 32, 12);
        top = 2 * rr;
        append_name(sc, "torus");
        break;
    }
    case 4: { /* L-block: two boxes, concave corner */
        double h = xrng_uniform(r, 0.1, 0.25), a[3] = {0.2, h, 0.06}, b[3] = {0.06, h, 0.2};
        double ca[3] = {x, h, z - 0.14}, cb[3] = {x - 0.14, h, z};
        *ok = *ok && xshape_box(m, ca, a, 0.0) && xshape_box(m, cb, b, 0.0);
        top = 2 * h;
        append_name(sc, "lblock");
        break;
    }
    case 5: { /* thin stick held horizontally */
        double hgt = xrng_uniform(r, 0.15, 0.35), c[3] = {x, hgt, z};
        *ok = *ok && xshape_cylinder(m, c, xrng_uniform(r, 0.006, 0.012), xrng_uniform(r, 0.3, 0.5),
                                     xrng_below(r, 2) ? 0 : 2, 12);
        top = hgt + 0.012;
        append_name(sc, "stick");
        break;
    }
    case 6: { /* blade standing on its long edge */
        double h[3] = {xrng_uniform(r, 0.15, 0.3), xrng_uniform(r, 0.08, 0.2), 0.0015}, c[3] = {x, h[1], z};
        *ok = *ok && xshape_box(m, c, h, yaw);
        top = 2 * h[1];
        append_name(sc, "blade");
        break;
    }
    case 7: { /* random blob */
        double rad = xrng_uniform(r, 0.08, 0.16), c[3] = {x, rad * 1.4, z};
        *ok = *ok && xshape_blob(m, c, rad, r);
        top = rad * 2.9;
        append_name(sc, "blob");
        break;
    }
    default: { /* table: top and four legs */
        double hgt = xrng_uniform(r, 0.25, 0.45), tx = xrng_uniform(r, 0.2, 0.35), tz = xrng_uniform(r, 0.15, 0.3);
        double top_half[3] = {tx, 0.015, tz}, top_c[3] = {x, hgt - 0.015, z};
        *ok = *ok && xshape_box(m, top_c, top_half, 0.0);
        for (int k = 0; k < 4; ++k) {
            double leg[3] = {0.02, (hgt - 0.03) / 2, 0.02};
            double lc[3] = {x + ((k & 1) ? 1 : -1) * (tx - 0.03), (hgt - 0.03) / 2, z + ((k & 2) ? 1 : -1) * (tz - 0.03)};
            *ok = *ok && xshape_box(m, lc, leg, 0.0);
        }
        top = hgt;
        append_name(sc, "table");
        break;
    }
    }
    return top;
}

static weft_result build_drop(xscene *sc, const weft_sim_sequence_def *def, xrng *r)
{
    bool ok = xshape_ground(&sc->collider, 3.0);
    uint32_t objects = 1 + (xrng_below(r, 3) == 0);
    double top = 0.0;
    for (uint32_t k = 0; k < objects && ok; ++k) {
        double x = objects == 1 ? 0.0 : (k ? 0.22 : -0.22), z = xrng_uniform(r, -0.05, 0.05);
        double t = add_object(sc, r, x, z, &ok);
        top = t > top ? t : top;
    }
    xsheet_shape shape = (xsheet_shape)xrng_below(r, XSHEET_COUNT);
    double sx = xrng_uniform(r, 0.5, 1.0), sz = sx * xrng_uniform(r, 0.6, 1.0);
    ok = ok && xsheet_make(&sc->cloth, shape, sx, sz, def->cloth_vertices);
    if (!ok) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: scene construction ran out of memory");
    }
    /* Initial placement: random yaw, tilt up to 20 degrees, offset, height above the top. */
    double yaw = xrng_uniform(r, 0, 2 * SPI), tilt = xrng_uniform(r, 0, 0.35), tdir = xrng_uniform(r, 0, 2 * SPI);
    double off[3] = {xrng_uniform(r, -0.12, 0.12), top + xrng_uniform(r, 0.08, 0.3) + 0.5 * sx * sin(tilt),
                     xrng_uniform(r, -0.12, 0.12)};
    sc->cloth_init = malloc(sizeof(float) * 3 * sc->cloth.nv);
    if (!sc->cloth_init) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    double ax[3] = {cos(tdir), 0, sin(tdir)}; /* tilt axis in the XZ plane */
    for (uint32_t i = 0; i < sc->cloth.nv; ++i) {
        double p[3] = {sc->cloth.pos[3 * i], sc->cloth.pos[3 * i + 1], sc->cloth.pos[3 * i + 2]};
        rot_yaw(yaw, &p[0], &p[2]);
        /* Rodrigues rotation about ax by tilt. */
        double c = cos(tilt), s = sin(tilt), d = ax[0] * p[0] + ax[2] * p[2];
        double cr[3] = {ax[1] * p[2] - ax[2] * p[1], ax[2] * p[0] - ax[0] * p[2], ax[0] * p[1] - ax[1] * p[0]};
        for (int k = 0; k < 3; ++k) {
            sc->cloth_init[3 * i + k] = (float)(p[k] * c + cr[k] * s + ax[k] * d * (1 - c) + off[k]);
        }
    }
    snprintf(sc->description, sizeof sc->description, "drop: %s sheet %.2fx%.2f m onto %.96s", xsheet_shape_name(shape),
             sx, sz, sc->objects);
    sc->moving_begin = sc->collider.nv;
    return WEFT_OK;
}

static double smooth01(double t) { return t <= 0 ? 0 : (t >= 1 ? 1 : t * t * (3 - 2 * t)); }

/* Height of the grasped patch above its initial height when the gripper has set the sheet
 * down and lets go (m): room for about ten cloth layers folded beneath it. */
#define GRIPPER_SET_DOWN 0.02

/* Gripper centre (fingertip midpoint) and jaw gap at frame f. */
static void gripper_at(const xscene *sc, uint32_t f, double c[3], double *gap)
{
    const double hover = 0.15;
    double g0[3] = {sc->grasp[0], sc->grasp[1], sc->grasp[2]};
    c[0] = g0[0], c[1] = g0[1], c[2] = g0[2];
    double lift = 0.0, mv = 0.0, rise = 0.0;
    if (f < sc->f_close) {
        /* descend from the hover height to the grasp height */
        c[1] += hover * (1.0 - smooth01((double)f / (sc->f_close * 0.7)));
    }
    if (f >= sc->f_close) {
        lift = smooth01((double)(f - sc->f_close) / (sc->f_lifted - sc->f_close));
    }
    if (f >= sc->f_lifted) {
        mv = smooth01((double)(f - sc->f_lifted) / (sc->f_moved - sc->f_lifted));
    }
    if (f >= sc->f_moved) {
        /* Set down to GRIPPER_SET_DOWN above the grasp height, not to it: the hanging sheet
         * lands first and folds under the grasped patch, and pins driven back to their
         * initial 4 mm would press it into the ground (two layers need 2.5 + 1.5 mm plus
         * 1.5 mm to the pinned vertex), which no contact can resolve. */
        const double low = GRIPPER_SET_DOWN / sc->lift;
        lift = 1.0 - (1.0 - low) * smooth01((double)(f - sc->f_moved) / (sc->f_lowered - sc->f_moved));
    }
    if (f >= sc->f_open) {
        rise = smooth01((double)(f - sc->f_open) / 25.0);
    }
    c[0] += mv * sc->move[0];
    c[2] += mv * sc->move[1];
    c[1] += lift * sc->lift + rise * hover;
    double close_t = 0.7 * sc->f_close;
    double closing = f < close_t ? 0.0 : smooth01((f - close_t) / (sc->f_close - close_t));
    double opening = f < sc->f_release ? 0.0 : smooth01((double)(f - sc->f_release) / (sc->f_open - sc->f_release));
    *gap = sc->gap_open + (sc->gap_closed - sc->gap_open) * (closing - opening);
}

static weft_result build_gripper(xscene *sc, const weft_sim_sequence_def *def, xrng *r)
{
    bool ok = xshape_ground(&sc->collider, 3.0);
    xsheet_shape shape = (xsheet_shape)xrng_below(r, XSHEET_COUNT);
    double sx = xrng_uniform(r, 0.3, 0.7), sz = sx * xrng_uniform(r, 0.6, 1.0);
    ok = ok && xsheet_make(&sc->cloth, shape, sx, sz, def->cloth_vertices);
    sc->cloth_init = ok ? malloc(sizeof(float) * 3 * sc->cloth.nv) : NULL;
    if (!ok || !sc->cloth_init) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: scene construction ran out of memory");
    }
    double yaw = xrng_uniform(r, 0, 2 * SPI);
    const double rest_h = 0.004; /* above the ground contact thickness */
    for (uint32_t i = 0; i < sc->cloth.nv; ++i) {
        double x = sc->cloth.pos[3 * i], z = sc->cloth.pos[3 * i + 2];
        rot_yaw(yaw, &x, &z);
        sc->cloth_init[3 * i] = (float)x;
        sc->cloth_init[3 * i + 1] = (float)rest_h;
        sc->cloth_init[3 * i + 2] = (float)z;
    }
    /* Grasp point: a random vertex, biased to the border half of the time. */
    uint32_t gv = xrng_below(r, sc->cloth.nv);
    if (xrng_below(r, 2)) {
        double best = -1.0;
        for (int k = 0; k < 8; ++k) {
            uint32_t cand = xrng_below(r, sc->cloth.nv);
            double d = fabs(sc->cloth.pos[3 * cand]) / sx + fabs(sc->cloth.pos[3 * cand + 2]) / sz;
            if (d > best) {
                best = d, gv = cand;
            }
        }
    }
    sc->finger_half[0] = 0.006, sc->finger_half[1] = 0.03, sc->finger_half[2] = 0.012;
    sc->gap_open = 0.06;
    sc->gap_closed = 0.02;
    sc->grasp[0] = sc->cloth_init[3 * gv];
    sc->grasp[1] = rest_h + 0.011; /* fingertips 11 mm above the cloth */
    sc->grasp[2] = sc->cloth_init[3 * gv + 2];
    sc->lift = xrng_uniform(r, 0.15, 0.45);
    double ang = xrng_uniform(r, 0, 2 * SPI), dist = xrng_uniform(r, 0.1, 0.4);
    sc->move[0] = dist * cos(ang), sc->move[1] = dist * sin(ang);
    /* Time scale of the whole schedule: drawn first so every motion_speed gets the same draw. */
    double speed = xrng_uniform(r, 0.7, 1.3) / def->motion_speed;
    sc->f_close = (uint32_t)(30 * speed);
    sc->f_lifted = sc->f_close + (uint32_t)(45 * speed);
    sc->f_moved = sc->f_lifted + (uint32_t)(45 * speed);
    sc->f_lowered = sc->f_moved + (uint32_t)(40 * speed);
    sc->f_release = sc->f_lowered + 5;
    sc->f_open = sc->f_release + 10;
    /* Grasped patch: vertices within 12 mm (horizontally) of the grasp point. */
    sc->grasped = malloc(sizeof(uint32_t) * sc->cloth.nv);
    sc->grasp_offset = malloc(sizeof(float) * 3 * sc->cloth.nv);
    sc->finger_rest = malloc(sizeof(float) * 48);
    if (!sc->grasped || !sc->grasp_offset || !sc->finger_rest) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    for (uint32_t i = 0; i < sc->cloth.nv; ++i) {
        double dx = sc->cloth_init[3 * i] - sc->grasp[0], dz = sc->cloth_init[3 * i + 2] - sc->grasp[2];
        if (dx * dx + dz * dz <= 0.012 * 0.012) {
            sc->grasped[sc->grasp_count] = i;
            sc->grasp_offset[3 * sc->grasp_count] = (float)dx;
            sc->grasp_offset[3 * sc->grasp_count + 1] = (float)(sc->cloth_init[3 * i + 1] - sc->grasp[1]);
            sc->grasp_offset[3 * sc->grasp_count + 2] = (float)dz;
            sc->grasp_count++;
        }
    }
    if (sc->grasp_count == 0) {
        sc->grasped[0] = gv;
        sc->grasp_offset[0] = 0.0f;
        sc->grasp_offset[1] = (float)(rest_h - sc->grasp[1]);
        sc->grasp_offset[2] = 0.0f;
        sc->grasp_count = 1;
    }
    /* Two fingers (boxes) along X of the gripper frame, tips at the gripper centre height. */
    sc->moving_begin = sc->collider.nv;
    double zero[3] = {0, 0, 0};
    xmesh fingers = {0};
    ok = xshape_box(&fingers, zero, sc->finger_half, 0.0) && xshape_box(&fingers, zero, sc->finger_half, 0.0) &&
         xmesh_append(&sc->collider, &fingers);
    if (ok) {
        memcpy(sc->finger_rest, fingers.pos, sizeof(float) * 48);
    }
    xmesh_free(&fingers);
    if (!ok) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    xscene_collider_at(sc, 0, sc->collider.pos);
    append_name(sc, "ground,gripper");
    snprintf(sc->description, sizeof sc->description,
             "gripper: %s sheet %.2fx%.2f m, grasp vertex %u, lift %.2f m, move %.2f m", xsheet_shape_name(shape), sx,
             sz, gv, sc->lift, dist);
    return WEFT_OK;
}

/* The clip's pose turned by -clip_yaw about the vertical through clip_from, moved to clip_to. */
static void clip_normalise(const xscene *sc, weft_pose *pose)
{
    weft_pose_place(sc->body, pose, -sc->clip_yaw, sc->clip_from, sc->clip_to);
}

static void clip_pose_at(const xscene *sc, double t, weft_pose *pose)
{
    if (weft_clip_sample(sc->clip, sc->clip_start_s + t * sc->clip_speed, pose) != WEFT_OK) {
        *pose = sc->start_pose; /* cannot happen: the clip was checked when loaded */
        return;
    }
    clip_normalise(sc, pose);
}

/* Body pose at frame f: blend from the bind pose to the motion's first pose over the first
 * half of the pre-roll, hold it to settle, then play the motion. */
static void garment_pose_at(const xscene *sc, uint32_t f, weft_pose *pose)
{
    if (sc->clip) {
        if (f >= sc->preroll) {
            clip_pose_at(sc, (f - sc->preroll) / 60.0, pose);
        } else if (weft_pose_blend(&sc->bind_pose, &sc->start_pose, smooth01((double)f / (sc->preroll / 2)), pose) !=
                   WEFT_OK) {
            *pose = sc->start_pose;
        }
        return;
    }
    if (f >= sc->preroll) {
        /* Eased in, the motion's clock speeds up linearly from 0 to 1 over ease_in_s (tau = t^2/2T,
         * then t - T/2): the limbs start from rest instead of at full speed (a run's fastest
         * vertex moved 8 cm in its first frame, xpbd.garment_band). */
        double t = (f - sc->preroll) / 60.0, T = sc->ease_in_s;
        weft_motion_sample(&sc->motion, t >= T ? t - 0.5 * T : t * t / (2.0 * T), pose);
        return;
    }
    double a = smooth01((double)f / (sc->preroll / 2));
    for (size_t k = 0; k < sizeof pose->rotations / sizeof pose->rotations[0]; ++k) {
        pose->rotations[k] = (float)((1 - a) * sc->bind_pose.rotations[k] + a * sc->start_pose.rotations[k]);
    }
    for (int k = 0; k < 3; ++k) {
        pose->translation[k] = (float)((1 - a) * sc->bind_pose.translation[k] + a * sc->start_pose.translation[k]);
    }
}

/* Orthonormal frame of triangle (a, b, c): edge direction, bitangent, normal. */
static void tri_frame(const float *a, const float *b, const float *c, double e[3], double t[3], double n[3])
{
    double u[3], w[3];
    for (int k = 0; k < 3; ++k) {
        u[k] = (double)b[k] - a[k];
        w[k] = (double)c[k] - a[k];
    }
    geo_cross(n, u, w);
    double ln = geo_len(n), lu = geo_len(u);
    for (int k = 0; k < 3; ++k) {
        n[k] = ln > 0.0 ? n[k] / ln : 0.0;
        e[k] = lu > 0.0 ? u[k] / lu : 0.0;
    }
    geo_cross(t, n, e);
}

static void band_point(const xscene *sc, const float *body, uint32_t k, double out[3], double e[3], double t[3],
                       double n[3])
{
    const uint32_t *tri = sc->collider.tris + 3 * (size_t)sc->band_tri[k];
    const float *a = body + 3 * (size_t)tri[0], *b = body + 3 * (size_t)tri[1], *c = body + 3 * (size_t)tri[2];
    const float *w = sc->band_bary + 3 * (size_t)k;
    for (int i = 0; i < 3; ++i) {
        out[i] = (double)w[0] * a[i] + (double)w[1] * b[i] + (double)w[2] * c[i];
    }
    tri_frame(a, b, c, e, t, n);
}

/* Binds the garment's top ring (rest y within 12 mm of its highest vertex) to the closest
 * body triangles at the bind pose (collider.pos at frame 0). */
static bool bind_band(xscene *sc)
{
    const xmesh *cl = &sc->cloth, *co = &sc->collider;
    float top = -INFINITY;
    for (uint32_t i = 0; i < cl->nv; ++i) {
        top = fmaxf(top, cl->pos[3 * (size_t)i + 1]);
    }
    uint32_t n = 0;
    for (uint32_t i = 0; i < cl->nv; ++i) {
        n += cl->pos[3 * (size_t)i + 1] >= top - 0.012f;
    }
    sc->band_idx = malloc(sizeof(uint32_t) * n);
    sc->band_tri = malloc(sizeof(uint32_t) * n);
    sc->band_bary = malloc(sizeof(float) * 3 * n);
    sc->band_off = malloc(sizeof(float) * 3 * n);
    if (!sc->band_idx || !sc->band_tri || !sc->band_bary || !sc->band_off) {
        return false;
    }
    for (uint32_t i = 0; i < cl->nv; ++i) {
        if (cl->pos[3 * (size_t)i + 1] < top - 0.012f) {
            continue;
        }
        double x[3] = {cl->pos[3 * (size_t)i], cl->pos[3 * (size_t)i + 1], cl->pos[3 * (size_t)i + 2]};
        double best = INFINITY, bary[3] = {1, 0, 0};
        uint32_t bt = 0;
        for (uint32_t t = 0; t < co->nt; ++t) {
            const uint32_t *tri = co->tris + 3 * (size_t)t;
            double p[3][3], w[3];
            for (int v = 0; v < 3; ++v) {
                for (int k = 0; k < 3; ++k) {
                    p[v][k] = co->pos[3 * (size_t)tri[v] + k];
                }
            }
            double d = geo_point_triangle_sq(x, p[0], p[1], p[2], w);
            if (d < best) {
                best = d, bt = t;
                memcpy(bary, w, sizeof bary);
            }
        }
        uint32_t k = sc->band_count++;
        sc->band_idx[k] = i;
        sc->band_tri[k] = bt;
        for (int a = 0; a < 3; ++a) {
            sc->band_bary[3 * (size_t)k + a] = (float)bary[a];
        }
        double q[3], e[3], t[3], nn[3], d[3];
        band_point(sc, co->pos, k, q, e, t, nn);
        geo_sub(d, x, q);
        sc->band_off[3 * (size_t)k + 0] = (float)geo_dot(d, e);
        sc->band_off[3 * (size_t)k + 1] = (float)geo_dot(d, t);
        sc->band_off[3 * (size_t)k + 2] = (float)geo_dot(d, nn);
    }
    return true;
}

/* The dress's top ring sits at the armpits: pinned there, its side vertices cannot yield when
 * the arms come down from the bind pose, and the upper arm sweeps through them (measured: every
 * rejected dress had its first hit on the band, 23-35 frames into the blend). Band vertices whose
 * pinned target comes within BAND_ARM_CLEARANCE of an arm vertex (skinning weight on the
 * shoulder..hand joints over one half) during the pre-roll are left free; the rest of the band
 * holds the garment up. Nothing is released where the arms stay clear (skirts, most waists). */
#define BAND_ARM_CLEARANCE 0.04
static bool release_band_near_arms(xscene *sc)
{
    const uint32_t nv = weft_body_vertex_count(sc->body);
    const float *w = weft_body_weights(sc->body);
    float *body = malloc(sizeof(float) * 3 * nv);
    double *closest = malloc(sizeof(double) * (sc->band_count ? sc->band_count : 1));
    uint32_t *arm = malloc(sizeof(uint32_t) * nv);
    if (!body || !closest || !arm) {
        free(body), free(closest), free(arm);
        return false;
    }
    uint32_t na = 0;
    for (uint32_t i = 0; i < nv; ++i) {
        float s = 0.0f;
        for (uint32_t j = WEFT_JOINT_LEFT_SHOULDER; j <= WEFT_JOINT_RIGHT_HAND; ++j) {
            s += w[24 * (size_t)i + j];
        }
        if (s > 0.5f) {
            arm[na++] = i;
        }
    }
    for (uint32_t k = 0; k < sc->band_count; ++k) {
        closest[k] = INFINITY;
    }
    for (uint32_t f = 0; f <= sc->preroll; ++f) { /* the blend, then the held first pose */
        xscene_collider_at(sc, f, body);
        for (uint32_t k = 0; k < sc->band_count; ++k) {
            double q[3], e[3], t[3], n[3], x[3];
            band_point(sc, body, k, q, e, t, n);
            const float *o = sc->band_off + 3 * (size_t)k;
            for (int a = 0; a < 3; ++a) {
                x[a] = q[a] + o[0] * e[a] + o[1] * t[a] + o[2] * n[a];
            }
            for (uint32_t i = 0; i < na; ++i) {
                const float *p = body + 3 * (size_t)arm[i];
                double d[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
                closest[k] = fmin(closest[k], geo_dot(d, d));
            }
        }
    }
    uint32_t kept = 0;
    for (uint32_t k = 0; k < sc->band_count; ++k) {
        if (closest[k] < BAND_ARM_CLEARANCE * BAND_ARM_CLEARANCE) {
            continue;
        }
        sc->band_idx[kept] = sc->band_idx[k];
        sc->band_tri[kept] = sc->band_tri[k];
        memcpy(sc->band_bary + 3 * (size_t)kept, sc->band_bary + 3 * (size_t)k, sizeof(float) * 3);
        memcpy(sc->band_off + 3 * (size_t)kept, sc->band_off + 3 * (size_t)k, sizeof(float) * 3);
        kept++;
    }
    sc->band_released = sc->band_count - kept;
    sc->band_count = kept;
    free(body), free(closest), free(arm);
    return true;
}

/* Whether the garment mesh (at the bind pose) intersects the body or itself at the bind pose
 * (exact triangle tests). *out is the answer; the result reports failures to check. */
static weft_result garment_intersects(weft_context *ctx, const weft_cloth_mesh *mesh, const weft_body *body,
                                      bool *out)
{
    const uint32_t bnv = weft_body_vertex_count(body), bnt = weft_body_triangle_count(body);
    float *bp = malloc(sizeof(float) * 3 * bnv);
    if (!bp) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    weft_pose bind;
    weft_body_bind_pose(body, &bind);
    weft_result res = weft_body_pose(body, &bind, bp, NULL);
    weft_ccd_world_def wd = weft_default_ccd_world_def();
    wd.cloth_triangles = mesh->triangles;
    wd.cloth_triangle_count = mesh->triangle_count;
    wd.cloth_vertex_count = mesh->vertex_count;
    wd.collider_triangles = weft_body_triangles(body);
    wd.collider_triangle_count = bnt;
    wd.collider_vertex_count = bnv;
    weft_ccd_world *w = NULL;
    if (res == WEFT_OK) {
        res = weft_ccd_world_create(ctx, &wd, &w);
    }
    weft_ccd_intersections in = {0};
    if (res == WEFT_OK) {
        res = weft_ccd_intersect_frame(w, mesh->positions, bp, &in);
    }
    *out = in.cloth_cloth + in.cloth_collider > 0;
    weft_ccd_world_destroy(w);
    free(bp);
    return res;
}

/* The motion-capture clip of def->motion_path retargeted to sc->body, its window turned and moved
 * to start where the bind pose stands, facing as it does, and the body parts of the reference
 * garment and the validator. */
static weft_result load_clip(weft_context *ctx, xscene *sc, const weft_sim_sequence_def *def)
{
    weft_bvh_def bd = weft_default_bvh_def();
    bd.rest_joints = weft_body_rest_joints(sc->body);
    bd.joint_map = def->motion_joint_map;
    weft_result res = weft_bvh_load_file(ctx, def->motion_path, &bd, &sc->clip);
    if (res != WEFT_OK) {
        return res;
    }
    const double duration = sc->clip->frame_count > 1 ? (sc->clip->frame_count - 1) / (double)sc->clip->fps : 0.0;
    if (!(def->motion_start_s < duration)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "simgen: motion_start_s %g is not before the end of %s (%.2f s)",
                          def->motion_start_s, def->motion_path, duration);
    }
    sc->clip_start_s = def->motion_start_s;
    sc->clip_speed = def->motion_speed;
    weft_pose first;
    if ((res = weft_clip_sample(sc->clip, sc->clip_start_s, &first)) != WEFT_OK) {
        return res;
    }
    sc->clip_yaw = weft_pose_heading(&first); /* the root's forward axis (+Z at rest) on the floor */
    weft_pose_pelvis_xz(sc->body, &first, sc->clip_from);
    weft_pose_pelvis_xz(sc->body, &sc->bind_pose, sc->clip_to);
    clip_pose_at(sc, 0.0, &sc->start_pose);
    const uint32_t nt = weft_body_triangle_count(sc->body);
    sc->parts = malloc(nt ? nt : 1);
    if (!sc->parts) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    return weft_body_triangle_parts(sc->body, sc->parts, nt);
}

/* The garment scenario on the host's character (def->character): its meshes and parts copied, the
 * garment at rest on the bind pose, no waistband. */
static weft_result build_character(xscene *sc, const weft_sim_sequence_def *def)
{
    const weft_sim_character *c = def->character;
    sc->character = c;
    bool ok = reserve(&sc->cloth, c->garment_vertex_count, c->garment_triangle_count) &&
              reserve(&sc->collider, c->vertex_count, c->triangle_count);
    sc->cloth_init = ok ? malloc(sizeof(float) * 3 * c->garment_vertex_count) : NULL;
    sc->parts = c->triangle_parts && sc->cloth_init ? malloc(c->triangle_count) : NULL;
    if (!sc->cloth_init || (c->triangle_parts && !sc->parts)) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    memcpy(sc->cloth.pos, c->garment_positions, sizeof(float) * 3 * c->garment_vertex_count);
    memcpy(sc->cloth.tris, c->garment_triangles, sizeof(uint32_t) * 3 * c->garment_triangle_count);
    memcpy(sc->cloth_init, c->garment_positions, sizeof(float) * 3 * c->garment_vertex_count);
    sc->cloth.nv = c->garment_vertex_count;
    sc->cloth.nt = c->garment_triangle_count;
    memcpy(sc->collider.tris, c->triangles, sizeof(uint32_t) * 3 * c->triangle_count);
    sc->collider.nv = c->vertex_count;
    sc->collider.nt = c->triangle_count;
    if (sc->parts) {
        memcpy(sc->parts, c->triangle_parts, c->triangle_count);
    }
    sc->moving_begin = 0;
    sc->preroll = c->preroll;
    xscene_collider_at(sc, 0, sc->collider.pos);
    snprintf(sc->objects, sizeof sc->objects, "character");
    snprintf(sc->description, sizeof sc->description, "garment: %u-vertex garment on character %.64s%s",
             c->garment_vertex_count, c->name, sc->parts ? ", body parts" : "");
    return WEFT_OK;
}

static weft_result build_garment(weft_context *ctx, xscene *sc, const weft_sim_sequence_def *def, xrng *r,
                                 const xscene_gentle *gentle)
{
    if (def->character) {
        return build_character(sc, def);
    }
    weft_avatar_def ad = weft_default_avatar_def();
    ad.height = (float)xrng_uniform(r, 1.55, 1.9);
    ad.girth = (float)xrng_uniform(r, 0.85, 1.15);
    ad.shoulder_width = (float)xrng_uniform(r, 0.9, 1.1);
    ad.hip_width = (float)xrng_uniform(r, 0.9, 1.15);
    ad.chest = (float)xrng_uniform(r, 0.9, 1.15);
    ad.target_vertices = 4000;
    weft_result res = weft_avatar_create(ctx, &ad, &sc->body);
    if (res != WEFT_OK) {
        return res;
    }
    static const weft_cloth_kind kinds[3] = {WEFT_CLOTH_TSHIRT, WEFT_CLOTH_SKIRT, WEFT_CLOTH_DRESS};
    weft_cloth_kind kind = kinds[xrng_below(r, 3)]; /* drawn either way, so the later draws stay the seed's */
    if (def->garment_kind >= 0) {
        kind = (weft_cloth_kind)def->garment_kind;
    }
    weft_cloth_def cd = weft_default_cloth_def(kind);
    cd.target_vertices = def->cloth_vertices;
    weft_cloth_mesh *mesh = NULL;
    res = weft_cloth_create(ctx, &cd, sc->body, &mesh);
    /* A coarse garment's flat triangles can cut into the curved body although its vertices
     * keep their clearance (a 256-vertex T-shirt around the armpits): widen the clearance
     * until the bind-pose garment is intersection-free, so every sequence starts clean. */
    for (int widen = 0; res == WEFT_OK && widen < 6; ++widen) {
        bool hits = false;
        res = garment_intersects(ctx, mesh, sc->body, &hits);
        if (res != WEFT_OK || !hits) {
            break;
        }
        weft_cloth_destroy(mesh);
        mesh = NULL;
        cd.clearance *= 1.5f;
        if (cd.clearance > 0.1f) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH,
                              "simgen: the %u-vertex %s intersects the avatar at every clearance up to 10 cm",
                              def->cloth_vertices, weft_cloth_kind_name(kind));
        }
        res = weft_cloth_create(ctx, &cd, sc->body, &mesh);
    }
    if (res != WEFT_OK) {
        weft_cloth_destroy(mesh);
        return res;
    }
    sc->garment_clearance = cd.clearance;
    sc->cloth_kind = (int)kind;
    bool ok = reserve(&sc->cloth, mesh->vertex_count, mesh->triangle_count);
    if (ok) {
        memcpy(sc->cloth.pos, mesh->positions, sizeof(float) * 3 * mesh->vertex_count);
        memcpy(sc->cloth.tris, mesh->triangles, sizeof(uint32_t) * 3 * mesh->triangle_count);
        sc->cloth.nv = mesh->vertex_count;
        sc->cloth.nt = mesh->triangle_count;
        sc->cloth_init = malloc(sizeof(float) * 3 * mesh->vertex_count);
        ok = sc->cloth_init != NULL;
    }
    weft_cloth_destroy(mesh);
    uint32_t bnv = weft_body_vertex_count(sc->body), bnt = weft_body_triangle_count(sc->body);
    ok = ok && reserve(&sc->collider, bnv, bnt);
    if (!ok) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    memcpy(sc->cloth_init, sc->cloth.pos, sizeof(float) * 3 * sc->cloth.nv);
    memcpy(sc->collider.tris, weft_body_triangles(sc->body), sizeof(uint32_t) * 3 * bnt);
    sc->collider.nv = bnv;
    sc->collider.nt = bnt;
    sc->moving_begin = 0;
    static const weft_motion motions[6] = {WEFT_MOTION_IDLE,  WEFT_MOTION_WALK,  WEFT_MOTION_RUN,
                                           WEFT_MOTION_JUMP,  WEFT_MOTION_DANCE, WEFT_MOTION_ARM_RAISE};
    weft_motion m = motions[xrng_below(r, 6)];
    sc->motion = weft_default_motion_def(m);
    sc->motion.speed = (float)xrng_uniform(r, 0.6, 1.4) * def->motion_speed;
    sc->motion.amplitude = (float)xrng_uniform(r, 0.6, 1.0);
    sc->motion.height = ad.height;
    sc->motion.arm_spread = def->garment_arm_spread;
    if (gentle) { /* after every draw: the same scene either way */
        sc->motion.arm_spread += gentle->arm_spread;
        sc->ease_in_s = gentle->ease_in_s;
        sc->motion.amplitude *= gentle->amplitude_scale;
    }
    weft_body_bind_pose(sc->body, &sc->bind_pose);
    const char *motion_label = weft_motion_name(m);
    if (def->motion_path) {
        if ((res = load_clip(ctx, sc, def)) != WEFT_OK) {
            return res;
        }
        motion_label = sc->clip->name;
    } else if ((res = weft_motion_sample(&sc->motion, 0.0, &sc->start_pose)) != WEFT_OK) {
        return res;
    }
    sc->preroll = 90; /* 1.5 s: 45 frames of blending, 45 of settling */
    xscene_collider_at(sc, 0, sc->collider.pos);
    /* Skirts and dresses hang from an elastic band at their top edge; without it they slide
     * off the body during the drape (measured: below the knees after 90 frames). T-shirts
     * rest on the shoulders. */
    if ((kind == WEFT_CLOTH_SKIRT || kind == WEFT_CLOTH_DRESS) && (!bind_band(sc) || !release_band_near_arms(sc))) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "simgen: out of memory");
    }
    snprintf(sc->objects, sizeof sc->objects, "avatar");
    if (sc->clip) {
        snprintf(sc->description, sizeof sc->description,
                 "garment: %s on avatar h=%.2f girth=%.2f, mocap %s from %.2f s speed %.2f, projected body",
                 weft_cloth_kind_name(kind), ad.height, ad.girth, motion_label, sc->clip_start_s, sc->clip_speed);
    } else {
        snprintf(sc->description, sizeof sc->description,
                 "garment: %s on avatar h=%.2f girth=%.2f, motion %s speed %.2f amplitude %.2f%s",
                 weft_cloth_kind_name(kind), ad.height, ad.girth, motion_label, sc->motion.speed, sc->motion.amplitude,
                 gentle ? ", gentle retry" : "");
    }
    return WEFT_OK;
}

void xscene_collider_at(const xscene *sc, uint32_t f, float *out)
{
    if (sc->character) {
        sc->character->collider_at(sc->character->user, f, out);
        return;
    }
    if (sc->scenario == WEFT_SIM_SCENARIO_GARMENT) {
        weft_pose pose;
        garment_pose_at(sc, f, &pose);
        weft_body_pose(sc->body, &pose, out, NULL);
        return;
    }
    if (out != sc->collider.pos) {
        memcpy(out, sc->collider.pos, sizeof(float) * 3 * sc->moving_begin);
    }
    if (sc->scenario != WEFT_SIM_SCENARIO_GRIPPER) {
        return;
    }
    double c[3], gap;
    gripper_at(sc, f, c, &gap);
    for (uint32_t k = 0; k < 16; ++k) {
        double side = k < 8 ? -1.0 : 1.0;
        const float *p = sc->finger_rest + 3 * k;
        float *o = out + 3 * (size_t)(sc->moving_begin + k);
        o[0] = (float)(c[0] + p[0] + side * (0.5 * gap + sc->finger_half[0]));
        o[1] = (float)(c[1] + p[1] + sc->finger_half[1]);
        o[2] = (float)(c[2] + p[2]);
    }
}

weft_garment_def xscene_garment_def(const xscene *sc, uint32_t substeps, uint32_t fast_collider_factor)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_XPBD;
    gd.substeps = substeps;
    gd.substeps_max = fast_collider_factor > 1 ? substeps * fast_collider_factor : 0;
    gd.ccd.enabled = false;
    gd.rest_positions = sc->cloth.pos;
    gd.vertex_count = sc->cloth.nv;
    gd.triangles = sc->cloth.tris;
    gd.triangle_count = sc->cloth.nt;
    gd.initial_positions = sc->cloth_init;
    gd.collider_rest_positions = sc->collider.pos;
    gd.collider_vertex_count = sc->collider.nv;
    gd.collider_triangles = sc->collider.tris;
    gd.collider_triangle_count = sc->collider.nt;
    gd.collision.triangle_parts = sc->parts;
    gd.collision.part_neighbours = false; /* a host's character: docs/REFSIM.md, Real motion */
    gd.collision.part_margin = 0.01f;
    if (sc->clip) {
        /* Motion capture (docs/REFSIM.md, Real motion): the body overlaps itself, so its contacts
         * are a projection each substep against the whole body, not bounds, and the floor and, for
         * a T-shirt, the worn-garment recipe's max distance, held inside the substeps, keep the
         * garment on its wearer. A skirt or dress hangs from its waistband (the pins) and has no
         * max distance: pulled toward a skinned hem the legs fold through itself as they close,
         * its cloth went through its other layer. Cloth-cloth contacts keep their bounds; no push
         * after the step (it would move cloth past them). */
        gd.collider_projection = true;
        gd.collision.triangle_parts = NULL;
        gd.tethers.distance = weft_wear_reference_tether_cm(sc->cloth_kind) / 100.0f;
        gd.collision.ground = true;
    }
    return gd;
}

uint32_t xscene_pins_at(const xscene *sc, uint32_t f, const float *collider, uint32_t *idx, float *targets)
{
    if (sc->scenario == WEFT_SIM_SCENARIO_GARMENT) {
        for (uint32_t k = 0; k < sc->band_count; ++k) {
            double q[3], e[3], t[3], n[3];
            band_point(sc, collider, k, q, e, t, n);
            const float *o = sc->band_off + 3 * (size_t)k;
            idx[k] = sc->band_idx[k];
            for (int a = 0; a < 3; ++a) {
                targets[3 * (size_t)k + a] = (float)(q[a] + o[0] * e[a] + o[1] * t[a] + o[2] * n[a]);
            }
        }
        return sc->band_count;
    }
    if (sc->scenario != WEFT_SIM_SCENARIO_GRIPPER || f <= sc->f_close || f > sc->f_release) {
        return 0;
    }
    double c[3], gap;
    gripper_at(sc, f, c, &gap);
    for (uint32_t k = 0; k < sc->grasp_count; ++k) {
        idx[k] = sc->grasped[k];
        for (int a = 0; a < 3; ++a) {
            targets[3 * k + a] = (float)(c[a] + sc->grasp_offset[3 * k + a]);
        }
    }
    return sc->grasp_count;
}

weft_result xscene_build(weft_context *ctx, xscene *sc, const weft_sim_sequence_def *def, uint64_t seed,
                         const xscene_gentle *gentle)
{
    *sc = (xscene){0};
    sc->scenario = def->scenario;
    xrng r = {seed ^ 0x5EED0F5CE0E5ull};
    weft_result res;
    switch (def->scenario) {
    case WEFT_SIM_SCENARIO_DROP:
        res = build_drop(sc, def, &r);
        break;
    case WEFT_SIM_SCENARIO_GRIPPER:
        res = build_gripper(sc, def, &r);
        break;
    case WEFT_SIM_SCENARIO_GARMENT:
        res = build_garment(ctx, sc, def, &r, gentle);
        break;
    default:
        res = weft__fail(WEFT_ERROR_UNSUPPORTED, "simgen: scenario '%s' is not available in this build",
                         weft_sim_scenario_name(def->scenario));
        break;
    }
    if (res != WEFT_OK) {
        xscene_free(sc);
    }
    return res;
}
