/* OBJ + PC2 point caches (samples/common/pc2.c): a cache written sample by sample reads back
 * bit for bit with its counts and start frame; a truncated file, a wrong signature and a count
 * that disagrees with the size are refused by name; NaN is refused at write time. */
#include "test.h"
#include "pc2.h"

#include <stdint.h>

static void test_round_trip(void)
{
    const char *path = WEFT_BINARY_DIR "/tests/pc2_round_trip.pc2";
    enum { P = 5, S = 3 };
    float src[S][P][3];
    for (int s = 0; s < S; ++s) {
        for (int p = 0; p < P; ++p) {
            for (int k = 0; k < 3; ++k) {
                src[s][p][k] = (float)(s * 100 + p * 10 + k) * 0.01f - 0.7f;
            }
        }
    }
    weft_pc2_writer w = {0};
    CHECK_RESULT(weft_pc2_open(&w, path, P, 12.0f), WEFT_OK);
    for (int s = 0; s < S; ++s) {
        CHECK_RESULT(weft_pc2_write(&w, &src[s][0][0]), WEFT_OK);
    }
    float bad[P * 3] = {0};
    bad[4] = NAN;
    CHECK_RESULT(weft_pc2_write(&w, bad), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_pc2_close(&w), WEFT_OK);
    float *got = NULL, start = 0.0f;
    uint32_t points = 0, samples = 0;
    CHECK_RESULT(weft_pc2_read(path, &got, &points, &samples, &start), WEFT_OK);
    CHECK_EQ_INT(points, P);
    CHECK_EQ_INT(samples, S);
    CHECK_NEAR(start, 12.0, 0.0);
    CHECK(got && memcmp(got, src, sizeof src) == 0);
    free(got);
    /* the header as DCC tools expect it */
    FILE *f = fopen(path, "rb");
    unsigned char h[32] = {0};
    CHECK(f && fread(h, 1, 32, f) == 32);
    if (f) {
        fclose(f);
    }
    CHECK(memcmp(h, "POINTCACHE2\0", 12) == 0);
    CHECK_EQ_INT(h[12], 1);
    CHECK_EQ_INT(h[16], P);
    CHECK_EQ_INT(h[28], S);
}

static void write_bytes(const char *path, const void *b, size_t n)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (f) {
        fwrite(b, 1, n, f);
        fclose(f);
    }
}

static void test_bad_files(void)
{
    const char *path = WEFT_BINARY_DIR "/tests/pc2_bad.pc2";
    float *pos = NULL, start;
    uint32_t points, samples;
    write_bytes(path, "POINTCACHE2", 11);
    CHECK_RESULT(weft_pc2_read(path, &pos, &points, &samples, &start), WEFT_ERROR_FORMAT);
    unsigned char h[32 + 12] = "POINTCACHE2";
    h[12] = 1;
    h[16] = 1;  /* one point */
    h[28] = 2;  /* two samples claimed, one stored */
    write_bytes(path, h, sizeof h);
    CHECK_RESULT(weft_pc2_read(path, &pos, &points, &samples, &start), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "1 points x 2 samples") != NULL);
    h[28] = 1;
    h[0] = 'X';
    write_bytes(path, h, sizeof h);
    CHECK_RESULT(weft_pc2_read(path, &pos, &points, &samples, &start), WEFT_ERROR_FORMAT);
    CHECK(pos == NULL);
    CHECK_RESULT(weft_pc2_read(WEFT_BINARY_DIR "/tests/no_such.pc2", &pos, &points, &samples, &start), WEFT_ERROR_IO);
}

TEST_MAIN(TEST_CASE(test_round_trip), TEST_CASE(test_bad_files))
