/*
 * weft/clip_place.h — putting a motion clip's poses somewhere on the floor.
 *
 * `weft simgen` turns each real-motion clip to face +Z at the avatar's bind position; `weft bench
 * mocap --chain` plays the clips of a list back to back (weft_clip_chain), each starting where,
 * and facing where, the one before ended. Both turn a pose about the vertical through a floor
 * point of its pelvis and move that point.
 */
#ifndef WEFT_CLIP_PLACE_H
#define WEFT_CLIP_PLACE_H

#include "weft/body.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The pose's heading, radians about +Y: its root's forward axis (+Z at rest) on the floor,
 * atan2(x, z). */
double weft_pose_heading(const weft_pose *pose);

/* The pelvis's floor point (x, z) of a pose on `body` (its rest pelvis moved by the root translation). */
void weft_pose_pelvis_xz(const weft_body *body, const weft_pose *pose, double out[2]);

/* Turns `pose` by `yaw` radians about the vertical through the pelvis floor point `from` (x, z)
 * and moves that point onto `to` (x, z): the root rotation is turned, the root translation rotated
 * about that vertical and moved; the height is kept. */
void weft_pose_place(const weft_body *body, weft_pose *pose, double yaw, const double from[2], const double to[2]);

/* The clips back to back as one new clip of `frames` frames at 60 Hz (each clip sampled at 60 Hz
 * over its own duration), in their order and again from the first when they run out, as a game
 * plays a list of animations. The first clip plays where it is; each next one is placed where the
 * one before ended and facing where it faced (weft_pose_place: turned by the difference of the
 * headings about its first frame's pelvis, moved onto the last frame's pelvis) and is reached by
 * `blend` frames blending (smoothstep, weft_pose_blend) from the last pose into its first. Errors:
 * no clips, a NULL clip, frames 0 or over 10,000,000 (WEFT_ERROR_INVALID_ARGUMENT); `out` is
 * untouched then. */
weft_result weft_clip_chain(weft_context *context, const weft_body *body, const weft_clip *const *clips, uint32_t count,
                            uint32_t frames, uint32_t blend, weft_clip **out);

#ifdef __cplusplus
}
#endif

#endif
