/* Offline quantiser (see quant.h). The whole input is validated and every output tensor is
 * built in memory before anything is written, so a failure never leaves a file behind. */
#include "quant.h"

#include "core/core.h"
#include "io/safetensors.h"
#include "kernels/qkernels.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define QUANT_DEF_COOKIE 0x51554e54u

weft_quant_def weft_default_quant_def(void)
{
    weft_quant_def def = {0};
    def.format = WEFT_QUANT_INT8;
    def.min_dim = 16;
    def.internal_cookie = QUANT_DEF_COOKIE;
    return def;
}

void weft_quant_report_free(weft_quant_report *report)
{
    if (report) {
        free(report->tensors);
        *report = (weft_quant_report){0};
    }
}

void weft_quant_buffer_free(weft_context *ctx, void *buffer, size_t size) { weft__free(ctx, buffer, size); }

static const char *meta_value(const weft_st_header *h, const char *key)
{
    for (uint32_t i = 0; i < h->meta_count; ++i) {
        if (strcmp(h->meta[i].key, key) == 0) {
            return h->meta[i].value;
        }
    }
    return NULL;
}

/* Names the model asks to keep in fp32: metadata "keep_fp32", a comma-separated list. */
static bool meta_keeps(const char *list, const char *name)
{
    size_t n = strlen(name);
    for (const char *p = list; p && *p;) {
        const char *end = strchr(p, ',');
        size_t len = end ? (size_t)(end - p) : strlen(p);
        if (len == n && memcmp(p, name, n) == 0) {
            return true;
        }
        p = end ? end + 1 : NULL;
    }
    return false;
}

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && memcmp(s + n - k, suffix, k) == 0;
}

static bool def_keeps(const weft_quant_def *def, const char *name)
{
    for (const char *const *k = def->keep; k && *k; ++k) {
        if (strcmp(*k, name) == 0) {
            return true;
        }
    }
    return false;
}

typedef struct plan {
    const weft_st_entry *entry;
    const float *w;
    bool quantize;
    char reason[40];
    /* outputs */
    void *q;          /* I8 or F16 data */
    float *scale;     /* int8 only */
    char qname[160], sname[160];
    uint64_t scale_shape[1];
} plan;

static weft_result plan_tensor(const weft_quant_def *def, const char *keep, plan *p)
{
    const weft_st_entry *e = p->entry;
    if (e->dtype != WEFT_DTYPE_F32) {
        return weft__fail(WEFT_ERROR_TENSOR_DTYPE, "quantize: tensor '%s' is %s; the quantiser reads F32 models only",
                          e->name, weft__dtype_name(e->dtype));
    }
    for (uint64_t i = 0; i < e->count; ++i) {
        if (!isfinite(p->w[i])) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "quantize: tensor '%s' has a NaN or infinity at element %llu",
                              e->name, (unsigned long long)i);
        }
    }
    if (strlen(e->name) + sizeof ".scale" > sizeof p->qname) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: tensor name '%.64s...' is too long", e->name);
    }
    p->quantize = false;
    if (e->rank != 2) {
        snprintf(p->reason, sizeof p->reason, "fp32 (rank %u)", e->rank);
    } else if (meta_keeps(keep, e->name) || def_keeps(def, e->name)) {
        snprintf(p->reason, sizeof p->reason, "fp32 (kept by request)");
    } else if (!ends_with(e->name, ".weight")) {
        snprintf(p->reason, sizeof p->reason, "fp32 (not a layer weight)");
    } else if (e->shape[0] < def->min_dim || e->shape[1] < def->min_dim) {
        snprintf(p->reason, sizeof p->reason, "fp32 (small: %llux%llu)", (unsigned long long)e->shape[0],
                 (unsigned long long)e->shape[1]);
    } else if (e->shape[0] > UINT32_MAX || e->shape[1] > UINT32_MAX) {
        snprintf(p->reason, sizeof p->reason, "fp32 (too large)");
    } else {
        p->quantize = true;
        if (def->format == WEFT_QUANT_FP16) {
            for (uint64_t i = 0; i < e->count; ++i) {
                if (fabsf(p->w[i]) > 65504.0f) {
                    p->quantize = false;
                    snprintf(p->reason, sizeof p->reason, "fp32 (outside fp16 range)");
                    break;
                }
            }
        }
    }
    return WEFT_OK;
}

static void report_errors(weft_quant_tensor_report *r, const plan *p, weft_quant_format format)
{
    const weft_st_entry *e = p->entry;
    double sw = 0, se = 0, emax = 0;
    for (uint64_t i = 0; i < e->count; ++i) {
        double w = p->w[i], d = w;
        if (p->quantize && format == WEFT_QUANT_INT8) {
            uint64_t row = i / e->shape[1];
            d = (double)((const int8_t *)p->q)[i] * p->scale[row];
        } else if (p->quantize) {
            d = weft_f16_to_f32(((const uint16_t *)p->q)[i]);
        }
        sw += w * w;
        se += (d - w) * (d - w);
        emax = fmax(emax, fabs(d - w));
    }
    snprintf(r->name, sizeof r->name, "%s", e->name);
    snprintf(r->scheme, sizeof r->scheme, "%s",
             !p->quantize ? p->reason : (format == WEFT_QUANT_INT8 ? "int8-per-channel" : "fp16"));
    r->count = e->count;
    r->weight_rms = e->count ? sqrt(sw / (double)e->count) : 0.0;
    r->error_rms = e->count ? sqrt(se / (double)e->count) : 0.0;
    r->error_max = emax;
    r->rel_error = r->weight_rms > 0 ? r->error_rms / r->weight_rms : 0.0;
}

/* The metadata the output carries: the input's, plus "precision" and "quantization". */
static char *quant_metadata_json(const weft_quant_def *def, const plan *plans, uint32_t n)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "format_version", WEFT_QUANT_FORMAT_VERSION);
    cJSON_AddStringToObject(root, "format", def->format == WEFT_QUANT_INT8 ? "int8" : "fp16");
    cJSON_AddNumberToObject(root, "min_dim", def->min_dim);
    cJSON *schemes = cJSON_AddObjectToObject(root, "schemes");
    for (uint32_t i = 0; i < n; ++i) {
        const char *scheme = !plans[i].quantize ? plans[i].reason
                             : def->format == WEFT_QUANT_INT8 ? "int8-per-channel-symmetric"
                                                              : "fp16";
        cJSON_AddStringToObject(schemes, plans[i].entry->name, scheme);
    }
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    return text;
}

weft_result weft_quantize_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                 void **out, size_t *out_size, weft_quant_report *report)
{
    if (!ctx || !def || !in || !out || !out_size) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: ctx, def, input and outputs are required");
    }
    if (def->internal_cookie != QUANT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: def was not made by weft_default_quant_def()");
    }
    if (def->format != WEFT_QUANT_INT8 && def->format != WEFT_QUANT_FP16) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: unknown format %d", (int)def->format);
    }
    /* The loader's checks first: file rules, finiteness, and the architecture's required tensors. */
    weft_model *model = NULL;
    weft_result r = weft_model_load_memory(ctx, in, in_size, &model);
    if (r != WEFT_OK) {
        return r;
    }
    weft_model_destroy(model);
    weft_st_header h;
    const uint8_t *data;
    r = weft__st_parse_memory(ctx, in, in_size, &h, &data);
    if (r != WEFT_OK) {
        return r;
    }
    plan *plans = NULL;
    weft_st_tensor_in *tensors = NULL;
    weft_st_meta *meta = NULL;
    char *quant_json = NULL;
    uint32_t n = h.entry_count;

    if (meta_value(&h, "quantization")) {
        r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: the input is already quantised (metadata "
                                                    "'quantization' present)");
        goto done;
    }
    const char *keep = meta_value(&h, "keep_fp32");

    plans = calloc(n ? n : 1, sizeof *plans);
    tensors = calloc(2 * (size_t)n + 1, sizeof *tensors);
    meta = calloc((size_t)h.meta_count + 2, sizeof *meta);
    if (!plans || !tensors || !meta) {
        r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
        goto done;
    }
    for (uint32_t i = 0; i < n; ++i) {
        plans[i].entry = &h.entries[i];
        plans[i].w = (const float *)(data + h.entries[i].begin);
        r = plan_tensor(def, keep, &plans[i]);
        if (r != WEFT_OK) {
            goto done;
        }
    }
    uint32_t t = 0, quantized = 0;
    for (uint32_t i = 0; i < n; ++i) {
        plan *p = &plans[i];
        const weft_st_entry *e = p->entry;
        if (!p->quantize) {
            tensors[t++] = (weft_st_tensor_in){e->name, WEFT_DTYPE_F32, e->rank, e->shape, p->w};
            continue;
        }
        quantized++;
        uint32_t N = (uint32_t)e->shape[0], K = (uint32_t)e->shape[1];
        if (def->format == WEFT_QUANT_INT8) {
            p->q = malloc(e->count ? e->count : 1);
            p->scale = malloc(N * sizeof(float));
            if (!p->q || !p->scale) {
                r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for '%s'", e->name);
                goto done;
            }
            weft_q8_quantize_weights(p->w, N, K, p->q, p->scale);
            snprintf(p->qname, sizeof p->qname, "%s.q8", e->name);
            snprintf(p->sname, sizeof p->sname, "%s.scale", e->name);
            p->scale_shape[0] = N;
            tensors[t++] = (weft_st_tensor_in){p->qname, WEFT_DTYPE_I8, 2, e->shape, p->q};
            tensors[t++] = (weft_st_tensor_in){p->sname, WEFT_DTYPE_F32, 1, p->scale_shape, p->scale};
        } else {
            uint16_t *hq = malloc(e->count * sizeof(uint16_t));
            if (!hq) {
                r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for '%s'", e->name);
                goto done;
            }
            for (uint64_t k = 0; k < e->count; ++k) {
                hq[k] = weft_f32_to_f16(p->w[k]);
            }
            p->q = hq;
            tensors[t++] = (weft_st_tensor_in){e->name, WEFT_DTYPE_F16, 2, e->shape, p->q};
        }
    }
    quant_json = quant_metadata_json(def, plans, n);
    uint32_t m = 0;
    for (uint32_t i = 0; i < h.meta_count; ++i) {
        if (strcmp(h.meta[i].key, "precision") != 0) {
            meta[m++] = h.meta[i];
        }
    }
    meta[m++] = (weft_st_meta){"precision", def->format == WEFT_QUANT_INT8 ? "int8" : "fp16"};
    meta[m++] = (weft_st_meta){"quantization", quant_json};
    r = weft__st_write_memory(ctx, tensors, t, meta, m, out, out_size);
    if (r != WEFT_OK) {
        goto done;
    }
    if (report) {
        *report = (weft_quant_report){0};
        report->tensors = calloc(n ? n : 1, sizeof *report->tensors);
        if (!report->tensors) {
            weft__free(ctx, *out, *out_size);
            r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for the report");
            goto done;
        }
        for (uint32_t i = 0; i < n; ++i) {
            report_errors(&report->tensors[i], &plans[i], def->format);
        }
        report->tensor_count = n;
        report->quantized_count = quantized;
        report->bytes_in = in_size;
        report->bytes_out = *out_size;
    }
done:
    if (plans) {
        for (uint32_t i = 0; i < n; ++i) {
            free(plans[i].q);
            free(plans[i].scale);
        }
    }
    free(plans);
    free(tensors);
    free(meta);
    free(quant_json);
    weft__st_header_free(ctx, &h);
    return r;
}

static weft_result read_file(weft_context *ctx, const char *path, void **out, size_t *size)
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
    void *buf = weft__alloc(ctx, (size_t)len);
    if (!buf) {
        fclose(f);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    if (fread(buf, 1, (size_t)len, f) != (size_t)len) {
        fclose(f);
        weft__free(ctx, buf, (size_t)len);
        return weft__fail(WEFT_ERROR_IO, "quantize: short read on '%s'", path);
    }
    fclose(f);
    *out = buf;
    *size = (size_t)len;
    return WEFT_OK;
}

static weft_result write_file_atomic(const char *path, const void *bytes, size_t size)
{
    char tmp[4096];
    if ((size_t)snprintf(tmp, sizeof tmp, "%s.tmp", path) >= sizeof tmp) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: output path too long");
    }
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "quantize: cannot create '%s'", tmp);
    }
    bool ok = fwrite(bytes, 1, size, f) == size;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path) != 0) {
        remove(tmp);
        return weft__fail(WEFT_ERROR_IO, "quantize: cannot write '%s'", path);
    }
    return WEFT_OK;
}

weft_result weft_quantize_file(weft_context *ctx, const weft_quant_def *def, const char *in_path,
                               const char *out_path, weft_quant_report *report)
{
    if (!ctx || !in_path || !out_path) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: input and output paths are required");
    }
    if (!def || def->internal_cookie != QUANT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: def was not made by weft_default_quant_def()");
    }
    if (strcmp(in_path, out_path) == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: output '%s' would overwrite the input", out_path);
    }
    void *in = NULL, *out = NULL;
    size_t in_size = 0, out_size = 0;
    weft_result r = read_file(ctx, in_path, &in, &in_size);
    if (r != WEFT_OK) {
        return r;
    }
    r = weft_quantize_memory(ctx, def, in, in_size, &out, &out_size, report);
    weft__free(ctx, in, in_size);
    if (r != WEFT_OK) {
        return r;
    }
    r = write_file_atomic(out_path, out, out_size);
    weft__free(ctx, out, out_size);
    if (r != WEFT_OK && report) {
        weft_quant_report_free(report);
    }
    return r;
}

void weft_quant_report_write_json(const weft_quant_report *report, weft_quant_format format, FILE *out)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "format", format == WEFT_QUANT_INT8 ? "int8" : "fp16");
    cJSON_AddNumberToObject(root, "format_version", WEFT_QUANT_FORMAT_VERSION);
    cJSON_AddNumberToObject(root, "bytes_in", (double)report->bytes_in);
    cJSON_AddNumberToObject(root, "bytes_out", (double)report->bytes_out);
    cJSON_AddNumberToObject(root, "quantized", report->quantized_count);
    cJSON *list = cJSON_AddArrayToObject(root, "tensors");
    for (uint32_t i = 0; i < report->tensor_count; ++i) {
        const weft_quant_tensor_report *t = &report->tensors[i];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", t->name);
        cJSON_AddStringToObject(o, "scheme", t->scheme);
        cJSON_AddNumberToObject(o, "count", (double)t->count);
        cJSON_AddNumberToObject(o, "weight_rms", t->weight_rms);
        cJSON_AddNumberToObject(o, "error_rms", t->error_rms);
        cJSON_AddNumberToObject(o, "error_max", t->error_max);
        cJSON_AddNumberToObject(o, "rel_error", t->rel_error);
        cJSON_AddItemToArray(list, o);
    }
    char *text = cJSON_Print(root);
    if (text) {
        fprintf(out, "%s\n", text);
    }
    free(text);
    cJSON_Delete(root);
}
