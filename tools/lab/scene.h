/* Scene assembly for the dataset scenarios: growable float/uint32 meshes, procedural cloth
 * sheets and rigid objects, and the per-frame kinematics (collider and pins). Scene
 * construction runs once per sequence, outside any per-frame path, so it uses malloc. */
#ifndef WEFT_XPBD_SCENE_H
#define WEFT_XPBD_SCENE_H

#include "weft/body.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

typedef struct xmesh {
    float *pos;
    uint32_t *tris;
    uint32_t nv, nt, cap_v, cap_t;
} xmesh;

void xmesh_free(xmesh *m);
bool xmesh_append(xmesh *dst, const xmesh *src);

/* Deterministic generator (splitmix64). */
typedef struct xrng {
    uint64_t s;
} xrng;
uint64_t xrng_next(xrng *r);
double xrng_uniform(xrng *r, double lo, double hi);
uint32_t xrng_below(xrng *r, uint32_t n);

typedef enum xsheet_shape { XSHEET_RECT = 0, XSHEET_ELLIPSE, XSHEET_LSHAPE, XSHEET_COUNT } xsheet_shape;

/* Sheet of about target_vertices vertices, size sx x sz, in the XZ plane at the origin. */
bool xsheet_make(xmesh *m, xsheet_shape shape, double sx, double sz, uint32_t target_vertices);
const char *xsheet_shape_name(xsheet_shape shape);

/* Closed rigid shapes (outward triangles). yaw rotates about +Y. */
bool xshape_box(xmesh *m, const double c[3], const double half[3], double yaw);
bool xshape_sphere(xmesh *m, const double c[3], double r, uint32_t rings, uint32_t segs);
bool xshape_cylinder(xmesh *m, const double c[3], double r, double half_len, int axis, uint32_t segs);
bool xshape_torus(xmesh *m, const double c[3], double R, double r, uint32_t segs_major, uint32_t segs_minor);
bool xshape_blob(xmesh *m, const double c[3], double r, xrng *rng);
bool xshape_ground(xmesh *m, double half);

/* A scenario instance: everything the sequence runner needs per frame. */
typedef struct xscene {
    weft_sim_scenario scenario;
    xmesh cloth;                 /* rest = initial positions */
    float *cloth_init;           /* initial positions (cloth.pos is the rest shape) */
    xmesh collider;              /* at frame 0 */
    uint32_t moving_begin;       /* collider vertices [moving_begin, nv) are animated (gripper) */
    char description[160];
    char objects[256];           /* comma-separated object names */
    /* Gripper schedule (frame times) and geometry. */
    double grasp[3], lift, move[2];
    uint32_t f_close, f_lifted, f_moved, f_lowered, f_release, f_open;
    double finger_half[3], gap_open, gap_closed;
    float *finger_rest;          /* 16 finger vertices relative to the gripper centre at gap 0 */
    uint32_t *grasped;
    uint32_t grasp_count;
    float *grasp_offset;         /* grasped vertex position relative to the gripper centre */
    /* Garment scenario: avatar, motion and the drape pre-roll (frames before recording). */
    weft_body *body;
    weft_motion_def motion;
    weft_clip *clip;             /* motion capture (def.motion_path), else NULL: `motion` */
    double clip_start_s, clip_speed;
    /* The clip's window starts where the bind pose stands, facing as it does: every pose is
     * turned by -clip_yaw about the vertical through the start's pelvis, which moves over the
     * bind pose's pelvis (clip_from: the start's pelvis, clip_to: the bind pose's; floor points
     * x, z, weft_pose_pelvis_xz). */
    double clip_yaw, clip_from[2], clip_to[2];
    uint8_t *parts;              /* collider triangle parts (clip and character scenes), else NULL */
    const weft_sim_character *character; /* the host's character (def.character), else NULL */
    weft_pose bind_pose, start_pose;
    uint32_t preroll;
    float ease_in_s;             /* the motion's time ramps in over this after the pre-roll (0: none) */
    float garment_clearance;     /* the wardrobe clearance the garment was made with */
    int cloth_kind;              /* the garment's weft_cloth_kind */
    /* Waistband (skirts, dresses): the garment's top ring rides on the body like an elastic
     * band. Each band vertex keeps its bind-pose offset in the frame of its closest body
     * triangle (barycentric point + offset along the edge, bitangent and normal). */
    uint32_t band_count;
    uint32_t band_released; /* band vertices left free because an arm comes down onto them */
    uint32_t *band_idx, *band_tri;
    float *band_bary, *band_off; /* 3 per band vertex each */
} xscene;

/* Frame indices passed to the per-frame functions count from the start of the pre-roll
 * (garments drape for `preroll` frames before frame 0 of the recording). */
/* A gentler take of the same garment scene, for a sequence the validator rejected: the avatar's
 * arms held wider still (added to the def's garment_arm_spread, radians), the motion eased in from rest over
 * ease_in_s seconds after the pre-roll instead of starting at full speed, and its joint angles
 * scaled by amplitude_scale (runs and jumps at full amplitude make most of the other rejections). */
typedef struct xscene_gentle {
    float arm_spread;
    float ease_in_s;
    float amplitude_scale;
} xscene_gentle;

/* gentle: NULL for the scene as drawn (garments only; every other draw is the same either way). */
weft_result xscene_build(weft_context *ctx, xscene *sc, const weft_sim_sequence_def *def, uint64_t seed,
                         const xscene_gentle *gentle);
void xscene_free(xscene *sc);
/* Collider positions at frame f into out (collider.nv * 3). */
void xscene_collider_at(const xscene *sc, uint32_t f, float *out);
/* The XPBD garment of the scene's cloth: its initial positions against the collider at frame 0,
 * `substeps` per frame and up to fast_collider_factor times that in frames whose collider moves
 * fast near the cloth (1: fixed). No CCD: ground truth is certified by the validator, never
 * post-processed. The def points into sc. */
weft_garment_def xscene_garment_def(const xscene *sc, uint32_t substeps, uint32_t fast_collider_factor);
/* Pins at frame f given the collider at f (from xscene_collider_at): writes indices/targets
 * (capacity cloth.nv), returns the count. */
uint32_t xscene_pins_at(const xscene *sc, uint32_t f, const float *collider, uint32_t *idx, float *targets);

#endif
