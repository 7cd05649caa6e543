/* Strain limiting (weft_garment_def.strain.limit): after a step that tears the sheet (a pinned
 * corner yanked far away in one frame), no edge is longer than (1 + limit) x rest once the sweeps
 * converge, pins keep their targets, radius-0 tethers stay glued, the contact-aware limit does not
 * drag the cloth lying on the box into it, and bad limits fail at creation. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct strain_scene {
    weft_context *ctx;
    test_mesh sheet, box;
} strain_scene;

static void scene_make(strain_scene *s)
{
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &s->ctx), WEFT_OK);
    s->sheet = test_sheet(10, 10, 0.5f, 0.5f, 0.0f, 0.21f, 0.0f);
    const float lo[3] = {-0.15f, 0.0f, -0.15f}, hi[3] = {0.15f, 0.2f, 0.15f};
    s->box = test_box(lo, hi);
}

static void scene_free(strain_scene *s)
{
    test_mesh_free(&s->box);
    test_mesh_free(&s->sheet);
    weft_context_destroy(s->ctx);
}

static weft_garment_def scene_def(const strain_scene *s)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_XPBD;
    gd.substeps = 1; /* one substep cannot follow the yank: the step itself tears the sheet */
    gd.ccd.enabled = false;  /* the limit acts before CCD; this test checks the limit itself */
    gd.rest_positions = s->sheet.pos;
    gd.vertex_count = s->sheet.nv;
    gd.triangles = s->sheet.tris;
    gd.triangle_count = s->sheet.nt;
    gd.collider_rest_positions = s->box.pos;
    gd.collider_vertex_count = s->box.nv;
    gd.collider_triangles = s->box.tris;
    gd.collider_triangle_count = s->box.nt;
    return gd;
}

/* Largest |length / rest - 1| over the sheet's triangle edges, stretch only. */
static double max_stretch(const strain_scene *s, const float *x)
{
    double worst = 0.0;
    for (uint32_t t = 0; t < s->sheet.nt; ++t) {
        for (int k = 0; k < 3; ++k) {
            uint32_t a = s->sheet.tris[3 * t + k], b = s->sheet.tris[3 * t + (k + 1) % 3];
            double l = 0.0, r = 0.0;
            for (int c = 0; c < 3; ++c) {
                double d = (double)x[3 * a + c] - x[3 * b + c];
                double e = (double)s->sheet.pos[3 * a + c] - s->sheet.pos[3 * b + c];
                l += d * d;
                r += e * e;
            }
            worst = fmax(worst, sqrt(l / r) - 1.0);
        }
    }
    return worst;
}

/* Steps one frame with corner 0 pinned 0.3 m away from where it was. */
static void yank(const strain_scene *s, weft_garment *g)
{
    const uint32_t pin = 0;
    const float target[3] = {s->sheet.pos[0] - 0.3f, s->sheet.pos[1] + 0.1f, s->sheet.pos[2]};
    CHECK_RESULT(weft_garment_set_collider(g, s->box.pos), WEFT_OK);
    CHECK_RESULT(weft_garment_set_pins(g, &pin, target, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    CHECK_MSG(memcmp(weft_garment_positions(g), target, sizeof target) == 0, "the pinned corner left its target");
}

static void test_strain_limit_bounds_the_stretch(void)
{
    strain_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s);
    weft_garment *torn = NULL, *limited = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &torn), WEFT_OK);
    gd.strain.limit = 0.1f;
    gd.strain.iterations = 1000; /* Gauss-Seidel needs many sweeps to drag a whole sheet */
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &limited), WEFT_OK);
    yank(&s, torn);
    yank(&s, limited);
    double torn_max = max_stretch(&s, weft_garment_positions(torn));
    double limited_max = max_stretch(&s, weft_garment_positions(limited));
    CHECK_MSG(torn_max > 0.5, "the yank stretched the sheet only %g: the scene tests nothing", torn_max);
    CHECK_MSG(limited_max <= 0.1 + 1e-3, "an edge is stretched by %g with a 0.1 limit", limited_max);
    CHECK_MSG(weft_garment_stats(limited).strain_limited_edges > 0, "no edge was counted over the limit");
    CHECK_EQ_INT(weft_garment_stats(torn).strain_limited_edges, 0);
    /* The default 8 sweeps do not converge on this yank, but they shorten the worst edge. */
    gd.strain.iterations = weft_default_garment_def().strain.iterations;
    weft_garment *few = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &few), WEFT_OK);
    yank(&s, few);
    double few_max = max_stretch(&s, weft_garment_positions(few));
    CHECK_MSG(few_max < torn_max, "8 sweeps left the worst edge at %g (unlimited %g)", few_max, torn_max);
    weft_garment_destroy(few);
    weft_garment_destroy(torn);
    weft_garment_destroy(limited);
    scene_free(&s);
}

static int cmp_edge(const void *a, const void *b)
{
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

/* The oracle: Gauss-Seidel sweeps over every unique edge (ascending (min, max) pairs) measuring
 * each one, the pinned vertex 0 held, until a sweep finds none over or `sweeps` ran. */
static void sweep_all_edges(const strain_scene *s, float *x, float limit, uint32_t sweeps)
{
    const size_t n = (size_t)s->sheet.nt * 3;
    uint64_t *keys = malloc(n * sizeof *keys);
    for (size_t i = 0; i < n; ++i) {
        const uint32_t a = s->sheet.tris[i], b = s->sheet.tris[i - i % 3 + (i % 3 + 1) % 3];
        keys[i] = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
    }
    qsort(keys, n, sizeof *keys, cmp_edge);
    const float grow = 1.0f + limit;
    for (uint32_t sweep = 0; sweep < sweeps; ++sweep) {
        uint32_t over = 0;
        for (size_t i = 0; i < n; ++i) {
            if (i > 0 && keys[i] == keys[i - 1]) {
                continue;
            }
            const uint32_t a = (uint32_t)(keys[i] >> 32), b = (uint32_t)keys[i];
            const float *ra = s->sheet.pos + 3 * (size_t)a, *rb = s->sheet.pos + 3 * (size_t)b;
            const float r[3] = {ra[0] - rb[0], ra[1] - rb[1], ra[2] - rb[2]};
            const float cap = grow * sqrtf(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
            float *p = x + 3 * (size_t)a, *q = x + 3 * (size_t)b;
            const float d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            const float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (!(len > cap)) {
                continue;
            }
            over++;
            const float wa = a == 0 ? 0.0f : 1.0f, wb = b == 0 ? 0.0f : 1.0f;
            const float sc = (len - cap) / (len * (wa + wb));
            for (int k = 0; k < 3; ++k) {
                const float dp = wa * sc * d[k], dq = -wb * sc * d[k];
                p[k] += dp;
                q[k] += dq;
            }
        }
        if (over == 0) {
            break;
        }
    }
    free(keys);
}

/* The sweeps measure again only the edges that were over or whose ends moved since they were last
 * measured; that changes no bit against sweeping every edge, for few sweeps and for many. */
static void test_strain_limit_equals_every_edge_sweeps(void)
{
    strain_scene s;
    scene_make(&s);
    const uint32_t sweep_counts[3] = {1, 8, 200};
    for (int c = 0; c < 3; ++c) {
        weft_garment_def gd = scene_def(&s);
        weft_garment *torn = NULL, *limited = NULL;
        CHECK_RESULT(weft_garment_create(s.ctx, &gd, &torn), WEFT_OK);
        gd.strain.limit = 0.1f;
        gd.strain.iterations = sweep_counts[c];
        CHECK_RESULT(weft_garment_create(s.ctx, &gd, &limited), WEFT_OK);
        if (!torn || !limited) {
            weft_garment_destroy(torn);
            weft_garment_destroy(limited);
            continue;
        }
        yank(&s, torn);
        yank(&s, limited);
        const size_t n = (size_t)s.sheet.nv * 3;
        float *want = malloc(n * sizeof(float));
        memcpy(want, weft_garment_positions(torn), n * sizeof(float));
        sweep_all_edges(&s, want, 0.1f, sweep_counts[c]);
        CHECK_MSG(memcmp(want, weft_garment_positions(limited), n * sizeof(float)) == 0,
                  "%u sweeps differ from sweeping every edge", sweep_counts[c]);
        CHECK(memcmp(want, weft_garment_positions(torn), n * sizeof(float)) != 0); /* the sweeps moved it */
        free(want);
        weft_garment_destroy(torn);
        weft_garment_destroy(limited);
    }
    scene_free(&s);
}

static void test_strain_limit_keeps_glued_vertices(void)
{
    strain_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s);
    float *radii = malloc(sizeof(float) * s.sheet.nv);
    for (uint32_t i = 0; i < s.sheet.nv; ++i) {
        radii[i] = i >= 90 ? 0.0f : 1.0f; /* the far row glued to the (still) box */
    }
    gd.tethers.distances = radii;
    gd.strain.limit = 0.1f;
    gd.strain.iterations = 50;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_OK);
    yank(&s, g);
    const float *x = weft_garment_positions(g);
    double glue = 0.0;
    for (uint32_t i = 90; i < 100; ++i) {
        for (int k = 0; k < 3; ++k) {
            glue = fmax(glue, fabs((double)x[3 * i + k] - s.sheet.pos[3 * i + k]));
        }
    }
    CHECK_MSG(glue < 5e-6, "the glued row moved %g m under the strain limit", glue);
    free(radii);
    weft_garment_destroy(g);
    scene_free(&s);
}

/* Sheet vertices inside the box (below its top, within its footprint). */
static uint32_t inside_box(const strain_scene *s, const float *x)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < s->sheet.nv; ++i) {
        const float *p = x + 3 * (size_t)i;
        n += fabsf(p[0]) < 0.149f && fabsf(p[2]) < 0.149f && p[1] < 0.2f - 1e-4f;
    }
    return n;
}

/* A corner pulled down past the box's edge: the plain limit drags the sheet lying on the box top
 * down into it; the contact-aware one lets it slide along the top instead. */
static void test_strain_limit_contact_keeps_cloth_out(void)
{
    strain_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s);
    gd.strain.limit = 0.1f;
    gd.strain.iterations = 1000;
    weft_garment *plain = NULL, *aware = NULL, *torn = NULL;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &plain), WEFT_OK);
    gd.strain.contact = 0.02f;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &aware), WEFT_OK);
    gd.strain.limit = 0.0f;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &torn), WEFT_OK);
    const uint32_t pin = 0;
    const float target[3] = {s.sheet.pos[0] - 0.1f, s.sheet.pos[1] - 0.4f, s.sheet.pos[2] - 0.1f};
    weft_garment *all[3] = {plain, aware, torn};
    for (int k = 0; k < 3; ++k) {
        CHECK_RESULT(weft_garment_set_collider(all[k], s.box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_set_pins(all[k], &pin, target, 1), WEFT_OK);
        CHECK_RESULT(weft_garment_step(all[k]), WEFT_OK);
    }
    uint32_t plain_in = inside_box(&s, weft_garment_positions(plain));
    uint32_t aware_in = inside_box(&s, weft_garment_positions(aware));
    CHECK_EQ_INT(inside_box(&s, weft_garment_positions(torn)), 0);
    CHECK_MSG(plain_in > 0, "the plain limit kept the sheet out of the box: the scene tests nothing");
    CHECK_MSG(aware_in == 0, "the contact-aware limit put %u vertices into the box (plain: %u)", aware_in, plain_in);
    double torn_max = max_stretch(&s, weft_garment_positions(torn));
    double aware_max = max_stretch(&s, weft_garment_positions(aware));
    CHECK_MSG(aware_max < 0.5 * torn_max, "the contact-aware limit left the worst edge at %g (unlimited %g)",
              aware_max, torn_max);
    CHECK(weft_garment_stats(aware).strain_limited_edges > 0);
    weft_garment_destroy(plain);
    weft_garment_destroy(aware);
    weft_garment_destroy(torn);
    scene_free(&s);
}

static void test_strain_limit_bad_input(void)
{
    strain_scene s;
    scene_make(&s);
    weft_garment_def gd = scene_def(&s);
    weft_garment *g = NULL;
    const float bad[] = {-0.01f, NAN, INFINITY, 11.0f};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        gd.strain.limit = bad[k];
        CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "strain.limit") != NULL);
    }
    gd.strain.limit = 0.1f;
    gd.strain.iterations = 0;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "strain.iterations") != NULL);
    gd.strain.iterations = 8;
    const float bad_contact[] = {-0.01f, NAN, INFINITY, 1.5f};
    for (size_t k = 0; k < sizeof bad_contact / sizeof bad_contact[0]; ++k) {
        gd.strain.contact = bad_contact[k];
        CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "strain.contact") != NULL);
    }
    gd.strain.contact = 0.01f; /* looks for a collider the garment does not have */
    gd.collider_vertex_count = 0;
    gd.collider_rest_positions = NULL;
    gd.collider_triangles = NULL;
    gd.collider_triangle_count = 0;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_ERROR_NO_COLLIDER);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "strain.contact") != NULL);
    gd = scene_def(&s);
    gd.strain.limit = 0.0f; /* off: the sweep count is not looked at */
    gd.strain.iterations = 0;
    CHECK_RESULT(weft_garment_create(s.ctx, &gd, &g), WEFT_OK);
    weft_garment_destroy(g);
    scene_free(&s);
}

TEST_MAIN(TEST_CASE(test_strain_limit_bounds_the_stretch), TEST_CASE(test_strain_limit_equals_every_edge_sweeps), TEST_CASE(test_strain_limit_keeps_glued_vertices),
          TEST_CASE(test_strain_limit_contact_keeps_cloth_out), TEST_CASE(test_strain_limit_bad_input))
