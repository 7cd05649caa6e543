/* Offline quantiser (see quant.h). The whole input is validated, calibrated and every output
 * tensor built in memory (and, when asked, the result rolled out against the fp32 model) before
 * anything is written, so a failure never leaves a file behind. */
#include "quant_internal.h"

#include "core/core.h"
#include "io/safetensors.h"
#include "kernels/qkernels.h"
#include "model/transformer.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define QUANT_DEF_COOKIE 0x51554e54u
#define QUANT_MAX_GROUPS 160u

weft_quant_def weft_default_quant_def(void)
{
    weft_quant_def def = {0};
    def.format = WEFT_QUANT_INT8;
    def.min_dim = 16;
    def.calib_frames = WEFT_QUANT_DEFAULT_CALIB_FRAMES;
    def.smoothquant_alpha = -1.0f;
    def.max_layer_error = WEFT_QUANT_DEFAULT_MAX_LAYER_ERROR;
    def.internal_cookie = QUANT_DEF_COOKIE;
    return def;
}

const char *weft_quant_default_val_dir(void) { return WEFT_QUANT_SOURCE_DIR "/tests/data/sample_seq"; }

void weft_quant_report_free(weft_quant_report *report)
{
    if (report) {
        for (uint32_t i = 0; report->layers && i < report->layer_count; ++i) {
            free(report->layers[i].channel_absmax);
        }
        free(report->layers);
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
    bool layer;          /* a rank-2 "*.weight": gets a quant.layer.<name> decision */
    char reason[48];     /* scheme when kept, e.g. "fp32 (small: 3x48)" */
    char decision[48];   /* "int8", "fp16", "fp32:tiny", "fp32:request", "fp32:range", "fp32:error=..." */
    char layer_name[128];
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
    const char *fmt = def->format == WEFT_QUANT_INT8 ? "int8" : "fp16";
    p->quantize = false;
    p->layer = e->rank == 2 && ends_with(e->name, ".weight");
    if (p->layer) {
        size_t n = strlen(e->name) - strlen(".weight");
        memcpy(p->layer_name, e->name, n);
        p->layer_name[n] = '\0';
    }
    if (e->rank != 2) {
        snprintf(p->reason, sizeof p->reason, "fp32 (rank %u)", e->rank);
    } else if (meta_keeps(keep, e->name) || def_keeps(def, e->name)) {
        snprintf(p->reason, sizeof p->reason, "fp32 (kept by request)");
        snprintf(p->decision, sizeof p->decision, "fp32:request");
    } else if (!p->layer) {
        snprintf(p->reason, sizeof p->reason, "fp32 (not a layer weight)");
    } else if (e->shape[0] < def->min_dim || e->shape[1] < def->min_dim) {
        snprintf(p->reason, sizeof p->reason, "fp32 (small: %llux%llu)", (unsigned long long)e->shape[0],
                 (unsigned long long)e->shape[1]);
        snprintf(p->decision, sizeof p->decision, "fp32:tiny");
    } else if (e->shape[0] > UINT32_MAX || e->shape[1] > UINT32_MAX) {
        snprintf(p->reason, sizeof p->reason, "fp32 (too large)");
        snprintf(p->decision, sizeof p->decision, "fp32:size");
    } else {
        p->quantize = true;
        snprintf(p->decision, sizeof p->decision, "%s", fmt);
        if (def->format == WEFT_QUANT_FP16) {
            for (uint64_t i = 0; i < e->count; ++i) {
                if (fabsf(p->w[i]) > 65504.0f) {
                    p->quantize = false;
                    snprintf(p->reason, sizeof p->reason, "fp32 (outside fp16 range)");
                    snprintf(p->decision, sizeof p->decision, "fp32:range");
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

/* ------------------------------------------------------------------------------------------ */
/* One quantisation run                                                                        */

enum { GROUP_SKIPPED = 0, GROUP_APPLIED, GROUP_REVERTED };

typedef struct job {
    weft_context *ctx;
    const weft_quant_def *def;
    const void *in;
    size_t in_size;
    weft_st_header h;
    const uint8_t *data;            /* the input's data section */
    uint8_t *work;                  /* writable copy of the input when smoothing (else NULL) */
    uint8_t *wdata;                 /* its data section */
    plan *plans;
    uint32_t n;
    char **seqs;
    uint32_t seq_count;
    quant_layer_stats *st1, *st2;   /* calibration of the input, and of the smoothed model */
    uint32_t c1, c2, frames;
    quant_smooth_group *groups;
    uint32_t group_count;
    int group_state[QUANT_MAX_GROUPS];
    char group_why[QUANT_MAX_GROUPS][200];
} job;

static plan *plan_of_layer(const job *j, const char *layer)
{
    for (uint32_t i = 0; i < j->n; ++i) {
        if (j->plans[i].layer && strcmp(j->plans[i].layer_name, layer) == 0) {
            return &j->plans[i];
        }
    }
    return NULL;
}

static bool eligible_cb(const char *name, uint32_t out, uint32_t in, void *user)
{
    (void)out;
    (void)in;
    const plan *p = plan_of_layer(user, name);
    return p && p->quantize;
}

static double act_error_of(const quant_layer_stats *st)
{
    return st && st->rows > 0 && st->eligible && st->err_den > 0 ? sqrt(st->err_num / st->err_den) : -1.0;
}

static int group_of_layer(const job *j, const char *layer)
{
    for (uint32_t g = 0; g < j->group_count; ++g) {
        for (uint32_t i = 0; i < j->groups[g].count; ++i) {
            if (strcmp(j->groups[g].layers[i], layer) == 0) {
                return (int)g;
            }
        }
    }
    return -1;
}

/* The statistics that describe the layer as it will be stored. */
static const quant_layer_stats *final_stats(const job *j, const char *layer)
{
    int g = group_of_layer(j, layer);
    if (g >= 0 && j->group_state[g] == GROUP_APPLIED && j->st2) {
        return quant_stats_find(j->st2, j->c2, layer);
    }
    return j->st1 ? quant_stats_find(j->st1, j->c1, layer) : NULL;
}

/* Copies a group's tensors from the input back into the working image (undoes its migration). */
static void restore_group(job *j, const quant_smooth_group *g)
{
    char names[QUANT_MAX_GROUP + 2][160];
    uint32_t n = 0;
    snprintf(names[n++], sizeof names[0], "%s.weight", g->ln);
    snprintf(names[n++], sizeof names[0], "%s.bias", g->ln);
    for (uint32_t i = 0; i < g->count; ++i) {
        snprintf(names[n++], sizeof names[0], "%s.weight", g->layers[i]);
    }
    for (uint32_t k = 0; k < n; ++k) {
        for (uint32_t i = 0; i < j->h.entry_count; ++i) {
            const weft_st_entry *e = &j->h.entries[i];
            if (strcmp(e->name, names[k]) == 0) {
                memcpy(j->wdata + e->begin, j->data + e->begin, e->end - e->begin);
            }
        }
    }
}

/* Decides which groups can be migrated and applies them to the working image. */
static weft_result smooth_groups(job *j, float alpha)
{
    weft_model *m = NULL;
    weft_result r = weft_model_load_memory(j->ctx, j->in, j->in_size, &m);
    if (r != WEFT_OK) {
        return r;
    }
    j->groups = calloc(QUANT_MAX_GROUPS, sizeof *j->groups);
    if (!j->groups) {
        weft_model_destroy(m);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
    }
    j->group_count = quant_smooth_groups(m, j->groups, QUANT_MAX_GROUPS);
    weft_model_destroy(m);
    j->work = weft__alloc(j->ctx, j->in_size);
    if (!j->work) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(j->work, j->in, j->in_size);
    j->wdata = j->work + ((const uint8_t *)j->data - (const uint8_t *)j->in);
    for (uint32_t g = 0; g < j->group_count; ++g) {
        const quant_smooth_group *gr = &j->groups[g];
        j->group_state[g] = GROUP_SKIPPED;
        const char *why = NULL;
        for (uint32_t i = 0; i < gr->count && !why; ++i) {
            const plan *p = plan_of_layer(j, gr->layers[i]);
            const quant_layer_stats *st = quant_stats_find(j->st1, j->c1, gr->layers[i]);
            if (!p || !p->quantize) {
                snprintf(j->group_why[g], sizeof j->group_why[g], "skipped: %.64s stays fp32 (%.40s)", gr->layers[i],
                         p ? p->decision + 5 : "absent");
                why = j->group_why[g];
            } else if (!st || st->rows == 0) {
                snprintf(j->group_why[g], sizeof j->group_why[g], "skipped: %.64s never ran during calibration",
                         gr->layers[i]);
                why = j->group_why[g];
            }
        }
        if (why) {
            continue;
        }
        if (!quant_smooth_apply_group(&j->h, j->wdata, gr, j->st1, j->c1, alpha)) {
            snprintf(j->group_why[g], sizeof j->group_why[g], "skipped: no finite positive factor for %.64s", gr->ln);
            continue;
        }
        j->group_state[g] = GROUP_APPLIED;
        snprintf(j->group_why[g], sizeof j->group_why[g], "applied (folded into %.64s)", gr->ln);
    }
    /* Every plan reads the working image from now on. */
    for (uint32_t i = 0; i < j->n; ++i) {
        j->plans[i].w = (const float *)(j->wdata + j->plans[i].entry->begin);
    }
    return WEFT_OK;
}

/* After the second calibration: keep a migration only where it lowered the group's worst error. */
static void judge_groups(job *j)
{
    for (uint32_t g = 0; g < j->group_count; ++g) {
        if (j->group_state[g] != GROUP_APPLIED) {
            continue;
        }
        const quant_smooth_group *gr = &j->groups[g];
        double before = 0, after = 0;
        for (uint32_t i = 0; i < gr->count; ++i) {
            before = fmax(before, act_error_of(quant_stats_find(j->st1, j->c1, gr->layers[i])));
            after = fmax(after, act_error_of(quant_stats_find(j->st2, j->c2, gr->layers[i])));
        }
        if (after < before) {
            snprintf(j->group_why[g], sizeof j->group_why[g], "applied (folded into %.64s; worst error %.4f -> %.4f)",
                     gr->ln, before, after);
        } else {
            restore_group(j, gr);
            j->group_state[g] = GROUP_REVERTED;
            snprintf(j->group_why[g], sizeof j->group_why[g], "reverted: worst error %.4f -> %.4f with %.64s smoothed",
                     before, after, gr->ln);
        }
    }
}

/* Calibration, SmoothQuant and the per-layer error decision. */
static weft_result calibrate(job *j, bool smooth_only)
{
    const weft_quant_def *def = j->def;
    weft_result r = quant_seq_expand(def->calib, def->calib_split, &j->seqs, &j->seq_count);
    if (r != WEFT_OK) {
        return r;
    }
    r = quant_calibrate(j->ctx, j->in, j->in_size, def->format, j->seqs, j->seq_count, def->calib_frames, eligible_cb,
                        j, &j->st1, &j->c1, &j->frames);
    if (r != WEFT_OK) {
        return r;
    }
    if (def->smoothquant_alpha >= 0.0f) {
        if ((r = smooth_groups(j, def->smoothquant_alpha)) != WEFT_OK) {
            return r;
        }
        if (smooth_only) {
            return WEFT_OK;
        }
        uint32_t frames2 = 0;
        r = quant_calibrate(j->ctx, j->work, j->in_size, def->format, j->seqs, j->seq_count, def->calib_frames,
                            eligible_cb, j, &j->st2, &j->c2, &frames2);
        if (r != WEFT_OK) {
            return r;
        }
        judge_groups(j);
    }
    for (uint32_t i = 0; i < j->n; ++i) {
        plan *p = &j->plans[i];
        if (!p->layer || !p->quantize) {
            continue;
        }
        double err = act_error_of(final_stats(j, p->layer_name));
        if (err > def->max_layer_error) {
            p->quantize = false;
            snprintf(p->reason, sizeof p->reason, "fp32 (error %.3g > %.3g)", err, def->max_layer_error);
            snprintf(p->decision, sizeof p->decision, "fp32:error=%.3g", err);
        }
    }
    return WEFT_OK;
}

/* "quantization" metadata: format, decisions per tensor, and how they were reached. */
static char *quant_metadata_json(const job *j)
{
    const weft_quant_def *def = j->def;
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "format_version", WEFT_QUANT_FORMAT_VERSION);
    cJSON_AddStringToObject(root, "format", def->format == WEFT_QUANT_INT8 ? "int8" : "fp16");
    cJSON_AddNumberToObject(root, "min_dim", def->min_dim);
    cJSON *schemes = cJSON_AddObjectToObject(root, "schemes");
    for (uint32_t i = 0; i < j->n; ++i) {
        const char *scheme = !j->plans[i].quantize ? j->plans[i].reason
                             : def->format == WEFT_QUANT_INT8 ? "int8-per-channel-symmetric"
                                                              : "fp16";
        cJSON_AddStringToObject(schemes, j->plans[i].entry->name, scheme);
    }
    if (j->st1) {
        cJSON *cal = cJSON_AddObjectToObject(root, "calibration");
        cJSON_AddStringToObject(cal, "mode", "autoregressive fp32 rollouts, ccd off");
        cJSON_AddNumberToObject(cal, "sequences", j->seq_count);
        cJSON_AddNumberToObject(cal, "frames", j->frames);
        cJSON_AddNumberToObject(cal, "max_layer_error", def->max_layer_error);
        if (def->smoothquant_alpha >= 0.0f) {
            cJSON_AddNumberToObject(cal, "smoothquant_alpha", def->smoothquant_alpha);
            cJSON *applied = cJSON_AddArrayToObject(cal, "smoothed_norms");
            for (uint32_t g = 0; g < j->group_count; ++g) {
                if (j->group_state[g] == GROUP_APPLIED) {
                    cJSON_AddItemToArray(applied, cJSON_CreateString(j->groups[g].ln));
                }
            }
        }
    }
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    return text;
}

static weft_result fill_layers(const job *j, weft_quant_report *rep)
{
    uint32_t count = 0;
    for (uint32_t i = 0; i < j->n; ++i) {
        count += j->plans[i].layer;
    }
    rep->layers = calloc(count ? count : 1, sizeof *rep->layers);
    if (!rep->layers) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for the report");
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < j->n; ++i) {
        const plan *p = &j->plans[i];
        if (!p->layer) {
            continue;
        }
        weft_quant_layer_report *L = &rep->layers[k];
        snprintf(L->name, sizeof L->name, "%s", p->layer_name);
        L->out = (uint32_t)p->entry->shape[0];
        L->in = (uint32_t)p->entry->shape[1];
        snprintf(L->decision, sizeof L->decision, "%s", p->decision);
        L->weight_error = rep->tensors[i].rel_error;
        L->absmax = L->p999 = L->channel_ratio = L->act_error = L->act_error_plain = -1.0;
        const quant_layer_stats *s1 = j->st1 ? quant_stats_find(j->st1, j->c1, p->layer_name) : NULL;
        if (s1) {
            L->rows = s1->rows;
            L->absmax = s1->absmax;
            L->p999 = s1->p999;
            L->channel_ratio = s1->channel_ratio;
            L->act_error_plain = act_error_of(s1);
            L->act_error = act_error_of(final_stats(j, p->layer_name));
            L->channel_absmax = malloc(L->in * sizeof(float));
            if (!L->channel_absmax) {
                rep->layer_count = k + 1;
                return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for the report");
            }
            memcpy(L->channel_absmax, s1->ch_absmax, L->in * sizeof(float));
        }
        if (j->def->smoothquant_alpha >= 0.0f && j->st1) {
            int g = group_of_layer(j, p->layer_name);
            snprintf(L->smooth, sizeof L->smooth, "%s",
                     g >= 0 ? j->group_why[g] : "skipped: the input is not a LayerNorm output");
        } else {
            snprintf(L->smooth, sizeof L->smooth, "off");
        }
        k++;
    }
    rep->layer_count = k;
    return WEFT_OK;
}

static weft_result end_to_end(const job *j, const void *out, size_t out_size, weft_quant_e2e *e)
{
    weft_model *fp = NULL, *qm = NULL;
    weft_result r = weft_model_load_memory(j->ctx, j->in, j->in_size, &fp);
    if (r == WEFT_OK) {
        r = weft_model_load_memory(j->ctx, out, out_size, &qm);
    }
    uint32_t f1 = 0, f2 = 0;
    if (r == WEFT_OK) {
        r = weft_quant_rollout_mve(j->ctx, fp, WEFT_PRECISION_FP32, j->def->val, j->def->val_frames, &e->mve_fp32_cm,
                                   &f1);
    }
    if (r == WEFT_OK) {
        r = weft_quant_rollout_mve(j->ctx, qm,
                                   j->def->format == WEFT_QUANT_INT8 ? WEFT_PRECISION_INT8 : WEFT_PRECISION_FP16,
                                   j->def->val, j->def->val_frames, &e->mve_quant_cm, &f2);
    }
    weft_model_destroy(qm);
    weft_model_destroy(fp);
    if (r == WEFT_OK) {
        e->measured = true;
        snprintf(e->val, sizeof e->val, "%s", j->def->val);
        e->frames = f2;
        e->ratio = e->mve_fp32_cm > 0 ? e->mve_quant_cm / e->mve_fp32_cm : 1.0;
    }
    return r;
}

static weft_result check_def(const weft_quant_def *def)
{
    if (def->internal_cookie != QUANT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: def was not made by weft_default_quant_def()");
    }
    if (def->format != WEFT_QUANT_INT8 && def->format != WEFT_QUANT_FP16) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: unknown format %d", (int)def->format);
    }
    const bool calib = def->calib && def->calib[0];
    if (isnan(def->smoothquant_alpha) || def->smoothquant_alpha > 1.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: smoothquant alpha %g is outside [0, 1]",
                          (double)def->smoothquant_alpha);
    }
    if (def->smoothquant_alpha >= 0.0f && !calib) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: SmoothQuant needs calibration sequences");
    }
    if (!(def->max_layer_error > 0.0) || !isfinite(def->max_layer_error)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: max layer error %g must be positive and finite",
                          def->max_layer_error);
    }
    if (calib && def->calib_frames == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: calibration needs at least one frame");
    }
    if (def->calib_split && strcmp(def->calib_split, "train") != 0 && strcmp(def->calib_split, "val") != 0 &&
        strcmp(def->calib_split, "test") != 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: unknown split '%s' (train, val or test)",
                          def->calib_split);
    }
    return WEFT_OK;
}

static void job_free(job *j)
{
    if (j->plans) {
        for (uint32_t i = 0; i < j->n; ++i) {
            free(j->plans[i].q);
            free(j->plans[i].scale);
        }
    }
    free(j->plans);
    quant_list_free(j->seqs, j->seq_count);
    quant_stats_free(j->st1, j->c1);
    quant_stats_free(j->st2, j->c2);
    free(j->groups);
    weft__free(j->ctx, j->work, j->in_size);
    weft__st_header_free(j->ctx, &j->h);
}

/* Loader checks, the already-quantised check and a plan for every tensor. */
static weft_result job_start(job *j, weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size)
{
    memset(j, 0, sizeof *j);
    j->ctx = ctx;
    j->def = def;
    j->in = in;
    j->in_size = in_size;
    /* The loader's checks first: file rules, finiteness, and the architecture's required tensors. */
    weft_model *model = NULL;
    weft_result r = weft_model_load_memory(ctx, in, in_size, &model);
    if (r != WEFT_OK) {
        return r;
    }
    weft_model_destroy(model);
    r = weft__st_parse_memory(ctx, in, in_size, &j->h, &j->data);
    if (r != WEFT_OK) {
        return r;
    }
    if (meta_value(&j->h, "quantization")) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: the input is already quantised (metadata "
                                                       "'quantization' present)");
    }
    const char *keep = meta_value(&j->h, "keep_fp32");
    j->n = j->h.entry_count;
    j->plans = calloc(j->n ? j->n : 1, sizeof *j->plans);
    if (!j->plans) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
    }
    for (uint32_t i = 0; i < j->n; ++i) {
        j->plans[i].entry = &j->h.entries[i];
        j->plans[i].w = (const float *)(j->data + j->h.entries[i].begin);
        if ((r = plan_tensor(def, keep, &j->plans[i])) != WEFT_OK) {
            return r;
        }
    }
    return WEFT_OK;
}

/* The output image: quantised tensors, the rest as F32, and the metadata. */
static weft_result build_output(job *j, void **out, size_t *out_size, uint32_t *quantized)
{
    const weft_quant_def *def = j->def;
    const uint32_t n = j->n;
    weft_st_tensor_in *tensors = calloc(2 * (size_t)n + 1, sizeof *tensors);
    weft_st_meta *meta = calloc((size_t)j->h.meta_count + n + 2, sizeof *meta);
    char(*keys)[160] = calloc(n ? n : 1, sizeof *keys);
    char *quant_json = NULL;
    weft_result r = WEFT_OK;
    if (!tensors || !meta || !keys) {
        r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
        goto done;
    }
    uint32_t t = 0;
    *quantized = 0;
    for (uint32_t i = 0; i < n; ++i) {
        plan *p = &j->plans[i];
        const weft_st_entry *e = p->entry;
        if (!p->quantize) {
            tensors[t++] = (weft_st_tensor_in){e->name, WEFT_DTYPE_F32, e->rank, e->shape, p->w};
            continue;
        }
        (*quantized)++;
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
    quant_json = quant_metadata_json(j);
    if (!quant_json) {
        r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for the metadata");
        goto done;
    }
    uint32_t m = 0;
    for (uint32_t i = 0; i < j->h.meta_count; ++i) {
        const char *key = j->h.meta[i].key;
        if (strcmp(key, "precision") != 0 && strncmp(key, "quant.layer.", 12) != 0) {
            meta[m++] = j->h.meta[i];
        }
    }
    meta[m++] = (weft_st_meta){"precision", def->format == WEFT_QUANT_INT8 ? "int8" : "fp16"};
    meta[m++] = (weft_st_meta){"quantization", quant_json};
    /* One key per layer, the form the runtime and tools read: "quant.layer.<name>". */
    for (uint32_t i = 0; i < n; ++i) {
        if (j->plans[i].layer) {
            snprintf(keys[i], sizeof keys[i], "quant.layer.%s", j->plans[i].layer_name);
            meta[m++] = (weft_st_meta){keys[i], j->plans[i].decision};
        }
    }
    r = weft__st_write_memory(j->ctx, tensors, t, meta, m, out, out_size);
done:
    free(tensors);
    free(meta);
    free(keys);
    free(quant_json);
    return r;
}

weft_result weft_quantize_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                 void **out, size_t *out_size, weft_quant_report *report)
{
    if (!ctx || !def || !in || !out || !out_size) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: ctx, def, input and outputs are required");
    }
    weft_result r = check_def(def);
    if (r != WEFT_OK) {
        return r;
    }
    job j;
    void *image = NULL;
    size_t image_size = 0;
    uint32_t quantized = 0;
    weft_quant_e2e e2e = {0};
    r = job_start(&j, ctx, def, in, in_size);
    if (r == WEFT_OK && def->calib && def->calib[0]) {
        r = calibrate(&j, false);
    }
    if (r == WEFT_OK) {
        r = build_output(&j, &image, &image_size, &quantized);
    }
    if (r == WEFT_OK && def->val) {
        r = end_to_end(&j, image, image_size, &e2e);
    }
    if (r == WEFT_OK && report) {
        *report = (weft_quant_report){0};
        report->tensors = calloc(j.n ? j.n : 1, sizeof *report->tensors);
        if (!report->tensors) {
            r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for the report");
        } else {
            for (uint32_t i = 0; i < j.n; ++i) {
                report_errors(&report->tensors[i], &j.plans[i], def->format);
            }
            report->tensor_count = j.n;
            report->quantized_count = quantized;
            report->bytes_in = in_size;
            report->bytes_out = image_size;
            report->calib_sequences = j.st1 ? j.seq_count : 0;
            report->calib_frames = j.st1 ? j.frames : 0;
            report->smoothquant_alpha = j.st1 ? def->smoothquant_alpha : -1.0f;
            report->max_layer_error = def->max_layer_error;
            report->e2e = e2e;
            r = fill_layers(&j, report);
        }
        if (r != WEFT_OK) {
            weft_quant_report_free(report);
        }
    }
    if (r == WEFT_OK) {
        *out = image;
        *out_size = image_size;
    } else if (image) {
        weft__free(ctx, image, image_size);
    }
    job_free(&j);
    return r;
}

weft_result weft_quant_smooth_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                     void **out, size_t *out_size)
{
    if (!ctx || !def || !in || !out || !out_size) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: ctx, def, input and outputs are required");
    }
    weft_result r = check_def(def);
    if (r == WEFT_OK && (def->smoothquant_alpha < 0.0f || !def->calib || !def->calib[0])) {
        r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: SmoothQuant needs an alpha in [0, 1] and calibration "
                                                    "sequences");
    }
    if (r != WEFT_OK) {
        return r;
    }
    job j;
    r = job_start(&j, ctx, def, in, in_size);
    if (r == WEFT_OK) {
        r = calibrate(&j, true);
    }
    weft_st_tensor_in *tensors = NULL;
    weft_st_meta *meta = NULL;
    char *info = NULL;
    if (r == WEFT_OK) {
        tensors = calloc(j.n ? j.n : 1, sizeof *tensors);
        meta = calloc((size_t)j.h.meta_count + 1, sizeof *meta);
        cJSON *root = cJSON_CreateObject();
        cJSON_AddNumberToObject(root, "alpha", def->smoothquant_alpha);
        cJSON *applied = cJSON_AddArrayToObject(root, "norms");
        for (uint32_t g = 0; g < j.group_count; ++g) {
            if (j.group_state[g] == GROUP_APPLIED) {
                cJSON_AddItemToArray(applied, cJSON_CreateString(j.groups[g].ln));
            }
        }
        info = cJSON_PrintUnformatted(root);
        cJSON_Delete(root);
        if (!tensors || !meta || !info) {
            r = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory");
        }
    }
    if (r == WEFT_OK) {
        for (uint32_t i = 0; i < j.n; ++i) {
            const weft_st_entry *e = j.plans[i].entry;
            tensors[i] = (weft_st_tensor_in){e->name, WEFT_DTYPE_F32, e->rank, e->shape, j.plans[i].w};
        }
        uint32_t m = 0;
        for (uint32_t i = 0; i < j.h.meta_count; ++i) {
            if (strcmp(j.h.meta[i].key, "smoothquant") != 0) {
                meta[m++] = j.h.meta[i];
            }
        }
        meta[m++] = (weft_st_meta){"smoothquant", info};
        r = weft__st_write_memory(ctx, tensors, j.n, meta, m, out, out_size);
    }
    free(tensors);
    free(meta);
    free(info);
    job_free(&j);
    return r;
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
    weft_result r = quant_read_all(ctx, in_path, &in, &in_size);
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

/* ------------------------------------------------------------------------------------------ */
/* Report output                                                                               */

static void add_opt_number(cJSON *o, const char *key, double v)
{
    if (v >= 0) {
        cJSON_AddNumberToObject(o, key, v);
    } else {
        cJSON_AddNullToObject(o, key);
    }
}

void weft_quant_report_write_json(const weft_quant_report *report, weft_quant_format format, FILE *out)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "format", format == WEFT_QUANT_INT8 ? "int8" : "fp16");
    cJSON_AddNumberToObject(root, "format_version", WEFT_QUANT_FORMAT_VERSION);
    cJSON_AddNumberToObject(root, "bytes_in", (double)report->bytes_in);
    cJSON_AddNumberToObject(root, "bytes_out", (double)report->bytes_out);
    cJSON_AddNumberToObject(root, "quantized", report->quantized_count);
    cJSON *cal = cJSON_AddObjectToObject(root, "calibration");
    cJSON_AddNumberToObject(cal, "sequences", report->calib_sequences);
    cJSON_AddNumberToObject(cal, "frames", report->calib_frames);
    cJSON_AddStringToObject(cal, "mode", report->calib_frames ? "autoregressive fp32 rollouts, ccd off" : "none");
    add_opt_number(cal, "smoothquant_alpha", report->smoothquant_alpha);
    cJSON_AddNumberToObject(cal, "max_layer_error", report->max_layer_error);
    cJSON *e2e = cJSON_AddObjectToObject(root, "e2e");
    cJSON_AddBoolToObject(e2e, "measured", report->e2e.measured);
    if (report->e2e.measured) {
        cJSON_AddStringToObject(e2e, "val", report->e2e.val);
        cJSON_AddNumberToObject(e2e, "frames", report->e2e.frames);
        cJSON_AddNumberToObject(e2e, "mve_fp32_cm", report->e2e.mve_fp32_cm);
        cJSON_AddNumberToObject(e2e, "mve_quant_cm", report->e2e.mve_quant_cm);
        cJSON_AddNumberToObject(e2e, "ratio", report->e2e.ratio);
    }
    cJSON *layers = cJSON_AddArrayToObject(root, "layers");
    for (uint32_t i = 0; i < report->layer_count; ++i) {
        const weft_quant_layer_report *L = &report->layers[i];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", L->name);
        cJSON_AddNumberToObject(o, "out", L->out);
        cJSON_AddNumberToObject(o, "in", L->in);
        cJSON_AddStringToObject(o, "decision", L->decision);
        cJSON_AddNumberToObject(o, "weight_error", L->weight_error);
        add_opt_number(o, "act_error", L->act_error);
        add_opt_number(o, "act_error_plain", L->act_error_plain);
        cJSON_AddNumberToObject(o, "rows", (double)L->rows);
        add_opt_number(o, "absmax", L->absmax);
        add_opt_number(o, "p999", L->p999);
        add_opt_number(o, "channel_ratio", L->channel_ratio);
        cJSON_AddStringToObject(o, "smoothquant", L->smooth);
        if (L->channel_absmax) {
            cJSON *ch = cJSON_AddArrayToObject(o, "channel_absmax");
            for (uint32_t k = 0; k < L->in; ++k) {
                cJSON_AddItemToArray(ch, cJSON_CreateNumber(L->channel_absmax[k]));
            }
        }
        cJSON_AddItemToArray(layers, o);
    }
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

static void put_opt(FILE *out, double v)
{
    if (v >= 0) {
        fprintf(out, " %9.4f", v);
    } else {
        fprintf(out, " %9s", "-");
    }
}

void weft_quant_report_print(const weft_quant_report *report, FILE *out)
{
    fprintf(out, "%-22s %9s %-18s %9s %9s %9s %9s %9s %7s  %s\n", "layer", "out x in", "decision", "w_err", "act_err",
            "act_plain", "absmax", "p99.9", "ch_max/", "smoothquant");
    fprintf(out, "%-22s %9s %-18s %9s %9s %9s %9s %9s %7s\n", "", "", "", "", "", "", "", "", "median");
    for (uint32_t i = 0; i < report->layer_count; ++i) {
        const weft_quant_layer_report *L = &report->layers[i];
        char shape[24];
        snprintf(shape, sizeof shape, "%ux%u", L->out, L->in);
        fprintf(out, "%-22s %9s %-18s %9.4f", L->name, shape, L->decision, L->weight_error);
        put_opt(out, L->act_error);
        put_opt(out, L->act_error_plain);
        put_opt(out, L->absmax);
        put_opt(out, L->p999);
        if (L->channel_ratio >= 0) {
            fprintf(out, " %7.1f", L->channel_ratio);
        } else {
            fprintf(out, " %7s", "-");
        }
        fprintf(out, "  %s\n", L->smooth);
    }
    fprintf(out, "%u of %u tensors quantised, %llu -> %llu bytes (%.2fx smaller)\n", report->quantized_count,
            report->tensor_count, (unsigned long long)report->bytes_in, (unsigned long long)report->bytes_out,
            report->bytes_out ? (double)report->bytes_in / (double)report->bytes_out : 0.0);
    if (report->calib_frames) {
        fprintf(out, "calibration: %u sequences, %u frames (autoregressive fp32, ccd off)", report->calib_sequences,
                report->calib_frames);
        if (report->smoothquant_alpha >= 0) {
            fprintf(out, ", SmoothQuant alpha %.2f", (double)report->smoothquant_alpha);
        }
        fprintf(out, ", max layer error %.3g\n", report->max_layer_error);
    }
    if (report->e2e.measured) {
        fprintf(out, "end to end on %s (%u frames, ccd off): MVE fp32 %.4f cm, quantised %.4f cm, ratio %.4f\n",
                report->e2e.val, report->e2e.frames, report->e2e.mve_fp32_cm, report->e2e.mve_quant_cm,
                report->e2e.ratio);
    }
}
