/* Bad input to the XPBD method, the validator and the sequence generator: clear errors,
 * nothing changed, no crash. */
#include "scene.h"
#include "test.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

static weft_context *ctx_;

static weft_garment_def xpbd_def(const test_mesh *m)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_XPBD;
    gd.ccd.enabled = false;
    gd.rest_positions = m->pos;
    gd.vertex_count = m->nv;
    gd.triangles = m->tris;
    gd.triangle_count = m->nt;
    return gd;
}

static void test_non_manifold(void)
{
    /* Three triangles on one edge (0, 1). */
    float pos[] = {0, 0, 0, 1, 0, 0, 0.5f, 1, 0, 0.5f, -1, 0, 0.5f, 0, 1};
    uint32_t tris[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    test_mesh m = {pos, tris, 5, 3};
    weft_garment_def gd = xpbd_def(&m);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(strstr(weft_last_error(), "non-manifold") != NULL);
    CHECK(g == NULL);
}

static void test_duplicate_triangle(void)
{
    float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t tris[] = {0, 1, 2, 1, 0, 2};
    test_mesh m = {pos, tris, 3, 2};
    weft_garment_def gd = xpbd_def(&m);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(strstr(weft_last_error(), "duplicate") != NULL);
}

static void test_isolated_vertex(void)
{
    float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5};
    uint32_t tris[] = {0, 1, 2};
    test_mesh m = {pos, tris, 4, 1};
    weft_garment_def gd = xpbd_def(&m);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(strstr(weft_last_error(), "no triangle") != NULL);
}

static void test_nan_and_configure(void)
{
    test_mesh m = test_sheet(6, 6, 0.3f, 0.3f, 0, 0.5f, 0);
    weft_garment_def gd = xpbd_def(&m);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    float *before = malloc(sizeof(float) * 3 * m.nv);
    memcpy(before, weft_garment_positions(g), sizeof(float) * 3 * m.nv);
    float *bad = malloc(sizeof(float) * 3 * m.nv);
    memcpy(bad, before, sizeof(float) * 3 * m.nv);
    bad[7] = NAN;
    CHECK_RESULT(weft_garment_set_state(g, bad, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(before, weft_garment_positions(g), sizeof(float) * 3 * m.nv) == 0);
    xpbd_params p = xpbd_default_params();
    p.bound_gamma = 0.6; /* must stay below 0.5 for the non-penetration guarantee */
    CHECK_RESULT(weft__xpbd_configure(g, &p), WEFT_ERROR_INVALID_ARGUMENT);
    p = xpbd_default_params();
    p.poisson_ratio = 0.5;
    CHECK_RESULT(weft__xpbd_configure(g, &p), WEFT_ERROR_INVALID_ARGUMENT);
    p = xpbd_default_params();
    p.youngs_modulus = 2e6;
    CHECK_RESULT(weft__xpbd_configure(g, &p), WEFT_OK);
    CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    free(before);
    free(bad);
    weft_garment_destroy(g);
    test_mesh_free(&m);
}

static void test_inverted_initial_state(void)
{
    /* Start with every other vertex pushed through its neighbours (inverted, crumpled
     * triangles): the solver stays finite and the membrane restores the sheet. */
    test_mesh m = test_sheet(8, 8, 0.4f, 0.4f, 0, 0.5f, 0);
    float *init = malloc(sizeof(float) * 3 * m.nv);
    memcpy(init, m.pos, sizeof(float) * 3 * m.nv);
    for (uint32_t i = 0; i < m.nv; i += 2) {
        init[3 * i] += 0.08f;
    }
    weft_garment_def gd = xpbd_def(&m);
    gd.initial_positions = init;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx_, &gd, &g), WEFT_OK);
    xpbd_params p = xpbd_default_params();
    p.self_collision = false; /* the crumpled start is self-intersecting by construction */
    CHECK_RESULT(weft__xpbd_configure(g, &p), WEFT_OK);
    for (int f = 0; f < 60; ++f) {
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
    }
    xpbd_frame_stats st = weft__xpbd_last_stats(g);
    CHECK(isfinite(st.elastic_energy));
    CHECK_MSG(st.max_strain < 0.05, "max strain after recovery %g", st.max_strain);
    free(init);
    weft_garment_destroy(g);
    test_mesh_free(&m);
}

static void test_validator_bad_input(void)
{
    uint32_t tris[] = {0, 1, 7};
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx_, tris, 1, 3, NULL, 0, 0, &v), WEFT_ERROR_DEGENERATE_MESH);
    CHECK_RESULT(weft_sim_validator_create(ctx_, NULL, 1, 3, NULL, 0, 0, &v), WEFT_ERROR_INVALID_ARGUMENT);
    uint32_t ok_tris[] = {0, 1, 2};
    CHECK_RESULT(weft_sim_validator_create(ctx_, ok_tris, 1, 3, NULL, 0, 0, &v), WEFT_OK);
    float a[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, b[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    weft_sim_validation res;
    CHECK_RESULT(weft_sim_validator_check(v, a, b, NULL, NULL, &res), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_sim_validator_check(v, a, a, NULL, NULL, &res), WEFT_OK);
    CHECK_EQ_INT(res.ccd_hits + res.intersection_hits, 0);
    weft_sim_validator_destroy(v);
}

/* A small sheet moves from beside a box to above it. Its chord cuts through the box's upper
 * corner, but a two-piece path (up, then across) goes around it: check() rejects the chord,
 * check_path() accepts the path; a path through the box is still caught. */
static void test_validator_path(void)
{
    test_mesh sheet = test_sheet(3, 3, 0.04f, 0.04f, 0.0f, 0.0f, 0.0f);
    const float lo[3] = {-0.1f, -0.1f, -0.1f}, hi[3] = {0.1f, 0.1f, 0.1f};
    test_mesh box = test_box(lo, hi);
    const uint32_t n = sheet.nv;
    float *path = malloc(sizeof(float) * 3 * n * 3);
    const float at[3][2] = {{0.2f, -0.05f}, {0.2f, 0.2f}, {0.0f, 0.2f}}; /* (x, y) of the sheet centre */
    for (int k = 0; k < 3; ++k) {
        for (uint32_t i = 0; i < n; ++i) {
            path[(size_t)k * 3 * n + 3 * i + 0] = sheet.pos[3 * i + 0] + at[k][0];
            path[(size_t)k * 3 * n + 3 * i + 1] = sheet.pos[3 * i + 1] + at[k][1];
            path[(size_t)k * 3 * n + 3 * i + 2] = sheet.pos[3 * i + 2];
        }
    }
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx_, sheet.tris, sheet.nt, n, box.tris, box.nt, box.nv, &v), WEFT_OK);
    weft_sim_validation res;
    CHECK_RESULT(weft_sim_validator_check(v, path, path + 6 * n, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.ccd_hits > 0);
    CHECK_EQ_INT(res.motions_checked, 1);
    CHECK_RESULT(weft_sim_validator_check_path(v, path, 3, box.pos, box.pos, &res), WEFT_OK);
    CHECK_EQ_INT(res.ccd_hits + res.intersection_hits, 0);
    CHECK_EQ_INT(res.motions_checked, 2);
    /* Through the box: the middle state sits inside it. */
    for (uint32_t i = 0; i < n; ++i) {
        path[3 * n + 3 * i + 0] = sheet.pos[3 * i + 0];
        path[3 * n + 3 * i + 1] = 0.05f;
    }
    CHECK_RESULT(weft_sim_validator_check_path(v, path, 3, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.ccd_hits > 0);
    /* Bad input: one state, NaN, a missing collider. */
    weft_sim_validation keep = res;
    CHECK_RESULT(weft_sim_validator_check_path(v, path, 1, box.pos, box.pos, &res), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_sim_validator_check_path(v, path, 3, NULL, box.pos, &res), WEFT_ERROR_INVALID_ARGUMENT);
    path[3 * n + 4] = NAN;
    CHECK_RESULT(weft_sim_validator_check_path(v, path, 3, box.pos, box.pos, &res), WEFT_ERROR_NOT_FINITE);
    CHECK_EQ_INT(res.ccd_hits, keep.ccd_hits);
    free(path);
    weft_sim_validator_destroy(v);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
}

/* Body parts: a sheet falling into a box, and one resting cut by the box's faces, are certified
 * when the sheet's vertices do not collide with the box's part, caught when they do; bad calls
 * are refused and leave the parts as they were. */
static void test_validator_parts(void)
{
    test_mesh sheet = test_sheet(5, 5, 0.2f, 0.2f, 0, 0.3f, 0);
    const float lo[3] = {-0.3f, 0.0f, -0.3f}, hi[3] = {0.3f, 0.2f, 0.3f};
    test_mesh box = test_box(lo, hi);
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx_, sheet.tris, sheet.nt, sheet.nv, box.tris, box.nt, box.nv, &v), WEFT_OK);
    float *inside = malloc(sizeof(float) * 3 * sheet.nv);
    uint32_t *masks = malloc(sizeof(uint32_t) * sheet.nv), *bits = malloc(sizeof(uint32_t) * box.nt);
    memcpy(inside, sheet.pos, sizeof(float) * 3 * sheet.nv);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        inside[3 * i + 1] = 0.1f;
        masks[i] = 1u << 2; /* the sheet collides with part 2 only */
    }
    for (uint32_t t = 0; t < box.nt; ++t) {
        bits[t] = 1u << 5; /* the box is part 5 */
    }
    weft_sim_validation res;
    CHECK_RESULT(weft_sim_validator_set_parts(v, masks, bits), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, sheet.pos, inside, box.pos, box.pos, &res), WEFT_OK);
    CHECK_MSG(res.ccd_hits + res.intersection_hits == 0, "another part's box: %u CCD, %u intersection hits",
              res.ccd_hits, res.intersection_hits);
    /* a sheet cut by the box's side faces at rest */
    float *across = malloc(sizeof(float) * 3 * sheet.nv);
    memcpy(across, inside, sizeof(float) * 3 * sheet.nv);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        across[3 * i + 0] = 4.0f * sheet.pos[3 * i + 0]; /* 0.8 m wide: out through both sides */
    }
    CHECK_RESULT(weft_sim_validator_check(v, across, across, box.pos, box.pos, &res), WEFT_OK);
    CHECK_EQ_INT(res.ccd_hits + res.intersection_hits, 0);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        masks[i] |= 1u << 5;
    }
    CHECK_RESULT(weft_sim_validator_check(v, sheet.pos, inside, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.ccd_hits > 0);
    CHECK_RESULT(weft_sim_validator_check(v, across, across, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.intersection_hits > 0);
    /* one array without the other is refused; NULL, NULL clears */
    CHECK_RESULT(weft_sim_validator_set_parts(v, masks, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_sim_validator_set_parts(NULL, masks, bits), WEFT_ERROR_INVALID_ARGUMENT);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        masks[i] = 1u << 2;
    }
    CHECK_RESULT(weft_sim_validator_set_parts(v, NULL, NULL), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, sheet.pos, inside, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.ccd_hits > 0);
    weft_sim_validator_destroy(v);
    uint32_t ok_tris[] = {0, 1, 2};
    CHECK_RESULT(weft_sim_validator_create(ctx_, ok_tris, 1, 3, NULL, 0, 0, &v), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_set_parts(v, masks, bits), WEFT_ERROR_INVALID_ARGUMENT); /* no collider */
    weft_sim_validator_destroy(v);
    free(across);
    free(bits);
    free(masks);
    free(inside);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
}

static void test_validator_catches_penetration(void)
{
    /* A sheet falling through a box in one frame is caught by the sweeps; a sheet resting
     * inside the box's faces is caught by the intersection tests. */
    test_mesh sheet = test_sheet(5, 5, 0.2f, 0.2f, 0, 0.3f, 0);
    const float lo[3] = {-0.3f, 0.0f, -0.3f}, hi[3] = {0.3f, 0.2f, 0.3f};
    test_mesh box = test_box(lo, hi);
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx_, sheet.tris, sheet.nt, sheet.nv, box.tris, box.nt, box.nv, &v), WEFT_OK);
    float *below = malloc(sizeof(float) * 3 * sheet.nv);
    memcpy(below, sheet.pos, sizeof(float) * 3 * sheet.nv);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        below[3 * i + 1] = 0.1f; /* inside the box */
    }
    weft_sim_validation res;
    CHECK_RESULT(weft_sim_validator_check(v, sheet.pos, below, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.ccd_hits > 0);
    /* It names one hit: a cloth-against-box contact with indices into the right meshes. */
    CHECK_MSG(res.hit.type <= WEFT_CCD_FV, "hit type %u", res.hit.type);
    if (res.hit.type == WEFT_CCD_VF) {
        CHECK(res.hit.v[0] < sheet.nv && res.hit.v[1] < box.nv && res.hit.v[2] < box.nv && res.hit.v[3] < box.nv);
    } else if (res.hit.type == WEFT_CCD_EE) {
        CHECK(res.hit.v[0] < sheet.nv && res.hit.v[1] < sheet.nv && res.hit.v[2] < box.nv && res.hit.v[3] < box.nv);
    } else {
        CHECK(res.hit.v[0] < box.nv && res.hit.v[1] < sheet.nv && res.hit.v[2] < sheet.nv && res.hit.v[3] < sheet.nv);
    }
    /* A sheet crossing the top face. */
    float *cross = malloc(sizeof(float) * 3 * sheet.nv);
    memcpy(cross, sheet.pos, sizeof(float) * 3 * sheet.nv);
    for (uint32_t i = 0; i < sheet.nv; ++i) {
        cross[3 * i + 1] = 0.2f + 0.5f * (cross[3 * i] + 0.013f);
    }
    CHECK_RESULT(weft_sim_validator_check(v, cross, cross, box.pos, box.pos, &res), WEFT_OK);
    CHECK(res.intersection_hits > 0);
    /* Still above: clean. */
    CHECK_RESULT(weft_sim_validator_check(v, sheet.pos, sheet.pos, box.pos, box.pos, &res), WEFT_OK);
    CHECK_EQ_INT(res.ccd_hits + res.intersection_hits, 0);
    CHECK_EQ_INT(res.hit.type, WEFT_CCD_TYPE_COUNT);
    free(below);
    free(cross);
    weft_sim_validator_destroy(v);
    test_mesh_free(&box);
    test_mesh_free(&sheet);
}

static void test_generate_bad_def(void)
{
    weft_sim_sequence_def d = weft_sim_default_sequence_def();
    weft_sim_sequence_result res;
    d.frames = 1;
    CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    d = weft_sim_default_sequence_def();
    d.max_substeps = 10; /* below substeps */
    CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    d = weft_sim_default_sequence_def();
    d.motion_speed = 0.0f;
    CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    d.motion_speed = NAN;
    CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    const float spreads[3] = {-0.1f, 0.81f, NAN};
    for (int k = 0; k < 3; ++k) {
        d = weft_sim_default_sequence_def();
        d.scenario = WEFT_SIM_SCENARIO_GARMENT;
        d.garment_retry_arm_spread = spreads[k];
        CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(strstr(weft_last_error(), "garment_retry_arm_spread") != NULL);
        d.garment_retry_arm_spread = 0.3f;
        d.garment_retry_ease_in = k == 0 ? -0.5f : (k == 1 ? 2.5f : NAN);
        CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
        d.garment_retry_ease_in = 0.5f;
        d.garment_retry_amplitude = k == 0 ? 0.0f : (k == 1 ? 1.5f : NAN);
        CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    }
    d = weft_sim_default_sequence_def();
    const uint32_t factors[3] = {0, 17, 16}; /* 16 x max_substeps 300 exceeds 4000 substeps */
    for (int k = 0; k < 3; ++k) {
        d.fast_collider_factor = factors[k];
        d.max_substeps = k == 2 ? 300 : 80;
        CHECK_RESULT(weft_sim_generate(ctx_, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(strstr(weft_last_error(), "fast_collider_factor") != NULL);
    }
    weft_sim_sequence_def raw = {0};
    CHECK_RESULT(weft_sim_generate(ctx_, &raw, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
}

static void setup(void)
{
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx_), WEFT_OK);
}

static void teardown(void) { weft_context_destroy(ctx_); }

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_non_manifold), TEST_CASE(test_duplicate_triangle),
          TEST_CASE(test_isolated_vertex), TEST_CASE(test_nan_and_configure), TEST_CASE(test_inverted_initial_state),
          TEST_CASE(test_validator_bad_input), TEST_CASE(test_validator_catches_penetration), TEST_CASE(test_validator_path),
          TEST_CASE(test_validator_parts),
          TEST_CASE(test_generate_bad_def), TEST_CASE(teardown))
