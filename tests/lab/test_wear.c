/* Wear measures (tools/lab/wear.c): on two overlapping closed boxes, a point inside both
 * counts once, points outside count zero, the winding number is right at random points against a
 * box oracle, the buried corners of one box count as body overlap and nothing else does, points
 * inside within 5 cm of a buried corner are not inside_clear and the other inside points are, and
 * off_body counts vertices beyond the distance from their skinned twins. */
#include "../xpbd/scene.h"
#include "test.h"
#include "weft/wear.h"

static const float k_a_lo[3] = {0.0f, 0.0f, 0.0f}, k_a_hi[3] = {1.0f, 1.0f, 1.0f};
static const float k_b_lo[3] = {0.6f, 0.3f, 0.3f}, k_b_hi[3] = {1.6f, 0.7f, 0.7f};

static bool in_box(const float *p, const float *lo, const float *hi)
{
    return p[0] > lo[0] && p[0] < hi[0] && p[1] > lo[1] && p[1] < hi[1] && p[2] > lo[2] && p[2] < hi[2];
}

static void test_inside_counts_the_union_once(void)
{
    test_mesh a = test_box(k_a_lo, k_a_hi), b = test_box(k_b_lo, k_b_hi), body = test_mesh_join(&a, &b);
    enum { N = 400 };
    float pts[N][3], skinned[N][3];
    test_rng rng = {12345};
    uint32_t expect_inside = 0;
    for (int i = 0; i < N; ++i) {
        for (int k = 0; k < 3; ++k) {
            pts[i][k] = test_rng_float(&rng, -0.3f, 1.9f);
            skinned[i][k] = pts[i][k];
        }
        expect_inside += in_box(pts[i], k_a_lo, k_a_hi) || in_box(pts[i], k_b_lo, k_b_hi);
    }
    /* one point in both boxes, one in neither, one inside 2 cm from a buried corner */
    const float both[3] = {0.8f, 0.5f, 0.5f}, neither[3] = {1.3f, 0.9f, 0.9f}, by_corner[3] = {0.61f, 0.31f, 0.69f};
    memcpy(pts[0], both, sizeof both);
    memcpy(pts[1], neither, sizeof neither);
    memcpy(pts[4], by_corner, sizeof by_corner);
    memcpy(skinned[0], both, sizeof both);
    memcpy(skinned[1], neither, sizeof neither);
    memcpy(skinned[4], by_corner, sizeof by_corner);
    expect_inside = 0;
    uint32_t expect_clear = 0, near_corner = 0;
    for (int i = 0; i < N; ++i) {
        const bool in = in_box(pts[i], k_a_lo, k_a_hi) || in_box(pts[i], k_b_lo, k_b_hi);
        /* the buried body vertices: box b's corners at x = 0.6 */
        bool near = false;
        for (int c = 0; c < 4; ++c) {
            const float q[3] = {0.6f, c & 1 ? 0.7f : 0.3f, c & 2 ? 0.7f : 0.3f};
            const float e[3] = {q[0] - pts[i][0], q[1] - pts[i][1], q[2] - pts[i][2]};
            near = near || e[0] * e[0] + e[1] * e[1] + e[2] * e[2] <= 0.05f * 0.05f;
        }
        expect_inside += in;
        expect_clear += in && !near;
        near_corner += in && near;
    }
    CHECK(near_corner >= 1);
    skinned[2][0] += 0.2f; /* 20 cm off its skinned twin */
    skinned[3][1] -= 0.05f; /* 5 cm */
    weft_wear *w = NULL;
    CHECK_RESULT(weft_wear_create(body.tris, body.nt, body.nv, N, &w), WEFT_OK);
    weft_wear_frame f;
    CHECK_RESULT(weft_wear_measure(w, body.pos, &pts[0][0], &skinned[0][0], 0.1f, &f), WEFT_OK);
    CHECK_NEAR(f.inside_body, (double)expect_inside / N, 1e-12);
    CHECK_NEAR(f.inside_clear, (double)expect_clear / N, 1e-12);
    CHECK_NEAR(f.off_body, 1.0 / N, 1e-12);
    /* box b's four corners at x = 0.6 lie inside box a; its other four and all of a's do not */
    CHECK_NEAR(f.body_self_overlap, 4.0 / 16.0, 1e-12);
    weft_wear_summary s = {0};
    weft_wear_summary_add(&s, &f);
    weft_wear_frame far = f;
    far.off_body = 0.02;
    weft_wear_summary_add(&s, &far);
    CHECK_EQ_INT(s.frames, 2);
    CHECK_EQ_INT(s.frames_off, 1);
    CHECK_NEAR(s.off_body_max, 0.02, 1e-12);
    weft_wear_destroy(w);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&body);
}

/* weft_wear_near_overlap: a unit box and a larger one 5 mm beside it do not overlap, so no point
 * is near a buried vertex at a 2 mm reach; at a 1 cm reach three of the unit box's facing corners
 * (moved 1 cm out along their normals) are inside the larger box, so a point within 5 cm of the
 * corner (1, 1, 1) is flagged and points far from them are not. Bad reach and NULL arrays are
 * refused. */
static void test_near_overlap_reach(void)
{
    const float alo[3] = {0.0f, 0.0f, 0.0f}, ahi[3] = {1.0f, 1.0f, 1.0f};
    const float blo[3] = {1.005f, -0.5f, -0.5f}, bhi[3] = {2.0f, 1.5f, 1.5f};
    test_mesh a = test_box(alo, ahi), b = test_box(blo, bhi), body = test_mesh_join(&a, &b);
    const float pts[3][3] = {{1.0025f, 0.98f, 0.98f}, {1.0025f, 0.5f, 0.5f}, {0.5f, 0.5f, -0.3f}};
    weft_wear *w = NULL;
    CHECK_RESULT(weft_wear_create(body.tris, body.nt, body.nv, 3, &w), WEFT_OK);
    weft_wear_frame f;
    CHECK_RESULT(weft_wear_measure(w, body.pos, pts[0], pts[0], 1.0f, &f), WEFT_OK);
    CHECK(f.body_self_overlap == 0.0);
    uint8_t near[3] = {9, 9, 9};
    CHECK_RESULT(weft_wear_near_overlap(w, body.pos, 0.002f, pts[0], 3, near), WEFT_OK);
    CHECK(near[0] == 0 && near[1] == 0 && near[2] == 0);
    CHECK_RESULT(weft_wear_near_overlap(w, body.pos, 0.01f, pts[0], 3, near), WEFT_OK);
    CHECK_MSG(near[0] == 1, "a point by a facing corner: %u", near[0]);
    CHECK_MSG(near[1] == 0 && near[2] == 0, "points far from the corners: %u %u", near[1], near[2]);
    CHECK_RESULT(weft_wear_near_overlap(w, body.pos, -0.01f, pts[0], 3, near), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_wear_near_overlap(w, body.pos, 0.01f, NULL, 3, near), WEFT_ERROR_INVALID_ARGUMENT);
    weft_wear_destroy(w);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&body);
}

static void test_bad_input(void)
{
    test_mesh a = test_box(k_a_lo, k_a_hi);
    weft_wear *w = NULL;
    CHECK_RESULT(weft_wear_create(NULL, 12, 8, 4, &w), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_wear_create(a.tris, 0, 8, 4, &w), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(w == NULL);
    CHECK_RESULT(weft_wear_create(a.tris, a.nt, a.nv, 1, &w), WEFT_OK);
    float p[3] = {0.5f, 0.5f, 0.5f};
    weft_wear_frame f;
    a.pos[4] = NAN;
    CHECK_RESULT(weft_wear_measure(w, a.pos, p, p, 0.1f, &f), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_wear_measure(w, a.pos, NULL, p, 0.1f, &f), WEFT_ERROR_INVALID_ARGUMENT);
    weft_wear_destroy(w);
    test_mesh_free(&a);
}

/* weft_wear_measure_memo: the same figures as weft_wear_measure for frames measured, read back
 * from the memo and measured again after the body moved (the checksum misses); box b moved clear
 * of box a buries nothing, and moved back reads its four buried corners from the memo. A memo of
 * another body size or a frame past its end is refused. */
static void test_memo(void)
{
    test_mesh a = test_box(k_a_lo, k_a_hi), b = test_box(k_b_lo, k_b_hi), body = test_mesh_join(&a, &b);
    const float pts[3][3] = {{0.8f, 0.5f, 0.5f}, {1.3f, 0.9f, 0.9f}, {0.61f, 0.31f, 0.69f}};
    float *moved = malloc((size_t)body.nv * 3 * sizeof(float));
    memcpy(moved, body.pos, (size_t)body.nv * 3 * sizeof(float));
    for (uint32_t v = a.nv; v < body.nv; ++v) {
        moved[3 * (size_t)v] += 1.0f; /* box b clear of box a */
    }
    weft_wear *w = NULL;
    weft_wear_memo *memo = NULL;
    CHECK_RESULT(weft_wear_create(body.tris, body.nt, body.nv, 3, &w), WEFT_OK);
    CHECK_RESULT(weft_wear_memo_create(body.nv, 2, &memo), WEFT_OK);
    weft_wear_frame plain, first, again, other, back;
    CHECK_RESULT(weft_wear_measure(w, body.pos, pts[0], pts[0], 0.1f, &plain), WEFT_OK);
    CHECK_RESULT(weft_wear_measure_memo(w, memo, 1, body.pos, pts[0], pts[0], 0.1f, &first), WEFT_OK);
    CHECK_RESULT(weft_wear_measure_memo(w, memo, 1, body.pos, pts[0], pts[0], 0.1f, &again), WEFT_OK);
    CHECK_RESULT(weft_wear_measure_memo(w, memo, 1, moved, pts[0], pts[0], 0.1f, &other), WEFT_OK);
    CHECK_RESULT(weft_wear_measure_memo(w, memo, 0, body.pos, pts[0], pts[0], 0.1f, &back), WEFT_OK);
    CHECK(memcmp(&plain, &first, sizeof plain) == 0 && memcmp(&plain, &again, sizeof plain) == 0 &&
          memcmp(&plain, &back, sizeof plain) == 0);
    CHECK_NEAR(plain.body_self_overlap, 4.0 / 16.0, 1e-12);
    CHECK_NEAR(other.body_self_overlap, 0.0, 0.0);
    CHECK(plain.inside_clear < plain.inside_body); /* the point by a buried corner */
    CHECK_NEAR(other.inside_clear, other.inside_body, 0.0);
    weft_wear_memo *small = NULL;
    CHECK_RESULT(weft_wear_memo_create(body.nv - 1, 2, &small), WEFT_OK);
    CHECK_RESULT(weft_wear_measure_memo(w, small, 0, body.pos, pts[0], pts[0], 0.1f, &other),
                 WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_wear_measure_memo(w, memo, 2, body.pos, pts[0], pts[0], 0.1f, &other),
                 WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_wear_memo_create(0, 2, &small), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_wear_memo_create(body.nv, 0, &small), WEFT_ERROR_INVALID_ARGUMENT);
    weft_wear_memo_destroy(small);
    weft_wear_memo_destroy(memo);
    weft_wear_destroy(w);
    free(moved);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&body);
}

static void test_percentile(void)
{
    double v[5] = {5, 1, 4, 2, 3};
    CHECK_NEAR(weft_wear_percentile(v, 5, 50.0), 3.0, 0.0);
    CHECK_NEAR(weft_wear_percentile(v, 5, 100.0), 5.0, 0.0);
    CHECK_NEAR(weft_wear_percentile(v, 5, 0.0), 1.0, 0.0);
    CHECK(isnan(weft_wear_percentile(v, 0, 50.0)));
}

TEST_MAIN(TEST_CASE(test_inside_counts_the_union_once), TEST_CASE(test_near_overlap_reach), TEST_CASE(test_bad_input),
          TEST_CASE(test_memo), TEST_CASE(test_percentile))
