/* Golden-image tests. Each scene in samples/common/scenes.c is rendered at 256x256 and compared
 * with tests/golden/<scene>.png: a pixel differs when an RGB channel is off by more than 8
 * counts, and a scene passes when at most 0.5% of its pixels differ. On failure the rendered
 * image and a diff (differing pixels red) go to <build>/golden-out/.
 *
 * Determinism: the renderer switches Mesa to softpipe with its C vertex path
 * (GALLIUM_DRIVER=softpipe, DRAW_USE_LLVM=0, set with setenv before OSMesa starts): no JIT code
 * for the host's vector ISA and no thread count affects the pixels, unlike llvmpipe. The
 * tolerance absorbs libm differences in the transcendental calls that build the meshes (the
 * procedural sheet, the avatar's surface), which can differ between C libraries.
 *
 * ctest runs one test per scene (samples.golden.<scene>) and samples.golden for the comparison
 * itself; without an argument this program runs every case.
 *
 * Regenerate: WEFT_UPDATE_GOLDENS=1 ctest -R samples.golden   (or: weft render --update-goldens)
 */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "weft_scenes.h"

#include <sys/stat.h>

static weft_context *make_context(void)
{
    weft_context_def cdef = weft_default_context_def();
    cdef.isa = WEFT_ISA_SCALAR; /* scenes only pose meshes; the portable kernels suffice */
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cdef, &ctx), WEFT_OK);
    return ctx;
}

static void check_scene(uint32_t scene)
{
    const char *update_env = getenv("WEFT_UPDATE_GOLDENS");
    bool update = update_env && update_env[0] == '1';
    const char *out_dir = WEFT_BINARY_DIR "/golden-out";
    mkdir(out_dir, 0755);
    weft_golden_outcome o;
    weft_context *ctx = make_context();
    weft_result res = weft_golden_check(scene, ctx, WEFT_SOURCE_DIR "/tests/golden", out_dir, update, &o);
    weft_context_destroy(ctx);
    CHECK_MSG(res == WEFT_OK, "scene %s: %s (%s)", weft_golden_scene_name(scene), weft_result_string(res),
              weft_last_error());
    if (res != WEFT_OK) {
        return;
    }
    if (o.updated) {
        printf("updated %s\n", o.golden_path);
    } else {
        printf("%-20s %6llu pixels over %u counts (%.4f%%), max channel diff %u\n", weft_golden_scene_name(scene),
               (unsigned long long)o.diff.pixels_over, WEFT_GOLDEN_CHANNEL_TOLERANCE, 100.0 * o.diff.fraction_over,
               o.diff.max_channel_diff);
    }
    CHECK_MSG(o.passed, "scene %s differs from %s: %.3f%% of pixels over tolerance (limit %.3f%%); see %s and %s",
              weft_golden_scene_name(scene), o.golden_path, 100.0 * o.diff.fraction_over, 100.0 * WEFT_GOLDEN_MAX_FRACTION,
              o.diff_path, o.actual_path);
}

/* One ctest per scene (tests/samples/CMakeLists.txt runs this program with a case name). */
static void check_scene_named(const char *name)
{
    for (uint32_t i = 0; i < weft_golden_scene_count(); ++i) {
        if (strcmp(weft_golden_scene_name(i), name) == 0) {
            check_scene(i);
            return;
        }
    }
    CHECK_MSG(0, "scene %s is not in this build", name);
}

static void test_scene_sheet_sphere(void) { check_scene_named("sheet_sphere"); }
static void test_scene_avatar_rest(void) { check_scene_named("avatar_rest"); }
static void test_scene_avatar_posed(void) { check_scene_named("avatar_posed"); }
static void test_scene_avatar_cmu(void) { check_scene_named("avatar_cmu"); }
static void test_scene_avatar_tshirt(void) { check_scene_named("avatar_tshirt"); }
static void test_scene_avatar_dress_posed(void) { check_scene_named("avatar_dress_posed"); }
static void test_scene_avatar_model_int8(void) { check_scene_named("avatar_model_int8"); }
static void test_scene_avatar_cmu_worn(void) { check_scene_named("avatar_cmu_worn"); }
static void test_scene_avatar_cmu_worn_lbs(void) { check_scene_named("avatar_cmu_worn_lbs"); }
static void test_scene_avatar_cmu_worn_xpbd_fast(void) { check_scene_named("avatar_cmu_worn_xpbd_fast"); }

/* The same scene rendered twice in one process must be bit-identical: rendering holds no
 * state between frames that could leak into the image. */
static void test_check_repeatable(void)
{
    weft_render_def def = weft_default_render_def();
    def.width = def.height = 64;
    weft_renderer *r = NULL;
    CHECK_RESULT(weft_renderer_create(&def, &r), WEFT_OK);
    if (!r) {
        return;
    }
    uint8_t *first = malloc(64 * 64 * 4);
    CHECK(first != NULL);
    weft_context *ctx = make_context();
    CHECK_RESULT(weft_golden_scene_render(0, ctx, r), WEFT_OK);
    memcpy(first, weft_renderer_pixels(r), 64 * 64 * 4);
    CHECK_RESULT(weft_golden_scene_render(0, ctx, r), WEFT_OK);
    weft_context_destroy(ctx);
    CHECK(memcmp(first, weft_renderer_pixels(r), 64 * 64 * 4) == 0);
    free(first);
    weft_renderer_destroy(r);
}

/* A golden compared with a corrupted copy must fail and write the diff image. */
static void test_check_detects_change(void)
{
    weft_render_def def = weft_default_render_def();
    def.width = def.height = 32;
    uint8_t a[32 * 32 * 4], b[32 * 32 * 4], diff[32 * 32 * 4];
    memset(a, 100, sizeof a);
    memcpy(b, a, sizeof b);
    weft_image_diff d;
    CHECK_RESULT(weft_render_compare(a, b, 32, 32, WEFT_GOLDEN_CHANNEL_TOLERANCE, &d, diff), WEFT_OK);
    CHECK_EQ_INT(d.pixels_over, 0);
    for (int i = 0; i < 10; ++i) {
        b[4 * (i * 37) + 1] = 100 + 9; /* just over the tolerance */
    }
    b[4 * 5 + 2] = 100 + 8; /* exactly at the tolerance: not counted */
    CHECK_RESULT(weft_render_compare(a, b, 32, 32, WEFT_GOLDEN_CHANNEL_TOLERANCE, &d, diff), WEFT_OK);
    CHECK_EQ_INT(d.pixels_over, 10);
    CHECK_EQ_INT(d.max_channel_diff, 9);
    CHECK_NEAR(d.fraction_over, 10.0 / 1024.0, 1e-12);
    CHECK_EQ_INT(diff[4 * 37 + 0], 255);
    CHECK_EQ_INT(diff[4 * 37 + 1], 0);
    (void)def;
}

TEST_MAIN(TEST_CASE(test_check_detects_change), TEST_CASE(test_check_repeatable),
          TEST_CASE(test_scene_sheet_sphere), TEST_CASE(test_scene_avatar_rest), TEST_CASE(test_scene_avatar_posed),
          TEST_CASE(test_scene_avatar_cmu), TEST_CASE(test_scene_avatar_tshirt), TEST_CASE(test_scene_avatar_dress_posed),
          TEST_CASE(test_scene_avatar_model_int8), TEST_CASE(test_scene_avatar_cmu_worn),
          TEST_CASE(test_scene_avatar_cmu_worn_lbs), TEST_CASE(test_scene_avatar_cmu_worn_xpbd_fast))
