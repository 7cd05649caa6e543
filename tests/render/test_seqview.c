/* Sequence contact sheets (samples/common/seqview.c): the committed sample sequence renders
 * to a sheet of the expected size with cloth in every tile, byte-identically twice, and
 * broken folders (missing, truncated or inconsistent arrays, bad metadata) fail with a clear
 * result and write nothing. */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "weft_sample.h"

#include <math.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#define SAMPLE_DIR WEFT_SOURCE_DIR "/tests/data/sample_seq"
#define TMP_ROOT WEFT_BINARY_DIR "/test_seqview_tmp"
#define TILE 96u

static const char *const k_files[] = {"meta.json", "cloth_pos.npy", "faces.npy", "collider_pos.npy",
                                      "collider_faces.npy", "rest_pos.npy", "pinned.npy", "stats.npy"};

static uint8_t *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    if (b) {
        b[n] = 0; /* meta.json is edited as a string */
    }
    *size = b ? (size_t)n : 0;
    return b;
}

static bool write_all(const char *path, const void *bytes, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        return false;
    }
    bool ok = fwrite(bytes, 1, size, f) == size;
    return fclose(f) == 0 && ok;
}

static bool exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* A fresh copy of the sample sequence in TMP_ROOT/name, without the files in skip (" a b "). */
static void copy_sample(const char *name, const char *skip, char *out_dir, size_t cap)
{
    mkdir(TMP_ROOT, 0755);
    snprintf(out_dir, cap, "%s/%s", TMP_ROOT, name);
    mkdir(out_dir, 0755);
    for (size_t i = 0; i < sizeof k_files / sizeof k_files[0]; ++i) {
        char src[1024], dst[1024];
        snprintf(dst, sizeof dst, "%s/%s", out_dir, k_files[i]);
        remove(dst);
        char token[64];
        snprintf(token, sizeof token, " %s ", k_files[i]);
        if (skip && strstr(skip, token)) {
            continue;
        }
        snprintf(src, sizeof src, "%s/%s", SAMPLE_DIR, k_files[i]);
        size_t n = 0;
        uint8_t *b = read_all(src, &n);
        CHECK_MSG(b && write_all(dst, b, n), "copying %s", src);
        free(b);
    }
}

/* Writes a little-endian .npy with a v1.0 header. */
static bool write_npy(const char *path, const char *descr, const char *shape, const void *data, size_t bytes)
{
    char header[256];
    int n = snprintf(header, sizeof header, "{'descr': '%s', 'fortran_order': False, 'shape': %s, }", descr, shape);
    size_t total = 10 + (size_t)n + 1;
    size_t pad = (64 - total % 64) % 64;
    uint8_t *buf = malloc(total + pad + bytes);
    if (!buf) {
        return false;
    }
    memcpy(buf, "\x93NUMPY\x01\x00", 8);
    uint16_t hl = (uint16_t)(n + 1 + pad);
    buf[8] = (uint8_t)(hl & 0xff);
    buf[9] = (uint8_t)(hl >> 8);
    memcpy(buf + 10, header, (size_t)n);
    memset(buf + 10 + n, ' ', pad);
    buf[10 + n + pad] = '\n';
    if (bytes) {
        memcpy(buf + total + pad, data, bytes);
    }
    bool ok = write_all(path, buf, total + pad + bytes);
    free(buf);
    return ok;
}

/* Pixels where blue or orange clearly dominates: the two sides of the cloth. The collider,
 * ground, background and gutters are all near-grey. */
static uint32_t cloth_pixels(const uint8_t *rgba, uint32_t width, uint32_t x0, uint32_t y0, uint32_t w, uint32_t h)
{
    uint32_t n = 0;
    for (uint32_t y = y0; y < y0 + h; ++y) {
        for (uint32_t x = x0; x < x0 + w; ++x) {
            const uint8_t *p = rgba + ((size_t)y * width + x) * 4;
            int r = p[0], g = p[1], b = p[2];
            n += (b > r + 50 && b > g + 20) || (r > b + 60 && r > g + 20);
        }
    }
    return n;
}

static void test_sample_sheet(void)
{
    char out[1024], out2[1024];
    mkdir(TMP_ROOT, 0755);
    snprintf(out, sizeof out, "%s/sample_sheet.png", TMP_ROOT);
    snprintf(out2, sizeof out2, "%s/sample_sheet_again.png", TMP_ROOT);
    remove(out);
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = SAMPLE_DIR;
    o.out_path = out;
    o.tile = TILE;
    weft_seq_sheet_info info;
    memset(&info, 0, sizeof info);
    CHECK_RESULT(weft_seq_sheet_render(&o, &info), WEFT_OK);
    /* the committed sample: 60 frames, 941 cloth vertices, a blob on the 6 m floor quad */
    CHECK_EQ_INT(info.sequence_frames, 60);
    CHECK_EQ_INT(info.cloth_vertices, 941);
    CHECK_EQ_INT(info.cloth_triangles, 1762);
    CHECK_EQ_INT(info.collider_vertices, 614);
    CHECK_EQ_INT(info.ground_triangles, 2);
    CHECK_EQ_INT(info.accepted, 1);
    CHECK_EQ_INT(info.validated, 1);
    CHECK_EQ_INT(info.validator_hits, 0);
    CHECK(strcmp(info.scenario, "drop") == 0);
    CHECK(strstr(info.description, "blob") != NULL);
    static const uint32_t expect[5] = {0, 15, 30, 45, 59};
    CHECK_EQ_INT(info.frame_count, 5);
    for (uint32_t i = 0; i < 5 && i < info.frame_count; ++i) {
        CHECK_EQ_INT(info.frames[i], expect[i]);
    }
    uint8_t *img = NULL;
    uint32_t w = 0, h = 0;
    CHECK_RESULT(weft_render_read_png(out, &img, &w, &h), WEFT_OK);
    /* five tiles in one row with 2-pixel gutters, under the caption strip */
    CHECK_EQ_INT(w, 5 * TILE + 6 * 2);
    CHECK_EQ_INT(w, info.width);
    CHECK_EQ_INT(h, info.height);
    CHECK(h > TILE + 4);
    if (img && w == 5 * TILE + 12 && h > TILE + 4) {
        uint32_t top = h - TILE - 2;
        for (uint32_t t = 0; t < 5; ++t) {
            uint32_t n = cloth_pixels(img, w, 2 + t * (TILE + 2), top, TILE, TILE);
            CHECK_MSG(n > TILE * TILE / 50, "tile %u has %u cloth pixels", t, n);
        }
    }
    /* same folder and options, same bytes */
    o.out_path = out2;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_OK);
    uint8_t *img2 = NULL;
    uint32_t w2 = 0, h2 = 0;
    CHECK_RESULT(weft_render_read_png(out2, &img2, &w2, &h2), WEFT_OK);
    CHECK(img && img2 && w2 == w && h2 == h && memcmp(img, img2, (size_t)w * h * 4) == 0);
    weft_render_free_image(img);
    weft_render_free_image(img2);
}

static void test_frames_and_layout(void)
{
    char out[1024];
    mkdir(TMP_ROOT, 0755);
    snprintf(out, sizeof out, "%s/two_frames.png", TMP_ROOT);
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = SAMPLE_DIR;
    o.out_path = out;
    o.tile = 64;
    o.tile_height = 80;
    o.columns = 1;
    o.caption = false;
    o.yaw = -40.0f;
    o.pitch = 60.0f;
    CHECK_RESULT(weft_seq_sheet_parse_frames("59,0", &o), WEFT_OK);
    weft_seq_sheet_info info;
    memset(&info, 0, sizeof info);
    CHECK_RESULT(weft_seq_sheet_render(&o, &info), WEFT_OK);
    CHECK_EQ_INT(info.frame_count, 2);
    CHECK_EQ_INT(info.frames[0], 59);
    CHECK_EQ_INT(info.frames[1], 0);
    CHECK_EQ_INT(info.tile_width, 64);
    CHECK_EQ_INT(info.tile_height, 80);
    CHECK_EQ_INT(info.width, 64 + 4);
    CHECK_EQ_INT(info.height, 2 * 80 + 6);
    uint8_t *img = NULL;
    uint32_t w = 0, h = 0;
    CHECK_RESULT(weft_render_read_png(out, &img, &w, &h), WEFT_OK);
    CHECK(w == 68 && h == 166);
    if (img && w == 68 && h == 166) {
        CHECK(cloth_pixels(img, w, 2, 2, 64, 80) > 0);
        CHECK(cloth_pixels(img, w, 2, 84, 64, 80) > 0);
    }
    weft_render_free_image(img);
}

static void test_cloth_only(void)
{
    char dir[1024], out[1100];
    copy_sample("no_collider", " collider_pos.npy collider_faces.npy ", dir, sizeof dir);
    snprintf(out, sizeof out, "%s/sheet.png", dir);
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = dir;
    o.out_path = out;
    o.tile = 64;
    weft_seq_sheet_info info;
    memset(&info, 0, sizeof info);
    CHECK_RESULT(weft_seq_sheet_render(&o, &info), WEFT_OK);
    CHECK_EQ_INT(info.collider_vertices, 0);
    CHECK_EQ_INT(info.ground_triangles, 0);
    CHECK(exists(out));
}

/* A sequence written with --no-validate says so (meta.json validator.run false). */
static void test_unvalidated(void)
{
    char dir[1024], path[1100], out[1100];
    copy_sample("unvalidated", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    size_t n = 0;
    uint8_t *b = read_all(path, &n);
    char *run = b ? strstr((char *)b, "\"run\":") : NULL;
    char *value = run ? strstr(run, "true") : NULL;
    CHECK(value != NULL);
    if (value) {
        FILE *f = fopen(path, "wb");
        CHECK(f != NULL);
        if (f) {
            fwrite(b, 1, (size_t)(value - (char *)b), f);
            fputs("false", f);
            fputs(value + 4, f);
            fclose(f);
        }
    }
    free(b);
    snprintf(out, sizeof out, "%s/sheet.png", dir);
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = dir;
    o.out_path = out;
    o.tile = 64;
    CHECK_RESULT(weft_seq_sheet_parse_frames("0", &o), WEFT_OK);
    weft_seq_sheet_info info;
    memset(&info, 0, sizeof info);
    CHECK_RESULT(weft_seq_sheet_render(&o, &info), WEFT_OK);
    CHECK_EQ_INT(info.accepted, 1);
    CHECK_EQ_INT(info.validated, 0);
}

static void test_parse_frames(void)
{
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    CHECK_RESULT(weft_seq_sheet_parse_frames("0,60,120,180,239", &o), WEFT_OK);
    CHECK_EQ_INT(o.frame_count, 5);
    CHECK_EQ_INT(o.frames[3], 180);
    static const char *const bad[] = {"", ",", "1,,2", "1,2,", "a", "-1", "1 2", "1;2", "4294967296", "3000000000"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        CHECK_RESULT(weft_seq_sheet_parse_frames(bad[i], &o), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK_EQ_INT(o.frame_count, 5); /* unchanged */
    }
    char many[256] = "0";
    for (int i = 1; i <= (int)WEFT_SEQ_SHEET_MAX_FRAMES; ++i) {
        size_t len = strlen(many);
        snprintf(many + len, sizeof many - len, ",%d", i);
    }
    CHECK_RESULT(weft_seq_sheet_parse_frames(many, &o), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_seq_sheet_parse_frames(NULL, &o), WEFT_ERROR_INVALID_ARGUMENT);
}

/* Renders dir into dir/sheet.png expecting `expected`, and checks nothing was written. */
static void expect_failure(const char *dir, weft_result expected, const char *what)
{
    char out[1024];
    int len = snprintf(out, sizeof out, "%s/sheet.png", exists(dir) ? dir : TMP_ROOT);
    CHECK(len > 0 && (size_t)len < sizeof out);
    remove(out);
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = dir;
    o.out_path = out;
    o.tile = 64;
    weft_result r = weft_seq_sheet_render(&o, NULL);
    CHECK_MSG(r == expected, "%s: got %s (%s), expected %s", what, weft_result_string(r), weft_last_error(),
              weft_result_string(expected));
    CHECK_MSG(strlen(weft_last_error()) > 10, "%s: no message", what);
    CHECK_MSG(!exists(out), "%s: a sheet was written", what);
}

static void test_bad_input(void)
{
    char dir[1024], path[1200];
    mkdir(TMP_ROOT, 0755);
    expect_failure(TMP_ROOT "/does_not_exist", WEFT_ERROR_IO, "missing folder");
    expect_failure(SAMPLE_DIR "/meta.json", WEFT_ERROR_IO, "a file, not a folder");

    copy_sample("no_meta", " meta.json ", dir, sizeof dir);
    expect_failure(dir, WEFT_ERROR_IO, "missing meta.json");

    copy_sample("bad_meta", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    CHECK(write_all(path, "[1, 2", 5));
    expect_failure(dir, WEFT_ERROR_FORMAT, "meta.json not an object");

    copy_sample("no_cloth", " cloth_pos.npy ", dir, sizeof dir);
    expect_failure(dir, WEFT_ERROR_IO, "missing cloth_pos.npy");

    /* truncated cloth positions: the header promises more data than the file holds */
    copy_sample("truncated", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/cloth_pos.npy", dir);
    size_t n = 0;
    uint8_t *b = read_all(path, &n);
    CHECK(b && n > 1000 && write_all(path, b, n / 2));
    expect_failure(dir, WEFT_ERROR_FORMAT, "truncated cloth_pos.npy");
    CHECK(b && write_all(path, b, 40));
    expect_failure(dir, WEFT_ERROR_FORMAT, "cloth_pos.npy cut inside the header");
    CHECK(write_all(path, "", 0));
    expect_failure(dir, WEFT_ERROR_FORMAT, "empty cloth_pos.npy");

    /* NaN in a drawn frame */
    if (b && n > 1000) {
        copy_sample("nan", NULL, dir, sizeof dir);
        snprintf(path, sizeof path, "%s/cloth_pos.npy", dir);
        size_t data = 10u + (size_t)(b[8] | (b[9] << 8));
        float nan = NAN;
        memcpy(b + data + 4 * 7, &nan, sizeof nan);
        CHECK(write_all(path, b, n));
        expect_failure(dir, WEFT_ERROR_NOT_FINITE, "NaN in frame 0");
    }
    free(b);

    /* wrong rank, wrong last dimension, strings */
    copy_sample("shapes", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/cloth_pos.npy", dir);
    float zeros[24] = {0};
    CHECK(write_npy(path, "<f4", "(8, 3)", zeros, sizeof zeros));
    expect_failure(dir, WEFT_ERROR_SIZE_MISMATCH, "cloth_pos of rank 2");
    CHECK(write_npy(path, "<f4", "(2, 3, 4)", zeros, sizeof zeros));
    expect_failure(dir, WEFT_ERROR_SIZE_MISMATCH, "cloth_pos last dimension 4");
    CHECK(write_npy(path, "<U4", "(2, 1, 3)", zeros, sizeof zeros));
    expect_failure(dir, WEFT_ERROR_FORMAT, "cloth_pos of strings");

    /* a face index past the cloth's vertex count */
    copy_sample("bad_faces", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/faces.npy", dir);
    const int32_t faces[6] = {0, 1, 2, 0, 2, 941};
    CHECK(write_npy(path, "<i4", "(2, 3)", faces, sizeof faces));
    expect_failure(dir, WEFT_ERROR_DEGENERATE_MESH, "face index out of range");

    /* collider recorded for a different number of frames, and half a collider */
    copy_sample("collider_frames", NULL, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/collider_pos.npy", dir);
    float *c = calloc(59 * 614 * 3, sizeof *c);
    CHECK(c && write_npy(path, "<f4", "(59, 614, 3)", c, 59 * 614 * 3 * sizeof *c));
    free(c);
    expect_failure(dir, WEFT_ERROR_SIZE_MISMATCH, "collider with 59 frames");
    copy_sample("half_collider", " collider_faces.npy ", dir, sizeof dir);
    expect_failure(dir, WEFT_ERROR_FORMAT, "collider_pos.npy without collider_faces.npy");

    /* bad options */
    weft_seq_sheet_options o;
    weft_seq_sheet_default_options(&o);
    o.seq_dir = SAMPLE_DIR;
    o.out_path = TMP_ROOT "/never.png";
    remove(o.out_path);
    CHECK_RESULT(weft_seq_sheet_parse_frames("0,60", &o), WEFT_OK);
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_INVALID_ARGUMENT); /* the sample has 60 frames */
    o.frame_count = 0;
    o.tile = 16;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    o.tile = 64;
    o.tile_height = 2000;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    o.tile_height = 0;
    o.pitch = 90.0f;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    o.pitch = NAN;
    o.yaw = INFINITY;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(!exists(o.out_path));
    CHECK_RESULT(weft_seq_sheet_render(NULL, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    /* an unwritable output path is an IO error */
    weft_seq_sheet_default_options(&o);
    o.seq_dir = SAMPLE_DIR;
    o.out_path = TMP_ROOT "/no/such/folder/sheet.png";
    o.tile = 64;
    CHECK_RESULT(weft_seq_sheet_render(&o, NULL), WEFT_ERROR_IO);
}

TEST_MAIN(TEST_CASE(test_parse_frames), TEST_CASE(test_sample_sheet), TEST_CASE(test_frames_and_layout),
          TEST_CASE(test_cloth_only), TEST_CASE(test_unvalidated), TEST_CASE(test_bad_input))
