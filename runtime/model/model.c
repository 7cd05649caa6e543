/* Model loading: the safetensors header is validated completely (runtime/io) before any tensor
 * byte is read; tensors are then copied into one allocation at 64-byte aligned offsets, checked
 * for non-finite values and the quantised-weight conventions, and the metadata "config" JSON is
 * parsed into a sorted key table. Any failure frees everything and leaves *out_model untouched. */
#define _POSIX_C_SOURCE 200809L /* fileno, fstat */
#include "model/model.h"
#include "model/transformer.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Architectures weft has forward passes for. Files naming one of them must carry a config,
 * and the forward pass's `validate` checks every tensor against it at load. Any other
 * architecture string (or none) loads as a generic weights file, which garment creation with
 * WEFT_METHOD_MODEL rejects. */
static const weft__architecture g_architectures[] = {
    {WEFT_CT_ARCHITECTURE, true, weft__ct_validate},
    {"fnopt", true, NULL}, /* FNOpt weights: checked by runtime/fnopt when an optimizer is built */
};

const weft__architecture *weft__architecture_find(const char *name)
{
    if (!name) {
        return NULL;
    }
    for (size_t i = 0; i < sizeof g_architectures / sizeof g_architectures[0]; ++i) {
        if (strcmp(name, g_architectures[i].name) == 0) {
            return &g_architectures[i];
        }
    }
    return NULL;
}

/* ---------------------------------------------------------------------------------------- */
/* Lookups                                                                                    */

static int cmp_tensor_name(const void *a, const void *b)
{
    return strcmp(((const weft_tensor *)a)->name, ((const weft_tensor *)b)->name);
}

static int cmp_key_tensor(const void *key, const void *elem)
{
    return strcmp((const char *)key, ((const weft_tensor *)elem)->name);
}

static int cmp_config_key(const void *a, const void *b)
{
    return strcmp(((const weft_config_value *)a)->key, ((const weft_config_value *)b)->key);
}

static int cmp_key_config(const void *key, const void *elem)
{
    return strcmp((const char *)key, ((const weft_config_value *)elem)->key);
}

const weft_tensor *weft__model_find(const weft_model *model, const char *name)
{
    if (!model || !name || model->tensor_count == 0) {
        return NULL;
    }
    return bsearch(name, model->tensors, model->tensor_count, sizeof *model->tensors, cmp_key_tensor);
}

static void format_dims(char *buf, size_t cap, uint32_t rank, const uint64_t *dims)
{
    size_t len = (size_t)snprintf(buf, cap, "[");
    for (uint32_t d = 0; d < rank && len < cap; ++d) {
        if (dims[d] == WEFT_DIM_ANY) {
            len += (size_t)snprintf(buf + len, cap - len, d ? ", *" : "*");
        } else {
            len += (size_t)snprintf(buf + len, cap - len, d ? ", %llu" : "%llu", (unsigned long long)dims[d]);
        }
    }
    if (len < cap) {
        snprintf(buf + len, cap - len, "]");
    }
}

weft_result weft__model_require(const weft_model *model, const char *name, weft_dtype dtype, uint32_t rank,
                                const uint64_t *dims, const weft_tensor **out)
{
    if (!model || !name || (rank && !dims) || rank > WEFT_ST_MAX_RANK) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__model_require: NULL argument or rank %u over %u", rank,
                          WEFT_ST_MAX_RANK);
    }
    const weft_tensor *t = weft__model_find(model, name);
    if (!t) {
        return weft__fail(WEFT_ERROR_MISSING_TENSOR, "model: tensor '%s' is missing", name);
    }
    if (t->dtype != dtype) {
        return weft__fail(WEFT_ERROR_TENSOR_DTYPE, "model: tensor '%s' is %s, expected %s", name,
                          weft__dtype_name(t->dtype), weft__dtype_name(dtype));
    }
    bool match = t->rank == rank;
    for (uint32_t d = 0; d < rank && match; ++d) {
        match = dims[d] == WEFT_DIM_ANY || dims[d] == t->shape[d];
    }
    if (!match) {
        char want[160], have[160];
        format_dims(want, sizeof want, rank, dims);
        format_dims(have, sizeof have, t->rank, t->shape);
        return weft__fail(WEFT_ERROR_TENSOR_SHAPE, "model: tensor '%s' has shape %s, expected %s", name, have, want);
    }
    if (out) {
        *out = t;
    }
    return WEFT_OK;
}

const char *weft__model_metadata(const weft_model *model, const char *key)
{
    if (!model || !key) {
        return NULL;
    }
    for (uint32_t i = 0; i < model->meta_count; ++i) {
        if (strcmp(model->meta[i].key, key) == 0) {
            return model->meta[i].value;
        }
    }
    return NULL;
}

const weft_config_value *weft__model_config_find(const weft_model *model, const char *key)
{
    if (!model || !key || model->config_count == 0) {
        return NULL;
    }
    return bsearch(key, model->config, model->config_count, sizeof *model->config, cmp_key_config);
}

static weft_result config_get(const weft_model *model, const char *key, weft_config_kind kind, const char *what,
                              const weft_config_value **out)
{
    if (!model || !key) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "model config: NULL model or key");
    }
    const weft_config_value *v = weft__model_config_find(model, key);
    if (!v) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: key '%s' is missing", key);
    }
    if (v->kind != kind) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: key '%s' is not %s", key, what);
    }
    *out = v;
    return WEFT_OK;
}

weft_result weft__model_config_number(const weft_model *model, const char *key, double *out)
{
    const weft_config_value *v = NULL;
    weft_result r = config_get(model, key, WEFT_CONFIG_NUMBER, "a number", &v);
    if (r == WEFT_OK && out) {
        *out = v->number;
    }
    return r;
}

weft_result weft__model_config_int(const weft_model *model, const char *key, int64_t *out)
{
    const weft_config_value *v = NULL;
    weft_result r = config_get(model, key, WEFT_CONFIG_NUMBER, "a number", &v);
    if (r != WEFT_OK) {
        return r;
    }
    if (fabs(v->number) > 9007199254740992.0 || v->number != (double)(int64_t)v->number) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: key '%s' = %g is not an integer", key, v->number);
    }
    if (out) {
        *out = (int64_t)v->number;
    }
    return WEFT_OK;
}

weft_result weft__model_config_u32(const weft_model *model, const char *key, uint32_t min, uint32_t max,
                                   uint32_t *out)
{
    int64_t v = 0;
    weft_result r = weft__model_config_int(model, key, &v);
    if (r != WEFT_OK) {
        return r;
    }
    if (v < (int64_t)min || v > (int64_t)max) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: key '%s' = %lld is outside [%u, %u]", key,
                          (long long)v, min, max);
    }
    if (out) {
        *out = (uint32_t)v;
    }
    return WEFT_OK;
}

weft_result weft__model_config_bool(const weft_model *model, const char *key, bool *out)
{
    const weft_config_value *v = NULL;
    weft_result r = config_get(model, key, WEFT_CONFIG_BOOL, "true or false", &v);
    if (r == WEFT_OK && out) {
        *out = v->number != 0.0;
    }
    return r;
}

weft_result weft__model_config_string(const weft_model *model, const char *key, const char **out)
{
    const weft_config_value *v = NULL;
    weft_result r = config_get(model, key, WEFT_CONFIG_STRING, "a string", &v);
    if (r == WEFT_OK && out) {
        *out = v->string;
    }
    return r;
}

weft_result weft__model_config_array(const weft_model *model, const char *key, const double **out,
                                     uint32_t *out_count)
{
    const weft_config_value *v = NULL;
    weft_result r = config_get(model, key, WEFT_CONFIG_ARRAY, "a list of numbers", &v);
    if (r == WEFT_OK) {
        if (out) {
            *out = v->array;
        }
        if (out_count) {
            *out_count = v->array_count;
        }
    }
    return r;
}

/* ---------------------------------------------------------------------------------------- */
/* Public info                                                                                */

weft_model_info weft_model_get_info(const weft_model *model)
{
    if (!model) {
        return (weft_model_info){.name = "", .architecture = "", .precision = WEFT_PRECISION_FP32};
    }
    return model->info;
}

/* ---------------------------------------------------------------------------------------- */
/* Destruction                                                                                */

static void model_free(weft_model *m)
{
    const weft_context *ctx = m->ctx;
    weft__free(ctx, m->data, m->data_bytes);
    weft__free(ctx, m->tensors, (size_t)m->tensor_count * sizeof *m->tensors);
    weft__free(ctx, m->meta, (size_t)m->meta_count * sizeof *m->meta);
    weft__free(ctx, m->strings, m->strings_size);
    weft__free(ctx, m->config, (size_t)m->config_count * sizeof *m->config);
    weft__free(ctx, m->config_numbers, m->config_numbers_count * sizeof *m->config_numbers);
    weft__free(ctx, m->config_strings, m->config_strings_size);
    weft__free(ctx, m, sizeof *m);
}

void weft_model_destroy(weft_model *model)
{
    if (model) {
        model_free(model);
    }
}

/* ---------------------------------------------------------------------------------------- */
/* Config                                                                                     */

static int cmp_str_ptr(const void *a, const void *b)
{
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* Checks one config value; returns its kind and adds its storage needs. */
static weft_result config_check_value(const cJSON *v, weft_config_kind *kind, size_t *strings, size_t *numbers)
{
    const char *key = v->string;
    if (cJSON_IsNumber(v)) {
        if (!isfinite(v->valuedouble)) {
            return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: key '%s' is not a finite number", key);
        }
        *kind = WEFT_CONFIG_NUMBER;
    } else if (cJSON_IsBool(v)) {
        *kind = WEFT_CONFIG_BOOL;
    } else if (cJSON_IsString(v)) {
        *kind = WEFT_CONFIG_STRING;
        *strings += strlen(v->valuestring) + 1;
    } else if (cJSON_IsArray(v)) {
        for (const cJSON *e = v->child; e; e = e->next) {
            if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble)) {
                return weft__fail(WEFT_ERROR_BAD_METADATA,
                                  "model config: key '%s' is a list with an element that is not a finite number", key);
            }
            (*numbers)++;
        }
        *kind = WEFT_CONFIG_ARRAY;
    } else {
        return weft__fail(WEFT_ERROR_BAD_METADATA,
                          "model config: key '%s' must be a number, boolean, string or list of numbers", key);
    }
    *strings += strlen(key) + 1;
    return WEFT_OK;
}

static weft_result config_build(weft_model *m, const cJSON *root)
{
    const weft_context *ctx = m->ctx;
    uint32_t count = 0;
    size_t strings = 0, numbers = 0;
    for (const cJSON *v = root->child; v; v = v->next) {
        weft_config_kind kind;
        weft_result r = config_check_value(v, &kind, &strings, &numbers);
        if (r != WEFT_OK) {
            return r;
        }
        count++;
    }
    if (count == 0) {
        return WEFT_OK;
    }
    const char **keys = weft__alloc(ctx, (size_t)count * sizeof *keys);
    if (!keys) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    uint32_t k = 0;
    for (const cJSON *v = root->child; v; v = v->next) {
        keys[k++] = v->string;
    }
    qsort(keys, count, sizeof *keys, cmp_str_ptr);
    weft_result r = WEFT_OK;
    for (uint32_t i = 1; i < count && r == WEFT_OK; ++i) {
        if (strcmp(keys[i - 1], keys[i]) == 0) {
            r = weft__fail(WEFT_ERROR_DUPLICATE_NAME, "model config: key '%s' appears twice", keys[i]);
        }
    }
    weft__free(ctx, keys, (size_t)count * sizeof *keys);
    if (r != WEFT_OK) {
        return r;
    }

    /* Sizes are bounded by the header cap, so the products below cannot overflow. */
    m->config = weft__alloc(ctx, (size_t)count * sizeof *m->config);
    m->config_strings = weft__alloc(ctx, strings);
    m->config_numbers = numbers ? weft__alloc(ctx, numbers * sizeof *m->config_numbers) : NULL;
    if (!m->config || !m->config_strings || (numbers && !m->config_numbers)) {
        weft__free(ctx, m->config, (size_t)count * sizeof *m->config);
        weft__free(ctx, m->config_strings, strings);
        weft__free(ctx, m->config_numbers, numbers * sizeof *m->config_numbers);
        m->config = NULL;
        m->config_strings = NULL;
        m->config_numbers = NULL;
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    m->config_count = count;
    m->config_strings_size = strings;
    m->config_numbers_count = numbers;

    size_t spos = 0, npos = 0;
    k = 0;
    for (const cJSON *v = root->child; v; v = v->next, ++k) {
        weft_config_value *c = &m->config[k];
        size_t len = strlen(v->string) + 1;
        memcpy(m->config_strings + spos, v->string, len);
        c->key = m->config_strings + spos;
        spos += len;
        if (cJSON_IsNumber(v)) {
            c->kind = WEFT_CONFIG_NUMBER;
            c->number = v->valuedouble;
        } else if (cJSON_IsBool(v)) {
            c->kind = WEFT_CONFIG_BOOL;
            c->number = cJSON_IsTrue(v) ? 1.0 : 0.0;
        } else if (cJSON_IsString(v)) {
            c->kind = WEFT_CONFIG_STRING;
            len = strlen(v->valuestring) + 1;
            memcpy(m->config_strings + spos, v->valuestring, len);
            c->string = m->config_strings + spos;
            spos += len;
        } else {
            c->kind = WEFT_CONFIG_ARRAY;
            c->array = m->config_numbers ? m->config_numbers + npos : NULL;
            for (const cJSON *e = v->child; e; e = e->next) {
                m->config_numbers[npos++] = e->valuedouble;
                c->array_count++;
            }
        }
    }
    qsort(m->config, count, sizeof *m->config, cmp_config_key);
    return WEFT_OK;
}

/* Parses metadata "config" (a JSON object encoded as a string), when present. */
static weft_result config_parse(weft_model *m)
{
    const char *text = weft__model_metadata(m, "config");
    if (!text) {
        return WEFT_OK;
    }
    weft_result r = weft__json_screen((const uint8_t *)text, strlen(text), WEFT_ERROR_BAD_METADATA,
                                      "model config (metadata 'config')");
    if (r != WEFT_OK) {
        return r;
    }
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
    if (!root) {
        size_t at = end && end >= text ? (size_t)(end - text) : 0;
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: metadata 'config' is not valid JSON (near byte %zu)",
                          at);
    }
    if (!cJSON_IsObject(root)) {
        r = weft__fail(WEFT_ERROR_BAD_METADATA, "model config: metadata 'config' is not a JSON object");
    } else {
        r = config_build(m, root);
    }
    cJSON_Delete(root);
    return r;
}

/* Parses metadata "deploy", when present: {"strain_limit": f, "tether_distance": m, "push": m,
 * "ccd": bool}, each optional, each in the range weft_garment_def accepts
 * (weft_model_garment_def in runtime/garment applies them). */
static weft_result deploy_parse(weft_model *m)
{
    const char *text = weft__model_metadata(m, "deploy");
    if (!text) {
        return WEFT_OK;
    }
    cJSON *root = cJSON_ParseWithOpts(text, NULL, 1);
    weft_result r = WEFT_OK;
    if (!cJSON_IsObject(root)) {
        r = weft__fail(WEFT_ERROR_BAD_METADATA, "model: metadata 'deploy' is not a JSON object");
    }
    static const struct {
        const char *key;
        double lo, hi;
        uint32_t bit;
    } numbers[] = {{"strain_limit", 0.0, 10.0, WEFT__DEPLOY_STRAIN_LIMIT},
                   {"tether_distance", 0.0, WEFT_MAX_COORDINATE, WEFT__DEPLOY_TETHER_DISTANCE},
                   {"push", 0.0, 0.1, WEFT__DEPLOY_PUSH}};
    float *dst[] = {&m->deploy_strain_limit, &m->deploy_tether_distance, &m->deploy_push};
    for (size_t i = 0; r == WEFT_OK && i < sizeof numbers / sizeof numbers[0]; ++i) {
        const cJSON *v = cJSON_GetObjectItemCaseSensitive(root, numbers[i].key);
        if (!v) {
            continue;
        }
        if (!cJSON_IsNumber(v) || !(v->valuedouble >= numbers[i].lo && v->valuedouble <= numbers[i].hi)) {
            r = weft__fail(WEFT_ERROR_BAD_METADATA, "model: metadata 'deploy': %s must be a number in [%g, %g]",
                           numbers[i].key, numbers[i].lo, numbers[i].hi);
        } else {
            *dst[i] = (float)v->valuedouble;
            m->deploy_set |= numbers[i].bit;
        }
    }
    const cJSON *ccd = r == WEFT_OK ? cJSON_GetObjectItemCaseSensitive(root, "ccd") : NULL;
    if (ccd && !cJSON_IsBool(ccd)) {
        r = weft__fail(WEFT_ERROR_BAD_METADATA, "model: metadata 'deploy': ccd must be true or false");
    } else if (ccd) {
        m->deploy_ccd = cJSON_IsTrue(ccd);
        m->deploy_set |= WEFT__DEPLOY_CCD;
    }
    const cJSON *item = NULL;
    cJSON_ArrayForEach(item, root)
    {
        if (r == WEFT_OK && strcmp(item->string, "strain_limit") && strcmp(item->string, "tether_distance") &&
            strcmp(item->string, "push") && strcmp(item->string, "ccd")) {
            r = weft__fail(WEFT_ERROR_BAD_METADATA, "model: metadata 'deploy': unknown key '%.64s' (strain_limit, "
                           "tether_distance, push, ccd)", item->string);
        }
    }
    cJSON_Delete(root);
    return r;
}

/* ---------------------------------------------------------------------------------------- */
/* Content checks                                                                             */

/* Float tensors must be finite: a NaN weight would surface as NaN cloth frames later, far from
 * its cause. Checked on the bit patterns (exponent all ones), so no conversion is needed. */
static weft_result check_finite(const weft_tensor *t)
{
    uint64_t bad = t->count;
    if (t->dtype == WEFT_DTYPE_F32) {
        const uint32_t *p = t->data;
        for (uint64_t i = 0; i < t->count && bad == t->count; ++i) {
            bad = (p[i] & 0x7F800000u) == 0x7F800000u ? i : bad;
        }
    } else if (t->dtype == WEFT_DTYPE_F16 || t->dtype == WEFT_DTYPE_BF16) {
        const uint16_t *p = t->data;
        uint16_t mask = t->dtype == WEFT_DTYPE_F16 ? 0x7C00u : 0x7F80u;
        for (uint64_t i = 0; i < t->count && bad == t->count; ++i) {
            bad = (p[i] & mask) == mask ? i : bad;
        }
    }
    if (bad != t->count) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "model: tensor '%s' has a NaN or infinity at element %llu", t->name,
                          (unsigned long long)bad);
    }
    return WEFT_OK;
}

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && memcmp(s + n - k, suffix, k) == 0;
}

/* A name given as prefix + suffix, compared without building the string. */
typedef struct split_name {
    const char *prefix;
    size_t prefix_len;
    const char *suffix;
} split_name;

static int cmp_split_tensor(const void *key, const void *elem)
{
    const split_name *k = key;
    const char *name = ((const weft_tensor *)elem)->name;
    int c = strncmp(k->prefix, name, k->prefix_len); /* the prefix has no NUL, so a shorter name differs */
    return c ? c : strcmp(k->suffix, name + k->prefix_len);
}

/* Quantised weights: "<base>.q8" is I8 in [-127, 127] (symmetric, so the int8 kernels may negate
 * it) and needs "<base>.scale": F32 [rows], finite and non-negative, one scale per output row. */
static weft_result check_quantized(const weft_model *m, const weft_tensor *t)
{
    if (ends_with(t->name, ".scale")) {
        if (t->dtype != WEFT_DTYPE_F32) {
            return weft__fail(WEFT_ERROR_TENSOR_DTYPE, "model: scale tensor '%s' is %s, expected F32", t->name,
                              weft__dtype_name(t->dtype));
        }
        const float *p = t->data;
        for (uint64_t i = 0; i < t->count; ++i) {
            if (!(p[i] >= 0.0f)) {
                return weft__fail(WEFT_ERROR_FORMAT, "model: scale tensor '%s' has a negative value at element %llu",
                                  t->name, (unsigned long long)i);
            }
        }
        return WEFT_OK;
    }
    if (!ends_with(t->name, ".q8")) {
        return WEFT_OK;
    }
    if (t->dtype != WEFT_DTYPE_I8) {
        return weft__fail(WEFT_ERROR_TENSOR_DTYPE, "model: quantised tensor '%s' is %s, expected I8", t->name,
                          weft__dtype_name(t->dtype));
    }
    const int8_t *q = t->data;
    for (uint64_t i = 0; i < t->count; ++i) {
        if (q[i] == INT8_MIN) {
            return weft__fail(WEFT_ERROR_FORMAT, "model: quantised tensor '%s' holds -128 at element %llu (range is "
                                                 "[-127, 127])",
                              t->name, (unsigned long long)i);
        }
    }
    int base = (int)(strlen(t->name) - 3);
    split_name key = {t->name, (size_t)base, ".scale"};
    const weft_tensor *scale =
        m->tensor_count ? bsearch(&key, m->tensors, m->tensor_count, sizeof *m->tensors, cmp_split_tensor) : NULL;
    if (!scale) {
        return weft__fail(WEFT_ERROR_MISSING_TENSOR, "model: quantised tensor '%s' has no scale tensor '%.*s.scale'",
                          t->name, base, t->name);
    }
    /* One scale per output channel (row): W[N][...] pairs with scale[N]. */
    uint64_t rows = t->rank ? t->shape[0] : 1;
    if (scale->rank != 1 || scale->shape[0] != rows) {
        return weft__fail(WEFT_ERROR_TENSOR_SHAPE, "model: scale tensor '%s' must have shape [%llu] to match '%s'",
                          scale->name, (unsigned long long)rows, t->name);
    }
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Loading                                                                                    */

/* Copies one tensor's bytes (entries arrive in file order) into dst. */
typedef weft_result model_fill_fn(void *user, const weft_st_entry *entry, void *dst);

static weft_result model_build(weft_context *ctx, weft_st_header *header, model_fill_fn *fill, void *user,
                               weft_model **out_model)
{
    /* Every tensor starts on a 64-byte boundary so SIMD code can use aligned loads. */
    uint64_t total = 0;
    for (uint32_t i = 0; i < header->entry_count; ++i) {
        uint64_t bytes = header->entries[i].end - header->entries[i].begin;
        uint64_t padded = (bytes + WEFT_ALIGN - 1) & ~(uint64_t)(WEFT_ALIGN - 1);
        if (!weft__add_u64(total, padded, &total)) {
            weft__st_header_free(ctx, header);
            return weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "model: total tensor size overflows");
        }
    }
    if (total > SIZE_MAX - WEFT_ALIGN) {
        weft__st_header_free(ctx, header);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "model: %llu bytes of tensors do not fit in memory",
                          (unsigned long long)total);
    }

    weft_model *m = weft__alloc(ctx, sizeof *m);
    if (!m) {
        weft__st_header_free(ctx, header);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    /* The model takes over the header's metadata and string pool. */
    m->ctx = ctx;
    m->meta = header->meta;
    m->meta_count = header->meta_count;
    m->strings = header->strings;
    m->strings_size = header->strings_size;
    header->meta = NULL;
    header->meta_count = 0;
    header->strings = NULL;
    header->strings_size = 0;

    weft_result r = WEFT_OK;
    m->data_bytes = (size_t)total;
    m->data = weft__alloc(ctx, m->data_bytes);
    if (header->entry_count) {
        m->tensors = weft__alloc(ctx, (size_t)header->entry_count * sizeof *m->tensors);
    }
    m->tensor_count = header->entry_count; /* model_free releases the array by this count */
    if (!m->data || (header->entry_count && !m->tensors)) {
        r = WEFT_ERROR_OUT_OF_MEMORY;
        goto fail;
    }

    uint64_t pos = 0;
    for (uint32_t i = 0; i < header->entry_count; ++i) {
        const weft_st_entry *e = &header->entries[i];
        weft_tensor *t = &m->tensors[i];
        t->name = e->name;
        t->dtype = e->dtype;
        t->rank = e->rank;
        memcpy(t->shape, e->shape, sizeof t->shape);
        t->count = e->count;
        t->bytes = e->end - e->begin;
        t->data = (char *)m->data + pos;
        r = fill(user, e, (char *)m->data + pos);
        if (r != WEFT_OK) {
            goto fail;
        }
        pos += (t->bytes + WEFT_ALIGN - 1) & ~(uint64_t)(WEFT_ALIGN - 1);
        m->info.parameter_count += t->count;
        m->info.weight_bytes += t->bytes;
        if (t->dtype == WEFT_DTYPE_I8) {
            m->info.precision = WEFT_PRECISION_INT8;
        } else if (t->dtype == WEFT_DTYPE_F16 && m->info.precision != WEFT_PRECISION_INT8) {
            m->info.precision = WEFT_PRECISION_FP16;
        }
    }
    weft__st_header_free(ctx, header);
    if (m->tensor_count > 1) {
        qsort(m->tensors, m->tensor_count, sizeof *m->tensors, cmp_tensor_name);
    }
    for (uint32_t i = 0; i < m->tensor_count && r == WEFT_OK; ++i) {
        r = check_finite(&m->tensors[i]);
        if (r == WEFT_OK) {
            r = check_quantized(m, &m->tensors[i]);
        }
    }
    if (r != WEFT_OK) {
        goto fail;
    }

    r = config_parse(m);
    r = r != WEFT_OK ? r : deploy_parse(m);
    if (r != WEFT_OK) {
        goto fail;
    }
    const char *name = weft__model_metadata(m, "name");
    const char *arch = weft__model_metadata(m, "architecture");
    m->info.name = name ? name : "";
    m->info.architecture = arch ? arch : "";
    m->info.tensor_count = m->tensor_count;
    m->arch = weft__architecture_find(arch);
    if (m->arch) {
        if (m->arch->needs_config && !weft__model_metadata(m, "config")) {
            r = weft__fail(WEFT_ERROR_BAD_METADATA, "model: architecture '%s' needs metadata 'config'", arch);
            goto fail;
        }
        if (m->arch->validate) {
            r = m->arch->validate(m);
            if (r != WEFT_OK) {
                goto fail;
            }
        }
    }
    *out_model = m;
    return WEFT_OK;

fail:
    weft__st_header_free(ctx, header);
    model_free(m);
    return r;
}

static weft_result check_load_args(const weft_context *ctx, const void *p, weft_model **out_model, const char *fn)
{
    if (!ctx || !p || !out_model) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: context, source and out_model must not be NULL", fn);
    }
    return WEFT_OK;
}

typedef struct memory_source {
    const uint8_t *data;
} memory_source;

static weft_result fill_from_memory(void *user, const weft_st_entry *e, void *dst)
{
    const memory_source *src = user;
    if (e->end > e->begin) {
        memcpy(dst, src->data + e->begin, (size_t)(e->end - e->begin));
    }
    return WEFT_OK;
}

weft_result weft_model_load_memory(weft_context *context, const void *bytes, size_t size, weft_model **out_model)
{
    weft_result r = check_load_args(context, bytes, out_model, "weft_model_load_memory");
    if (r != WEFT_OK) {
        return r;
    }
    weft_st_header header;
    memory_source src;
    r = weft__st_parse_memory(context, bytes, size, &header, &src.data);
    if (r != WEFT_OK) {
        return r;
    }
    return model_build(context, &header, fill_from_memory, &src, out_model);
}

typedef struct file_source {
    FILE *f;
    const char *path;
} file_source;

/* Tensors arrive in offset order and tile the data section, so reads are sequential. */
static weft_result fill_from_file(void *user, const weft_st_entry *e, void *dst)
{
    const file_source *src = user;
    size_t n = (size_t)(e->end - e->begin);
    if (n && fread(dst, 1, n, src->f) != n) {
        if (ferror(src->f)) {
            return weft__fail(WEFT_ERROR_IO, "model: reading tensor '%s' from '%s' failed", e->name, src->path);
        }
        return weft__fail(WEFT_ERROR_FILE_TRUNCATED, "model: '%s' ended inside tensor '%s' (file changed while loading?)",
                          src->path, e->name);
    }
    return WEFT_OK;
}

/* Refuses a header whose metadata "architecture" is not `want` (NULL: any), before any tensor
 * is read. */
static weft_result check_architecture(weft_context *ctx, weft_st_header *header, const char *want, const char *path)
{
    if (!want) {
        return WEFT_OK;
    }
    const char *arch = NULL;
    for (uint32_t i = 0; i < header->meta_count; ++i) {
        if (strcmp(header->meta[i].key, "architecture") == 0) {
            arch = header->meta[i].value;
        }
    }
    if (arch && strcmp(arch, want) == 0) {
        return WEFT_OK;
    }
    weft_result r = weft__fail(WEFT_ERROR_BAD_METADATA,
                               "weft_model_load_file_as: '%s' is a model of architecture '%s', not '%s' (no tensor "
                               "was read)",
                               path, arch ? arch : "(none)", want);
    weft__st_header_free(ctx, header);
    return r;
}

static weft_result load_file(weft_context *context, const char *path, const char *architecture,
                             weft_model **out_model, const char *fn)
{
    weft_result r = check_load_args(context, path, out_model, fn);
    if (r != WEFT_OK) {
        return r;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "weft_model_load_file: cannot open '%s': %s", path, strerror(errno));
    }
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size < 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "weft_model_load_file: '%s' is not a regular file", path);
    }
    uint64_t file_size = (uint64_t)st.st_size;
    uint8_t prefix[8] = {0};
    size_t want = file_size < 8 ? (size_t)file_size : 8;
    uint64_t header_size = 0;
    if (fread(prefix, 1, want, f) != want) {
        r = weft__fail(WEFT_ERROR_IO, "weft_model_load_file: reading '%s' failed", path);
    } else {
        r = weft__st_header_length(prefix, file_size, &header_size);
    }
    char *json = NULL;
    if (r == WEFT_OK) {
        json = weft__alloc(context, (size_t)header_size);
        if (!json) {
            r = WEFT_ERROR_OUT_OF_MEMORY;
        } else if (header_size && fread(json, 1, (size_t)header_size, f) != header_size) {
            r = weft__fail(WEFT_ERROR_IO, "weft_model_load_file: reading the header of '%s' failed", path);
        }
    }
    weft_st_header header;
    if (r == WEFT_OK) {
        r = weft__st_parse_header(context, json, (size_t)header_size, file_size - 8 - header_size, &header);
    }
    weft__free(context, json, (size_t)header_size);
    if (r == WEFT_OK) {
        r = check_architecture(context, &header, architecture, path);
    }
    if (r == WEFT_OK) {
        file_source src = {f, path};
        r = model_build(context, &header, fill_from_file, &src, out_model);
    }
    fclose(f);
    return r;
}

weft_result weft_model_load_file(weft_context *context, const char *path, weft_model **out_model)
{
    return load_file(context, path, NULL, out_model, "weft_model_load_file");
}

weft_result weft_model_load_file_as(weft_context *context, const char *path, const char *architecture,
                                    weft_model **out_model)
{
    if (!architecture) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_model_load_file_as: architecture must not be NULL");
    }
    return load_file(context, path, architecture, out_model, "weft_model_load_file_as");
}
