/* A user's own character for the render sample and `weft render` (--avatar gltf:PATH): a skinned
 * glTF/FBX mesh read by weft_skinned_load_file (any joint names), played by its own animation,
 * as the garment's collider; garments are the user's OBJ fitted to its bind pose
 * (docs/RENDER.md, *Your own character*).
 *
 * The character must be in metres with Y up (glTF's convention) and stand between 0.3 and 3 m
 * tall; its bind pose is the mesh as stored (every skinning matrix the identity). Body parts for
 * the garment's body collision are each triangle's dominant joint, joints merged into their
 * parents (smallest first) until at most 32 parts remain. */
#ifndef WEFT_SAMPLE_CHARACTER_H
#define WEFT_SAMPLE_CHARACTER_H

#include "weft.h"
#include "weft/body.h"

typedef struct weft_sample_character weft_sample_character;

/* The index of the point of `points` (count * 3) nearest to p, and its squared distance; a linear
 * scan, for binding garments at load time (both the character and weft's avatar use it). */
uint32_t weft_sample_nearest_point(const float *points, uint32_t count, const float p[3], double *out_d2);

/* Loads and checks a character (WEFT_ERROR_FORMAT naming the problem: not skinned, a height
 * outside 0.3..3 m, ...). */
weft_result weft_sample_character_load(weft_context *context, const char *path, weft_sample_character **out);
void weft_sample_character_destroy(weft_sample_character *c);

uint32_t weft_sample_character_vertex_count(const weft_sample_character *c);
uint32_t weft_sample_character_triangle_count(const weft_sample_character *c);
const float *weft_sample_character_bind_vertices(const weft_sample_character *c);
const uint32_t *weft_sample_character_triangles(const weft_sample_character *c);
/* triangle_count part ids in [0, part_count) (weft_garment_def.collision.triangle_parts) */
const uint8_t *weft_sample_character_parts(const weft_sample_character *c, uint32_t *part_count);
uint32_t weft_sample_character_joint_count(const weft_sample_character *c);
/* Seconds of animation (0 for a single frame) and its frames. */
double weft_sample_character_duration(const weft_sample_character *c);
uint32_t weft_sample_character_frame_count(const weft_sample_character *c);

/* Poses the character at t seconds into its animation (clamped to it, the nearest sampled frame),
 * blended from the bind pose by u in [0, 1] (1: the animation's pose; per joint, the rotation
 * slerped and the translation and scale interpolated). Writes vertex_count * 3 positions and
 * keeps the blended matrices for weft_sample_character_skin_garment. Allocates nothing. */
weft_result weft_sample_character_pose(weft_sample_character *c, double t, double u, float *out_vertices);

/* Plays an SMPL clip (weft_bvh_load_file's output for `body`, e.g. a library clip) on the
 * character instead of its own animation, from then on (weft_sample_character_pose's t runs over
 * the clip). joint_map: 24 entries in SMPL order, the character joint each SMPL joint drives
 * (weft_bvh_read_joint_map's entries; NULL or "" = none; a namespace prefix before ':' is
 * ignored). Retargeting: each mapped joint turns from its bind pose by its SMPL joint's world
 * rotation times a rest correction (the smallest rotation taking the character's bind bone onto
 * SMPL's T-pose bone, so a character bound in an A-pose works); unmapped joints turn with their
 * parent; the root follows the pelvis path scaled by the legs' length ratio. Needs the pelvis,
 * hips, knees, spine1, shoulders and elbows mapped; fails naming what is missing or a name that is
 * no joint of the character. Allocates the clip's skinning matrices here; posing allocates
 * nothing. */
weft_result weft_sample_character_set_clip(weft_sample_character *c, const weft_body *body, const weft_clip *clip,
                                           const char *const *joint_map);

/* Binds a garment mesh fitted to the bind pose: each garment vertex takes the skinning of its
 * nearest character vertex. Refuses a garment that is not on this character (median distance
 * to the character over 10 cm) or that lies inside it (over 5 % of its vertices inside the
 * character's surface), naming the figure. Replaces any earlier binding. */
weft_result weft_sample_character_bind(weft_sample_character *c, const float *garment_positions, uint32_t vertex_count);
/* The bound garment skinned with the last pose (the garment carried by the skin). */
weft_result weft_sample_character_skin_garment(const weft_sample_character *c, float *out_positions);

#endif
