/* SMPL .npz loader: cross-check of posed vertices against an independent numpy implementation
 * (tests/assets/make_fake_smpl.py, run as the fake_smpl ctest fixture), strict .npy header
 * parsing, and damaged archives that must fail cleanly. */
#include "test.h"

#include "core/core.h"
#include "npz.h"
#include "weft.h"
#include "weft/body.h"

#define DATA_DIR WEFT_BINARY_DIR "/tests/fake_smpl"

/* Tolerance: C poses in float32, numpy in float64 from the same float32 inputs. Vertices lie
 * within ~3 m of the origin after 4-5 chained rotations; float32 rounding through the chain
 * stays below 1e-5 m, 1e-4 m leaves margin without hiding a wrong formula (errors of those
 * are centimetres or more). */
#define POSE_TOL 1e-4

static weft_context *make_context(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    return ctx;
}

static unsigned char *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc((size_t)n);
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return b;
}

static void cross_check(const char *model_file, const char *expected_file, bool has_posedirs)
{
    weft_context *ctx = make_context();
    weft_body *body = NULL;
    CHECK_RESULT(weft_smpl_load_npz_file(ctx, model_file, &body), WEFT_OK);
    weft_npz *exp = NULL;
    CHECK_RESULT(weft_npz_read_file(ctx, expected_file, &exp), WEFT_OK);
    if (!body || !exp) {
        weft_body_destroy(body);
        weft_npz_destroy(exp);
        weft_context_destroy(ctx);
        return;
    }
    CHECK_EQ_INT(weft_body_shape_count(body), 10);
    const weft_npy_array *betas = weft_npz_find(exp, "betas"), *poses = weft_npz_find(exp, "poses");
    const weft_npy_array *trans = weft_npz_find(exp, "trans"), *verts = weft_npz_find(exp, "verts");
    const weft_npy_array *joints = weft_npz_find(exp, "joints");
    CHECK(betas && poses && trans && verts && joints);
    if (!(betas && poses && trans && verts && joints)) {
        return;
    }
    uint32_t cases = (uint32_t)betas->shape[0];
    uint32_t nv = weft_body_vertex_count(body);
    CHECK_EQ_INT(verts->shape[1], nv);
    float *b = malloc(betas->count * sizeof(float)), *p = malloc(poses->count * sizeof(float));
    float *t = malloc(trans->count * sizeof(float)), *v = malloc(verts->count * sizeof(float));
    float *j = malloc(joints->count * sizeof(float));
    float *out = malloc((size_t)nv * 3 * sizeof(float));
    float xf[WEFT_BODY_JOINTS * 16];
    CHECK_RESULT(weft_npy_to_f32(betas, b, betas->count), WEFT_OK);
    CHECK_RESULT(weft_npy_to_f32(poses, p, poses->count), WEFT_OK);
    CHECK_RESULT(weft_npy_to_f32(trans, t, trans->count), WEFT_OK);
    CHECK_RESULT(weft_npy_to_f32(verts, v, verts->count), WEFT_OK);
    CHECK_RESULT(weft_npy_to_f32(joints, j, joints->count), WEFT_OK);
    double worst = 0, worst_joint = 0, moved = 0;
    for (uint32_t c = 0; c < cases; ++c) {
        CHECK_RESULT(weft_body_set_shape(body, b + 10 * c, 10), WEFT_OK);
        weft_pose pose;
        memcpy(pose.rotations, p + 72 * c, sizeof pose.rotations);
        memcpy(pose.translation, t + 3 * c, sizeof pose.translation);
        CHECK_RESULT(weft_body_pose(body, &pose, out, xf), WEFT_OK);
        for (uint32_t i = 0; i < nv * 3; ++i) {
            double d = fabs((double)out[i] - v[(size_t)c * nv * 3 + i]);
            worst = d > worst ? d : worst;
            double m = fabs((double)out[i] - weft_body_rest_vertices(body)[i]);
            moved = m > moved ? m : moved;
        }
        for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
            for (int a = 0; a < 3; ++a) {
                double d = fabs((double)xf[16 * k + 12 + a] - j[(size_t)c * 72 + 3 * k + a]);
                worst_joint = d > worst_joint ? d : worst_joint;
            }
        }
    }
    printf("%s: %u poses, max |C - numpy| vertices %.3g m, joints %.3g m (posedirs %s)\n", model_file, cases, worst,
           worst_joint, has_posedirs ? "yes" : "no");
    CHECK_NEAR(worst, 0.0, POSE_TOL);
    CHECK_NEAR(worst_joint, 0.0, POSE_TOL);
    CHECK(moved > 0.1); /* the poses really move the vertices */
    free(b), free(p), free(t), free(v), free(j), free(out);
    weft_npz_destroy(exp);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

static void test_dense_matches_numpy(void)
{
    cross_check(DATA_DIR "/fake_smpl_dense.npz", DATA_DIR "/expected_dense.npz", true);
}

static void test_sparse_matches_numpy(void)
{
    cross_check(DATA_DIR "/fake_smpl_sparse.npz", DATA_DIR "/expected_sparse.npz", false);
}

static void test_nan_pose_and_betas(void)
{
    weft_context *ctx = make_context();
    weft_body *body = NULL;
    CHECK_RESULT(weft_smpl_load_npz_file(ctx, DATA_DIR "/fake_smpl_dense.npz", &body), WEFT_OK);
    if (!body) {
        weft_context_destroy(ctx);
        return;
    }
    uint32_t nv = weft_body_vertex_count(body);
    float *out = malloc((size_t)nv * 3 * sizeof(float));
    for (uint32_t i = 0; i < nv * 3; ++i) {
        out[i] = 7.0f;
    }
    weft_pose pose;
    memset(&pose, 0, sizeof pose);
    pose.rotations[40] = NAN;
    CHECK_RESULT(weft_body_pose(body, &pose, out, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(out[0] == 7.0f && out[3 * nv - 1] == 7.0f); /* untouched */
    pose.rotations[40] = 0;
    pose.translation[1] = INFINITY;
    CHECK_RESULT(weft_body_pose(body, &pose, out, NULL), WEFT_ERROR_NOT_FINITE);
    float betas[10] = {0};
    betas[4] = NAN;
    float before = weft_body_rest_vertices(body)[5];
    CHECK_RESULT(weft_body_set_shape(body, betas, 10), WEFT_ERROR_NOT_FINITE);
    CHECK(weft_body_rest_vertices(body)[5] == before);
    CHECK_RESULT(weft_body_set_shape(body, betas, 11), WEFT_ERROR_SIZE_MISMATCH);
    CHECK(strstr(weft_last_error(), "11") != NULL);
    free(out);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
}

typedef struct corrupt_case {
    const char *name;
    weft_result expected;
    const char *message_part; /* the error message must name this */
} corrupt_case;

static void test_corrupt_archives(void)
{
    static const corrupt_case cases[] = {
        {"npy_magic", WEFT_ERROR_FORMAT, "weights"},
        {"npy_version", WEFT_ERROR_FORMAT, "version"},
        {"npy_header_key", WEFT_ERROR_FORMAT, "dtype"},
        {"npy_header_order", WEFT_ERROR_FORMAT, "fortran_order"},
        {"npy_header_len", WEFT_ERROR_FORMAT, "weights"},
        {"npy_truncated_data", WEFT_ERROR_FORMAT, "weights"},
        {"npy_shape_vs_data", WEFT_ERROR_FORMAT, "data bytes"},
        {"dtype_string", WEFT_ERROR_FORMAT, "weights"},
        {"dtype_big_endian", WEFT_ERROR_FORMAT, "v_template"},
        {"weights_shape", WEFT_ERROR_FORMAT, "weights"},
        {"regressor_joints", WEFT_ERROR_FORMAT, "J_regressor"},
        {"kintree_joints", WEFT_ERROR_FORMAT, "25 joints"},
        {"faces_range", WEFT_ERROR_FORMAT, "'f'"},
        {"posedirs_shape", WEFT_ERROR_FORMAT, "posedirs"},
        {"missing_template", WEFT_ERROR_FORMAT, "v_template"},
        {"nan_template", WEFT_ERROR_NOT_FINITE, "v_template"},
    };
    weft_context *ctx = make_context();
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char path[512];
        snprintf(path, sizeof path, DATA_DIR "/corrupt_%s.npz", cases[i].name);
        weft_body *body = (weft_body *)(uintptr_t)0x1;
        weft_result r = weft_smpl_load_npz_file(ctx, path, &body);
        CHECK_MSG(r == cases[i].expected, "%s: got %s (%s)", cases[i].name, weft_result_string(r), weft_last_error());
        CHECK_MSG(strstr(weft_last_error(), cases[i].message_part) != NULL, "%s: message '%s' lacks '%s'", cases[i].name,
                  weft_last_error(), cases[i].message_part);
        CHECK_MSG(body == (weft_body *)(uintptr_t)0x1, "%s: output written on failure", cases[i].name);
    }
    weft_body *body = NULL;
    CHECK_RESULT(weft_smpl_load_npz_file(ctx, DATA_DIR "/does_not_exist.npz", &body), WEFT_ERROR_IO);
    weft_context_destroy(ctx);
}

/* Every prefix length class and scattered byte flips of a real archive: errors, never a crash
 * (the sanitizer build turns any out-of-bounds access into a failure). */
static void test_truncated_and_flipped_bytes(void)
{
    weft_context *ctx = make_context();
    size_t size = 0;
    unsigned char *bytes = read_all(DATA_DIR "/fake_smpl_sparse.npz", &size);
    CHECK(bytes != NULL && size > 1000);
    if (!bytes) {
        weft_context_destroy(ctx);
        return;
    }
    weft_body *body = NULL;
    CHECK_RESULT(weft_smpl_load_npz_memory(ctx, bytes, size, &body), WEFT_OK);
    weft_body_destroy(body);
    for (size_t cut = 0; cut < size; cut += size / 97 + 1) {
        body = NULL;
        weft_result r = weft_smpl_load_npz_memory(ctx, bytes, cut, &body);
        CHECK_MSG(r == WEFT_ERROR_FORMAT || r == WEFT_ERROR_INVALID_ARGUMENT, "cut at %zu: %s", cut, weft_result_string(r));
        CHECK(body == NULL);
    }
    unsigned char *copy = malloc(size);
    test_rng rng = {0x9e3779b97f4a7c15ull};
    int failures = 0;
    for (int trial = 0; trial < 120; ++trial) {
        memcpy(copy, bytes, size);
        size_t at = test_rng_u32(&rng) % size;
        copy[at] ^= (unsigned char)(1u + test_rng_u32(&rng) % 255u);
        body = NULL;
        weft_result r = weft_smpl_load_npz_memory(ctx, copy, size, &body);
        if (r != WEFT_OK) {
            failures++;
            CHECK(body == NULL);
            CHECK(weft_last_error()[0] != '\0');
        }
        weft_body_destroy(body);
    }
    CHECK(failures > 60); /* compressed data and CRCs catch nearly every flip */
    free(copy);
    free(bytes);
    weft_context_destroy(ctx);
}

/* A directory entry claiming gigabytes (a forged size in a few-kB file) must be refused
 * before anything that size is allocated. */
static void test_forged_sizes(void)
{
    weft_context *ctx = make_context();
    size_t size = 0;
    unsigned char *bytes = read_all(DATA_DIR "/fuzz_corpus/tiny_deflated.npz", &size);
    CHECK(bytes != NULL && size > 100);
    if (!bytes) {
        weft_context_destroy(ctx);
        return;
    }
    int patched = 0;
    for (size_t i = 0; i + 46 <= size; ++i) {
        if (memcmp(bytes + i, "PK\x01\x02", 4) == 0) { /* central directory file header */
            static const unsigned char huge[4] = {0x00, 0x00, 0x00, 0x70}; /* 1.75 GiB */
            memcpy(bytes + i + 20, huge, 4); /* compressed size */
            memcpy(bytes + i + 24, huge, 4); /* uncompressed size */
            patched++;
        }
    }
    CHECK(patched >= 5);
    weft_body *body = NULL;
    double t0 = weft__now_ms();
    CHECK_RESULT(weft_smpl_load_npz_memory(ctx, bytes, size, &body), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "compressed bytes") != NULL);
    CHECK(weft__now_ms() - t0 < 1000.0);
    CHECK(body == NULL);
    free(bytes);
    weft_context_destroy(ctx);
}

static void test_npy_headers(void)
{
    static const struct {
        const char *header;
        size_t payload;
        weft_result expected;
    } cases[] = {
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }", 24, WEFT_OK},
        {"{'descr': '<f8', 'fortran_order': True, 'shape': (3,), }", 24, WEFT_OK},
        {"{'descr': '|u1', 'fortran_order': False, 'shape': (), }", 1, WEFT_OK},
        {"{\"descr\": \"<i8\", \"fortran_order\": False, \"shape\": (2L, 1L)}", 16, WEFT_OK},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }", 20, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': False}", 4, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': ()}", 4, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (2 3)}", 24, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (-2,)}", 8, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': 0, 'shape': (2,)}", 8, WEFT_ERROR_FORMAT},
        {"{'descr': 'f4', 'fortran_order': False, 'shape': (2,)}", 8, WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999, 99999999999, 99999999999)}", 8,
         WEFT_ERROR_FORMAT},
        {"{'descr': '<f4', 'fortran_order': False, 'shape': (2,)} junk", 8, WEFT_ERROR_FORMAT},
        {"['descr', '<f4']", 8, WEFT_ERROR_FORMAT},
    };
    unsigned char buf[512];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        size_t hl = strlen(cases[i].header) + 1;
        memcpy(buf, "\x93NUMPY\x01\x00", 8);
        buf[8] = (unsigned char)(hl & 0xff);
        buf[9] = (unsigned char)(hl >> 8);
        memcpy(buf + 10, cases[i].header, hl - 1);
        buf[10 + hl - 1] = '\n';
        memset(buf + 10 + hl, 0, cases[i].payload);
        weft_npy_array a;
        weft_result r = weft_npy_parse(buf, 10 + hl + cases[i].payload, "t", &a);
        CHECK_MSG(r == cases[i].expected, "case %zu '%s': %s (%s)", i, cases[i].header, weft_result_string(r),
                  weft_last_error());
    }
    /* Fortran order is honoured by the conversion: a (2, 3) array stored column-major. */
    const char *h = "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 3), }";
    size_t hl = strlen(h) + 1;
    memcpy(buf, "\x93NUMPY\x01\x00", 8);
    buf[8] = (unsigned char)hl;
    buf[9] = 0;
    memcpy(buf + 10, h, hl - 1);
    buf[10 + hl - 1] = '\n';
    float colmajor[6] = {0, 3, 1, 4, 2, 5}; /* C order would be 0 1 2 / 3 4 5 */
    memcpy(buf + 10 + hl, colmajor, sizeof colmajor);
    weft_npy_array a;
    CHECK_RESULT(weft_npy_parse(buf, 10 + hl + sizeof colmajor, "f", &a), WEFT_OK);
    float c[6];
    CHECK_RESULT(weft_npy_to_f32(&a, c, 6), WEFT_OK);
    for (int i = 0; i < 6; ++i) {
        CHECK_NEAR(c[i], (float)i, 0.0);
    }
    CHECK_RESULT(weft_npy_to_f32(&a, c, 5), WEFT_ERROR_SIZE_MISMATCH);
}

TEST_MAIN(TEST_CASE(test_dense_matches_numpy), TEST_CASE(test_sparse_matches_numpy), TEST_CASE(test_nan_pose_and_betas),
          TEST_CASE(test_corrupt_archives), TEST_CASE(test_truncated_and_flipped_bytes), TEST_CASE(test_forged_sizes),
          TEST_CASE(test_npy_headers))
