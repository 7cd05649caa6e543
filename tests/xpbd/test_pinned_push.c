/* Kinematically pinned cloth pushing free cloth (a gripper's grasped patch pressed into the
 * sheet below it): the free sheet must be carried along without the two crossing. The pinned
 * patch moves 0.25 mm per substep, so a four-substep proximity window would take 1 mm off the
 * free sheet's bounds: it could then retreat only 0.4 (d - 1 mm) per window and falls behind
 * for every gap d under 3.5 mm, far outside the 1.5 mm contact radius. The solver must shorten
 * the window for moving pins as it does for a moving collider. */
#include "scene.h"
#include "test.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

#include <string.h>

static void test_pinned_patch_lifts_sheet(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    /* Free sheet A 2 cm above a smaller pinned sheet B that rises at 0.6 m/s (the peak speed
     * of a gripper set-down) for 20 frames. */
    test_mesh a = test_sheet(11, 11, 0.2f, 0.2f, 0.0f, 0.02f, 0.0f);
    test_mesh b = test_sheet(5, 5, 0.08f, 0.08f, 0.003f, 0.0f, -0.002f);
    test_mesh both = test_mesh_join(&a, &b);
    CHECK(both.pos && both.tris);
    const uint32_t S = 40, frames = 20;
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD, &both, NULL, S);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    weft_sim_validator *val = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, both.tris, both.nt, both.nv, NULL, 0, 0, &val), WEFT_OK);
    float *path = malloc(sizeof(float) * 3 * both.nv * (S + 1));
    float *prev = malloc(sizeof(float) * 3 * both.nv);
    uint32_t *idx = malloc(sizeof(uint32_t) * b.nv);
    float *tgt = malloc(sizeof(float) * 3 * b.nv);
    CHECK(path && prev && idx && tgt);
    CHECK_RESULT(weft__xpbd_record_substeps(g, path, S), WEFT_OK);
    const double speed = 0.6;
    uint32_t hits = 0;
    for (uint32_t f = 1; f <= frames; ++f) {
        for (uint32_t i = 0; i < b.nv; ++i) {
            idx[i] = a.nv + i;
            tgt[3 * i + 0] = b.pos[3 * i + 0];
            tgt[3 * i + 1] = (float)(b.pos[3 * i + 1] + speed * f / 60.0);
            tgt[3 * i + 2] = b.pos[3 * i + 2];
        }
        memcpy(prev, weft_garment_positions(g), sizeof(float) * 3 * both.nv);
        CHECK_RESULT(weft_garment_set_pins(g, idx, tgt, b.nv), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        /* The solver certifies its substep path (the chord may graze where the path bends). */
        weft_sim_validation v;
        CHECK_RESULT(weft_sim_validator_check(val, prev, weft_garment_positions(g), NULL, NULL, &v), WEFT_OK);
        if (v.ccd_hits || v.intersection_hits) {
            CHECK_EQ_INT(weft__xpbd_recorded_states(g), S + 1);
            CHECK_RESULT(weft_sim_validator_check_path(val, path, S + 1, NULL, NULL, &v), WEFT_OK);
        }
        hits += v.ccd_hits + v.intersection_hits;
    }
    CHECK_MSG(hits == 0, "the pinned patch crossed the free sheet: %u validator hits", hits);
    /* The free sheet was carried up: its centre rides above the patch (20 frames at 0.6 m/s
     * lift the patch to 0.2 m). */
    const float *x = weft_garment_positions(g);
    const float patch_y = (float)(speed * frames / 60.0);
    const float centre_y = x[3 * (5 * 11 + 5) + 1];
    CHECK_MSG(centre_y > patch_y && centre_y < patch_y + 0.01f, "sheet centre at %g, patch at %g", centre_y, patch_y);
    xpbd_frame_stats st = weft__xpbd_last_stats(g);
    CHECK(st.min_self_distance > 0.0);
    free(path);
    free(prev);
    free(idx);
    free(tgt);
    weft_sim_validator_destroy(val);
    weft_garment_destroy(g);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&both);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_pinned_patch_lifts_sheet))
