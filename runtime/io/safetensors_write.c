/* safetensors writer. The header JSON is produced directly (two passes: measure, then write)
 * so integer fields are exact and the output is byte-for-byte deterministic. */
#include "io/safetensors.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct sink {
    char *buf;   /* NULL while measuring */
    size_t len;
} sink;

static void put(sink *s, const char *text, size_t n)
{
    if (s->buf) {
        memcpy(s->buf + s->len, text, n);
    }
    s->len += n;
}

static void put_str(sink *s, const char *text) { put(s, text, strlen(text)); }

static void put_u64(sink *s, uint64_t v)
{
    char tmp[24];
    int n = snprintf(tmp, sizeof tmp, "%llu", (unsigned long long)v);
    put(s, tmp, (size_t)n);
}

/* JSON string literal: quotes, backslashes and control characters escaped; UTF-8 passes. */
static void put_json_string(sink *s, const char *text)
{
    static const char hex[] = "0123456789abcdef";
    put(s, "\"", 1);
    for (const unsigned char *p = (const unsigned char *)text; *p; ++p) {
        if (*p == '"' || *p == '\\') {
            char esc[2] = {'\\', (char)*p};
            put(s, esc, 2);
        } else if (*p < 0x20) {
            char esc[6] = {'\\', 'u', '0', '0', hex[*p >> 4], hex[*p & 15]};
            put(s, esc, 6);
        } else {
            put(s, (const char *)p, 1);
        }
    }
    put(s, "\"", 1);
}

static bool valid_utf8(const char *text)
{
    const unsigned char *s = (const unsigned char *)text;
    while (*s) {
        unsigned char c = *s;
        size_t len;
        uint32_t cp, min;
        if (c < 0x80) {
            s++;
            continue;
        } else if ((c & 0xE0) == 0xC0) {
            len = 2, cp = c & 0x1Fu, min = 0x80;
        } else if ((c & 0xF0) == 0xE0) {
            len = 3, cp = c & 0x0Fu, min = 0x800;
        } else if ((c & 0xF8) == 0xF0) {
            len = 4, cp = c & 0x07u, min = 0x10000;
        } else {
            return false;
        }
        for (size_t k = 1; k < len; ++k) {
            if ((s[k] & 0xC0) != 0x80) {
                return false; /* also stops at the terminator */
            }
            cp = (cp << 6) | (s[k] & 0x3Fu);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) {
            return false;
        }
        s += len;
    }
    return true;
}

typedef struct plan_item {
    const weft_st_tensor_in *t;
    uint64_t bytes, begin;
} plan_item;

static int cmp_plan(const void *a, const void *b)
{
    const weft_st_tensor_in *x = ((const plan_item *)a)->t, *y = ((const plan_item *)b)->t;
    size_t sx = weft__dtype_size(x->dtype), sy = weft__dtype_size(y->dtype);
    if (sx != sy) {
        return sx > sy ? -1 : 1;
    }
    return strcmp(x->name, y->name);
}

static int cmp_name(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Checks every input and orders the tensors. On success *out_plan (count items) must be freed
 * by the caller with weft__free(ctx, plan, count * sizeof *plan). */
static weft_result make_plan(const weft_context *ctx, const weft_st_tensor_in *tensors, uint32_t count,
                             const weft_st_meta *meta, uint32_t meta_count, plan_item **out_plan,
                             uint64_t *out_data_size)
{
    if (!ctx || (count && !tensors) || (meta_count && !meta)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "safetensors writer: NULL tensors or metadata array");
    }
    size_t names_count = count > meta_count ? count : meta_count;
    const char **names = names_count ? weft__alloc(ctx, names_count * sizeof *names) : NULL;
    plan_item *plan = count ? weft__alloc(ctx, (size_t)count * sizeof *plan) : NULL;
    if ((names_count && !names) || (count && !plan)) {
        weft__free(ctx, names, names_count * sizeof *names);
        weft__free(ctx, plan, (size_t)count * sizeof *plan);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    weft_result r = WEFT_OK;
    for (uint32_t i = 0; i < count && r == WEFT_OK; ++i) {
        const weft_st_tensor_in *t = &tensors[i];
        uint64_t elems = 1, bytes;
        if (!t->name || !t->name[0] || strcmp(t->name, "__metadata__") == 0 || !valid_utf8(t->name)) {
            r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                           "safetensors writer: tensor %u: name is NULL, empty, '__metadata__' or not UTF-8", i);
        } else if ((unsigned)t->dtype >= WEFT_DTYPE_COUNT) {
            r = weft__fail(WEFT_ERROR_UNKNOWN_DTYPE, "safetensors writer: tensor '%s': invalid dtype %d", t->name,
                           (int)t->dtype);
        } else if (t->rank > WEFT_ST_MAX_RANK || (t->rank && !t->shape)) {
            r = weft__fail(WEFT_ERROR_BAD_SHAPE, "safetensors writer: tensor '%s': rank %u (max %u) or NULL shape",
                           t->name, t->rank, WEFT_ST_MAX_RANK);
        }
        for (uint32_t d = 0; d < t->rank && r == WEFT_OK; ++d) {
            if ((double)t->shape[d] >= WEFT_ST_MAX_EXACT || !weft__mul_u64(elems, t->shape[d], &elems)) {
                r = weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "safetensors writer: tensor '%s': shape too large", t->name);
            }
        }
        if (r == WEFT_OK && !weft__mul_u64(elems, weft__dtype_size(t->dtype), &bytes)) {
            r = weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "safetensors writer: tensor '%s': byte size overflows", t->name);
        }
        if (r == WEFT_OK && bytes && !t->data) {
            r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "safetensors writer: tensor '%s': data is NULL", t->name);
        }
        if (r == WEFT_OK) {
            plan[i] = (plan_item){.t = t, .bytes = bytes};
            names[i] = t->name;
        }
    }
    if (r == WEFT_OK && count > 1) {
        qsort(names, count, sizeof *names, cmp_name);
        for (uint32_t i = 1; i < count && r == WEFT_OK; ++i) {
            if (strcmp(names[i - 1], names[i]) == 0) {
                r = weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors writer: tensor name '%s' appears twice",
                               names[i]);
            }
        }
    }
    for (uint32_t i = 0; i < meta_count && r == WEFT_OK; ++i) {
        if (!meta[i].key || !meta[i].value || !valid_utf8(meta[i].key) || !valid_utf8(meta[i].value)) {
            r = weft__fail(WEFT_ERROR_BAD_METADATA, "safetensors writer: metadata entry %u: key or value NULL or not "
                                                    "UTF-8", i);
        } else {
            names[i] = meta[i].key;
        }
    }
    if (r == WEFT_OK && meta_count > 1) {
        qsort(names, meta_count, sizeof *names, cmp_name);
        for (uint32_t i = 1; i < meta_count && r == WEFT_OK; ++i) {
            if (strcmp(names[i - 1], names[i]) == 0) {
                r = weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors writer: metadata key '%s' appears twice",
                               names[i]);
            }
        }
    }
    weft__free(ctx, names, names_count * sizeof *names);
    uint64_t pos = 0;
    if (r == WEFT_OK) {
        if (count > 1) {
            qsort(plan, count, sizeof *plan, cmp_plan);
        }
        for (uint32_t i = 0; i < count && r == WEFT_OK; ++i) {
            plan[i].begin = pos;
            if (!weft__add_u64(pos, plan[i].bytes, &pos)) {
                r = weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "safetensors writer: total data size overflows");
            }
        }
    }
    if (r != WEFT_OK) {
        weft__free(ctx, plan, (size_t)count * sizeof *plan);
        return r;
    }
    *out_plan = plan;
    *out_data_size = pos;
    return WEFT_OK;
}

/* Emits the header JSON (without the length field or padding). */
static void emit_header(sink *s, const plan_item *plan, uint32_t count, const weft_st_meta *meta, uint32_t meta_count)
{
    put(s, "{", 1);
    bool first = true;
    if (meta_count) {
        put_str(s, "\"__metadata__\":{");
        for (uint32_t i = 0; i < meta_count; ++i) {
            if (i) {
                put(s, ",", 1);
            }
            put_json_string(s, meta[i].key);
            put(s, ":", 1);
            put_json_string(s, meta[i].value);
        }
        put(s, "}", 1);
        first = false;
    }
    for (uint32_t i = 0; i < count; ++i) {
        const weft_st_tensor_in *t = plan[i].t;
        if (!first) {
            put(s, ",", 1);
        }
        first = false;
        put_json_string(s, t->name);
        put_str(s, ":{\"dtype\":\"");
        put_str(s, weft__dtype_name(t->dtype));
        put_str(s, "\",\"shape\":[");
        for (uint32_t d = 0; d < t->rank; ++d) {
            if (d) {
                put(s, ",", 1);
            }
            put_u64(s, t->shape[d]);
        }
        put_str(s, "],\"data_offsets\":[");
        put_u64(s, plan[i].begin);
        put(s, ",", 1);
        put_u64(s, plan[i].begin + plan[i].bytes);
        put_str(s, "]}");
    }
    put(s, "}", 1);
}

/* Builds "u64 N + header + padding" in one buffer; N + 8 is a multiple of 8. */
static weft_result build_prefix(const weft_context *ctx, const plan_item *plan, uint32_t count,
                                const weft_st_meta *meta, uint32_t meta_count, uint64_t data_size, size_t extra,
                                char **out_buf, size_t *out_prefix, size_t *out_alloc)
{
    sink measure = {0};
    emit_header(&measure, plan, count, meta, meta_count);
    size_t n = (measure.len + 7) & ~(size_t)7;
    if (n > WEFT_ST_MAX_HEADER) {
        return weft__fail(WEFT_ERROR_HEADER_TOO_LARGE, "safetensors writer: header of %zu bytes exceeds the cap",
                          measure.len);
    }
    uint64_t total;
    if (!weft__add_u64(8 + n, extra ? data_size : 0, &total) || total > SIZE_MAX) {
        return weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "safetensors writer: file size overflows");
    }
    char *buf = weft__alloc(ctx, (size_t)total);
    if (!buf) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (int i = 0; i < 8; ++i) {
        buf[i] = (char)(uint8_t)((uint64_t)n >> (8 * i));
    }
    sink out = {.buf = buf + 8};
    emit_header(&out, plan, count, meta, meta_count);
    memset(buf + 8 + out.len, ' ', n - out.len);
    *out_buf = buf;
    *out_prefix = 8 + n;
    *out_alloc = (size_t)total;
    return WEFT_OK;
}

weft_result weft__st_write_memory(const weft_context *ctx, const weft_st_tensor_in *tensors, uint32_t tensor_count,
                                  const weft_st_meta *meta, uint32_t meta_count, void **out_bytes, size_t *out_size)
{
    if (!out_bytes || !out_size) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__st_write_memory: NULL output");
    }
    plan_item *plan = NULL;
    uint64_t data_size = 0;
    weft_result r = make_plan(ctx, tensors, tensor_count, meta, meta_count, &plan, &data_size);
    if (r != WEFT_OK) {
        return r;
    }
    char *buf = NULL;
    size_t prefix = 0, total = 0;
    r = build_prefix(ctx, plan, tensor_count, meta, meta_count, data_size, 1, &buf, &prefix, &total);
    if (r == WEFT_OK) {
        for (uint32_t i = 0; i < tensor_count; ++i) {
            if (plan[i].bytes) {
                memcpy(buf + prefix + plan[i].begin, plan[i].t->data, (size_t)plan[i].bytes);
            }
        }
        *out_bytes = buf;
        *out_size = total;
    }
    weft__free(ctx, plan, (size_t)tensor_count * sizeof *plan);
    return r;
}

weft_result weft__st_write_file(const weft_context *ctx, const char *path, const weft_st_tensor_in *tensors,
                                uint32_t tensor_count, const weft_st_meta *meta, uint32_t meta_count)
{
    if (!path || !path[0]) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__st_write_file: empty path");
    }
    plan_item *plan = NULL;
    uint64_t data_size = 0;
    weft_result r = make_plan(ctx, tensors, tensor_count, meta, meta_count, &plan, &data_size);
    if (r != WEFT_OK) {
        return r;
    }
    char *buf = NULL;
    size_t prefix = 0, alloc = 0;
    r = build_prefix(ctx, plan, tensor_count, meta, meta_count, data_size, 0, &buf, &prefix, &alloc);
    if (r != WEFT_OK) {
        weft__free(ctx, plan, (size_t)tensor_count * sizeof *plan);
        return r;
    }
    size_t tmp_len = strlen(path) + sizeof ".tmp";
    char *tmp = weft__alloc(ctx, tmp_len);
    if (!tmp) {
        r = WEFT_ERROR_OUT_OF_MEMORY;
    } else {
        snprintf(tmp, tmp_len, "%s.tmp", path);
        FILE *f = fopen(tmp, "wb");
        if (!f) {
            r = weft__fail(WEFT_ERROR_IO, "safetensors writer: cannot create '%s'", tmp);
        } else {
            bool ok = fwrite(buf, 1, prefix, f) == prefix;
            for (uint32_t i = 0; i < tensor_count && ok; ++i) {
                size_t n = (size_t)plan[i].bytes;
                ok = n == 0 || fwrite(plan[i].t->data, 1, n, f) == n;
            }
            ok = (fclose(f) == 0) && ok;
            if (!ok || rename(tmp, path) != 0) {
                remove(tmp);
                r = weft__fail(WEFT_ERROR_IO, "safetensors writer: writing '%s' failed", path);
            }
        }
        weft__free(ctx, tmp, tmp_len);
    }
    weft__free(ctx, buf, alloc);
    weft__free(ctx, plan, (size_t)tensor_count * sizeof *plan);
    return r;
}
