/* The OSMesa renderer: argument checking, two-sided cloth shading, camera framing, images,
 * contact sheets and the no-allocation update path. */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "weft_scenes.h"

#include <stdint.h>

#define SIZE 96

static weft_renderer *make_renderer(uint32_t w, uint32_t h, bool ground)
{
    weft_render_def def = weft_default_render_def();
    def.width = w;
    def.height = h;
    def.ground = ground;
    weft_renderer *r = NULL;
    CHECK_RESULT(weft_renderer_create(&def, &r), WEFT_OK);
    return r;
}

static bool is_background(const uint8_t *p)
{
    weft_render_def def = weft_default_render_def();
    for (int k = 0; k < 3; ++k) {
        if (abs((int)p[k] - (int)lroundf(def.background[k] * 255.0f)) > 2) {
            return false;
        }
    }
    return true;
}

static void test_bad_arguments(void)
{
    weft_renderer *r = NULL;
    weft_render_def def = weft_default_render_def();
    CHECK_RESULT(weft_renderer_create(NULL, &r), WEFT_ERROR_INVALID_ARGUMENT);
    weft_render_def raw = def;
    raw.internal_cookie = 0;
    CHECK_RESULT(weft_renderer_create(&raw, &r), WEFT_ERROR_INVALID_ARGUMENT);
    raw = def;
    raw.width = 8;
    CHECK_RESULT(weft_renderer_create(&raw, &r), WEFT_ERROR_INVALID_ARGUMENT);
    raw = def;
    raw.supersample = 9;
    CHECK_RESULT(weft_renderer_create(&raw, &r), WEFT_ERROR_INVALID_ARGUMENT);
    raw = def;
    raw.background[1] = NAN;
    CHECK_RESULT(weft_renderer_create(&raw, &r), WEFT_ERROR_NOT_FINITE);
    CHECK(r == NULL);

    r = make_renderer(SIZE, SIZE, true);
    if (!r) {
        return;
    }
    const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t idx[3] = {0, 1, 2}, bad_idx[3] = {0, 1, 3};
    const float nan_tri[9] = {0, 0, 0, 1, NAN, 0, 0, 1, 0};
    uint32_t id = 99;
    CHECK_RESULT(weft_renderer_render(r), WEFT_ERROR_INVALID_ARGUMENT); /* no camera yet */
    CHECK_RESULT(weft_renderer_add_mesh(r, tri, 3, bad_idx, 1, WEFT_RENDER_CLOTH, &id), WEFT_ERROR_DEGENERATE_MESH);
    CHECK_RESULT(weft_renderer_add_mesh(r, nan_tri, 3, idx, 1, WEFT_RENDER_CLOTH, &id), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_renderer_add_mesh(r, tri, 0, idx, 1, WEFT_RENDER_CLOTH, &id), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_renderer_add_mesh(r, tri, 3, idx, 1, (weft_render_material)17, &id), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_EQ_INT(id, 99);
    CHECK_EQ_INT(weft_renderer_mesh_count(r), 0);
    float lo[3], hi[3];
    CHECK_RESULT(weft_renderer_scene_bounds(r, lo, hi), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_renderer_add_mesh(r, tri, 3, idx, 1, WEFT_RENDER_CLOTH, &id), WEFT_OK);
    CHECK_EQ_INT(id, 0);
    CHECK_RESULT(weft_renderer_update_mesh(r, 1, tri), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_renderer_update_mesh(r, 0, nan_tri), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_renderer_scene_bounds(r, lo, hi), WEFT_OK);
    CHECK_NEAR(hi[1], 1.0, 0.0); /* the NaN update left the mesh as it was */
    const float bad_color[3] = {2.0f, 0.0f, 0.0f};
    CHECK_RESULT(weft_renderer_set_mesh_colors(r, 0, bad_color, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    const float box_lo[3] = {0, 0, 0}, box_hi[3] = {1, 1, 1}, box_nan[3] = {0, NAN, 0};
    CHECK_RESULT(weft_renderer_frame_box(r, box_hi, box_lo, 0, 0), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_renderer_frame_box(r, box_lo, box_nan, 0, 0), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_renderer_frame_box(r, box_lo, box_hi, 0, 89.0f), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_renderer_set_mesh_visible(r, 0, false), WEFT_OK);
    CHECK_RESULT(weft_renderer_frame_scene(r, 0, 0), WEFT_ERROR_INVALID_ARGUMENT); /* nothing visible */
    weft_renderer_destroy(r);
}

/* A flat sheet seen from above shows its front (blue) colour, from below its back (orange). */
static void test_two_sided_cloth(void)
{
    weft_renderer *r = make_renderer(SIZE, SIZE, false);
    if (!r) {
        return;
    }
    const float sheet[12] = {-0.5f, 1, -0.5f, 0.5f, 1, -0.5f, -0.5f, 1, 0.5f, 0.5f, 1, 0.5f};
    const uint32_t tris[6] = {0, 2, 1, 1, 2, 3}; /* counter-clockwise from +Y */
    CHECK_RESULT(weft_renderer_add_mesh(r, sheet, 4, tris, 2, WEFT_RENDER_CLOTH, NULL), WEFT_OK);
    const uint8_t *px = weft_renderer_pixels(r);
    const uint8_t *center = px + ((SIZE / 2) * SIZE + SIZE / 2) * 4;

    CHECK_RESULT(weft_renderer_frame_scene(r, 0.0f, 60.0f), WEFT_OK); /* from above */
    CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
    printf("front (from above): %u %u %u\n", center[0], center[1], center[2]);
    CHECK(center[2] > center[0] + 40); /* blue dominates */

    CHECK_RESULT(weft_renderer_frame_scene(r, 0.0f, -60.0f), WEFT_OK); /* from below */
    CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
    printf("back (from below): %u %u %u\n", center[0], center[1], center[2]);
    CHECK(center[0] > center[2] + 40); /* orange dominates */
    weft_renderer_destroy(r);
}

/* The framed object fills the image: its silhouette reaches close to two opposite edges and
 * stays inside the frame. */
static void test_framing(void)
{
    static const float yaws[3] = {0.0f, 45.0f, 130.0f};
    for (int i = 0; i < 3; ++i) {
        weft_renderer *r = make_renderer(SIZE, SIZE * 3 / 2, false);
        if (!r) {
            return;
        }
        /* an off-centre box: its silhouette is exactly what the framing fits */
        float cube[24];
        for (int v = 0; v < 8; ++v) {
            cube[3 * v + 0] = 3.0f + ((v & 1) ? 0.4f : -0.4f);
            cube[3 * v + 1] = 2.0f + ((v & 2) ? 0.3f : -0.3f);
            cube[3 * v + 2] = -1.0f + ((v & 4) ? 0.5f : -0.5f);
        }
        static const uint32_t faces[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                           2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
        CHECK_RESULT(weft_renderer_add_mesh(r, cube, 8, faces, 12, WEFT_RENDER_RIGID, NULL), WEFT_OK);
        CHECK_RESULT(weft_renderer_frame_scene(r, yaws[i], 15.0f), WEFT_OK);
        CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
        const uint8_t *px = weft_renderer_pixels(r);
        uint32_t w = SIZE, h = SIZE * 3 / 2;
        uint32_t x0 = w, x1 = 0, y0 = h, y1 = 0;
        for (uint32_t y = 0; y < h; ++y) {
            for (uint32_t x = 0; x < w; ++x) {
                if (!is_background(px + ((size_t)y * w + x) * 4)) {
                    x0 = x < x0 ? x : x0;
                    x1 = x > x1 ? x : x1;
                    y0 = y < y0 ? y : y0;
                    y1 = y > y1 ? y : y1;
                }
            }
        }
        printf("yaw %.0f: silhouette x %u..%u y %u..%u of %ux%u\n", (double)yaws[i], x0, x1, y0, y1, w, h);
        CHECK(x0 >= 1 && x1 <= w - 2 && y0 >= 1 && y1 <= h - 2); /* inside the frame */
        CHECK(x1 - x0 > w * 4 / 5);                               /* the limiting axis is filled */
        CHECK((x0 + x1) / 2 > w / 2 - 3 && (x0 + x1) / 2 < w / 2 + 3);
        weft_renderer_destroy(r);
    }
}

/* Updating positions and rendering again touches no allocator: the same scene re-rendered
 * after a round trip of updates is bit-identical, and the result reflects the update. */
static void test_update_path(void)
{
    weft_renderer *r = make_renderer(SIZE, SIZE, true);
    if (!r) {
        return;
    }
    const float c[3] = {0, 0.5f, 0};
    weft_render_mesh sphere;
    CHECK_RESULT(weft_render_make_sphere(c, 0.3f, 16, 24, &sphere), WEFT_OK);
    uint32_t id;
    CHECK_RESULT(weft_renderer_add_mesh(r, sphere.positions, sphere.vertex_count, sphere.triangles, sphere.triangle_count,
                                        WEFT_RENDER_SKIN, &id),
                 WEFT_OK);
    const float lo[3] = {-1, 0, -1}, hi[3] = {1, 1.2f, 1};
    CHECK_RESULT(weft_renderer_frame_box(r, lo, hi, 10.0f, 10.0f), WEFT_OK);
    CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
    uint8_t *first = malloc(SIZE * SIZE * 4);
    memcpy(first, weft_renderer_pixels(r), SIZE * SIZE * 4);
    float *moved = malloc((size_t)sphere.vertex_count * 3 * sizeof(float));
    for (uint32_t v = 0; v < sphere.vertex_count; ++v) {
        moved[3 * v] = sphere.positions[3 * v] + 0.4f;
        moved[3 * v + 1] = sphere.positions[3 * v + 1];
        moved[3 * v + 2] = sphere.positions[3 * v + 2];
    }
    CHECK_RESULT(weft_renderer_update_mesh(r, id, moved), WEFT_OK);
    CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
    weft_image_diff d;
    CHECK_RESULT(weft_render_compare(first, weft_renderer_pixels(r), SIZE, SIZE, 8, &d, NULL), WEFT_OK);
    CHECK(d.fraction_over > 0.02); /* the ball moved */
    CHECK_RESULT(weft_renderer_update_mesh(r, id, sphere.positions), WEFT_OK);
    CHECK_RESULT(weft_renderer_render(r), WEFT_OK);
    CHECK(memcmp(first, weft_renderer_pixels(r), SIZE * SIZE * 4) == 0);
    free(first);
    free(moved);
    weft_render_mesh_free(&sphere);
    weft_renderer_destroy(r);
}

static void test_png_and_sheet(void)
{
    uint8_t img[40 * 30 * 4];
    for (int i = 0; i < 40 * 30; ++i) {
        img[4 * i + 0] = (uint8_t)(i * 7);
        img[4 * i + 1] = (uint8_t)(i * 3);
        img[4 * i + 2] = (uint8_t)(255 - i);
        img[4 * i + 3] = 255;
    }
    const char *path = WEFT_BINARY_DIR "/tests/render_roundtrip.png";
    CHECK_RESULT(weft_render_write_png(path, img, 40, 30), WEFT_OK);
    uint8_t *back = NULL;
    uint32_t w = 0, h = 0;
    CHECK_RESULT(weft_render_read_png(path, &back, &w, &h), WEFT_OK);
    CHECK_EQ_INT(w, 40);
    CHECK_EQ_INT(h, 30);
    if (back) {
        CHECK(memcmp(back, img, sizeof img) == 0);
        weft_render_free_image(back);
    }
    CHECK_RESULT(weft_render_write_png(WEFT_BINARY_DIR "/no/such/dir/x.png", img, 40, 30), WEFT_ERROR_IO);
    CHECK_RESULT(weft_render_read_png(WEFT_BINARY_DIR "/no/such/file.png", &back, &w, &h), WEFT_ERROR_IO);
    /* a file that is not a PNG */
    FILE *f = fopen(WEFT_BINARY_DIR "/tests/not_a_png.png", "wb");
    if (f) {
        fputs("\x89PNG but not really", f);
        fclose(f);
    }
    CHECK_RESULT(weft_render_read_png(WEFT_BINARY_DIR "/tests/not_a_png.png", &back, &w, &h), WEFT_ERROR_FORMAT);

    const uint8_t *tiles[5] = {img, img, img, img, img};
    const char *labels[5] = {"a", NULL, "frame 2", "", "x"};
    uint8_t *sheet = NULL;
    CHECK_RESULT(weft_render_contact_sheet(tiles, labels, 5, 40, 30, 3, &sheet, &w, &h), WEFT_OK);
    CHECK_EQ_INT(w, 3 * 40 + 4 * 2);
    CHECK_EQ_INT(h, 2 * 30 + 3 * 2);
    if (sheet) {
        /* tile 1 (no label) is copied exactly; tile 0 carries a label in its corner */
        const uint8_t *t1 = sheet + ((size_t)2 * w + 2 + 42) * 4;
        CHECK(memcmp(t1, img, 40 * 4) == 0);
        const uint8_t *t0 = sheet + ((size_t)(2 + 4) * w + 2) * 4;
        CHECK(memcmp(t0, img + 4 * 40 * 4, 20 * 4) != 0);
        /* the unused sixth slot is gutter colour */
        const uint8_t *empty = sheet + ((size_t)(2 + 30 + 2 + 10) * w + 2 + 2 * 42 + 10) * 4;
        CHECK_EQ_INT(empty[0], 40);
        weft_render_free_image(sheet);
    }
    const uint8_t *with_null[2] = {img, NULL};
    CHECK_RESULT(weft_render_contact_sheet(with_null, NULL, 2, 40, 30, 2, &sheet, &w, &h), WEFT_ERROR_INVALID_ARGUMENT);
}

TEST_MAIN(TEST_CASE(test_bad_arguments), TEST_CASE(test_two_sided_cloth), TEST_CASE(test_framing),
          TEST_CASE(test_update_path), TEST_CASE(test_png_and_sheet))
