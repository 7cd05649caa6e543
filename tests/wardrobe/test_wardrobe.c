/* Garments and sheets: counts per resolution, manifold-with-boundary topology, triangle
 * quality, clearance from the avatar's skin (an independent mesh distance test), no
 * intersections, weights, cross-resolution consistency and bad input. */
#include "test.h"

#include "../body/mesh_check.h"
#include "body/mesh.h"
#include "core/core.h"
#include "weft.h"
#include "weft/body.h"

static weft_context *g_ctx;
static weft_body *g_body;
static mc_grid g_grid; /* body triangles */

static void release_all(void)
{
    if (g_body) {
        mc_grid_free(&g_grid);
    }
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
    g_body = NULL;
    g_ctx = NULL;
}

/* The context, and the default avatar unless only sheets are needed. */
static void setup_for(bool need_body)
{
    if (!g_ctx) {
        /* ctest runs one case per process (see CMakeLists.txt): free at exit either way. */
        atexit(release_all);
        weft_context_def def = weft_default_context_def();
        CHECK_RESULT(weft_context_create(&def, &g_ctx), WEFT_OK);
    }
    if (!need_body || g_body || !g_ctx) {
        return;
    }
    weft_avatar_def ad = weft_default_avatar_def();
    CHECK_RESULT(weft_avatar_create(g_ctx, &ad, &g_body), WEFT_OK);
    if (g_body) {
        mc_grid_build(&g_grid, weft_body_rest_vertices(g_body), weft_body_vertex_count(g_body), weft_body_triangles(g_body),
                      weft_body_triangle_count(g_body), 0.03f);
    }
}

typedef struct expect {
    weft_cloth_kind kind;
    int64_t euler;       /* 2 - 2 * genus - holes */
    float min_angle;     /* degrees */
} expect;

static const expect g_expect[] = {
    {WEFT_CLOTH_TSHIRT, -2, 8.0f}, /* neck, hem, two sleeves */
    {WEFT_CLOTH_SKIRT, 0, 20.0f},  /* waist and hem */
    {WEFT_CLOTH_DRESS, 0, 20.0f},
    {WEFT_CLOTH_SHEET, 1, 40.0f},
    {WEFT_CLOTH_SHEET_IRREGULAR, 1, 15.0f},
};

static void setup(void) { setup_for(true); }

static weft_cloth_mesh *make(weft_cloth_kind kind, weft_cloth_resolution res)
{
    weft_cloth_def def = weft_default_cloth_def(kind);
    def.resolution = res;
    weft_cloth_mesh *m = NULL;
    double t0 = weft__now_ms();
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, g_body, &m), WEFT_OK);
    if (m) {
        printf("%-16s %-3s %6u vertices %6u triangles %7.0f ms\n", weft_cloth_kind_name(kind), weft_cloth_resolution_name(res),
               m->vertex_count, m->triangle_count, weft__now_ms() - t0);
    }
    return m;
}

static void check_mesh(const weft_cloth_mesh *m, const expect *e, uint32_t target)
{
    CHECK_MSG(m->vertex_count > 0.85 * target && m->vertex_count < 1.15 * target, "%s: %u vertices for %u",
              weft_cloth_kind_name(m->kind), m->vertex_count, target);
    weft__mesh_topology topo;
    CHECK_RESULT(weft__mesh_topology_of(g_ctx, m->positions, m->vertex_count, m->triangles, m->triangle_count, &topo), WEFT_OK);
    CHECK_EQ_INT(topo.nonmanifold_edges, 0);
    CHECK_EQ_INT(topo.nonmanifold_vertices, 0);
    CHECK_EQ_INT(topo.misoriented_edges, 0);
    CHECK_EQ_INT(topo.components, 1);
    CHECK_EQ_INT(topo.euler, e->euler);
    CHECK(topo.boundary_edges > 0);
    CHECK_MSG(topo.min_angle_deg >= e->min_angle, "%s: min angle %.2f < %.1f", weft_cloth_kind_name(m->kind),
              (double)topo.min_angle_deg, (double)e->min_angle);
    CHECK(weft__all_finite(m->positions, (size_t)m->vertex_count * 3));
    CHECK(weft__all_finite(m->uvs, (size_t)m->vertex_count * 2));
    if (m->weights) {
        double worst = 0;
        for (uint32_t i = 0; i < m->vertex_count; ++i) {
            double s = 0;
            for (int j = 0; j < WEFT_BODY_JOINTS; ++j) {
                s += m->weights[(size_t)i * WEFT_BODY_JOINTS + j];
            }
            worst = fmax(worst, fabs(s - 1));
        }
        CHECK_NEAR(worst, 0.0, 1e-4);
    }
}

/* Every garment vertex outside the body by at least half the clearance, and no garment edge
 * crossing a body triangle. */
static void check_clearance_on(const weft_cloth_mesh *m, const weft_body *body, const mc_grid *grid)
{
    const float *bv = weft_body_rest_vertices(body);
    const uint32_t *bt = weft_body_triangles(body);
    uint32_t bnt = weft_body_triangle_count(body);
    double closest = 1e9;
    uint32_t inside = 0;
    for (uint32_t i = 0; i < m->vertex_count; ++i) {
        double d = mc_signed_distance(grid, bv, bt, bnt, m->positions + 3 * i, 0.1f);
        closest = fmin(closest, d);
        inside += d < 0;
    }
    printf("  %s: closest vertex to the skin %.4f m, inside %u\n", weft_cloth_kind_name(m->kind), closest, inside);
    CHECK_EQ_INT(inside, 0);
    CHECK_MSG(closest >= 0.005, "%s: a vertex is %.4f m from the skin", weft_cloth_kind_name(m->kind), closest);
    uint32_t crossings = 0;
    for (uint32_t f = 0; f < m->triangle_count; ++f) {
        for (int e = 0; e < 3; ++e) {
            const float *p = m->positions + 3 * m->triangles[3 * f + e], *q = m->positions + 3 * m->triangles[3 * f + (e + 1) % 3];
            int lo[3], hi[3];
            for (int a = 0; a < 3; ++a) {
                lo[a] = mc_clampi((int)floorf((fminf(p[a], q[a]) - grid->lo[a]) / grid->cell), 0, grid->n[a] - 1);
                hi[a] = mc_clampi((int)floorf((fmaxf(p[a], q[a]) - grid->lo[a]) / grid->cell), 0, grid->n[a] - 1);
            }
            for (int z = lo[2]; z <= hi[2]; ++z) {
                for (int y = lo[1]; y <= hi[1]; ++y) {
                    for (int x = lo[0]; x <= hi[0]; ++x) {
                        size_t c = (size_t)x + (size_t)grid->n[0] * ((size_t)y + (size_t)grid->n[1] * (size_t)z);
                        for (uint32_t k = grid->start[c]; k < grid->start[c + 1]; ++k) {
                            const uint32_t *t = bt + 3 * grid->items[k];
                            crossings += mc_segment_hits_triangle(p, q, bv + 3 * t[0], bv + 3 * t[1], bv + 3 * t[2]);
                        }
                    }
                }
            }
        }
    }
    CHECK_EQ_INT(crossings, 0);
    uint32_t self = mc_count_self_intersections(m->positions, m->vertex_count, m->triangles, m->triangle_count, 0.03f);
    CHECK_EQ_INT(self, 0);
}

static void check_clearance(const weft_cloth_mesh *m) { check_clearance_on(m, g_body, &g_grid); }

static double area(const weft_cloth_mesh *m)
{
    double a = 0;
    for (uint32_t f = 0; f < m->triangle_count; ++f) {
        double e1[3], e2[3], n[3];
        mc_sub(m->positions + 3 * m->triangles[3 * f + 1], m->positions + 3 * m->triangles[3 * f], e1);
        mc_sub(m->positions + 3 * m->triangles[3 * f + 2], m->positions + 3 * m->triangles[3 * f], e2);
        mc_cross(e1, e2, n);
        a += 0.5 * sqrt(mc_dot(n, n));
    }
    return a;
}

static void bbox(const weft_cloth_mesh *m, float *lo, float *hi)
{
    for (int a = 0; a < 3; ++a) {
        lo[a] = 1e30f, hi[a] = -1e30f;
    }
    for (uint32_t i = 0; i < m->vertex_count; ++i) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = fminf(lo[a], m->positions[3 * i + a]);
            hi[a] = fmaxf(hi[a], m->positions[3 * i + a]);
        }
    }
}

static void run_kind(weft_cloth_kind kind, int max_res, int clearance_res)
{
    bool garment = kind != WEFT_CLOTH_SHEET && kind != WEFT_CLOTH_SHEET_IRREGULAR;
    setup_for(garment);
    if (garment && !g_body) {
        return;
    }
    const expect *e = &g_expect[kind];
    static const uint32_t targets[4] = {1000, 4000, 16000, 40000};
    double area0 = 0;
    float lo0[3] = {0, 0, 0}, hi0[3] = {0, 0, 0};
    for (int r = 0; r <= max_res; ++r) {
        weft_cloth_mesh *m = make(kind, (weft_cloth_resolution)r);
        if (!m) {
            continue;
        }
        check_mesh(m, e, targets[r]);
        if (r <= clearance_res && m->weights) {
            check_clearance(m);
        }
        /* Every resolution meshes the same cloth: same extent and area. */
        double a = area(m);
        float lo[3], hi[3];
        bbox(m, lo, hi);
        if (r == 0) {
            area0 = a;
            memcpy(lo0, lo, sizeof lo0);
            memcpy(hi0, hi, sizeof hi0);
        } else {
            CHECK_MSG(fabs(a - area0) < 0.04 * area0, "%s: area %.4f at %s vs %.4f at 1k", weft_cloth_kind_name(kind), a,
                      weft_cloth_resolution_name((weft_cloth_resolution)r), area0);
            for (int k = 0; k < 3; ++k) {
                CHECK_NEAR(lo[k], lo0[k], 0.025);
                CHECK_NEAR(hi[k], hi0[k], 0.025);
            }
        }
        if (m->weights) {
            /* The LBS placement of a posed body: finite, moves with the body. */
            weft_motion_def walk = weft_default_motion_def(WEFT_MOTION_WALK);
            weft_pose pose;
            CHECK_RESULT(weft_motion_sample(&walk, 0.3, &pose), WEFT_OK);
            float *out = malloc((size_t)m->vertex_count * 3 * sizeof(float));
            CHECK_RESULT(weft_body_skin_points(g_body, &pose, m->positions, m->weights, m->vertex_count, out), WEFT_OK);
            CHECK(weft__all_finite(out, (size_t)m->vertex_count * 3));
            free(out);
        }
        weft_cloth_destroy(m);
    }
}

static void test_tshirt(void) { run_kind(WEFT_CLOTH_TSHIRT, 2, 1); }
static void test_skirt(void) { run_kind(WEFT_CLOTH_SKIRT, 3, 1); }
static void test_dress(void) { run_kind(WEFT_CLOTH_DRESS, 3, 1); }
static void test_square_sheet(void) { run_kind(WEFT_CLOTH_SHEET, 3, -1); }
static void test_irregular_sheet(void) { run_kind(WEFT_CLOTH_SHEET_IRREGULAR, 3, -1); }

static void test_sheet_geometry(void)
{
    setup_for(false);
    weft_cloth_def def = weft_default_cloth_def(WEFT_CLOTH_SHEET);
    def.resolution = WEFT_CLOTH_RES_1K;
    def.size = 0.9f;
    def.height = 1.2f;
    weft_cloth_mesh *m = NULL;
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, NULL, &m), WEFT_OK);
    if (!m) {
        return;
    }
    CHECK_EQ_INT(m->vertex_count, 1024); /* 32 x 32, as MeshGraphNet's square_1024 */
    CHECK(m->weights == NULL);
    float lo[3], hi[3];
    bbox(m, lo, hi);
    CHECK_NEAR(hi[0] - lo[0], 0.9, 1e-5);
    CHECK_NEAR(hi[2] - lo[2], 0.9, 1e-5);
    CHECK_NEAR(lo[1], 1.2, 1e-6);
    CHECK_NEAR(hi[1], 1.2, 1e-6);
    CHECK_NEAR(area(m), 0.81, 1e-4);
    for (uint32_t f = 0; f < m->triangle_count; ++f) {
        double e1[3], e2[3], n[3];
        mc_sub(m->positions + 3 * m->triangles[3 * f + 1], m->positions + 3 * m->triangles[3 * f], e1);
        mc_sub(m->positions + 3 * m->triangles[3 * f + 2], m->positions + 3 * m->triangles[3 * f], e2);
        mc_cross(e1, e2, n);
        CHECK(n[1] > 0); /* faces +Y */
    }
    weft_cloth_destroy(m);
}

/* Garments fitted to other shapes: a tall heavy body (thick neck and arms next to the
 * collar and the dress top) and a short slim one. */
static void test_other_bodies(void)
{
    setup_for(false);
    static const float shapes[2][5] = {{1.90f, 1.3f, 1.2f, 1.2f, 0.55f}, {1.55f, 0.75f, 0.85f, 0.85f, 0.45f}};
    for (int sidx = 0; sidx < 2; ++sidx) {
        weft_avatar_def ad = weft_default_avatar_def();
        ad.height = shapes[sidx][0];
        ad.girth = shapes[sidx][1];
        ad.hip_width = shapes[sidx][2];
        ad.shoulder_width = shapes[sidx][3];
        ad.leg_fraction = shapes[sidx][4];
        weft_body *body = NULL;
        CHECK_RESULT(weft_avatar_create(g_ctx, &ad, &body), WEFT_OK);
        if (!body) {
            continue;
        }
        mc_grid grid;
        mc_grid_build(&grid, weft_body_rest_vertices(body), weft_body_vertex_count(body), weft_body_triangles(body),
                      weft_body_triangle_count(body), 0.03f);
        for (int k = 0; k < 3; ++k) {
            weft_cloth_def def = weft_default_cloth_def((weft_cloth_kind)k);
            def.resolution = WEFT_CLOTH_RES_1K;
            weft_cloth_mesh *m = NULL;
            CHECK_RESULT(weft_cloth_create(g_ctx, &def, body, &m), WEFT_OK);
            if (m) {
                check_mesh(m, &g_expect[k], 1000);
                check_clearance_on(m, body, &grid);
                weft_cloth_destroy(m);
            }
        }
        mc_grid_free(&grid);
        weft_body_destroy(body);
    }
}

static void test_bad_input(void)
{
    setup();
    weft_cloth_mesh *m = (weft_cloth_mesh *)(uintptr_t)0x1;
    weft_cloth_def def = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, NULL, &m), WEFT_ERROR_UNSUPPORTED);
    def.clearance = NAN;
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, g_body, &m), WEFT_ERROR_NOT_FINITE);
    def = weft_default_cloth_def(WEFT_CLOTH_SHEET);
    def.target_vertices = 50;
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, NULL, &m), WEFT_ERROR_INVALID_ARGUMENT);
    def = weft_default_cloth_def(WEFT_CLOTH_COUNT);
    CHECK_RESULT(weft_cloth_create(g_ctx, &def, NULL, &m), WEFT_ERROR_INVALID_ARGUMENT);
    weft_cloth_def raw;
    memset(&raw, 0, sizeof raw);
    CHECK_RESULT(weft_cloth_create(g_ctx, &raw, NULL, &m), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(m == (weft_cloth_mesh *)(uintptr_t)0x1);
    weft_cloth_kind k;
    CHECK_RESULT(weft_cloth_kind_from_name("dress", &k), WEFT_OK);
    CHECK_EQ_INT(k, WEFT_CLOTH_DRESS);
    CHECK_RESULT(weft_cloth_kind_from_name("kilt", &k), WEFT_ERROR_INVALID_ARGUMENT);
    weft_cloth_resolution r;
    CHECK_RESULT(weft_cloth_resolution_from_name("16k", &r), WEFT_OK);
    CHECK_EQ_INT(r, WEFT_CLOTH_RES_16K);
}

TEST_MAIN(TEST_CASE(test_tshirt), TEST_CASE(test_skirt), TEST_CASE(test_dress), TEST_CASE(test_square_sheet),
          TEST_CASE(test_irregular_sheet), TEST_CASE(test_sheet_geometry), TEST_CASE(test_other_bodies), TEST_CASE(test_bad_input))
