/* OBJ + PC2 point caches (pc2.h). */
#define _POSIX_C_SOURCE 200809L /* strtok_r */
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

/* ---------------------------------------------------------------------------------------- */
/* OBJ reading                                                                                 */

#define OBJ_MAX_BYTES ((size_t)1 << 30)
#define OBJ_MAX_VERTICES (1u << 24)
#define OBJ_MAX_TRIANGLES (1u << 26)
#define OBJ_MAX_POLYGON 256u

typedef struct obj_arrays {
    float *v;
    uint32_t nv, cap_v;
    uint32_t *t;
    uint32_t nt, cap_t;
} obj_arrays;

static bool grow(void **p, uint32_t *cap, uint32_t need, size_t item)
{
    if (need <= *cap) {
        return true;
    }
    uint32_t next = *cap ? *cap : 1024;
    while (next < need) {
        next = next > UINT32_MAX / 2 ? need : next * 2;
    }
    void *q = realloc(*p, (size_t)next * item);
    if (!q) {
        return false;
    }
    *p = q;
    *cap = next;
    return true;
}

/* One face index ("7", "7/1", "7//3", "-1/..."): the vertex index, 0-based, or -1 when bad. */
static int64_t obj_index(const char *tok, uint32_t nv)
{
    char *end = NULL;
    errno = 0;
    long long i = strtoll(tok, &end, 10);
    if (end == tok || errno != 0 || (*end != '\0' && *end != '/')) {
        return -1;
    }
    if (i > 0 && (unsigned long long)i <= nv) {
        return i - 1;
    }
    if (i < 0 && (unsigned long long)(-(i + 1)) < nv) {
        return (int64_t)nv + i; /* relative: -1 is the last vertex so far */
    }
    return -1;
}

static weft_result obj_parse_line(char *line, size_t number, const char *path, obj_arrays *o)
{
    char *save = NULL;
    const char *key = strtok_r(line, " \t\r", &save);
    if (!key || key[0] == '#') {
        return WEFT_OK;
    }
    if (strcmp(key, "v") == 0) {
        float p[3];
        for (int k = 0; k < 3; ++k) {
            const char *tok = strtok_r(NULL, " \t\r", &save);
            char *end = NULL;
            p[k] = tok ? strtof(tok, &end) : NAN;
            if (!tok || *end != '\0') {
                return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s' line %zu: a vertex needs three numbers", path, number);
            }
            if (!(fabsf(p[k]) <= WEFT_MAX_COORDINATE)) {
                return weft__fail(WEFT_ERROR_NOT_FINITE, "OBJ '%s' line %zu: coordinate %s is not finite or beyond %g m",
                                  path, number, tok, (double)WEFT_MAX_COORDINATE);
            }
        }
        if (o->nv >= OBJ_MAX_VERTICES) {
            return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s': more than %u vertices", path, OBJ_MAX_VERTICES);
        }
        if (!grow((void **)&o->v, &o->cap_v, o->nv + 1, 3 * sizeof(float))) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "OBJ '%s': out of memory", path);
        }
        memcpy(o->v + 3 * (size_t)o->nv, p, sizeof p);
        o->nv++;
        return WEFT_OK;
    }
    if (strcmp(key, "f") == 0) {
        uint32_t poly[OBJ_MAX_POLYGON];
        uint32_t n = 0;
        for (const char *tok; (tok = strtok_r(NULL, " \t\r", &save)) != NULL;) {
            int64_t i = obj_index(tok, o->nv);
            if (i < 0) {
                return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s' line %zu: face index '%s' names no vertex defined before it",
                                  path, number, tok);
            }
            if (n == OBJ_MAX_POLYGON) {
                return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s' line %zu: a face with more than %u corners", path, number,
                                  OBJ_MAX_POLYGON);
            }
            poly[n++] = (uint32_t)i;
        }
        if (n < 3) {
            return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s' line %zu: a face needs at least three corners", path, number);
        }
        if (o->nt + (n - 2) > OBJ_MAX_TRIANGLES) {
            return weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s': more than %u triangles", path, OBJ_MAX_TRIANGLES);
        }
        if (!grow((void **)&o->t, &o->cap_t, o->nt + (n - 2), 3 * sizeof(uint32_t))) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "OBJ '%s': out of memory", path);
        }
        for (uint32_t k = 1; k + 1 < n; ++k) { /* a fan: convex polygons as modelling tools write them */
            uint32_t *t = o->t + 3 * (size_t)o->nt++;
            t[0] = poly[0], t[1] = poly[k], t[2] = poly[k + 1];
        }
    }
    return WEFT_OK; /* vt, vn, o, g, s, usemtl, mtllib, l, p: not needed for cloth */
}

weft_result weft_obj_read(const char *path, float **out_positions, uint32_t *out_vertex_count, uint32_t **out_triangles,
                          uint32_t *out_triangle_count)
{
    if (!path || !out_positions || !out_vertex_count || !out_triangles || !out_triangle_count) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_obj_read: path and every output are required");
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "OBJ: cannot open '%s': %s", path, strerror(errno));
    }
    obj_arrays o = {0};
    weft_result r = WEFT_OK;
    char line[4096];
    size_t number = 0, bytes = 0;
    while (r == WEFT_OK && fgets(line, sizeof line, f)) {
        number++;
        size_t len = strlen(line);
        bytes += len;
        if (len == sizeof line - 1 && line[len - 1] != '\n' && !feof(f)) {
            r = weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s' line %zu: longer than %zu characters", path, number, sizeof line - 2);
        } else if (memchr(line, '\0', len) != NULL || bytes > OBJ_MAX_BYTES) {
            r = weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s': not a text OBJ of at most 1 GiB", path);
        } else {
            line[strcspn(line, "\n")] = '\0';
            r = obj_parse_line(line, number, path, &o);
        }
    }
    if (r == WEFT_OK && ferror(f)) {
        r = weft__fail(WEFT_ERROR_IO, "OBJ: reading '%s' failed (is it a folder?)", path);
    }
    fclose(f);
    if (r == WEFT_OK && (o.nv == 0 || o.nt == 0)) {
        r = weft__fail(WEFT_ERROR_FORMAT, "OBJ '%s': no %s", path, o.nv == 0 ? "vertices" : "faces");
    }
    if (r != WEFT_OK) {
        free(o.v);
        free(o.t);
        return r;
    }
    *out_positions = o.v;
    *out_vertex_count = o.nv;
    *out_triangles = o.t;
    *out_triangle_count = o.nt;
    return WEFT_OK;
}
