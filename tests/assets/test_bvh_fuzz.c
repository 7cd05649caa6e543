/* Fuzz target for the BVH importer: arbitrary bytes -> weft_bvh_load_memory. An accepted
 * input must give a finite clip at 60 Hz; a rejected one must explain itself in
 * weft_last_error(). Built two ways (tests/fuzz/CMakeLists.txt): with libFuzzer
 * (-DWEFT_BUILD_FUZZ=ON, clang), and as the ctest fuzz.bvh_replay together with
 * tests/fuzz/replay_main.c; test_bvh.c runs its own mutation loop over the CMU clips too.
 *
 *   bash tools/fuzz.sh 60 bvh     (seeds: tests/fuzz/corpus/bvh, dictionary: tests/fuzz/bvh.dict) */
#include "bvh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(cond)                                                                              \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "fuzz_bvh: property failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
            abort();                                                                               \
        }                                                                                          \
    } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static weft_context *ctx;
    if (!ctx) {
        weft_context_def def = weft_default_context_def();
        REQUIRE(weft_context_create(&def, &ctx) == WEFT_OK);
    }
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *clip = NULL;
    weft_result r = weft_bvh_load_memory(ctx, data, size, &def, &clip);
    if (r != WEFT_OK) {
        REQUIRE(clip == NULL);
        REQUIRE(weft_last_error()[0] != '\0');
        return 0;
    }
    REQUIRE(clip && clip->frame_count > 0 && clip->fps == 60.0f);
    for (size_t i = 0; i < (size_t)clip->frame_count * WEFT_POSE_ROTATION_FLOATS; ++i) {
        REQUIRE(isfinite(clip->rotations[i]));
    }
    for (size_t i = 0; i < (size_t)clip->frame_count * 3; ++i) {
        REQUIRE(isfinite(clip->translations[i]));
    }
    weft_clip_destroy(clip);
    return 0;
}
