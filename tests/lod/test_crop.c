/* The collider crop as a level-of-detail axis: the optional crop columns of the table (absent,
 * some, all, any order; malformed values fail naming the column), and a weft_lod_garment that
 * applies its level's crop at creation and at every switch, giving the same step as a plain
 * garment created with that crop. */
#include "sheet_floor_scene.h"
#include "test.h"
#include "weft.h"
#include "weft/lod.h"

#include <stdbool.h>
#include <stdint.h>

#define GAME WEFT_SOURCE_DIR "/tools/train/models/game.safetensors"

#define HEADER "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames"

static weft_context *ctx_make(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

static weft_result load(weft_context *ctx, const char *text, weft_lod_table **t)
{
    return weft_lod_table_load_memory(ctx, text, strlen(text), t);
}

static void test_columns_optional(void)
{
    weft_context *ctx = ctx_make();
    weft_lod_table *t = NULL;
    /* A table from before the crop columns: every model level has the model's own crop. */
    CHECK_RESULT(load(ctx, HEADER "\ngame-fp32,model,game,fp32,-,on,1,3,13,8,7,826\nlbs,lbs,-,-,-,on,1,0.3,30,0,7,826\n",
                      &t),
                 WEFT_OK);
    if (t) {
        for (uint32_t i = 0; i < 2; ++i) {
            const weft_lod_level *l = weft_lod_table_level(t, i);
            CHECK(l->crop_cm == 0.0 && l->collider_crop == WEFT_COLLIDER_CROP_BOX && l->max_collider_tokens == 0);
        }
        weft_lod_table_destroy(t);
        t = NULL;
    }
    /* All three, in another order, '-' where the default is meant. */
    CHECK_RESULT(load(ctx,
                      "max_collider_tokens,collider_crop," HEADER ",crop_cm\n"
                      "-,-,game-own,model,game,fp32,-,on,1,3,13,8,7,826,-\n"
                      "4000,cells,game-c8,model,game,int8,-,off,1,1.5,14,8,7,826,8.5\n"
                      "-,box,game-b5,model,game,fp16,-,on,1,2,15,8,7,826,5\n"
                      "-,-,xpbd-5,xpbd,-,-,5,on,1,40,8,5,7,826,-\n",
                      &t),
                 WEFT_OK);
    if (t) {
        const weft_lod_level *l = weft_lod_table_level(t, 0);
        CHECK(l->crop_cm == 0.0 && l->collider_crop == WEFT_COLLIDER_CROP_BOX && l->max_collider_tokens == 0);
        l = weft_lod_table_level(t, 1);
        CHECK(l->crop_cm == 8.5 && l->collider_crop == WEFT_COLLIDER_CROP_CELLS && l->max_collider_tokens == 4000);
        l = weft_lod_table_level(t, 2);
        CHECK(l->crop_cm == 5.0 && l->collider_crop == WEFT_COLLIDER_CROP_BOX && l->max_collider_tokens == 0);
        l = weft_lod_table_level(t, 3);
        CHECK(l->method == WEFT_METHOD_XPBD && l->crop_cm == 0.0 && l->max_collider_tokens == 0);
        weft_lod_table_destroy(t);
        t = NULL;
    }
    /* Only one of them. */
    CHECK_RESULT(load(ctx, HEADER ",crop_cm\ngame-c4,model,game,fp32,-,on,1,3,13,8,7,826,4\n", &t), WEFT_OK);
    if (t) {
        CHECK(weft_lod_table_level(t, 0)->crop_cm == 4.0);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
}

static void test_malformed_crop(void)
{
    weft_context *ctx = ctx_make();
    static const struct {
        const char *text, *must_name;
    } cases[] = {
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,-1\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,0\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,nan\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,inf\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,8cm\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,20000\n", "crop_cm"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,\n", "crop_cm"},
        {HEADER ",crop_cm\nx,lbs,-,-,-,on,1,3,13,8,7,826,5\n", "crop_cm"},
        {HEADER ",collider_crop\nx,model,game,fp32,-,on,1,3,13,8,7,826,grid\n", "collider_crop"},
        {HEADER ",collider_crop\nx,xpbd,-,-,5,on,1,3,13,8,7,826,cells\n", "collider_crop"},
        {HEADER ",max_collider_tokens\nx,model,game,fp32,-,on,1,3,13,8,7,826,0\n", "max_collider_tokens"},
        {HEADER ",max_collider_tokens\nx,model,game,fp32,-,on,1,3,13,8,7,826,-5\n", "max_collider_tokens"},
        {HEADER ",max_collider_tokens\nx,model,game,fp32,-,on,1,3,13,8,7,826,1e3\n", "max_collider_tokens"},
        {HEADER ",max_collider_tokens\nx,model,game,fp32,-,on,1,3,13,8,7,826,99999999999\n", "max_collider_tokens"},
        {HEADER ",crop_cm,crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826,5,5\n", "twice"},
        {HEADER ",crop_cm\nx,model,game,fp32,-,on,1,3,13,8,7,826\n", "columns"},
        {HEADER ",crop\nx,model,game,fp32,-,on,1,3,13,8,7,826,5\n", "unknown column"},
        {"level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,crop_cm\n"
         "x,model,game,fp32,-,on,1,3,13,8,7,5\n",
         "frames"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        weft_lod_table *t = NULL;
        weft_result r = load(ctx, cases[i].text, &t);
        CHECK_MSG(r == WEFT_ERROR_FORMAT && t == NULL, "case %zu: %s", i, weft_result_string(r));
        CHECK_MSG(strstr(weft_last_error(), cases[i].must_name) != NULL, "case %zu: '%s' does not name '%s'", i,
                  weft_last_error(), cases[i].must_name);
        weft_lod_table_destroy(t);
    }
    weft_context_destroy(ctx);
}

/* ---------------------------------------------------------------------------------------- */
/* A garment at crop levels                                                                   */

typedef sheet_floor scene;

/* The sheet 3 cm above the floor: it falls, and the margin decides how much of the floor the
 * model sees. */
static void scene_make(scene *s)
{
    sheet_floor_make(s, 0.03f, 0.0f);
}

static const char k_levels[] = HEADER ",crop_cm,collider_crop,max_collider_tokens\n"
                                      "own,model,game,fp32,-,off,1,2,10,1,1,10,-,-,-\n"
                                      "near,model,game,fp32,-,off,1,1,12,1,1,10,8,box,-\n"
                                      "capped,model,game,fp32,-,off,1,0.5,13,1,1,10,8,cells,9\n"
                                      "wide,model,game,fp32,-,off,1,3,9,1,1,10,40,box,-\n"
                                      "lbs,lbs,-,-,-,off,1,0.1,30,0,1,10,-,-,-\n";

/* One step of a plain garment with level l's crop from state (x, xp): positions into out, tokens
 * returned. */
static uint32_t plain_step(weft_context *ctx, const scene *s, const weft_model *m, const weft_lod_level *l,
                           const float *x, const float *xp, float *out)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = WEFT_METHOD_MODEL;
    d.model = m;
    d.ccd.enabled = l->ccd;
    d.collider_crop_margin = (float)(l->crop_cm / 100.0);
    d.collider_crop = l->collider_crop;
    d.max_collider_tokens = l->max_collider_tokens;
    d.rest_positions = s->rest;
    d.vertex_count = s->nv;
    d.triangles = s->tris;
    d.triangle_count = s->nt;
    d.collider_rest_positions = s->floor;
    d.collider_vertex_count = s->nf;
    d.collider_triangles = s->ftris;
    d.collider_triangle_count = s->nft;
    weft_garment *g = NULL;
    uint32_t tokens = UINT32_MAX;
    if (weft_garment_create(ctx, &d, &g) == WEFT_OK && weft_garment_set_state(g, x, xp) == WEFT_OK &&
        weft_garment_set_collider(g, s->floor) == WEFT_OK && weft_garment_step(g) == WEFT_OK) {
        memcpy(out, weft_garment_positions(g), (size_t)s->nv * 3 * sizeof(float));
        tokens = weft_garment_stats(g).collider_tokens;
    }
    weft_garment_destroy(g);
    return tokens;
}

static void test_garment_follows_level_crop(void)
{
    weft_context *ctx = ctx_make();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, GAME, &m), WEFT_OK);
    weft_lod_table *t = NULL;
    CHECK_RESULT(load(ctx, k_levels, &t), WEFT_OK);
    if (!m || !t) {
        weft_model_destroy(m);
        weft_lod_table_destroy(t);
        weft_context_destroy(ctx);
        return;
    }
    static scene s;
    scene_make(&s);
    const weft_model *models[] = {m};
    weft_lod_garment_def d = weft_default_lod_garment_def();
    d.table = t;
    d.level = 0;
    d.models = models;
    d.model_count = 1;
    d.rest_positions = s.rest;
    d.vertex_count = s.nv;
    d.triangles = s.tris;
    d.triangle_count = s.nt;
    d.collider_rest_positions = s.floor;
    d.collider_vertex_count = s.nf;
    d.collider_triangles = s.ftris;
    d.collider_triangle_count = s.nft;
    weft_lod_garment *lg = NULL;
    CHECK_RESULT(weft_lod_garment_create(ctx, &d, &lg), WEFT_OK);
    if (!lg) {
        weft_model_destroy(m);
        weft_lod_table_destroy(t);
        weft_context_destroy(ctx);
        return;
    }
    /* own -> near -> capped -> lbs -> wide -> own, two frames at each, each model frame compared
     * with a plain garment of that crop stepped from the same state (the game model keeps one
     * latent frame, so a switch carries everything it needs). */
    static const uint32_t order[] = {0, 1, 2, 4, 3, 0};
    static float x[3 * 64], xp[3 * 64], want[3 * 64];
    memcpy(x, s.rest, sizeof x);
    memcpy(xp, s.rest, sizeof xp);
    uint32_t tokens_at[5] = {0};
    for (size_t k = 0; k < sizeof order / sizeof order[0]; ++k) {
        CHECK_RESULT(weft_lod_garment_switch(lg, order[k]), WEFT_OK);
        CHECK_EQ_INT(weft_lod_garment_level(lg), order[k]);
        const weft_lod_level *l = weft_lod_table_level(t, order[k]);
        for (int f = 0; f < 2; ++f) {
            const uint32_t expect = l->method == WEFT_METHOD_MODEL ? plain_step(ctx, &s, m, l, x, xp, want) : 0;
            CHECK_RESULT(weft_lod_garment_set_collider(lg, s.floor), WEFT_OK);
            CHECK_RESULT(weft_lod_garment_step(lg), WEFT_OK);
            const float *now = weft_lod_garment_positions(lg);
            if (l->method == WEFT_METHOD_MODEL) {
                const uint32_t got = weft_garment_stats(weft_lod_garment_current(lg)).collider_tokens;
                CHECK_MSG(got == expect, "level %s frame %d: %u tokens, a plain garment of that crop %u", l->name, f,
                          got, expect);
                CHECK_MSG(memcmp(now, want, sizeof want) == 0, "level %s frame %d: positions differ from a plain "
                          "garment of that crop", l->name, f);
                tokens_at[order[k]] = got;
            }
            memcpy(xp, x, sizeof x);
            memcpy(x, now, sizeof x);
        }
    }
    /* The levels do what their crops say: 8 cm keeps less than the model's 15, a cap of 9 keeps
     * 9, 40 cm keeps more. */
    CHECK_MSG(tokens_at[1] < tokens_at[0] && tokens_at[2] == 9 && tokens_at[3] > tokens_at[0],
              "tokens own %u near %u capped %u wide %u", tokens_at[0], tokens_at[1], tokens_at[2], tokens_at[3]);
    weft_lod_garment_destroy(lg);
    weft_model_destroy(m);
    weft_lod_table_destroy(t);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_columns_optional), TEST_CASE(test_malformed_crop), TEST_CASE(test_garment_follows_level_crop))
