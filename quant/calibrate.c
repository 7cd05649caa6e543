/* Calibration: autoregressive fp32 rollouts through the runtime with an observer on every linear
 * layer, recording input ranges and the error the quantised layer would make on those inputs;
 * and the rollout MVE used by the end-to-end check.
 *
 * Why autoregressive rather than teacher-forced: in a game the model only ever sees its own
 * previous outputs, so the activations worth calibrating for are the ones its own rollouts
 * produce, drift included. Rollouts start, as `weft eval` does, from the first two ground-truth
 * frames and then see only the collider. */
#include "quant_internal.h"

#include "core/core.h"
#include "kernels/qkernels.h"
#include "model/model.h"
#include "model/transformer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* |x| histogram: 32 linear sub-bins per octave over [2^-24, 2^16), plus one bin below (zeros
 * and tiny values) and one above. Relative resolution 1/32 of an octave's lower edge (~3%). */
#define HIST_SUB 32
#define HIST_EMIN (-24)
#define HIST_EMAX 16
#define HIST_BINS ((HIST_EMAX - HIST_EMIN) * HIST_SUB + 2)

typedef struct calib_layer {
    quant_layer_stats *st;
    const float *w, *b;                 /* fp32 weights and bias (b may be NULL) */
    uint64_t *hist;                     /* HIST_BINS */
    /* quantised forms for the error measurement */
    weft_q8_weights q8;
    int8_t *packed;
    float *pscale;
    int32_t *wsum;
    uint16_t *ht;                       /* fp16 W^T [in][out] */
} calib_layer;

struct quant_calib {
    calib_layer *layers;
    quant_layer_stats *stats;
    uint32_t count;
    weft_quant_format format;
    const weft_qkernels *qk;
    bool recording;
    char error[256];
    /* scratch, grown on demand (calibration is offline): int8 rows, row scales, layer output */
    void *qa, *qs, *yq;
    size_t qa_bytes, qs_bytes, yq_bytes;
};

static int cmp_stats(const void *a, const void *b)
{
    return strcmp(((const quant_layer_stats *)a)->name, ((const quant_layer_stats *)b)->name);
}

const quant_layer_stats *quant_stats_find(const quant_layer_stats *stats, uint32_t count, const char *name)
{
    quant_layer_stats key;
    if (strlen(name) >= sizeof key.name) {
        return NULL;
    }
    strcpy(key.name, name);
    return count ? bsearch(&key, stats, count, sizeof *stats, cmp_stats) : NULL;
}

void quant_stats_free(quant_layer_stats *stats, uint32_t count)
{
    for (uint32_t i = 0; stats && i < count; ++i) {
        free(stats[i].ch_absmax);
    }
    free(stats);
}

static int hist_bin(float ax)
{
    if (!(ax >= 0x1p-24f)) {
        return 0;
    }
    int e;
    float m = frexpf(ax, &e); /* ax = m 2^e, m in [0.5, 1) */
    int oct = e - 1 - HIST_EMIN;
    if (oct >= HIST_EMAX - HIST_EMIN) {
        return HIST_BINS - 1;
    }
    int sub = (int)((2.0f * m - 1.0f) * HIST_SUB);
    return 1 + oct * HIST_SUB + (sub < HIST_SUB ? sub : HIST_SUB - 1);
}

/* Upper edge of bin b. */
static double hist_edge(int b)
{
    if (b == 0) {
        return 0x1p-24;
    }
    int oct = (b - 1) / HIST_SUB, sub = (b - 1) % HIST_SUB;
    return ldexp(1.0 + (sub + 1.0) / HIST_SUB, oct + HIST_EMIN);
}

static bool grow(void **p, size_t *have, size_t need)
{
    if (need <= *have) {
        return true;
    }
    void *n = realloc(*p, need);
    if (!n) {
        return false;
    }
    *p = n;
    *have = need;
    return true;
}

static void observe(const char *name, const float *in, uint32_t rows, uint32_t in_cols, const float *out,
                    uint32_t out_cols, void *user)
{
    (void)out;
    struct quant_calib *c = user;
    if (!c->recording || c->error[0] || rows == 0) {
        return;
    }
    const quant_layer_stats *found = quant_stats_find(c->stats, c->count, name);
    if (!found) {
        snprintf(c->error, sizeof c->error, "the forward pass ran layer '%s', which has no fp32 weight in the file",
                 name);
        return;
    }
    calib_layer *L = &c->layers[found - c->stats];
    quant_layer_stats *st = L->st;
    if (in_cols != st->in || out_cols != st->out) {
        snprintf(c->error, sizeof c->error, "layer '%s' ran as %ux%u, its weight is %ux%u", name, out_cols, in_cols,
                 st->out, st->in);
        return;
    }
    const uint32_t K = st->in, N = st->out;
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = in + (size_t)r * K;
        for (uint32_t k = 0; k < K; ++k) {
            float a = fabsf(x[k]);
            if (a > st->ch_absmax[k]) {
                st->ch_absmax[k] = a;
            }
            L->hist[hist_bin(a)]++;
        }
    }
    st->rows += rows;
    if (!st->eligible) {
        return;
    }
    const size_t kp = weft_q8_pad_k(K);
    if (!grow(&c->yq, &c->yq_bytes, (size_t)rows * N * sizeof(float)) ||
        (c->format == WEFT_QUANT_INT8 && (!grow(&c->qa, &c->qa_bytes, (size_t)rows * kp) ||
                                          !grow(&c->qs, &c->qs_bytes, (size_t)rows * sizeof(float))))) {
        snprintf(c->error, sizeof c->error, "out of memory measuring layer '%s'", name);
        return;
    }
    float *yq = c->yq;
    /* The layer as the runtime computes it at reduced precision... */
    if (c->format == WEFT_QUANT_INT8) {
        c->qk->quantize_rows(in, rows, K, K, c->qa, (uint32_t)kp, c->qs);
        c->qk->gemm_q8(rows, c->qa, (uint32_t)kp, c->qs, &L->q8, L->b, yq, N, WEFT_ACT_NONE, false);
    } else {
        c->qk->gemm_f16(rows, N, K, in, K, L->ht, N, L->b, yq, N, WEFT_ACT_NONE, false);
    }
    /* ...against the exact fp32 layer, accumulated in double. */
    for (uint32_t r = 0; r < rows; ++r) {
        const float *x = in + (size_t)r * K;
        for (uint32_t n = 0; n < N; ++n) {
            const float *w = L->w + (size_t)n * K;
            double acc = L->b ? L->b[n] : 0.0;
            for (uint32_t k = 0; k < K; ++k) {
                acc += (double)x[k] * w[k];
            }
            double d = (double)yq[(size_t)r * N + n] - acc;
            st->err_num += d * d;
            st->err_den += acc * acc;
        }
    }
}

static void calib_free(struct quant_calib *c)
{
    for (uint32_t i = 0; c->layers && i < c->count; ++i) {
        calib_layer *L = &c->layers[i];
        free(L->hist);
        free(L->packed);
        free(L->pscale);
        free(L->wsum);
        free(L->ht);
    }
    free(c->layers);
    free(c->qa);
    free(c->qs);
    free(c->yq);
}

/* Builds the layer table from the model's tensors: every F32 rank-2 "<name>.weight". */
static weft_result calib_setup(struct quant_calib *c, const weft_model *m, quant_eligible_fn *eligible, void *user)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < m->tensor_count; ++i) {
        const weft_tensor *t = &m->tensors[i];
        size_t len = strlen(t->name);
        n += t->rank == 2 && t->dtype == WEFT_DTYPE_F32 && len > 7 && len - 7 < sizeof c->stats->name &&
             strcmp(t->name + len - 7, ".weight") == 0;
    }
    c->stats = calloc(n ? n : 1, sizeof *c->stats);
    c->layers = calloc(n ? n : 1, sizeof *c->layers);
    if (!c->stats || !c->layers) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for calibration");
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < m->tensor_count; ++i) {
        const weft_tensor *t = &m->tensors[i];
        size_t len = strlen(t->name);
        if (!(t->rank == 2 && t->dtype == WEFT_DTYPE_F32 && len > 7 && len - 7 < sizeof c->stats->name &&
              strcmp(t->name + len - 7, ".weight") == 0)) {
            continue;
        }
        quant_layer_stats *st = &c->stats[k++];
        memcpy(st->name, t->name, len - 7);
        st->name[len - 7] = '\0';
        st->out = (uint32_t)t->shape[0];
        st->in = (uint32_t)t->shape[1];
        st->absmax = st->p999 = st->channel_ratio = -1.0;
    }
    c->count = k;
    qsort(c->stats, k, sizeof *c->stats, cmp_stats);
    for (uint32_t i = 0; i < k; ++i) {
        quant_layer_stats *st = &c->stats[i];
        calib_layer *L = &c->layers[i];
        L->st = st;
        char nm[160];
        snprintf(nm, sizeof nm, "%s.weight", st->name);
        L->w = weft__model_find(m, nm)->data;
        snprintf(nm, sizeof nm, "%s.bias", st->name);
        const weft_tensor *b = weft__model_find(m, nm);
        L->b = b && b->dtype == WEFT_DTYPE_F32 && b->rank == 1 && b->shape[0] == st->out ? b->data : NULL;
        st->ch_absmax = calloc(st->in ? st->in : 1, sizeof(float));
        L->hist = calloc(HIST_BINS, sizeof(uint64_t));
        if (!st->ch_absmax || !L->hist) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for calibration");
        }
        st->eligible = eligible(st->name, st->out, st->in, user);
        if (!st->eligible) {
            continue;
        }
        const uint32_t N = st->out, K = st->in;
        if (c->format == WEFT_QUANT_INT8) {
            const uint32_t Np = weft_q8_pad_n(N), Kp = weft_q8_pad_k(K);
            int8_t *wq = malloc((size_t)N * K);
            float *scale = malloc((size_t)N * sizeof(float));
            L->packed = malloc((size_t)Np * Kp);
            L->pscale = malloc((size_t)Np * sizeof(float));
            L->wsum = malloc((size_t)Np * sizeof(int32_t));
            bool ok = wq && scale && L->packed && L->pscale && L->wsum;
            if (ok) {
                weft_q8_quantize_weights(L->w, N, K, wq, scale);
                weft_q8_pack(wq, scale, N, K, L->packed, L->pscale, L->wsum);
                L->q8 = (weft_q8_weights){N, K, Np, Kp, L->packed, L->pscale, L->wsum};
            }
            free(wq);
            free(scale);
            if (!ok) {
                return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for calibration");
            }
        } else {
            L->ht = malloc((size_t)N * K * sizeof(uint16_t));
            if (!L->ht) {
                return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "quantize: out of memory for calibration");
            }
            for (uint32_t o = 0; o < N; ++o) {
                for (uint32_t j = 0; j < K; ++j) {
                    L->ht[(size_t)j * N + o] = weft_f32_to_f16(L->w[(size_t)o * K + j]);
                }
            }
        }
    }
    return WEFT_OK;
}

static void garment_def_for(const quant_seq *s, const weft_model *m, weft_precision precision, weft_garment_def *d)
{
    *d = weft_default_garment_def();
    d->method = WEFT_METHOD_MODEL;
    d->model = m;
    d->precision = precision;
    d->ccd.enabled = false; /* the model alone, as the MVE tables in docs/ are measured */
    d->rest_positions = s->rest;
    d->vertex_count = s->V;
    d->triangles = s->faces;
    d->triangle_count = s->F;
    const size_t nv = (size_t)s->V * 3, nc = (size_t)s->Vc * 3;
    if (s->cpos) {
        d->collider_rest_positions = s->cpos + nc; /* the collider at frame 1, where rollouts start */
        d->collider_vertex_count = s->Vc;
        d->collider_triangles = s->cfaces;
        d->collider_triangle_count = s->Fc;
    }
    d->initial_positions = s->pos + nv;
}

static weft_result start_rollout(weft_context *ctx, const quant_seq *s, const weft_model *m, weft_precision precision,
                                 const char *dir, weft_garment **out)
{
    weft_garment_def d;
    garment_def_for(s, m, precision, &d);
    weft_garment *g = NULL;
    weft_result r = weft_garment_create(ctx, &d, &g);
    if (r == WEFT_OK) {
        r = weft_garment_set_state(g, s->pos + (size_t)s->V * 3, s->pos);
    }
    if (r != WEFT_OK) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", weft_last_error());
        weft_garment_destroy(g);
        return weft__fail(r, "quantize: %s: %s", dir, msg);
    }
    *out = g;
    return WEFT_OK;
}

static weft_result calib_sequence(weft_context *ctx, struct quant_calib *c, const weft_model *m, const char *dir,
                                  uint32_t want, uint32_t *seen)
{
    quant_seq s;
    weft_result r = quant_seq_load(dir, &s);
    if (r != WEFT_OK) {
        return r;
    }
    weft_garment *g = NULL;
    if (want == 0) {
        quant_seq_free(&s); /* checked, but its share of the frames is zero */
        return WEFT_OK;
    }
    if ((r = start_rollout(ctx, &s, m, WEFT_PRECISION_FP32, dir, &g)) != WEFT_OK) {
        quant_seq_free(&s);
        return r;
    }
    /* `want` recorded steps spread evenly over the T - 2 predicted frames. */
    const uint32_t avail = s.T - 2, k = want < avail ? want : avail;
    const size_t nc = (size_t)s.Vc * 3;
    for (uint32_t i = 0; i < avail && r == WEFT_OK; ++i) {
        const uint64_t a = (uint64_t)i * k / avail, b = (uint64_t)(i + 1) * k / avail;
        c->recording = b > a;
        if (s.cpos) {
            r = weft_garment_set_collider(g, s.cpos + (size_t)(i + 2) * nc);
        }
        if (r == WEFT_OK) {
            r = quant_seq_set_pins(g, &s, i + 2);
        }
        /* Observed steps re-run the constant layers and pack every layer's input: only the
         * recorded ones pay for it. */
        if (r == WEFT_OK) {
            r = weft__ct_set_observer(g, c->recording ? observe : NULL, c);
        }
        if (r == WEFT_OK) {
            r = weft_garment_step(g);
        }
        if (r != WEFT_OK) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s", weft_last_error());
            r = weft__fail(r, "quantize: calibration on %s, frame %u: %s", dir, i + 2, msg);
        } else if (c->error[0]) {
            r = weft__fail(WEFT_ERROR_TENSOR_SHAPE, "quantize: calibration on %s: %s", dir, c->error);
        } else {
            *seen += c->recording;
        }
        if (b >= k) {
            break; /* the last recorded frame */
        }
    }
    c->recording = false;
    weft_garment_destroy(g);
    quant_seq_free(&s);
    return r;
}

static void finish_stats(struct quant_calib *c)
{
    for (uint32_t i = 0; i < c->count; ++i) {
        quant_layer_stats *st = c->layers[i].st;
        const uint64_t *h = c->layers[i].hist;
        if (st->rows == 0) {
            continue;
        }
        double mx = 0;
        float *sorted = malloc(st->in * sizeof(float));
        for (uint32_t k = 0; k < st->in; ++k) {
            mx = fmax(mx, st->ch_absmax[k]);
        }
        st->absmax = mx;
        const uint64_t total = st->rows * st->in, target = total - total / 1000;
        uint64_t cum = 0;
        for (int b = 0; b < HIST_BINS; ++b) {
            cum += h[b];
            if (cum >= target) {
                st->p999 = fmin(hist_edge(b), mx);
                break;
            }
        }
        if (sorted) {
            memcpy(sorted, st->ch_absmax, st->in * sizeof(float));
            /* median by insertion sort: widths are a few hundred at most */
            for (uint32_t a = 1; a < st->in; ++a) {
                float v = sorted[a];
                uint32_t b = a;
                for (; b > 0 && sorted[b - 1] > v; --b) {
                    sorted[b] = sorted[b - 1];
                }
                sorted[b] = v;
            }
            double med = sorted[st->in / 2];
            st->channel_ratio = med > 0 ? mx / med : 0.0;
            free(sorted);
        }
    }
}

weft_result quant_calibrate(weft_context *ctx, const void *bytes, size_t size, weft_quant_format format,
                            char *const *seqs, uint32_t seq_count, uint32_t total_frames, quant_eligible_fn *eligible,
                            void *eligible_user, quant_layer_stats **out, uint32_t *out_count, uint32_t *frames_seen)
{
    if (seq_count == 0 || total_frames == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "quantize: calibration needs sequences and frames");
    }
    weft_model *m = NULL;
    weft_result r = weft_model_load_memory(ctx, bytes, size, &m);
    if (r != WEFT_OK) {
        return r;
    }
    if ((r = weft__ct_bind(m, NULL, NULL)) != WEFT_OK) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", weft_last_error());
        weft_model_destroy(m);
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "quantize: calibration runs clothtransformer models only (%s)", msg);
    }
    struct quant_calib c = {0};
    c.format = format;
    c.qk = weft_qkernels_for_isa(weft_context_isa(ctx));
    if (!c.qk) {
        c.qk = weft_qkernels_for_isa(WEFT_ISA_SCALAR);
    }
    r = calib_setup(&c, m, eligible, eligible_user);
    /* total_frames shared out as evenly as whole frames allow (a short sequence gives what it has) */
    uint32_t seen = 0;
    for (uint32_t i = 0; i < seq_count && r == WEFT_OK; ++i) {
        const uint32_t want = (uint32_t)((uint64_t)(i + 1) * total_frames / seq_count -
                                         (uint64_t)i * total_frames / seq_count);
        r = calib_sequence(ctx, &c, m, seqs[i], want, &seen);
    }
    if (r == WEFT_OK) {
        finish_stats(&c);
        *out = c.stats;
        *out_count = c.count;
        *frames_seen = seen;
    } else {
        quant_stats_free(c.stats, c.count);
    }
    calib_free(&c);
    weft_model_destroy(m);
    return r;
}

weft_result weft_quant_rollout_mve(weft_context *ctx, const weft_model *model, weft_precision precision,
                                   const char *dir, uint32_t max_frames, double *mve_cm, uint32_t *frames)
{
    if (!ctx || !model || !dir || !mve_cm || !frames) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_quant_rollout_mve: NULL argument");
    }
    quant_seq s;
    weft_result r = quant_seq_load(dir, &s);
    if (r != WEFT_OK) {
        return r;
    }
    weft_garment *g = NULL;
    if ((r = start_rollout(ctx, &s, model, precision, dir, &g)) != WEFT_OK) {
        quant_seq_free(&s);
        return r;
    }
    const size_t nv = (size_t)s.V * 3, nc = (size_t)s.Vc * 3;
    uint32_t last = s.T - 1;
    if (max_frames && max_frames + 1 < last) {
        last = max_frames + 1;
    }
    double err = 0;
    uint32_t n = 0;
    for (uint32_t t = 1; t < last && r == WEFT_OK; ++t) {
        if (s.cpos) {
            r = weft_garment_set_collider(g, s.cpos + (size_t)(t + 1) * nc);
        }
        if (r == WEFT_OK) {
            r = quant_seq_set_pins(g, &s, t + 1);
        }
        if (r == WEFT_OK) {
            r = weft_garment_step(g);
        }
        if (r != WEFT_OK) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s", weft_last_error());
            r = weft__fail(r, "quantize: rollout on %s at %s, frame %u: %s", dir,
                           precision == WEFT_PRECISION_INT8   ? "int8"
                           : precision == WEFT_PRECISION_FP16 ? "fp16"
                                                              : "fp32",
                           t + 1, msg);
            break;
        }
        const float *x = weft_garment_positions(g), *gt = s.pos + (size_t)(t + 1) * nv;
        for (uint32_t i = 0; i < s.V; ++i) {
            double dx = (double)x[3 * i] - gt[3 * i], dy = (double)x[3 * i + 1] - gt[3 * i + 1],
                   dz = (double)x[3 * i + 2] - gt[3 * i + 2];
            err += sqrt(dx * dx + dy * dy + dz * dz);
        }
        n++;
    }
    weft_garment_destroy(g);
    if (r == WEFT_OK) {
        *mve_cm = n ? err / ((double)n * s.V) * 100.0 : 0.0;
        *frames = n;
    }
    quant_seq_free(&s);
    return r;
}
