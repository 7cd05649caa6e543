/* Procedural motions (looping, smoothness, speed, plausible poses on the avatar) and clips
 * (baking, slerp sampling, resampling, bad input). */
#include "test.h"

#include "core/core.h"
#include "weft.h"
#include "weft/body.h"

static weft_context *g_ctx;
static weft_body *g_body;

static void setup(void)
{
    if (!g_ctx) {
        weft_context_def def = weft_default_context_def();
        CHECK_RESULT(weft_context_create(&def, &g_ctx), WEFT_OK);
        weft_avatar_def ad = weft_default_avatar_def();
        ad.target_vertices = 3000;
        CHECK_RESULT(weft_avatar_create(g_ctx, &ad, &g_body), WEFT_OK);
    }
}

/* Largest rotation angle between two poses' joint rotations (radians), via quaternions. */
static double pose_distance(const weft_pose *a, const weft_pose *b)
{
    double worst = 0;
    for (int j = 0; j < WEFT_BODY_JOINTS; ++j) {
        double qa[4], qb[4];
        const float *ra = a->rotations + 3 * j, *rb = b->rotations + 3 * j;
        const float *r[2] = {ra, rb};
        double *q[2] = {qa, qb};
        for (int k = 0; k < 2; ++k) {
            double th = sqrt((double)r[k][0] * r[k][0] + (double)r[k][1] * r[k][1] + (double)r[k][2] * r[k][2]);
            double s = th > 1e-12 ? sin(th / 2) / th : 0.5;
            q[k][0] = cos(th / 2), q[k][1] = r[k][0] * s, q[k][2] = r[k][1] * s, q[k][3] = r[k][2] * s;
        }
        double d = fabs(qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]);
        d = d > 1 ? 1 : d;
        worst = fmax(worst, 2 * acos(d));
    }
    for (int k = 0; k < 3; ++k) {
        worst = fmax(worst, fabs(a->translation[k] - b->translation[k]));
    }
    return worst;
}

static void test_all_motions_loop_and_are_smooth(void)
{
    for (int m = 0; m < WEFT_MOTION_COUNT; ++m) {
        weft_motion_def def = weft_default_motion_def((weft_motion)m);
        double period = weft_motion_period(&def);
        CHECK(period > 0.3 && period < 5.0);
        weft_pose a, b;
        double max_step = 0;
        for (int i = 0; i <= 480; ++i) {
            double t = period * i / 480.0;
            CHECK_RESULT(weft_motion_sample(&def, t, &a), WEFT_OK);
            CHECK(weft__all_finite(a.rotations, 72) && weft__all_finite(a.translation, 3));
            CHECK_RESULT(weft_motion_sample(&def, t + period, &b), WEFT_OK);
            CHECK_MSG(pose_distance(&a, &b) < 1e-4, "%s not periodic at t=%g", weft_motion_name((weft_motion)m), t);
            CHECK_RESULT(weft_motion_sample(&def, t + period / 480.0, &b), WEFT_OK);
            max_step = fmax(max_step, pose_distance(&a, &b));
        }
        /* Per 1/480 of a cycle no joint turns more than ~0.1 rad (no jumps); the flip's root
         * turns 2 pi in under half a cycle, the fastest motion. */
        printf("%-9s period %.2f s, largest step per 1/480 cycle %.4f\n", weft_motion_name((weft_motion)m), period, max_step);
        CHECK_MSG(max_step < 0.1, "%s jumps by %g", weft_motion_name((weft_motion)m), max_step);
        /* speed 2: twice as fast. */
        weft_motion_def fast = def;
        fast.speed = 2.0f;
        CHECK_NEAR(weft_motion_period(&fast), period / 2, 1e-9);
        CHECK_RESULT(weft_motion_sample(&fast, 0.37, &a), WEFT_OK);
        CHECK_RESULT(weft_motion_sample(&def, 0.74, &b), WEFT_OK);
        CHECK(pose_distance(&a, &b) < 1e-5);
        weft_motion found;
        CHECK_RESULT(weft_motion_from_name(weft_motion_name((weft_motion)m), &found), WEFT_OK);
        CHECK_EQ_INT(found, m);
    }
}

static void joints_at(const weft_motion_def *def, double t, float *xf)
{
    weft_pose p;
    CHECK_RESULT(weft_motion_sample(def, t, &p), WEFT_OK);
    CHECK_RESULT(weft_body_pose(g_body, &p, NULL, xf), WEFT_OK);
}

#define JY(xf, j) ((xf)[16 * (j) + 13])
#define JZ(xf, j) ((xf)[16 * (j) + 14])

static void test_motions_do_what_they_say(void)
{
    setup();
    if (!g_body) {
        return;
    }
    float xf[WEFT_BODY_JOINTS * 16];
    weft_motion_def walk = weft_default_motion_def(WEFT_MOTION_WALK);
    double p = weft_motion_period(&walk);
    joints_at(&walk, p / 4, xf);
    CHECK(JZ(xf, WEFT_JOINT_LEFT_ANKLE) > JZ(xf, WEFT_JOINT_RIGHT_ANKLE) + 0.2f); /* left foot forward */
    CHECK(JZ(xf, WEFT_JOINT_RIGHT_WRIST) > JZ(xf, WEFT_JOINT_LEFT_WRIST));       /* opposite arm */
    joints_at(&walk, 3 * p / 4, xf);
    CHECK(JZ(xf, WEFT_JOINT_RIGHT_ANKLE) > JZ(xf, WEFT_JOINT_LEFT_ANKLE) + 0.2f);
    CHECK(JY(xf, WEFT_JOINT_LEFT_WRIST) < JY(xf, WEFT_JOINT_LEFT_SHOULDER) - 0.3f); /* arms hang */

    weft_motion_def raise = weft_default_motion_def(WEFT_MOTION_ARM_RAISE);
    joints_at(&raise, weft_motion_period(&raise) / 2, xf);
    CHECK(JY(xf, WEFT_JOINT_LEFT_WRIST) > JY(xf, WEFT_JOINT_HEAD) + 0.2f);
    CHECK(JY(xf, WEFT_JOINT_RIGHT_WRIST) > JY(xf, WEFT_JOINT_HEAD) + 0.2f);

    weft_motion_def jump = weft_default_motion_def(WEFT_MOTION_JUMP);
    double jp = weft_motion_period(&jump);
    joints_at(&jump, 0.0, xf);
    float stand = JY(xf, WEFT_JOINT_PELVIS);
    joints_at(&jump, 0.52 * jp, xf);
    CHECK(JY(xf, WEFT_JOINT_PELVIS) > stand + 0.25f); /* in the air */
    joints_at(&jump, 0.22 * jp, xf);
    CHECK(JY(xf, WEFT_JOINT_PELVIS) < stand - 0.15f); /* crouched */

    weft_motion_def flip = weft_default_motion_def(WEFT_MOTION_FLIP);
    joints_at(&flip, 0.46 * weft_motion_period(&flip), xf);
    CHECK(JY(xf, WEFT_JOINT_HEAD) < JY(xf, WEFT_JOINT_PELVIS)); /* upside down mid-flip */

    weft_motion_def dance = weft_default_motion_def(WEFT_MOTION_DANCE);
    joints_at(&dance, weft_motion_period(&dance) / 2, xf);
    /* Half a turn: the face (head forward axis, column 2) points to -Z. */
    CHECK(xf[16 * WEFT_JOINT_PELVIS + 10] < -0.9f);
}

/* arm_spread opens the shoulders by exactly that angle and touches no other joint. */
static void test_arm_spread(void)
{
    setup();
    if (!g_body) {
        return;
    }
    float xf[WEFT_BODY_JOINTS * 16], xs[WEFT_BODY_JOINTS * 16];
    /* Idle at amplitude 0 holds the arms 1.25 rad down from the T-pose with no swing, in the
     * frontal plane: the upper arm's angle from straight down grows by exactly the spread. */
    weft_motion_def still = weft_default_motion_def(WEFT_MOTION_IDLE);
    still.amplitude = 0.0f;
    double base[2] = {0, 0};
    for (int k = 0; k < 3; ++k) {
        still.arm_spread = 0.2f * (float)k;
        joints_at(&still, 0.0, xf);
        for (int side = 0; side < 2; ++side) {
            const int sh = WEFT_JOINT_LEFT_SHOULDER + side, el = WEFT_JOINT_LEFT_ELBOW + side;
            double dx = xf[16 * el + 12] - xf[16 * sh + 12], dy = JY(xf, el) - JY(xf, sh);
            double angle = atan2(fabs(dx), -dy);
            if (k == 0) {
                base[side] = angle;
                CHECK(angle > 0.1 && angle < 0.5); /* about pi/2 - 1.25, the skeleton's own slope aside */
            }
            CHECK_NEAR(angle - base[side], still.arm_spread, 1e-4);
            CHECK(dx * (side == 0 ? 1.0 : -1.0) > 0.0); /* each arm on its own side */
        }
    }
    for (int m = 0; m < WEFT_MOTION_COUNT; ++m) {
        weft_motion_def def = weft_default_motion_def((weft_motion)m), wide = def;
        wide.arm_spread = 0.3f;
        for (int i = 0; i < 8; ++i) {
            double t = weft_motion_period(&def) * i / 8.0;
            joints_at(&def, t, xf);
            joints_at(&wide, t, xs);
            double arm = 0.0, rest = 0.0;
            for (int j = 0; j < WEFT_BODY_JOINTS; ++j) {
                for (int c = 12; c < 15; ++c) {
                    double d = fabs((double)xf[16 * j + c] - xs[16 * j + c]);
                    if (j >= WEFT_JOINT_LEFT_ELBOW) {
                        arm = fmax(arm, d);
                    } else {
                        rest = fmax(rest, d);
                    }
                }
            }
            CHECK_MSG(rest == 0.0, "%s: arm_spread moved a joint outside the arms by %g", weft_motion_name((weft_motion)m), rest);
            CHECK_MSG(arm > 0.02, "%s: arm_spread 0.3 moved the arms by only %g m", weft_motion_name((weft_motion)m), arm);
        }
    }
}

static void test_clips(void)
{
    setup();
    weft_motion_def walk = weft_default_motion_def(WEFT_MOTION_WALK);
    double period = weft_motion_period(&walk);
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_clip_from_motion(g_ctx, &walk, 2 * period, 60.0f, &clip), WEFT_OK);
    if (!clip) {
        return;
    }
    CHECK(clip->loops);
    CHECK_EQ_INT(clip->frame_count, (uint32_t)floor(2 * period * 60 + 0.5));
    CHECK(strcmp(clip->name, "walk") == 0);
    weft_pose a, b;
    /* At frame times the clip equals the motion; between frames it stays close. */
    CHECK_RESULT(weft_clip_sample(clip, 10.0 / 60.0, &a), WEFT_OK);
    CHECK_RESULT(weft_motion_sample(&walk, 10.0 / 60.0, &b), WEFT_OK);
    CHECK(pose_distance(&a, &b) < 1e-5);
    CHECK_RESULT(weft_clip_sample(clip, 10.5 / 60.0, &a), WEFT_OK);
    CHECK_RESULT(weft_motion_sample(&walk, 10.5 / 60.0, &b), WEFT_OK);
    CHECK(pose_distance(&a, &b) < 0.01);
    /* Resampling 60 -> 120 -> 60 returns the original frames. */
    weft_clip *up = NULL, *down = NULL;
    CHECK_RESULT(weft_clip_resample(clip, 120.0f, &up), WEFT_OK);
    if (up) {
        CHECK_EQ_INT(up->frame_count, 2 * clip->frame_count);
        CHECK_RESULT(weft_clip_resample(up, 60.0f, &down), WEFT_OK);
        if (down) {
            CHECK_EQ_INT(down->frame_count, clip->frame_count);
            double worst = 0;
            for (uint32_t i = 0; i < clip->frame_count * 72; ++i) {
                worst = fmax(worst, fabs(down->rotations[i] - clip->rotations[i]));
            }
            CHECK_NEAR(worst, 0.0, 1e-5);
        }
    }
    weft_clip_destroy(up);
    weft_clip_destroy(down);
    weft_clip_destroy(clip);

    /* A BVH-like clip: 3 frames at 30 fps, not looping; slerp halfway between 0 and 1 rad. */
    CHECK_RESULT(weft_clip_create(g_ctx, 3, 30.0f, &clip), WEFT_OK);
    if (!clip) {
        return;
    }
    clip->rotations[72 * 1 + 3 * 4 + 0] = 1.0f;
    clip->rotations[72 * 2 + 3 * 4 + 0] = 1.0f;
    clip->translations[3 * 2 + 1] = 0.6f;
    CHECK_RESULT(weft_clip_sample(clip, 0.5 / 30.0, &a), WEFT_OK);
    CHECK_NEAR(a.rotations[12], 0.5, 1e-6);
    CHECK_RESULT(weft_clip_sample(clip, 1.5 / 30.0, &a), WEFT_OK);
    CHECK_NEAR(a.translation[1], 0.3, 1e-6);
    CHECK_RESULT(weft_clip_sample(clip, 99.0, &a), WEFT_OK); /* held at the end */
    CHECK_NEAR(a.translation[1], 0.6, 1e-6);
    weft_clip *r60 = NULL;
    CHECK_RESULT(weft_clip_resample(clip, 60.0f, &r60), WEFT_OK);
    if (r60) {
        CHECK_EQ_INT(r60->frame_count, 5);
        CHECK_NEAR(r60->rotations[72 * 1 + 12], 0.5, 1e-6);
        weft_clip_destroy(r60);
    }
    clip->rotations[72 + 5] = NAN;
    r60 = (weft_clip *)(uintptr_t)0x1;
    CHECK_RESULT(weft_clip_resample(clip, 60.0f, &r60), WEFT_ERROR_NOT_FINITE);
    CHECK(r60 == (weft_clip *)(uintptr_t)0x1);
    CHECK_RESULT(weft_clip_sample(clip, 1.0 / 30.0, &a), WEFT_ERROR_NOT_FINITE);
    weft_clip_destroy(clip);
}

static void test_bad_input(void)
{
    weft_motion_def def = weft_default_motion_def(WEFT_MOTION_RUN);
    weft_pose p;
    CHECK_RESULT(weft_motion_sample(&def, NAN, &p), WEFT_ERROR_NOT_FINITE);
    def.speed = 0;
    CHECK_RESULT(weft_motion_sample(&def, 0.0, &p), WEFT_ERROR_INVALID_ARGUMENT);
    def = weft_default_motion_def(WEFT_MOTION_RUN);
    const float spreads[3] = {-0.1f, 0.9f, NAN};
    for (int k = 0; k < 3; ++k) {
        def.arm_spread = spreads[k];
        CHECK_RESULT(weft_motion_sample(&def, 0.0, &p), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(strstr(weft_last_error(), "arm_spread") != NULL);
    }
    def = weft_default_motion_def(WEFT_MOTION_COUNT);
    CHECK_RESULT(weft_motion_sample(&def, 0.0, &p), WEFT_ERROR_INVALID_ARGUMENT);
    weft_motion m;
    CHECK_RESULT(weft_motion_from_name("moonwalk", &m), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "moonwalk") != NULL);
    weft_clip *c = NULL;
    setup();
    CHECK_RESULT(weft_clip_create(g_ctx, 0, 60.0f, &c), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_clip_create(g_ctx, 10, -1.0f, &c), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(c == NULL);
}

static void cleanup(void)
{
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
    g_body = NULL;
    g_ctx = NULL;
    CHECK(1);
}

/* weft_pose_blend: the ends are the poses, the middle of a 1 rad turn is a 0.5 rad turn (slerp,
 * not a lerp of axis-angle vectors), the short way round, bad input refused untouched. */
static void test_pose_blend(void)
{
    weft_pose a, b, out;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    b.rotations[3 * 5 + 2] = 1.0f;  /* joint 5: 1 rad about z */
    b.rotations[3 * 7 + 0] = 3.0f;  /* joint 7: 3 rad about x ... */
    a.rotations[3 * 7 + 0] = -3.0f; /* ... from -3 rad: the short way is through pi */
    b.translation[1] = 2.0f;
    CHECK_RESULT(weft_pose_blend(&a, &b, 0.0, &out), WEFT_OK);
    CHECK_NEAR(out.rotations[3 * 5 + 2], 0.0f, 1e-6);
    CHECK_RESULT(weft_pose_blend(&a, &b, 1.0, &out), WEFT_OK);
    CHECK_NEAR(out.rotations[3 * 5 + 2], 1.0f, 1e-5);
    CHECK_NEAR(out.translation[1], 2.0f, 1e-6);
    CHECK_RESULT(weft_pose_blend(&a, &b, 0.5, &out), WEFT_OK);
    CHECK_NEAR(out.rotations[3 * 5 + 2], 0.5f, 1e-5);
    CHECK_NEAR(out.translation[1], 1.0f, 1e-6);
    /* halfway between -3 and 3 rad about x the short way: pi about x (either sign) */
    CHECK_NEAR(fabsf(out.rotations[3 * 7 + 0]), 3.14159265f, 1e-4);
    weft_pose keep = out;
    CHECK_RESULT(weft_pose_blend(&a, &b, 1.5, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_pose_blend(&a, &b, NAN, &out), WEFT_ERROR_INVALID_ARGUMENT);
    b.rotations[0] = NAN;
    CHECK_RESULT(weft_pose_blend(&a, &b, 0.5, &out), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(&keep, &out, sizeof out) == 0);
    CHECK_RESULT(weft_pose_blend(NULL, &b, 0.5, &out), WEFT_ERROR_INVALID_ARGUMENT);
}

TEST_MAIN(TEST_CASE(test_all_motions_loop_and_are_smooth), TEST_CASE(test_pose_blend), TEST_CASE(test_motions_do_what_they_say),
          TEST_CASE(test_arm_spread), TEST_CASE(test_clips),
          TEST_CASE(test_bad_input), TEST_CASE(cleanup))
