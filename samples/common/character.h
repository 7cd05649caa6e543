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

/* Binds a garment mesh fitted to the bind pose: each garment vertex takes the skinning of its
 * nearest character vertex. Refuses a garment that is not on this character (median distance
 * to the character over 10 cm) or that lies inside it (over 5 % of its vertices inside the
 * character's surface), naming the figure. Replaces any earlier binding. */
weft_result weft_sample_character_bind(weft_sample_character *c, const float *garment_positions, uint32_t vertex_count);
/* The bound garment skinned with the last pose (the garment carried by the skin). */
weft_result weft_sample_character_skin_garment(const weft_sample_character *c, float *out_positions);

#endif
