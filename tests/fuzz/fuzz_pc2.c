/* Fuzz target for the PC2 point-cache reader (samples/common/pc2.c): arbitrary bytes -> a file ->
 * weft_pc2_read (the reader takes a path only, so each input goes to a per-process file).
 *
 * The file is always readable, so a rejection must be WEFT_ERROR_FORMAT with a message, and the
 * outputs must be left untouched. An accepted file must have a positive point count, a finite
 * start frame and exactly 32 + points x samples x 12 bytes, all positions finite and equal to
 * the file's floats. Small accepted caches are also written back with weft_pc2_open / _write /
 * _close and read again, which must give the same header and bit-identical positions. Any
 * violated property aborts, which the fuzzer reports.
 *
 * Built two ways (tests/fuzz/CMakeLists.txt): with libFuzzer (WEFT_BUILD_FUZZ=ON, clang), and as
 * the ctest fuzz.pc2_replay together with replay_main.c. */
#define _POSIX_C_SOURCE 200809L /* getpid */

#include "pc2.h"
#include "core/core.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(cond)                                                                              \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "fuzz_pc2: property failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__); \
            abort();                                                                               \
        }                                                                                          \
    } while (0)

#define ROUND_TRIP_MAX_FLOATS 4096u

static uint32_t le32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }

static void write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    REQUIRE(f != NULL);
    REQUIRE(fwrite(data, 1, size, f) == size);
    REQUIRE(fclose(f) == 0);
}

/* Writes the cache with weft's writer and reads it back. */
static void round_trip(const char *path, const float *pos, uint32_t points, uint32_t samples, float start)
{
    weft_pc2_writer w;
    REQUIRE(weft_pc2_open(&w, path, points, start) == WEFT_OK);
    for (uint32_t s = 0; s < samples; ++s) {
        REQUIRE(weft_pc2_write(&w, pos + (size_t)s * points * 3) == WEFT_OK);
    }
    REQUIRE(weft_pc2_close(&w) == WEFT_OK);
    float *again = NULL, start2 = 0.0f;
    uint32_t points2 = 0, samples2 = 0;
    REQUIRE(weft_pc2_read(path, &again, &points2, &samples2, &start2) == WEFT_OK);
    REQUIRE(points2 == points && samples2 == samples && memcmp(&start2, &start, sizeof start) == 0);
    REQUIRE(memcmp(again, pos, (size_t)points * samples * 3 * sizeof(float)) == 0);
    free(again);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[128], copy[128];
    if (!path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(path, sizeof path, "%.64s/weft_fuzz_pc2_%ld.pc2", dir && *dir ? dir : "/tmp", (long)getpid());
        snprintf(copy, sizeof copy, "%.64s/weft_fuzz_pc2_%ld_copy.pc2", dir && *dir ? dir : "/tmp", (long)getpid());
    }
    write_file(path, data, size);

    float *pos = (float *)(uintptr_t)1, start = -7.0f;
    uint32_t points = 0xDEADu, samples = 0xBEEFu;
    weft__clear_error();
    weft_result r = weft_pc2_read(path, &pos, &points, &samples, &start);
    remove(path);
    if (r != WEFT_OK) {
        REQUIRE(r == WEFT_ERROR_FORMAT);
        REQUIRE(weft_last_error()[0] != '\0');
        REQUIRE(pos == (float *)(uintptr_t)1 && points == 0xDEADu && samples == 0xBEEFu && start == -7.0f);
        return 0;
    }
    REQUIRE(size >= 32 && memcmp(data, "POINTCACHE2", 12) == 0 && le32(data + 12) == 1);
    REQUIRE(points > 0 && points == le32(data + 16) && samples == le32(data + 28));
    REQUIRE(weft__all_finite(&start, 1) && memcmp(&start, data + 20, 4) == 0);
    /* the size check by division, so that no product can wrap */
    const size_t records = (size - 32) / 12;
    REQUIRE((size - 32) % 12 == 0);
    REQUIRE(samples == 0 ? records == 0 : records % samples == 0 && records / samples == points);
    const size_t n = records * 3;
    REQUIRE(weft__all_finite(pos, n));
    REQUIRE(memcmp(pos, data + 32, n * sizeof(float)) == 0); /* little-endian host */
    if (n <= ROUND_TRIP_MAX_FLOATS) {
        round_trip(copy, pos, points, samples, start);
        remove(copy);
    }
    free(pos);
    return 0;
}
