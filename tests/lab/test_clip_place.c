/* Clips placed on the floor (tools/lab/clip_place.c): a pose turned by weft_pose_place gains that
 * heading, its pelvis lands where asked and its height stays; weft_clip_chain plays two procedural
 * clips back to back, the first as it is, each next one starting where and facing where the one
 * before ended, the pelvis never jumping at a seam, the list repeating in order; bad input fails
 * and leaves the output untouched. */
#include "test.h"
#include "weft.h"
#include "weft/body.h"
#include "weft/clip_place.h"

#include <math.h>

static weft_context *g_ctx;
static weft_body *g_body;

static const double k_pi = 3.14159265358979323846;

static double wrap(double a)
{
    while (a > k_pi) {
        a -= 2.0 * k_pi;
    }
    while (a < -k_pi) {
        a += 2.0 * k_pi;
    }
    return a;
}

static weft_clip *procedural(weft_motion motion, double seconds)
{
    weft_motion_def d = weft_default_motion_def(motion);
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_clip_from_motion(g_ctx, &d, seconds, 60.0f, &clip), WEFT_OK);
    return clip;
}

static void frame_pose(const weft_clip *clip, uint32_t f, weft_pose *pose)
{
    memcpy(pose->rotations, clip->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS, sizeof pose->rotations);
    memcpy(pose->translation, clip->translations + (size_t)f * 3, sizeof pose->translation);
}

static void test_place_turns_and_moves(void)
{
    weft_clip *dance = procedural(WEFT_MOTION_DANCE, 1.0);
    weft_pose pose, placed;
    CHECK_RESULT(weft_clip_sample(dance, 0.4, &pose), WEFT_OK);
    for (double yaw = -3.0; yaw <= 3.0; yaw += 0.75) {
        placed = pose;
        double from[2], to[2] = {3.0, -2.0}, at[2];
        weft_pose_pelvis_xz(g_body, &pose, from);
        weft_pose_place(g_body, &placed, yaw, from, to);
        CHECK_NEAR(wrap(weft_pose_heading(&placed) - weft_pose_heading(&pose) - yaw), 0.0, 1e-5);
        weft_pose_pelvis_xz(g_body, &placed, at);
        CHECK_NEAR(at[0], to[0], 1e-5);
        CHECK_NEAR(at[1], to[1], 1e-5);
        CHECK_NEAR(placed.translation[1], pose.translation[1], 1e-6);
        for (int j = 1; j < WEFT_BODY_JOINTS; ++j) { /* only the root turns */
            CHECK(memcmp(placed.rotations + 3 * j, pose.rotations + 3 * j, 3 * sizeof(float)) == 0);
        }
    }
    weft_clip_destroy(dance);
}

static void test_chain_seams(void)
{
    enum { NA = 60, NB = 45, BLEND = 10 };
    weft_clip *a = procedural(WEFT_MOTION_WALK, NA / 60.0), *b = procedural(WEFT_MOTION_DANCE, NB / 60.0);
    /* the dance turned away, so that the seam has a heading to make up */
    for (uint32_t f = 0; f < b->frame_count; ++f) {
        weft_pose p;
        frame_pose(b, f, &p);
        const double from[2] = {0.0, 0.0}, to[2] = {1.5, 0.5};
        weft_pose_place(g_body, &p, 2.0, from, to);
        memcpy(b->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS, p.rotations, sizeof p.rotations);
        memcpy(b->translations + (size_t)f * 3, p.translation, sizeof p.translation);
    }
    const weft_clip *list[2] = {a, b};
    const uint32_t frames = NA + BLEND + NB + BLEND + NA;
    weft_clip *chain = NULL;
    CHECK_RESULT(weft_clip_chain(g_ctx, g_body, list, 2, frames, BLEND, &chain), WEFT_OK);
    CHECK(chain && chain->frame_count == frames && chain->fps == 60.0f);
    if (!chain) {
        weft_clip_destroy(a), weft_clip_destroy(b);
        return;
    }
    weft_pose p, q;
    for (uint32_t f = 0; f < NA; ++f) { /* the first clip plays as it is */
        CHECK_RESULT(weft_clip_sample(a, f / 60.0, &p), WEFT_OK);
        frame_pose(chain, f, &q);
        CHECK(memcmp(&p, &q, sizeof p) == 0);
    }
    /* each next clip starts on the last frame's pelvis, facing its heading */
    const uint32_t seams[2][2] = {{NA - 1, NA + BLEND}, {NA + BLEND + NB - 1, NA + BLEND + NB + BLEND}};
    for (int s = 0; s < 2; ++s) {
        double end[2], start[2];
        frame_pose(chain, seams[s][0], &p);
        frame_pose(chain, seams[s][1], &q);
        weft_pose_pelvis_xz(g_body, &p, end);
        weft_pose_pelvis_xz(g_body, &q, start);
        CHECK_NEAR(start[0], end[0], 1e-4);
        CHECK_NEAR(start[1], end[1], 1e-4);
        CHECK_NEAR(wrap(weft_pose_heading(&q) - weft_pose_heading(&p)), 0.0, 1e-4);
    }
    /* the pelvis moves smoothly through the whole chain (the dance was put 1.6 m away and turned) */
    double worst = 0.0;
    for (uint32_t f = 1; f < frames; ++f) {
        double x0[2], x1[2];
        frame_pose(chain, f - 1, &p);
        frame_pose(chain, f, &q);
        weft_pose_pelvis_xz(g_body, &p, x0);
        weft_pose_pelvis_xz(g_body, &q, x1);
        worst = fmax(worst, hypot(x1[0] - x0[0], x1[1] - x0[1]));
    }
    CHECK_MSG(worst < 0.05, "the pelvis jumps %.3f m in one frame", worst);
    weft_clip_destroy(chain);
    weft_clip_destroy(a);
    weft_clip_destroy(b);
}

static void test_chain_bad_input(void)
{
    weft_clip *a = procedural(WEFT_MOTION_IDLE, 0.5);
    weft_clip *sentinel = (weft_clip *)&g_ctx, *out = sentinel;
    const weft_clip *list[2] = {a, NULL};
    CHECK_RESULT(weft_clip_chain(g_ctx, g_body, list, 0, 100, 10, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_clip_chain(g_ctx, g_body, list, 1, 0, 10, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_clip_chain(g_ctx, g_body, list, 2, 100, 10, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "clip 1") != NULL);
    CHECK(out == sentinel);
    /* one short clip repeated: 100 frames of 30 + 5 blended each time */
    CHECK_RESULT(weft_clip_chain(g_ctx, g_body, list, 1, 100, 5, &out), WEFT_OK);
    CHECK(out != sentinel && out->frame_count == 100);
    if (out != sentinel) {
        weft_clip_destroy(out);
    }
    weft_clip_destroy(a);
}

int main(int argc, char **argv)
{
    weft_context_def cd = weft_default_context_def();
    weft_avatar_def ad = weft_default_avatar_def();
    if (weft_context_create(&cd, &g_ctx) != WEFT_OK || weft_avatar_create(g_ctx, &ad, &g_body) != WEFT_OK) {
        fprintf(stderr, "setup: %s\n", weft_last_error());
        return 1;
    }
    static const test_case_ cases[] = {TEST_CASE(test_place_turns_and_moves), TEST_CASE(test_chain_seams),
                                       TEST_CASE(test_chain_bad_input)};
    const int rc = test_run_(cases, sizeof cases / sizeof cases[0], argc, argv);
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
    return rc;
}
