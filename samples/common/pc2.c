/* OBJ + PC2 point caches (pc2.h). */
#include "pc2.h"
#include "core/core.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char k_signature[12] = "POINTCACHE2";

static void put_u32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8), p[2] = (unsigned char)(v >> 16), p[3] = (unsigned char)(v >> 24);
}

static uint32_t get_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_f32(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(p, v);
}

static float get_f32(const unsigned char *p)
{
    uint32_t v = get_u32(p);
    float f;
    memcpy(&f, &v, 4);
    return f;
}

weft_result weft_pc2_open(weft_pc2_writer *w, const char *path, uint32_t points, float start_frame)
{
    if (!w || !path || points == 0 || !isfinite(start_frame)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_pc2_open: a path, points > 0 and a finite start frame");
    }
    FILE *f = fopen(path, "wb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "PC2: cannot create '%s': %s", path, strerror(errno));
    }
    unsigned char h[32];
    memcpy(h, k_signature, 12);
    put_u32(h + 12, 1);
    put_u32(h + 16, points);
    put_f32(h + 20, start_frame);
    put_f32(h + 24, 1.0f);
    put_u32(h + 28, 0);
    if (fwrite(h, 1, sizeof h, f) != sizeof h) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "PC2: cannot write '%s'", path);
    }
    w->f = f;
    w->points = points;
    w->samples = 0;
    return WEFT_OK;
}

weft_result weft_pc2_write(weft_pc2_writer *w, const float *positions)
{
    if (!w || !w->f || !positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_pc2_write: an open writer and positions are required");
    }
    const size_t n = (size_t)w->points * 3;
    if (!weft__all_finite(positions, n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "PC2: sample %u holds NaN or infinity", w->samples);
    }
    unsigned char buf[4 * 3 * 256];
    for (size_t i = 0; i < n;) {
        size_t k = 0;
        for (; k < sizeof buf / 4 && i < n; ++k, ++i) {
            put_f32(buf + 4 * k, positions[i]);
        }
        if (fwrite(buf, 4, k, w->f) != k) {
            return weft__fail(WEFT_ERROR_IO, "PC2: write failed at sample %u", w->samples);
        }
    }
    w->samples++;
    return WEFT_OK;
}

weft_result weft_pc2_close(weft_pc2_writer *w)
{
    if (!w || !w->f) {
        return WEFT_OK;
    }
    unsigned char c[4];
    put_u32(c, w->samples);
    const bool ok = fseek(w->f, 28, SEEK_SET) == 0 && fwrite(c, 1, 4, w->f) == 4;
    const bool closed = fclose(w->f) == 0;
    w->f = NULL;
    return ok && closed ? WEFT_OK : weft__fail(WEFT_ERROR_IO, "PC2: cannot finish the file");
}

weft_result weft_pc2_read(const char *path, float **out_positions, uint32_t *out_points, uint32_t *out_samples,
                          float *out_start_frame)
{
    FILE *f = path ? fopen(path, "rb") : NULL;
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "PC2: cannot open '%s'", path ? path : "(null)");
    }
    unsigned char h[32];
    long size = -1;
    if (fread(h, 1, sizeof h, f) != sizeof h || fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 32 ||
        fseek(f, 32, SEEK_SET) != 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_FORMAT, "PC2: '%s' is shorter than its 32-byte header", path);
    }
    const uint32_t version = get_u32(h + 12), points = get_u32(h + 16), samples = get_u32(h + 28);
    const float start = get_f32(h + 20);
    /* points x samples fits in 64 bits, points x samples x 12 may not: compare records, not bytes,
     * so that a wrapped product cannot match a small file. */
    const uint64_t records = (uint64_t)points * samples, payload = (uint64_t)size - 32;
    if (memcmp(h, k_signature, 12) != 0 || version != 1 || points == 0 || !isfinite(start) || payload % 12 != 0 ||
        payload / 12 != records) {
        fclose(f);
        return weft__fail(WEFT_ERROR_FORMAT,
                          "PC2: '%s': signature, version %u, %u points x %u samples disagree with its %ld bytes", path,
                          version, points, samples, size);
    }
    const size_t n = (size_t)points * samples * 3;
    float *pos = malloc(n ? n * sizeof(float) : 1);
    unsigned char *raw = malloc(n ? n * 4 : 1);
    if (!pos || !raw || fread(raw, 4, n, f) != n) {
        free(pos);
        free(raw);
        fclose(f);
        return weft__fail(pos && raw ? WEFT_ERROR_IO : WEFT_ERROR_OUT_OF_MEMORY, "PC2: cannot read '%s'", path);
    }
    fclose(f);
    for (size_t i = 0; i < n; ++i) {
        pos[i] = get_f32(raw + 4 * i);
    }
    free(raw);
    if (!weft__all_finite(pos, n)) {
        free(pos);
        return weft__fail(WEFT_ERROR_FORMAT, "PC2: '%s' holds NaN or infinity", path);
    }
    *out_positions = pos;
    *out_points = points;
    *out_samples = samples;
    *out_start_frame = start;
    return WEFT_OK;
}

weft_result weft_obj_write(const char *path, const float *positions, uint32_t vertex_count, const uint32_t *triangles,
                           uint32_t triangle_count)
{
    FILE *f = path ? fopen(path, "w") : NULL;
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "OBJ: cannot create '%s': %s", path ? path : "(null)", strerror(errno));
    }
    fprintf(f, "# weft: %u vertices, %u triangles\n", vertex_count, triangle_count);
    for (uint32_t v = 0; v < vertex_count; ++v) {
        const float *p = positions + 3 * (size_t)v;
        fprintf(f, "v %.7g %.7g %.7g\n", (double)p[0], (double)p[1], (double)p[2]);
    }
    for (uint32_t t = 0; t < triangle_count; ++t) {
        const uint32_t *tri = triangles + 3 * (size_t)t;
        fprintf(f, "f %u %u %u\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
    }
    return fclose(f) == 0 ? WEFT_OK : weft__fail(WEFT_ERROR_IO, "OBJ: cannot write '%s'", path);
}
