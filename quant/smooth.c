/* SmoothQuant-style migration of activation outliers into the weights, folded into the
 * preceding LayerNorm (Xiao et al., arXiv 2211.10438):
 *
 *   LN(x) = g * xhat + b,   Y = LN(x) W^T + c
 *   s_j = max|X_j|^a / max|W_j|^(1-a)        (X_j: input channel j over the calibration rows,
 *                                              W_j: column j over every layer reading this LN)
 *   g' = g / s,  b' = b / s,  W' = W diag(s)  =>  Y' = (LN(x) / s) (W diag(s))^T + c = Y
 *
 * exact up to fp32 rounding, and free at run time. Only layers whose input is a LayerNorm
 * output can be migrated this way; layers sharing one LN (q, k, v; gate, up) share one s. */
#include "quant_internal.h"

#include "core/core.h"
#include "model/model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static bool has_f32(const weft_model *m, const char *name, uint32_t rank)
{
    const weft_tensor *t = weft__model_find(m, name);
    return t && t->dtype == WEFT_DTYPE_F32 && t->rank == rank;
}

static void add_group(const weft_model *m, quant_smooth_group *out, uint32_t cap, uint32_t *n, const char *ln,
                      const char *const *layers, uint32_t count)
{
    if (*n >= cap) {
        return;
    }
    char a[160], b[160];
    snprintf(a, sizeof a, "%s.weight", ln);
    snprintf(b, sizeof b, "%s.bias", ln);
    if (!has_f32(m, a, 1) || !has_f32(m, b, 1)) {
        return;
    }
    quant_smooth_group *g = &out[*n];
    memset(g, 0, sizeof *g);
    snprintf(g->ln, sizeof g->ln, "%s", ln);
    for (uint32_t i = 0; i < count; ++i) {
        snprintf(a, sizeof a, "%s.weight", layers[i]);
        if (!has_f32(m, a, 2)) {
            return;
        }
        snprintf(g->layers[i], sizeof g->layers[i], "%s", layers[i]);
    }
    g->count = count;
    (*n)++;
}

/* The LayerNorm -> linear pairs of the clothtransformer forward pass (transformer.c: cross_block
 * reads ln_kv into k and v, ln_ff into ff.fc1; precompute reads ln_q into q; each temporal layer
 * reads ln1 into q, k, v and ln2 into gate and up; the head reads dec_ln). */
uint32_t quant_smooth_groups(const weft_model *m, quant_smooth_group *out, uint32_t cap)
{
    uint32_t n = 0;
    static const char *const xattn[2] = {"enc_xattn", "dec_xattn"};
    char ln[128], l0[128], l1[128], l2[128];
    for (int i = 0; i < 2; ++i) {
        snprintf(ln, sizeof ln, "%s.ln_q", xattn[i]);
        snprintf(l0, sizeof l0, "%s.q", xattn[i]);
        add_group(m, out, cap, &n, ln, (const char *const[]){l0}, 1);
        snprintf(ln, sizeof ln, "%s.ln_kv", xattn[i]);
        snprintf(l0, sizeof l0, "%s.k", xattn[i]);
        snprintf(l1, sizeof l1, "%s.v", xattn[i]);
        add_group(m, out, cap, &n, ln, (const char *const[]){l0, l1}, 2);
        snprintf(ln, sizeof ln, "%s.ln_ff", xattn[i]);
        snprintf(l0, sizeof l0, "%s.ff.fc1", xattn[i]);
        add_group(m, out, cap, &n, ln, (const char *const[]){l0}, 1);
    }
    for (uint32_t l = 0; l < 4096; ++l) {
        snprintf(ln, sizeof ln, "tmp.%u.ln1.weight", l);
        if (!weft__model_find(m, ln)) {
            break;
        }
        snprintf(ln, sizeof ln, "tmp.%u.ln1", l);
        snprintf(l0, sizeof l0, "tmp.%u.q", l);
        snprintf(l1, sizeof l1, "tmp.%u.k", l);
        snprintf(l2, sizeof l2, "tmp.%u.v", l);
        add_group(m, out, cap, &n, ln, (const char *const[]){l0, l1, l2}, 3);
        snprintf(ln, sizeof ln, "tmp.%u.ln2", l);
        snprintf(l0, sizeof l0, "tmp.%u.gate", l);
        snprintf(l1, sizeof l1, "tmp.%u.up", l);
        add_group(m, out, cap, &n, ln, (const char *const[]){l0, l1}, 2);
    }
    add_group(m, out, cap, &n, "dec_ln", (const char *const[]){"dec_head"}, 1);
    return n;
}

static float *find_f32(const weft_st_header *h, uint8_t *data, const char *name, uint64_t *count)
{
    for (uint32_t i = 0; i < h->entry_count; ++i) {
        if (strcmp(h->entries[i].name, name) == 0 && h->entries[i].dtype == WEFT_DTYPE_F32) {
            *count = h->entries[i].count;
            return (float *)(data + h->entries[i].begin);
        }
    }
    return NULL;
}

bool quant_smooth_apply_group(const weft_st_header *h, uint8_t *data, const quant_smooth_group *g,
                              const quant_layer_stats *stats, uint32_t stat_count, float alpha)
{
    char nm[160];
    uint64_t ng = 0, nb = 0;
    snprintf(nm, sizeof nm, "%s.weight", g->ln);
    float *gain = find_f32(h, data, nm, &ng);
    snprintf(nm, sizeof nm, "%s.bias", g->ln);
    float *bias = find_f32(h, data, nm, &nb);
    if (!gain || !bias || ng != nb || ng == 0) {
        return false;
    }
    const uint32_t K = (uint32_t)ng;
    float *w[QUANT_MAX_GROUP];
    uint32_t rows[QUANT_MAX_GROUP];
    double *xmax = calloc(K, sizeof(double)), *wmax = calloc(K, sizeof(double));
    float *s = malloc(K * sizeof(float));
    bool ok = xmax && wmax && s;
    for (uint32_t i = 0; ok && i < g->count; ++i) {
        const quant_layer_stats *st = quant_stats_find(stats, stat_count, g->layers[i]);
        uint64_t n = 0;
        snprintf(nm, sizeof nm, "%s.weight", g->layers[i]);
        w[i] = find_f32(h, data, nm, &n);
        ok = st && w[i] && st->in == K && st->rows > 0 && n == (uint64_t)st->out * K;
        if (!ok) {
            break;
        }
        rows[i] = st->out;
        for (uint32_t j = 0; j < K; ++j) {
            xmax[j] = fmax(xmax[j], st->ch_absmax[j]);
        }
        for (uint32_t r = 0; r < st->out; ++r) {
            for (uint32_t j = 0; j < K; ++j) {
                wmax[j] = fmax(wmax[j], fabs(w[i][(size_t)r * K + j]));
            }
        }
    }
    for (uint32_t j = 0; ok && j < K; ++j) {
        /* A dead channel (never non-zero, or an all-zero weight column) keeps s = 1. */
        double v = 1.0;
        if (xmax[j] > 0 && wmax[j] > 0) {
            v = pow(fmax(xmax[j], 1e-5), alpha) / pow(fmax(wmax[j], 1e-5), 1.0 - alpha);
        }
        s[j] = (float)v;
        ok = isfinite(s[j]) && s[j] > 0 && isfinite(gain[j] / s[j]) && isfinite(bias[j] / s[j]);
    }
    if (ok) {
        for (uint32_t i = 0; i < g->count; ++i) {
            for (uint32_t r = 0; r < rows[i]; ++r) {
                for (uint32_t j = 0; j < K; ++j) {
                    w[i][(size_t)r * K + j] *= s[j];
                }
            }
        }
        for (uint32_t j = 0; j < K; ++j) {
            gain[j] /= s[j];
            bias[j] /= s[j];
        }
    }
    free(xmax);
    free(wmax);
    free(s);
    return ok;
}
