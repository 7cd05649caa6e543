/* Switching a live garment between levels without a pop.
 *
 * Pop metric: J, the largest vertex displacement in the first frame after the switch, against M,
 * the largest per-frame vertex displacement over the POP_WINDOW frames before it (the "normal
 * motion"). The bound asserted is J <= POP_BOUND * M + POP_FLOOR_M (docs/LOD.md). The same
 * quantities are printed for a naive switch (a fresh garment given only x_t: no velocity, no
 * latent history) so the log shows what the carried state buys.
 *
 * Cases: the committed sample sequence (tests/data/sample_seq, a sheet dropped on a blob) with
 * its ground-truth collider, and a procedural sheet falling on a sphere that slides sideways.
 * Also: a switch between two identical model levels is exact (bit-identical rollout to never
 * switching) because the latent window is rebuilt, and it is not without the past-frame ring;
 * failed switches leave the garment as it was. */
#include "test.h"
#include "weft/lod.h"
#include "weft/body.h"
#include "assets/npz.h"

#include <stdint.h>

#define POP_WINDOW 8
#define POP_BOUND 1.5
/* g dt^2 = 9.81 / 60^2 m: what a vertex at rest moves in its first frame of free fall. A cloth
 * that was still (e.g. glued by LBS to a still collider) and starts to fall is motion, not a pop. */
#define POP_FLOOR_M (9.81 / 3600.0)

typedef struct scene {
    const char *name;
    float *rest, *x0, *x1;              /* x0, x1: the first two frames (x1 NULL: start at x0, at rest) */
    uint32_t *tris;
    uint32_t N, T;
    float *crest, *cpos;                /* cpos: frames x C x 3, frame k is the collider at garment frame k */
    uint32_t *ctris;
    uint32_t C, CT, frames;
} scene;

static const char *const table_text =
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames\n"
    "xpbd-3,xpbd,-,-,3,on,1,2.0,1.0,0.02,1,1\n"
    "xpbd-2,xpbd,-,-,2,on,1,1.0,1.5,0.03,1,1\n"
    "lbs,lbs,-,-,-,on,1,0.1,4.0,0.01,1,1\n"
    "golden-fp32,model,golden,fp32,-,on,1,1.5,0.8,0.03,1,1\n"
    "golden-copy,model,golden,fp32,-,on,1,1.5,0.8,0.03,1,1\n"
    "golden-int8,model,golden,int8,-,on,1,0.9,0.9,0.03,1,1\n"
    "game-int8,model,game,int8,-,off,1,0.5,1.2,0.03,1,1\n"
    "missing-model,model,nosuch,fp32,-,on,1,0.5,1.2,0.03,1,1\n";

/* ---------------------------------------------------------------------------------------- */
/* Scenes                                                                                     */

static bool read_npy(const char *name, weft_npy_array *a, void **bytes)
{
    char path[512];
    snprintf(path, sizeof path, "%s/tests/data/sample_seq/%s", WEFT_SOURCE_DIR, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        return false;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    *bytes = malloc(n > 0 ? (size_t)n : 1);
    bool ok = *bytes && n > 0 && fread(*bytes, 1, (size_t)n, f) == (size_t)n;
    fclose(f);
    return ok && weft_npy_parse(*bytes, (size_t)n, name, a) == WEFT_OK;
}

static float *npy_f32(const char *name, uint64_t *shape0, uint64_t *shape1)
{
    weft_npy_array a;
    void *bytes = NULL;
    float *out = NULL;
    if (read_npy(name, &a, &bytes)) {
        out = malloc(a.count * sizeof(float));
        if (out && weft_npy_to_f32(&a, out, a.count) != WEFT_OK) {
            free(out);
            out = NULL;
        }
        *shape0 = a.shape[0];
        *shape1 = a.ndim > 1 ? a.shape[1] : 1;
    }
    free(bytes);
    return out;
}

static uint32_t *npy_u32(const char *name, uint64_t *rows)
{
    weft_npy_array a;
    void *bytes = NULL;
    uint32_t *out = NULL;
    if (read_npy(name, &a, &bytes)) {
        int64_t *tmp = malloc(a.count * sizeof(int64_t));
        out = malloc(a.count * sizeof(uint32_t));
        if (tmp && out && weft_npy_to_i64(&a, tmp, a.count) == WEFT_OK) {
            for (uint64_t i = 0; i < a.count; ++i) {
                out[i] = (uint32_t)tmp[i];
            }
        } else {
            free(out);
            out = NULL;
        }
        free(tmp);
        *rows = a.shape[0];
    }
    free(bytes);
    return out;
}

/* The sample sequence from sequence frame `start`: garment frame k = sequence frame start + k + 1
 * (the rollout starts from two ground-truth frames, as `weft eval` does from frames 0 and 1). */
static bool scene_sample(scene *s, uint32_t start)
{
    memset(s, 0, sizeof *s);
    s->name = "sample_seq";
    uint64_t T = 0, N = 0, rn = 0, one = 0, F = 0, CT = 0, C = 0, T2 = 0;
    float *cloth = npy_f32("cloth_pos.npy", &T, &N);
    s->rest = npy_f32("rest_pos.npy", &rn, &one);
    s->tris = npy_u32("faces.npy", &F);
    float *cpos = npy_f32("collider_pos.npy", &T2, &C);
    s->ctris = npy_u32("collider_faces.npy", &CT);
    if (!cloth || !s->rest || !s->tris || !cpos || !s->ctris || T < start + 3 || T2 != T || rn != N) {
        free(cloth);
        free(cpos);
        return false;
    }
    s->N = (uint32_t)N;
    s->T = (uint32_t)F;
    s->C = (uint32_t)C;
    s->CT = (uint32_t)CT;
    s->frames = (uint32_t)T - 1 - start;
    size_t nx = (size_t)N * 3, nc = (size_t)C * 3;
    s->x0 = malloc(nx * sizeof(float));
    s->x1 = malloc(nx * sizeof(float));
    s->cpos = malloc(nc * s->frames * sizeof(float));
    s->crest = malloc(nc * sizeof(float));
    memcpy(s->x0, cloth + nx * start, nx * sizeof(float));
    memcpy(s->x1, cloth + nx * (start + 1), nx * sizeof(float));
    memcpy(s->cpos, cpos + nc * (start + 1), nc * s->frames * sizeof(float));
    memcpy(s->crest, cpos + nc * (start + 1), nc * sizeof(float));
    free(cloth);
    free(cpos);
    return true;
}

/* A ~1k-vertex sheet 0.15 m above a sphere of radius 0.2 m that slides along +X at 0.6 m/s. */
static bool scene_procedural(weft_context *ctx, scene *s)
{
    memset(s, 0, sizeof *s);
    s->name = "procedural";
    weft_cloth_def cd = weft_default_cloth_def(WEFT_CLOTH_SHEET);
    cd.resolution = WEFT_CLOTH_RES_1K;
    cd.size = 0.6f;
    cd.height = 0.55f;
    weft_cloth_mesh *m = NULL;
    if (weft_cloth_create(ctx, &cd, NULL, &m) != WEFT_OK) {
        fprintf(stderr, "sheet: %s\n", weft_last_error());
        return false;
    }
    s->N = m->vertex_count;
    s->T = m->triangle_count;
    s->rest = malloc((size_t)s->N * 3 * sizeof(float));
    s->tris = malloc((size_t)s->T * 3 * sizeof(uint32_t));
    memcpy(s->rest, m->positions, (size_t)s->N * 3 * sizeof(float));
    memcpy(s->tris, m->triangles, (size_t)s->T * 3 * sizeof(uint32_t));
    weft_cloth_destroy(m);
    s->x0 = malloc((size_t)s->N * 3 * sizeof(float));
    memcpy(s->x0, s->rest, (size_t)s->N * 3 * sizeof(float));

    enum { RINGS = 12, SEGS = 24 };
    const float radius = 0.2f, cy = 0.2f;
    s->C = (RINGS - 1) * SEGS + 2;
    s->CT = 2 * SEGS * (RINGS - 1);
    s->crest = malloc((size_t)s->C * 3 * sizeof(float));
    s->ctris = malloc((size_t)s->CT * 3 * sizeof(uint32_t));
    float *v = s->crest;
    v[0] = 0.0f, v[1] = cy + radius, v[2] = 0.0f;
    uint32_t k = 1;
    for (uint32_t r = 1; r < RINGS; ++r) {
        double th = 3.14159265358979 * r / RINGS;
        for (uint32_t j = 0; j < SEGS; ++j, ++k) {
            double ph = 2.0 * 3.14159265358979 * j / SEGS;
            v[3 * k + 0] = (float)(radius * sin(th) * cos(ph));
            v[3 * k + 1] = (float)(cy + radius * cos(th));
            v[3 * k + 2] = (float)(radius * sin(th) * sin(ph));
        }
    }
    const uint32_t bottom = k;
    v[3 * bottom + 0] = 0.0f, v[3 * bottom + 1] = cy - radius, v[3 * bottom + 2] = 0.0f;
    uint32_t *t = s->ctris, nt = 0;
    for (uint32_t j = 0; j < SEGS; ++j) { /* caps, counter-clockwise from outside */
        uint32_t a = 1 + j, b = 1 + (j + 1) % SEGS;
        t[3 * nt + 0] = 0, t[3 * nt + 1] = b, t[3 * nt + 2] = a, nt++;
        uint32_t c = 1 + (RINGS - 2) * SEGS + j, d = 1 + (RINGS - 2) * SEGS + (j + 1) % SEGS;
        t[3 * nt + 0] = bottom, t[3 * nt + 1] = c, t[3 * nt + 2] = d, nt++;
    }
    for (uint32_t r = 0; r + 2 < RINGS; ++r) {
        for (uint32_t j = 0; j < SEGS; ++j) {
            uint32_t a = 1 + r * SEGS + j, b = 1 + r * SEGS + (j + 1) % SEGS;
            uint32_t c = a + SEGS, d = b + SEGS;
            t[3 * nt + 0] = a, t[3 * nt + 1] = b, t[3 * nt + 2] = c, nt++;
            t[3 * nt + 0] = b, t[3 * nt + 1] = d, t[3 * nt + 2] = c, nt++;
        }
    }
    s->CT = nt;
    s->frames = 60;
    s->cpos = malloc((size_t)s->C * 3 * s->frames * sizeof(float));
    for (uint32_t f = 0; f < s->frames; ++f) {
        float dx = 0.6f * (float)f / 60.0f;
        for (uint32_t i = 0; i < s->C; ++i) {
            float *o = s->cpos + ((size_t)f * s->C + i) * 3;
            o[0] = v[3 * i + 0] + dx;
            o[1] = v[3 * i + 1];
            o[2] = v[3 * i + 2];
        }
    }
    return true;
}

static void scene_free(scene *s)
{
    free(s->rest);
    free(s->x0);
    free(s->x1);
    free(s->tris);
    free(s->crest);
    free(s->cpos);
    free(s->ctris);
}

/* ---------------------------------------------------------------------------------------- */

typedef struct fixture {
    weft_context *ctx;
    weft_model *models[2];
    weft_lod_table *table;
} fixture;

static bool fixture_make(fixture *fx)
{
    memset(fx, 0, sizeof *fx);
    weft_context_def d = weft_default_context_def();
    bool ok = weft_context_create(&d, &fx->ctx) == WEFT_OK;
    /* "golden": the parity tests' model with a latent history of two frames, trained on sheets
     * falling onto spheres as these scenes are; "game": a shipped one-frame model */
    static const char *const files[2] = {WEFT_SOURCE_DIR "/tests/model/data/golden_model.safetensors",
                                         WEFT_SOURCE_DIR "/tools/train/models/game.safetensors"};
    for (int i = 0; ok && i < 2; ++i) {
        const char *path = files[i];
        ok = weft_model_load_file(fx->ctx, path, &fx->models[i]) == WEFT_OK;
        if (!ok) {
            fprintf(stderr, "%s: %s\n", path, weft_last_error());
        }
    }
    ok = ok && weft_lod_table_load_memory(fx->ctx, table_text, strlen(table_text), &fx->table) == WEFT_OK;
    CHECK(ok);
    return ok;
}

static void fixture_free(fixture *fx)
{
    weft_lod_table_destroy(fx->table);
    for (int i = 0; i < 2; ++i) {
        weft_model_destroy(fx->models[i]);
    }
    weft_context_destroy(fx->ctx);
}

static uint32_t level_of(const fixture *fx, const char *name)
{
    uint32_t i = 0;
    CHECK_RESULT(weft_lod_table_find(fx->table, name, &i), WEFT_OK);
    return i;
}

static weft_result make_lod(const fixture *fx, const scene *s, uint32_t level, uint32_t history, weft_lod_garment **out)
{
    weft_lod_garment_def d = weft_default_lod_garment_def();
    d.table = fx->table;
    d.level = level;
    d.models = (const weft_model *const *)fx->models;
    d.model_count = 2;
    d.rest_positions = s->rest;
    d.vertex_count = s->N;
    d.triangles = s->tris;
    d.triangle_count = s->T;
    d.collider_rest_positions = s->crest;
    d.collider_vertex_count = s->C;
    d.collider_triangles = s->ctris;
    d.collider_triangle_count = s->CT;
    d.initial_positions = s->x1 ? s->x1 : s->x0;
    d.history_frames = history;
    weft_result r = weft_lod_garment_create(fx->ctx, &d, out);
    if (r == WEFT_OK && s->x1) {
        r = weft_lod_garment_set_state(*out, s->x1, s->x0);
    }
    return r;
}

/* Steps frame k -> k+1 with the scene's collider and stores x_{k+1} in traj. */
static bool step_frame(weft_lod_garment *g, const scene *s, uint32_t k, float *traj)
{
    weft_result r = weft_lod_garment_set_collider(g, s->cpos + (size_t)(k + 1) * s->C * 3);
    if (r == WEFT_OK) {
        r = weft_lod_garment_step(g);
    }
    CHECK_MSG(r == WEFT_OK, "%s frame %u: %s", s->name, k, weft_last_error());
    if (r == WEFT_OK) {
        memcpy(traj + (size_t)(k + 1) * s->N * 3, weft_lod_garment_positions(g), (size_t)s->N * 3 * sizeof(float));
    }
    return r == WEFT_OK;
}

static double max_disp(const float *a, const float *b, uint32_t n)
{
    double m = 0;
    for (uint32_t i = 0; i < n; ++i) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        double d = sqrt(dx * dx + dy * dy + dz * dz);
        m = d > m ? d : m;
    }
    return m;
}

/* Largest |x_{k+1} - 2 x_k + x_{k-1}| over vertices: the change of velocity in frame k -> k+1. */
static double max_accel(const float *next, const float *cur, const float *prev, uint32_t n)
{
    double m = 0;
    for (uint32_t i = 0; i < n; ++i) {
        double s2 = 0;
        for (int d = 0; d < 3; ++d) {
            double a = (double)next[3 * i + d] - 2.0 * cur[3 * i + d] + prev[3 * i + d];
            s2 += a * a;
        }
        m = s2 > m ? s2 : m;
    }
    return sqrt(m);
}

typedef struct pop {
    double jump, normal;                /* J and M (metres) */
    double accel, accel_normal;         /* velocity change at the switch and its max over the window */
} pop;

static void pop_measure(const float *traj, uint32_t at, uint32_t n, pop *p)
{
    const size_t f = (size_t)n * 3;
    p->jump = max_disp(traj + (at + 1) * f, traj + at * f, n);
    p->accel = max_accel(traj + (at + 1) * f, traj + at * f, traj + (at - 1) * f, n);
    p->normal = p->accel_normal = 0;
    for (uint32_t k = at - POP_WINDOW; k < at; ++k) {
        double d = max_disp(traj + (k + 1) * f, traj + k * f, n);
        double a = max_accel(traj + (k + 1) * f, traj + k * f, traj + (k - 1) * f, n);
        p->normal = d > p->normal ? d : p->normal;
        p->accel_normal = a > p->accel_normal ? a : p->accel_normal;
    }
}

/* Runs `from` for `at` frames, then steps one frame twice from that state: once after
 * weft_lod_garment_switch to `to`, once with a naive switch (a new garment of level `to` placed
 * at x_t, at rest, with no history: what a host without this API would do). */
static bool measure_pop(const fixture *fx, const scene *s, const char *from, const char *to, uint32_t at, pop *sw,
                        pop *naive)
{
    const size_t f = (size_t)s->N * 3;
    float *traj = calloc((size_t)(at + 2) * f, sizeof(float));
    float *alt = calloc((size_t)(at + 2) * f, sizeof(float));
    weft_lod_garment *g = NULL, *n = NULL;
    bool ok = traj && alt && make_lod(fx, s, level_of(fx, from), 0, &g) == WEFT_OK;
    CHECK_MSG(ok, "%s: create %s: %s", s->name, from, weft_last_error());
    if (ok) {
        memcpy(traj, weft_lod_garment_positions(g), f * sizeof(float));
        if (s->x1) { /* frame -1 for the acceleration at frame 0 */
            memcpy(traj, s->x1, f * sizeof(float));
        }
    }
    for (uint32_t k = 0; ok && k < at; ++k) {
        ok = step_frame(g, s, k, traj);
    }
    if (ok) {
        scene moved = *s;
        moved.x0 = traj + (size_t)at * f;
        moved.x1 = NULL;
        moved.crest = s->cpos + (size_t)at * s->C * 3; /* the collider "now" */
        ok = make_lod(fx, &moved, level_of(fx, to), 1, &n) == WEFT_OK;
        CHECK_MSG(ok, "%s: naive %s: %s", s->name, to, weft_last_error());
    }
    if (ok) {
        weft_result r = weft_lod_garment_switch(g, level_of(fx, to));
        CHECK_MSG(r == WEFT_OK, "%s: switch %s -> %s: %s", s->name, from, to, weft_last_error());
        ok = r == WEFT_OK;
        CHECK(ok && weft_lod_garment_level(g) == level_of(fx, to));
        CHECK(ok && memcmp(weft_lod_garment_positions(g), traj + (size_t)at * f, f * sizeof(float)) == 0);
    }
    if (ok) {
        memcpy(alt, traj, (size_t)(at + 1) * f * sizeof(float));
        ok = step_frame(g, s, at, traj) && step_frame(n, s, at, alt);
    }
    if (ok) {
        pop_measure(traj, at, s->N, sw);
        pop_measure(alt, at, s->N, naive);
    }
    weft_lod_garment_destroy(g);
    weft_lod_garment_destroy(n);
    free(traj);
    free(alt);
    return ok;
}

static void check_pops(const scene *s, uint32_t at, const char *const (*pairs)[2], size_t count)
{
    fixture fx;
    if (!fixture_make(&fx)) {
        fixture_free(&fx);
        return;
    }
    for (size_t i = 0; i < count; ++i) {
        pop p, q;
        if (!measure_pop(&fx, s, pairs[i][0], pairs[i][1], at, &p, &q)) {
            continue;
        }
        /* Ratios against a window with no velocity change at all (rigid LBS motion) are printed
         * as "-": dividing by rounding noise means nothing. */
        char r1[16] = "-", r2[16] = "-";
        if (p.accel_normal > 1e-5) {
            snprintf(r1, sizeof r1, "%.2f", p.accel / p.accel_normal);
            snprintf(r2, sizeof r2, "%.2f", q.accel / q.accel_normal);
        }
        printf("%-10s %-12s -> %-12s at %2u: jump %6.2f mm / normal %6.2f mm = %.2f, dv %6.2f mm / normal %6.2f mm "
               "= %s | naive: jump %6.2f mm = %.2f, dv %6.2f mm = %s\n",
               s->name, pairs[i][0], pairs[i][1], at, p.jump * 1e3, p.normal * 1e3, p.jump / p.normal,
               p.accel * 1e3, p.accel_normal * 1e3, r1, q.jump * 1e3, q.jump / q.normal, q.accel * 1e3, r2);
        CHECK_MSG(p.jump <= POP_BOUND * p.normal + POP_FLOOR_M, "%s %s -> %s: jump %.4g m over %.2f x normal %.4g m",
                  s->name, pairs[i][0], pairs[i][1], p.jump, POP_BOUND, p.normal);
    }
    fixture_free(&fx);
}

static void test_pop_sample_seq(void)
{
    /* From frame 14 (falling onto the blob), switching 10 frames later: XPBD is the slow part. */
    scene s;
    bool ok = scene_sample(&s, 14);
    CHECK_MSG(ok, "tests/data/sample_seq could not be read");
    if (ok) {
        static const char *const pairs[][2] = {
            {"golden-fp32", "xpbd-2"},       {"golden-fp32", "lbs"}, {"golden-fp32", "golden-int8"},
            {"golden-fp32", "game-int8"},    {"game-int8", "golden-fp32"}, {"xpbd-2", "golden-fp32"},
        };
        check_pops(&s, 10, pairs, sizeof pairs / sizeof pairs[0]);
    }
    scene_free(&s);
}

static void test_pop_procedural(void)
{
    fixture fx;
    bool ok = fixture_make(&fx);
    scene s;
    ok = ok && scene_procedural(fx.ctx, &s);
    fixture_free(&fx);
    CHECK(ok);
    if (ok) {
        static const char *const pairs[][2] = {
            {"golden-fp32", "xpbd-2"}, {"golden-fp32", "lbs"},      {"golden-fp32", "golden-int8"},
            {"game-int8", "golden-fp32"}, {"lbs", "golden-fp32"},
        };
        check_pops(&s, 16, pairs, sizeof pairs / sizeof pairs[0]);
        scene_free(&s);
    }
}

/* A switch between two identical model levels rebuilds the latent window exactly. */
static void test_switch_exact(void)
{
    fixture fx;
    scene s;
    if (!fixture_make(&fx) || !scene_sample(&s, 0)) {
        CHECK(false);
        fixture_free(&fx);
        return;
    }
    const uint32_t at = 12, after = 6;
    const size_t f = (size_t)s.N * 3;
    float *ref = calloc((size_t)(at + after + 1) * f, sizeof(float));
    float *sw = calloc((size_t)(at + after + 1) * f, sizeof(float));
    float *cold = calloc((size_t)(at + after + 1) * f, sizeof(float));
    weft_lod_garment *a = NULL, *b = NULL, *c = NULL;
    CHECK_RESULT(make_lod(&fx, &s, level_of(&fx, "golden-fp32"), 0, &a), WEFT_OK);
    CHECK_RESULT(make_lod(&fx, &s, level_of(&fx, "golden-fp32"), 0, &b), WEFT_OK);
    CHECK_RESULT(make_lod(&fx, &s, level_of(&fx, "golden-fp32"), 1, &c), WEFT_OK); /* no ring */
    bool ok = a && b && c;
    for (uint32_t k = 0; ok && k < at + after; ++k) {
        if (k == at) {
            CHECK_RESULT(weft_lod_garment_switch(b, level_of(&fx, "golden-copy")), WEFT_OK);
            CHECK_RESULT(weft_lod_garment_switch(c, level_of(&fx, "golden-copy")), WEFT_OK);
        }
        ok = step_frame(a, &s, k, ref) && step_frame(b, &s, k, sw) && step_frame(c, &s, k, cold);
    }
    if (ok) {
        size_t bytes = (size_t)(at + after + 1) * f * sizeof(float);
        CHECK_MSG(memcmp(ref, sw, bytes) == 0, "switched rollout differs from the continuous one");
        double diff = max_disp(cold + (size_t)(at + 1) * f, ref + (size_t)(at + 1) * f, s.N);
        printf("history rebuilt: identical rollout; without the past-frame ring the first frame after the switch "
               "differs by %.4f mm\n",
               diff * 1e3);
        CHECK(diff > 0.0);
    }
    weft_lod_garment_destroy(a);
    weft_lod_garment_destroy(b);
    weft_lod_garment_destroy(c);
    free(ref);
    free(sw);
    free(cold);
    scene_free(&s);
    fixture_free(&fx);
}

/* Failed switches and bad arguments leave everything as it was. */
static void test_switch_failures(void)
{
    fixture fx;
    scene s;
    if (!fixture_make(&fx) || !scene_sample(&s, 0)) {
        CHECK(false);
        fixture_free(&fx);
        return;
    }
    const size_t f = (size_t)s.N * 3;
    float *traj = calloc(8 * f, sizeof(float));
    weft_lod_garment *g = NULL;
    CHECK_RESULT(make_lod(&fx, &s, level_of(&fx, "xpbd-2"), 0, &g), WEFT_OK);
    for (uint32_t k = 0; g && k < 3; ++k) {
        step_frame(g, &s, k, traj);
    }
    if (g) {
        float *before = malloc(f * sizeof(float));
        memcpy(before, weft_lod_garment_positions(g), f * sizeof(float));
        uint32_t lv = weft_lod_garment_level(g);
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&fx, "missing-model")), WEFT_ERROR_NO_MODEL);
        CHECK(strstr(weft_last_error(), "nosuch") != NULL);
        CHECK_RESULT(weft_lod_garment_switch(g, 1000), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK_EQ_INT(weft_lod_garment_level(g), lv);
        /* Pins: carried XPBD -> XPBD. */
        uint32_t pin = 5;
        const float *p = weft_lod_garment_positions(g) + 3 * pin;
        float target[3] = {p[0], p[1], p[2]};
        CHECK_RESULT(weft_lod_garment_set_pins(g, &pin, target, 1), WEFT_OK);
        CHECK_EQ_INT(weft_lod_garment_level(g), lv);
        CHECK(memcmp(before, weft_lod_garment_positions(g), f * sizeof(float)) == 0);
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&fx, "xpbd-3")), WEFT_OK);
        weft_garment *cur = weft_lod_garment_current(g);
        CHECK_EQ_INT(cur ? weft_garment_stats(cur).frame : 99, 0);
        CHECK(memcmp(before, weft_lod_garment_positions(g), f * sizeof(float)) == 0);
        for (uint32_t k = 3; k < 5; ++k) {
            step_frame(g, &s, k, traj);
            /* The carried pin holds its target. */
            CHECK_NEAR(weft_lod_garment_positions(g)[3 * pin + 1], target[1], 1e-5);
        }
        CHECK_RESULT(weft_lod_garment_switch(g, weft_lod_garment_level(g)), WEFT_OK); /* no-op */
        /* A non-finite teleport is refused and changes nothing. */
        float *bad = malloc(f * sizeof(float));
        memcpy(bad, weft_lod_garment_positions(g), f * sizeof(float));
        memcpy(before, bad, f * sizeof(float));
        bad[7] = NAN;
        CHECK_RESULT(weft_lod_garment_set_state(g, bad, NULL), WEFT_ERROR_NOT_FINITE);
        CHECK(memcmp(before, weft_lod_garment_positions(g), f * sizeof(float)) == 0);
        CHECK_RESULT(weft_lod_garment_set_state(NULL, bad, NULL), WEFT_ERROR_INVALID_ARGUMENT);
        free(bad);
        free(before);
    }
    weft_lod_garment_destroy(g);
    /* Creation errors. */
    weft_lod_garment_def d = weft_default_lod_garment_def();
    weft_lod_garment *out = NULL;
    CHECK_RESULT(weft_lod_garment_create(fx.ctx, &d, &out), WEFT_ERROR_INVALID_ARGUMENT);
    d.table = fx.table;
    d.level = level_of(&fx, "missing-model");
    d.rest_positions = s.rest;
    d.vertex_count = s.N;
    d.triangles = s.tris;
    d.triangle_count = s.T;
    CHECK_RESULT(weft_lod_garment_create(fx.ctx, &d, &out), WEFT_ERROR_NO_MODEL);
    weft_lod_garment_def raw;
    memset(&raw, 0, sizeof raw);
    CHECK_RESULT(weft_lod_garment_create(fx.ctx, &raw, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(out == NULL);
    CHECK_RESULT(weft_lod_garment_step(NULL), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_lod_garment_switch(NULL, 0), WEFT_ERROR_INVALID_ARGUMENT);
    free(traj);
    scene_free(&s);
    fixture_free(&fx);
}

TEST_MAIN(TEST_CASE(test_pop_sample_seq), TEST_CASE(test_pop_procedural), TEST_CASE(test_switch_exact),
          TEST_CASE(test_switch_failures))
