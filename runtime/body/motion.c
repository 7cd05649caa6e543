/* Procedural motions (analytic functions of time on the SMPL-24 skeleton) and sampled clips
 * with quaternion interpolation. Angles follow SMPL: joint frames equal the world frame in
 * the T-pose, so +X rotations swing legs back / tilt the spine forward, and the left arm
 * (along +X) lowers with a negative Z rotation. */
#include "body/body_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define PI 3.14159265358979323846

static const char *const g_motion_names[WEFT_MOTION_COUNT] = {"idle", "walk", "run", "jump", "dance", "arm_raise", "flip"};
/* Seconds per cycle at speed 1. */
static const double g_periods[WEFT_MOTION_COUNT] = {4.0, 1.1, 0.72, 1.6, 2.4, 3.0, 1.5};

const char *weft_motion_name(weft_motion motion)
{
    return (unsigned)motion < WEFT_MOTION_COUNT ? g_motion_names[motion] : NULL;
}

weft_result weft_motion_from_name(const char *name, weft_motion *out_motion)
{
    if (!name || !out_motion) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_motion_from_name: NULL argument");
    }
    for (int m = 0; m < WEFT_MOTION_COUNT; ++m) {
        if (strcmp(name, g_motion_names[m]) == 0) {
            *out_motion = (weft_motion)m;
            return WEFT_OK;
        }
    }
    return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "unknown motion '%s' (idle, walk, run, jump, dance, arm_raise, flip)", name);
}

weft_motion_def weft_default_motion_def(weft_motion motion)
{
    weft_motion_def def;
    memset(&def, 0, sizeof def);
    def.motion = motion;
    def.speed = 1.0f;
    def.amplitude = 1.0f;
    def.height = 1.70f;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

static weft_result check_def(const weft_motion_def *def)
{
    if (!def || def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: NULL or not made by weft_default_motion_def()");
    }
    if ((unsigned)def->motion >= WEFT_MOTION_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: motion %d out of range", (int)def->motion);
    }
    if (!isfinite(def->speed) || !isfinite(def->amplitude) || !isfinite(def->height)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "motion def: speed, amplitude or height is not finite");
    }
    if (def->speed <= 0.0f || def->speed > 8.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: speed %g outside (0, 8]", (double)def->speed);
    }
    if (def->amplitude < 0.0f || def->amplitude > 1.5f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: amplitude %g outside [0, 1.5]", (double)def->amplitude);
    }
    if (def->height < 0.5f || def->height > 2.5f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: height %g outside [0.5, 2.5]", (double)def->height);
    }
    if (!(def->arm_spread >= 0.0f && def->arm_spread <= 0.8f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion def: arm_spread %g outside [0, 0.8]", (double)def->arm_spread);
    }
    return WEFT_OK;
}

double weft_motion_period(const weft_motion_def *def)
{
    if (check_def(def) != WEFT_OK) {
        return 0.0;
    }
    return g_periods[def->motion] / def->speed;
}

/* ---------------------------------------------------------------------------------------- */
/* Rotation helpers (double precision)                                                        */

typedef struct quat {
    double w, x, y, z;
} quat;

static quat quat_from_aa(const double *aa)
{
    double th = sqrt(aa[0] * aa[0] + aa[1] * aa[1] + aa[2] * aa[2]);
    if (th < 1e-12) {
        return (quat){1, 0.5 * aa[0], 0.5 * aa[1], 0.5 * aa[2]};
    }
    double s = sin(0.5 * th) / th;
    return (quat){cos(0.5 * th), aa[0] * s, aa[1] * s, aa[2] * s};
}

static void quat_to_aa(quat q, float *out)
{
    if (q.w < 0) {
        q.w = -q.w, q.x = -q.x, q.y = -q.y, q.z = -q.z;
    }
    double n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
    if (n < 1e-12) {
        out[0] = (float)(2 * q.x), out[1] = (float)(2 * q.y), out[2] = (float)(2 * q.z);
        return;
    }
    double th = 2.0 * atan2(n, q.w);
    out[0] = (float)(q.x / n * th), out[1] = (float)(q.y / n * th), out[2] = (float)(q.z / n * th);
}

static quat quat_mul(quat a, quat b)
{
    return (quat){a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
                  a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

static quat quat_slerp(quat a, quat b, double t)
{
    double d = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
    if (d < 0) {
        b.w = -b.w, b.x = -b.x, b.y = -b.y, b.z = -b.z;
        d = -d;
    }
    double ka, kb;
    if (d > 0.9995) {
        ka = 1 - t, kb = t;
    } else {
        double th = acos(d), s = sin(th);
        ka = sin((1 - t) * th) / s;
        kb = sin(t * th) / s;
    }
    quat r = {ka * a.w + kb * b.w, ka * a.x + kb * b.x, ka * a.y + kb * b.y, ka * a.z + kb * b.z};
    double n = sqrt(r.w * r.w + r.x * r.x + r.y * r.y + r.z * r.z);
    r.w /= n, r.x /= n, r.y /= n, r.z /= n;
    return r;
}

/* Joint rotation as successive turns about world X, then Y, then Z... applied as
 * R = Rz(z) * Ry(y) * Rx(x): x first. Written into the pose as axis-angle. */
static void set_xyz(weft_pose *pose, int joint, double x, double y, double z)
{
    double ax[3] = {x, 0, 0}, ay[3] = {0, y, 0}, az[3] = {0, 0, z};
    quat q = quat_mul(quat_from_aa(az), quat_mul(quat_from_aa(ay), quat_from_aa(ax)));
    quat_to_aa(q, pose->rotations + 3 * joint);
}

/* Arm posture: lowered by `down` radians from the T-pose, then swung forward by `fwd`
 * (positive = forward) and the elbow bent by `bend`. side 0 = left, 1 = right. */
static void set_arm(weft_pose *pose, int side, double down, double fwd, double bend)
{
    double s = side == 0 ? 1.0 : -1.0;
    double az[3] = {0, 0, -s * down}, ax[3] = {-fwd, 0, 0};
    quat q = quat_mul(quat_from_aa(ax), quat_from_aa(az));
    quat_to_aa(q, pose->rotations + 3 * (WEFT_JOINT_LEFT_SHOULDER + side));
    /* Elbow: bend about the local Y axis towards the front. */
    double ay[3] = {0, -s * bend, 0};
    quat_to_aa(quat_from_aa(ay), pose->rotations + 3 * (WEFT_JOINT_LEFT_ELBOW + side));
}

/* Abducts both upper arms by `spread` radians in the shoulder's own frame, before the motion's
 * rotation: set_arm's R = Rx(fwd) Rz(-s down) becomes Rx(fwd) Rz(-s (down - spread)), and any
 * other shoulder rotation is opened the same way. */
static void spread_arms(weft_pose *pose, double spread)
{
    for (int side = 0; side < 2; ++side) {
        double s = side == 0 ? 1.0 : -1.0;
        float *r = pose->rotations + 3 * (WEFT_JOINT_LEFT_SHOULDER + side);
        double aa[3] = {r[0], r[1], r[2]}, az[3] = {0, 0, s * spread};
        quat_to_aa(quat_mul(quat_from_aa(aa), quat_from_aa(az)), r);
    }
}

/* Smooth ease between keyframes: values[k] at times[k] (ascending in [0, 1], first 0, last
 * 1), cosine-eased so the curve has zero slope at each key. */
static double keys(const double *times, const double *values, int n, double u)
{
    for (int k = 0; k + 1 < n; ++k) {
        if (u <= times[k + 1]) {
            double s = (u - times[k]) / (times[k + 1] - times[k]);
            s = 0.5 - 0.5 * cos(PI * s);
            return values[k] + (values[k + 1] - values[k]) * s;
        }
    }
    return values[n - 1];
}

/* ---------------------------------------------------------------------------------------- */

static void motion_pose(const weft_motion_def *def, double t, weft_pose *p)
{
    memset(p, 0, sizeof *p);
    const double a = def->amplitude, hs = def->height / 1.70;
    const double period = g_periods[def->motion] / def->speed;
    double u = fmod(t / period, 1.0);
    if (u < 0) {
        u += 1.0;
    }
    const double ph = 2 * PI * u;
    switch (def->motion) {
    case WEFT_MOTION_IDLE: {
        double breathe = sin(ph), sway = sin(ph + 0.7);
        set_xyz(p, WEFT_JOINT_SPINE3, a * 0.03 * breathe, 0, 0);
        set_xyz(p, WEFT_JOINT_PELVIS, 0, a * 0.05 * sway, a * 0.03 * sway);
        set_xyz(p, WEFT_JOINT_NECK, a * 0.05 * sin(ph + 1.3), a * 0.1 * sin(ph * 1.0 + 2.0), 0);
        set_arm(p, 0, 1.25, a * 0.06 * sway, 0.2 + a * 0.05 * breathe);
        set_arm(p, 1, 1.25, -a * 0.06 * sway, 0.2 + a * 0.05 * breathe);
        set_xyz(p, WEFT_JOINT_LEFT_HIP, 0, 0, -a * 0.03 * sway);
        set_xyz(p, WEFT_JOINT_RIGHT_HIP, 0, 0, -a * 0.03 * sway);
        p->translation[0] = (float)(a * 0.015 * hs * sway);
        break;
    }
    case WEFT_MOTION_WALK:
    case WEFT_MOTION_RUN: {
        bool run = def->motion == WEFT_MOTION_RUN;
        double hip = a * (run ? 0.7 : 0.35), knee = a * (run ? 1.1 : 0.55);
        double s = sin(ph);
        /* Left leg forward when s > 0 (a negative X turn lifts the thigh forward). */
        set_xyz(p, WEFT_JOINT_LEFT_HIP, -hip * s, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_HIP, hip * s, 0, 0);
        /* Knees bend while the leg swings through: peaks a quarter cycle after the thigh. */
        set_xyz(p, WEFT_JOINT_LEFT_KNEE, 0.08 + knee * (0.5 - 0.5 * cos(ph - 0.9)), 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_KNEE, 0.08 + knee * (0.5 - 0.5 * cos(ph + PI - 0.9)), 0, 0);
        set_xyz(p, WEFT_JOINT_LEFT_ANKLE, a * 0.2 * sin(ph - 0.5), 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_ANKLE, -a * 0.2 * sin(ph - 0.5), 0, 0);
        double arm = a * (run ? 0.6 : 0.35), bend = run ? 1.4 : 0.3;
        set_arm(p, 0, 1.25, -arm * s, bend + 0.15 * a * s);
        set_arm(p, 1, 1.25, arm * s, bend - 0.15 * a * s);
        set_xyz(p, WEFT_JOINT_PELVIS, 0, -a * 0.12 * s, 0);
        set_xyz(p, WEFT_JOINT_SPINE1, run ? a * 0.15 : a * 0.03, a * 0.08 * s, 0);
        set_xyz(p, WEFT_JOINT_SPINE3, 0, a * 0.06 * s, 0);
        double bob = run ? 0.06 * fabs(sin(ph)) - 0.03 : 0.018 * cos(2 * ph);
        p->translation[1] = (float)(a * hs * bob);
        p->translation[0] = (float)(a * hs * 0.01 * sin(ph));
        break;
    }
    case WEFT_MOTION_JUMP: {
        /* crouch, take off, flight, land, recover */
        static const double tk[] = {0.0, 0.22, 0.32, 0.52, 0.70, 0.80, 1.0};
        static const double crouch[] = {0.0, 1.0, 0.0, 0.05, 0.0, 0.8, 0.0};
        static const double lift[] = {0.0, 0.0, 0.25, 1.0, 0.0, 0.0, 0.0};
        static const double arms[] = {0.0, -0.6, 1.6, 1.2, 0.4, -0.2, 0.0};
        double c = a * keys(tk, crouch, 7, u), l = keys(tk, lift, 7, u), ar = a * keys(tk, arms, 7, u);
        set_xyz(p, WEFT_JOINT_LEFT_HIP, -1.0 * c, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_HIP, -1.0 * c, 0, 0);
        set_xyz(p, WEFT_JOINT_LEFT_KNEE, 1.7 * c, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_KNEE, 1.7 * c, 0, 0);
        set_xyz(p, WEFT_JOINT_LEFT_ANKLE, -0.7 * c + 0.3 * l, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_ANKLE, -0.7 * c + 0.3 * l, 0, 0);
        set_xyz(p, WEFT_JOINT_SPINE1, 0.45 * c, 0, 0);
        set_arm(p, 0, 1.25 - 0.5 * fmax(ar, 0.0), ar, 0.3);
        set_arm(p, 1, 1.25 - 0.5 * fmax(ar, 0.0), ar, 0.3);
        /* Hips drop by about the crouch; the flight rises ~0.35 m at amplitude 1. */
        p->translation[1] = (float)(hs * (-0.30 * c + 0.35 * a * l));
        break;
    }
    case WEFT_MOTION_DANCE: {
        /* A full turn per cycle with swinging arms, swaying hips and bouncing knees. */
        double b = sin(2 * ph);
        set_xyz(p, WEFT_JOINT_PELVIS, 0, ph, a * 0.08 * sin(2 * ph));
        set_xyz(p, WEFT_JOINT_SPINE2, 0, -a * 0.25 * sin(2 * ph), -a * 0.1 * sin(2 * ph));
        set_xyz(p, WEFT_JOINT_LEFT_HIP, -a * 0.25 * (0.5 + 0.5 * b), 0, -a * 0.05);
        set_xyz(p, WEFT_JOINT_RIGHT_HIP, -a * 0.25 * (0.5 - 0.5 * b), 0, a * 0.05);
        set_xyz(p, WEFT_JOINT_LEFT_KNEE, a * 0.5 * (0.5 + 0.5 * b), 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_KNEE, a * 0.5 * (0.5 - 0.5 * b), 0, 0);
        set_arm(p, 0, 0.3 - a * 0.5 * sin(2 * ph), a * 0.5 * cos(2 * ph), a * (0.6 + 0.4 * b));
        set_arm(p, 1, 0.3 + a * 0.5 * sin(2 * ph), -a * 0.5 * cos(2 * ph), a * (0.6 - 0.4 * b));
        set_xyz(p, WEFT_JOINT_HEAD, 0, -a * 0.3 * sin(2 * ph), 0);
        p->translation[1] = (float)(-a * hs * 0.04 * (0.5 + 0.5 * fabs(b)));
        break;
    }
    case WEFT_MOTION_ARM_RAISE: {
        /* Arms from the sides (1.3 rad below horizontal) to overhead (1.35 above). */
        double lift = 0.5 - 0.5 * cos(ph);
        double down = 1.3 - a * 2.65 * lift;
        set_arm(p, 0, down, a * 0.15 * sin(ph), 0.15);
        set_arm(p, 1, down, a * 0.15 * sin(ph), 0.15);
        set_xyz(p, WEFT_JOINT_SPINE3, -a * 0.08 * lift, 0, 0);
        set_xyz(p, WEFT_JOINT_NECK, -a * 0.15 * lift, 0, 0);
        break;
    }
    case WEFT_MOTION_FLIP:
    default: {
        /* Crouch, a tucked back flip in 0.45 of the cycle (0.68 s at speed 1), land. */
        static const double tk[] = {0.0, 0.15, 0.25, 0.45, 0.70, 0.82, 1.0};
        static const double crouch[] = {0.0, 0.8, 0.0, 1.0, 0.0, 0.7, 0.0};
        static const double lift[] = {0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0};
        double c = keys(tk, crouch, 7, u), l = keys(tk, lift, 7, u);
        /* Rotation progress: smoothstep over the flight; one full turn back (+X). */
        double r = (u - 0.22) / (0.70 - 0.22);
        r = r < 0 ? 0 : r > 1 ? 1 : r * r * (3 - 2 * r);
        double turn = 2 * PI * r;
        set_xyz(p, WEFT_JOINT_PELVIS, -turn, 0, 0);
        double tuck = a * c;
        set_xyz(p, WEFT_JOINT_LEFT_HIP, -1.6 * tuck, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_HIP, -1.6 * tuck, 0, 0);
        set_xyz(p, WEFT_JOINT_LEFT_KNEE, 2.0 * tuck, 0, 0);
        set_xyz(p, WEFT_JOINT_RIGHT_KNEE, 2.0 * tuck, 0, 0);
        set_xyz(p, WEFT_JOINT_SPINE1, 0.4 * tuck, 0, 0);
        set_arm(p, 0, 1.25 - 1.2 * l, 0.8 * tuck + 0.8 * l, 0.5 * tuck);
        set_arm(p, 1, 1.25 - 1.2 * l, 0.8 * tuck + 0.8 * l, 0.5 * tuck);
        p->translation[1] = (float)(hs * (-0.25 * c * (1 - l) + 0.7 * l));
        break;
    }
    }
}

weft_result weft_motion_sample(const weft_motion_def *def, double t, weft_pose *out_pose)
{
    weft_result r = check_def(def);
    if (r != WEFT_OK) {
        return r;
    }
    if (!out_pose) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_motion_sample: NULL pose");
    }
    if (!isfinite(t)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_motion_sample: time is not finite");
    }
    motion_pose(def, t, out_pose);
    if (def->arm_spread > 0.0f) {
        spread_arms(out_pose, def->arm_spread);
    }
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Clips                                                                                      */

static size_t clip_bytes(uint32_t frames, uint32_t per_frame) { return (size_t)frames * per_frame * sizeof(float); }

weft_result weft_clip_create(weft_context *context, uint32_t frame_count, float fps, weft_clip **out_clip)
{
    if (!context || !out_clip) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_create: NULL argument");
    }
    if (frame_count == 0 || frame_count > 10000000u) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_create: frame_count %u outside [1, 1e7]", frame_count);
    }
    if (!isfinite(fps) || fps <= 0.0f || fps > 10000.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_create: fps %g outside (0, 10000]", (double)fps);
    }
    weft_clip *c = weft__alloc(context, sizeof *c);
    if (!c) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    c->rotations = weft__alloc(context, clip_bytes(frame_count, WEFT_POSE_ROTATION_FLOATS));
    c->translations = weft__alloc(context, clip_bytes(frame_count, 3));
    c->context = context;
    c->frame_count = frame_count;
    c->fps = fps;
    if (!c->rotations || !c->translations) {
        weft_clip_destroy(c);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *out_clip = c;
    return WEFT_OK;
}

void weft_clip_destroy(weft_clip *clip)
{
    if (!clip) {
        return;
    }
    weft_context *ctx = clip->context;
    weft__free(ctx, clip->rotations, clip_bytes(clip->frame_count, WEFT_POSE_ROTATION_FLOATS));
    weft__free(ctx, clip->translations, clip_bytes(clip->frame_count, 3));
    weft__free(ctx, clip, sizeof *clip);
}

static weft_result check_clip(const weft_clip *clip)
{
    if (!clip || !clip->rotations || !clip->translations || clip->frame_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clip: NULL or empty");
    }
    if (!isfinite(clip->fps) || clip->fps <= 0.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clip: fps %g is not positive", (double)clip->fps);
    }
    return WEFT_OK;
}

/* Duration covered by the clip: a looping clip wraps from the last frame to the first. */
static double clip_duration(const weft_clip *clip)
{
    return (clip->loops ? (double)clip->frame_count : (double)(clip->frame_count - 1)) / clip->fps;
}

static void sample_frames(const weft_clip *clip, double t, weft_pose *out)
{
    const uint32_t n = clip->frame_count;
    double f = t * clip->fps;
    uint32_t i0, i1;
    double w;
    if (clip->loops) {
        f = fmod(f, (double)n);
        if (f < 0) {
            f += n;
        }
        i0 = (uint32_t)f;
        if (i0 >= n) {
            i0 = n - 1;
        }
        i1 = (i0 + 1) % n;
        w = f - i0;
    } else {
        if (f <= 0 || n == 1) {
            i0 = i1 = 0, w = 0;
        } else if (f >= n - 1) {
            i0 = i1 = n - 1, w = 0;
        } else {
            i0 = (uint32_t)f;
            i1 = i0 + 1;
            w = f - i0;
        }
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        const float *a = clip->rotations + (size_t)i0 * WEFT_POSE_ROTATION_FLOATS + 3 * j;
        const float *b = clip->rotations + (size_t)i1 * WEFT_POSE_ROTATION_FLOATS + 3 * j;
        double da[3] = {a[0], a[1], a[2]}, db[3] = {b[0], b[1], b[2]};
        quat_to_aa(quat_slerp(quat_from_aa(da), quat_from_aa(db), w), out->rotations + 3 * j);
    }
    for (int k = 0; k < 3; ++k) {
        out->translation[k] = (float)((1 - w) * clip->translations[3 * (size_t)i0 + k] + w * clip->translations[3 * (size_t)i1 + k]);
    }
}

weft_result weft_pose_blend(const weft_pose *a, const weft_pose *b, double u, weft_pose *out_pose)
{
    if (!a || !b || !out_pose) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_pose_blend: a, b and out_pose are required");
    }
    if (!(u >= 0.0 && u <= 1.0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_pose_blend: u = %g is not in [0, 1]", u);
    }
    if (!weft__all_finite(a->rotations, WEFT_POSE_ROTATION_FLOATS) || !weft__all_finite(a->translation, 3) ||
        !weft__all_finite(b->rotations, WEFT_POSE_ROTATION_FLOATS) || !weft__all_finite(b->translation, 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_pose_blend: a pose holds NaN or infinity");
    }
    weft_pose p;
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        const float *ra = a->rotations + 3 * j, *rb = b->rotations + 3 * j;
        double da[3] = {ra[0], ra[1], ra[2]}, db[3] = {rb[0], rb[1], rb[2]};
        quat_to_aa(quat_slerp(quat_from_aa(da), quat_from_aa(db), u), p.rotations + 3 * j);
    }
    for (int k = 0; k < 3; ++k) {
        p.translation[k] = (float)((1.0 - u) * a->translation[k] + u * b->translation[k]);
    }
    *out_pose = p;
    return WEFT_OK;
}

weft_result weft_clip_sample(const weft_clip *clip, double t, weft_pose *out_pose)
{
    weft_result r = check_clip(clip);
    if (r != WEFT_OK) {
        return r;
    }
    if (!out_pose) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_sample: NULL pose");
    }
    if (!isfinite(t)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_clip_sample: time is not finite");
    }
    weft_pose p;
    sample_frames(clip, t, &p);
    if (!weft__all_finite(p.rotations, WEFT_POSE_ROTATION_FLOATS) || !weft__all_finite(p.translation, 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_clip_sample: the clip holds NaN or infinity near t = %g", t);
    }
    *out_pose = p;
    return WEFT_OK;
}

weft_result weft_clip_resample(const weft_clip *clip, float fps, weft_clip **out_clip)
{
    weft_result r = check_clip(clip);
    if (r != WEFT_OK) {
        return r;
    }
    if (!out_clip) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_resample: NULL output");
    }
    if (!weft__all_finite(clip->rotations, (size_t)clip->frame_count * WEFT_POSE_ROTATION_FLOATS) ||
        !weft__all_finite(clip->translations, (size_t)clip->frame_count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_clip_resample: clip '%s' holds NaN or infinity", clip->name);
    }
    if (!isfinite(fps) || fps <= 0.0f || fps > 10000.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_resample: fps %g outside (0, 10000]", (double)fps);
    }
    double duration = clip_duration(clip);
    double frames = clip->loops ? floor(duration * fps + 0.5) : floor(duration * fps + 0.5) + 1;
    if (frames < 1) {
        frames = 1;
    }
    if (frames > 10000000.0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_resample: %g frames is too many", frames);
    }
    weft_clip *out = NULL;
    r = weft_clip_create(clip->context, (uint32_t)frames, fps, &out);
    if (r != WEFT_OK) {
        return r;
    }
    out->loops = clip->loops;
    memcpy(out->name, clip->name, sizeof out->name);
    out->name[sizeof out->name - 1] = '\0';
    for (uint32_t f = 0; f < out->frame_count; ++f) {
        weft_pose p;
        sample_frames(clip, (double)f / fps, &p);
        memcpy(out->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS, p.rotations, sizeof p.rotations);
        memcpy(out->translations + (size_t)f * 3, p.translation, sizeof p.translation);
    }
    *out_clip = out;
    return WEFT_OK;
}

weft_result weft_clip_from_motion(weft_context *context, const weft_motion_def *def, double duration, float fps,
                                  weft_clip **out_clip)
{
    weft_result r = check_def(def);
    if (r != WEFT_OK) {
        return r;
    }
    if (!context || !out_clip) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_from_motion: NULL argument");
    }
    if (!isfinite(duration) || duration <= 0 || duration > 3600 || !isfinite(fps) || fps <= 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_clip_from_motion: duration %g s / fps %g invalid", duration,
                          (double)fps);
    }
    double frames = floor(duration * fps + 0.5);
    if (frames < 1) {
        frames = 1;
    }
    weft_clip *c = NULL;
    r = weft_clip_create(context, (uint32_t)frames, fps, &c);
    if (r != WEFT_OK) {
        return r;
    }
    /* A clip baked over whole cycles loops seamlessly. */
    double cycles = duration / weft_motion_period(def);
    c->loops = fabs(cycles - floor(cycles + 0.5)) < 1e-6;
    snprintf(c->name, sizeof c->name, "%s", g_motion_names[def->motion]);
    for (uint32_t f = 0; f < c->frame_count; ++f) {
        weft_pose p;
        motion_pose(def, (double)f / fps, &p);
        memcpy(c->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS, p.rotations, sizeof p.rotations);
        memcpy(c->translations + (size_t)f * 3, p.translation, sizeof p.translation);
    }
    *out_clip = c;
    return WEFT_OK;
}
