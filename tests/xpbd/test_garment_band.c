/* A skirt's or dress's top ring is pinned to the body as a band, except where an arm comes down
 * onto it during the pre-roll: pinned vertices cannot yield, and the upper arm swept through a
 * dress's band at the armpits in every rejected dress (docs/REFSIM.md, dress rejections).
 * Checks on the kinematics alone (no simulation), recomputing the arm distances independently. */
#include "test.h"
#include "weft/sim.h"
/* the runtime scene header (tests/xpbd/scene.h, the test meshes, shadows "xpbd/scene.h") */
#include "../../runtime/xpbd/scene.h"

#include <string.h>

/* Smallest distance from point p to a body vertex mostly skinned to the shoulder..hand joints. */
static double arm_distance(const weft_body *body, const float *verts, const float *p)
{
    const uint32_t nv = weft_body_vertex_count(body);
    const float *w = weft_body_weights(body);
    double best = 1e30;
    for (uint32_t i = 0; i < nv; ++i) {
        float s = 0.0f;
        for (uint32_t j = WEFT_JOINT_LEFT_SHOULDER; j <= WEFT_JOINT_RIGHT_HAND; ++j) {
            s += w[24 * (size_t)i + j];
        }
        if (s <= 0.5f) {
            continue;
        }
        double d[3] = {verts[3 * i] - p[0], verts[3 * i + 1] - p[1], verts[3 * i + 2] - p[2]};
        best = fmin(best, sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
    }
    return best;
}

static void test_band_clear_of_arms(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    uint32_t banded = 0, dresses_released = 0;
    for (uint64_t seed = 1; seed <= 9; ++seed) {
        weft_sim_sequence_def def = weft_sim_default_sequence_def();
        def.scenario = WEFT_SIM_SCENARIO_GARMENT;
        def.cloth_vertices = 1024;
        def.seed = seed;
        xscene sc;
        CHECK_RESULT(xscene_build(ctx, &sc, &def, seed), WEFT_OK);
        const bool dress = strstr(sc.description, "dress") != NULL;
        const bool skirt = strstr(sc.description, "skirt") != NULL;
        if (!dress && !skirt) {
            CHECK(sc.band_count == 0 && sc.band_released == 0); /* T-shirts rest on the shoulders */
            xscene_free(&sc);
            continue;
        }
        banded++;
        /* The band is the top ring, less what was released. */
        float top = -1e9f;
        for (uint32_t i = 0; i < sc.cloth.nv; ++i) {
            top = fmaxf(top, sc.cloth.pos[3 * (size_t)i + 1]);
        }
        uint32_t ring = 0;
        for (uint32_t i = 0; i < sc.cloth.nv; ++i) {
            ring += sc.cloth.pos[3 * (size_t)i + 1] >= top - 0.012f;
        }
        CHECK_MSG(sc.band_count + sc.band_released == ring, "seed %u: band %u + released %u != ring %u",
                  (unsigned)seed, sc.band_count, sc.band_released, ring);
        CHECK_MSG(sc.band_count * 2 > ring, "seed %u: only %u of %u ring vertices hold the garment", (unsigned)seed,
                  sc.band_count, ring);
        dresses_released += dress && sc.band_released > 0;
        /* Every pinned band vertex stays 4 cm from the arms over the whole pre-roll. */
        const uint32_t nc = sc.collider.nv, nv = sc.cloth.nv;
        float *col = malloc(sizeof(float) * 3 * nc), *tgt = malloc(sizeof(float) * 3 * nv);
        uint32_t *idx = malloc(sizeof(uint32_t) * nv);
        CHECK(col && tgt && idx);
        double closest = 1e30;
        for (uint32_t f = 0; f <= sc.preroll; f += 3) {
            xscene_collider_at(&sc, f, col);
            uint32_t np = xscene_pins_at(&sc, f, col, idx, tgt);
            CHECK(np == sc.band_count);
            for (uint32_t k = 0; k < np; ++k) {
                closest = fmin(closest, arm_distance(sc.body, col, tgt + 3 * (size_t)k));
            }
        }
        CHECK_MSG(closest >= 0.04 - 1e-6, "seed %u: a pinned band vertex comes %.4f m from an arm", (unsigned)seed,
                  closest);
        free(col);
        free(tgt);
        free(idx);
        xscene_free(&sc);
    }
    CHECK(banded >= 2);
    CHECK_MSG(dresses_released >= 1, "no dress among the seeds released a band vertex");
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_band_clear_of_arms))
