#define _POSIX_C_SOURCE 200809L /* opendir, stat, strdup */
/* Calibration and validation sequences: simgen folders (meta.json + .npy arrays), folders of
 * them, and split lists. Everything is checked here so that calibration never sees a bad frame. */
#include "quant_internal.h"

#include "assets/npz.h"
#include "core/core.h"
#include "weft/sim.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

weft_result quant_read_all(weft_context *ctx, const char *path, void **out, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "quantize: cannot open '%s'", path);
    }
    long len = -1;
    if (fseek(f, 0, SEEK_END) == 0) {
        len = ftell(f);
    }
    if (len < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "quantize: cannot size '%s'", path);
    }
    void *buf = ctx ? weft__alloc(ctx, (size_t)len) : malloc(len ? (size_t)len : 1);
    if (!buf) {
        fclose(f);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory reading '%s'", path);
    }
    if (fread(buf, 1, (size_t)len, f) != (size_t)len) {
        fclose(f);
        if (ctx) {
            weft__free(ctx, buf, (size_t)len);
        } else {
            free(buf);
        }
        return weft__fail(WEFT_ERROR_IO, "quantize: short read on '%s'", path);
    }
    fclose(f);
    *out = buf;
    *size = (size_t)len;
    return WEFT_OK;
}

static bool join(char *out, size_t cap, const char *dir, const char *name)
{
    int n = snprintf(out, cap, "%s/%s", dir, name);
    return n > 0 && (size_t)n < cap;
}

static bool is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

static bool is_file_in(const char *dir, const char *name)
{
    char p[4096];
    struct stat st;
    return join(p, sizeof p, dir, name) && stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

/* Reads and parses dir/name.npy into a (which points into *bytes: the caller frees it, also on
 * failure); path receives the file's path for messages. */
static weft_result read_npy(const char *dir, const char *name, char path[4096], void **bytes, weft_npy_array *a)
{
    char file[64];
    snprintf(file, sizeof file, "%s.npy", name);
    *bytes = NULL;
    if (!join(path, 4096, dir, file)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: path too long under '%s'", dir);
    }
    size_t size = 0;
    weft_result r = quant_read_all(NULL, path, bytes, &size);
    return r == WEFT_OK ? weft_npy_parse(*bytes, size, name, a) : r;
}

/* dir/name.npy as float32 [shape] or (as_index) uint32 indices below index_limit. rank must
 * match; shape[rank-1] must be 3. */
static weft_result load_array(const char *dir, const char *name, uint32_t rank, bool as_index, uint64_t index_limit,
                              void **out, uint64_t shape[3])
{
    char path[4096], file[64];
    snprintf(file, sizeof file, "%s.npy", name);
    void *bytes = NULL;
    weft_npy_array a;
    weft_result r = read_npy(dir, name, path, &bytes, &a);
    if (r == WEFT_OK && (a.ndim != rank || a.shape[rank - 1] != 3 || a.count == 0 || a.count > (1ull << 31))) {
        r = weft__fail(WEFT_ERROR_FORMAT, "quantize: %s: '%s' must be a non-empty [%s3] array", dir, file,
                       rank == 3 ? "T, n, " : "n, ");
    }
    void *data = NULL;
    if (r == WEFT_OK) {
        data = malloc((size_t)a.count * (as_index ? sizeof(uint32_t) : sizeof(float)));
        int64_t *tmp = as_index ? malloc((size_t)a.count * sizeof(int64_t)) : NULL;
        if (!data || (as_index && !tmp)) {
            r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for '%s'", path);
        } else if (as_index) {
            r = weft_npy_to_i64(&a, tmp, a.count);
            for (uint64_t i = 0; r == WEFT_OK && i < a.count; ++i) {
                if (tmp[i] < 0 || (uint64_t)tmp[i] >= index_limit) {
                    r = weft__fail(WEFT_ERROR_FORMAT, "quantize: %s: '%s' index %lld at %llu is outside [0, %llu)", dir,
                                   file, (long long)tmp[i], (unsigned long long)i, (unsigned long long)index_limit);
                }
                ((uint32_t *)data)[i] = (uint32_t)tmp[i];
            }
        } else {
            r = weft_npy_to_f32(&a, data, a.count);
            if (r == WEFT_ERROR_NOT_FINITE) {
                r = weft__fail(WEFT_ERROR_NOT_FINITE, "quantize: %s: '%s' holds NaN or infinity", dir, file);
            }
        }
        free(tmp);
    }
    free(bytes);
    if (r != WEFT_OK) {
        free(data);
        return r;
    }
    for (uint32_t i = 0; i < rank; ++i) {
        shape[i] = a.shape[i];
    }
    *out = data;
    return WEFT_OK;
}

void quant_seq_free(quant_seq *s)
{
    free(s->pinned);
    free(s->pin_index);
    free(s->pin_target);
    free(s->rest);
    free(s->pos);
    free(s->cpos);
    free(s->faces);
    free(s->cfaces);
    memset(s, 0, sizeof *s);
}

/* dir/pinned.npy: [T, V] of any numeric dtype (non-zero = pinned), T and V as the cloth's. */
static weft_result load_pins(const char *dir, quant_seq *s)
{
    char path[4096];
    void *bytes = NULL;
    weft_npy_array a;
    weft_result r = read_npy(dir, "pinned", path, &bytes, &a);
    if (r == WEFT_OK && (a.ndim != 2 || a.shape[0] != s->T || a.shape[1] != s->V)) {
        r = weft__fail(WEFT_ERROR_SIZE_MISMATCH, "quantize: %s: pinned.npy must be [%u, %u] (frames, vertices)", dir,
                       s->T, s->V);
    }
    if (r == WEFT_OK) {
        s->pinned = malloc((size_t)a.count * sizeof(float));
        s->pin_index = malloc((size_t)s->V * sizeof(uint32_t));
        s->pin_target = malloc((size_t)s->V * 3 * sizeof(float));
        r = s->pinned && s->pin_index && s->pin_target
                ? weft_npy_to_f32(&a, s->pinned, a.count)
                : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for '%s'", path);
        if (r == WEFT_ERROR_NOT_FINITE) {
            r = weft__fail(WEFT_ERROR_NOT_FINITE, "quantize: %s: 'pinned.npy' holds NaN or infinity", dir);
        }
    }
    free(bytes);
    return r;
}

weft_result quant_seq_load(const char *dir, quant_seq *s)
{
    memset(s, 0, sizeof *s);
    if (!is_dir(dir)) {
        return weft__fail(WEFT_ERROR_IO, "quantize: sequence folder '%s' does not exist", dir);
    }
    char path[4096];
    void *text = NULL;
    size_t size = 0;
    if (!join(path, sizeof path, dir, "meta.json")) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: path too long under '%s'", dir);
    }
    weft_result r = quant_read_all(NULL, path, &text, &size);
    if (r != WEFT_OK) {
        return r;
    }
    cJSON *meta = cJSON_ParseWithLength(text, size);
    bool ok = cJSON_IsObject(meta);
    cJSON_Delete(meta);
    free(text);
    if (!ok) {
        return weft__fail(WEFT_ERROR_FORMAT, "quantize: %s/meta.json is not a JSON object", dir);
    }
    uint64_t sr[3] = {0}, sf[3] = {0}, sp[3] = {0}, sc[3] = {0}, scf[3] = {0};
    if ((r = load_array(dir, "rest_pos", 2, false, 0, (void **)&s->rest, sr)) != WEFT_OK ||
        (r = load_array(dir, "faces", 2, true, sr[0], (void **)&s->faces, sf)) != WEFT_OK ||
        (r = load_array(dir, "cloth_pos", 3, false, 0, (void **)&s->pos, sp)) != WEFT_OK) {
        quant_seq_free(s);
        return r;
    }
    s->V = (uint32_t)sr[0];
    s->F = (uint32_t)sf[0];
    s->T = (uint32_t)sp[0];
    if (sp[1] != sr[0] || s->T < 3) {
        quant_seq_free(s);
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH,
                          "quantize: %s: cloth_pos is [%llu, %llu, 3] but rest_pos has %llu vertices (need >= 3 frames)",
                          dir, (unsigned long long)sp[0], (unsigned long long)sp[1], (unsigned long long)sr[0]);
    }
    bool has_c = is_file_in(dir, "collider_pos.npy"), has_cf = is_file_in(dir, "collider_faces.npy");
    if (has_c != has_cf) {
        quant_seq_free(s);
        return weft__fail(WEFT_ERROR_FORMAT, "quantize: %s: collider_pos.npy and collider_faces.npy come together", dir);
    }
    if (has_c) {
        if ((r = load_array(dir, "collider_pos", 3, false, 0, (void **)&s->cpos, sc)) != WEFT_OK ||
            (r = load_array(dir, "collider_faces", 2, true, sc[1], (void **)&s->cfaces, scf)) != WEFT_OK) {
            quant_seq_free(s);
            return r;
        }
        if (sc[0] != sp[0]) {
            quant_seq_free(s);
            return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "quantize: %s: collider_pos has %llu frames, cloth_pos %llu",
                              dir, (unsigned long long)sc[0], (unsigned long long)sp[0]);
        }
        s->Vc = (uint32_t)sc[1];
        s->Fc = (uint32_t)scf[0];
    }
    if (is_file_in(dir, "pinned.npy") && (r = load_pins(dir, s)) != WEFT_OK) {
        quant_seq_free(s);
        return r;
    }
    return WEFT_OK;
}

weft_result quant_seq_set_pins(weft_garment *g, const quant_seq *s, uint32_t t)
{
    if (!s->pinned || t >= s->T) {
        return WEFT_OK;
    }
    const float *mask = s->pinned + (size_t)t * s->V, *x = s->pos + (size_t)t * s->V * 3;
    uint32_t n = 0;
    for (uint32_t v = 0; v < s->V; ++v) {
        if (mask[v] != 0.0f) {
            s->pin_index[n] = v;
            memcpy(s->pin_target + 3 * (size_t)n, x + 3 * (size_t)v, 3 * sizeof(float));
            n++;
        }
    }
    return weft_garment_set_pins(g, s->pin_index, s->pin_target, n);
}

void quant_list_free(char **list, uint32_t count)
{
    for (uint32_t i = 0; i < count; ++i) {
        free(list[i]);
    }
    free(list);
}

typedef struct str_list {
    char **v;
    uint32_t n, cap;
} str_list;

static bool list_push(str_list *l, const char *s)
{
    if (l->n == l->cap) {
        uint32_t cap = l->cap ? 2 * l->cap : 16;
        char **nv = realloc(l->v, cap * sizeof *nv);
        if (!nv) {
            return false;
        }
        l->v = nv;
        l->cap = cap;
    }
    char *c = strdup(s);
    if (!c) {
        return false;
    }
    l->v[l->n++] = c;
    return true;
}


static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static weft_result expand_folder(const char *dir, const char *split, str_list *out)
{
    DIR *dh = opendir(dir);
    if (!dh) {
        return weft__fail(WEFT_ERROR_IO, "quantize: cannot open calibration folder '%s'", dir);
    }
    str_list names = {0};
    struct dirent *de;
    bool ok = true;
    while (ok && (de = readdir(dh)) != NULL) {
        if (de->d_name[0] != '.') {
            ok = list_push(&names, de->d_name);
        }
    }
    closedir(dh);
    if (!ok) {
        quant_list_free(names.v, names.n);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory listing '%s'", dir);
    }
    if (names.n) {
        qsort(names.v, names.n, sizeof *names.v, cmp_str);
    }
    uint32_t before = out->n;
    weft_result r = WEFT_OK;
    for (uint32_t i = 0; i < names.n && r == WEFT_OK; ++i) {
        char path[4096];
        if (join(path, sizeof path, dir, names.v[i]) && is_file_in(path, "meta.json") &&
            is_file_in(path, "cloth_pos.npy") && (!split || strcmp(weft_sim_sequence_split(path), split) == 0) &&
            !list_push(out, path)) {
            r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory listing '%s'", dir);
        }
    }
    quant_list_free(names.v, names.n);
    if (r == WEFT_OK && out->n == before) {
        r = weft__fail(WEFT_ERROR_FORMAT, "quantize: no sequences (meta.json + cloth_pos.npy)%s%s under '%s'",
                       split ? " in split " : "", split ? split : "", dir);
    }
    return r;
}

/* A split list: one sequence folder name per line; '#' starts a comment. Names resolve against
 * the list's folder, then its parent (simgen writes ROOT/splits/<scenario>_<split>.txt). */
static weft_result expand_list(const char *file, str_list *out)
{
    void *text = NULL;
    size_t size = 0;
    weft_result r = quant_read_all(NULL, file, &text, &size);
    if (r != WEFT_OK) {
        return r;
    }
    char base[4096], parent[4096];
    snprintf(base, sizeof base, "%s", file);
    char *slash = strrchr(base, '/');
    if (slash) {
        *slash = '\0';
    } else {
        snprintf(base, sizeof base, ".");
    }
    if (!join(parent, sizeof parent, base, "..")) {
        free(text);
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: path too long: '%s'", file);
    }
    const char *p = text, *end = (const char *)text + size;
    uint32_t before = out->n, line_no = 0;
    while (p < end && r == WEFT_OK) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        const char *le = nl ? nl : end;
        line_no++;
        char line[512];
        size_t len = (size_t)(le - p);
        const char *hash = memchr(p, '#', len);
        if (hash) {
            len = (size_t)(hash - p);
        }
        while (len && (p[len - 1] == ' ' || p[len - 1] == '\t' || p[len - 1] == '\r')) {
            len--;
        }
        while (len && (*p == ' ' || *p == '\t')) {
            p++, len--;
        }
        if (len >= sizeof line) {
            r = weft__fail(WEFT_ERROR_FORMAT, "quantize: %s:%u: line too long", file, line_no);
            break;
        }
        if (len) {
            memcpy(line, p, len);
            line[len] = '\0';
            char a[4096], b[4096];
            bool ja = join(a, sizeof a, base, line), jb = join(b, sizeof b, parent, line);
            const char *hit = ja && is_dir(a) ? a : (jb && is_dir(b) ? b : NULL);
            if (!hit) {
                r = weft__fail(WEFT_ERROR_IO, "quantize: %s:%u: no sequence folder '%s' next to the list or in its "
                                              "parent folder", file, line_no, line);
            } else if (!list_push(out, hit)) {
                r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory reading '%s'", file);
            }
        }
        p = nl ? nl + 1 : end;
    }
    free(text);
    if (r == WEFT_OK && out->n == before) {
        r = weft__fail(WEFT_ERROR_FORMAT, "quantize: split list '%s' names no sequences", file);
    }
    return r;
}

weft_result quant_seq_expand(const char *const *args, const char *split, char ***out, uint32_t *count)
{
    str_list l = {0};
    weft_result r = WEFT_OK;
    for (const char *const *a = args; a && *a && r == WEFT_OK; ++a) {
        struct stat st;
        if (stat(*a, &st) != 0) {
            r = weft__fail(WEFT_ERROR_IO, "quantize: calibration input '%s' does not exist", *a);
        } else if (S_ISREG(st.st_mode)) {
            r = expand_list(*a, &l);
        } else if (!S_ISDIR(st.st_mode)) {
            r = weft__fail(WEFT_ERROR_IO, "quantize: calibration input '%s' is neither a folder nor a list", *a);
        } else if (is_file_in(*a, "meta.json") || is_file_in(*a, "cloth_pos.npy")) {
            if (!list_push(&l, *a)) {
                r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
            }
        } else {
            r = expand_folder(*a, split, &l);
        }
    }
    if (r != WEFT_OK) {
        quant_list_free(l.v, l.n);
        return r;
    }
    *out = l.v;
    *count = l.n;
    return WEFT_OK;
}
