/* Fuzz target for the OBJ reader (samples/common/pc2.c, weft_obj_read: the user's garment of
 * `--garment obj:PATH`): arbitrary bytes -> a file -> weft_obj_read (it takes a path only, so
 * each input goes to a per-process file).
 *
 * The file is always readable, so a rejection must be WEFT_ERROR_FORMAT or _NOT_FINITE with a
 * message, and the outputs must be left untouched. An accepted file must give at least one
 * vertex and one triangle, every coordinate within +-WEFT_MAX_COORDINATE, every index in range;
 * small accepted meshes are written back with weft_obj_write and read again, which must give
 * the same triangles and positions equal to 7 significant digits. Any violated property aborts,
 * which the fuzzer reports.
 *
 * Built two ways (tests/fuzz/CMakeLists.txt): with libFuzzer (WEFT_BUILD_FUZZ=ON, clang), and as
 * the ctest fuzz.obj_replay together with replay_main.c. */
#define _POSIX_C_SOURCE 200809L /* getpid */

#include "pc2.h"
#include "core/core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(cond)                                                                              \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "fuzz_obj: property failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
            abort();                                                                               \
        }                                                                                          \
    } while (0)

#define ROUND_TRIP_MAX_VERTICES 2048u

static void write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    REQUIRE(f != NULL);
    REQUIRE(fwrite(data, 1, size, f) == size);
    REQUIRE(fclose(f) == 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[128], copy[128];
    if (!path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(path, sizeof path, "%.64s/weft_fuzz_obj_%ld.obj", dir && *dir ? dir : "/tmp", (long)getpid());
        snprintf(copy, sizeof copy, "%.64s/weft_fuzz_obj_%ld_copy.obj", dir && *dir ? dir : "/tmp", (long)getpid());
    }
    write_file(path, data, size);

    float *pos = (float *)(uintptr_t)1;
    uint32_t *tris = (uint32_t *)(uintptr_t)2, nv = 0xDEADu, nt = 0xBEEFu;
    weft__clear_error();
    weft_result r = weft_obj_read(path, &pos, &nv, &tris, &nt);
    remove(path);
    if (r != WEFT_OK) {
        REQUIRE(r == WEFT_ERROR_FORMAT || r == WEFT_ERROR_NOT_FINITE);
        REQUIRE(weft_last_error()[0] != '\0');
        REQUIRE(pos == (float *)(uintptr_t)1 && tris == (uint32_t *)(uintptr_t)2 && nv == 0xDEADu && nt == 0xBEEFu);
        return 0;
    }
    REQUIRE(nv > 0 && nt > 0 && pos && tris);
    REQUIRE(weft__first_outside(pos, (size_t)nv * 3) == SIZE_MAX);
    for (size_t i = 0; i < (size_t)nt * 3; ++i) {
        REQUIRE(tris[i] < nv);
    }
    if (nv <= ROUND_TRIP_MAX_VERTICES && nt <= 4 * ROUND_TRIP_MAX_VERTICES) {
        REQUIRE(weft_obj_write(copy, pos, nv, tris, nt) == WEFT_OK);
        float *pos2 = NULL;
        uint32_t *tris2 = NULL, nv2 = 0, nt2 = 0;
        REQUIRE(weft_obj_read(copy, &pos2, &nv2, &tris2, &nt2) == WEFT_OK);
        REQUIRE(nv2 == nv && nt2 == nt);
        REQUIRE(memcmp(tris2, tris, (size_t)nt * 3 * sizeof(uint32_t)) == 0);
        for (size_t i = 0; i < (size_t)nv * 3; ++i) {
            REQUIRE(fabsf(pos2[i] - pos[i]) <= 1e-6f * fmaxf(1.0f, fabsf(pos[i])));
        }
        free(pos2);
        free(tris2);
        remove(copy);
    }
    free(pos);
    free(tris);
    return 0;
}
