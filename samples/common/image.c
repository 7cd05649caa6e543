/* RGBA8 image helpers: PNG in/out (stb from Debian's libstb-dev), golden comparison, contact
 * sheets and a tiny text overlay for labels (stb_easy_font's quads, rasterised on the CPU). */
#include "weft_render.h"
#include "core/core.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* stb declares static functions that the PNG-only configuration never defines; the warning
 * fires at the end of the file, so it stays off for this whole translation unit. */
#pragma GCC diagnostic ignored "-Wunused-function"
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb/stb_image_write.h>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_PNG
#include <stb/stb_image.h>

#include <stb/stb_easy_font.h>

#define IMAGE_MAX_SIDE 16384u

weft_result weft_render_write_png(const char *path, const uint8_t *rgba, uint32_t width, uint32_t height)
{
    if (!path || !rgba) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_write_png: path and pixels are required");
    }
    if (width == 0 || height == 0 || width > IMAGE_MAX_SIDE || height > IMAGE_MAX_SIDE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_write_png: size %ux%u out of range", width, height);
    }
    /* Open first so a bad path reports errno rather than stb's silent 0. */
    FILE *probe = fopen(path, "wb");
    if (!probe) {
        return weft__fail(WEFT_ERROR_IO, "weft_render_write_png: cannot open '%s': %s", path, strerror(errno));
    }
    fclose(probe);
    if (!stbi_write_png(path, (int)width, (int)height, 4, rgba, (int)(width * 4))) {
        remove(path);
        return weft__fail(WEFT_ERROR_IO, "weft_render_write_png: writing '%s' failed", path);
    }
    return WEFT_OK;
}

weft_result weft_render_read_png(const char *path, uint8_t **out_rgba, uint32_t *out_width, uint32_t *out_height)
{
    if (!path || !out_rgba || !out_width || !out_height) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_read_png: arguments are required");
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "weft_render_read_png: cannot open '%s': %s", path, strerror(errno));
    }
    int w = 0, h = 0, comp = 0;
    uint8_t *data = stbi_load_from_file(f, &w, &h, &comp, 4);
    fclose(f);
    if (!data) {
        return weft__fail(WEFT_ERROR_FORMAT, "weft_render_read_png: '%s' is not a readable PNG (%s)", path,
                          stbi_failure_reason());
    }
    if (w <= 0 || h <= 0 || (uint32_t)w > IMAGE_MAX_SIDE || (uint32_t)h > IMAGE_MAX_SIDE) {
        stbi_image_free(data);
        return weft__fail(WEFT_ERROR_FORMAT, "weft_render_read_png: '%s' has size %dx%d", path, w, h);
    }
    *out_rgba = data;
    *out_width = (uint32_t)w;
    *out_height = (uint32_t)h;
    return WEFT_OK;
}

void weft_render_free_image(uint8_t *rgba) { stbi_image_free(rgba); }

weft_result weft_render_compare(const uint8_t *reference, const uint8_t *actual, uint32_t width, uint32_t height,
                                uint32_t channel_tolerance, weft_image_diff *out_diff, uint8_t *diff_rgba)
{
    if (!reference || !actual || !out_diff) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_compare: images and out_diff are required");
    }
    if (width == 0 || height == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_compare: empty image");
    }
    weft_image_diff d = {0};
    size_t n = (size_t)width * height;
    for (size_t i = 0; i < n; ++i) {
        const uint8_t *a = reference + 4 * i, *b = actual + 4 * i;
        uint32_t worst = 0;
        for (int k = 0; k < 3; ++k) {
            uint32_t diff = (uint32_t)abs((int)a[k] - (int)b[k]);
            worst = diff > worst ? diff : worst;
        }
        d.max_channel_diff = worst > d.max_channel_diff ? worst : d.max_channel_diff;
        bool over = worst > channel_tolerance;
        d.pixels_over += over;
        if (diff_rgba) {
            uint8_t *o = diff_rgba + 4 * i;
            if (over) {
                o[0] = 255;
                o[1] = 0;
                o[2] = 0;
            } else {
                uint8_t grey = (uint8_t)(((unsigned)a[0] + a[1] + a[2]) / 6 + 96); /* dimmed context */
                o[0] = o[1] = o[2] = grey;
            }
            o[3] = 255;
        }
    }
    d.fraction_over = (double)d.pixels_over / (double)n;
    *out_diff = d;
    return WEFT_OK;
}

static void fill_rect(uint8_t *rgba, uint32_t width, uint32_t height, int x0, int y0, int x1, int y1, const uint8_t c[4])
{
    x0 = x0 < 0 ? 0 : x0;
    y0 = y0 < 0 ? 0 : y0;
    x1 = x1 > (int)width ? (int)width : x1;
    y1 = y1 > (int)height ? (int)height : y1;
    for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
            uint8_t *p = rgba + ((size_t)y * width + (size_t)x) * 4;
            unsigned a = c[3];
            for (int k = 0; k < 3; ++k) {
                p[k] = (uint8_t)((c[k] * a + p[k] * (255u - a) + 127u) / 255u);
            }
            p[3] = 255;
        }
    }
}

void weft_render_draw_text(uint8_t *rgba, uint32_t width, uint32_t height, int x, int y, int scale, const char *text)
{
    if (!rgba || !text || scale < 1 || scale > 16) {
        return;
    }
    char buf[96];
    size_t len = strlen(text);
    len = len < sizeof buf - 1 ? len : sizeof buf - 1;
    memcpy(buf, text, len);
    buf[len] = '\0';
    /* stb_easy_font emits at most ~270 bytes of quads per character */
    float quads[96 * 72];
    int nq = stb_easy_font_print(0.0f, 0.0f, buf, NULL, quads, (int)sizeof quads);
    int tw = stb_easy_font_width(buf), th = stb_easy_font_height(buf);
    const uint8_t backing[4] = {20, 22, 28, 150};
    const uint8_t ink[4] = {255, 255, 255, 255};
    fill_rect(rgba, width, height, x - 2 * scale, y - 2 * scale, x + (tw + 1) * scale, y + (th - 1) * scale, backing);
    for (int q = 0; q < nq; ++q) {
        const float *v = quads + (size_t)q * 16; /* 4 vertices of x, y, z, colour */
        int qx0 = (int)v[0], qy0 = (int)v[1], qx1 = (int)v[8], qy1 = (int)v[9];
        fill_rect(rgba, width, height, x + qx0 * scale, y + qy0 * scale, x + qx1 * scale, y + qy1 * scale, ink);
    }
}

weft_result weft_render_contact_sheet(const uint8_t *const *images, const char *const *labels, uint32_t count,
                                      uint32_t tile_width, uint32_t tile_height, uint32_t columns,
                                      uint8_t **out_rgba, uint32_t *out_width, uint32_t *out_height)
{
    const uint32_t gutter = 2;
    if (!images || !out_rgba || !out_width || !out_height || count == 0 || columns == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_contact_sheet: images, outputs, count and columns are required");
    }
    if (tile_width == 0 || tile_height == 0 || tile_width > IMAGE_MAX_SIDE || tile_height > IMAGE_MAX_SIDE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_contact_sheet: tile size %ux%u out of range",
                          tile_width, tile_height);
    }
    for (uint32_t i = 0; i < count; ++i) {
        if (!images[i]) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_contact_sheet: image %u is NULL", i);
        }
    }
    uint32_t cols = columns < count ? columns : count;
    uint32_t rows = (count + cols - 1) / cols;
    uint64_t w = (uint64_t)cols * tile_width + (uint64_t)(cols + 1) * gutter;
    uint64_t h = (uint64_t)rows * tile_height + (uint64_t)(rows + 1) * gutter;
    if (w > IMAGE_MAX_SIDE || h > IMAGE_MAX_SIDE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_contact_sheet: sheet %llux%llu too large",
                          (unsigned long long)w, (unsigned long long)h);
    }
    uint8_t *sheet = malloc((size_t)(w * h * 4));
    if (!sheet) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_render_contact_sheet: out of memory");
    }
    for (size_t i = 0; i < (size_t)(w * h); ++i) {
        sheet[4 * i + 0] = 40;
        sheet[4 * i + 1] = 42;
        sheet[4 * i + 2] = 48;
        sheet[4 * i + 3] = 255;
    }
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t ox = gutter + (i % cols) * (tile_width + gutter);
        uint32_t oy = gutter + (i / cols) * (tile_height + gutter);
        for (uint32_t y = 0; y < tile_height; ++y) {
            memcpy(sheet + ((size_t)(oy + y) * w + ox) * 4, images[i] + (size_t)y * tile_width * 4, (size_t)tile_width * 4);
        }
        if (labels && labels[i] && labels[i][0]) {
            int scale = tile_width >= 384 ? 2 : 1;
            weft_render_draw_text(sheet, (uint32_t)w, (uint32_t)h, (int)ox + 4 * scale, (int)oy + 4 * scale, scale, labels[i]);
        }
    }
    *out_rgba = sheet;
    *out_width = (uint32_t)w;
    *out_height = (uint32_t)h;
    return WEFT_OK;
}
