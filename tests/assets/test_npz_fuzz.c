/* Fuzz target for the .npz / .npy readers and the SMPL loader. Linked with
 * tests/fuzz/replay_main.c it runs in ctest (seed archives from the fake_smpl fixture plus
 * deterministic mutations); built with clang -fsanitize=fuzzer it is a libFuzzer target:
 *   clang -g -fsanitize=fuzzer,address,undefined -Iinclude -Iruntime -Iruntime/assets \
 *         tests/assets/test_npz_fuzz.c build/lib/libweft_assets.a build/lib/libweft.a \
 *         -lminizip -lz -lassimp -lcjson -lm */
#include "npz.h"
#include "weft.h"
#include "weft/body.h"

#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static weft_context *ctx;
    if (!ctx) {
        weft_context_def def = weft_default_context_def();
        if (weft_context_create(&def, &ctx) != WEFT_OK) {
            return 0;
        }
    }
    /* The bytes as an archive and as a lone .npy image. */
    weft_body *body = NULL;
    if (weft_smpl_load_npz_memory(ctx, data, size, &body) == WEFT_OK) {
        uint32_t nv = weft_body_vertex_count(body);
        weft_pose pose = {{0}, {0}};
        pose.rotations[3] = 0.5f;
        float joints[WEFT_BODY_JOINTS * 16];
        (void)nv;
        weft_body_pose(body, &pose, NULL, joints);
        weft_body_destroy(body);
    }
    weft_npy_array a;
    if (weft_npy_parse(data, size, "fuzz", &a) == WEFT_OK && a.dtype != WEFT_NPY_UNSUPPORTED && a.count <= 4096) {
        float out[4096];
        weft_npy_to_f32(&a, out, a.count);
    }
    return 0;
}
