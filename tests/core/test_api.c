/* Public API contract: defaults, result strings, allocator hook, argument checking, and the
 * garment lifecycle's failure modes (no model, bad meshes, NaN) leaving state untouched. */
#include "test.h"
#include "weft.h"

#include <stdint.h>

typedef struct counting_allocator {
    size_t live_bytes;
    int live_blocks;
    int fail_after; /* -1: never fail */
} counting_allocator;

static void *count_alloc(size_t size, size_t alignment, void *user)
{
    counting_allocator *a = user;
    if (a->fail_after == 0) {
        return NULL;
    }
    if (a->fail_after > 0) {
        a->fail_after--;
    }
    void *p = aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
    if (p) {
        a->live_bytes += size;
        a->live_blocks++;
    }
    return p;
}

static void count_free(void *ptr, size_t size, void *user)
{
    counting_allocator *a = user;
    a->live_bytes -= size;
    a->live_blocks--;
    free(ptr);
}

static void test_result_strings(void)
{
    for (int r = 0; r < WEFT_RESULT_COUNT; ++r) {
        const char *s = weft_result_string((weft_result)r);
        CHECK(s != NULL);
        CHECK_MSG(strcmp(s, "unknown result") != 0, "result %d has no string", r);
        for (int q = 0; q < r; ++q) {
            CHECK_MSG(strcmp(s, weft_result_string((weft_result)q)) != 0, "results %d and %d share '%s'", q, r, s);
        }
    }
    CHECK(strcmp(weft_result_string((weft_result)9999), "unknown result") == 0);
}

static void test_version_and_config(void)
{
    char expect[32];
    snprintf(expect, sizeof expect, "%d.%d.%d", WEFT_VERSION_MAJOR, WEFT_VERSION_MINOR, WEFT_VERSION_PATCH);
    CHECK(strcmp(weft_version_string(), expect) == 0);
    const char *cfg = weft_config_string();
    CHECK(strstr(cfg, expect) != NULL);
    CHECK(strstr(cfg, "isa=") != NULL);
}

static void test_context_defaults_and_errors(void)
{
    weft_context_def def = weft_default_context_def();
    CHECK(def.max_workers == 1);
    CHECK(def.isa == WEFT_ISA_AUTO);
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    CHECK(ctx != NULL);
    CHECK(weft_context_isa(ctx) != WEFT_ISA_AUTO);
    weft_context_destroy(ctx);

    weft_context_def raw = {0};
    weft_context *none = (weft_context *)(uintptr_t)0x1;
    CHECK_RESULT(weft_context_create(&raw, &none), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(none == (weft_context *)(uintptr_t)0x1); /* untouched on failure */
    CHECK(strstr(weft_last_error(), "weft_default_context_def") != NULL);
    CHECK_RESULT(weft_context_create(NULL, &none), WEFT_ERROR_INVALID_ARGUMENT);

    def.max_workers = 0;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_ERROR_INVALID_ARGUMENT);
    def = weft_default_context_def();
    def.isa = (weft_isa)77;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_ERROR_INVALID_ARGUMENT);
    def = weft_default_context_def();
    def.isa = WEFT_ISA_SCALAR;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    CHECK(weft_context_isa(ctx) == WEFT_ISA_SCALAR);
    weft_context_destroy(ctx);
}

/* A 2x2-quad sheet: 9 vertices, 8 triangles, in the XZ plane. */
static float g_sheet[9 * 3];
static uint32_t g_sheet_tris[8 * 3];

static void make_sheet(void)
{
    for (int j = 0; j < 3; ++j) {
        for (int i = 0; i < 3; ++i) {
            float *p = g_sheet + 3 * (j * 3 + i);
            p[0] = 0.1f * (float)i;
            p[1] = 1.0f;
            p[2] = 0.1f * (float)j;
        }
    }
    int t = 0;
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            uint32_t a = (uint32_t)(j * 3 + i), b = a + 1, c = a + 3, d = a + 4;
            uint32_t quad[6] = {a, c, b, b, c, d};
            memcpy(g_sheet_tris + 6 * t++, quad, sizeof quad);
        }
    }
}

static void test_garment_needs_model(void)
{
    make_sheet();
    counting_allocator counter = {0, 0, -1};
    weft_context_def cdef = weft_default_context_def();
    cdef.allocator = (weft_allocator){count_alloc, count_free, &counter};
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cdef, &ctx), WEFT_OK);
    CHECK(counter.live_blocks == 1);

    weft_garment_def def = weft_default_garment_def();
    CHECK(def.method == WEFT_METHOD_MODEL);
    CHECK(def.ccd.enabled);
    CHECK(def.substeps == 10);
    def.rest_positions = g_sheet;
    def.vertex_count = 9;
    def.triangles = g_sheet_tris;
    def.triangle_count = 8;
    weft_garment *g = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_NO_MODEL);
    CHECK(g == NULL);
    CHECK(strstr(weft_last_error(), "model") != NULL);
    CHECK(counter.live_blocks == 1); /* nothing leaked by the failed create */

    weft_garment_def raw = {0};
    CHECK_RESULT(weft_garment_create(ctx, &raw, &g), WEFT_ERROR_INVALID_ARGUMENT);
    weft_context_destroy(ctx);
    CHECK(counter.live_blocks == 0);
    CHECK(counter.live_bytes == 0);
}

static void test_garment_rejects_bad_meshes(void)
{
    make_sheet();
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cdef, &ctx), WEFT_OK);
    weft_garment_def def = weft_default_garment_def();
    def.method = WEFT_METHOD_XPBD;
    def.rest_positions = g_sheet;
    def.vertex_count = 9;
    def.triangles = g_sheet_tris;
    def.triangle_count = 8;
    weft_garment *g = NULL;

    uint32_t bad_index[8 * 3];
    memcpy(bad_index, g_sheet_tris, sizeof bad_index);
    bad_index[5] = 9;
    def.triangles = bad_index;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_DEGENERATE_MESH);
    CHECK(strstr(weft_last_error(), "triangle 1") != NULL);

    uint32_t repeated[8 * 3];
    memcpy(repeated, g_sheet_tris, sizeof repeated);
    repeated[1] = repeated[0];
    def.triangles = repeated;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_DEGENERATE_MESH);

    float collapsed[9 * 3];
    memcpy(collapsed, g_sheet, sizeof collapsed);
    for (int i = 0; i < 9; ++i) {
        collapsed[3 * i + 2] = 0.0f; /* every vertex on one line */
    }
    def.triangles = g_sheet_tris;
    def.rest_positions = collapsed;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_DEGENERATE_MESH);

    float with_nan[9 * 3];
    memcpy(with_nan, g_sheet, sizeof with_nan);
    with_nan[4] = NAN;
    def.rest_positions = with_nan;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_NOT_FINITE);

    def.rest_positions = g_sheet;
    def.substeps = 0;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_INVALID_ARGUMENT);
    def.substeps = 10;
    def.method = WEFT_METHOD_XPBD;
    def.substeps_max = 5; /* below substeps */
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(strstr(weft_last_error(), "substeps_max") != NULL);
    def.substeps_max = 4001;
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_INVALID_ARGUMENT);
    def.substeps_max = 0;
    def.collider_vertex_count = 3; /* collider count without arrays */
    CHECK_RESULT(weft_garment_create(ctx, &def, &g), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(g == NULL);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_result_strings), TEST_CASE(test_version_and_config),
          TEST_CASE(test_context_defaults_and_errors), TEST_CASE(test_garment_needs_model),
          TEST_CASE(test_garment_rejects_bad_meshes))
