/* The cape of the avatar sample: a grid cloth stepped by the learned optimizer FNOpt
 * (weft/fnopt.h), or by fast XPBD for comparison, whose whole top row is pinned along a curve
 * behind the shoulders and the neck.
 * The pins are points bound to the body in its bind pose with the skinning weights of the
 * nearest skin vertex, so every frame their targets are the body's own skinning of them.
 *
 * FNOpt has no body collision in its energy (its only contact term is the cloth's
 * self-repulsion). The cape gets it from weft's constraint stage: after each FNOpt step its
 * positions go through an external garment (WEFT_METHOD_EXTERNAL, weft_garment_constrain) whose
 * collision pushes cloth inside the body (up to 5 cm deep) or nearer than 1 cm to 1 cm in front
 * of it, and its attachments keep every vertex within 1.1 times its rest distance down the cape
 * from its pin; where that moved the cloth, the corrected positions (and the velocities by the
 * same correction) go back into the optimizer. The XPBD cape is a weft_garment over the same grid
 * with the same pins, collider, collision distances and attachments. */
#include "weft_sample.h"

#if WEFT_RENDER_HAVE_SAMPLE

#include "weft/fnopt.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CAPE_CURVE_SAMPLES 256u
#define CAPE_OFFSET_M 0.035f    /* pins this far outside the skin (bind pose) */
#define CAPE_PUSH_M 0.01f      /* body collision: cloth kept this far in front of the skin */
#define CAPE_PUSH_DEPTH_M 0.05f /* and pushed out from up to this deep inside it */
#define CAPE_SLACK 0.1f        /* attachments: no vertex farther from its pin than 1.1 x its rest path */
#define CAPE_TILT_RAD 0.03f     /* initial lean of the hanging cloth away from the back: small, a large one swings the cape into the body */

struct weft_sample_cape {
    weft_context *ctx;
    weft_model *model;
    weft_fnopt *fnopt;
    uint32_t across, down, n;   /* grid: `across` columns of the top row, `down` rows */
    float lc;                   /* grid units per metre */
    float *pin_rest, *pin_weights, *pin_world, *pin_grid; /* across * 3 / * 24 / * 3 / * 3 */
    uint32_t *pin_index;        /* across */
    float *world;               /* n * 3 positions in metres */
    uint32_t *tris;
    uint32_t tri_count;
    uint32_t failed_steps;
    weft_garment *collide;      /* FNOpt: the body collision stage (external garment) */
    weft_garment *xpbd;         /* XPBD: the whole cape */
    float *grid_fix, *vel_fix;  /* n * 3: corrected grid positions and velocities */
    uint32_t pushed;            /* cape vertices the last step's collision moved */
};

void weft_sample_cape_destroy(weft_sample_cape *c)
{
    if (!c) {
        return;
    }
    weft_garment_destroy(c->collide);
    weft_garment_destroy(c->xpbd);
    free(c->grid_fix);
    free(c->vel_fix);
    weft_fnopt_destroy(c->fnopt);
    weft_model_destroy(c->model);
    free(c->pin_rest);
    free(c->pin_weights);
    free(c->pin_world);
    free(c->pin_grid);
    free(c->pin_index);
    free(c->world);
    free(c->tris);
    free(c);
}

static void bezier(const float a[3], const float m[3], const float b[3], float t, float out[3])
{
    for (int k = 0; k < 3; ++k) {
        out[k] = (1 - t) * (1 - t) * a[k] + 2 * t * (1 - t) * m[k] + t * t * b[k];
    }
}

/* Moves p along -z (behind the avatar, which faces +z) until it is `offset` outside the skin. */
static void push_behind(const weft_body *body, float p[3], float offset)
{
    for (int it = 0; it < 200; ++it) {
        float d = 0.0f;
        if (weft_avatar_distance(body, p, 1, &d) != WEFT_OK || d >= offset) {
            return;
        }
        p[2] -= fmaxf(offset - d, 0.002f);
    }
}

/* The pin curve in the bind pose: from above-behind the right shoulder, around the back of the
 * neck, to the left shoulder, pushed outside the skin, then resampled to `count` points at equal
 * arc length. Returns the curve length in metres. */
static float pin_curve(const weft_body *body, const float *joints, uint32_t count, float *out)
{
    const float *jl = joints + 3 * WEFT_JOINT_LEFT_SHOULDER, *jr = joints + 3 * WEFT_JOINT_RIGHT_SHOULDER;
    const float *jn = joints + 3 * WEFT_JOINT_NECK;
    const float a[3] = {jr[0], jr[1] + 0.05f, jr[2] - 0.02f}, b[3] = {jl[0], jl[1] + 0.05f, jl[2] - 0.02f};
    /* the control point makes the curve pass about 6 cm behind the neck joint at its middle */
    float m[3];
    for (int k = 0; k < 3; ++k) {
        m[k] = 2.0f * jn[k] - 0.5f * (a[k] + b[k]);
    }
    m[1] = jn[1] - 0.02f;
    m[2] = 2.0f * (jn[2] - 0.06f) - 0.5f * (a[2] + b[2]);
    /* Without body collision the cloth hangs straight down from the pins, so they go behind the
     * furthest-back skin below them (shoulder blades, buttocks) within the cape's width. */
    const float *rv = weft_body_rest_vertices(body);
    const uint32_t nv = weft_body_vertex_count(body);
    const float half = 0.5f * fabsf(jl[0] - jr[0]) + 0.05f, xc = 0.5f * (jl[0] + jr[0]);
    const float y_top = fminf(a[1], b[1]), y_low = joints[3 * WEFT_JOINT_PELVIS + 1] - 0.25f;
    float back = INFINITY;
    for (uint32_t v = 0; v < nv; ++v) {
        const float *p = rv + 3 * v;
        if (fabsf(p[0] - xc) < half && p[1] < y_top && p[1] > y_low) {
            back = fminf(back, p[2]);
        }
    }
    float curve[CAPE_CURVE_SAMPLES][3];
    float arc[CAPE_CURVE_SAMPLES];
    for (uint32_t s = 0; s < CAPE_CURVE_SAMPLES; ++s) {
        bezier(a, m, b, (float)s / (float)(CAPE_CURVE_SAMPLES - 1), curve[s]);
        push_behind(body, curve[s], CAPE_OFFSET_M);
        if (isfinite(back)) {
            curve[s][2] = fminf(curve[s][2], back - CAPE_OFFSET_M);
        }
        arc[s] = s ? arc[s - 1] + sqrtf((curve[s][0] - curve[s - 1][0]) * (curve[s][0] - curve[s - 1][0]) +
                                        (curve[s][1] - curve[s - 1][1]) * (curve[s][1] - curve[s - 1][1]) +
                                        (curve[s][2] - curve[s - 1][2]) * (curve[s][2] - curve[s - 1][2]))
                   : 0.0f;
    }
    const float total = arc[CAPE_CURVE_SAMPLES - 1];
    uint32_t s = 0;
    for (uint32_t i = 0; i < count; ++i) {
        float target = total * (float)i / (float)(count - 1);
        while (s + 2 < CAPE_CURVE_SAMPLES && arc[s + 1] < target) {
            ++s;
        }
        float span = arc[s + 1] - arc[s], u = span > 0.0f ? (target - arc[s]) / span : 0.0f;
        u = u < 0.0f ? 0.0f : (u > 1.0f ? 1.0f : u);
        for (int k = 0; k < 3; ++k) {
            out[3 * i + k] = curve[s][k] + u * (curve[s + 1][k] - curve[s][k]);
        }
    }
    return total;
}

/* The FNOpt cape's optimizer (from the grid laid out in grid0) and its collision stage (gd). */
static weft_result fnopt_setup(weft_sample_cape *c, const weft_sample_cape_def *def, const float *grid0,
                               const weft_garment_def *gd)
{
    weft_result r = weft_model_load_file_as(c->ctx, def->model_path, "fnopt", &c->model);
    if (r != WEFT_OK) {
        return r;
    }
    weft_fnopt_def fd = weft_default_fnopt_def();
    fd.height = c->across;
    fd.width = c->down;
    fd.initial_positions = grid0;
    fd.model = c->model;
    fd.precision = def->precision;
    /* the material fitted to the XPBD reference (docs/FNOPT.md), inside the training ranges */
    fd.stretch = 100.0f;
    fd.shear = 3.0f;
    fd.bend = 5.0f;
    fd.gravity[0] = fd.gravity[2] = 0.0f;
    fd.gravity[1] = -9.81f * c->lc / (60.0f * 60.0f); /* Y up, one step per 60 Hz frame */
    if ((r = weft_fnopt_create(c->ctx, &fd, &c->fnopt)) != WEFT_OK) {
        return r;
    }
    c->grid_fix = malloc((size_t)c->n * 3 * sizeof(float));
    c->vel_fix = malloc((size_t)c->n * 3 * sizeof(float));
    if (!c->grid_fix || !c->vel_fix) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    return weft_garment_create(c->ctx, gd, &c->collide);
}

weft_sample_cape_def weft_sample_default_cape_def(void)
{
    return (weft_sample_cape_def){.model_path = "tools/fnopt/models/fnopt_32.safetensors",
                                  .precision = WEFT_PRECISION_FP32, .across = 32, .down = 40, .xpbd_substeps = 0};
}

weft_result weft_sample_cape_create(weft_context *ctx, const weft_body *body, const weft_sample_cape_def *def,
                                    weft_sample_cape **out)
{
    if (!ctx || !body || !def || !out || (!def->model_path && def->xpbd_substeps == 0) || def->across < 10 ||
        def->down < 10 || def->across > 256 || def->down > 256 || def->xpbd_substeps > 200) {
        return WEFT_ERROR_INVALID_ARGUMENT;
    }
    const uint32_t across = def->across, down = def->down;
    *out = NULL;
    weft_sample_cape *c = calloc(1, sizeof *c);
    if (!c) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    c->ctx = ctx;
    c->across = across;
    c->down = down;
    c->n = across * down;
    c->tri_count = 2 * (across - 1) * (down - 1);
    c->pin_rest = malloc((size_t)across * 3 * sizeof(float));
    c->pin_weights = calloc((size_t)across * WEFT_BODY_JOINTS, sizeof(float));
    c->pin_world = malloc((size_t)across * 3 * sizeof(float));
    c->pin_grid = malloc((size_t)across * 3 * sizeof(float));
    c->pin_index = malloc((size_t)across * sizeof(uint32_t));
    c->world = malloc((size_t)c->n * 3 * sizeof(float));
    c->tris = malloc((size_t)c->tri_count * 3 * sizeof(uint32_t));
    float *grid0 = malloc((size_t)c->n * 3 * sizeof(float));
    float joints[24 * 16];
    weft_pose bind;
    weft_body_bind_pose(body, &bind);
    weft_result r = WEFT_ERROR_OUT_OF_MEMORY;
    if (!c->pin_rest || !c->pin_weights || !c->pin_world || !c->pin_grid || !c->pin_index || !c->world || !c->tris ||
        !grid0) {
        goto fail;
    }
    if ((r = weft_body_pose(body, &bind, NULL, joints)) != WEFT_OK) {
        goto fail;
    }
    /* joint positions are the translations of the column-major transforms */
    float jpos[24 * 3];
    for (int j = 0; j < 24; ++j) {
        for (int k = 0; k < 3; ++k) {
            jpos[3 * j + k] = joints[16 * j + 12 + k];
        }
    }
    const float length = pin_curve(body, jpos, across, c->pin_rest);
    if (!(length > 0.05f)) {
        r = WEFT_ERROR_DEGENERATE_MESH;
        goto fail;
    }
    /* one grid unit = one rest edge = the pin spacing */
    c->lc = (float)(across - 1) / length;
    /* pin weights: those of the nearest skin vertex in the bind pose */
    const float *rv = weft_body_rest_vertices(body), *rw = weft_body_weights(body);
    const uint32_t nv = weft_body_vertex_count(body);
    for (uint32_t i = 0; i < across; ++i) {
        const float *p = c->pin_rest + 3 * i;
        uint32_t best = 0;
        float bd = INFINITY;
        for (uint32_t v = 0; v < nv; ++v) {
            float dx = rv[3 * v] - p[0], dy = rv[3 * v + 1] - p[1], dz = rv[3 * v + 2] - p[2];
            float d = dx * dx + dy * dy + dz * dz;
            if (d < bd) {
                bd = d, best = v;
            }
        }
        memcpy(c->pin_weights + (size_t)i * WEFT_BODY_JOINTS, rw + (size_t)best * WEFT_BODY_JOINTS,
               WEFT_BODY_JOINTS * sizeof(float));
    }
    /* FNOpt vertex (i, j) has index i * W + j with W = `down`: row j = 0 is the pinned top */
    for (uint32_t i = 0; i < across; ++i) {
        c->pin_index[i] = i * down;
        for (uint32_t j = 0; j < down; ++j) {
            float *g = grid0 + 3 * ((size_t)i * down + j);
            g[0] = c->pin_rest[3 * i] * c->lc;
            g[1] = c->pin_rest[3 * i + 1] * c->lc - (float)j * cosf(CAPE_TILT_RAD);
            g[2] = c->pin_rest[3 * i + 2] * c->lc - (float)j * sinf(CAPE_TILT_RAD);
        }
    }
    for (uint32_t i = 0, t = 0; i + 1 < across; ++i) {
        for (uint32_t j = 0; j + 1 < down; ++j) {
            uint32_t v00 = i * down + j, v10 = (i + 1) * down + j;
            c->tris[t++] = v00, c->tris[t++] = v00 + 1, c->tris[t++] = v10;
            c->tris[t++] = v10, c->tris[t++] = v00 + 1, c->tris[t++] = v10 + 1;
        }
    }
    for (size_t q = 0; q < (size_t)c->n * 3; ++q) {
        c->world[q] = grid0[q] / c->lc;
    }
    /* the body collision: the cape as laid out in the bind pose against the body in it */
    weft_garment_def gd = weft_sample_body_garment_def(body, def->xpbd_substeps ? WEFT_METHOD_XPBD_FAST
                                                                                : WEFT_METHOD_EXTERNAL,
                                                       c->world, c->n, c->tris, c->tri_count);
    gd.collision.push = CAPE_PUSH_M;
    gd.collision.push_depth = CAPE_PUSH_DEPTH_M;
    gd.ccd.enabled = false;
    gd.attachments.enabled = true;
    gd.attachments.slack = CAPE_SLACK;
    if (def->xpbd_substeps) {
        weft_sample_set_substeps(&gd, def->xpbd_substeps);
        r = weft_garment_create(ctx, &gd, &c->xpbd);
    } else {
        r = fnopt_setup(c, def, grid0, &gd);
    }
    if (r != WEFT_OK) {
        goto fail;
    }
    free(grid0);
    *out = c;
    return WEFT_OK;
fail:
    free(grid0);
    weft_sample_cape_destroy(c);
    return r;
}

weft_result weft_sample_cape_step(weft_sample_cape *c, const weft_body *body, const weft_pose *pose,
                                  const float *body_vertices)
{
    weft_result r = weft_body_skin_points(body, pose, c->pin_rest, c->pin_weights, c->across, c->pin_world);
    if (r != WEFT_OK) {
        return r;
    }
    if (c->xpbd) {
        if (!body_vertices) {
            return WEFT_ERROR_INVALID_ARGUMENT; /* the solver collides as it steps */
        }
        if ((r = weft_garment_set_collider(c->xpbd, body_vertices)) != WEFT_OK ||
            (r = weft_garment_set_pins(c->xpbd, c->pin_index, c->pin_world, c->across)) != WEFT_OK ||
            (r = weft_garment_step(c->xpbd)) != WEFT_OK) {
            c->failed_steps += r == WEFT_ERROR_NOT_FINITE;
            return r;
        }
        memcpy(c->world, weft_garment_positions(c->xpbd), (size_t)c->n * 3 * sizeof(float));
        c->pushed = weft_garment_stats(c->xpbd).pushed_vertices;
        return WEFT_OK;
    }
    for (uint32_t q = 0; q < 3 * c->across; ++q) {
        c->pin_grid[q] = c->pin_world[q] * c->lc;
    }
    if ((r = weft_fnopt_set_handles(c->fnopt, c->pin_index, c->pin_grid, c->across)) != WEFT_OK) {
        return r;
    }
    r = weft_fnopt_step(c->fnopt);
    if (r != WEFT_OK) {
        /* the object kept its previous state; the cape holds still for this frame */
        c->failed_steps++;
        return r;
    }
    const float *g = weft_fnopt_positions(c->fnopt);
    for (size_t q = 0; q < (size_t)c->n * 3; ++q) {
        c->world[q] = g[q] / c->lc;
    }
    c->pushed = 0;
    if (!body_vertices) {
        return WEFT_OK;
    }
    if ((r = weft_garment_set_collider(c->collide, body_vertices)) != WEFT_OK ||
        (r = weft_garment_set_pins(c->collide, c->pin_index, c->pin_world, c->across)) != WEFT_OK ||
        (r = weft_garment_constrain(c->collide, c->world)) != WEFT_OK) {
        return r;
    }
    const weft_step_stats st = weft_garment_stats(c->collide);
    const float *x = weft_garment_positions(c->collide);
    if (st.pushed_vertices == 0 && st.attachment_vertices_clamped == 0 && !st.collider_cut) {
        return WEFT_OK;
    }
    /* the correction goes back into the optimizer, positions and velocities alike */
    c->pushed = st.pushed_vertices;
    const float *v = weft_fnopt_velocities(c->fnopt);
    for (size_t q = 0; q < (size_t)c->n * 3; ++q) {
        c->grid_fix[q] = x[q] * c->lc;
        c->vel_fix[q] = st.collider_cut ? 0.0f : v[q] + (x[q] - c->world[q]) * c->lc;
    }
    if ((r = weft_fnopt_set_state(c->fnopt, c->grid_fix, c->vel_fix)) != WEFT_OK) {
        return r;
    }
    memcpy(c->world, x, (size_t)c->n * 3 * sizeof(float));
    return WEFT_OK;
}

uint32_t weft_sample_cape_pushed(const weft_sample_cape *c) { return c->pushed; }

const float *weft_sample_cape_positions(const weft_sample_cape *c) { return c->world; }
uint32_t weft_sample_cape_vertex_count(const weft_sample_cape *c) { return c->n; }
const uint32_t *weft_sample_cape_triangles(const weft_sample_cape *c, uint32_t *count)
{
    *count = c->tri_count;
    return c->tris;
}
float weft_sample_cape_units_per_metre(const weft_sample_cape *c) { return c->lc; }
uint32_t weft_sample_cape_failed_steps(const weft_sample_cape *c) { return c->failed_steps; }

#endif
