/*
 * weft/sim.h — reference simulation: the penetration validator and the dataset scenarios.
 *
 * The XPBD solver and the LBS baseline themselves are garment methods (WEFT_METHOD_XPBD,
 * WEFT_METHOD_LBS in weft.h). This header adds what ground-truth generation needs:
 *
 *   - an independent validator built on the CCD module (weft/ccd.h) that certifies a motion:
 *     conservative CCD of all five contact types (cloth vertex-face and edge-edge against the
 *     collider, collider vertex against cloth faces, cloth self vertex-face and edge-edge) over
 *     the linear motion between two frames or along a recorded substep path, plus exact
 *     triangle-triangle intersection tests at the end of the motion;
 *   - the scenario builders and the sequence writer used by `weft simgen`.
 *
 * Units and layouts follow weft.h (metres, Y up, float xyz triplets, uint32 triangles).
 */
#ifndef WEFT_SIM_H
#define WEFT_SIM_H

#include "weft/ccd.h"
#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------------------------------- */
/* Validator                                                                                 */

typedef struct weft_sim_validator weft_sim_validator;

typedef struct weft_sim_validation {
    uint32_t ccd_hits;            /* swept pairs whose separation fell below the tolerance */
    uint32_t intersection_hits;   /* intersecting triangle pairs at the later frame */
    uint32_t pairs_tested;        /* swept candidate pairs examined */
    uint32_t motions_checked;     /* linear motions swept (1 per frame pair, S for an S-substep path) */
    /* Where it failed: one swept hit (the first the traversal kept) when ccd_hits > 0; its type is
     * WEFT_CCD_TYPE_COUNT when there is none (no hit, or only intersecting triangles, which the
     * exact test counts without naming). */
    weft_ccd_hit hit;
} weft_sim_validation;

/* Separation below which a sweep counts as a hit (metres): 10 micrometres. */
#define WEFT_SIM_VALIDATOR_TOLERANCE 1e-5
/* Real motion (weft_sim_sequence_def.motion_path): a frame with more than this share of the cloth
 * inside the body where the body does not overlap itself (weft/wear.h, inside_clear) rejects the
 * sequence (docs/REFSIM.md, Real motion). */
#define WEFT_SIM_INSIDE_CLEAR_MAX 0.02
/* Real motion: cloth within 5 cm of a body vertex that another part of the body reaches within
 * this many metres (weft_wear_near_overlap) is squeezed by the body and not certified against
 * itself (weft_sim_validator_set_self_exempt). */
#define WEFT_SIM_SQUEEZE_REACH 0.01f
/* Real motion: a frame whose cloth crosses itself over this share of its vertices (the crossing
 * triangles' corners, weft_sim_validator_tangled's count) outside where the body pinches it (near
 * a squeeze at that frame or the one before) rejects the sequence, whatever exempt place the
 * crossing came from. */
#define WEFT_SIM_TANGLED_MAX 0.02

/* Topology is copied. The collider may be absent (collider_vertex_count 0). Cloth triangles
 * that share a vertex are not tested against each other; the mesh checks of
 * weft_garment_create apply. */
WEFT_API weft_result weft_sim_validator_create(weft_context *context, const uint32_t *cloth_triangles,
                                               uint32_t cloth_triangle_count, uint32_t cloth_vertex_count,
                                               const uint32_t *collider_triangles, uint32_t collider_triangle_count,
                                               uint32_t collider_vertex_count, weft_sim_validator **out_validator);
WEFT_API void weft_sim_validator_destroy(weft_sim_validator *validator);
/* Body parts (weft.h, collision.triangle_parts): cloth_masks holds one 32-bit part mask per cloth
 * vertex and collider_triangle_bits one bit (1 << part) per collider triangle, as the garment made
 * them (weft_sim_generate takes them from its reference garment). Kept, not copied; both NULL
 * clears. From then on a cloth-collider pair counts only where the cloth side has the collider
 * triangle's part, in the sweeps and in the exact triangle tests: cloth between two overlapping
 * parts of a self-intersecting body is certified against the parts it belongs to. */
WEFT_API weft_result weft_sim_validator_set_parts(weft_sim_validator *validator, const uint32_t *cloth_masks,
                                                  const uint32_t *collider_triangle_bits);
/* Cloth vertices (cloth_vertex_count flags, read by every later check, not copied; NULL: none)
 * whose cloth-cloth pairs are not certified: a pair of cloth triangles with an exempt vertex is
 * neither swept nor intersected. simgen on real motion exempts the cloth near where the body
 * overlaps itself, which squeezes cloth through cloth (docs/REFSIM.md, Real motion). */
WEFT_API weft_result weft_sim_validator_set_self_exempt(weft_sim_validator *validator, const uint8_t *exempt);
/* The cloth crossing itself at `cloth`: sets tangled[v] (cloth vertex count) to 1 at the corners of
 * every pair of cloth triangles that intersect, exempt or not, and at the corners' one ring; 0
 * elsewhere. *count: the corners (the ring not counted); *count_clear (optional, required with
 * `pinched`): the corners whose `pinched` flag is 0 (all of them when pinched is NULL). simgen on
 * real motion keeps cloth that crossed itself in an exempt zone exempt while it stays crossed,
 * hands it to the reference to untangle, and counts the crossing outside where the body pinches
 * the cloth (docs/REFSIM.md, Real motion). */
WEFT_API weft_result weft_sim_validator_tangled(weft_sim_validator *validator, const float *cloth,
                                                const uint8_t *pinched, uint8_t *tangled, uint32_t *count,
                                                uint32_t *count_clear);
/* Checks the motion from frame t (cloth0, collider0) to t+1 (cloth1, collider1). Collider
 * arrays may be NULL when there is no collider. Allocates nothing. */
WEFT_API weft_result weft_sim_validator_check(weft_sim_validator *validator, const float *cloth0, const float *cloth1,
                                              const float *collider0, const float *collider1,
                                              weft_sim_validation *out_validation);
/* Checks the motion over one frame along a finer path: cloth_states holds state_count >= 2
 * cloth states (state 0 = frame t, the last = frame t+1, e.g. the solver's substep ends) and
 * the collider moves linearly from collider0 to collider1, state k at k / (state_count - 1).
 * Every consecutive pair of states is swept as one linear motion; triangles are tested at the
 * last state. The path is what the reference simulator actually integrated, so it certifies
 * ground truth whose frame-to-frame chord grazes a curved surface the substeps went around. */
WEFT_API weft_result weft_sim_validator_check_path(weft_sim_validator *validator, const float *cloth_states,
                                                   uint32_t state_count, const float *collider0,
                                                   const float *collider1, weft_sim_validation *out_validation);

/* ---------------------------------------------------------------------------------------- */
/* Scenarios and sequences                                                                   */

typedef enum weft_sim_scenario {
    WEFT_SIM_SCENARIO_DROP = 0,   /* a sheet falls onto procedural rigid objects */
    WEFT_SIM_SCENARIO_GRIPPER,    /* a two-finger gripper grasps, lifts, moves and sets down a sheet */
    WEFT_SIM_SCENARIO_GARMENT,    /* a garment on an animated avatar (needs the body/wardrobe modules) */
    WEFT_SIM_SCENARIO_COUNT
} weft_sim_scenario;

/* A host's own character as the garment scenario's collider (`weft simgen --avatar`): its bind-pose
 * mesh, body parts, and the collider of every frame from a callback; the garment is the host's
 * mesh fitted to the bind pose, starting at rest there. The avatar, garment and motion draws, the
 * arm spread, the waistband and the gentle retry do not apply. Frames count from the start of
 * the pre-roll: the first `preroll` frames are simulated and validated but not recorded (the
 * character settling from its bind pose into its animation is the callback's business). The
 * meshes and the callback's state must outlive weft_sim_generate. */
typedef struct weft_sim_character {
    const char *name;                    /* written into meta.json (1..64 characters) */
    const float *rest_positions;         /* vertex_count * 3, the bind pose */
    uint32_t vertex_count;
    const uint32_t *triangles;
    uint32_t triangle_count;
    const uint8_t *triangle_parts;       /* triangle_count body parts (< 32), NULL: none */
    const float *garment_positions;      /* garment_vertex_count * 3, fitted to the bind pose */
    uint32_t garment_vertex_count;
    const uint32_t *garment_triangles;
    uint32_t garment_triangle_count;
    uint32_t preroll;                    /* 0..1000 */
    void (*collider_at)(void *user, uint32_t frame, float *out_positions);
    void *user;
} weft_sim_character;

typedef struct weft_sim_sequence_def {
    weft_sim_scenario scenario;
    uint64_t seed;                /* every random choice of the sequence derives from it */
    uint32_t frames;              /* recorded frames including the initial one (default 240) */
    uint32_t substeps;            /* XPBD substeps per 1/60 s frame (default 40) */
    uint32_t max_substeps;        /* a rejected sequence is retried with doubled substeps up to this (default 80) */
    /* Frames whose collider moves fast near the cloth get up to this factor times the attempt's
     * substeps, so that the bounds can keep pushed cloth outside it (weft_garment_def.substeps_max;
     * docs/REFSIM.md, Where the last rejections came from). Frames that need no more run exactly
     * as with fixed substeps. 1: fixed substeps, as sequences made before this setting (1..16,
     * default 8). */
    uint32_t fast_collider_factor;
    uint32_t cloth_vertices;      /* approximate vertex count of the sheet (default 1024) */
    bool validate;                /* run the validator on every frame (default true) */
    float motion_speed;           /* scales the kinematic motion: the avatar's motion (garment) and the
                                   * gripper's schedule; 1 = as drawn from the seed, which stays the same
                                   * draw at any speed; the drop scenario has none (0.1..10, default 1) */
    /* Radians the avatar's upper arms are held further from the torso than the motion has them, in
     * every garment sequence on a procedural motion (weft_motion_def.arm_spread; default 0.3; not
     * with motion_path). As drawn, the skinned avatar intersects itself at the armpits in nearly
     * every frame of idle, walk and run for the default and broader shapes (`weft bench body
     * --self-contact`), and cloth caught in that fold cannot be made penetration-free. 0
     * reproduces sequences made before this setting. */
    float garment_arm_spread;
    /* A garment sequence still rejected at max_substeps is tried once more, from `substeps`, as
     * a gentler take of the same scene: the avatar's arms held garment_retry_arm_spread radians
     * further still (garment_arm_spread + this <= 0.8; default 0.3), the motion eased
     * in from rest over garment_retry_ease_in seconds after the drape (0..2, default 0.5) and its
     * amplitude scaled by garment_retry_amplitude (0.1..1, default 0.75). garment_retry = false
     * turns the retry off (default true; docs/REFSIM.md, Dress rejections). */
    bool garment_retry;
    /* Garment scenario: the garment to wear, WEFT_CLOTH_TSHIRT, _SKIRT or _DRESS, instead of the
     * seed's draw; every other draw (avatar, motion) stays the seed's (default -1: the draw). */
    int32_t garment_kind;
    float garment_retry_arm_spread;
    float garment_retry_ease_in;
    float garment_retry_amplitude;
    /* Every this many frames the run saves its state to out_dir/checkpoint.bin, and a later call
     * with the same def and out_dir continues from the last one (0: no checkpoints, default). The
     * solver starts its candidate lists afresh at those frames, so such a sequence is the same
     * whether or not it was interrupted, though not bit-identical to one made without
     * checkpoints. A checkpoint of another def, a truncated or corrupt file is ignored (the run
     * starts over) and replaced. The file is removed when the sequence is finished. */
    uint32_t checkpoint_frames;
    /* Garment scenario on motion capture: a BVH file (plain or gzip, weft_bvh_load_file) retargeted
     * to the drawn avatar and played from motion_start_s seconds of the clip once the drape is done,
     * at motion_speed, turned and moved so that it starts where the bind pose stands, facing as it
     * does. The avatar and the garment stay the seed's draws; garment_arm_spread and the gentle
     * retry do not apply (the motion is the clip's as captured). The reference then projects the
     * whole body each substep and the validator measures the cloth inside it instead of sweeping
     * against it (docs/REFSIM.md, Real motion). Past the clip's end the last pose holds. NULL
     * (default): a procedural motion drawn from the seed. */
    const char *motion_path;
    /* With motion_path: a window the validator rejects keeps the frames recorded before the
     * rejected one, each validated, as a shorter sequence when there are at least this many
     * (meta.json "truncated"; weft_sim_sequence_result.truncated); fewer, or 0, and a rejected
     * window writes no arrays (0..100000, default 60: one second). */
    uint32_t prefix_frames_min;
    /* With motion_path: its joint for each SMPL joint (weft_bvh_def.joint_map; 24 entries); NULL
     * (default): the naming tables. */
    const char *const *motion_joint_map;
    double motion_start_s;        /* seconds into the clip, >= 0 and before its end (default 0) */
    /* Garment scenario on a host's character instead of the drawn avatar (see weft_sim_character);
     * NULL (default): the avatar. Excludes motion_path. */
    const weft_sim_character *character;
    /* "train", "val" or "test" written into meta.json (the mocap library's split of the clip);
     * NULL (default): none, the split is the name's hash (weft_sim_split_of). */
    const char *split;
    /* With checkpoint_frames: return at the first checkpoint after this many seconds of this call,
     * with out_result->finished false and nothing written but the checkpoint (0: no limit, default;
     * for job arrays with a wall-time limit). */
    double time_limit_s;
    uint32_t internal_cookie;     /* set by weft_sim_default_sequence_def(); do not touch */
} weft_sim_sequence_def;

typedef struct weft_sim_sequence_result {
    bool finished;                /* false only when time_limit_s stopped the run at a checkpoint */
    bool accepted;                /* validated with zero hits: written as ground truth */
    /* Accepted as the frames before the one that rejected the last attempt (first_hit_frame;
     * weft_sim_sequence_def.prefix_frames_min): `frames` is then that many, fewer than the def's. */
    bool truncated;
    uint32_t resumed_frame;       /* the checkpoint frame this call continued from (0: from the start) */
    uint32_t substeps_used;
    uint32_t attempts;
    bool gentle;                  /* the last attempt was the gentle garment retry (its settings: the def's) */
    uint32_t vertex_count, collider_vertex_count, frames;
    uint32_t ccd_hits, intersection_hits;  /* of the last attempt */
    int32_t first_hit_frame;      /* -1 when none */
    /* The hit that rejected the last attempt (type WEFT_CCD_TYPE_COUNT when none was named), the
     * position of its first vertex at that frame (a cloth vertex, or the collider vertex of an FV
     * hit), and for garments the body joint whose skinning weight dominates the body vertex
     * nearest that point (weft_joint_name, e.g. "left_hip"); "" otherwise. */
    weft_ccd_hit hit;
    float hit_position[3];
    char hit_joint[24];
    /* Real motion: the last attempt was rejected for cloth inside the body (WEFT_SIM_INSIDE_CLEAR_MAX,
     * at first_hit_frame), and the shares of the cloth inside the body over its frames (mean, worst)
     * and inside where the body does not overlap itself (worst); 0 on other scenes. */
    bool inside_clear_rejected;
    bool tangled_rejected; /* real motion: rejected for cloth crossing itself (WEFT_SIM_TANGLED_MAX) */
    float rejected_share;  /* with either: that frame's share of the cloth inside, or crossing itself */
    float inside_body_mean, inside_body_max, inside_clear_max;
    /* Real motion: the share of the cloth the validator did not certify against itself, mean over
     * the frames (stats self_exempt), and the worst frame's share crossing itself (stats tangled). */
    float self_exempt_mean, tangled_max;
    float tangled_clear_max; /* the worst frame's share crossing itself outside a pinch (stats tangled_clear) */
    uint32_t chord_retries;       /* frames redone with one proximity pass (see docs/REFSIM.md) */
    uint32_t path_frames;         /* frames whose chord grazed but whose substep path is clean */
    double simulate_s, validate_s; /* wall time of the last attempt */
    char description[160];        /* e.g. "drop: sheet 0.9x0.7 m ellipse onto table" */
} weft_sim_sequence_result;

WEFT_API weft_sim_sequence_def weft_sim_default_sequence_def(void);
/* The split of a sequence from its name alone: "train", "val" or "test" in the ratio 8:1:1
 * (FNV-1a of the name, a splitmix64 finaliser, modulo 10), so a sequence never changes split
 * when the set grows. `weft simgen` writes it into the manifest; tools/train/data.py computes the
 * same. NULL name: "train". */
WEFT_API const char *weft_sim_split_of(const char *sequence_name);
/* The split of the sequence in folder `dir`: its meta.json "split" (packed and hand-made
 * sequences carry one), else its entry in the dataset's manifest.json one folder up, else
 * weft_sim_split_of(the folder's name). "train", "val" or "test"; NULL for a NULL or empty path. */
WEFT_API const char *weft_sim_sequence_split(const char *dir);
WEFT_API const char *weft_sim_scenario_name(weft_sim_scenario scenario);

/* Simulates one sequence and writes it into out_dir (created if missing): meta.json plus
 * rest_pos.npy [N,3] f32, faces.npy [F,3] i32, cloth_pos.npy [T,N,3] f32,
 * collider_pos.npy [T,M,3] f32, collider_faces.npy [G,3] i32, pinned.npy [T,N] u8 and
 * stats.npy [T,K] f32 (column names in meta.json). A sequence the validator rejects even at
 * max_substeps gets only a meta.json with "accepted": false and the hit counts; its arrays
 * are never written. meta.json is written last (atomically), so its presence marks a
 * finished sequence. progress(frame, frames, user) is called after every frame when given. */
typedef void weft_sim_progress_fn(uint32_t frame, uint32_t frames, void *user);
WEFT_API weft_result weft_sim_generate(weft_context *context, const weft_sim_sequence_def *def, const char *out_dir,
                                       weft_sim_progress_fn *progress, void *progress_user,
                                       weft_sim_sequence_result *out_result);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_SIM_H */
