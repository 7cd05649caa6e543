/*
 * Motion and character import (library weft_assets; link it with `pkg-config weft-assets` or
 * CMake's weft::weft_assets): BVH clips retargeted onto weft's SMPL-24 skeleton, skinned glTF 2.0
 * and FBX characters with their animation, SMPL bodies from .npz. These read files users bring,
 * through assimp, minizip and zlib, so they live apart from libweft, which has no dependency.
 * Every loader validates its input and fails with a result code and weft_last_error() naming the
 * problem; nothing is returned on failure.
 */
#ifndef WEFT_MOTION_H
#define WEFT_MOTION_H

#include "weft.h"
#include "weft/body.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------------------------------- */
/* BVH                                                                                         */

/*
 * BVH motion import (weft_assets), through assimp, retargeted onto the SMPL-24 skeleton.
 *
 *   weft_bvh_def def = weft_default_bvh_def();
 *   def.rest_joints = weft_body_rest_joints(avatar);     // scale translation to this body
 *   weft_clip *clip;
 *   weft_bvh_load_file(ctx, "/usr/share/assimp/models/BVH/01_01.bvh", &def, &clip);
 *   ... weft_clip_sample(clip, t, &pose); weft_body_pose(avatar, &pose, verts, NULL);
 *   weft_clip_destroy(clip);
 *
 * Skeletons recognised by joint names: CMU/MotionBuilder (Hips, LeftUpLeg, LowerBack, Spine,
 * Spine1, LeftShoulder = collar, LeftArm, LeftForeArm, LeftHand, ...), CMU's 3ds Max naming
 * (LeftHip, LeftKnee, LeftAnkle, LeftToe, lowerback, Chest, Chest2, lowerneck, Neck, Head,
 * LeftCollar, LeftShoulder = upper arm, LeftElbow, LeftWrist, lhand), the "collar" naming of
 * many mocap exports (Hips, Ab, Chest, LeftCollar, LeftShoulder = upper arm, LeftElbow,
 * LeftWrist, LeftHip, LeftKnee, LeftAnkle, LeftToes), Mixamo (mixamorig:Hips, LeftUpLeg, Spine,
 * Spine1, Spine2, ...; a namespace prefix before ':' is ignored), and SMPL's own names (pelvis,
 * left_hip, ... or Pelvis, L_Hip, ...), or any skeleton through a joint map (def.joint_map,
 * weft_bvh_read_joint_map). The naming with the most joints found is used; a
 * skeleton where it finds fewer than 21 of the 24 SMPL joints is refused with the missing joints
 * named (a partial match never passes silently), and def.report says what drove what. Source joints with no SMPL counterpart (CMU's LHipJoint, Neck1,
 * fingers) fold into their parents; SMPL joints with no source joint keep a zero local rotation.
 *
 * Retargeting (world-space delta): for every mapped joint the source's world rotation relative
 * to its rest, D = G(t) G(rest)^-1, is applied to the SMPL joint, whose rest is the zero-pose
 * T-pose (identity world rotations). A per-bone rest correction C (the smallest rotation taking
 * the SMPL rest bone direction onto the source rest bone direction) absorbs differences between
 * the two rest poses, so sources whose rest is not a T-pose work too. SMPL local rotations are
 * then G_parent^-1 G. The root translation is the source hips' path scaled by the ratio of leg
 * lengths (target / source, which also converts units), started above the origin in X and Z,
 * and stood on the target's floor: one vertical shift for the whole clip puts the 5th percentile
 * (over the imported frames) of the lowest foot joint (ankle or toe) at that joint's rest height,
 * since mocap floors are rarely at y = 0 (def.keep_source_height keeps the source's floor at
 * y = 0 instead). Frames are resampled to def.fps with quaternion slerp.
 *
 * Bad input (not BVH, truncated, NaN values, a value count that disagrees with Frames x
 * CHANNELS, an unknown skeleton, a retargeted root more than 10 km from the start) returns WEFT_ERROR_FORMAT, _NOT_FINITE or _SIZE_MISMATCH with
 * a message in weft_last_error(); *out_clip is untouched.
 */

/* How a file's skeleton was mapped onto SMPL-24 (weft_bvh_def.report). */
typedef struct weft_bvh_report {
    const char *naming;                         /* the naming recognised, e.g. "CMU/MotionBuilder" */
    uint32_t mapped;                            /* SMPL joints driven by a source joint */
    char source[WEFT_BODY_JOINTS][64];          /* the source joint of each SMPL joint; "" when none */
} weft_bvh_report;

typedef struct weft_bvh_def {
    float fps;                  /* output rate (default 60) */
    /* Rest joints (zero pose, 24 * 3, feet on y = 0) of the body the clip will drive, e.g.
     * weft_body_rest_joints(avatar). NULL: SMPL-neutral proportions of a 1.7 m body. */
    const float *rest_joints;
    /* Metres per BVH unit for the root path. 0 (default): the leg-length ratio. */
    float unit_scale;
    uint32_t first_frame;       /* first source frame to import (default 0) */
    uint32_t max_frames;        /* at most this many source frames; 0 = all */
    bool keep_horizontal_origin;/* keep the source's X/Z position instead of starting at 0 */
    /* keep the source's height (its floor at y = 0 lands on the target's floor) instead of
     * standing the clip on the target's floor (default false) */
    bool keep_source_height;
    weft_bvh_report *report;    /* optional output: the joint mapping of a successful load */
    /* A joint map instead of the naming tables: the source joint driving each SMPL joint, 24
     * entries in SMPL order (NULL or "" = none), e.g. from weft_bvh_read_joint_map. Each name
     * must be a joint of the file (matched like the tables: a namespace prefix before ':' is
     * ignored), or the load fails naming it; the same 21-of-24 and required-joint rules apply.
     * NULL (default): the naming tables. */
    const char *const *joint_map;
    uint32_t internal_cookie;
} weft_bvh_def;

WEFT_API weft_bvh_def weft_default_bvh_def(void);

/* A joint-name map file: one "smpl_joint source_joint" pair a line (SMPL names as
 * weft_joint_name gives them, e.g. "left_elbow LowerArm.L"; '#' starts a comment). Fills
 * out->names (SMPL order, "" when the file maps nothing to that joint) and out->entries (for
 * weft_bvh_def.joint_map). Fails with WEFT_ERROR_IO (unreadable) or WEFT_ERROR_FORMAT naming
 * the line: an unknown SMPL joint, one mapped twice, a missing or extra field, a name over 63
 * characters; out is untouched on failure. */
typedef struct weft_bvh_joint_map {
    char names[WEFT_BODY_JOINTS][64];
    const char *entries[WEFT_BODY_JOINTS];
} weft_bvh_joint_map;
WEFT_API weft_result weft_bvh_read_joint_map(const char *path, weft_bvh_joint_map *out);

/* Reads and retargets a BVH file, plain or gzip-compressed (at most 256 MiB either way). */
WEFT_API weft_result weft_bvh_load_file(weft_context *context, const char *path, const weft_bvh_def *def, weft_clip **out_clip);
/* Same from memory. */
WEFT_API weft_result weft_bvh_load_memory(weft_context *context, const void *data, size_t size, const weft_bvh_def *def,
                                 weft_clip **out_clip);

/* SMPL-neutral rest joints (zero pose, feet on y = 0, 24 * 3), the default target. */
WEFT_API const float *weft_bvh_default_rest_joints(void);

/* ---------------------------------------------------------------------------------------- */
/* Skinned meshes (glTF 2.0, FBX)                                                              */

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
    float *bind_matrices;           /* joint_count * 16, column-major: each joint's mesh-space transform in
                                     * the bind pose (the inverse of its inverse bind matrix) */
    weft_context *context;
} weft_skinned_asset;

/* Imports the first skinned mesh set and animation of a file assimp reads (glTF, FBX, ...),
 * sampling the animation at fps (1..1000). On POSIX systems assimp reads the file in a child
 * process (fork) whose answer is checked again here, so a file that crashes assimp, hangs it
 * (300 s) or makes it allocate without bound (16 GiB of address space) is refused with
 * WEFT_ERROR_FORMAT instead of taking the caller down. Call it where forking is acceptable (a
 * loading screen, a tool; not from a thread holding locks the child would need). */
WEFT_API weft_result weft_skinned_load_file(weft_context *context, const char *path, float fps, weft_skinned_asset **out_asset);

WEFT_API void weft_skinned_asset_destroy(weft_skinned_asset *asset);

/* Skinned positions at frame (0..frame_count-1), vertex_count * 3. Allocates nothing. */
WEFT_API weft_result weft_skinned_pose(const weft_skinned_asset *asset, uint32_t frame, float *out_positions);

/* The animation as an SMPL clip, for skeletons whose 24 joints carry SMPL names (pelvis,
 * left_hip, ... or Pelvis, L_Hip, ...): local rotations relative to each joint's rest
 * rotation, the root translation relative to its rest. Other skeletons: SIZE_MISMATCH or
 * FORMAT naming the missing joint. */
WEFT_API weft_result weft_skinned_to_clip(weft_context *context, const weft_skinned_asset *asset, weft_clip **out_clip);

/* Writes a body and a clip as a glTF 2.0 skinned mesh: gltf_path (JSON) and, next to it, the
 * same name with ".bin". 24 joint nodes with SMPL names whose rest translations are the body's
 * zero-pose joint offsets, the mesh in its bind pose with the matching inverse bind matrices,
 * the four largest weights per vertex, and one animation (per-joint rotations, root
 * translation) at the clip's rate. clip may be NULL (no animation). */
WEFT_API weft_result weft_gltf_write_body(const char *gltf_path, const weft_body *body, const weft_clip *clip);

/* ---------------------------------------------------------------------------------------- */
/* SMPL bodies from .npz                                                                       */

/* Loads an SMPL-format model: v_template (V,3), f (F,3), weights (V,24), J_regressor dense
 * (24,V) or sparse (J_regressor_data / _indices / _indptr / _shape, CSR or CSC as scipy
 * stores them), kintree_table (2,24), optional shapedirs (V,3,B) and posedirs (V,3,207).
 * Any dtype numpy writes for them (float16/32/64, integers), either storage order. Every array
 * is validated before use; WEFT_ERROR_FORMAT (or IO / OUT_OF_MEMORY) names the entry. */
WEFT_API weft_result weft_smpl_load_npz_file(weft_context *context, const char *path, weft_body **out_body);
WEFT_API weft_result weft_smpl_load_npz_memory(weft_context *context, const void *bytes, size_t size,
                                               weft_body **out_body);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_MOTION_H */
