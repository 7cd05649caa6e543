/* weft_sim_sequence_def.garment_kind: the def chooses the garment and every other draw of the
 * seed (avatar, motion) stays as drawn; a value that is not a garment is refused. */
#include "test.h"
#include "weft/sim.h"
/* the runtime scene header (tests/xpbd/scene.h, the test meshes, shadows "xpbd/scene.h") */
#include "../../tools/lab/scene.h"

#include <string.h>

/* The description after the garment's name ("garment: tshirt on avatar h=..., motion ..."). */
static const char *after_kind(const char *description)
{
    const char *on = strstr(description, " on avatar");
    return on ? on : description;
}

static void test_kind_chosen(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    static const weft_cloth_kind kinds[3] = {WEFT_CLOTH_TSHIRT, WEFT_CLOTH_SKIRT, WEFT_CLOTH_DRESS};
    for (uint64_t seed = 1; seed <= 3; ++seed) {
        weft_sim_sequence_def def = weft_sim_default_sequence_def();
        def.scenario = WEFT_SIM_SCENARIO_GARMENT;
        def.cloth_vertices = 256;
        def.seed = seed;
        xscene drawn;
        CHECK_RESULT(xscene_build(ctx, &drawn, &def, seed, NULL), WEFT_OK);
        for (int k = 0; k < 3; ++k) {
            weft_sim_sequence_def chosen = def;
            chosen.garment_kind = kinds[k];
            xscene sc;
            CHECK_RESULT(xscene_build(ctx, &sc, &chosen, seed, NULL), WEFT_OK);
            char want[64];
            snprintf(want, sizeof want, "garment: %s on", weft_cloth_kind_name(kinds[k]));
            CHECK_MSG(strncmp(sc.description, want, strlen(want)) == 0, "seed %u: '%s'", (unsigned)seed,
                      sc.description);
            /* the same avatar and motion as the seed's own draw */
            CHECK_MSG(strcmp(after_kind(sc.description), after_kind(drawn.description)) == 0, "'%s' vs '%s'",
                      sc.description, drawn.description);
            CHECK(sc.collider.nv == drawn.collider.nv &&
                  memcmp(sc.collider.pos, drawn.collider.pos, sizeof(float) * 3 * sc.collider.nv) == 0);
            if (strncmp(drawn.description, want, strlen(want)) == 0) {
                /* choosing the garment the seed draws changes nothing */
                CHECK(sc.cloth.nv == drawn.cloth.nv &&
                      memcmp(sc.cloth.pos, drawn.cloth.pos, sizeof(float) * 3 * sc.cloth.nv) == 0);
            }
            xscene_free(&sc);
        }
        xscene_free(&drawn);
    }
    weft_context_destroy(ctx);
}

static void test_kind_refused(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    static const int32_t bad[] = {-2, WEFT_CLOTH_SHEET, WEFT_CLOTH_SHEET_IRREGULAR, WEFT_CLOTH_COUNT, 1000};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        weft_sim_sequence_def def = weft_sim_default_sequence_def();
        def.scenario = WEFT_SIM_SCENARIO_GARMENT;
        def.garment_kind = bad[i];
        weft_sim_sequence_result res = {0};
        CHECK_RESULT(weft_sim_generate(ctx, &def, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    }
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_kind_chosen), TEST_CASE(test_kind_refused))
