/* safetensors reader. Every size read from the file is checked with 64-bit overflow-checked
 * arithmetic before it is used, and the header text is screened (UTF-8, NUL bytes, nesting
 * depth) before cJSON sees it, so no input can make the parser recurse deeply. */
#include "io/safetensors.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const struct {
    const char *name;
    size_t size;
} g_dtypes[WEFT_DTYPE_COUNT] = {
    [WEFT_DTYPE_F32] = {"F32", 4}, [WEFT_DTYPE_F16] = {"F16", 2}, [WEFT_DTYPE_BF16] = {"BF16", 2},
    [WEFT_DTYPE_I8] = {"I8", 1},   [WEFT_DTYPE_I32] = {"I32", 4}, [WEFT_DTYPE_U8] = {"U8", 1},
};

size_t weft__dtype_size(weft_dtype dtype)
{
    return (unsigned)dtype < WEFT_DTYPE_COUNT ? g_dtypes[dtype].size : 0;
}

const char *weft__dtype_name(weft_dtype dtype)
{
    return (unsigned)dtype < WEFT_DTYPE_COUNT ? g_dtypes[dtype].name : "?";
}

bool weft__dtype_parse(const char *name, weft_dtype *out)
{
    for (int i = 0; i < WEFT_DTYPE_COUNT; ++i) {
        if (strcmp(name, g_dtypes[i].name) == 0) {
            *out = (weft_dtype)i;
            return true;
        }
    }
    return false;
}

weft_result weft__st_header_length(const uint8_t *prefix, uint64_t file_size, uint64_t *out_header_size)
{
    if (file_size < 8) {
        return weft__fail(WEFT_ERROR_FILE_TRUNCATED,
                          "safetensors: file has %llu bytes, fewer than the 8-byte header length field",
                          (unsigned long long)file_size);
    }
    uint64_t n = 0;
    for (int i = 7; i >= 0; --i) {
        n = (n << 8) | prefix[i];
    }
    if (n > WEFT_ST_MAX_HEADER) {
        return weft__fail(WEFT_ERROR_HEADER_TOO_LARGE, "safetensors: header length %llu exceeds the %u-byte cap",
                          (unsigned long long)n, WEFT_ST_MAX_HEADER);
    }
    if (n > file_size - 8) {
        return weft__fail(WEFT_ERROR_HEADER_TOO_LARGE,
                          "safetensors: header length %llu exceeds the %llu bytes after the length field",
                          (unsigned long long)n, (unsigned long long)(file_size - 8));
    }
    *out_header_size = n;
    return WEFT_OK;
}

weft_result weft__json_screen(const uint8_t *s, size_t n, weft_result code, const char *what)
{
    if (n == 0 || s[0] != '{') {
        return weft__fail(code, "%s does not start with '{'", what);
    }
    unsigned depth = 0;
    bool in_string = false;
    size_t i = 0;
    while (i < n) {
        uint8_t c = s[i];
        if (c == 0) {
            return weft__fail(code, "%s has a NUL byte at offset %zu", what, i);
        }
        if (c >= 0x80) {
            /* Multi-byte UTF-8: reject overlong forms, surrogates and code points over U+10FFFF. */
            size_t len;
            uint32_t cp, min;
            if ((c & 0xE0) == 0xC0) {
                len = 2, cp = c & 0x1Fu, min = 0x80;
            } else if ((c & 0xF0) == 0xE0) {
                len = 3, cp = c & 0x0Fu, min = 0x800;
            } else if ((c & 0xF8) == 0xF0) {
                len = 4, cp = c & 0x07u, min = 0x10000;
            } else {
                return weft__fail(code, "%s is not UTF-8 (byte %zu)", what, i);
            }
            if (len > n - i) {
                return weft__fail(code, "%s ends inside a UTF-8 sequence", what);
            }
            for (size_t k = 1; k < len; ++k) {
                if ((s[i + k] & 0xC0) != 0x80) {
                    return weft__fail(code, "%s is not UTF-8 (byte %zu)", what, i + k);
                }
                cp = (cp << 6) | (s[i + k] & 0x3Fu);
            }
            if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) {
                return weft__fail(code, "%s is not UTF-8 (byte %zu)", what, i);
            }
            i += len;
            continue;
        }
        if (in_string) {
            if (c == '\\') {
                if (i + 1 < n && s[i + 1] == 'u' && n - i >= 6 && memcmp(s + i + 2, "0000", 4) == 0) {
                    return weft__fail(code, "%s has an escaped NUL (\\u0000) at offset %zu", what, i);
                }
                /* The escaped character cannot end the string; a non-ASCII one is left for the
                 * UTF-8 check (JSON refuses it as an escape anyway). */
                i += (i + 1 < n && s[i + 1] < 0x80) ? 2 : 1;
                continue;
            }
            if (c == '"') {
                in_string = false;
            }
        } else if (c == '"') {
            in_string = true;
        } else if (c == '{' || c == '[') {
            if (++depth > WEFT_ST_MAX_DEPTH) {
                return weft__fail(code, "%s nests deeper than %u levels", what, WEFT_ST_MAX_DEPTH);
            }
        } else if ((c == '}' || c == ']') && depth > 0) {
            depth--;
        }
        i++;
    }
    return WEFT_OK;
}

/* A JSON number that is an exact non-negative integer. "3.0" counts as 3; 3.5, -1, -0 and
 * anything at or above 2^53 (where doubles stop being exact) do not. */
static bool json_uint(const cJSON *v, uint64_t *out)
{
    if (!cJSON_IsNumber(v)) {
        return false;
    }
    double d = v->valuedouble;
    if (!(d >= 0.0) || signbit(d) || d >= WEFT_ST_MAX_EXACT || d != (double)(uint64_t)d) {
        return false;
    }
    *out = (uint64_t)d;
    return true;
}

static void format_shape(const weft_st_entry *e, char *buf, size_t cap)
{
    size_t len = (size_t)snprintf(buf, cap, "[");
    for (uint32_t d = 0; d < e->rank && len < cap; ++d) {
        len += (size_t)snprintf(buf + len, cap - len, d ? ", %llu" : "%llu", (unsigned long long)e->shape[d]);
    }
    if (len < cap) {
        snprintf(buf + len, cap - len, "]");
    }
}

static weft_result parse_entry(const cJSON *item, weft_st_entry *e)
{
    const char *name = item->string;
    if (!cJSON_IsObject(item)) {
        return weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: tensor '%s': entry is not a JSON object", name);
    }
    const cJSON *dtype = NULL, *shape = NULL, *offsets = NULL;
    for (const cJSON *f = item->child; f; f = f->next) {
        const cJSON **slot = strcmp(f->string, "dtype") == 0          ? &dtype
                             : strcmp(f->string, "shape") == 0        ? &shape
                             : strcmp(f->string, "data_offsets") == 0 ? &offsets
                                                                      : NULL;
        if (!slot) {
            return weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: tensor '%s': unknown field '%s'", name,
                              f->string);
        }
        if (*slot) {
            return weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors: tensor '%s': field '%s' appears twice", name,
                              f->string);
        }
        *slot = f;
    }

    if (!dtype) {
        return weft__fail(WEFT_ERROR_UNKNOWN_DTYPE, "safetensors: tensor '%s': missing 'dtype'", name);
    }
    if (!cJSON_IsString(dtype)) {
        return weft__fail(WEFT_ERROR_UNKNOWN_DTYPE, "safetensors: tensor '%s': 'dtype' is not a string", name);
    }
    if (!weft__dtype_parse(dtype->valuestring, &e->dtype)) {
        return weft__fail(WEFT_ERROR_UNKNOWN_DTYPE,
                          "safetensors: tensor '%s': dtype '%.32s' is not one of F32, F16, BF16, I8, I32, U8", name,
                          dtype->valuestring);
    }

    if (!shape) {
        return weft__fail(WEFT_ERROR_BAD_SHAPE, "safetensors: tensor '%s': missing 'shape'", name);
    }
    if (!cJSON_IsArray(shape)) {
        return weft__fail(WEFT_ERROR_BAD_SHAPE, "safetensors: tensor '%s': 'shape' is not a list", name);
    }
    e->rank = 0;
    e->count = 1;
    for (const cJSON *d = shape->child; d; d = d->next) {
        if (e->rank == WEFT_ST_MAX_RANK) {
            return weft__fail(WEFT_ERROR_BAD_SHAPE, "safetensors: tensor '%s': more than %u dimensions", name,
                              WEFT_ST_MAX_RANK);
        }
        uint64_t v;
        if (!json_uint(d, &v)) {
            return weft__fail(WEFT_ERROR_BAD_SHAPE,
                              "safetensors: tensor '%s': shape[%u] is not an integer in [0, 2^53)", name, e->rank);
        }
        e->shape[e->rank++] = v;
    }
    char shape_text[200];
    format_shape(e, shape_text, sizeof shape_text);
    for (uint32_t d = 0; d < e->rank; ++d) {
        if (!weft__mul_u64(e->count, e->shape[d], &e->count)) {
            return weft__fail(WEFT_ERROR_SIZE_OVERFLOW,
                              "safetensors: tensor '%s': element count of shape %s overflows 64 bits", name,
                              shape_text);
        }
    }
    uint64_t bytes;
    if (!weft__mul_u64(e->count, weft__dtype_size(e->dtype), &bytes)) {
        return weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "safetensors: tensor '%s': byte size of %s %s overflows 64 bits",
                          name, weft__dtype_name(e->dtype), shape_text);
    }

    if (!offsets) {
        return weft__fail(WEFT_ERROR_BAD_OFFSETS, "safetensors: tensor '%s': missing 'data_offsets'", name);
    }
    if (!cJSON_IsArray(offsets) || cJSON_GetArraySize(offsets) != 2 || !json_uint(offsets->child, &e->begin) ||
        !json_uint(offsets->child->next, &e->end)) {
        return weft__fail(WEFT_ERROR_BAD_OFFSETS,
                          "safetensors: tensor '%s': 'data_offsets' is not a list of two integers in [0, 2^53)", name);
    }
    if (e->end < e->begin) {
        return weft__fail(WEFT_ERROR_BAD_OFFSETS, "safetensors: tensor '%s': data_offsets [%llu, %llu] are reversed",
                          name, (unsigned long long)e->begin, (unsigned long long)e->end);
    }
    if (e->end - e->begin != bytes) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH,
                          "safetensors: tensor '%s': data_offsets span %llu bytes but %s %s needs %llu", name,
                          (unsigned long long)(e->end - e->begin), weft__dtype_name(e->dtype), shape_text,
                          (unsigned long long)bytes);
    }
    return WEFT_OK;
}

static int cmp_str_ptr(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

typedef struct parse_item {
    const cJSON *json;
    weft_st_entry entry;
} parse_item;

static int cmp_item_offset(const void *a, const void *b)
{
    const weft_st_entry *x = &((const parse_item *)a)->entry, *y = &((const parse_item *)b)->entry;
    if (x->begin != y->begin) {
        return x->begin < y->begin ? -1 : 1;
    }
    if (x->end != y->end) {
        return x->end < y->end ? -1 : 1;
    }
    return strcmp(x->name, y->name);
}

/* The tensors must tile [0, data_size) exactly, in offset order. An entry past the end of a
 * layout that is otherwise contiguous means the file was cut short; past the end of a broken
 * layout it means the offsets themselves are wrong. */
static weft_result check_layout(const parse_item *items, uint32_t n, uint64_t data_size)
{
    uint32_t gap = n;
    uint64_t pos = 0;
    for (uint32_t i = 0; i < n; ++i) {
        if (items[i].entry.begin != pos) {
            gap = i;
            break;
        }
        pos = items[i].entry.end;
    }
    for (uint32_t i = 0; i < n; ++i) {
        const weft_st_entry *e = &items[i].entry;
        if (e->end > data_size) {
            if (gap == n) {
                return weft__fail(WEFT_ERROR_FILE_TRUNCATED,
                                  "safetensors: tensor '%s' ends at data byte %llu but the file holds only %llu "
                                  "data bytes",
                                  e->name, (unsigned long long)e->end, (unsigned long long)data_size);
            }
            return weft__fail(WEFT_ERROR_BAD_OFFSETS,
                              "safetensors: tensor '%s': data_offsets [%llu, %llu] lie outside the %llu-byte data "
                              "section",
                              e->name, (unsigned long long)e->begin, (unsigned long long)e->end,
                              (unsigned long long)data_size);
        }
    }
    if (gap < n) {
        const weft_st_entry *e = &items[gap].entry;
        if (e->begin < pos) {
            return weft__fail(WEFT_ERROR_OVERLAP,
                              "safetensors: tensor '%s' [%llu, %llu] overlaps tensor '%s' which ends at %llu", e->name,
                              (unsigned long long)e->begin, (unsigned long long)e->end, items[gap - 1].entry.name,
                              (unsigned long long)pos);
        }
        return weft__fail(WEFT_ERROR_OVERLAP,
                          "safetensors: data bytes [%llu, %llu) before tensor '%s' belong to no tensor (hole)",
                          (unsigned long long)pos, (unsigned long long)e->begin, e->name);
    }
    if (pos != data_size) {
        return weft__fail(WEFT_ERROR_OVERLAP, "safetensors: %llu trailing bytes after the last tensor%s%s%s",
                          (unsigned long long)(data_size - pos), n ? " ('" : "", n ? items[n - 1].entry.name : "",
                          n ? "')" : "");
    }
    return WEFT_OK;
}

static void *alloc_array(const weft_context *ctx, size_t count, size_t elem, size_t *out_bytes)
{
    *out_bytes = 0;
    if (count == 0) {
        return NULL;
    }
    if (count > SIZE_MAX / elem) {
        weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "safetensors: array of %zu entries overflows", count);
        return NULL;
    }
    *out_bytes = count * elem;
    return weft__alloc(ctx, *out_bytes);
}

static bool is_json_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

/* Validates the parsed tree and builds the header. Fails without touching *out. */
static weft_result build_header(const weft_context *ctx, const cJSON *root, uint64_t data_size, weft_st_header *out)
{
    const cJSON *metadata = NULL;
    uint32_t tensor_count = 0, meta_count = 0;
    size_t strings_size = 0; /* bounded by the header size, so these sums cannot overflow */
    for (const cJSON *c = root->child; c; c = c->next) {
        if (strcmp(c->string, "__metadata__") == 0) {
            if (metadata) {
                return weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors: '__metadata__' appears twice");
            }
            if (!cJSON_IsObject(c)) {
                return weft__fail(WEFT_ERROR_BAD_METADATA, "safetensors: '__metadata__' is not a JSON object");
            }
            metadata = c;
            for (const cJSON *m = c->child; m; m = m->next) {
                if (!cJSON_IsString(m)) {
                    return weft__fail(WEFT_ERROR_BAD_METADATA, "safetensors: metadata key '%s': value is not a string",
                                      m->string);
                }
                meta_count++;
                strings_size += strlen(m->string) + 1 + strlen(m->valuestring) + 1;
            }
        } else {
            tensor_count++;
            strings_size += strlen(c->string) + 1;
        }
    }

    weft_result r = WEFT_OK;
    size_t items_bytes, names_bytes, entries_bytes, meta_bytes, keys_bytes;
    parse_item *items = alloc_array(ctx, tensor_count, sizeof *items, &items_bytes);
    const char **names = alloc_array(ctx, tensor_count, sizeof *names, &names_bytes);
    weft_st_entry *entries = alloc_array(ctx, tensor_count, sizeof *entries, &entries_bytes);
    weft_st_meta *meta = alloc_array(ctx, meta_count, sizeof *meta, &meta_bytes);
    const char **keys = alloc_array(ctx, meta_count, sizeof *keys, &keys_bytes);
    char *strings = strings_size ? weft__alloc(ctx, strings_size) : NULL;
    if ((tensor_count && (!items || !names || !entries)) || (meta_count && (!meta || !keys)) ||
        (strings_size && !strings)) {
        r = WEFT_ERROR_OUT_OF_MEMORY; /* weft__alloc has set the message */
        goto done;
    }

    uint32_t t = 0;
    for (const cJSON *c = root->child; c; c = c->next) {
        if (c == metadata) {
            continue;
        }
        if (c->string[0] == '\0') {
            r = weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: a tensor has an empty name");
            goto done;
        }
        items[t].json = c;
        items[t].entry.name = c->string;
        names[t] = c->string;
        r = parse_entry(c, &items[t].entry);
        if (r != WEFT_OK) {
            goto done;
        }
        t++;
    }
    if (tensor_count > 1) {
        qsort(names, tensor_count, sizeof *names, cmp_str_ptr);
        for (uint32_t i = 1; i < tensor_count; ++i) {
            if (strcmp(names[i - 1], names[i]) == 0) {
                r = weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors: tensor name '%s' appears twice", names[i]);
                goto done;
            }
        }
    }
    if (metadata && meta_count > 1) {
        uint32_t k = 0;
        for (const cJSON *m = metadata->child; m; m = m->next) {
            keys[k++] = m->string;
        }
        qsort(keys, meta_count, sizeof *keys, cmp_str_ptr);
        for (uint32_t i = 1; i < meta_count; ++i) {
            if (strcmp(keys[i - 1], keys[i]) == 0) {
                r = weft__fail(WEFT_ERROR_DUPLICATE_NAME, "safetensors: metadata key '%s' appears twice", keys[i]);
                goto done;
            }
        }
    }
    if (tensor_count > 1) {
        qsort(items, tensor_count, sizeof *items, cmp_item_offset);
    }
    r = check_layout(items, tensor_count, data_size);
    if (r != WEFT_OK) {
        goto done;
    }

    /* Valid: copy names and metadata out of the cJSON tree. */
    size_t pos = 0;
    for (uint32_t i = 0; i < tensor_count; ++i) {
        entries[i] = items[i].entry;
        size_t len = strlen(items[i].json->string) + 1;
        memcpy(strings + pos, items[i].json->string, len);
        entries[i].name = strings + pos;
        pos += len;
    }
    uint32_t k = 0;
    if (metadata) {
        for (const cJSON *m = metadata->child; m; m = m->next, ++k) {
            size_t klen = strlen(m->string) + 1, vlen = strlen(m->valuestring) + 1;
            memcpy(strings + pos, m->string, klen);
            meta[k].key = strings + pos;
            pos += klen;
            memcpy(strings + pos, m->valuestring, vlen);
            meta[k].value = strings + pos;
            pos += vlen;
        }
    }
    *out = (weft_st_header){
        .entries = entries,
        .entry_count = tensor_count,
        .meta = meta,
        .meta_count = meta_count,
        .strings = strings,
        .strings_size = strings_size,
        .data_size = data_size,
    };
    entries = NULL;
    meta = NULL;
    strings = NULL;

done:
    weft__free(ctx, items, items_bytes);
    weft__free(ctx, names, names_bytes);
    weft__free(ctx, keys, keys_bytes);
    weft__free(ctx, entries, entries_bytes);
    weft__free(ctx, meta, meta_bytes);
    weft__free(ctx, strings, strings_size);
    return r;
}

weft_result weft__st_parse_header(const weft_context *ctx, const char *json, size_t size, uint64_t data_size,
                                  weft_st_header *out)
{
    if (!ctx || (!json && size) || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__st_parse_header: NULL argument");
    }
    if (size > WEFT_ST_MAX_HEADER) {
        return weft__fail(WEFT_ERROR_HEADER_TOO_LARGE, "safetensors: header length %zu exceeds the %u-byte cap", size,
                          WEFT_ST_MAX_HEADER);
    }
    weft_result r = weft__json_screen((const uint8_t *)json, size, WEFT_ERROR_HEADER_JSON, "safetensors: header");
    if (r != WEFT_OK) {
        return r;
    }
    /* cJSON wants a terminated string; the copy also keeps it from reading past `size`. */
    char *text = weft__alloc(ctx, size + 1);
    if (!text) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(text, json, size);
    text[size] = '\0';
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 0);
    if (!root) {
        size_t at = end && end >= text && end <= text + size ? (size_t)(end - text) : 0;
        r = weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: header is not valid JSON (error near byte %zu)", at);
    } else {
        /* The header may be right-padded with whitespace, nothing else. */
        for (const char *p = end; p < text + size; ++p) {
            if (!is_json_space(*p)) {
                r = weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: unexpected bytes after the header JSON at byte %zu",
                               (size_t)(p - text));
                break;
            }
        }
        if (r == WEFT_OK && !cJSON_IsObject(root)) {
            r = weft__fail(WEFT_ERROR_HEADER_JSON, "safetensors: header is not a JSON object");
        }
        if (r == WEFT_OK) {
            r = build_header(ctx, root, data_size, out);
        }
        cJSON_Delete(root);
    }
    weft__free(ctx, text, size + 1);
    return r;
}

void weft__st_header_free(const weft_context *ctx, weft_st_header *header)
{
    if (!header) {
        return;
    }
    weft__free(ctx, header->entries, (size_t)header->entry_count * sizeof *header->entries);
    weft__free(ctx, header->meta, (size_t)header->meta_count * sizeof *header->meta);
    weft__free(ctx, header->strings, header->strings_size);
    *header = (weft_st_header){0};
}

weft_result weft__st_parse_memory(const weft_context *ctx, const void *bytes, size_t size, weft_st_header *out,
                                  const uint8_t **out_data)
{
    if (!ctx || (!bytes && size) || !out || !out_data) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__st_parse_memory: NULL argument");
    }
    const uint8_t *b = bytes;
    uint64_t n = 0;
    weft_result r = weft__st_header_length(b, size, &n);
    if (r != WEFT_OK) {
        return r;
    }
    r = weft__st_parse_header(ctx, (const char *)b + 8, (size_t)n, size - 8 - n, out);
    if (r == WEFT_OK) {
        *out_data = b + 8 + n;
    }
    return r;
}
