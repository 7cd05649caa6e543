/* Fuzz target for the skinned-mesh importer (runtime/assets/gltf.c, through assimp): arbitrary
 * bytes -> a file -> weft_skinned_load_file. The importer takes a path only, so each input is
 * written to a per-process file whose extension follows the content: "glTF" magic -> .glb, an
 * FBX header -> .fbx, anything else -> .gltf (assimp picks its reader by extension first).
 *
 * assimp reads each input in a child process (runtime/assets/isolate.h), so the target checks
 * weft's side: the checks before assimp, the child's answer decoded and re-validated, and the
 * conversion (strict mode: a child dying after assimp returned aborts this process).
 *
 * A rejected input must leave *out_asset NULL and explain itself in weft_last_error(). An
 * accepted one must be consistent (counts, indices in range, weights that sum to one, each
 * parent another joint or -1, a finite bind pose), pose to finite positions at its
 * first frames and its last (at most 33 frames are posed, so long animations stay cheap), and
 * weft_skinned_to_clip must either succeed with a finite clip of the same length or explain
 * why not. Any violated property aborts, which the fuzzer reports.
 *
 * Built two ways (tests/fuzz/CMakeLists.txt): with libFuzzer (WEFT_BUILD_FUZZ=ON, clang), and as
 * the ctest fuzz.gltf_replay together with replay_main.c. */
#define _POSIX_C_SOURCE 200809L /* getpid */

#include "gltf.h"
#include "core/core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(cond)                                                                               \
    do {                                                                                            \
        if (!(cond)) {                                                                              \
            fprintf(stderr, "fuzz_gltf: property failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
            abort();                                                                                \
        }                                                                                           \
    } while (0)

#define MAX_POSED_FRAMES 32u

enum { KIND_GLTF, KIND_GLB, KIND_FBX, KINDS };
static const char *const k_extension[KINDS] = {"gltf", "glb", "fbx"};

static int kind_of(const uint8_t *data, size_t size)
{
    if (size >= 4 && memcmp(data, "glTF", 4) == 0) {
        return KIND_GLB;
    }
    static const char *const fbx[] = {"Kaydara FBX Binary", "; FBX"};
    for (size_t i = 0; i < sizeof fbx / sizeof fbx[0]; ++i) {
        size_t n = strlen(fbx[i]);
        if (size >= n && memcmp(data, fbx[i], n) == 0) {
            return KIND_FBX;
        }
    }
    return KIND_GLTF;
}

static void check_asset(const weft_skinned_asset *a, float fps)
{
    REQUIRE(a->vertex_count > 0 && a->triangle_count > 0);
    REQUIRE(a->joint_count > 0 && a->joint_count <= WEFT_SKIN_MAX_JOINTS);
    REQUIRE(a->frame_count >= 1 && a->fps == fps);
    REQUIRE(weft__all_finite(a->positions, (size_t)a->vertex_count * 3));
    for (size_t i = 0; i < (size_t)a->triangle_count * 3; ++i) {
        REQUIRE(a->triangles[i] < a->vertex_count);
    }
    for (size_t v = 0; v < a->vertex_count; ++v) {
        double sum = 0.0;
        for (size_t k = 0; k < 4; ++k) {
            float w = a->joint_weights[4 * v + k];
            REQUIRE(w >= 0.0f && w <= 1.0f);
            REQUIRE(w == 0.0f || a->joint_indices[4 * v + k] < a->joint_count);
            sum += w;
        }
        REQUIRE(fabs(sum - 1.0) < 1e-4);
    }
    for (uint32_t j = 0; j < a->joint_count; ++j) {
        REQUIRE(a->joint_names[j][WEFT_SKIN_NAME - 1] == '\0');
        REQUIRE(a->parents[j] == -1 || (a->parents[j] >= 0 && (uint32_t)a->parents[j] < a->joint_count &&
                                        (uint32_t)a->parents[j] != j));
    }
    REQUIRE(weft__all_finite(a->rest_rotations, (size_t)a->joint_count * 4));
    REQUIRE(weft__all_finite(a->rest_translations, (size_t)a->joint_count * 3));
    const size_t per_frame = (size_t)a->frame_count * a->joint_count;
    REQUIRE(weft__all_finite(a->skin_matrices, per_frame * 16));
    REQUIRE(weft__all_finite(a->local_rotations, per_frame * 4));
}

static void pose_frames(const weft_skinned_asset *a)
{
    float *out = malloc((size_t)a->vertex_count * 3 * sizeof(float));
    REQUIRE(out != NULL);
    uint32_t posed = a->frame_count < MAX_POSED_FRAMES ? a->frame_count : MAX_POSED_FRAMES;
    for (uint32_t i = 0; i <= posed; ++i) {
        uint32_t f = i < posed ? i : a->frame_count - 1;
        REQUIRE(weft_skinned_pose(a, f, out) == WEFT_OK);
        REQUIRE(weft__all_finite(out, (size_t)a->vertex_count * 3));
    }
    weft__clear_error();
    REQUIRE(weft_skinned_pose(a, a->frame_count, out) == WEFT_ERROR_INVALID_ARGUMENT);
    REQUIRE(weft_last_error()[0] != '\0');
    free(out);
}

static void check_clip(weft_context *ctx, const weft_skinned_asset *a)
{
    weft_clip *clip = NULL;
    weft__clear_error();
    weft_result r = weft_skinned_to_clip(ctx, a, &clip);
    if (r != WEFT_OK) {
        REQUIRE(clip == NULL);
        REQUIRE(weft_last_error()[0] != '\0');
        return;
    }
    REQUIRE(clip && clip->frame_count == a->frame_count && clip->fps == a->fps);
    REQUIRE(weft__all_finite(clip->rotations, (size_t)clip->frame_count * WEFT_POSE_ROTATION_FLOATS));
    REQUIRE(weft__all_finite(clip->translations, (size_t)clip->frame_count * 3));
    weft_clip_destroy(clip);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static weft_context *ctx;
    static char path[KINDS][128];
    if (!ctx) {
        weft_context_def def = weft_default_context_def();
        REQUIRE(weft_context_create(&def, &ctx) == WEFT_OK);
        /* assimp runs in a child process: its faults refuse the input; a child that fails in
         * weft's own conversion after assimp returned aborts here, a defect to report. A hang
         * is refused after 20 s, below libFuzzer's -timeout. */
        weft__skinned_import_limits(20.0, true);
        const char *dir = getenv("TMPDIR");
        for (int i = 0; i < KINDS; ++i) {
            snprintf(path[i], sizeof path[i], "%.64s/weft_fuzz_gltf_%ld.%s", dir && *dir ? dir : "/tmp",
                     (long)getpid(), k_extension[i]);
        }
    }
    const char *file = path[kind_of(data, size)];
    FILE *f = fopen(file, "wb");
    REQUIRE(f != NULL);
    REQUIRE(fwrite(data, 1, size, f) == size);
    REQUIRE(fclose(f) == 0);

    const float fps = 30.0f;
    weft_skinned_asset *a = NULL;
    weft__clear_error();
    weft_result r = weft_skinned_load_file(ctx, file, fps, &a);
    remove(file);
    if (r != WEFT_OK) {
        REQUIRE(a == NULL);
        REQUIRE(weft_last_error()[0] != '\0');
        return 0;
    }
    REQUIRE(a != NULL);
    check_asset(a, fps);
    pose_frames(a);
    check_clip(ctx, a);
    weft_skinned_asset_destroy(a);
    return 0;
}
