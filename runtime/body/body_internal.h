/* Internal layout of weft_body and helpers shared by the body, avatar and wardrobe code. */
#ifndef WEFT_BODY_INTERNAL_H
#define WEFT_BODY_INTERNAL_H

#include "core/core.h"
#include "weft/body.h"

#include <cglm/cglm.h>

/* One primitive of the avatar's implicit surface: a capsule with radii varying linearly from
 * a to b, optionally squashed into an ellipse across its axis (scale along `side` and `front`). */
typedef struct weft_avatar_part {
    float a[3], b[3];        /* segment end points (bind pose) */
    float ra, rb;            /* radii at a and b */
    float side[3];           /* unit axis of the first cross-section scale */
    float sx, sz;            /* cross-section scale along `side` and along axis x side */
    float blend;             /* smooth-union radius with the parts before it */
    uint8_t joint;           /* bone the part follows (skinning) */
    uint8_t joint_b;         /* joint at the b end (weights blend towards it) */
    /* Derived once by the builder: axis, cross-section frame, bounding sphere. */
    float u[3], t[3], w[3];
    float ab[3], inv_l2, inv_sx, inv_sz, smin;
    float center[3], bound;  /* every point within `bound` of center may be inside */
    float smax;
} weft_avatar_part;

#define WEFT_AVATAR_MAX_PARTS 64

typedef struct weft_avatar_shape {
    weft_avatar_def def;
    uint32_t part_count;
    weft_avatar_part parts[WEFT_AVATAR_MAX_PARTS];
    float bind_joints[WEFT_BODY_JOINTS * 3]; /* joint positions in the bind (A) pose */
    float feet_y;                            /* lowest point, 0 after placement */
} weft_avatar_shape;

struct weft_body {
    weft_context *context;
    uint32_t vertex_count, triangle_count, shape_count;
    float *template_vertices;      /* as given, bind pose */
    float *shaped_vertices;        /* template + shapedirs * betas */
    uint32_t *triangles;
    float *weights;                /* vertex_count * 24 */
    float *shapedirs;              /* vertex_count * 3 * shape_count, or NULL */
    float *posedirs;               /* vertex_count * 3 * 207, or NULL */
    float *j_regressor;            /* dense 24 * vertex_count, or NULL */
    uint32_t *csr_indptr, *csr_indices;
    float *csr_data;
    uint32_t csr_nnz;
    int32_t parents[WEFT_BODY_JOINTS];
    float joints[WEFT_BODY_JOINTS * 3]; /* rest (zero-pose) joints for the current shape */
    bool has_bind_pose;
    weft_pose bind_pose;
    mat4 inverse_bind[WEFT_BODY_JOINTS];
    weft_avatar_shape *avatar;     /* set by weft_avatar_create, else NULL */
};

/* SMPL parents. */
extern const int32_t weft__smpl_parents[WEFT_BODY_JOINTS];

/* Rodrigues: rotation matrix of an axis-angle vector (stable for tiny angles). */
void weft__axis_angle_to_mat3(const float *aa, mat3 out);
/* World transforms of all joints for `pose` on rest joints `joints`. */
void weft__forward_kinematics(const int32_t *parents, const float *joints, const weft_pose *pose,
                              mat4 out_world[WEFT_BODY_JOINTS]);
/* Skinning matrices world * inverse_bind. */
void weft__skinning_matrices(const weft_body *body, const weft_pose *pose, mat4 out[WEFT_BODY_JOINTS],
                             mat4 out_world[WEFT_BODY_JOINTS]);

/* Avatar implicit value (negative inside) in the bind pose; `part_out` gets the nearest part. */
float weft__avatar_field(const weft_avatar_shape *shape, const float *p, uint32_t *part_out);
/* Same, from only the parts that follow the joints in joint_mask (bit j = joint j). */
float weft__avatar_field_masked(const weft_avatar_shape *shape, const float *p, uint32_t joint_mask);
/* Smooth skinning weights (24) for a point near the avatar's surface. */
void weft__avatar_point_weights(const weft_avatar_shape *shape, const float *p, float *out_weights);

#endif
