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
 * lengths (target / source, which also converts units), placed so that a source floor at y = 0
 * lands on the target's floor, and started above the origin in X and Z. Frames are resampled to
 * def.fps with quaternion slerp.
 *
 * Bad input (not BVH, truncated, NaN values, a value count that disagrees with Frames x
 * CHANNELS, an unknown skeleton, a retargeted root more than 10 km from the start) returns WEFT_ERROR_FORMAT, _NOT_FINITE or _SIZE_MISMATCH with
 * a message in weft_last_error(); *out_clip is untouched.
 */
#ifndef WEFT_ASSETS_BVH_H
#define WEFT_ASSETS_BVH_H

#include "weft.h"
#include "weft/body.h"

#ifdef __cplusplus
extern "C" {
#endif

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
    weft_bvh_report *report;    /* optional output: the joint mapping of a successful load */
    /* A joint map instead of the naming tables: the source joint driving each SMPL joint, 24
     * entries in SMPL order (NULL or "" = none), e.g. from weft_bvh_read_joint_map. Each name
     * must be a joint of the file (matched like the tables: a namespace prefix before ':' is
     * ignored), or the load fails naming it; the same 21-of-24 and required-joint rules apply.
     * NULL (default): the naming tables. */
    const char *const *joint_map;
    uint32_t internal_cookie;
} weft_bvh_def;

weft_bvh_def weft_default_bvh_def(void);

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
weft_result weft_bvh_read_joint_map(const char *path, weft_bvh_joint_map *out);

/* Reads and retargets a BVH file, plain or gzip-compressed (at most 256 MiB either way). */
weft_result weft_bvh_load_file(weft_context *context, const char *path, const weft_bvh_def *def, weft_clip **out_clip);
/* Same from memory. */
weft_result weft_bvh_load_memory(weft_context *context, const void *data, size_t size, const weft_bvh_def *def,
                                 weft_clip **out_clip);

/* SMPL-neutral rest joints (zero pose, feet on y = 0, 24 * 3), the default target. */
const float *weft_bvh_default_rest_joints(void);

#ifdef __cplusplus
}
#endif

#endif
