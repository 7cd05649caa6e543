/*
 * Skinned meshes and their animation: glTF 2.0 (and FBX, Collada, ... through assimp) import,
 * and a small glTF 2.0 writer for skinned meshes (weft_assets).
 *
 *   weft_skinned_asset *a;
 *   weft_skinned_load_file(ctx, "/usr/share/assimp/models/glTF2/simple_skin/simple_skin.gltf", 60.0f, &a);
 *   weft_skinned_pose(a, frame, positions);          // linear blend skinning at a frame
 *   weft_skinned_to_clip(ctx, a, &clip);             // SMPL-named skeletons -> weft_clip
 *   weft_skinned_asset_destroy(a);
 *
 *   weft_gltf_write_body(path, body, clip);          // weft's avatar + a motion -> .gltf + .bin
 *
 * Import keeps the file's vertex order, merges every skinned mesh of the scene into one, keeps
 * the four largest weights per vertex (renormalised) and samples the first animation at a fixed
 * rate (translation lerp, rotation slerp, scale lerp between keys). Bad input (unreadable file,
 * no skinned mesh, out-of-range weights, NaN) fails with WEFT_ERROR_FORMAT / _NOT_FINITE and a
 * message; nothing is returned. glTF files are checked before assimp reads them: a skin must
 * name inverseBindMatrices, a float MAT4 accessor with a matrix per joint (optional in glTF 2.0,
 * but assimp 5.2 crashes without it), and the JSON must parse.
 */
#ifndef WEFT_ASSETS_GLTF_H
#define WEFT_ASSETS_GLTF_H

#include "weft.h"
#include "weft/body.h"

#ifdef __cplusplus
extern "C" {
#endif

#define WEFT_SKIN_MAX_JOINTS 256u
#define WEFT_SKIN_NAME 64u

typedef struct weft_skinned_asset {
    uint32_t vertex_count, triangle_count, joint_count;
    float *positions;               /* vertex_count * 3, bind pose (mesh space) */
    uint32_t *triangles;            /* triangle_count * 3 */
    uint32_t *joint_indices;        /* vertex_count * 4 */
    float *joint_weights;           /* vertex_count * 4, rows sum to 1 */
    char (*joint_names)[WEFT_SKIN_NAME];
    int32_t *parents;               /* joint_count: parent joint, -1 when no ancestor is a joint */
    uint32_t frame_count;           /* >= 1 (1 when the file has no animation: the rest pose) */
    float fps;
    float *skin_matrices;           /* frame_count * joint_count * 16, column-major: global * inverse bind */
    float *local_rotations;         /* frame_count * joint_count * 4, quaternion x y z w, node-local */
    float *local_translations;      /* frame_count * joint_count * 3, node-local */
    float *rest_rotations;          /* joint_count * 4, node-local rotation in the file's node tree */
    float *rest_translations;       /* joint_count * 3 */
    weft_context *context;
} weft_skinned_asset;

/* Imports the first skinned mesh set and animation of a file assimp reads (glTF, FBX, ...),
 * sampling the animation at fps (1..1000). On POSIX systems assimp reads the file in a child
 * process (fork) whose answer is checked again here, so a file that crashes assimp, hangs it
 * (300 s) or makes it allocate without bound (16 GiB of address space) is refused with
 * WEFT_ERROR_FORMAT instead of taking the caller down. Call it where forking is acceptable (a
 * loading screen, a tool; not from a thread holding locks the child would need). */
weft_result weft_skinned_load_file(weft_context *context, const char *path, float fps, weft_skinned_asset **out_asset);

/* Tests and fuzzers: the child's wall-clock limit (seconds > 0; default 300), and strict mode,
 * in which a child that fails after assimp returned (in weft's own conversion code) aborts the
 * caller, so a fuzzer reports it as the defect it is. */
void weft__skinned_import_limits(double seconds, bool strict);
void weft_skinned_asset_destroy(weft_skinned_asset *asset);

/* Skinned positions at frame (0..frame_count-1), vertex_count * 3. Allocates nothing. */
weft_result weft_skinned_pose(const weft_skinned_asset *asset, uint32_t frame, float *out_positions);

/* The animation as an SMPL clip, for skeletons whose 24 joints carry SMPL names (pelvis,
 * left_hip, ... or Pelvis, L_Hip, ...): local rotations relative to each joint's rest
 * rotation, the root translation relative to its rest. Other skeletons: SIZE_MISMATCH or
 * FORMAT naming the missing joint. */
weft_result weft_skinned_to_clip(weft_context *context, const weft_skinned_asset *asset, weft_clip **out_clip);

/* Writes a body and a clip as a glTF 2.0 skinned mesh: gltf_path (JSON) and, next to it, the
 * same name with ".bin". 24 joint nodes with SMPL names whose rest translations are the body's
 * zero-pose joint offsets, the mesh in its bind pose with the matching inverse bind matrices,
 * the four largest weights per vertex, and one animation (per-joint rotations, root
 * translation) at the clip's rate. clip may be NULL (no animation). */
weft_result weft_gltf_write_body(const char *gltf_path, const weft_body *body, const weft_clip *clip);

#ifdef __cplusplus
}
#endif

#endif
