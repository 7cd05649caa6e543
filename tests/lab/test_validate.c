/* The validator's cloth-cloth exemption (weft_sim_validator_set_self_exempt): a sheet pushed down
 * through another is a hit in the sweeps and in the triangle test; with the moving sheet's
 * vertices exempt it is not, and with the mask removed again it is. NULL validator is refused. */
#include "../xpbd/scene.h"
#include "test.h"
#include "weft/sim.h"

#include <string.h>

static void test_exempt_cloth_is_not_certified(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    test_mesh a = test_sheet(6, 6, 0.3f, 0.3f, 0.0f, 0.0f, 0.0f);
    test_mesh b = test_sheet(6, 6, 0.2f, 0.2f, 0.01f, 0.01f, 0.01f);
    test_mesh both = test_mesh_join(&a, &b);
    CHECK(both.pos && both.tris);
    float *after = malloc(sizeof(float) * 3 * both.nv);
    uint8_t *exempt = calloc(both.nv, 1);
    CHECK(after && exempt);
    memcpy(after, both.pos, sizeof(float) * 3 * both.nv);
    for (uint32_t i = a.nv; i < both.nv; ++i) {
        after[3 * i + 1] -= 0.02f; /* from 1 cm above the other sheet to 1 cm below it */
        exempt[i] = 1;
    }
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, both.tris, both.nt, both.nv, NULL, 0, 0, &v), WEFT_OK);
    weft_sim_validation val;
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK(val.ccd_hits > 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(v, exempt), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK_EQ_INT(val.ccd_hits, 0);
    CHECK_EQ_INT(val.intersection_hits, 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(v, NULL), WEFT_OK);
    CHECK_RESULT(weft_sim_validator_check(v, both.pos, after, NULL, NULL, &val), WEFT_OK);
    CHECK(val.ccd_hits > 0);
    CHECK_RESULT(weft_sim_validator_set_self_exempt(NULL, exempt), WEFT_ERROR_INVALID_ARGUMENT);
    weft_sim_validator_destroy(v);
    free(after);
    free(exempt);
    test_mesh_free(&a);
    test_mesh_free(&b);
    test_mesh_free(&both);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_exempt_cloth_is_not_certified))
