/* Dense layered cloth (a sheet piled up under a gripper) needs many self contacts per vertex:
 * the solver's contact list must hold them all. A dropped pair keeps its bound but gets no
 * repulsion, so its gap shrinks towards zero and the validator (10 um) rejects the frame. */
#include "scene.h"
#include "test.h"
#include "weft/sim.h"
#include "xpbd/xpbd.h"

#include <string.h>

/* `layers` 8 x 8 cm sheets of side x side vertices, 2 mm apart and slightly offset, on the top of
 * a 20 cm box: one mesh (*cloth) and the XPBD garment stepping it at 20 substeps. */
static weft_garment *stacked_layers(weft_context *ctx, int layers, uint32_t side, test_mesh *cloth, test_mesh *box)
{
    *cloth = (test_mesh){0};
    test_mesh layer[8];
    for (int k = 0; k < layers; ++k) {
        layer[k] = test_sheet(side, side, 0.08f, 0.08f, 0.0007f * (float)k, 0.1035f + 0.002f * (float)k,
                              -0.0005f * (float)k);
        cloth->nv += layer[k].nv;
        cloth->nt += layer[k].nt;
    }
    cloth->pos = malloc(sizeof(float) * 3 * cloth->nv);
    cloth->tris = malloc(sizeof(uint32_t) * 3 * cloth->nt);
    CHECK(cloth->pos && cloth->tris);
    uint32_t v0 = 0, t0 = 0;
    for (int k = 0; k < layers; ++k) {
        memcpy(cloth->pos + 3 * v0, layer[k].pos, sizeof(float) * 3 * layer[k].nv);
        for (uint32_t i = 0; i < 3 * layer[k].nt; ++i) {
            cloth->tris[3 * t0 + i] = layer[k].tris[i] + v0;
        }
        v0 += layer[k].nv;
        t0 += layer[k].nt;
        test_mesh_free(&layer[k]);
    }
    const float lo[3] = {-0.1f, 0.0f, -0.1f}, hi[3] = {0.1f, 0.1f, 0.1f};
    *box = test_box(lo, hi);
    weft_garment_def gd = test_garment_def(WEFT_METHOD_XPBD, cloth, box, 20);
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &gd, &g), WEFT_OK);
    return g;
}

static void test_stacked_layers(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    /* Three sheets with 1 cm edges (as a 1k gripper sheet): more than 24 self contacts per
     * vertex per pass (a list of 24 per vertex dropped 286584 pairs over these 10 frames). */
    test_mesh all, box;
    weft_garment *g = stacked_layers(ctx, 3, 9, &all, &box);
    uint32_t dropped = 0;
    for (int f = 0; f < 10 && g; ++f) {
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        xpbd_frame_stats st = weft__xpbd_last_stats(g);
        dropped += st.contacts_dropped;
        CHECK(st.contacts > 0);
    }
    CHECK_MSG(dropped == 0, "%u contact pairs dropped", dropped);
    weft_garment_destroy(g);
    test_mesh_free(&all);
    test_mesh_free(&box);
    weft_context_destroy(ctx);
}

/* Finer still (2.5 mm edges, as a small 4k gripper sheet), four layers: the first sweep of a
 * pass finds more candidate self contacts than the list holds (64 per vertex), so the pass
 * sweeps again keeping only the pairs its final bounds let close to the self radius (and, when
 * those still overflow, the ones with the least slack). Nothing is dropped then, and no two
 * layers cross (the validator's CCD and intersection tests, every frame). */
static void test_fine_layers_second_sweep(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    enum { FRAMES = 3 };
    test_mesh all, box;
    weft_garment *g = stacked_layers(ctx, 4, 33, &all, &box);
    weft_sim_validator *val = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, all.tris, all.nt, all.nv, box.tris, box.nt, box.nv, &val), WEFT_OK);
    float *prev = malloc(sizeof(float) * 3 * all.nv);
    CHECK(prev != NULL);
    if (prev) {
        memcpy(prev, all.pos, sizeof(float) * 3 * all.nv);
    }
    uint32_t dropped = 0, tight = 0, hits = 0;
    for (int f = 0; f < FRAMES && prev && g; ++f) {
        CHECK_RESULT(weft_garment_set_collider(g, box.pos), WEFT_OK);
        CHECK_RESULT(weft_garment_step(g), WEFT_OK);
        xpbd_frame_stats st = weft__xpbd_last_stats(g);
        dropped += st.contacts_dropped;
        tight += st.tight_passes;
        weft_sim_validation v;
        CHECK_RESULT(weft_sim_validator_check(val, prev, weft_garment_positions(g), box.pos, box.pos, &v), WEFT_OK);
        hits += v.ccd_hits + v.intersection_hits;
        memcpy(prev, weft_garment_positions(g), sizeof(float) * 3 * all.nv);
    }
    CHECK_MSG(tight > 0, "no pass overflowed: the scene no longer tests the second sweep");
    CHECK_MSG(dropped == 0, "%u contact pairs dropped after the second sweeps", dropped);
    CHECK_MSG(hits == 0, "%u validator hits", hits);
    free(prev);
    weft_sim_validator_destroy(val);
    weft_garment_destroy(g);
    test_mesh_free(&all);
    test_mesh_free(&box);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_stacked_layers), TEST_CASE(test_fine_layers_second_sweep))
