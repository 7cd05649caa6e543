/* Putting a motion clip's poses somewhere on the floor (weft/clip_place.h). */
#include "weft/clip_place.h"

#include "core/core.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Unit quaternions (w, x, y, z) from and to axis-angle (the body module's own are static to
 * motion.c). */
static void quat_from_aa(const float *aa, double q[4])
{
    const double a = sqrt((double)aa[0] * aa[0] + (double)aa[1] * aa[1] + (double)aa[2] * aa[2]);
    const double s = a > 1e-12 ? sin(0.5 * a) / a : 0.5;
    q[0] = cos(0.5 * a);
    for (int k = 0; k < 3; ++k) {
        q[k + 1] = s * aa[k];
    }
}

static void quat_to_aa(const double q[4], float *aa)
{
    const double w = q[0] < 0 ? -q[0] : q[0], sgn = q[0] < 0 ? -1.0 : 1.0;
    const double v = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double a = 2.0 * atan2(v, w);
    const double f = v > 1e-12 ? a / v : 2.0;
    for (int k = 0; k < 3; ++k) {
        aa[k] = (float)(sgn * f * q[k + 1]);
    }
}

static void quat_mul(const double a[4], const double b[4], double o[4])
{
    o[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3];
    o[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2];
    o[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1];
    o[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0];
}

double weft_pose_heading(const weft_pose *pose)
{
    double q[4];
    quat_from_aa(pose->rotations, q);
    const double fx = 2.0 * (q[1] * q[3] + q[0] * q[2]);
    const double fz = 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]);
    return atan2(fx, fz);
}

void weft_pose_pelvis_xz(const weft_body *body, const weft_pose *pose, double out[2])
{
    const float *p0 = weft_body_rest_joints(body); /* the pelvis at rest */
    out[0] = p0[0] + pose->translation[0];
    out[1] = p0[2] + pose->translation[2];
}

void weft_pose_place(const weft_body *body, weft_pose *pose, double yaw, const double from[2], const double to[2])
{
    const double c = cos(yaw), s = sin(yaw);
    const double turn[4] = {cos(0.5 * yaw), 0.0, sin(0.5 * yaw), 0.0};
    double q[4], o[4];
    quat_from_aa(pose->rotations, q);
    quat_mul(turn, q, o);
    quat_to_aa(o, pose->rotations);
    const float *p0 = weft_body_rest_joints(body); /* the pelvis at rest */
    const double P[3] = {p0[0] + pose->translation[0] - from[0], p0[1] + pose->translation[1],
                         p0[2] + pose->translation[2] - from[1]};
    const double R[3] = {c * P[0] + s * P[2], P[1], -s * P[0] + c * P[2]};
    pose->translation[0] = (float)(R[0] + to[0] - p0[0]);
    pose->translation[1] = (float)(R[1] - p0[1]);
    pose->translation[2] = (float)(R[2] + to[1] - p0[2]);
}

static void chain_put(weft_clip *chain, uint32_t f, const weft_pose *pose)
{
    memcpy(chain->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS, pose->rotations, sizeof pose->rotations);
    memcpy(chain->translations + (size_t)f * 3, pose->translation, sizeof pose->translation);
}

weft_result weft_clip_chain(weft_context *context, const weft_body *body, const weft_clip *const *clips, uint32_t count,
                            uint32_t frames, uint32_t blend, weft_clip **out)
{
    if (!out || !body || !clips || count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clip chain: no clips");
    }
    if (frames == 0 || frames > 10000000u) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clip chain: %u frames (1..10000000)", frames);
    }
    for (uint32_t c = 0; c < count; ++c) {
        if (!clips[c] || clips[c]->frame_count == 0 || !(clips[c]->fps > 0.0f)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clip chain: clip %u is missing or empty", c);
        }
    }
    weft_clip *chain = NULL;
    weft_result r = weft_clip_create(context, frames, 60.0f, &chain);
    if (r != WEFT_OK) {
        return r;
    }
    snprintf(chain->name, sizeof chain->name, "chain of %u clips", count);
    weft_pose last, first, pose;
    uint32_t f = 0;
    for (uint32_t c = 0; r == WEFT_OK && f < frames; ++c) {
        const weft_clip *clip = clips[c % count];
        /* at least one frame a clip, so that a list of very short clips still moves on */
        uint32_t m = (uint32_t)floor((double)clip->frame_count / (double)clip->fps * 60.0);
        m = m ? m : 1;
        double yaw = 0.0, from[2] = {0.0, 0.0}, to[2] = {0.0, 0.0};
        if ((r = weft_clip_sample(clip, 0.0, &first)) != WEFT_OK) {
            break;
        }
        if (c > 0) {
            yaw = weft_pose_heading(&last) - weft_pose_heading(&first);
            weft_pose_pelvis_xz(body, &first, from);
            weft_pose_pelvis_xz(body, &last, to);
            weft_pose_place(body, &first, yaw, from, to);
            for (uint32_t b = 0; r == WEFT_OK && b < blend && f < frames; ++b, ++f) {
                const double u = (b + 1.0) / (blend + 1.0);
                if ((r = weft_pose_blend(&last, &first, u * u * (3.0 - 2.0 * u), &pose)) == WEFT_OK) {
                    chain_put(chain, f, &pose);
                }
            }
        }
        for (uint32_t j = 0; r == WEFT_OK && j < m && f < frames; ++j, ++f) {
            if ((r = weft_clip_sample(clip, j / 60.0, &pose)) == WEFT_OK) {
                if (c > 0) {
                    weft_pose_place(body, &pose, yaw, from, to);
                }
                chain_put(chain, f, &pose);
                last = pose;
            }
        }
    }
    if (r != WEFT_OK) {
        weft_clip_destroy(chain);
        return r;
    }
    *out = chain;
    return WEFT_OK;
}
