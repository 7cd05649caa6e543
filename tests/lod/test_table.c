/* The LOD table: a valid CSV loads (any column order, comments, CRLF), every malformed input
 * fails with WEFT_ERROR_FORMAT naming the line and column and returns nothing, and the pick
 * chooses the cheapest level meeting both targets, else says which target it had to give up. */
#include "test.h"
#include "weft/lod.h"

static const char *const header =
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames\n";

static weft_context *ctx_make(void)
{
    weft_context_def d = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&d, &ctx), WEFT_OK);
    return ctx;
}

static weft_result load_text(weft_context *ctx, const char *text, weft_lod_table **t)
{
    return weft_lod_table_load_memory(ctx, text, strlen(text), t);
}

static const char *const good =
    "# measured by weft bench lod\n"
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames\n"
    "lbs,lbs,-,-,-,off,1,0.05,4.0,0.01,3,300\n"
    "xpbd-5,xpbd,-,-,5,on,1,0.9,1.5,0.05,3,300\n"
    "xpbd-40,xpbd,-,-,40,on,1,6.0,0.4,0.02,3,300\n"
    "game-int8,model,game,int8,-,off,1,0.6,2.0,0.04,3,300\n"
    "garment-fp32,model,garment,fp32,-,on,1,2.5,0.9,0.03,3,300\n";

static void test_load_good(void)
{
    weft_context *ctx = ctx_make();
    weft_lod_table *t = NULL;
    CHECK_RESULT(load_text(ctx, good, &t), WEFT_OK);
    CHECK_EQ_INT(weft_lod_table_count(t), 5);
    const weft_lod_level *l = weft_lod_table_level(t, 1);
    CHECK(l && strcmp(l->name, "xpbd-5") == 0 && l->method == WEFT_METHOD_XPBD && l->substeps == 5 && l->ccd);
    l = weft_lod_table_level(t, 3);
    CHECK(l && l->method == WEFT_METHOD_MODEL && strcmp(l->model, "game") == 0 && l->precision == WEFT_PRECISION_INT8 &&
          !l->ccd && l->substeps == 0);
    CHECK_NEAR(l->ms_per_frame, 0.6, 1e-12);
    CHECK_NEAR(l->mve_cm, 2.0, 1e-12);
    CHECK(weft_lod_table_level(t, 5) == NULL);
    uint32_t idx = 99;
    CHECK_RESULT(weft_lod_table_find(t, "garment-fp32", &idx), WEFT_OK);
    CHECK_EQ_INT(idx, 4);
    idx = 99;
    CHECK_RESULT(weft_lod_table_find(t, "nope", &idx), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_EQ_INT(idx, 99);
    weft_lod_table_destroy(t);

    /* Columns reordered, CRLF line ends, blank lines and spaces around cells. */
    const char *shuffled = "frames,sequences,level,ms_per_frame,mve_cm,method,model,precision,substeps,ccd,resolution,"
                           "max_edge_strain\r\n"
                           "\r\n"
                           "120, 2, xpbd-10 ,1.25,0.75,xpbd,-,-,10,on,1,0.02\r\n";
    t = NULL;
    CHECK_RESULT(load_text(ctx, shuffled, &t), WEFT_OK);
    l = weft_lod_table_level(t, 0);
    CHECK(l && strcmp(l->name, "xpbd-10") == 0 && l->frames == 120 && l->sequences == 2 && l->substeps == 10);
    CHECK_NEAR(l ? l->ms_per_frame : 0, 1.25, 1e-12);
    weft_lod_table_destroy(t);

    /* From a file, and a missing file. */
    char path[512];
    snprintf(path, sizeof path, "%s/tests/lod_table_%d.csv", WEFT_BINARY_DIR, 1);
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (f) {
        fputs(good, f);
        fclose(f);
        t = NULL;
        CHECK_RESULT(weft_lod_table_load_file(ctx, path, &t), WEFT_OK);
        CHECK_EQ_INT(weft_lod_table_count(t), 5);
        weft_lod_table_destroy(t);
        remove(path);
    }
    t = NULL;
    CHECK_RESULT(weft_lod_table_load_file(ctx, "/nonexistent/lod.csv", &t), WEFT_ERROR_IO);
    CHECK(t == NULL);
    CHECK(strstr(weft_last_error(), "/nonexistent/lod.csv") != NULL);
    weft_context_destroy(ctx);
}

#define HEADER_GARMENT                                                                                             \
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames,"      \
    "tether_cm,strain_limit_pct\n"
#define HEADER_CONTACT                                                                                             \
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames,"      \
    "strain_limit_pct,strain_contact_cm\n"
#define HEADER_PUSH                                                                                                \
    "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames,"      \
    "push_cm\n"

/* The optional tether and strain-limit columns: absent means none, "-" means none, numbers in cm
 * and %; every method may have them. */
static void test_load_garment_columns(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    const char *text = HEADER_GARMENT "t,lbs,-,-,-,on,1,1,1,0,1,1,3,10\n"
                                      "n,xpbd,-,-,5,on,0.25,1,1,0,1,1,-,-\n"
                                      "m,model,game,int8,-,on,1,1,1,0,1,1,2.5,-\n";
    weft_lod_table *t = NULL;
    CHECK_RESULT(weft_lod_table_load_memory(ctx, text, strlen(text), &t), WEFT_OK);
    if (t) {
        const weft_lod_level *a = weft_lod_table_level(t, 0), *b = weft_lod_table_level(t, 1),
                             *c = weft_lod_table_level(t, 2);
        CHECK(a->tether_cm == 3.0 && a->strain_limit_pct == 10.0);
        CHECK(b->tether_cm == 0.0 && b->strain_limit_pct == 0.0 && b->resolution == 0.25);
        CHECK(c->tether_cm == 2.5 && c->strain_limit_pct == 0.0);
        CHECK(a->strain_contact_cm == 0.0 && c->strain_contact_cm == 0.0);
    }
    weft_lod_table_destroy(t);
    const char *contact = HEADER_CONTACT "x,xpbd,-,-,5,off,1,1,1,0,1,1,10,1\n"
                                         "p,xpbd,-,-,5,off,1,1,1,0,1,1,10,-\n";
    t = NULL;
    CHECK_RESULT(weft_lod_table_load_memory(ctx, contact, strlen(contact), &t), WEFT_OK);
    if (t) {
        CHECK(weft_lod_table_level(t, 0)->strain_contact_cm == 1.0);
        CHECK(weft_lod_table_level(t, 1)->strain_contact_cm == 0.0);
        CHECK(weft_lod_table_level(t, 0)->push_cm == 0.0);
    }
    weft_lod_table_destroy(t);
    const char *push = HEADER_PUSH "x,model,game,int8,-,on,1,1,1,0,1,1,1\n"
                                   "p,lbs,-,-,-,on,1,1,1,0,1,1,-\n";
    t = NULL;
    CHECK_RESULT(weft_lod_table_load_memory(ctx, push, strlen(push), &t), WEFT_OK);
    if (t) {
        CHECK(weft_lod_table_level(t, 0)->push_cm == 1.0);
        CHECK(weft_lod_table_level(t, 1)->push_cm == 0.0);
    }
    weft_lod_table_destroy(t);
    weft_context_destroy(ctx);
}

static void test_load_malformed(void)
{
    weft_context *ctx = ctx_make();
    static const struct {
        const char *row;    /* appended after the header; NULL entries use `whole` */
        const char *whole;
        const char *must_name;
    } cases[] = {
        {"x,warp,-,-,-,on,1,1,1,0,1,1\n", NULL, "method"},
        {"x,model,-,fp32,-,on,1,1,1,0,1,1\n", NULL, "model"},
        {"x,model,game,fp64,-,on,1,1,1,0,1,1\n", NULL, "precision"},
        {"x,xpbd,-,-,0,on,1,1,1,0,1,1\n", NULL, "substeps"},
        {"x,xpbd,-,-,5x,on,1,1,1,0,1,1\n", NULL, "substeps"},
        {"x,xpbd,-,-,1001,on,1,1,1,0,1,1\n", NULL, "substeps"},
        {"x,lbs,-,-,5,on,1,1,1,0,1,1\n", NULL, "substeps"},
        {"x,lbs,game,-,-,on,1,1,1,0,1,1\n", NULL, "model"},
        {"x,lbs,-,int8,-,on,1,1,1,0,1,1\n", NULL, "precision"},
        {"x,lbs,-,-,-,yes,1,1,1,0,1,1\n", NULL, "ccd"},
        {"x,lbs,-,-,-,on,2,1,1,0,1,1\n", NULL, "resolution"},
        {"x,lbs,-,-,-,on,1,nan,1,0,1,1\n", NULL, "ms_per_frame"},
        {"x,lbs,-,-,-,on,1,0,1,0,1,1\n", NULL, "ms_per_frame"},
        {"x,lbs,-,-,-,on,1,-1,1,0,1,1\n", NULL, "ms_per_frame"},
        {"x,lbs,-,-,-,on,1,1,inf,0,1,1\n", NULL, "mve_cm"},
        {"x,lbs,-,-,-,on,1,1,-0.5,0,1,1\n", NULL, "mve_cm"},
        {"x,lbs,-,-,-,on,1,1,1,1e999,1,1\n", NULL, "max_edge_strain"},
        {"x,lbs,-,-,-,on,1,1,1,0,0,1\n", NULL, "sequences"},
        {"x,lbs,-,-,-,on,1,1,1,0,1,-3\n", NULL, "frames"},
        {"x,lbs,-,-,-,on,1,1,1,0,1\n", NULL, "columns"},
        {"x,lbs,-,-,-,on,1,1,1,0,1,1,9\n", NULL, "columns"},
        {"bad name,lbs,-,-,-,on,1,1,1,0,1,1\n", NULL, "level"},
        {",lbs,-,-,-,on,1,1,1,0,1,1\n", NULL, "level"},
        {"x,lbs,-,-,-,on,1,1,1,0,1,1\nx,lbs,-,-,-,off,1,1,1,0,1,1\n", NULL, "twice"},
        {NULL, "", "header"},
        {NULL, "# only a comment\n", "header"},
        {NULL, "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,"
               "frames\n",
         "no levels"},
        {NULL, "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,"
               "frame\nx,lbs,-,-,-,on,1,1,1,0,1,1\n",
         "unknown column"},
        {NULL, "level,level,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,"
               "frames\nx,lbs,-,-,-,on,1,1,1,0,1,1\n",
         "twice"},
        {NULL, "level,method\nx,lbs\n", "header"},
        {NULL, HEADER_GARMENT "x,lbs,-,-,-,on,1,1,1,0,1,1,0,-\n", "tether_cm"},
        {NULL, HEADER_GARMENT "x,lbs,-,-,-,on,1,1,1,0,1,1,3cm,-\n", "tether_cm"},
        {NULL, HEADER_GARMENT "x,lbs,-,-,-,on,1,1,1,0,1,1,-,0\n", "strain_limit_pct"},
        {NULL, HEADER_GARMENT "x,lbs,-,-,-,on,1,1,1,0,1,1,-,1001\n", "strain_limit_pct"},
        {NULL, HEADER_GARMENT "x,lbs,-,-,-,on,1,1,1,0,1,1,-,nan\n", "strain_limit_pct"},
        {NULL, HEADER_CONTACT "x,lbs,-,-,-,on,1,1,1,0,1,1,-,1\n", "strain_contact_cm"},
        {NULL, HEADER_CONTACT "x,lbs,-,-,-,on,1,1,1,0,1,1,10,0\n", "strain_contact_cm"},
        {NULL, HEADER_CONTACT "x,lbs,-,-,-,on,1,1,1,0,1,1,10,101\n", "strain_contact_cm"},
        {NULL, HEADER_PUSH "x,lbs,-,-,-,on,1,1,1,0,1,1,0\n", "push_cm"},
        {NULL, HEADER_PUSH "x,lbs,-,-,-,on,1,1,1,0,1,1,11\n", "push_cm"},
        {NULL, HEADER_PUSH "x,lbs,-,-,-,on,1,1,1,0,1,1,inf\n", "push_cm"},
    };
    char text[2048];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        if (cases[i].row) {
            snprintf(text, sizeof text, "%s%s", header, cases[i].row);
        } else {
            snprintf(text, sizeof text, "%s", cases[i].whole);
        }
        weft_lod_table *t = NULL;
        weft_result r = load_text(ctx, text, &t);
        CHECK_MSG(r == WEFT_ERROR_FORMAT, "case %zu returned %s", i, weft_result_string(r));
        CHECK_MSG(t == NULL, "case %zu returned a table", i);
        CHECK_MSG(strstr(weft_last_error(), cases[i].must_name) != NULL, "case %zu: message '%s' lacks '%s'", i,
                  weft_last_error(), cases[i].must_name);
        weft_lod_table_destroy(t);
    }
    /* A long cell, an embedded NUL, and a header that is all that arrived (size cut). */
    char longrow[400];
    memset(longrow, 'a', sizeof longrow);
    longrow[sizeof longrow - 1] = '\0';
    snprintf(text, sizeof text, "%s%s,lbs,-,-,-,on,1,1,1,0,1,1\n", header, longrow);
    weft_lod_table *t = NULL;
    CHECK_RESULT(load_text(ctx, text, &t), WEFT_ERROR_FORMAT);
    CHECK(t == NULL);
    const char withnul[] = "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,"
                           "sequences,frames\nx,lb\0s,-,-,-,on,1,1,1,0,1,1\n";
    CHECK_RESULT(weft_lod_table_load_memory(ctx, withnul, sizeof withnul - 1, &t), WEFT_ERROR_FORMAT);
    CHECK(t == NULL);
    CHECK_RESULT(weft_lod_table_load_memory(ctx, good, 40, &t), WEFT_ERROR_FORMAT);
    CHECK(t == NULL);
    /* Argument checks. */
    CHECK_RESULT(weft_lod_table_load_memory(NULL, good, strlen(good), &t), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_lod_table_load_memory(ctx, NULL, 5, &t), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_lod_table_load_memory(ctx, good, strlen(good), NULL), WEFT_ERROR_INVALID_ARGUMENT);
    weft_context_destroy(ctx);
}

/* Every line of `good` cut at every byte either loads or fails cleanly. */
static void test_load_truncations(void)
{
    weft_context *ctx = ctx_make();
    size_t n = strlen(good);
    int loaded = 0;
    for (size_t cut = 0; cut <= n; ++cut) {
        weft_lod_table *t = NULL;
        weft_result r = weft_lod_table_load_memory(ctx, good, cut, &t);
        CHECK(r == WEFT_OK || r == WEFT_ERROR_FORMAT);
        CHECK((r == WEFT_OK) == (t != NULL));
        loaded += r == WEFT_OK;
        weft_lod_table_destroy(t);
    }
    CHECK(loaded > 0);
    weft_context_destroy(ctx);
}

static void test_pick(void)
{
    weft_context *ctx = ctx_make();
    weft_lod_table *t = NULL;
    CHECK_RESULT(load_text(ctx, good, &t), WEFT_OK);
    if (!t) {
        weft_context_destroy(ctx);
        return;
    }
    uint32_t lv = 99;
    /* Generous: the cheapest meeting 2 cm is game-int8 (0.6 ms) over xpbd-5 (0.9 ms). */
    CHECK_EQ_INT(weft_lod_pick(t, 10.0, 2.0, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 3);
    /* 1 cm: garment-fp32 (2.5 ms, 0.9 cm) is cheaper than xpbd-40 (6 ms). */
    CHECK_EQ_INT(weft_lod_pick(t, 10.0, 1.0, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 4);
    /* 0.5 cm needs xpbd-40. */
    CHECK_EQ_INT(weft_lod_pick(t, 10.0, 0.5, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 2);
    /* Budget 1 ms and 0.5 cm: nothing meets both; the most accurate under 1 ms is xpbd-5. */
    CHECK_EQ_INT(weft_lod_pick(t, 1.0, 0.5, &lv), WEFT_LOD_PICK_ACCURACY_MISSED);
    CHECK_EQ_INT(lv, 1);
    /* Budget on the boundary counts as within. */
    CHECK_EQ_INT(weft_lod_pick(t, 0.6, 2.0, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 3);
    /* Nothing fits 0.01 ms: the cheapest (lbs). */
    CHECK_EQ_INT(weft_lod_pick(t, 0.01, 1.0, &lv), WEFT_LOD_PICK_OVER_BUDGET);
    CHECK_EQ_INT(lv, 0);
    /* Infinite budget is "no limit". */
    CHECK_EQ_INT(weft_lod_pick(t, INFINITY, 0.1, &lv), WEFT_LOD_PICK_ACCURACY_MISSED);
    CHECK_EQ_INT(lv, 2);
    /* Restricted to usable levels (e.g. models not loaded): without game-int8 the 2 cm pick is xpbd-5. */
    const uint8_t usable[5] = {1, 1, 1, 0, 1};
    CHECK_EQ_INT(weft_lod_pick_among(t, usable, 10.0, 2.0, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 1);
    const uint8_t only_lbs[5] = {1, 0, 0, 0, 0};
    CHECK_EQ_INT(weft_lod_pick_among(t, only_lbs, 10.0, 1.0, &lv), WEFT_LOD_PICK_ACCURACY_MISSED);
    CHECK_EQ_INT(lv, 0);
    const uint8_t none[5] = {0, 0, 0, 0, 0};
    lv = 55;
    CHECK_EQ_INT(weft_lod_pick_among(t, none, 10.0, 1.0, &lv), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(lv, 55);
    /* Invalid: output untouched, message set. */
    lv = 77;
    CHECK_EQ_INT(weft_lod_pick(t, NAN, 1.0, &lv), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(weft_lod_pick(t, 1.0, -1.0, &lv), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(weft_lod_pick(t, 0.0, 1.0, &lv), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(weft_lod_pick(NULL, 1.0, 1.0, &lv), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(weft_lod_pick(t, 1.0, 1.0, NULL), WEFT_LOD_PICK_INVALID);
    CHECK_EQ_INT(lv, 77);
    CHECK(strstr(weft_last_error(), "weft_lod_pick") != NULL);
    CHECK(strlen(weft_lod_pick_result_string(WEFT_LOD_PICK_ACCURACY_MISSED)) > 0);
    weft_lod_table_destroy(t);

    /* Ties: equal cost goes to the more accurate, equal error to the cheaper. */
    const char *ties = "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,"
                       "sequences,frames\n"
                       "a,xpbd,-,-,5,on,1,1.0,2.0,0,1,1\n"
                       "b,xpbd,-,-,6,on,1,1.0,1.0,0,1,1\n"
                       "c,xpbd,-,-,7,on,1,3.0,0.5,0,1,1\n"
                       "d,xpbd,-,-,8,on,1,2.0,0.5,0,1,1\n";
    t = NULL;
    CHECK_RESULT(load_text(ctx, ties, &t), WEFT_OK);
    CHECK_EQ_INT(weft_lod_pick(t, 10.0, 2.0, &lv), WEFT_LOD_PICK_OK);
    CHECK_EQ_INT(lv, 1);
    CHECK_EQ_INT(weft_lod_pick(t, 10.0, 0.1, &lv), WEFT_LOD_PICK_ACCURACY_MISSED);
    CHECK_EQ_INT(lv, 3);
    weft_lod_table_destroy(t);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_load_good), TEST_CASE(test_load_garment_columns), TEST_CASE(test_load_malformed), TEST_CASE(test_load_truncations),
          TEST_CASE(test_pick))
