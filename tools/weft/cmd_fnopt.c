/* weft fnopt: FNOpt grid cloth scenes against the XPBD reference (docs/FNOPT.md).
 *
 *   weft fnopt run [options]    one scene: ms/frame, and e3D / Chamfer against XPBD with --gt
 *   weft fnopt fit [options]    coordinate search of the material (Y, S, B) against XPBD
 *
 * World frame: metres, Y up, the cloth hanging in the x-y plane centred on the origin, row
 * j = 0 on top. FNOpt's grid frame is z up: grid = Lc (x, -z, y) with Lc = (res-1)/size. One
 * FNOpt step per frame; gravity is 9.81 m/s^2 converted with the frame rate. */
#define _POSIX_C_SOURCE 200809L /* mkdir */
#include "../fnopt/fnopt_scene.h"
#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

const char weft_cmd_fnopt_help[] = "FNOpt grid cloth: run a handle scene, score it against XPBD, fit the material";

#define PI 3.14159265358979323846

/* ---- scenes ------------------------------------------------------------------------------ */

typedef struct motion_def {
    const char *name;
    float dir[3];       /* world (Y up) translation direction; 0 for rotations */
    int pivot;          /* rotations: handle the pair turns about (-1 for translations) */
} motion_def;

/* The direction vectors of the MGNRP motion generator (y up). */
static const motion_def g_motions[] = {
    {"xy", {1, 0, -1}, -1},  {"yz", {0, 1, -1}, -1},  {"xz", {1, -1, 0}, -1},   {"xyz", {1, 1, -1}, -1},
    {"xyz3", {1, -1, 1}, -1}, {"xyz4", {-1, 1, 1}, -1}, {"rot_h0", {0, 0, 0}, 0}, {"rot_h1", {0, 0, 0}, 1},
};

static bool handle_set(const char *name, uint32_t res, uint32_t *idx, uint32_t *count)
{
    const uint32_t W = res, last = res - 1, mid = (res - 1) / 2;
    /* vertex (i, j) = i*W + j; j = 0 is the top edge, i runs across */
    struct {
        const char *name;
        uint32_t a, b, count;
    } sets[] = {
        {"corners", 0, last * W, 2},
        {"diagonal", 0, last * W + last, 2},
        {"middle", mid, last * W + mid, 2},
        {"corner-middle", 0, last * W + mid, 2},
        {"corner-center", 0, mid * W + mid, 2},
        {"single-corner", 0, 0, 1},
        {"single-middle", mid * W, 0, 1},
        {"single-center", mid * W + mid, 0, 1},
    };
    for (size_t k = 0; k < sizeof sets / sizeof sets[0]; ++k) {
        if (strcmp(name, sets[k].name) == 0) {
            idx[0] = sets[k].a;
            idx[1] = sets[k].b;
            *count = sets[k].count;
            return true;
        }
    }
    return false;
}

/* Cosine-eased progress in [0, 1] over [0, 1]: zero velocity at both ends. */
static double ease(double t) { return t <= 0 ? 0 : (t >= 1 ? 1 : 0.5 * (1.0 - cos(PI * t))); }

weft_result fnopt_scene_make(const fnopt_scene_opts *o, fnopt_scene *s)
{
    memset(s, 0, sizeof *s);
    s->o = *o;
    if (o->res < 10 || o->res > 1024 || !(o->size_m > 0) || !(o->fps > 0) || !(o->speed > 0)) {
        fprintf(stderr, "weft fnopt: bad scene options (res >= 10, size, fps, speed > 0)\n");
        return WEFT_ERROR_INVALID_ARGUMENT;
    }
    char base[32];
    snprintf(base, sizeof base, "%s", o->motion);
    bool opp = false;
    size_t bl = strlen(base);
    if (bl > 4 && strcmp(base + bl - 4, "_opp") == 0) {
        base[bl - 4] = 0;
        opp = true;
    }
    const motion_def *m = NULL;
    for (size_t k = 0; k < sizeof g_motions / sizeof g_motions[0]; ++k) {
        if (strcmp(base, g_motions[k].name) == 0) {
            m = &g_motions[k];
        }
    }
    if (!m || !handle_set(o->handles, o->res, s->handles, &s->handle_count)) {
        fprintf(stderr, "weft fnopt: unknown motion '%s' or handles '%s'\n", o->motion, o->handles);
        return WEFT_ERROR_INVALID_ARGUMENT;
    }
    /* timeline: 0.25 s rest, move out (1 s / speed), move back (1 s / speed), 0.5 s rest */
    const double t_rest = 0.25, t_move = 1.0 / o->speed, t_end = 0.5;
    uint32_t full = (uint32_t)ceil((t_rest + 2 * t_move + t_end) * o->fps);
    s->frames = o->frames ? o->frames : full;
    const uint32_t R = o->res;
    s->n = R * R;
    s->rest = malloc(3 * (size_t)s->n * sizeof(float));
    s->traj = malloc(3 * (size_t)(s->frames + 1) * s->handle_count * sizeof(float));
    s->tri_count = 2 * (R - 1) * (R - 1);
    s->tris = malloc(3 * (size_t)s->tri_count * sizeof(uint32_t));
    if (!s->rest || !s->traj || !s->tris) {
        fnopt_scene_free(s);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    const double dx = o->size_m / (R - 1);
    for (uint32_t i = 0; i < R; ++i) {
        for (uint32_t j = 0; j < R; ++j) {
            float *p = s->rest + 3 * ((size_t)i * R + j);
            p[0] = (float)(((double)i - 0.5 * (R - 1)) * dx);
            p[1] = (float)(0.5 * o->size_m - (double)j * dx);
            p[2] = 0.0f;
        }
    }
    uint32_t t = 0;
    for (uint32_t i = 0; i + 1 < R; ++i) {
        for (uint32_t j = 0; j + 1 < R; ++j) {
            uint32_t a = i * R + j, b = (i + 1) * R + j, c = (i + 1) * R + j + 1, d = i * R + j + 1;
            /* counter-clockwise seen from +z */
            s->tris[3 * t] = a, s->tris[3 * t + 1] = d, s->tris[3 * t + 2] = c, t++;
            s->tris[3 * t] = a, s->tris[3 * t + 1] = c, s->tris[3 * t + 2] = b, t++;
        }
    }
    double dir[3] = {m->dir[0], m->dir[1], m->dir[2]};
    double dl = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    const double sign = opp ? -1.0 : 1.0;
    const double angle = sign * PI / 3.0;
    const float *piv = s->rest + 3 * (size_t)s->handles[m->pivot >= 0 && (uint32_t)m->pivot < s->handle_count ? m->pivot : 0];
    for (uint32_t f = 0; f <= s->frames; ++f) {
        double tt = f / (double)o->fps;
        double prog = ease((tt - t_rest) / t_move) - ease((tt - t_rest - t_move) / t_move);
        for (uint32_t k = 0; k < s->handle_count; ++k) {
            const float *p0 = s->rest + 3 * (size_t)s->handles[k];
            float *q = s->traj + 3 * ((size_t)f * s->handle_count + k);
            if (m->pivot < 0) {
                for (int c = 0; c < 3; ++c) {
                    q[c] = (float)(p0[c] + sign * o->amplitude_m * prog * dir[c] / dl);
                }
            } else {
                /* turn about the vertical axis through the pivot handle */
                double a = angle * prog, rx = p0[0] - piv[0], rz = p0[2] - piv[2];
                q[0] = (float)(piv[0] + cos(a) * rx + sin(a) * rz);
                q[1] = p0[1];
                q[2] = (float)(piv[2] - sin(a) * rx + cos(a) * rz);
            }
        }
    }
    return WEFT_OK;
}

void fnopt_scene_free(fnopt_scene *s)
{
    free(s->rest);
    free(s->traj);
    free(s->tris);
    memset(s, 0, sizeof *s);
}

/* ---- XPBD ground truth ------------------------------------------------------------------- */

static void gt_path(const fnopt_scene *s, char *buf, size_t size)
{
    char sz[32] = ""; /* the 1 m cloth keeps the names of the caches made before --size */
    if (s->o.size_m != 1.0f) {
        snprintf(sz, sizeof sz, "_m%.3f", (double)s->o.size_m);
    }
    snprintf(buf, size, "data/fnopt/gt/r%u_%s_%s_s%.2f_a%.2f_f%u_fps%.0f%s.f32", s->o.res, s->o.motion, s->o.handles,
             (double)s->o.speed, (double)s->o.amplitude_m, s->frames, (double)s->o.fps, sz);
}

weft_result fnopt_scene_ground_truth(weft_context *ctx, const fnopt_scene *s, float **out)
{
    const size_t count = (size_t)s->frames * s->n * 3;
    float *gt = malloc(count * sizeof(float));
    if (!gt) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    char path[256];
    gt_path(s, path, sizeof path);
    FILE *fh = fopen(path, "rb");
    if (fh) {
        size_t got = fread(gt, sizeof(float), count, fh);
        fclose(fh);
        if (got == count) {
            *out = gt;
            return WEFT_OK;
        }
    }
    weft_garment_def def = weft_default_garment_def();
    def.method = WEFT_METHOD_XPBD;
    def.rest_positions = s->rest;
    def.vertex_count = s->n;
    def.triangles = s->tris;
    def.triangle_count = s->tri_count;
    def.ccd.enabled = false;
    weft_garment *g = NULL;
    weft_result r = weft_garment_create(ctx, &def, &g);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft fnopt: XPBD garment: %s\n", weft_last_error());
        free(gt);
        return r;
    }
    if (s->o.fps != 60.0f) {
        fprintf(stderr, "weft fnopt: note: the XPBD reference steps 1/60 s frames; fps %.1f is ignored by it\n",
                (double)s->o.fps);
    }
    for (uint32_t f = 0; f < s->frames && r == WEFT_OK; ++f) {
        r = weft_garment_set_pins(g, s->handles, s->traj + 3 * (size_t)(f + 1) * s->handle_count, s->handle_count);
        if (r == WEFT_OK) {
            r = weft_garment_step(g);
        }
        if (r == WEFT_OK) {
            memcpy(gt + (size_t)f * s->n * 3, weft_garment_positions(g), 3 * (size_t)s->n * sizeof(float));
        }
    }
    weft_garment_destroy(g);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft fnopt: XPBD step: %s\n", weft_last_error());
        free(gt);
        return r;
    }
    mkdir("data", 0777);
    mkdir("data/fnopt", 0777);
    mkdir("data/fnopt/gt", 0777);
    fh = fopen(path, "wb");
    if (fh) {
        fwrite(gt, sizeof(float), count, fh);
        fclose(fh);
    }
    *out = gt;
    return WEFT_OK;
}

/* ---- metrics ----------------------------------------------------------------------------- */

#define CHAMFER_SAMPLES 10000

typedef struct pointgrid {
    float lo[3], cell;
    int dim[3];
    uint32_t *start, *items;   /* CSR over cells */
} pointgrid;

static uint64_t rng_next(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}
static double rng_unit(uint64_t *s) { return (double)(rng_next(s) >> 11) * (1.0 / 9007199254740992.0); }

/* Area-weighted uniform samples on a triangle mesh (a fixed seed per mesh role). */
static void sample_mesh(const float *p, const uint32_t *tris, uint32_t tc, double *cdf, uint64_t seed, float *out)
{
    double tot = 0.0;
    for (uint32_t t = 0; t < tc; ++t) {
        const float *a = p + 3 * tris[3 * t], *b = p + 3 * tris[3 * t + 1], *c = p + 3 * tris[3 * t + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2], z = u[0] * v[1] - u[1] * v[0];
        tot += 0.5 * sqrt(x * x + y * y + z * z);
        cdf[t] = tot;
    }
    uint64_t s = seed;
    for (int k = 0; k < CHAMFER_SAMPLES; ++k) {
        double r = rng_unit(&s) * tot;
        uint32_t lo = 0, hi = tc - 1;
        while (lo < hi) {
            uint32_t mid = (lo + hi) / 2;
            if (cdf[mid] < r) {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        double r1 = sqrt(rng_unit(&s)), r2 = rng_unit(&s);
        double wa = 1 - r1, wb = r1 * (1 - r2), wc = r1 * r2;
        const float *a = p + 3 * tris[3 * lo], *b = p + 3 * tris[3 * lo + 1], *c = p + 3 * tris[3 * lo + 2];
        for (int d = 0; d < 3; ++d) {
            out[3 * k + d] = (float)(wa * a[d] + wb * b[d] + wc * c[d]);
        }
    }
}

static bool grid_build(pointgrid *g, const float *pts, int n)
{
    float hi[3];
    for (int d = 0; d < 3; ++d) {
        g->lo[d] = hi[d] = pts[d];
    }
    for (int k = 1; k < n; ++k) {
        for (int d = 0; d < 3; ++d) {
            g->lo[d] = fminf(g->lo[d], pts[3 * k + d]);
            hi[d] = fmaxf(hi[d], pts[3 * k + d]);
        }
    }
    double ext = fmax(fmax(hi[0] - g->lo[0], hi[1] - g->lo[1]), hi[2] - g->lo[2]);
    g->cell = (float)fmax(ext / 32.0, 1e-6);
    size_t cells = 1;
    for (int d = 0; d < 3; ++d) {
        g->dim[d] = (int)((hi[d] - g->lo[d]) / g->cell) + 1;
        if (g->dim[d] > 64) {
            return false;
        }
        cells *= (size_t)g->dim[d];
    }
    g->start = calloc(cells + 1, sizeof(uint32_t));
    g->items = malloc((size_t)n * sizeof(uint32_t));
    if (!g->start || !g->items) {
        return false;
    }
    for (int k = 0; k < n; ++k) {
        int c[3];
        for (int d = 0; d < 3; ++d) {
            c[d] = (int)((pts[3 * k + d] - g->lo[d]) / g->cell);
            c[d] = c[d] < 0 ? 0 : (c[d] >= g->dim[d] ? g->dim[d] - 1 : c[d]);
        }
        g->start[((size_t)c[0] * g->dim[1] + c[1]) * g->dim[2] + c[2] + 1]++;
    }
    for (size_t c = 0; c < cells; ++c) {
        g->start[c + 1] += g->start[c];
    }
    uint32_t *fill = calloc(cells, sizeof(uint32_t));
    if (!fill) {
        return false;
    }
    for (int k = 0; k < n; ++k) {
        int c[3];
        for (int d = 0; d < 3; ++d) {
            c[d] = (int)((pts[3 * k + d] - g->lo[d]) / g->cell);
            c[d] = c[d] < 0 ? 0 : (c[d] >= g->dim[d] ? g->dim[d] - 1 : c[d]);
        }
        size_t cell = ((size_t)c[0] * g->dim[1] + c[1]) * g->dim[2] + c[2];
        g->items[g->start[cell] + fill[cell]++] = (uint32_t)k;
    }
    free(fill);
    return true;
}

/* Squared distance from q to the nearest grid point: search shells of cells until the shell
 * is farther than the best distance found. */
static double grid_nearest(const pointgrid *g, const float *pts, const float *q)
{
    int c[3];
    for (int d = 0; d < 3; ++d) {
        c[d] = (int)floorf((q[d] - g->lo[d]) / g->cell);
    }
    double best = INFINITY;
    int maxr = g->dim[0] + g->dim[1] + g->dim[2] + 2;
    for (int r = 0; r <= maxr; ++r) {
        double shell = (r - 1) * (double)g->cell;
        if (r > 0 && shell > 0 && shell * shell > best) {
            break;
        }
        for (int x = c[0] - r; x <= c[0] + r; ++x) {
            if (x < 0 || x >= g->dim[0]) continue;
            for (int y = c[1] - r; y <= c[1] + r; ++y) {
                if (y < 0 || y >= g->dim[1]) continue;
                for (int z = c[2] - r; z <= c[2] + r; ++z) {
                    if (z < 0 || z >= g->dim[2]) continue;
                    if (abs(x - c[0]) != r && abs(y - c[1]) != r && abs(z - c[2]) != r) continue;
                    size_t cell = ((size_t)x * g->dim[1] + y) * g->dim[2] + z;
                    for (uint32_t k = g->start[cell]; k < g->start[cell + 1]; ++k) {
                        const float *p = pts + 3 * g->items[k];
                        double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
                        double dd = dx * dx + dy * dy + dz * dz;
                        best = dd < best ? dd : best;
                    }
                }
            }
        }
    }
    if (best == INFINITY) {
        /* the query lies beyond the shells searched (a blown-up cloth): scan every point */
        for (uint32_t k = 0; k < g->start[(size_t)g->dim[0] * g->dim[1] * g->dim[2]]; ++k) {
            const float *p = pts + 3 * k;
            double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
            double dd = dx * dx + dy * dy + dz * dz;
            best = dd < best ? dd : best;
        }
    }
    return best;
}

/* Chamfer distance as pytorch3d's chamfer_distance with its defaults: mean squared nearest
 * distance from each sample set to the other, summed over both directions. */
static double chamfer(const float *a, const float *b, bool *ok)
{
    double sum = 0.0;
    for (int dir = 0; dir < 2 && *ok; ++dir) {
        const float *src = dir ? b : a, *dst = dir ? a : b;
        pointgrid g = {0};
        if (!grid_build(&g, dst, CHAMFER_SAMPLES)) {
            *ok = false;
        } else {
            double s = 0.0;
            for (int k = 0; k < CHAMFER_SAMPLES; ++k) {
                s += grid_nearest(&g, dst, src + 3 * k);
            }
            sum += s / CHAMFER_SAMPLES;
        }
        free(g.start);
        free(g.items);
    }
    return sum;
}

/* ---- running FNOpt on a scene ------------------------------------------------------------ */

static void world_to_grid(const float *w, float lc, float *g)
{
    g[0] = lc * w[0];
    g[1] = -lc * w[2];
    g[2] = lc * w[1];
}

static void grid_to_world(const float *g, float lc, float *w)
{
    w[0] = g[0] / lc;
    w[1] = g[2] / lc;
    w[2] = -g[1] / lc;
}

/* Largest relative length change of a horizontal or vertical grid edge (rest length 1 in grid
 * units): the strain bound of the stability tables. */
static double max_edge_strain(const float *x, uint32_t res)
{
    double worst = 0.0;
    for (uint32_t i = 0; i < res; ++i) {
        for (uint32_t j = 0; j < res; ++j) {
            const float *p = x + 3 * ((size_t)i * res + j);
            for (int e = 0; e < 2; ++e) {
                if ((e == 0 && i + 1 == res) || (e == 1 && j + 1 == res)) {
                    continue;
                }
                const float *q = e == 0 ? p + 3 * (size_t)res : p + 3;
                double dx = (double)q[0] - p[0], dy = (double)q[1] - p[1], dz = (double)q[2] - p[2];
                worst = fmax(worst, fabs(sqrt(dx * dx + dy * dy + dz * dz) - 1.0));
            }
        }
    }
    return worst;
}

weft_result fnopt_scene_run(weft_context *ctx, const fnopt_scene *s, const fnopt_run_opts *ro, const float *gt,
                            fnopt_run_result *res, float *positions_out)
{
    memset(res, 0, sizeof *res);
    const size_t n = s->n;
    const float lc = (float)(s->o.res - 1) / s->o.size_m;
    float *x0 = malloc(3 * n * sizeof(float)), *world = malloc(3 * n * sizeof(float));
    float *sa = malloc(3 * CHAMFER_SAMPLES * sizeof(float)), *sb = malloc(3 * CHAMFER_SAMPLES * sizeof(float));
    double *cdf = malloc(s->tri_count * sizeof(double));
    if (!x0 || !world || !sa || !sb || !cdf) {
        free(x0), free(world), free(sa), free(sb), free(cdf);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t v = 0; v < n; ++v) {
        world_to_grid(s->rest + 3 * v, lc, x0 + 3 * v);
    }
    weft_fnopt_def def = weft_default_fnopt_def();
    def.height = def.width = s->o.res;
    def.initial_positions = x0;
    def.optimizer = ro->optimizer;
    def.model = ro->model;
    def.iterations = ro->iterations;
    def.learning_rate = ro->learning_rate;
    def.stretch = ro->Y;
    def.shear = ro->S;
    def.bend = ro->B;
    def.repulsion = ro->repulsion;
    def.report_loss = ro->report_loss;
    def.precision = ro->precision;
    def.descent_guard = !ro->no_guard;
    def.max_step = ro->max_step;
    def.gravity[0] = def.gravity[1] = 0.0f;
    def.gravity[2] = -weft_fnopt_acceleration(9.81f, s->o.res, s->o.size_m, s->o.fps);
    weft_fnopt *f = NULL;
    weft_result r = weft_fnopt_create(ctx, &def, &f);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft fnopt: %s\n", weft_last_error());
        free(x0), free(world), free(sa), free(sb), free(cdf);
        return r;
    }
    float targets[6];
    double ms = 0.0, e3d = 0.0, cd = 0.0, loss = 0.0, guard_acted = 0.0;
    bool cd_ok = true;
    for (uint32_t fr = 0; fr < s->frames; ++fr) {
        for (uint32_t k = 0; k < s->handle_count; ++k) {
            world_to_grid(s->traj + 3 * ((size_t)(fr + 1) * s->handle_count + k), lc, targets + 3 * k);
        }
        weft_fnopt_set_handles(f, s->handles, targets, s->handle_count);
        if (weft_fnopt_step(f) != WEFT_OK) {
            res->diverged = true;
            break;
        }
        weft_fnopt_stats st = weft_fnopt_get_stats(f);
        ms += st.step_ms;
        loss += st.loss_final;
        guard_acted += st.committed_iterate < ro->iterations ? 1.0 : 0.0;
        const float *x = weft_fnopt_positions(f);
        res->max_strain = fmax(res->max_strain, max_edge_strain(x, s->o.res));
        bool out_of_box = false;
        for (size_t v = 0; v < n; ++v) {
            grid_to_world(x + 3 * v, lc, world + 3 * v);
            out_of_box |= fabsf(world[3 * v]) > 100.0f || fabsf(world[3 * v + 1]) > 100.0f || fabsf(world[3 * v + 2]) > 100.0f;
        }
        res->frames++;
        if (positions_out) {
            memcpy(positions_out + (size_t)fr * n * 3, world, 3 * n * sizeof(float));
        }
        if (gt) {
            const float *g = gt + (size_t)fr * n * 3;
            double num = 0.0, den = 0.0;
            for (size_t q = 0; q < 3 * n; ++q) {
                double d = (double)world[q] - g[q];
                num += d * d;
                den += (double)g[q] * g[q];
            }
            e3d += sqrt(num) / sqrt(den > 0 ? den : 1e-30);
            if (!out_of_box && cd_ok) {
                sample_mesh(world, s->tris, s->tri_count, cdf, 0x9e3779b97f4a7c15ull + fr, sa);
                sample_mesh(g, s->tris, s->tri_count, cdf, 0xd1b54a32d192ed03ull + fr, sb);
                cd += chamfer(sa, sb, &cd_ok);
            }
        }
        if (out_of_box) {
            res->diverged = true;
            break;
        }
    }
    uint32_t nf = res->frames ? res->frames : 1;
    res->ms_per_frame = ms / nf;
    res->loss = loss / nf;
    res->guard_acted = guard_acted / nf;
    res->e3d = gt ? e3d / nf : NAN;
    res->chamfer = gt && cd_ok && !res->diverged ? cd / nf : NAN;
    weft_fnopt_destroy(f);
    free(x0), free(world), free(sa), free(sb), free(cdf);
    return WEFT_OK;
}

/* ---- command line ------------------------------------------------------------------------ */

typedef struct cli {
    fnopt_scene_opts scene;
    fnopt_run_opts run;
    const char *model_path, *csv, *out;
    bool gt;
} cli;

static const char *const k_precision_names[WEFT_PRECISION_COUNT] = {"fp32", "fp16", "int8"};

bool fnopt_parse_precision(const char *s, weft_precision *out)
{
    for (int p = 0; p < WEFT_PRECISION_COUNT; ++p) {
        if (strcmp(s, k_precision_names[p]) == 0) {
            *out = (weft_precision)p;
            return true;
        }
    }
    return false;
}

static const char *optimizer_name(weft_fnopt_optimizer o)
{
    static const char *names[] = {"learned", "gd", "adam", "lbfgs"};
    return (unsigned)o < 4 ? names[o] : "?";
}

static const char k_tool[] = "weft fnopt";

enum {
    OPT_RES = 1, OPT_MOTION, OPT_HANDLES, OPT_FRAMES, OPT_SPEED, OPT_AMPLITUDE, OPT_SIZE, OPT_OPTIMIZER, OPT_ITERS, OPT_LR,
    OPT_MODEL, OPT_MATERIAL, OPT_REPULSION, OPT_PRECISION, OPT_NO_GUARD, OPT_MAX_STEP, OPT_GT, OPT_LOSS, OPT_CSV, OPT_OUT,
};

static const cli_option k_options[] = {
    {"res", "N", OPT_RES, "grid resolution, 10..1024 (32)"},
    {"motion", "M", OPT_MOTION, "xy yz xz xyz xyz3 xyz4 rot_h0 rot_h1, optionally with _opp (xy)"},
    {"handles", "H", OPT_HANDLES,
     "corners diagonal middle corner-middle corner-center single-corner\n"
     "single-middle single-center (corners)"},
    {"frames", "F", OPT_FRAMES, "frames to run, 0..100000 (0: the whole 2.75 s trajectory at speed 1)"},
    {"speed", "S", OPT_SPEED, "trajectory speed factor, 0.01..100 (1)"},
    {"amplitude", "A", OPT_AMPLITUDE, "translation per move in metres, 0..10 (0.5)"},
    {"size", "M", OPT_SIZE, "side of the square cloth in metres, 0.05..10 (1); gravity and handle\n"
                            "speeds in grid units scale with (res - 1) / size"},
    {"optimizer", "O", OPT_OPTIMIZER, "learned gd adam lbfgs (learned)"},
    {"iters", "K", OPT_ITERS, "inner iterations per step, 1..10000 (10)"},
    {"lr", "X", OPT_LR, "step size of gd/adam/lbfgs, 1e-6..100 (0.01)"},
    {"model", "PATH", OPT_MODEL, "FNOpt weights (tools/fnopt/models/fnopt_32.safetensors)"},
    {"material", "Y,S,B", OPT_MATERIAL, "energy coefficients in grid units, each 0..1e6 (1000,8,0.5)"},
    {"repulsion", "K", OPT_REPULSION, "self-repulsion weight, 0..1e6 (0)"},
    {"precision", "P", OPT_PRECISION, "fp32 fp16 int8: the learned optimizer's FNO arithmetic (fp32)"},
    {"no-guard", NULL, OPT_NO_GUARD, "turn the descent guard off (the paper's update rule; docs/FNOPT.md)"},
    {"max-step", "X", OPT_MAX_STEP, "the learned optimizer's trust region in grid units, 0..100 (0.5; 0: off)"},
    {"gt", NULL, OPT_GT, "score against the XPBD reference (e3D, Chamfer)"},
    {"loss", NULL, OPT_LOSS, "also report the mean final loss per step"},
    {"csv", "FILE", OPT_CSV, "append the result row to FILE"},
    {"out", "FILE", OPT_OUT, "write the positions (frames x res^2 x 3 float32, metres, Y up)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft fnopt",
    .synopsis = "weft fnopt run|fit [options]",
    .about = "FNOpt grid cloth scenes against the XPBD reference (docs/FNOPT.md):\n"
             "  run   one scene: ms/frame, and e3D / Chamfer against XPBD with --gt\n"
             "  fit   coordinate search of the material (Y, S, B) against XPBD",
    .options = k_options,
};

/* argv[0] is the subcommand (run or fit); the options follow it. */
static int parse(int argc, char **argv, cli *c)
{
    c->scene = (fnopt_scene_opts){.res = 32, .size_m = 1.0f, .fps = 60.0f, .speed = 1.0f, .amplitude_m = 0.5f,
                                  .motion = "xy", .handles = "corners", .frames = 0};
    c->run = (fnopt_run_opts){.optimizer = WEFT_FNOPT_LEARNED, .iterations = 10, .learning_rate = 0.01f,
                              .Y = 1000.0f, .S = 8.0f, .B = 0.5f, .max_step = weft_default_fnopt_def().max_step};
    c->model_path = "tools/fnopt/models/fnopt_32.safetensors";
    cli_parser p;
    cli_start(&p, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&p, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return p.exit == 0 ? 1 : p.exit; /* 1: help printed */
        case OPT_GT:
            c->gt = true;
            break;
        case OPT_LOSS:
            c->run.report_loss = true;
            break;
        case OPT_NO_GUARD:
            c->run.no_guard = true;
            break;
        case OPT_MAX_STEP:
            if (!cli_float(k_tool, a, v, 0.0f, 100.0f, &c->run.max_step)) {
                return 2;
            }
            break;
        case OPT_RES:
            if (!cli_u32(k_tool, a, v, 10, 1024, &c->scene.res)) {
                return 2;
            }
            break;
        case OPT_MOTION:
            c->scene.motion = v;
            break;
        case OPT_HANDLES:
            c->scene.handles = v;
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_tool, a, v, 0, 100000, &c->scene.frames)) {
                return 2;
            }
            break;
        case OPT_SPEED:
            if (!cli_float(k_tool, a, v, 0.01f, 100.0f, &c->scene.speed)) {
                return 2;
            }
            break;
        case OPT_AMPLITUDE:
            if (!cli_float(k_tool, a, v, 0.0f, 10.0f, &c->scene.amplitude_m)) {
                return 2;
            }
            break;
        case OPT_SIZE:
            if (!cli_float(k_tool, a, v, 0.05f, 10.0f, &c->scene.size_m)) {
                return 2;
            }
            break;
        case OPT_ITERS:
            if (!cli_u32(k_tool, a, v, 1, 10000, &c->run.iterations)) {
                return 2;
            }
            break;
        case OPT_LR:
            if (!cli_float(k_tool, a, v, 1e-6f, 100.0f, &c->run.learning_rate)) {
                return 2;
            }
            break;
        case OPT_MODEL:
            c->model_path = v;
            break;
        case OPT_REPULSION:
            if (!cli_float(k_tool, a, v, 0.0f, 1e6f, &c->run.repulsion)) {
                return 2;
            }
            break;
        case OPT_PRECISION:
            if (!fnopt_parse_precision(v, &c->run.precision)) {
                fprintf(stderr, "weft fnopt: --precision wants fp32, fp16 or int8\n");
                return 2;
            }
            break;
        case OPT_CSV:
            c->csv = v;
            break;
        case OPT_OUT:
            c->out = v;
            break;
        case OPT_MATERIAL: {
            float m[3];
            if (!cli_floats(k_tool, a, v, 0.0f, 1e6f, m, 3)) {
                return 2;
            }
            c->run.Y = m[0], c->run.S = m[1], c->run.B = m[2];
            break;
        }
        case OPT_OPTIMIZER: {
            int k = 0;
            for (; k < 4 && strcmp(v, optimizer_name((weft_fnopt_optimizer)k)) != 0; ++k) {
            }
            if (k == 4) {
                fprintf(stderr, "weft fnopt: unknown optimizer '%s'\n", v);
                return 2;
            }
            c->run.optimizer = (weft_fnopt_optimizer)k;
            break;
        }
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&p) != 0) {
        return 2;
    }
    return 0;
}

static void print_row(FILE *fh, const cli *c, const fnopt_scene *s, const fnopt_run_result *r)
{
    fprintf(fh, "%u,%s,%s,%.2f,%s,%s,%d,%.3g,%u,%.4g,%.4g,%.4g,%.4g,%u,%d,%.4f,%.3f,%.3f,%.5f,%.5f,%.6g\n",
            c->scene.res, c->scene.motion, c->scene.handles, (double)c->scene.speed, optimizer_name(c->run.optimizer),
            c->run.optimizer == WEFT_FNOPT_LEARNED ? k_precision_names[c->run.precision] : "fp32", c->run.no_guard ? 0 : 1,
            c->run.optimizer == WEFT_FNOPT_LEARNED ? (double)c->run.max_step : 0.0,
            c->run.iterations, (double)c->run.learning_rate, (double)c->run.Y, (double)c->run.S, (double)c->run.B,
            r->frames, r->diverged ? 1 : 0, r->max_strain, r->guard_acted, r->ms_per_frame, r->e3d, r->chamfer * 1e3,
            r->loss);
    (void)s;
}

static const char k_header[] =
    "res,motion,handles,speed,optimizer,precision,guard,max_step,iters,lr,Y,S,B,frames,diverged,max_strain,guard_acted,"
    "ms_per_frame,e3d,chamfer_x1e3,loss\n";

static int run_one(weft_context *ctx, cli *c, weft_model *model, fnopt_run_result *out, bool print)
{
    fnopt_scene s;
    if (fnopt_scene_make(&c->scene, &s) != WEFT_OK) {
        return 2;
    }
    float *gt = NULL;
    if (c->gt && fnopt_scene_ground_truth(ctx, &s, &gt) != WEFT_OK) {
        fnopt_scene_free(&s);
        return 1;
    }
    c->run.model = model;
    float *pos = c->out ? malloc((size_t)s.frames * s.n * 3 * sizeof(float)) : NULL;
    fnopt_run_result r;
    weft_result wr = fnopt_scene_run(ctx, &s, &c->run, gt, &r, pos);
    if (wr == WEFT_OK) {
        if (print) {
            printf("%s", k_header);
            print_row(stdout, c, &s, &r);
        }
        if (c->csv) {
            FILE *fh = fopen(c->csv, "a+");
            if (fh) {
                fseek(fh, 0, SEEK_END);
                if (ftell(fh) == 0) {
                    fputs(k_header, fh);
                }
                print_row(fh, c, &s, &r);
                fclose(fh);
            }
        }
        if (pos) {
            FILE *fh = fopen(c->out, "wb");
            if (!fh || fwrite(pos, sizeof(float), (size_t)r.frames * s.n * 3, fh) != (size_t)r.frames * s.n * 3) {
                fprintf(stderr, "weft fnopt: cannot write '%s'\n", c->out);
                wr = WEFT_ERROR_IO;
            }
            if (fh) {
                fclose(fh);
            }
        }
        *out = r;
    }
    free(pos);
    free(gt);
    fnopt_scene_free(&s);
    return wr == WEFT_OK ? 0 : 1;
}

/* Coordinate search of (Y, S, B) on the current scene: each coefficient in turn over a
 * log-spaced set, keeping the value with the lowest mean e3D. */
static int fit(weft_context *ctx, cli *c, weft_model *model)
{
    static const float Ys[] = {100, 300, 1000, 3000, 10000};
    static const float Ss[] = {1, 3, 8, 30, 100};
    static const float Bs[] = {0.01f, 0.05f, 0.5f, 5, 50};
    const float *sets[3] = {Ys, Ss, Bs};
    float *coef[3] = {&c->run.Y, &c->run.S, &c->run.B};
    c->gt = true;
    printf("%s", k_header);
    for (int round = 0; round < 2; ++round) {
        for (int which = 0; which < 3; ++which) {
            float best = *coef[which];
            double best_e = INFINITY;
            for (int k = 0; k < 5; ++k) {
                *coef[which] = sets[which][k];
                fnopt_run_result r;
                if (run_one(ctx, c, model, &r, false) != 0) {
                    return 1;
                }
                fnopt_scene s0 = {.o = c->scene};
                print_row(stdout, c, &s0, &r);
                fflush(stdout);
                double e = r.diverged ? INFINITY : r.e3d;
                if (e < best_e) {
                    best_e = e;
                    best = sets[which][k];
                }
            }
            *coef[which] = best;
        }
    }
    printf("fit: Y=%g S=%g B=%g\n", (double)c->run.Y, (double)c->run.S, (double)c->run.B);
    return 0;
}

int weft_cmd_fnopt(int argc, char **argv)
{
    if (argc >= 2 && (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0)) {
        cli_usage(&k_command, stdout);
        return 0;
    }
    if (argc < 2) {
        return cli_fail(&k_command, "run or fit is required");
    }
    if (strcmp(argv[1], "run") != 0 && strcmp(argv[1], "fit") != 0) {
        char what[512];
        snprintf(what, sizeof what, "unknown subcommand '%s', want run or fit", argv[1]);
        return cli_fail(&k_command, what);
    }
    cli c = {0};
    int pr = parse(argc - 1, argv + 1, &c);
    if (pr != 0) {
        return pr == 1 ? 0 : pr;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft fnopt: %s\n", weft_last_error());
        return 1;
    }
    weft_model *model = NULL;
    if (c.run.optimizer == WEFT_FNOPT_LEARNED && weft_model_load_file_as(ctx, c.model_path, "fnopt", &model) != WEFT_OK) {
        fprintf(stderr, "weft fnopt: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    int rc;
    if (strcmp(argv[1], "fit") == 0) {
        rc = fit(ctx, &c, model);
    } else {
        fnopt_run_result r;
        rc = run_one(ctx, &c, model, &r, true);
    }
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    return rc;
}
