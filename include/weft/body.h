/*
 * weft/body.h — bodies, motion and garment meshes.
 *
 *   Skeleton   SMPL's 24 joints, names and parents (weft_joint_name / weft_joint_parent).
 *   Body       a skinned mesh on that skeleton: linear blend skinning with optional shape
 *              blend shapes (betas) and pose blend shapes (SMPL posedirs). Made either from
 *              arrays (weft_body_create; the SMPL .npz loader in weft_assets fills the def)
 *              or procedurally (weft_avatar_create: weft's own mannequin).
 *   Motion     poses in SMPL convention (24 axis-angle local rotations + root translation),
 *              from procedural clips (weft_motion_*) or from imported clips (weft_clip).
 *   Wardrobe   procedural garments fitted to the avatar and flat cloth sheets, at several
 *              resolutions of one parameterisation (weft_wardrobe_create).
 *
 * Pose convention (SMPL): metres, +Y up, the body faces +Z, +X is the body's left. A zero pose
 * is the T-pose. Rotations are local (relative to the parent joint's frame) axis-angle vectors,
 * rotation angle = vector length in radians. The root translation is added to every vertex.
 *
 * Bind pose: the mesh of a body is skinned from the pose it was built in. SMPL files are built
 * in the T-pose (bind pose zero). weft's avatar is built in an A-pose (arms about 45 degrees
 * down), which garments are fitted in; weft_body_bind_pose() returns that pose, and skinning
 * uses inverse bind matrices, so a zero pose still gives a T-pose.
 */
#ifndef WEFT_BODY_H
#define WEFT_BODY_H

#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------------------------------- */
/* Skeleton                                                                                   */

#define WEFT_BODY_JOINTS 24
#define WEFT_POSE_ROTATION_FLOATS (3 * WEFT_BODY_JOINTS) /* 72 */
#define WEFT_POSE_BLEND_FLOATS (9 * (WEFT_BODY_JOINTS - 1)) /* 207: posedirs basis size */

typedef enum weft_joint {
    WEFT_JOINT_PELVIS = 0,
    WEFT_JOINT_LEFT_HIP,
    WEFT_JOINT_RIGHT_HIP,
    WEFT_JOINT_SPINE1,
    WEFT_JOINT_LEFT_KNEE,
    WEFT_JOINT_RIGHT_KNEE,
    WEFT_JOINT_SPINE2,
    WEFT_JOINT_LEFT_ANKLE,
    WEFT_JOINT_RIGHT_ANKLE,
    WEFT_JOINT_SPINE3,
    WEFT_JOINT_LEFT_FOOT,
    WEFT_JOINT_RIGHT_FOOT,
    WEFT_JOINT_NECK,
    WEFT_JOINT_LEFT_COLLAR,
    WEFT_JOINT_RIGHT_COLLAR,
    WEFT_JOINT_HEAD,
    WEFT_JOINT_LEFT_SHOULDER,
    WEFT_JOINT_RIGHT_SHOULDER,
    WEFT_JOINT_LEFT_ELBOW,
    WEFT_JOINT_RIGHT_ELBOW,
    WEFT_JOINT_LEFT_WRIST,
    WEFT_JOINT_RIGHT_WRIST,
    WEFT_JOINT_LEFT_HAND,
    WEFT_JOINT_RIGHT_HAND
} weft_joint;

/* SMPL joint name ("pelvis", "left_hip", ...), or NULL when joint >= 24. */
WEFT_API const char *weft_joint_name(uint32_t joint);
/* Parent joint index, -1 for the pelvis (and for joint >= 24). Parents precede children. */
WEFT_API int32_t weft_joint_parent(uint32_t joint);

/* One pose: local axis-angle rotations of the 24 joints and the root translation. */
typedef struct weft_pose {
    float rotations[WEFT_POSE_ROTATION_FLOATS]; /* joint j: rotations[3*j+0..2] */
    float translation[3];
} weft_pose;

/* ---------------------------------------------------------------------------------------- */
/* Body: a skinned mesh on the SMPL-24 skeleton.                                              */

typedef struct weft_body weft_body;

/* Arrays describing a body; all are copied at creation. Layouts are C order (row-major). */
typedef struct weft_body_def {
    const float *vertices;              /* vertex_count * 3: the template mesh in its bind pose */
    uint32_t vertex_count;
    const uint32_t *triangles;          /* triangle_count * 3, counter-clockwise from outside */
    uint32_t triangle_count;
    const float *weights;               /* vertex_count * 24 skinning weights, rows sum to 1 */

    /* Rest joints (zero pose), one of:
     *   joints           24 * 3 positions, or
     *   j_regressor      dense 24 * vertex_count, J = j_regressor * v_shaped, or
     *   CSR regressor    j_regressor_indptr (25 entries), j_regressor_indices and
     *                    j_regressor_data (j_regressor_nnz entries each): row j lists the
     *                    vertices and factors that make joint j.
     * A regressor is re-applied after every weft_body_set_shape(). */
    const float *joints;
    const float *j_regressor;
    const uint32_t *j_regressor_indptr;
    const uint32_t *j_regressor_indices;
    const float *j_regressor_data;
    uint32_t j_regressor_nnz;

    /* Kinematic tree: 24 parents (-1 for the root). NULL means SMPL's tree. A different tree
     * must keep parents before children. */
    const int32_t *parents;

    /* Optional shape blend shapes: vertex_count * 3 * shape_count (SMPL's (V, 3, B) layout). */
    const float *shapedirs;
    uint32_t shape_count;
    /* Optional pose blend shapes: vertex_count * 3 * 207 (SMPL's (V, 3, 207) layout), driven by
     * the entries of R(theta_j) - I for joints 1..23, row-major per joint. */
    const float *posedirs;

    /* Pose the template mesh is in; NULL means the zero (T) pose. Only with `joints` (a
     * regressor reads joints off the mesh, which then must be in the zero pose). */
    const weft_pose *bind_pose;

    uint32_t internal_cookie;           /* set by weft_default_body_def(); do not touch */
} weft_body_def;

WEFT_API weft_body_def weft_default_body_def(void);

/* Validates every array (finite, indices in range, weights non-negative summing to 1 within
 * 1e-3, parents ordered, no zero-area triangle) and copies it. */
WEFT_API weft_result weft_body_create(weft_context *context, const weft_body_def *def, weft_body **out_body);
WEFT_API void weft_body_destroy(weft_body *body);

WEFT_API uint32_t weft_body_vertex_count(const weft_body *body);
WEFT_API uint32_t weft_body_triangle_count(const weft_body *body);
WEFT_API const uint32_t *weft_body_triangles(const weft_body *body);
/* Template vertices after the current shape (v_shaped), in the bind pose, vertex_count * 3. */
WEFT_API const float *weft_body_rest_vertices(const weft_body *body);
/* Skinning weights, vertex_count * 24. */
WEFT_API const float *weft_body_weights(const weft_body *body);
/* Body parts for the garment's body collision (weft_garment_def.collision.triangle_parts): for
 * each triangle, the joint (0..23) with the largest summed skinning weight over its three
 * corners, ties to the lower joint; triangle_count entries. */
WEFT_API weft_result weft_body_triangle_parts(const weft_body *body, uint8_t *out_parts, uint32_t count);
/* Rest joint positions (zero pose) for the current shape, 24 * 3. */
WEFT_API const float *weft_body_rest_joints(const weft_body *body);
/* The pose the template is in (zero for SMPL files, an A-pose for the avatar). */
WEFT_API void weft_body_bind_pose(const weft_body *body, weft_pose *out_pose);
/* Number of shape coefficients (betas) the body accepts; 0 when it has no shapedirs. */
WEFT_API uint32_t weft_body_shape_count(const weft_body *body);

/* Sets the betas (count <= shape_count; missing ones are 0) and recomputes v_shaped and,
 * with a regressor, the joints. Allocates nothing. NaN -> WEFT_ERROR_NOT_FINITE. */
WEFT_API weft_result weft_body_set_shape(weft_body *body, const float *betas, uint32_t count);

/* Poses the body: out_vertices (vertex_count * 3, may be NULL) gets the skinned vertices,
 * out_joint_transforms (24 * 16, may be NULL) each joint's world transform, a column-major 4x4
 * matrix (cglm mat4 layout) whose translation is the posed joint position. Allocates nothing,
 * touches nothing else, and may be called from several threads at once. NaN in the pose ->
 * WEFT_ERROR_NOT_FINITE and the outputs are untouched. */
WEFT_API weft_result weft_body_pose(const weft_body *body, const weft_pose *pose, float *out_vertices,
                                    float *out_joint_transforms);

/* Skins other points bound to this body in its bind pose (a garment's rest positions with
 * weights from weft_wardrobe_create): out = sum_j w_j * M_j(pose) * M_j(bind)^-1 * p.
 * weights is count * 24. out must not alias rest_points. Allocates nothing. */
WEFT_API weft_result weft_body_skin_points(const weft_body *body, const weft_pose *pose, const float *rest_points,
                                           const float *weights, uint32_t count, float *out_points);

/* ---------------------------------------------------------------------------------------- */
/* The default avatar: a procedural mannequin on the SMPL-24 skeleton.                        */

typedef struct weft_avatar_def {
    float height;            /* standing height in metres, soles to crown (default 1.70) */
    float girth;             /* scales limb and torso thickness (default 1; 0.7 .. 1.3) */
    float leg_fraction;      /* hip joint height / height (default 0.50; 0.42 .. 0.58) */
    float shoulder_width;    /* scales the shoulder span (default 1; 0.8 .. 1.25) */
    float hip_width;         /* scales the hip span and hip volume (default 1; 0.8 .. 1.3) */
    float chest;             /* scales chest depth (default 1; 0.8 .. 1.3) */
    float arm_angle_deg;     /* bind pose: arms this far below horizontal (default 45; 0 .. 60) */
    uint32_t target_vertices;/* mesh size aimed at (default 8000; 2000 .. 40000), within ~15% */
    uint32_t internal_cookie;
} weft_avatar_def;

WEFT_API weft_avatar_def weft_default_avatar_def(void);

/* Builds the mannequin: a closed genus-0 2-manifold skin (orientation outward), smooth
 * skinning weights, joints on the SMPL tree, bind pose = the A-pose of arm_angle_deg.
 * Deterministic for the same def. Takes about a second at 8k vertices. Feet rest on y = 0 in
 * the bind pose, the body is centred on x = 0, z = 0 at the pelvis. A shape whose parts would
 * touch (a handle in the skin) fails with WEFT_ERROR_DEGENERATE_MESH. */
WEFT_API weft_result weft_avatar_create(weft_context *context, const weft_avatar_def *def, weft_body **out_body);

/* Signed distance-like value of the avatar's implicit surface at p in the bind pose
 * (negative inside, ~metres near the surface). Bodies not made by weft_avatar_create return
 * WEFT_ERROR_UNSUPPORTED. */
WEFT_API weft_result weft_avatar_distance(const weft_body *body, const float *points, uint32_t count,
                                          float *out_distance);

/* ---------------------------------------------------------------------------------------- */
/* Motion clips                                                                               */

typedef enum weft_motion {
    WEFT_MOTION_IDLE = 0,     /* breathing, slight sway (loops) */
    WEFT_MOTION_WALK,         /* walk in place (loops; translation stays near the origin) */
    WEFT_MOTION_RUN,          /* run in place (loops) */
    WEFT_MOTION_JUMP,         /* crouch, jump, land (loops with a pause) */
    WEFT_MOTION_DANCE,        /* spin on the spot with swinging arms and hips (loops) */
    WEFT_MOTION_ARM_RAISE,    /* arms from the sides to overhead and back (loops) */
    WEFT_MOTION_FLIP,         /* a fast full rotation about the X axis in the air (loops) */
    WEFT_MOTION_COUNT
} weft_motion;

typedef struct weft_motion_def {
    weft_motion motion;
    float speed;              /* time scale: 2 plays twice as fast (default 1; > 0, <= 8) */
    float amplitude;          /* scales the joint angles (default 1; 0 .. 1.5) */
    float height;             /* body height the motion is scaled to, for translations (default 1.70) */
    float arm_spread;         /* radians the upper arms are held further from the torso, applied at the
                               * shoulder before the motion's own rotation (default 0; 0 .. 0.8). Keeps
                               * arms from closing on cloth at the chest's sides (docs/REFSIM.md) */
    uint32_t internal_cookie;
} weft_motion_def;

WEFT_API weft_motion_def weft_default_motion_def(weft_motion motion);
/* "idle", "walk", ...; NULL when out of range. */
WEFT_API const char *weft_motion_name(weft_motion motion);
/* Looks a motion up by name; WEFT_ERROR_INVALID_ARGUMENT when unknown. */
WEFT_API weft_result weft_motion_from_name(const char *name, weft_motion *out_motion);
/* Length of one cycle in seconds at the def's speed. */
WEFT_API double weft_motion_period(const weft_motion_def *def);
/* The pose at time t (seconds, any value: clips loop). Smooth in t. Allocates nothing. */
WEFT_API weft_result weft_motion_sample(const weft_motion_def *def, double t, weft_pose *out_pose);

/* A sampled clip: frames of SMPL-24 poses at a fixed rate. Imported motions (BVH) fill one;
 * procedural motions can be baked into one. The arrays belong to the clip. */
typedef struct weft_clip {
    uint32_t frame_count;
    float fps;                /* frames per second, > 0 */
    bool loops;               /* sampling past the end wraps (else it holds the last frame) */
    float *rotations;         /* frame_count * 72 axis-angle, frame f at rotations[72*f] */
    float *translations;      /* frame_count * 3 root translation */
    weft_context *context;    /* owner; set by weft_clip_create */
    char name[64];            /* free text, e.g. the source file's stem */
} weft_clip;

/* Allocates a clip with zeroed frames. */
WEFT_API weft_result weft_clip_create(weft_context *context, uint32_t frame_count, float fps, weft_clip **out_clip);
WEFT_API void weft_clip_destroy(weft_clip *clip);
/* (1 - u) a + u b for poses: each joint's rotation by quaternion slerp (the shorter way),
 * the root translation linearly; u in [0, 1]. Blends a character into a clip (the render
 * sample settles from the bind pose into a clip's first frame this way) or between two clips. */
WEFT_API weft_result weft_pose_blend(const weft_pose *a, const weft_pose *b, double u, weft_pose *out_pose);

/* Interpolated pose at time t: rotations by quaternion slerp, translation linearly. */
WEFT_API weft_result weft_clip_sample(const weft_clip *clip, double t, weft_pose *out_pose);
/* A new clip of the same duration at `fps` (e.g. 60). Rejects non-finite frames. */
WEFT_API weft_result weft_clip_resample(const weft_clip *clip, float fps, weft_clip **out_clip);
/* Bakes `duration` seconds of a procedural motion at `fps`. */
WEFT_API weft_result weft_clip_from_motion(weft_context *context, const weft_motion_def *def, double duration,
                                           float fps, weft_clip **out_clip);

/* ---------------------------------------------------------------------------------------- */
/* Wardrobe: garments fitted to the avatar, and cloth sheets.                                 */

typedef enum weft_cloth_kind {
    WEFT_CLOTH_TSHIRT = 0,    /* torso tube with short sleeves; neck, hem and sleeve openings */
    WEFT_CLOTH_SKIRT,         /* flared tube from the waist to above the knees */
    WEFT_CLOTH_DRESS,         /* fitted bodice from the chest flaring to below the knees */
    WEFT_CLOTH_SHEET,         /* square sheet, `size` metres a side, in the XZ plane */
    WEFT_CLOTH_SHEET_IRREGULAR, /* wavy-outlined sheet of about size x size, unstructured mesh */
    WEFT_CLOTH_COUNT
} weft_cloth_kind;

typedef enum weft_cloth_resolution {
    WEFT_CLOTH_RES_1K = 0,    /* about 1,000 vertices */
    WEFT_CLOTH_RES_4K,        /* about 4,000 */
    WEFT_CLOTH_RES_16K,       /* about 16,000 */
    WEFT_CLOTH_RES_40K,       /* about 40,000 */
    WEFT_CLOTH_RES_COUNT
} weft_cloth_resolution;

typedef struct weft_cloth_def {
    weft_cloth_kind kind;
    weft_cloth_resolution resolution;
    uint32_t target_vertices; /* overrides resolution when non-zero (200 .. 200000) */
    float clearance;          /* garments: minimum gap to the body skin, metres (default 0.01) */
    float ease;               /* garments: extra looseness over the clearance (default 0.01) */
    float size;               /* sheets: edge length in metres (default 1.0) */
    float height;             /* sheets: y of the sheet plane (default 1.0) */
    uint32_t internal_cookie;
} weft_cloth_def;

/* A cloth mesh; every array belongs to it. */
typedef struct weft_cloth_mesh {
    weft_cloth_kind kind;
    uint32_t vertex_count;
    uint32_t triangle_count;
    float *positions;         /* vertex_count * 3 rest positions (garments: on the body's bind pose) */
    uint32_t *triangles;      /* triangle_count * 3, counter-clockwise seen from outside (sheets: +Y) */
    float *uvs;               /* vertex_count * 2, pattern coordinates in metres */
    float *weights;           /* vertex_count * 24 skinning weights from the nearest body point; NULL for sheets */
    weft_context *context;
} weft_cloth_mesh;

WEFT_API weft_cloth_def weft_default_cloth_def(weft_cloth_kind kind);
WEFT_API const char *weft_cloth_kind_name(weft_cloth_kind kind);                 /* "tshirt", ... */
WEFT_API weft_result weft_cloth_kind_from_name(const char *name, weft_cloth_kind *out_kind);
WEFT_API const char *weft_cloth_resolution_name(weft_cloth_resolution res);     /* "1k", ... */
WEFT_API weft_result weft_cloth_resolution_from_name(const char *name, weft_cloth_resolution *out_res);

/* Builds a garment or sheet. Garments need a body made by weft_avatar_create (they are fitted
 * to its bind pose; WEFT_ERROR_UNSUPPORTED otherwise, or when the body's arms would cross the
 * garment); sheets ignore body (may be NULL). Deterministic; takes up to a few seconds for a
 * 40k T-shirt. */
WEFT_API weft_result weft_cloth_create(weft_context *context, const weft_cloth_def *def, const weft_body *body,
                                       weft_cloth_mesh **out_mesh);
WEFT_API void weft_cloth_destroy(weft_cloth_mesh *mesh);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_BODY_H */
