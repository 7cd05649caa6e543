/* Skinned glTF import through assimp: assimp-testmodels' simple_skin, a round trip of weft's
 * own avatar and motion through the glTF writer, malformed files, the inputs assimp 5.2
 * crashes on (refused before assimp reads them), and one it crashes on past those checks
 * (refused when its child process dies). */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "gltf.h"

#include <stdint.h>
#include <unistd.h>

#define SIMPLE_SKIN "/usr/share/assimp/models/glTF2/simple_skin/simple_skin.gltf"

static weft_context *g_ctx;

static void test_simple_skin(void)
{
    weft_skinned_asset *a = NULL;
    CHECK_RESULT(weft_skinned_load_file(g_ctx, SIMPLE_SKIN, 60.0f, &a), WEFT_OK);
    if (!a) {
        return;
    }
    /* the glTF tutorial's skin: a 10-vertex strip of 8 triangles on two joints, one animation */
    CHECK_EQ_INT(a->vertex_count, 10);
    CHECK_EQ_INT(a->triangle_count, 8);
    CHECK_EQ_INT(a->joint_count, 2);
    CHECK(a->frame_count > 60);
    int root = a->parents[0] < 0 ? 0 : 1;
    CHECK_EQ_INT(a->parents[root], -1);
    CHECK_EQ_INT(a->parents[1 - root], root);
    for (uint32_t v = 0; v < a->vertex_count; ++v) {
        CHECK_NEAR(a->joint_weights[4 * v] + a->joint_weights[4 * v + 1] + a->joint_weights[4 * v + 2] +
                       a->joint_weights[4 * v + 3],
                   1.0, 1e-5);
    }
    /* The file's inverse bind matrices are translate(-0.5, -1, 0) for both joints, so even its
     * first frame is the mesh shifted by -0.5 in x; motion is measured from that frame. */
    float *x = malloc((size_t)a->vertex_count * 3 * sizeof(float));
    float *x0 = malloc((size_t)a->vertex_count * 3 * sizeof(float));
    CHECK_RESULT(weft_skinned_pose(a, 0, x0), WEFT_OK);
    CHECK_NEAR(x0[0], a->positions[0] - 0.5, 1e-6);
    CHECK_NEAR(x0[1], a->positions[1], 1e-6);
    double top_motion = 0.0;
    int still_checked = 0;
    for (uint32_t f = 0; f < a->frame_count; ++f) {
        CHECK_RESULT(weft_skinned_pose(a, f, x), WEFT_OK);
        for (uint32_t v = 0; v < a->vertex_count; ++v) {
            const float *p0 = x0 + 3 * v, *p = x + 3 * v;
            double d = sqrt((p[0] - p0[0]) * (p[0] - p0[0]) + (p[1] - p0[1]) * (p[1] - p0[1]) + (p[2] - p0[2]) * (p[2] - p0[2]));
            /* vertices bound only to the unanimated root joint never move */
            bool root_only = false;
            for (int k = 0; k < 4; ++k) {
                root_only |= a->joint_indices[4 * v + (uint32_t)k] == (uint32_t)root && a->joint_weights[4 * v + (uint32_t)k] > 0.999f;
            }
            if (root_only) {
                CHECK_NEAR(d, 0.0, 1e-5);
                still_checked++;
            }
            if (a->positions[3 * v + 1] > 1.9f) {
                top_motion = fmax(top_motion, d);
            }
        }
    }
    printf("simple_skin: %u frames at 60 Hz, top vertices move up to %.3f\n", a->frame_count, top_motion);
    CHECK(still_checked > 0);
    /* the top edge swings on the 1 m upper segment about the middle joint: well under 2 m */
    CHECK(top_motion > 0.3 && top_motion < 2.0);
    CHECK_RESULT(weft_skinned_pose(a, a->frame_count, x), WEFT_ERROR_INVALID_ARGUMENT);
    /* two joints are not an SMPL skeleton */
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_skinned_to_clip(g_ctx, a, &clip), WEFT_ERROR_SIZE_MISMATCH);
    CHECK(clip == NULL);
    free(x);
    free(x0);
    weft_skinned_asset_destroy(a);
}

/* An FBX skinned mesh through the same importer (assimp-testmodels' huesitos.fbx: quads, so the
 * importer's triangulation matters). */
static void test_fbx(void)
{
    const char *path = "/usr/share/assimp/models/FBX/huesitos.fbx";
    FILE *f = fopen(path, "rb");
    if (!f) {
        printf("skipped: %s not installed\n", path);
        CHECK(1);
        return;
    }
    fclose(f);
    weft_skinned_asset *a = NULL;
    CHECK_RESULT(weft_skinned_load_file(g_ctx, path, 30.0f, &a), WEFT_OK);
    if (!a) {
        return;
    }
    printf("huesitos.fbx: %u vertices, %u triangles, %u joints, %u frames at 30 Hz\n", a->vertex_count, a->triangle_count,
           a->joint_count, a->frame_count);
    CHECK_EQ_INT(a->vertex_count, 256);
    CHECK_EQ_INT(a->triangle_count, 120);
    CHECK_EQ_INT(a->joint_count, 9);
    CHECK(a->frame_count > 10);
    float *x = malloc((size_t)a->vertex_count * 3 * sizeof(float));
    float *x0 = malloc((size_t)a->vertex_count * 3 * sizeof(float));
    CHECK_RESULT(weft_skinned_pose(a, 0, x0), WEFT_OK);
    double moved = 0.0;
    bool finite = true;
    for (uint32_t fr = 1; fr < a->frame_count; ++fr) {
        CHECK_RESULT(weft_skinned_pose(a, fr, x), WEFT_OK);
        for (uint32_t i = 0; i < a->vertex_count * 3; ++i) {
            finite &= isfinite(x[i]) != 0;
            moved = fmax(moved, fabs((double)x[i] - x0[i]));
        }
    }
    CHECK(finite);
    CHECK(moved > 1e-3);
    free(x);
    free(x0);
    weft_skinned_asset_destroy(a);
}

/* Top-4 weights of a dense 24-weight row, renormalised (what the writer stores). */
static void top4_dense(const float *row, float *out)
{
    uint32_t idx[4] = {0, 0, 0, 0};
    float w[4] = {0, 0, 0, 0};
    for (uint32_t j = 0; j < 24; ++j) {
        int s = 0;
        for (int k = 1; k < 4; ++k) {
            s = w[k] < w[s] ? k : s;
        }
        if (row[j] > w[s]) {
            w[s] = row[j];
            idx[s] = j;
        }
    }
    float sum = w[0] + w[1] + w[2] + w[3];
    memset(out, 0, 24 * sizeof(float));
    for (int k = 0; k < 4; ++k) {
        out[idx[k]] += w[k] / sum;
    }
}

/* weft's avatar walking, written as glTF, read back through assimp: the skinned vertices at
 * every frame match weft's own skinning of the same (top-4) weights, and the clip comes back. */
static void test_avatar_roundtrip(void)
{
    weft_body *body = NULL;
    weft_avatar_def adef = weft_default_avatar_def();
    adef.target_vertices = 3000;
    CHECK_RESULT(weft_avatar_create(g_ctx, &adef, &body), WEFT_OK);
    weft_motion_def mdef = weft_default_motion_def(WEFT_MOTION_WALK);
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_clip_from_motion(g_ctx, &mdef, 0.5, 30.0f, &clip), WEFT_OK);
    if (!body || !clip) {
        weft_clip_destroy(clip);
        weft_body_destroy(body);
        return;
    }
    const char *path = WEFT_BINARY_DIR "/tests/avatar_walk.gltf";
    CHECK_RESULT(weft_gltf_write_body(path, body, clip), WEFT_OK);
    weft_skinned_asset *a = NULL;
    CHECK_RESULT(weft_skinned_load_file(g_ctx, path, 30.0f, &a), WEFT_OK);
    uint32_t nv = weft_body_vertex_count(body);
    if (a) {
        CHECK_EQ_INT(a->vertex_count, nv);
        CHECK_EQ_INT(a->triangle_count, weft_body_triangle_count(body));
        CHECK_EQ_INT(a->joint_count, 24);
        CHECK_EQ_INT(a->frame_count, clip->frame_count);
    }
    if (a && a->vertex_count == nv && a->frame_count == clip->frame_count) {
        float *w4 = malloc((size_t)nv * 24 * sizeof(float));
        float *expected = malloc((size_t)nv * 3 * sizeof(float));
        float *got = malloc((size_t)nv * 3 * sizeof(float));
        const float *w = weft_body_weights(body);
        for (uint32_t v = 0; v < nv; ++v) {
            top4_dense(w + 24 * (size_t)v, w4 + 24 * (size_t)v);
        }
        double worst = 0.0;
        for (uint32_t f = 0; f < clip->frame_count; ++f) {
            weft_pose pose;
            memcpy(pose.rotations, clip->rotations + 72 * (size_t)f, sizeof pose.rotations);
            memcpy(pose.translation, clip->translations + 3 * (size_t)f, sizeof pose.translation);
            CHECK_RESULT(weft_body_skin_points(body, &pose, weft_body_rest_vertices(body), w4, nv, expected), WEFT_OK);
            CHECK_RESULT(weft_skinned_pose(a, f, got), WEFT_OK);
            for (size_t i = 0; i < (size_t)nv * 3; ++i) {
                worst = fmax(worst, fabs((double)expected[i] - got[i]));
            }
        }
        printf("avatar round trip: %u vertices x %u frames, worst vertex difference %.2e m\n", nv, clip->frame_count, worst);
        CHECK(worst < 1e-4);
        weft_clip *back = NULL;
        CHECK_RESULT(weft_skinned_to_clip(g_ctx, a, &back), WEFT_OK);
        if (back) {
            double worst_rot = 0.0, worst_tr = 0.0;
            for (size_t i = 0; i < (size_t)clip->frame_count * 72; ++i) {
                worst_rot = fmax(worst_rot, fabs((double)back->rotations[i] - clip->rotations[i]));
            }
            for (size_t i = 0; i < (size_t)clip->frame_count * 3; ++i) {
                worst_tr = fmax(worst_tr, fabs((double)back->translations[i] - clip->translations[i]));
            }
            printf("clip round trip: worst rotation difference %.2e rad, translation %.2e m\n", worst_rot, worst_tr);
            CHECK(worst_rot < 1e-4);
            CHECK(worst_tr < 1e-5);
            weft_clip_destroy(back);
        }
        free(w4);
        free(expected);
        free(got);
    }
    weft_skinned_asset_destroy(a);
    /* a bad path for the writer changes nothing and says why */
    CHECK_RESULT(weft_gltf_write_body(WEFT_BINARY_DIR "/tests/no_such_dir/x.gltf", body, clip), WEFT_ERROR_IO);
    CHECK_RESULT(weft_gltf_write_body(WEFT_BINARY_DIR "/tests/x.txt", body, clip), WEFT_ERROR_INVALID_ARGUMENT);
    clip->rotations[5] = NAN;
    CHECK_RESULT(weft_gltf_write_body(path, body, clip), WEFT_ERROR_NOT_FINITE);
    weft_clip_destroy(clip);
    weft_body_destroy(body);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

static void expect_load_fail(const char *path, weft_result expected, const char *what)
{
    weft_skinned_asset *sentinel = (weft_skinned_asset *)(uintptr_t)0x1234, *a = sentinel;
    weft_result r = weft_skinned_load_file(g_ctx, path, 60.0f, &a);
    CHECK_MSG(r == expected, "%s: got %s (%s), expected %s", what, weft_result_string(r), weft_last_error(),
              weft_result_string(expected));
    CHECK_MSG(a == sentinel, "%s: out_asset written on failure", what);
    if (r == expected) {
        printf("  %-26s -> %s\n", what, weft_last_error());
    }
}

static void test_bad_files(void)
{
    weft_skinned_asset *a = NULL;
    CHECK_RESULT(weft_skinned_load_file(NULL, SIMPLE_SKIN, 60.0f, &a), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_skinned_load_file(g_ctx, SIMPLE_SKIN, 0.0f, &a), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_skinned_load_file(g_ctx, SIMPLE_SKIN, NAN, &a), WEFT_ERROR_INVALID_ARGUMENT);
    expect_load_fail("/nonexistent/skin.gltf", WEFT_ERROR_IO, "missing file");
    const char *garbage = WEFT_BINARY_DIR "/tests/garbage.gltf";
    write_text(garbage, "{ \"asset\": { \"version\": \"2.0\" }, \"nodes\": [ { \"mesh\": 7 } ");
    expect_load_fail(garbage, WEFT_ERROR_FORMAT, "truncated JSON");
    /* a valid glTF with a triangle but no skin */
    const char *unskinned = WEFT_BINARY_DIR "/tests/unskinned.gltf";
    write_text(unskinned,
               "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}],"
               "\"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}}]}],"
               "\"buffers\": [{\"uri\": \"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA\","
               " \"byteLength\": 36}],"
               "\"bufferViews\": [{\"buffer\": 0, \"byteLength\": 36}],"
               "\"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3, \"type\": \"VEC3\","
               " \"min\": [0, 0, 0], \"max\": [1, 1, 0]}]}");
    expect_load_fail(unskinned, WEFT_ERROR_FORMAT, "no skin");
    /* the exported avatar with its .bin cut short */
    weft_body *body = NULL;
    weft_avatar_def adef = weft_default_avatar_def();
    adef.target_vertices = 2000;
    CHECK_RESULT(weft_avatar_create(g_ctx, &adef, &body), WEFT_OK);
    if (body) {
        const char *path = WEFT_BINARY_DIR "/tests/truncated.gltf";
        CHECK_RESULT(weft_gltf_write_body(path, body, NULL), WEFT_OK);
        const char *bin = WEFT_BINARY_DIR "/tests/truncated.bin";
        FILE *f = fopen(bin, "r+b");
        CHECK(f != NULL);
        if (f) {
            CHECK(ftruncate(fileno(f), 1000) == 0);
            fclose(f);
        }
        expect_load_fail(path, WEFT_ERROR_FORMAT, "truncated .bin");
        /* a NaN vertex written into the binary buffer */
        CHECK_RESULT(weft_gltf_write_body(path, body, NULL), WEFT_OK);
        f = fopen(bin, "r+b");
        if (f) {
            float nan = NAN;
            fseek(f, 12 * 5 + 4, SEEK_SET);
            fwrite(&nan, 4, 1, f);
            fclose(f);
        }
        expect_load_fail(path, WEFT_ERROR_NOT_FINITE, "NaN vertex");
        weft_body_destroy(body);
    }
}

/* Inputs assimp 5.2 crashes on are refused before assimp reads them (runtime/assets/assimp_check.h);
 * the fuzz seeds in tests/fuzz/corpus/gltf hold one of each, two as the fuzzer found them, next
 * to valid glTF, glb and ASCII FBX skins that must still load. */
static void test_assimp_guards(void)
{
    static const char *const refused[] = {"bad_skin_without_ibm.gltf",  "bad_skin_short_ibm.glb",
                                          "crash_skin_without_ibm.glb", "bad_cyclic_connections.fbx",
                                          "crash_fbx_self_connection.fbx", "bad_deep_nesting.fbx",
                                          "crash_timeout_glb_version.glb", "crash_79d44f88_posed_overflow.glb",
                                          "crash_fbx_cluster_index.fbx", "crash_q3d_huge_allocation.bin",
                                          "crash_glb_no_attributes.glb", "crash_fbx_empty_key.fbx",
                                          "bad_fbx_binary_cluster_index.fbx", "crash_fbx_duplicate_connection.fbx",
                                          "crash_fbx_binary_header.fbx", "crash_fbx_cluster_unused_vertex.fbx"};
    char path[1024];
    for (size_t i = 0; i < sizeof refused / sizeof refused[0]; ++i) {
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/gltf/%s", WEFT_SOURCE_DIR, refused[i]);
        expect_load_fail(path, WEFT_ERROR_FORMAT, refused[i]);
    }
    /* neither glTF 2.0 nor FBX (a mutation of the hang above: assimp's other readers spin on it) */
    const char *noise = WEFT_BINARY_DIR "/tests/noise.gltf";
    write_text(noise, "flTF\x02<\n ngeometrynodeh:\"L_Kypn");
    expect_load_fail(noise, WEFT_ERROR_FORMAT, "noise");
    CHECK(strstr(weft_last_error(), "neither glTF 2.0") != NULL);
    static const char *const loaded[] = {"chain3_bend.glb", "strip_skin.fbx", "smpl24_walk.gltf"};
    for (size_t i = 0; i < sizeof loaded / sizeof loaded[0]; ++i) {
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/gltf/%s", WEFT_SOURCE_DIR, loaded[i]);
        weft_skinned_asset *a = NULL;
        CHECK_MSG(weft_skinned_load_file(g_ctx, path, 30.0f, &a) == WEFT_OK, "%s: %s", loaded[i], weft_last_error());
        weft_skinned_asset_destroy(a);
    }
}

/* assimp reads each file in a child process (runtime/assets/isolate.h): a file that crashes
 * assimp inside its glTF reader, past every check weft makes first, is refused with the
 * child's end named, and the caller goes on loading files. */
static void test_isolated_import(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/tests/fuzz/corpus/gltf/crash_glb_sampler_null_read.glb", WEFT_SOURCE_DIR);
    for (int round = 0; round < 3; ++round) {
        expect_load_fail(path, WEFT_ERROR_FORMAT, "assimp crash (isolated)");
        CHECK_MSG(strstr(weft_last_error(), "assimp failed reading") != NULL && strstr(weft_last_error(), "signal") != NULL,
                  "message: %s", weft_last_error());
    }
    /* the same process still imports, and an isolated import equals the file's content */
    weft_skinned_asset *a = NULL;
    CHECK_RESULT(weft_skinned_load_file(g_ctx, SIMPLE_SKIN, 60.0f, &a), WEFT_OK);
    if (a) {
        CHECK_EQ_INT(a->vertex_count, 10);
        CHECK(a->context == g_ctx);
        CHECK(strlen(a->joint_names[0]) > 0);
        weft_skinned_asset_destroy(a);
    }
}

static void setup(void)
{
    weft_context_def cdef = weft_default_context_def();
    cdef.isa = WEFT_ISA_SCALAR;
    CHECK_RESULT(weft_context_create(&cdef, &g_ctx), WEFT_OK);
}

static void teardown(void) { weft_context_destroy(g_ctx); }

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_simple_skin), TEST_CASE(test_fbx), TEST_CASE(test_avatar_roundtrip), TEST_CASE(test_bad_files),
          TEST_CASE(test_assimp_guards), TEST_CASE(test_isolated_import), TEST_CASE(teardown))
