/* Resolution levels of weft_lod_garment: a level with resolution < 1 simulates a coarser mesh of
 * the same garment (def.sim_meshes) and draws the garment's own mesh through a mesh map.
 *
 * Scene: a 4k sheet falling onto a box that slides sideways, with the 1k sheet of the same square
 * as the sim mesh. Checks: the drawn mesh keeps its vertex count at every level; switching 4k ->
 * 1k -> 4k mid-drape does not pop (the pop metric of test_switch.c: the largest vertex jump in the
 * frame after the switch against the largest per-frame motion over the 8 frames before), and a
 * switch without the blend is printed for comparison; set_state at a coarse level shows the given
 * state exactly; pins name drawn vertices at every level: a corner pinned at a coarse level, or
 * pinned before a switch onto it, holds while the rest falls, and the pins carry back to the fine
 * level exactly; a level without a matching sim mesh, bad pins and a bad sim mesh fail with clear
 * errors and leave the garment as it was. */
#include "../xpbd/scene.h"
#include "test.h"
#include "weft/body.h"
#include "weft/lod.h"

#include <math.h>
#include <string.h>

#define POP_WINDOW 8
#define POP_BOUND 1.5
#define POP_FLOOR_M (9.81 / 3600.0)
#define SWITCH_AT 16

static const char *const table_text =
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames,"
    "tether_cm,strain_limit_pct\n"
    "xpbd-4,xpbd,-,-,4,off,1,4.0,1.0,0.02,1,1,-,-\n"
    "xpbd-4-quarter,xpbd,-,-,4,off,0.25,1.0,1.5,0.02,1,1,-,-\n"
    "xpbd-4-half,xpbd,-,-,4,off,0.5,2.0,1.2,0.02,1,1,-,-\n"
    "xpbd-4-tethered,xpbd,-,-,4,off,1,4.1,1.0,0.02,1,1,2,-\n";

typedef struct res_scene {
    weft_context *ctx;
    weft_lod_table *table;
    weft_cloth_mesh *fine, *coarse;
    test_mesh box;
    float *moved;
} res_scene;

static bool scene_make(res_scene *s)
{
    memset(s, 0, sizeof *s);
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &s->ctx), WEFT_OK);
    weft_cloth_def d = weft_default_cloth_def(WEFT_CLOTH_SHEET);
    d.size = 0.6f;
    d.height = 0.55f;
    d.resolution = WEFT_CLOTH_RES_4K;
    CHECK_RESULT(weft_cloth_create(s->ctx, &d, NULL, &s->fine), WEFT_OK);
    d.resolution = WEFT_CLOTH_RES_1K;
    CHECK_RESULT(weft_cloth_create(s->ctx, &d, NULL, &s->coarse), WEFT_OK);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.4f, 0.15f};
    s->box = test_box(lo, hi);
    s->moved = malloc(sizeof(float) * 3 * s->box.nv);
    CHECK_RESULT(weft_lod_table_load_memory(s->ctx, table_text, strlen(table_text), &s->table), WEFT_OK);
    return s->fine && s->coarse && s->moved && s->table;
}

static void scene_free(res_scene *s)
{
    weft_lod_table_destroy(s->table);
    free(s->moved);
    test_mesh_free(&s->box);
    weft_cloth_destroy(s->fine);
    weft_cloth_destroy(s->coarse);
    weft_context_destroy(s->ctx);
}

static uint32_t level_of(const res_scene *s, const char *name)
{
    uint32_t i = 0;
    CHECK_RESULT(weft_lod_table_find(s->table, name, &i), WEFT_OK);
    return i;
}

static weft_result make(const res_scene *s, const char *level, uint32_t blend, bool with_mesh, weft_lod_garment **out)
{
    static weft_lod_mesh mesh;
    mesh.rest_positions = s->coarse->positions;
    mesh.vertex_count = s->coarse->vertex_count;
    mesh.triangles = s->coarse->triangles;
    mesh.triangle_count = s->coarse->triangle_count;
    weft_lod_garment_def d = weft_default_lod_garment_def();
    d.table = s->table;
    d.level = level_of(s, level);
    d.rest_positions = s->fine->positions;
    d.vertex_count = s->fine->vertex_count;
    d.triangles = s->fine->triangles;
    d.triangle_count = s->fine->triangle_count;
    d.collider_rest_positions = s->box.pos;
    d.collider_vertex_count = s->box.nv;
    d.collider_triangles = s->box.tris;
    d.collider_triangle_count = s->box.nt;
    d.sim_meshes = with_mesh ? &mesh : NULL;
    d.sim_mesh_count = with_mesh ? 1 : 0;
    d.resolution_blend_frames = blend;
    return weft_lod_garment_create(s->ctx, &d, out);
}

/* Frame f -> f+1: the box slides along +X at 0.6 m/s. */
static bool step(res_scene *s, weft_lod_garment *g, uint32_t f)
{
    const float dx = 0.6f * (float)(f + 1) / 60.0f;
    for (uint32_t i = 0; i < s->box.nv; ++i) {
        s->moved[3 * i] = s->box.pos[3 * i] + dx;
        s->moved[3 * i + 1] = s->box.pos[3 * i + 1];
        s->moved[3 * i + 2] = s->box.pos[3 * i + 2];
    }
    weft_result r = weft_lod_garment_set_collider(g, s->moved);
    if (r == WEFT_OK) {
        r = weft_lod_garment_step(g);
    }
    CHECK_MSG(r == WEFT_OK, "frame %u: %s", f, weft_last_error());
    return r == WEFT_OK;
}

static double max_disp(const float *a, const float *b, uint32_t n)
{
    double m = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        m = fmax(m, sqrt(dx * dx + dy * dy + dz * dz));
    }
    return m;
}

/* Runs `from` to SWITCH_AT, switches to `to`, steps once; jump and normal motion in metres. */
static bool measure(res_scene *s, const char *from, const char *to, uint32_t blend, double *jump, double *normal)
{
    const uint32_t N = s->fine->vertex_count;
    const size_t f = (size_t)N * 3;
    float *traj = calloc((size_t)(SWITCH_AT + 2) * f, sizeof(float));
    weft_lod_garment *g = NULL;
    bool ok = traj && make(s, from, blend, true, &g) == WEFT_OK;
    CHECK_MSG(ok, "create %s: %s", from, weft_last_error());
    if (ok) {
        CHECK_EQ_INT(weft_lod_garment_vertex_count(g), N);
        memcpy(traj, weft_lod_garment_positions(g), f * sizeof(float));
    }
    for (uint32_t k = 0; ok && k < SWITCH_AT; ++k) {
        ok = step(s, g, k);
        if (ok) {
            memcpy(traj + (k + 1) * f, weft_lod_garment_positions(g), f * sizeof(float));
        }
    }
    if (ok) {
        weft_result r = weft_lod_garment_switch(g, level_of(s, to));
        CHECK_MSG(r == WEFT_OK, "switch %s -> %s: %s", from, to, weft_last_error());
        ok = r == WEFT_OK;
    }
    if (ok) {
        /* The switch itself moves nothing that is drawn (without the blend, onto a coarse mesh, it
         * does: that is the pop the blend avoids). */
        CHECK_MSG((blend == 0 && strcmp(to, "xpbd-4-quarter") == 0) || memcmp(weft_lod_garment_positions(g), traj + SWITCH_AT * f, f * sizeof(float)) == 0,
                  "%s -> %s: the drawn positions changed at the switch", from, to);
        const uint32_t sim_n = weft_garment_vertex_count(weft_lod_garment_current(g));
        CHECK_EQ_INT(sim_n, strcmp(to, "xpbd-4-quarter") != 0 ? N : s->coarse->vertex_count);
        ok = step(s, g, SWITCH_AT);
    }
    if (ok) {
        memcpy(traj + (SWITCH_AT + 1) * f, weft_lod_garment_positions(g), f * sizeof(float));
        *jump = max_disp(traj + (SWITCH_AT + 1) * f, traj + SWITCH_AT * f, N);
        *normal = 0.0;
        for (uint32_t k = SWITCH_AT - POP_WINDOW; k < SWITCH_AT; ++k) {
            *normal = fmax(*normal, max_disp(traj + (k + 1) * f, traj + k * f, N));
        }
    }
    weft_lod_garment_destroy(g);
    free(traj);
    return ok;
}

static void test_resolution_switch_without_pop(void)
{
    res_scene s;
    if (!scene_make(&s)) {
        scene_free(&s);
        return;
    }
    static const char *const pairs[][2] = {{"xpbd-4", "xpbd-4-quarter"}, {"xpbd-4-quarter", "xpbd-4"}};
    for (size_t i = 0; i < 2; ++i) {
        double jump = 0, normal = 0, raw_jump = 0, raw_normal = 0;
        if (!measure(&s, pairs[i][0], pairs[i][1], 8, &jump, &normal) ||
            !measure(&s, pairs[i][0], pairs[i][1], 0, &raw_jump, &raw_normal)) {
            continue;
        }
        printf("%-15s -> %-15s at %u: jump %6.2f mm / normal %6.2f mm = %.2f | without the blend: %6.2f mm = %.2f\n",
               pairs[i][0], pairs[i][1], SWITCH_AT, jump * 1e3, normal * 1e3, jump / normal, raw_jump * 1e3,
               raw_jump / raw_normal);
        CHECK_MSG(normal > 1e-3, "the sheet barely moves before the switch (%g m): the scene tests nothing", normal);
        CHECK_MSG(jump <= POP_BOUND * normal + POP_FLOOR_M, "%s -> %s: jump %.4g m over %.2f x normal %.4g m",
                  pairs[i][0], pairs[i][1], jump, POP_BOUND, normal);
    }
    scene_free(&s);
}

static void test_resolution_state_and_failures(void)
{
    res_scene s;
    if (!scene_make(&s)) {
        scene_free(&s);
        return;
    }
    const uint32_t N = s.fine->vertex_count;
    const size_t nx = (size_t)N * 3 * sizeof(float);
    weft_lod_garment *g = NULL;

    /* No sim mesh: a coarse level cannot be created. */
    CHECK_RESULT(make(&s, "xpbd-4-quarter", 8, false, &g), WEFT_ERROR_UNSUPPORTED);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "xpbd-4-quarter") != NULL);

    /* A coarse level draws the fine mesh; set_state there shows the given state exactly. */
    CHECK_RESULT(make(&s, "xpbd-4-quarter", 8, true, &g), WEFT_OK);
    if (g) {
        CHECK_EQ_INT(weft_lod_garment_vertex_count(g), N);
        float *x = malloc(nx);
        memcpy(x, s.fine->positions, nx);
        for (uint32_t i = 0; i < N; ++i) {
            x[3 * i + 1] += 0.01f * sinf(40.0f * x[3 * i]); /* ripples finer than the 1k grid */
        }
        CHECK_RESULT(weft_lod_garment_set_state(g, x, x), WEFT_OK);
        CHECK(memcmp(weft_lod_garment_positions(g), x, nx) == 0);
        /* No mesh near 0.5 (the 1k sheet is a quarter): the switch fails, nothing changes. */
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4-half")), WEFT_ERROR_UNSUPPORTED);
        CHECK_EQ_INT(weft_lod_garment_level(g), level_of(&s, "xpbd-4-quarter"));
        CHECK(memcmp(weft_lod_garment_positions(g), x, nx) == 0);
        /* A NaN state is refused and the drawn state kept. */
        float *bad = malloc(nx);
        memcpy(bad, x, nx);
        bad[7] = NAN;
        CHECK_RESULT(weft_lod_garment_set_state(g, bad, NULL), WEFT_ERROR_NOT_FINITE);
        CHECK(memcmp(weft_lod_garment_positions(g), x, nx) == 0);
        /* Back to the fine mesh: it starts exactly where the drawn state was. */
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4")), WEFT_OK);
        CHECK(memcmp(weft_lod_garment_positions(g), x, nx) == 0);
        free(bad);
        free(x);
        weft_lod_garment_destroy(g);
        g = NULL;
    }

    /* A sim mesh with an index out of range fails at creation. */
    uint32_t *tris = malloc((size_t)s.coarse->triangle_count * 3 * sizeof(uint32_t));
    memcpy(tris, s.coarse->triangles, (size_t)s.coarse->triangle_count * 3 * sizeof(uint32_t));
    tris[5] = s.coarse->vertex_count + 3;
    weft_lod_mesh bad_mesh = {s.coarse->positions, s.coarse->vertex_count, tris, s.coarse->triangle_count};
    weft_lod_garment_def d = weft_default_lod_garment_def();
    d.table = s.table;
    d.level = level_of(&s, "xpbd-4");
    d.rest_positions = s.fine->positions;
    d.vertex_count = N;
    d.triangles = s.fine->triangles;
    d.triangle_count = s.fine->triangle_count;
    d.collider_rest_positions = s.box.pos;
    d.collider_vertex_count = s.box.nv;
    d.collider_triangles = s.box.tris;
    d.collider_triangle_count = s.box.nt;
    d.sim_meshes = &bad_mesh;
    d.sim_mesh_count = 1;
    CHECK_MSG(weft_lod_garment_create(s.ctx, &d, &g) != WEFT_OK, "a sim mesh with a bad index was accepted");
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "sim_meshes[0]") != NULL);
    free(tris);
    scene_free(&s);
}

/* The drawn vertices within 4 cm of the sheet's (-x, -z) corner, held where they start. */
static uint32_t corner_pins(const res_scene *s, uint32_t *idx, float *tgt)
{
    const float *x = s->fine->positions;
    float lo[2] = {INFINITY, INFINITY};
    for (uint32_t i = 0; i < s->fine->vertex_count; ++i) {
        lo[0] = fminf(lo[0], x[3 * i]);
        lo[1] = fminf(lo[1], x[3 * i + 2]);
    }
    uint32_t n = 0;
    for (uint32_t i = 0; i < s->fine->vertex_count; ++i) {
        const float dx = x[3 * i] - lo[0], dz = x[3 * i + 2] - lo[1];
        if (dx * dx + dz * dz < 0.04f * 0.04f) {
            idx[n] = i;
            memcpy(tgt + 3 * n, x + 3 * i, 3 * sizeof(float));
            n++;
        }
    }
    return n;
}

/* The largest displacement from the rest shape of the unpinned drawn vertices within `radius` of
 * the first pin (the corner's neighbourhood, which only the coarse pins hold up). */
static double near_corner_drop(const res_scene *s, const weft_lod_garment *g, const uint32_t *idx, uint32_t n,
                               float radius)
{
    const float *x = weft_lod_garment_positions(g), *r = s->fine->positions, *c = r + 3 * (size_t)idx[0];
    double worst = 0.0;
    for (uint32_t i = 0; i < s->fine->vertex_count; ++i) {
        bool pinned = false;
        for (uint32_t k = 0; k < n; ++k) {
            pinned |= idx[k] == i;
        }
        const float dx = r[3 * i] - c[0], dz = r[3 * i + 2] - c[2];
        if (!pinned && dx * dx + dz * dz < radius * radius) {
            worst = fmax(worst, (double)r[3 * i + 1] - x[3 * i + 1]);
        }
    }
    return worst;
}

/* The largest distance of the pinned drawn vertices from their targets. */
static double pin_error(const weft_lod_garment *g, const uint32_t *idx, const float *tgt, uint32_t n)
{
    const float *x = weft_lod_garment_positions(g);
    double worst = 0.0;
    for (uint32_t k = 0; k < n; ++k) {
        const float *p = x + 3 * (size_t)idx[k];
        const double dx = p[0] - tgt[3 * k], dy = p[1] - tgt[3 * k + 1], dz = p[2] - tgt[3 * k + 2];
        worst = fmax(worst, sqrt(dx * dx + dy * dy + dz * dz));
    }
    return worst;
}

/* Pins at a resolution level: set there, or carried by a switch onto it, a pinned corner stays
 * within a few mm (the coarse mesh's pins sit at the drawn targets; the drawn corner is mapped
 * from them) while the free corner falls; back at the fine level they hold exactly; bad pins at
 * a coarse level fail and leave the pins in use. */
static void test_resolution_pins(void)
{
    res_scene s;
    if (!scene_make(&s)) {
        scene_free(&s);
        return;
    }
    const uint32_t N = s.fine->vertex_count;
    uint32_t *idx = malloc(N * sizeof(uint32_t));
    float *tgt = malloc((size_t)N * 3 * sizeof(float));
    const uint32_t n = idx && tgt ? corner_pins(&s, idx, tgt) : 0;
    CHECK_MSG(n >= 4 && n < 64, "%u corner vertices", n);
    static const char *const starts[] = {"xpbd-4-quarter", "xpbd-4"};
    for (int run = 0; run < 2 && n > 0; ++run) {
        weft_lod_garment *g = NULL;
        CHECK_RESULT(make(&s, starts[run], 8, true, &g), WEFT_OK);
        if (!g) {
            continue;
        }
        CHECK_RESULT(weft_lod_garment_set_pins(g, idx, tgt, n), WEFT_OK);
        if (run == 1) { /* pinned at the fine level, then switched onto the coarse mesh */
            CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4-quarter")), WEFT_OK);
        }
        const uint32_t coarse_pins = weft_garment_pin_count(weft_lod_garment_current(g));
        bool ok = true;
        for (uint32_t f = 0; ok && f < 20; ++f) {
            ok = step(&s, g, f);
        }
        const double held = pin_error(g, idx, tgt, n), near = near_corner_drop(&s, g, idx, n, 0.06f);
        /* The opposite corner of the sheet (the last vertex) falls freely. */
        const double fell = s.fine->positions[3 * (N - 1) + 1] - weft_lod_garment_positions(g)[3 * (N - 1) + 1];
        printf("pins at the coarse level (%s): %u drawn pins -> %u coarse, corner held within %.2f mm, its 6 cm "
               "neighbourhood dropped %.1f mm, free corner fell %.1f cm\n",
               run == 0 ? "set there" : "carried by a switch", n, coarse_pins, held * 1e3, near * 1e3, fell * 1e2);
        CHECK_MSG(coarse_pins > 0 && coarse_pins <= n, "%u coarse pins for %u drawn ones", coarse_pins, n);
        CHECK_MSG(held == 0.0, "pinned corner moved %.4g m at the coarse level", held);
        CHECK_MSG(near < 0.25 * fell, "the corner's neighbourhood dropped %.4g m (free corner %.4g m): the coarse "
                  "pins do not hold it", near, fell);
        CHECK_MSG(fell > 0.05, "the free corner fell only %.4g m: the scene tests nothing", fell);
        /* Bad pins fail and leave the pins in use. */
        uint32_t bad_idx = N;
        CHECK_RESULT(weft_lod_garment_set_pins(g, &bad_idx, tgt, 1), WEFT_ERROR_INVALID_ARGUMENT);
        float nan_tgt[3] = {0.0f, NAN, 0.0f};
        CHECK_RESULT(weft_lod_garment_set_pins(g, idx, nan_tgt, 1), WEFT_ERROR_NOT_FINITE);
        CHECK_RESULT(weft_lod_garment_set_pins(g, idx, tgt, N + 1), WEFT_ERROR_SIZE_MISMATCH);
        CHECK_EQ_INT(weft_garment_pin_count(weft_lod_garment_current(g)), coarse_pins);
        /* Back to the fine mesh: the drawn pins carry over and hold exactly after a step. */
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4")), WEFT_OK);
        ok = ok && step(&s, g, 20);
        if (ok) {
            CHECK_MSG(pin_error(g, idx, tgt, n) == 0.0, "fine-level pins off by %g m", pin_error(g, idx, tgt, n));
        }
        /* Cleared at the coarse level, nothing is pinned there. */
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4-quarter")), WEFT_OK);
        CHECK_RESULT(weft_lod_garment_set_pins(g, NULL, NULL, 0), WEFT_OK);
        CHECK_EQ_INT(weft_garment_pin_count(weft_lod_garment_current(g)), 0);
        weft_lod_garment_destroy(g);
    }
    free(idx);
    free(tgt);
    scene_free(&s);
}

/* Stepping the current (coarse) garment directly, as a batched host does, then syncing, draws the
 * same positions as weft_lod_garment_step; a sync without a step changes nothing. */
static void test_resolution_sync(void)
{
    res_scene s;
    if (!scene_make(&s)) {
        scene_free(&s);
        return;
    }
    const size_t nx = (size_t)s.fine->vertex_count * 3 * sizeof(float);
    weft_lod_garment *a = NULL, *b = NULL;
    CHECK_RESULT(make(&s, "xpbd-4-quarter", 8, true, &a), WEFT_OK);
    CHECK_RESULT(make(&s, "xpbd-4-quarter", 8, true, &b), WEFT_OK);
    for (uint32_t f = 0; a && b && f < 4; ++f) {
        CHECK(step(&s, a, f));
        CHECK_RESULT(weft_lod_garment_set_collider(b, s.moved), WEFT_OK); /* step() left frame f+1's box */
        weft_garment *cur = weft_lod_garment_current(b);
        CHECK_RESULT(weft_garments_step(&cur, 1), WEFT_OK);
        CHECK_RESULT(weft_lod_garment_sync(b), WEFT_OK);
        CHECK_RESULT(weft_lod_garment_sync(b), WEFT_OK); /* nothing stepped since: no-op */
        CHECK_MSG(memcmp(weft_lod_garment_positions(a), weft_lod_garment_positions(b), nx) == 0,
                  "batched step + sync drew different positions at frame %u", f);
    }
    CHECK_RESULT(weft_lod_garment_sync(NULL), WEFT_ERROR_INVALID_ARGUMENT);
    weft_lod_garment_destroy(a);
    weft_lod_garment_destroy(b);
    scene_free(&s);
}

/* A level with tethers (lod.csv tether_cm): switched to mid-drape, it binds the garment to the box
 * as it is now, so every vertex then stays within 2 cm of where the switch left it plus the box's
 * later slide (the box only translates), and the switch does not pop. */
static void test_tethered_level_binds_at_switch(void)
{
    res_scene s;
    if (!scene_make(&s)) {
        scene_free(&s);
        return;
    }
    double jump = 0, normal = 0;
    if (measure(&s, "xpbd-4", "xpbd-4-tethered", 8, &jump, &normal)) {
        printf("xpbd-4 -> xpbd-4-tethered at %u: jump %6.2f mm / normal %6.2f mm = %.2f\n", SWITCH_AT, jump * 1e3,
               normal * 1e3, jump / normal);
        CHECK_MSG(jump <= POP_BOUND * normal + POP_FLOOR_M, "jump %.4g m over %.2f x normal %.4g m", jump, POP_BOUND,
                  normal);
    }
    const uint32_t N = s.fine->vertex_count;
    const size_t nx = (size_t)N * 3 * sizeof(float);
    weft_lod_garment *g = NULL;
    CHECK_RESULT(make(&s, "xpbd-4", 8, false, &g), WEFT_OK);
    for (uint32_t f = 0; g && f < SWITCH_AT; ++f) {
        CHECK(step(&s, g, f));
    }
    float *at = malloc(nx);
    if (g && at) {
        memcpy(at, weft_lod_garment_positions(g), nx);
        CHECK_RESULT(weft_lod_garment_switch(g, level_of(&s, "xpbd-4-tethered")), WEFT_OK);
        double worst = 0.0;
        for (uint32_t f = SWITCH_AT; f < SWITCH_AT + 10; ++f) {
            CHECK(step(&s, g, f));
            const double slide = 0.6 * (double)(f + 1 - SWITCH_AT) / 60.0; /* box motion since the switch */
            const float *x = weft_lod_garment_positions(g);
            for (uint32_t i = 0; i < N; ++i) {
                double dx = x[3 * i] - (at[3 * i] + slide), dy = x[3 * i + 1] - at[3 * i + 1],
                       dz = x[3 * i + 2] - at[3 * i + 2];
                worst = fmax(worst, sqrt(dx * dx + dy * dy + dz * dz));
            }
        }
        CHECK_MSG(worst <= 0.02 + 1e-4, "a vertex ended %g m from its tether target (radius 0.02 m)", worst);
    }
    free(at);
    weft_lod_garment_destroy(g);
    scene_free(&s);
}

TEST_MAIN(TEST_CASE(test_resolution_switch_without_pop), TEST_CASE(test_resolution_state_and_failures),
          TEST_CASE(test_resolution_pins), TEST_CASE(test_resolution_sync), TEST_CASE(test_tethered_level_binds_at_switch))
