/* Contact sheets of `weft simgen` sequence folders: the frames a reader wants to see, drawn
 * with the shared OSMesa renderer under one fixed camera. Used by `weft render --seq` and by the
 * scenario images in docs/. */
#define _POSIX_C_SOURCE 200809L /* stat */

#include "weft_sample.h"
#include "core/core.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#if WEFT_RENDER_HAVE_ASSETS
#include "assets/npz.h"
#include <cjson/cJSON.h>
#include <stb/stb_easy_font.h> /* text widths, to wrap the caption (image.c draws the text) */
#endif

#define SEQ_DEFAULT_TILE 240u
#define SEQ_DEFAULT_TILES 5u
#define SEQ_MAX_ROW 6u
#define SEQ_MAX_FILE_BYTES (4ull << 30)  /* the .npy reader's own 4 GiB limit */
#define SEQ_MAX_META_BYTES (1u << 20)    /* meta.json is a few kB; anything near this is not one */
#define SEQ_MAX_VERTICES (1u << 26)      /* far beyond any garment; keeps index math in 32 bits */
#define SEQ_FRAME_RATE 60.0              /* simgen records at 60 Hz (meta.json frame_dt) */

void weft_seq_sheet_default_options(weft_seq_sheet_options *o)
{
    if (!o) {
        return;
    }
    memset(o, 0, sizeof *o);
    o->tile = SEQ_DEFAULT_TILE;
    o->yaw = NAN;
    o->pitch = NAN;
    o->caption = true;
}

weft_result weft_seq_sheet_parse_frames(const char *text, weft_seq_sheet_options *o)
{
    if (!text || !o) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "--frames: a frame list and options are required");
    }
    uint32_t frames[WEFT_SEQ_SHEET_MAX_FRAMES];
    uint32_t n = 0;
    const char *p = text;
    for (;;) {
        if (*p < '0' || *p > '9') {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "--frames '%s': expected a frame number at offset %zu",
                              text, (size_t)(p - text));
        }
        uint64_t v = 0;
        while (*p >= '0' && *p <= '9') {
            v = v * 10u + (uint64_t)(*p - '0');
            if (v > (1u << 31)) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "--frames '%s': frame number too large", text);
            }
            ++p;
        }
        if (n == WEFT_SEQ_SHEET_MAX_FRAMES) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "--frames '%s': more than %u frames", text,
                              WEFT_SEQ_SHEET_MAX_FRAMES);
        }
        frames[n++] = (uint32_t)v;
        if (*p == '\0') {
            break;
        }
        if (*p != ',') {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "--frames '%s': unexpected '%c' at offset %zu", text, *p,
                              (size_t)(p - text));
        }
        ++p;
    }
    memcpy(o->frames, frames, n * sizeof frames[0]);
    o->frame_count = n;
    return WEFT_OK;
}

#if WEFT_RENDER_HAVE_ASSETS

/* Everything read from the folder. Positions hold only the chosen frames, in tile order. */
typedef struct seq_data {
    uint32_t T, N, F, M, G;
    float *cloth;           /* frame_count * N * 3 */
    float *collider;        /* frame_count * M * 3, NULL when there is no collider */
    uint32_t *faces;        /* F * 3 */
    uint32_t *cfaces;       /* G * 3 */
} seq_data;

static void seq_data_free(seq_data *s)
{
    free(s->cloth);
    free(s->collider);
    free(s->faces);
    free(s->cfaces);
    memset(s, 0, sizeof *s);
}

static weft_result join(char *out, size_t cap, const char *dir, const char *name)
{
    int n = snprintf(out, cap, "%s/%s", dir, name);
    if (n < 0 || (size_t)n >= cap) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "sequence '%s': path too long", dir);
    }
    return WEFT_OK;
}

/* Whole file into a malloc'd buffer. A missing file is reported as absent (not an error) when
 * optional, so the caller can tell "no collider" from a broken one. */
static weft_result slurp(const char *dir, const char *name, uint64_t limit, bool optional, uint8_t **out,
                         size_t *out_size)
{
    char path[4096];
    weft_result r = join(path, sizeof path, dir, name);
    if (r != WEFT_OK) {
        return r;
    }
    *out = NULL;
    *out_size = 0;
    FILE *f = fopen(path, "rb");
    if (!f) {
        if (optional && errno == ENOENT) {
            return WEFT_OK;
        }
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': cannot open %s (%s)", dir, name, strerror(errno));
    }
    long size = -1;
    if (fseek(f, 0, SEEK_END) == 0) {
        size = ftell(f);
    }
    if (size < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': cannot size %s", dir, name);
    }
    if ((uint64_t)size > limit) {
        fclose(f);
        return weft__fail(WEFT_ERROR_FORMAT, "sequence '%s': %s is %ld bytes, over the %llu-byte limit", dir, name,
                          size, (unsigned long long)limit);
    }
    uint8_t *buf = malloc((size_t)size + 1);
    if (!buf) {
        fclose(f);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "sequence '%s': out of memory for %s (%ld bytes)", dir, name, size);
    }
    size_t got = fread(buf, 1, (size_t)size, f);
    fclose(f);
    if (got != (size_t)size) {
        free(buf);
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': short read of %s", dir, name);
    }
    buf[size] = '\0'; /* meta.json is parsed as a C string */
    *out = buf;
    *out_size = (size_t)size;
    return WEFT_OK;
}

/* Parses name.npy and checks its rank and that its last dimension is 3. */
static weft_result parse_array(const char *dir, const char *file, const uint8_t *bytes, size_t size, uint32_t rank,
                               weft_npy_array *a)
{
    weft_result r = weft_npy_parse(bytes, size, file, a);
    if (r != WEFT_OK) {
        return r; /* the message names the file and the fault */
    }
    if (a->dtype == WEFT_NPY_UNSUPPORTED) {
        return weft__fail(WEFT_ERROR_FORMAT, "sequence '%s': %s has non-numeric dtype '%s'", dir, file, a->descr);
    }
    if (a->ndim != rank || a->shape[rank - 1] != 3) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "sequence '%s': %s must be [%s3], it has %u dimensions", dir, file,
                          rank == 3 ? "T, N, " : "N, ", a->ndim);
    }
    for (uint32_t d = 0; d + 1 < rank; ++d) {
        if (a->shape[d] == 0 || a->shape[d] > SEQ_MAX_VERTICES) {
            return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "sequence '%s': %s dimension %u is %llu (1..%u allowed)", dir,
                              file, d, (unsigned long long)a->shape[d], SEQ_MAX_VERTICES);
        }
    }
    return WEFT_OK;
}

/* Triangle indices as uint32, each < vertex_count. */
static weft_result load_faces(const char *dir, const char *file, uint32_t vertex_count, uint32_t **out,
                              uint32_t *out_count)
{
    uint8_t *bytes;
    size_t size;
    weft_result r = slurp(dir, file, SEQ_MAX_FILE_BYTES, false, &bytes, &size);
    if (r != WEFT_OK) {
        return r;
    }
    weft_npy_array a;
    r = parse_array(dir, file, bytes, size, 2, &a);
    int64_t *wide = NULL;
    uint32_t *idx = NULL;
    if (r == WEFT_OK) {
        wide = malloc(a.count * sizeof *wide);
        idx = malloc(a.count * sizeof *idx);
        r = wide && idx ? weft_npy_to_i64(&a, wide, a.count)
                        : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "sequence '%s': out of memory for %s", dir, file);
    }
    for (uint64_t i = 0; r == WEFT_OK && i < a.count; ++i) {
        if (wide[i] < 0 || wide[i] >= (int64_t)vertex_count) {
            r = weft__fail(WEFT_ERROR_DEGENERATE_MESH, "sequence '%s': %s triangle %llu has index %lld, outside 0..%u",
                           dir, file, (unsigned long long)(i / 3), (long long)wide[i], vertex_count - 1);
            break;
        }
        idx[i] = (uint32_t)wide[i];
    }
    free(wide);
    free(bytes);
    if (r != WEFT_OK) {
        free(idx);
        return r;
    }
    *out = idx;
    *out_count = (uint32_t)a.shape[0];
    return WEFT_OK;
}

/* Converts the chosen frames of a [T, V, 3] array to float32 (row-major, frame after frame). */
static weft_result gather_frames(const char *dir, const char *file, const weft_npy_array *a, const uint32_t *frames,
                                 uint32_t frame_count, float *out)
{
    uint64_t per_frame = a->shape[1] * 3u;
    if (a->fortran_order) {
        /* Column-major storage interleaves frames, so convert everything once. */
        float *all = malloc(a->count * sizeof *all);
        if (!all) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "sequence '%s': out of memory for %s", dir, file);
        }
        weft_result r = weft_npy_to_f32(a, all, a->count);
        for (uint32_t i = 0; r == WEFT_OK && i < frame_count; ++i) {
            memcpy(out + i * per_frame, all + frames[i] * per_frame, per_frame * sizeof *out);
        }
        free(all);
        return r;
    }
    for (uint32_t i = 0; i < frame_count; ++i) {
        weft_npy_array view = *a;
        view.ndim = 2;
        view.shape[0] = a->shape[1];
        view.shape[1] = 3;
        view.count = per_frame;
        view.data = a->data + (uint64_t)frames[i] * per_frame * a->item_size;
        weft_result r = weft_npy_to_f32(&view, out + i * per_frame, per_frame);
        if (r != WEFT_OK) {
            return weft__fail(r, "sequence '%s': %s frame %u: %s", dir, file, frames[i], weft_last_error());
        }
    }
    return WEFT_OK;
}

/* Picks the default frames: 0, T/4, T/2, 3T/4 and the last, or every frame of short ones. */
static uint32_t default_frames(uint32_t T, uint32_t *frames)
{
    uint32_t n = T < SEQ_DEFAULT_TILES ? T : SEQ_DEFAULT_TILES;
    for (uint32_t i = 0; i < n; ++i) {
        uint64_t f = n == 1 ? 0 : (uint64_t)i * T / (n - 1);
        frames[i] = f >= T ? T - 1 : (uint32_t)f;
    }
    return n;
}

static weft_result load_positions(const char *dir, const char *file, bool optional, uint32_t *T, uint32_t *V,
                                  uint32_t *frames, uint32_t *frame_count, float **out)
{
    uint8_t *bytes;
    size_t size;
    *out = NULL;
    weft_result r = slurp(dir, file, SEQ_MAX_FILE_BYTES, optional, &bytes, &size);
    if (r != WEFT_OK || !bytes) {
        return r;
    }
    weft_npy_array a;
    r = parse_array(dir, file, bytes, size, 3, &a);
    if (r == WEFT_OK && *T != 0 && a.shape[0] != *T) {
        r = weft__fail(WEFT_ERROR_SIZE_MISMATCH, "sequence '%s': %s has %llu frames, cloth_pos.npy %u", dir, file,
                       (unsigned long long)a.shape[0], *T);
    }
    if (r == WEFT_OK && *T == 0) {
        *T = (uint32_t)a.shape[0];
        if (*frame_count == 0) {
            *frame_count = default_frames(*T, frames);
        }
        for (uint32_t i = 0; i < *frame_count; ++i) {
            if (frames[i] >= *T) {
                r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "sequence '%s': frame %u requested, the sequence has %u (0..%u)",
                               dir, frames[i], *T, *T - 1);
                break;
            }
        }
    }
    float *pos = NULL;
    if (r == WEFT_OK) {
        pos = malloc((size_t)*frame_count * a.shape[1] * 3 * sizeof *pos);
        r = pos ? gather_frames(dir, file, &a, frames, *frame_count, pos)
                : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "sequence '%s': out of memory for %s", dir, file);
    }
    free(bytes);
    if (r != WEFT_OK) {
        free(pos);
        return r;
    }
    *V = (uint32_t)a.shape[1];
    *out = pos;
    return WEFT_OK;
}

static void copy_string(const cJSON *meta, const char *key, char *out, size_t cap)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(meta, key);
    if (cJSON_IsString(item) && item->valuestring) {
        snprintf(out, cap, "%s", item->valuestring);
    }
}

static weft_result read_meta(const char *dir, weft_seq_sheet_info *info, uint32_t *substeps)
{
    uint8_t *bytes;
    size_t size;
    weft_result r = slurp(dir, "meta.json", SEQ_MAX_META_BYTES, false, &bytes, &size);
    if (r != WEFT_OK) {
        return r;
    }
    cJSON *meta = cJSON_ParseWithLength((const char *)bytes, size);
    free(bytes);
    if (!cJSON_IsObject(meta)) {
        cJSON_Delete(meta);
        return weft__fail(WEFT_ERROR_FORMAT, "sequence '%s': meta.json is not a JSON object", dir);
    }
    copy_string(meta, "scenario", info->scenario, sizeof info->scenario);
    copy_string(meta, "description", info->description, sizeof info->description);
    const cJSON *accepted = cJSON_GetObjectItemCaseSensitive(meta, "accepted");
    info->accepted = cJSON_IsBool(accepted) ? cJSON_IsTrue(accepted) : -1;
    const cJSON *validator = cJSON_GetObjectItemCaseSensitive(meta, "validator");
    const cJSON *run = cJSON_GetObjectItemCaseSensitive(validator, "run");
    info->validated = cJSON_IsBool(run) ? cJSON_IsTrue(run) : -1;
    static const char *const hit_keys[] = {"ccd_hits", "intersection_hits"};
    for (int k = 0; k < 2; ++k) {
        const cJSON *hits = cJSON_GetObjectItemCaseSensitive(validator, hit_keys[k]);
        if (cJSON_IsNumber(hits) && hits->valuedouble >= 0 && hits->valuedouble < 1e9) {
            info->validator_hits += (uint32_t)hits->valuedouble;
        }
    }
    const cJSON *sub = cJSON_GetObjectItemCaseSensitive(meta, "substeps");
    *substeps = cJSON_IsNumber(sub) && sub->valuedouble >= 1 && sub->valuedouble < 1e6 ? (uint32_t)sub->valuedouble : 0;
    cJSON_Delete(meta);
    return WEFT_OK;
}

static weft_result load_sequence(const weft_seq_sheet_options *o, weft_seq_sheet_info *info, uint32_t *substeps,
                                 seq_data *s)
{
    const char *dir = o->seq_dir;
    struct stat st;
    if (stat(dir, &st) != 0) {
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': cannot open the folder (%s)", dir, strerror(errno));
    }
    if (!S_ISDIR(st.st_mode)) {
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': not a folder", dir);
    }
    weft_result r = read_meta(dir, info, substeps);
    if (r != WEFT_OK) {
        return r;
    }
    info->frame_count = o->frame_count;
    memcpy(info->frames, o->frames, sizeof info->frames);
    memset(s, 0, sizeof *s);
    char cloth_path[4096];
    if (info->accepted == 0 && join(cloth_path, sizeof cloth_path, dir, "cloth_pos.npy") == WEFT_OK &&
        stat(cloth_path, &st) != 0) {
        return weft__fail(WEFT_ERROR_IO, "sequence '%s': rejected by the validator, so it has no arrays to draw", dir);
    }
    uint32_t T = 0, cloth_n = 0, coll_t = 0, coll_m = 0;
    float *coll = NULL;
    r = load_positions(dir, "cloth_pos.npy", false, &T, &cloth_n, info->frames, &info->frame_count, &s->cloth);
    if (r == WEFT_OK) {
        s->T = T;
        s->N = cloth_n;
        r = load_faces(dir, "faces.npy", s->N, &s->faces, &s->F);
    }
    if (r == WEFT_OK) {
        coll_t = T;
        r = load_positions(dir, "collider_pos.npy", true, &coll_t, &coll_m, info->frames, &info->frame_count, &coll);
        s->collider = coll;
        s->M = coll_m;
    }
    if (r == WEFT_OK) {
        char faces_path[4096];
        bool have_cfaces = join(faces_path, sizeof faces_path, dir, "collider_faces.npy") == WEFT_OK &&
                           stat(faces_path, &st) == 0;
        if (have_cfaces != (s->collider != NULL)) {
            r = weft__fail(WEFT_ERROR_FORMAT, "sequence '%s': %s without %s", dir,
                           have_cfaces ? "collider_faces.npy" : "collider_pos.npy",
                           have_cfaces ? "collider_pos.npy" : "collider_faces.npy");
        } else if (have_cfaces) {
            r = load_faces(dir, "collider_faces.npy", s->M, &s->cfaces, &s->G);
        }
    }
    if (r != WEFT_OK) {
        seq_data_free(s);
    }
    return r;
}

/* Collider triangles that lie on the collider's lowest plane and face up: the floor. */
static uint32_t split_ground(const seq_data *s, uint32_t frame_count, uint32_t *kept, float *ground_y)
{
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < (size_t)frame_count * s->M; ++i) {
        float y = s->collider[3 * i + 1];
        lo = y < lo ? y : lo;
        hi = y > hi ? y : hi;
    }
    float eps = 1e-6f * (1.0f + (hi - lo));
    uint32_t nkept = 0, nground = 0;
    for (uint32_t t = 0; t < s->G; ++t) {
        const uint32_t *tri = s->cfaces + 3 * t;
        bool ground = true;
        for (uint32_t f = 0; f < frame_count && ground; ++f) {
            const float *p = s->collider + (size_t)f * s->M * 3;
            const float *a = p + 3 * tri[0], *b = p + 3 * tri[1], *c = p + 3 * tri[2];
            /* Y component of (b - a) x (c - a): positive for a CCW triangle seen from above */
            float ny = (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]);
            ground = a[1] <= lo + eps && b[1] <= lo + eps && c[1] <= lo + eps && ny > 0.0f;
        }
        if (ground) {
            nground++;
        } else {
            memcpy(kept + 3 * nkept++, tri, 3 * sizeof *tri);
        }
    }
    *ground_y = lo;
    return nground;
}

static void grow(float box[6], const float *p)
{
    for (int k = 0; k < 3; ++k) {
        box[k] = p[k] < box[k] ? p[k] : box[k];
        box[3 + k] = p[k] > box[3 + k] ? p[k] : box[3 + k];
    }
}

#define CAPTION_MAX_LINES 6

/* Greedy word wrap of text into lines no wider than max_width font units. */
static uint32_t wrap_text(const char *text, int max_width, char lines[][96], uint32_t max_lines)
{
    uint32_t n = 0;
    const char *p = text;
    while (*p && n < max_lines) {
        while (*p == ' ') {
            ++p;
        }
        if (!*p) {
            break;
        }
        size_t full = strlen(p), len = full < 95 ? full : 95, take = 0, last_space = 0;
        for (size_t k = 1; k <= len; ++k) {
            char buf[96];
            memcpy(buf, p, k);
            buf[k] = '\0';
            if (stb_easy_font_width(buf) > max_width) {
                break;
            }
            take = k;
            if (p[k] == ' ' || p[k] == '\0') {
                last_space = k;
            }
        }
        /* break after the last whole word that fits; a word wider than the line is cut */
        size_t cut = take == full ? take : last_space ? last_space : take ? take : 1;
        memcpy(lines[n], p, cut);
        lines[n][cut] = '\0';
        ++n;
        p += cut;
    }
    return n;
}

/* The caption: the description, then the sequence's size and validator verdict. */
static weft_result add_caption(uint8_t **sheet, uint32_t w, uint32_t *h, const weft_seq_sheet_info *info,
                               uint32_t substeps, const char *dir)
{
    char line1[160], line2[192];
    const char *name = strrchr(dir, '/');
    name = name && name[1] ? name + 1 : dir;
    snprintf(line1, sizeof line1, "%s", info->description[0] ? info->description : name);
    char sub[32] = "";
    if (substeps) {
        snprintf(sub, sizeof sub, ", %u substeps", substeps);
    }
    char verdict[64];
    if (info->accepted == 0) {
        snprintf(verdict, sizeof verdict, "REJECTED by the validator (%u hits)", info->validator_hits);
    } else if (info->validated == 0) {
        snprintf(verdict, sizeof verdict, "UNVALIDATED (written with --no-validate)");
    } else if (info->accepted == 1 && info->validated == 1) {
        snprintf(verdict, sizeof verdict, "validated, %u validator hits", info->validator_hits);
    } else {
        snprintf(verdict, sizeof verdict, "no validator verdict in meta.json");
    }
    snprintf(line2, sizeof line2, "%.60s: %u frames, %u cloth vertices%s, %s", name, info->sequence_frames,
             info->cloth_vertices, sub, verdict);
    int scale = w >= 1000 ? 2 : 1;
    int max_width = ((int)w - 16 * scale) / scale;
    char lines[CAPTION_MAX_LINES][96];
    uint32_t n = wrap_text(line1, max_width, lines, CAPTION_MAX_LINES / 2);
    n += wrap_text(line2, max_width, lines + n, CAPTION_MAX_LINES - n);
    uint32_t line_h = 14u * (uint32_t)scale;
    uint32_t strip = n * line_h + 6u * (uint32_t)scale;
    uint32_t nh = *h + strip;
    uint8_t *out = malloc((size_t)w * nh * 4);
    if (!out) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "contact sheet: out of memory for the caption");
    }
    for (size_t i = 0; i < (size_t)w * strip; ++i) {
        out[4 * i + 0] = 40; /* the sheet's gutter colour */
        out[4 * i + 1] = 42;
        out[4 * i + 2] = 48;
        out[4 * i + 3] = 255;
    }
    memcpy(out + (size_t)w * strip * 4, *sheet, (size_t)w * *h * 4);
    for (uint32_t i = 0; i < n; ++i) {
        weft_render_draw_text(out, w, nh, 6 * scale, 5 * scale + (int)(i * line_h), scale, lines[i]);
    }
    weft_render_free_image(*sheet);
    *sheet = out;
    *h = nh;
    return WEFT_OK;
}

static bool is_garment(const char *scenario)
{
    return strcmp(scenario, "garment") == 0 || strcmp(scenario, "human") == 0;
}

static weft_result render_sheet(const weft_seq_sheet_options *o, weft_seq_sheet_info *info, uint32_t substeps,
                                const seq_data *s)
{
    const uint32_t n = info->frame_count, tile_w = o->tile;
    uint32_t *kept = NULL;
    float ground_y = NAN;
    uint32_t nkept = 0;
    if (s->collider && s->G) {
        kept = malloc((size_t)s->G * 3 * sizeof *kept);
        if (!kept) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "contact sheet: out of memory");
        }
        info->ground_triangles = split_ground(s, n, kept, &ground_y);
        nkept = s->G - info->ground_triangles;
    }
    /* One camera for every tile, so motion between tiles reads as motion. */
    float box[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < (size_t)n * s->N; ++i) {
        grow(box, s->cloth + 3 * i);
    }
    for (uint32_t f = 0; f < n && nkept; ++f) {
        const float *p = s->collider + (size_t)f * s->M * 3;
        for (uint32_t t = 0; t < 3 * nkept; ++t) {
            grow(box, p + 3 * kept[t]);
        }
    }
    if (info->ground_triangles && ground_y < box[1]) {
        box[1] = ground_y; /* keep the contact with the floor in view */
    }
    bool garment = is_garment(info->scenario);
    /* a standing avatar fills a portrait tile better */
    const uint32_t tile_h = o->tile_height ? o->tile_height : garment ? tile_w * 4 / 3 : tile_w;
    float yaw = isfinite(o->yaw) ? o->yaw : garment ? 25.0f : 30.0f;
    float pitch = isfinite(o->pitch) ? o->pitch : garment ? 8.0f : 35.0f;

    weft_render_def rdef = weft_default_render_def();
    rdef.width = tile_w;
    rdef.height = tile_h;
    rdef.deterministic = true;
    weft_renderer *rr = NULL;
    size_t image_bytes = (size_t)tile_w * tile_h * 4;
    uint8_t *tiles = malloc(image_bytes * n);
    weft_result r = tiles ? weft_renderer_create(&rdef, &rr)
                          : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "contact sheet: out of memory for %u tiles", n);
    uint32_t cloth_mesh = 0, coll_mesh = 0;
    if (r == WEFT_OK) {
        r = weft_renderer_add_mesh(rr, s->cloth, s->N, s->faces, s->F, WEFT_RENDER_CLOTH, &cloth_mesh);
    }
    if (r == WEFT_OK && nkept) {
        r = weft_renderer_add_mesh(rr, s->collider, s->M, kept, nkept, garment ? WEFT_RENDER_SKIN : WEFT_RENDER_RIGID,
                                   &coll_mesh);
    }
    if (r == WEFT_OK) {
        weft_renderer_set_ground(rr, true, info->ground_triangles ? ground_y : NAN);
    }
    char labels[WEFT_SEQ_SHEET_MAX_FRAMES][48];
    const char *label_ptrs[WEFT_SEQ_SHEET_MAX_FRAMES];
    const uint8_t *tile_ptrs[WEFT_SEQ_SHEET_MAX_FRAMES];
    for (uint32_t f = 0; r == WEFT_OK && f < n; ++f) {
        r = weft_renderer_update_mesh(rr, cloth_mesh, s->cloth + (size_t)f * s->N * 3);
        if (r == WEFT_OK && nkept) {
            r = weft_renderer_update_mesh(rr, coll_mesh, s->collider + (size_t)f * s->M * 3);
        }
        if (r == WEFT_OK) {
            r = weft_renderer_frame_box(rr, box, box + 3, yaw, pitch);
        }
        if (r == WEFT_OK) {
            r = weft_renderer_render(rr);
        }
        if (r == WEFT_OK) {
            memcpy(tiles + image_bytes * f, weft_renderer_pixels(rr), image_bytes);
            snprintf(labels[f], sizeof labels[f], "frame %u  t=%.2f s", info->frames[f], info->frames[f] / SEQ_FRAME_RATE);
            label_ptrs[f] = labels[f];
            tile_ptrs[f] = tiles + image_bytes * f;
        }
    }
    weft_renderer_destroy(rr);
    free(kept);
    uint8_t *sheet = NULL;
    uint32_t w = 0, h = 0;
    if (r == WEFT_OK) {
        uint32_t cols = o->columns ? o->columns : n < SEQ_MAX_ROW ? n : SEQ_MAX_ROW;
        r = weft_render_contact_sheet(tile_ptrs, label_ptrs, n, tile_w, tile_h, cols, &sheet, &w, &h);
    }
    free(tiles);
    if (r == WEFT_OK && o->caption) {
        r = add_caption(&sheet, w, &h, info, substeps, o->seq_dir);
    }
    if (r == WEFT_OK) {
        r = weft_render_write_png(o->out_path, sheet, w, h);
    }
    weft_render_free_image(sheet);
    if (r == WEFT_OK) {
        info->width = w;
        info->height = h;
        info->tile_width = tile_w;
        info->tile_height = tile_h;
    }
    return r;
}

weft_result weft_seq_sheet_render(const weft_seq_sheet_options *o, weft_seq_sheet_info *out_info)
{
    if (!o || !o->seq_dir || !o->out_path) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_seq_sheet_render: a sequence folder and an output path are required");
    }
    if (o->tile < 64 || o->tile > 1024 || (o->tile_height && (o->tile_height < 64 || o->tile_height > 1024))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_seq_sheet_render: tile %ux%u outside 64..1024", o->tile,
                          o->tile_height);
    }
    if (o->frame_count > WEFT_SEQ_SHEET_MAX_FRAMES) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_seq_sheet_render: %u frames, at most %u", o->frame_count,
                          WEFT_SEQ_SHEET_MAX_FRAMES);
    }
    if (o->columns > WEFT_SEQ_SHEET_MAX_FRAMES) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_seq_sheet_render: %u columns, at most %u", o->columns,
                          WEFT_SEQ_SHEET_MAX_FRAMES);
    }
    if ((!isfinite(o->yaw) && !isnan(o->yaw)) || (!isfinite(o->pitch) && !isnan(o->pitch)) ||
        fabsf(o->pitch) > 85.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_seq_sheet_render: pitch must be within +-85 degrees, yaw finite");
    }
    weft_seq_sheet_info info;
    memset(&info, 0, sizeof info);
    uint32_t substeps = 0;
    seq_data s;
    weft_result r = load_sequence(o, &info, &substeps, &s);
    if (r != WEFT_OK) {
        return r;
    }
    info.sequence_frames = s.T;
    info.cloth_vertices = s.N;
    info.cloth_triangles = s.F;
    info.collider_vertices = s.M;
    info.collider_triangles = s.G;
    r = render_sheet(o, &info, substeps, &s);
    seq_data_free(&s);
    if (r == WEFT_OK && out_info) {
        *out_info = info;
    }
    return r;
}

#else

weft_result weft_seq_sheet_render(const weft_seq_sheet_options *o, weft_seq_sheet_info *out_info)
{
    (void)o;
    (void)out_info;
    return weft__fail(WEFT_ERROR_UNSUPPORTED, "sequence sheets need weft_assets (the .npy reader), absent from this build");
}

#endif
