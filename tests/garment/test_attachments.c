/* Long-range attachments (weft_garment_def.attachments): every vertex ends the step within
 * (1 + slack) x its rest path length of its anchor's pin target, the anchor being the pinned
 * vertex nearest along the rest edges; vertices already inside are not moved; anchors follow a
 * changed pin list; cloth with no pin in its piece is free; the bound holds with a solver and
 * CCD; instances of one asset keep their own anchors; bad slack is refused. */
#include "../xpbd/scene.h"
#include "test.h"

#include <math.h>
#include <string.h>

#define NX 9u  /* columns: the pinned top row is j = 0 */
#define NZ 13u /* rows */

static weft_garment_def sheet_def(const test_mesh *m, weft_method method)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = method;
    gd.substeps = 5;
    gd.ccd.enabled = false;
    gd.rest_positions = m->pos;
    gd.vertex_count = m->nv;
    gd.triangles = m->tris;
    gd.triangle_count = m->nt;
    gd.attachments.enabled = true;
    return gd;
}

/* The top row's indices and its rest positions moved by (dx, dy, dz). */
static void top_row(const test_mesh *m, float dx, float dy, float dz, uint32_t *idx, float *targets)
{
    for (uint32_t i = 0; i < NX; ++i) {
        idx[i] = i;
        targets[3 * i] = m->pos[3 * i] + dx;
        targets[3 * i + 1] = m->pos[3 * i + 1] + dy;
        targets[3 * i + 2] = m->pos[3 * i + 2] + dz;
    }
}

static double dist3(const float *a, const float *b)
{
    double e2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double e = (double)a[k] - (double)b[k];
        e2 += e * e;
    }
    return sqrt(e2);
}

/* Largest excess over the bound of the grid: vertex (i, j) within (1 + slack) j h of pin i. */
static double worst_excess(const test_mesh *m, const float *x, const float *targets, float slack)
{
    const double h = (double)m->pos[3 * NX + 2] - (double)m->pos[2];
    double worst = -INFINITY;
    for (uint32_t j = 0; j < NZ; ++j) {
        for (uint32_t i = 0; i < NX; ++i) {
            const double d = dist3(x + 3 * (j * NX + i), targets + 3 * i);
            worst = fmax(worst, d - (1.0 + slack) * (double)j * h);
        }
    }
    return worst;
}

static void test_attachments_bound_a_pulled_sheet(void)
{
    weft_context *ctx = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh m = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    weft_garment_def gd = sheet_def(&m, WEFT_METHOD_EXTERNAL);
    gd.attachments.slack = 0.1f;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    uint32_t idx[NX];
    float targets[3 * NX];
    /* The pins jump 2 m away while the host hands back the sheet where it was. */
    top_row(&m, 2.0f, 0.5f, -1.0f, idx, targets);
    CHECK_RESULT(weft_garment_set_pins(g, idx, targets, NX), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, m.pos), WEFT_OK);
    const float *x = weft_garment_positions(g);
    const double excess = worst_excess(&m, x, targets, 0.1f);
    CHECK_MSG(excess <= 1e-5, "a vertex %g m beyond its attachment", excess);
    for (uint32_t i = 0; i < NX; ++i) {
        CHECK(memcmp(x + 3 * i, targets + 3 * i, 3 * sizeof(float)) == 0); /* pins on their targets */
    }
    /* every vertex was 2.3 m from its pin, farther than 1.1 x 0.6 m: all moved, each onto its
     * sphere (the farthest row exactly at the bound) */
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, NX * NZ - NX);
    const double h = 0.6 / (NZ - 1);
    for (uint32_t i = 0; i < NX; ++i) {
        CHECK_NEAR(dist3(x + 3 * ((NZ - 1) * NX + i), targets + 3 * i), 1.1 * (NZ - 1) * h, 1e-5);
    }

    /* A cloth inside its bounds is left as it is, bit for bit: the sheet hanging straight down
     * 5 % longer than at rest. */
    float *hang = malloc(sizeof(float) * 3 * m.nv);
    top_row(&m, 0.0f, 0.0f, 0.0f, idx, targets);
    for (uint32_t j = 0; j < NZ; ++j) {
        for (uint32_t i = 0; i < NX; ++i) {
            float *p = hang + 3 * (j * NX + i);
            p[0] = targets[3 * i];
            p[1] = targets[3 * i + 1] - 1.05f * (float)(j * h);
            p[2] = targets[3 * i + 2];
        }
    }
    CHECK_RESULT(weft_garment_set_pins(g, idx, targets, NX), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, hang), WEFT_OK);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, 0);
    CHECK(memcmp(weft_garment_positions(g), hang, sizeof(float) * 3 * m.nv) == 0);

    /* 15 % longer: every vertex below the top row goes to 1.1 x its depth, straight below its pin. */
    for (uint32_t j = 0; j < NZ; ++j) {
        for (uint32_t i = 0; i < NX; ++i) {
            hang[3 * (j * NX + i) + 1] = targets[3 * i + 1] - 1.15f * (float)(j * h);
        }
    }
    CHECK_RESULT(weft_garment_constrain(g, hang), WEFT_OK);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, NX * NZ - NX);
    x = weft_garment_positions(g);
    for (uint32_t j = 1; j < NZ; ++j) {
        const float *p = x + 3 * (j * NX + 4);
        CHECK_NEAR(targets[3 * 4 + 1] - p[1], 1.1 * j * h, 1e-5);
        CHECK_NEAR(p[0], targets[3 * 4], 1e-6);
    }
    free(hang);
    weft_garment_destroy(g);
    test_mesh_free(&m);
    weft_context_destroy(ctx);
}

static void test_attachments_follow_the_pins(void)
{
    weft_context *ctx = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh m = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    weft_garment_def gd = sheet_def(&m, WEFT_METHOD_EXTERNAL);
    gd.attachments.slack = 0.0f;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    /* Nothing pinned: nothing attached, however far the host moves the cloth. */
    float *far = malloc(sizeof(float) * 3 * m.nv);
    for (uint32_t q = 0; q < 3 * m.nv; ++q) {
        far[q] = m.pos[q] + (q % 3 == 1 ? 3.0f : 0.0f);
    }
    CHECK_RESULT(weft_garment_constrain(g, far), WEFT_OK);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, 0);
    /* One corner pinned (vertex 0) at its rest place: with slack 0 each vertex ends within its
     * rest edge-path length of it, which on this grid is at least its straight rest distance. */
    const uint32_t corner = 0;
    CHECK_RESULT(weft_garment_set_pins(g, &corner, m.pos, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, far), WEFT_OK);
    const float *x = weft_garment_positions(g);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, m.nv - 1);
    const double hx = 0.4 / (NX - 1), hz = 0.6 / (NZ - 1);
    for (uint32_t j = 0; j < NZ; ++j) {
        for (uint32_t i = 0; i < NX; ++i) {
            /* the shortest path on this grid's edges is at most the path along the axes */
            const double bound = hx * i + hz * j;
            const double straight = sqrt(hx * hx * i * i + hz * hz * j * j);
            const double d = dist3(x + 3 * (j * NX + i), m.pos);
            CHECK_MSG(d <= bound + 1e-5 && d >= straight - 1e-5, "vertex (%u, %u) %g m from the corner, not in [%g, %g]",
                      i, j, d, straight, bound);
        }
    }
    /* Pins cleared: free again. */
    CHECK_RESULT(weft_garment_set_pins(g, NULL, NULL, 0), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, far), WEFT_OK);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, 0);
    free(far);
    weft_garment_destroy(g);
    test_mesh_free(&m);

    /* Two separate sheets in one garment, pins on the first only: the second is never moved. */
    test_mesh a = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    test_mesh b = test_sheet(NX, NZ, 0.4f, 0.6f, 1.0f, 1.0f, 0.0f);
    test_mesh two = {0};
    two.nv = a.nv + b.nv;
    two.nt = a.nt + b.nt;
    two.pos = malloc(sizeof(float) * 3 * two.nv);
    two.tris = malloc(sizeof(uint32_t) * 3 * two.nt);
    memcpy(two.pos, a.pos, sizeof(float) * 3 * a.nv);
    memcpy(two.pos + 3 * a.nv, b.pos, sizeof(float) * 3 * b.nv);
    memcpy(two.tris, a.tris, sizeof(uint32_t) * 3 * a.nt);
    for (uint32_t q = 0; q < 3 * b.nt; ++q) {
        two.tris[3 * a.nt + q] = b.tris[q] + a.nv;
    }
    gd = sheet_def(&two, WEFT_METHOD_EXTERNAL);
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    uint32_t idx[NX];
    float targets[3 * NX];
    top_row(&two, 0.0f, 2.0f, 0.0f, idx, targets);
    CHECK_RESULT(weft_garment_set_pins(g, idx, targets, NX), WEFT_OK);
    CHECK_RESULT(weft_garment_constrain(g, two.pos), WEFT_OK);
    CHECK_EQ_INT(weft_garment_stats(g).attachment_vertices_clamped, a.nv - NX);
    CHECK(memcmp(weft_garment_positions(g) + 3 * a.nv, b.pos, sizeof(float) * 3 * b.nv) == 0);
    weft_garment_destroy(g);
    test_mesh_free(&two);
    test_mesh_free(&b);
    test_mesh_free(&a);
    weft_context_destroy(ctx);
}

/* A solver stepping a hanging sheet whose pins fly sideways 30 cm a frame: without attachments
 * it stretches far past its length; with them it never passes the bound, with CCD too (the
 * attachments' last clamp comes after it). */
static void test_attachments_hold_a_solver(void)
{
    weft_context *ctx = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh m = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    for (int ccd = 0; ccd < 2; ++ccd) {
        weft_garment_def gd = sheet_def(&m, WEFT_METHOD_XPBD_FAST);
        gd.ccd.enabled = ccd != 0;
        gd.attachments.enabled = false;
        weft_garment *loose = NULL, *held = NULL;
        CHECK_RESULT(weft_garment_create(ctx, &gd, &loose), WEFT_OK);
        gd.attachments.enabled = true;
        CHECK_RESULT(weft_garment_create(ctx, &gd, &held), WEFT_OK);
        uint32_t idx[NX];
        float targets[3 * NX];
        double loose_excess = -INFINITY, held_excess = -INFINITY;
        uint32_t clamped = 0;
        for (int f = 1; f <= 12; ++f) {
            top_row(&m, 0.3f * (float)f, 0.0f, 0.0f, idx, targets);
            CHECK_RESULT(weft_garment_set_pins(loose, idx, targets, NX), WEFT_OK);
            CHECK_RESULT(weft_garment_set_pins(held, idx, targets, NX), WEFT_OK);
            CHECK_RESULT(weft_garment_step(loose), WEFT_OK);
            CHECK_RESULT(weft_garment_step(held), WEFT_OK);
            loose_excess = fmax(loose_excess, worst_excess(&m, weft_garment_positions(loose), targets, 0.1f));
            held_excess = fmax(held_excess, worst_excess(&m, weft_garment_positions(held), targets, 0.1f));
            clamped += weft_garment_stats(held).attachment_vertices_clamped;
        }
        CHECK_MSG(loose_excess > 0.1, "ccd %d: the sheet without attachments only %g m past the bound: the scene "
                  "tests nothing", ccd, loose_excess);
        CHECK_MSG(held_excess <= 1e-5, "ccd %d: a vertex %g m past its attachment", ccd, held_excess);
        CHECK(clamped > 0);
        weft_garment_destroy(loose);
        weft_garment_destroy(held);
    }
    test_mesh_free(&m);
    weft_context_destroy(ctx);
}

/* Two instances of one asset with different pins each match a garment of their own, bit for bit. */
static void test_attachments_per_instance(void)
{
    weft_context *ctx = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh m = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    weft_garment_def gd = sheet_def(&m, WEFT_METHOD_EXTERNAL);
    weft_garment_asset *asset = NULL;
    weft_garment *inst[2] = {NULL, NULL}, *own[2] = {NULL, NULL};
    CHECK_RESULT(weft_garment_asset_create(ctx, &gd, &asset), WEFT_OK);
    for (int k = 0; k < 2; ++k) {
        CHECK_RESULT(weft_garment_asset_instance(asset, &inst[k]), WEFT_OK);
        CHECK_RESULT(weft_garment_create(ctx, &gd, &own[k]), WEFT_OK);
    }
    const uint32_t pins[2][2] = {{0, NX - 1}, {NX * (NZ - 1), NX * NZ - 1}}; /* top corners, bottom corners */
    float targets[6];
    for (int f = 0; f < 3; ++f) {
        for (int k = 0; k < 2; ++k) {
            for (int p = 0; p < 2; ++p) {
                memcpy(targets + 3 * p, m.pos + 3 * pins[k][p], 3 * sizeof(float));
                targets[3 * p + 1] += 0.5f * (float)(f + 1);
            }
            CHECK_RESULT(weft_garment_set_pins(inst[k], pins[k], targets, 2), WEFT_OK);
            CHECK_RESULT(weft_garment_set_pins(own[k], pins[k], targets, 2), WEFT_OK);
            CHECK_RESULT(weft_garment_constrain(inst[k], m.pos), WEFT_OK);
            CHECK_RESULT(weft_garment_constrain(own[k], m.pos), WEFT_OK);
            CHECK(weft_garment_stats(inst[k]).attachment_vertices_clamped > 0);
            CHECK(memcmp(weft_garment_positions(inst[k]), weft_garment_positions(own[k]),
                         sizeof(float) * 3 * m.nv) == 0);
        }
        CHECK(memcmp(weft_garment_positions(inst[0]), weft_garment_positions(inst[1]), sizeof(float) * 3 * m.nv) != 0);
    }
    for (int k = 0; k < 2; ++k) {
        weft_garment_destroy(inst[k]);
        weft_garment_destroy(own[k]);
    }
    weft_garment_asset_destroy(asset);
    test_mesh_free(&m);
    weft_context_destroy(ctx);
}

static void test_attachments_bad_input(void)
{
    weft_context *ctx = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh m = test_sheet(NX, NZ, 0.4f, 0.6f, 0.0f, 1.0f, 0.0f);
    weft_garment_def gd = sheet_def(&m, WEFT_METHOD_EXTERNAL);
    const float bad[] = {-0.01f, 10.5f, NAN, INFINITY};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        gd.attachments.slack = bad[k];
        weft_garment *g = NULL;
        CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(g == NULL);
        CHECK(strstr(weft_last_error(), "attachments.slack") != NULL);
    }
    gd.attachments.enabled = false; /* off: the slack is not read */
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    weft_garment_destroy(g);
    CHECK_NEAR(weft_default_garment_def().attachments.slack, 0.1, 1e-7);
    CHECK(!weft_default_garment_def().attachments.enabled);
    test_mesh_free(&m);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_attachments_bound_a_pulled_sheet), TEST_CASE(test_attachments_follow_the_pins),
          TEST_CASE(test_attachments_hold_a_solver), TEST_CASE(test_attachments_per_instance),
          TEST_CASE(test_attachments_bad_input))
