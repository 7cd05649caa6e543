/* The gripper scenario sets the sheet down with the grasped patch 2 cm above its initial
 * height: the hanging part lands first and folds under the patch, and pins driven back to the
 * initial 4 mm would press the folded layers into the ground (docs/REFSIM.md, gripper
 * rejections). Checks the schedule on the kinematics alone (no simulation). */
#include "test.h"
#include "weft/sim.h"
/* the runtime scene header (tests/xpbd/scene.h, the test meshes, shadows "xpbd/scene.h") */
#include "../../tools/lab/scene.h"

static void test_setdown_height(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    for (uint64_t seed = 1; seed <= 8; ++seed) {
        weft_sim_sequence_def def = weft_sim_default_sequence_def();
        def.scenario = WEFT_SIM_SCENARIO_GRIPPER;
        def.cloth_vertices = 256;
        def.seed = seed;
        xscene sc;
        CHECK_RESULT(xscene_build(ctx, &sc, &def, seed, NULL), WEFT_OK);
        const uint32_t nv = sc.cloth.nv, nc = sc.collider.nv;
        float *col = malloc(sizeof(float) * 3 * nc), *tgt = malloc(sizeof(float) * 3 * nv);
        uint32_t *idx = malloc(sizeof(uint32_t) * nv);
        CHECK(col && tgt && idx);
        float lowest = 1e9f, at_release = 1e9f, at_moved = 1e9f;
        for (uint32_t f = sc.f_close + 1; f <= sc.f_release; ++f) {
            xscene_collider_at(&sc, f, col);
            uint32_t np = xscene_pins_at(&sc, f, col, idx, tgt);
            CHECK(np == sc.grasp_count);
            for (uint32_t k = 0; k < np; ++k) {
                /* height above the vertex's initial height */
                float rise = tgt[3 * k + 1] - sc.cloth_init[3 * idx[k] + 1];
                if (f >= sc.f_moved) {
                    lowest = fminf(lowest, rise); /* over the set-down */
                }
                if (f == sc.f_release) {
                    at_release = fminf(at_release, rise);
                }
                if (f == sc.f_moved) {
                    at_moved = fminf(at_moved, rise);
                }
            }
        }
        /* Set down 2 cm up (float rounding of the targets aside), after the full lift. */
        CHECK_MSG(fabsf(at_release - 0.02f) < 1e-5f, "seed %u: patch set down %g m above its start", (unsigned)seed,
                  at_release);
        CHECK(lowest > 0.02f - 1e-5f);
        CHECK(fabsf(at_moved - (float)sc.lift) < 1e-5f);
        free(col);
        free(tgt);
        free(idx);
        xscene_free(&sc);
    }
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_setdown_height))
