/* ClothTransformer fp32 forward pass: encoder (cloth GNN + collider triangle tokens + learned-query
 * cross-attention), block-causal temporal transformer over a latent history, decoder (rest-shape
 * queries cross-attending to the predicted latents, GNN refinement, displacement head).
 * Mirrors tools/train/model.py operation for operation; see docs/MODEL.md. */
#include "model/transformer.h"
#include "model/crop.h"
#include "garment/garment.h"
#include "geometry/geometry.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------------------------ */
/* Binding tensors                                                                              */

static weft_result get_u32(const weft_model *m, const char *key, uint32_t lo, uint32_t hi, uint32_t *out)
{
    return weft__model_config_u32(m, key, lo, hi, out);
}

static weft_result get_pos(const weft_model *m, const char *key, float *out)
{
    double v;
    weft_result r = weft__model_config_number(m, key, &v);
    if (r != WEFT_OK) {
        return r;
    }
    if (!(v > 0.0) || !isfinite(v) || v > 1e9) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config '%s' = %g must be a positive finite number", key,
                          v);
    }
    *out = (float)v;
    return WEFT_OK;
}

static const char *const g_prior_names[WEFT_CT_PRIOR_COUNT] = {"skinned", "ballistic", "grasp"};

/* Optional number `key` in [lo, hi]; `*out` keeps its default when the file has no such key. */
static weft_result get_optional_in(const weft_model *m, const char *key, double lo, double hi, float *out)
{
    if (!weft__model_config_find(m, key)) {
        return WEFT_OK;
    }
    double v;
    weft_result r = weft__model_config_number(m, key, &v);
    if (r != WEFT_OK) {
        return r;
    }
    if (!isfinite(v) || v < lo || v > hi) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config '%s' = %g must lie in [%g, %g]", key, v, lo, hi);
    }
    *out = (float)v;
    return WEFT_OK;
}

/* The prior called `name`; WEFT_CT_PRIOR_COUNT for none. */
static weft_ct_prior prior_named(const char *name)
{
    uint32_t p = 0;
    while (p < WEFT_CT_PRIOR_COUNT && strcmp(name, g_prior_names[p]) != 0) {
        ++p;
    }
    return (weft_ct_prior)p;
}

static weft_result read_config(const weft_model *m, weft_ct_config *c)
{
    weft_ct_config t = {0};
    weft_result r;
    if ((r = get_u32(m, "K", 1, 65536, &t.K)) || (r = get_u32(m, "D", 1, 8192, &t.D)) ||
        (r = get_u32(m, "L", 1, WEFT_CT_MAX_LAYERS, &t.L)) || (r = get_u32(m, "H", 1, 1024, &t.H)) ||
        (r = get_u32(m, "history", 1, 64, &t.history)) || (r = get_u32(m, "ffn", 1, 65536, &t.ffn)) ||
        (r = get_u32(m, "nfreq", 1, 64, &t.nfreq)) || (r = get_u32(m, "gnn_layers", 0, WEFT_CT_MAX_GNN, &t.gnn_layers)) ||
        (r = get_pos(m, "vel_scale", &t.vel_scale)) || (r = get_pos(m, "area_scale", &t.area_scale)) ||
        (r = get_pos(m, "out_scale", &t.out_scale)) || (r = get_pos(m, "crop_margin", &t.crop_margin)) ||
        (r = get_pos(m, "ln_eps", &t.ln_eps)) || (r = weft__model_config_bool(m, "dec_skip", &t.dec_skip))) {
        return r;
    }
    if (t.D % t.H != 0) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: D = %u is not a multiple of H = %u", t.D, t.H);
    }
    if ((uint64_t)t.history * t.K > 65536u) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "model config: history x K = %u x %u is too large", t.history,
                          t.K);
    }
    const char *prior = NULL;
    if ((r = weft__model_config_string(m, "prior", &prior)) != WEFT_OK) {
        return r;
    }
    t.prior = prior_named(prior);
    if (t.prior == WEFT_CT_PRIOR_COUNT) {
        return weft__fail(WEFT_ERROR_BAD_METADATA,
                          "model config 'prior' = '%s': expected 'skinned', 'ballistic' or 'grasp'",
                          prior);
    }
    t.prior_beta = 1.0f;
    t.prior_decay = 1.0f;
    t.gravity_step = (float)(9.81 / 3600.0);
    if ((r = get_optional_in(m, "prior_beta", 0.0, 1.0, &t.prior_beta)) != WEFT_OK ||
        (r = get_optional_in(m, "prior_decay", 0.0, 1.0, &t.prior_decay)) != WEFT_OK ||
        (r = get_optional_in(m, "gravity_step", 0.0, 0.1, &t.gravity_step)) != WEFT_OK) {
        return r;
    }
    /* Optional keys. */
    if (weft__model_config_find(m, "requires_collider") &&
        (r = weft__model_config_bool(m, "requires_collider", &t.requires_collider)) != WEFT_OK) {
        return r;
    }
    if (weft__model_config_find(m, "vertex_count") &&
        (r = get_u32(m, "vertex_count", 0, UINT32_MAX, &t.vertex_count)) != WEFT_OK) {
        return r;
    }
    if (weft__model_config_find(m, "attach_output") &&
        (r = weft__model_config_bool(m, "attach_output", &t.attach_output)) != WEFT_OK) {
        return r;
    }
    *c = t;
    return WEFT_OK;
}

/* Tensor names "a.b.c" built without printf (names are short; overlong parts are cut). */
#define CT_NAME 160

static void name_join(char *out, const char *a, const char *b)
{
    size_t la = strlen(a), lb = strlen(b);
    if (la > CT_NAME / 2 - 1) {
        la = CT_NAME / 2 - 1;
    }
    if (lb > CT_NAME / 2 - 2) {
        lb = CT_NAME / 2 - 2;
    }
    memmove(out, a, la);
    out[la] = '.';
    memcpy(out + la + 1, b, lb);
    out[la + 1 + lb] = '\0';
}

static void name_index(char *out, const char *a, uint32_t i, const char *b)
{
    char num[16];
    int n = 0;
    char rev[16];
    do {
        rev[n++] = (char)('0' + i % 10);
        i /= 10;
    } while (i && n < 15);
    for (int j = 0; j < n; ++j) {
        num[j] = rev[n - 1 - j];
    }
    num[n] = '\0';
    char tmp[CT_NAME];
    name_join(tmp, a, num);
    name_join(out, tmp, b);
}

/* Requires a float32 tensor of the given shape and checks that it is finite. */
static weft_result need(const weft_model *m, const char *name, uint32_t rank, const uint64_t *dims, const float **out)
{
    const weft_tensor *t = NULL;
    weft_result r = weft__model_require(m, name, WEFT_DTYPE_F32, rank, dims, &t);
    if (r != WEFT_OK) {
        return r;
    }
    if (!weft__all_finite((const float *)t->data, (size_t)t->count)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "tensor '%s' contains NaN or infinity", name);
    }
    *out = (const float *)t->data;
    return WEFT_OK;
}

/* A layer weight in any stored form: F32, F16 (fp16 file) or "<name>.q8" + "<name>.scale" (int8
 * file). The loader has already checked finiteness, the int8 range and the scales. */
static weft_result need_weight(const weft_model *m, const char *name, uint32_t out, uint32_t in, weft_ct_linear *l)
{
    const uint64_t dims[2] = {out, in};
    const weft_tensor *t = weft__model_find(m, name);
    if (t && t->dtype == WEFT_DTYPE_F16) {
        weft_result r = weft__model_require(m, name, WEFT_DTYPE_F16, 2, dims, &t);
        l->src_f16 = r == WEFT_OK ? t->data : NULL;
        return r;
    }
    if (!t) {
        char qname[CT_NAME], sname[CT_NAME];
        name_join(qname, name, "q8");
        name_join(sname, name, "scale");
        if (weft__model_find(m, qname)) {
            const weft_tensor *q = NULL, *sc = NULL;
            weft_result r = weft__model_require(m, qname, WEFT_DTYPE_I8, 2, dims, &q);
            if (r == WEFT_OK) {
                r = weft__model_require(m, sname, WEFT_DTYPE_F32, 1, dims, &sc);
            }
            if (r == WEFT_OK) {
                l->src_q8 = q->data;
                l->src_scale = sc->data;
            }
            return r;
        }
    }
    return need(m, name, 2, dims, &l->w);
}

static weft_result need_linear(const weft_model *m, const char *prefix, uint32_t out, uint32_t in, weft_ct_linear *l)
{
    char name[CT_NAME];
    weft_result r;
    name_join(name, prefix, "weight");
    if ((r = need_weight(m, name, out, in, l)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "bias");
    if ((r = need(m, name, 1, (const uint64_t[]){out}, &l->b)) != WEFT_OK) {
        return r;
    }
    l->out = out;
    l->in = in;
    size_t n = strlen(prefix);
    if (n >= sizeof l->name) {
        n = sizeof l->name - 1; /* names are far shorter; cut rather than overflow */
    }
    memcpy(l->name, prefix, n);
    l->name[n] = '\0';
    char key[CT_NAME + 16];
    snprintf(key, sizeof key, "quant.layer.%s", prefix);
    const char *decision = weft__model_metadata(m, key);
    l->keep_f32 = decision && strncmp(decision, "fp32", 4) == 0;
    return WEFT_OK;
}

static weft_result need_norm(const weft_model *m, const char *prefix, uint32_t d, weft_ct_norm *n)
{
    char name[CT_NAME];
    weft_result r;
    name_join(name, prefix, "weight");
    if ((r = need(m, name, 1, (const uint64_t[]){d}, &n->g)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "bias");
    return need(m, name, 1, (const uint64_t[]){d}, &n->b);
}

static weft_result need_mlp(const weft_model *m, const char *prefix, uint32_t in, uint32_t hidden, uint32_t out,
                            weft_ct_mlp *p)
{
    char name[CT_NAME];
    weft_result r;
    name_join(name, prefix, "fc1");
    if ((r = need_linear(m, name, hidden, in, &p->fc1)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "fc2");
    return need_linear(m, name, out, hidden, &p->fc2);
}

static weft_result need_xattn(const weft_model *m, const char *prefix, uint32_t d, weft_ct_xattn *x)
{
    static const char *const lin[4] = {"q", "k", "v", "o"};
    weft_ct_linear *dst[4] = {&x->q, &x->k, &x->v, &x->o};
    char name[CT_NAME];
    weft_result r;
    for (int i = 0; i < 4; ++i) {
        name_join(name, prefix, lin[i]);
        if ((r = need_linear(m, name, d, d, dst[i])) != WEFT_OK) {
            return r;
        }
    }
    name_join(name, prefix, "ln_q");
    if ((r = need_norm(m, name, d, &x->ln_q)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "ln_kv");
    if ((r = need_norm(m, name, d, &x->ln_kv)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "ln_ff");
    if ((r = need_norm(m, name, d, &x->ln_ff)) != WEFT_OK) {
        return r;
    }
    name_join(name, prefix, "ff");
    return need_mlp(m, name, d, 2 * d, d, &x->ff);
}

weft_result weft__ct_bind(const weft_model *model, weft_ct_config *out_config, weft_ct_weights *out_weights)
{
    if (!model) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "clothtransformer: model is NULL");
    }
    const char *arch = weft__model_metadata(model, "architecture");
    if (!arch || strcmp(arch, WEFT_CT_ARCHITECTURE) != 0) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "model architecture '%s' is not '%s'", arch ? arch : "",
                          WEFT_CT_ARCHITECTURE);
    }
    weft_ct_config c;
    weft_result r = read_config(model, &c);
    if (r != WEFT_OK) {
        return r;
    }
    weft_ct_weights wb;
    memset(&wb, 0, sizeof wb);
    weft_ct_weights *w = &wb;
    const uint32_t D = c.D, F = c.nfreq;
    char name[CT_NAME];
    if ((r = need(model, "freqs", 1, (const uint64_t[]){F}, &w->freqs)) ||
        (r = need_mlp(model, "enc_cloth", 6 * F + 3, D, D, &w->enc_cloth)) ||
        (r = need_mlp(model, "enc_coll", 18 * F + 13, D, D, &w->enc_coll)) ||
        (r = need(model, "queries", 2, (const uint64_t[]){c.K, D}, &w->queries)) ||
        (r = need_xattn(model, "enc_xattn", D, &w->enc_xattn)) ||
        (r = need(model, "time_embed", 2, (const uint64_t[]){c.history, D}, &w->time_embed)) ||
        (r = need_mlp(model, "dec_rest", 6 * F, D, D, &w->dec_rest)) ||
        (r = need_xattn(model, "dec_xattn", D, &w->dec_xattn)) || (r = need_norm(model, "dec_ln", D, &w->dec_ln)) ||
        (r = need_linear(model, "dec_head", 3, D, &w->dec_head))) {
        goto done;
    }
    for (uint32_t i = 0; i < c.gnn_layers; ++i) {
        name_index(name, "enc_gnn", i, "mlp");
        if ((r = need_mlp(model, name, 2 * D, D, D, &w->enc_gnn[i])) != WEFT_OK) {
            goto done;
        }
        name_index(name, "dec_gnn", i, "mlp");
        if ((r = need_mlp(model, name, 2 * D, D, D, &w->dec_gnn[i])) != WEFT_OK) {
            goto done;
        }
    }
    for (uint32_t l = 0; l < c.L; ++l) {
        weft_ct_layer *ly = &w->layers[l];
        static const char *const sq[4] = {"q", "k", "v", "o"};
        weft_ct_linear *dst[4] = {&ly->q, &ly->k, &ly->v, &ly->o};
        for (int i = 0; i < 4 && r == WEFT_OK; ++i) {
            name_index(name, "tmp", l, sq[i]);
            r = need_linear(model, name, D, D, dst[i]);
        }
        if (r != WEFT_OK) {
            goto done;
        }
        char n2[CT_NAME], n3[CT_NAME], n4[CT_NAME], n5[CT_NAME];
        name_index(name, "tmp", l, "ln1");
        name_index(n2, "tmp", l, "ln2");
        name_index(n3, "tmp", l, "gate");
        name_index(n4, "tmp", l, "up");
        name_index(n5, "tmp", l, "down");
        if ((r = need_norm(model, name, D, &ly->ln1)) || (r = need_norm(model, n2, D, &ly->ln2)) ||
            (r = need_linear(model, n3, c.ffn, D, &ly->gate)) || (r = need_linear(model, n4, c.ffn, D, &ly->up)) ||
            (r = need_linear(model, n5, D, c.ffn, &ly->down))) {
            goto done;
        }
    }
    for (uint32_t f = 0; f < F; ++f) {
        if (!(fabsf(w->freqs[f]) < 1e6f)) {
            r = weft__fail(WEFT_ERROR_BAD_METADATA, "tensor 'freqs'[%u] = %g is out of range", f, (double)w->freqs[f]);
            goto done;
        }
    }
    if (out_config) {
        *out_config = c;
    }
    if (out_weights) {
        *out_weights = *w;
    }
done:
    return r;
}

weft_result weft__ct_validate(const weft_model *model) { return weft__ct_bind(model, NULL, NULL); }

bool weft__ct_binds_collider(const weft_model *model)
{
    /* A loaded file of this architecture has passed read_config, so its prior is valid. */
    if (!model || !model->arch || strcmp(model->arch->name, WEFT_CT_ARCHITECTURE) != 0) {
        return false;
    }
    const weft_config_value *v = weft__model_config_find(model, "prior");
    return v && v->kind == WEFT_CONFIG_STRING && prior_named(v->string) == WEFT_CT_PRIOR_SKINNED;
}

/* ------------------------------------------------------------------------------------------ */
/* Garment state                                                                               */

typedef struct ct_buf {
    float **ptr;
    size_t floats;
} ct_buf;

/* Stacked temporal-stream scratch for weft__ct_step_group, kept by the garment that led a group
 * and sized for `capacity` members (grown, never shrunk, until the garment is destroyed). */
typedef struct ct_batch {
    uint32_t capacity;
    float *x, *xln, *xq, *xk, *xv, *xa;  /* capacity hk x D */
    float *xr, *xg;                      /* capacity K x D */
    float *wide, *wide2;                 /* capacity hk x ffn */
    float *qa_store, *qa_scale;          /* int8 activations: capacity hk rows x padded K */
    size_t hkd, kd, hkf, qa_floats, rows;
} ct_batch;

typedef struct ct_state {
    weft_ct_config c;
    weft_ct_weights w;
    const weft_context *ctx;            /* allocator and the host's parallel_for hook */
    const weft_kernels *k;
    /* Reduced precision: the table, int8 activation scratch, deterministic attention scratch,
     * and one arena holding every layer's packed / transposed weights. */
    weft_precision prec;
    const weft_qkernels *qk;
    int8_t *qa;                         /* max rows x max padded K (in qa_store) */
    float *qa_store;
    float *qa_scale;                    /* max rows */
    float *att_s;                       /* deterministic attention scratch */
    void *arena;
    size_t arena_bytes;
    uint32_t N, M;                      /* cloth vertices, collider triangles */
    uint32_t Mk;                        /* the most collider tokens a step keeps: M, or the token
                                         * cap below it; the token buffers are sized for N + Mk */
    weft_crop crop;                     /* which collider triangles become tokens (model/crop.h) */
    uint32_t *rowptr, *col;             /* CSR mesh adjacency (both directions) */
    size_t col_count;
    uint8_t *tmask;                     /* (history K)^2 block-causal mask, NULL when history = 1 */

    /* constant per garment */
    float *rest_tok;                    /* N x D  decoder rest tokens (residual stream start) */
    float *dec_q;                       /* N x D  their query projection */
    float *enc_q;                       /* K x D  query projection of the learned queries */

    /* latent history (history x K x D) and the window being built */
    float *hist, *hist_new;
    bool hist_empty;

    /* scratch */
    float *xc;                          /* max(N, 3) x 3 centred points */
    float *feat;                        /* N x (6F + 3) */
    float *cfeat;                       /* Mk x (18F + 13) */
    float *tok;                         /* (N + Mk) x D: cloth tokens, then kept collider tokens */
    float *tln, *tk, *tv;               /* (N + Mk) x D */
    float *key_bias;                    /* N + Mk: the encoder keys' log weights (0 on cloth tokens;
                                         * log crop.represented on sampled collider tokens) */
    float *wide;                        /* max(N + Mk, hK) x max(2D, ffn) */
    float *wide2;                       /* hK x ffn */
    float *gcat;                        /* N x 2D */
    float *z, *za;                      /* K x D latent, attention out */
    float *x, *xln, *xq, *xk, *xv, *xa; /* hK x D temporal stream */
    float *dh, *da, *dln;               /* N x D decoder stream, attention out, normed */
    float *out3;                        /* N x 3 */
    /* The skinned prior: the LBS method's binding, made from the garment at creation exactly as
     * lbs_create makes it (the S track of the training data is `weft eval --method lbs`), and
     * S_t, S_{t+1} (N x 3). NULL for the other priors. */
    geo_skin *skin;
    float *skin_cur, *skin_next;
    bool skin_shared;                   /* skin is the garment's (g->skin), not owned */
    /* This garment's (an instance's own) S_{t+1} of its last step and the collider positions it
     * was evaluated from (geo_skin_key_*): the next step's S_t when the collider at t is still
     * those positions, as it is after every plain step; anything that rewrites the collider
     * (weft_garment_set_state, a cut, a level switch) fails the comparison. */
    float *skin_last, *skin_key;
    bool skin_key_set;
    float *attn_scratch;
    size_t attn_scratch_floats;
    /* Calibration observer (weft__ct_set_observer) and its packing scratch: obs_rows rows of
     * obs_cols floats each for the input and for the layer's own output. */
    weft_ct_observer_fn *observer;
    void *observer_user;
    float *obs_in, *obs_out;
    size_t obs_floats;
    ct_batch *batch;                    /* NULL until this garment heads a batched step */
    ct_buf bufs[40];
    uint32_t buf_count;
} ct_state;

static ct_state *state_of(weft_garment *g) { return (ct_state *)g->method_state; }

/* Rows of one int8 quantise-then-multiply step (their int8 activations stay in L1). */
#define CT_Q8_ROWS 64u

/* C = act(A W^T + b (+ C)) for `rows` rows at the garment's precision. Rows are independent
 * (each output row depends on its input row only, in every precision), so any split of the rows
 * gives the same bits. */
static void linear_rows(const ct_state *s, uint32_t rows, const weft_ct_linear *l, const float *A, uint32_t lda,
                        float *C, uint32_t ldc, weft_activation act, bool accumulate, int8_t *qa, float *qa_scale)
{
    if (s->prec == WEFT_PRECISION_INT8) {
        if (l->q8.packed) {
            /* a few rows at a time, so their int8 copy is read back from L1 (same bits) */
            for (uint32_t r0 = 0; r0 < rows; r0 += CT_Q8_ROWS) {
                const uint32_t n = rows - r0 < CT_Q8_ROWS ? rows - r0 : CT_Q8_ROWS;
                s->qk->quantize_rows(A + (size_t)r0 * lda, n, l->in, lda, qa, l->q8.Kp, qa_scale);
                s->qk->gemm_q8(n, qa, l->q8.Kp, qa_scale, &l->q8, l->b, C + (size_t)r0 * ldc, ldc, act, accumulate);
            }
        } else {
            s->qk->gemm_det(rows, l->out, l->in, A, lda, l->wt, l->out, l->b, C, ldc, act, accumulate);
        }
        return;
    }
    if (s->prec == WEFT_PRECISION_FP16 && l->ht) {
        s->qk->gemm_f16(rows, l->out, l->in, A, lda, l->ht, l->out, l->b, C, ldc, act, accumulate);
        return;
    }
    s->k->gemm(rows, l->out, l->in, A, lda, l->w, l->in, l->b, C, ldc, act, accumulate);
}

typedef struct linear_job {
    const ct_state *s;
    const weft_ct_linear *l;
    const float *A;
    float *C;
    uint32_t lda, ldc;
    weft_activation act;
    bool accumulate;
} linear_job;

static void linear_chunk(uint32_t begin, uint32_t end, uint32_t worker, void *job_ptr)
{
    (void)worker;
    const linear_job *j = job_ptr;
    const ct_state *s = j->s;
    const size_t kp = j->l->q8.Kp;
    linear_rows(s, end - begin, j->l, j->A + (size_t)begin * j->lda, j->lda, j->C + (size_t)begin * j->ldc, j->ldc,
                j->act, j->accumulate, s->qa ? s->qa + (size_t)begin * kp : NULL,
                s->qa_scale ? s->qa_scale + begin : NULL);
}

/* Row blocks of the big per-vertex layers go through the host's parallel_for when it has one. */
#define CT_PARALLEL_MIN_ROWS 256u
#define CT_PARALLEL_CHUNK 128u

/* Shows the observer a layer's input and its own output, both packed (stride = width). A layer
 * that accumulated into a residual is run a second time without the residual, so the normal
 * path's bits and cost are untouched; rows are independent, so the rerun gives the same
 * per-row values the residual received. */
static void observe(const ct_state *s, uint32_t rows, const weft_ct_linear *l, const float *A, uint32_t lda,
                    const float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    const float *in = A, *out = C;
    if (lda != l->in) {
        for (uint32_t r = 0; r < rows; ++r) {
            memcpy(s->obs_in + (size_t)r * l->in, A + (size_t)r * lda, l->in * sizeof(float));
        }
        in = s->obs_in;
    }
    if (accumulate) {
        linear_rows(s, rows, l, A, lda, s->obs_out, l->out, act, false, s->qa, s->qa_scale);
        out = s->obs_out;
    } else if (ldc != l->out) {
        for (uint32_t r = 0; r < rows; ++r) {
            memcpy(s->obs_out + (size_t)r * l->out, C + (size_t)r * ldc, l->out * sizeof(float));
        }
        out = s->obs_out;
    }
    s->observer(l->name, in, rows, l->in, out, l->out, s->observer_user);
}

static void linear(const ct_state *s, uint32_t rows, const weft_ct_linear *l, const float *A, uint32_t lda,
                   float *C, uint32_t ldc, weft_activation act, bool accumulate)
{
    if (rows == 0) {
        return;
    }
    if (rows >= CT_PARALLEL_MIN_ROWS && s->ctx->parallel_for) {
        linear_job job = {s, l, A, C, lda, ldc, act, accumulate};
        weft__parallel_for(s->ctx, linear_chunk, rows, CT_PARALLEL_CHUNK, &job);
    } else {
        linear_rows(s, rows, l, A, lda, C, ldc, act, accumulate, s->qa, s->qa_scale);
    }
    if (s->observer) {
        observe(s, rows, l, A, lda, C, ldc, act, accumulate);
    }
}

/* Up to three layers reading the same rows of A (k and v; q, k and v; gate and up), no
 * activation, no residual. On the int8 path the rows are quantised once and every layer's GEMM
 * reads the same int8 rows: the same bits as quantising per layer (the quantisation is a
 * function of the row alone), at a third or half the cost. */
typedef struct shared_job {
    const ct_state *s;
    const weft_ct_linear *const *l;
    uint32_t count;
    const float *A;
    float *const *C;
    uint32_t lda;
    /* optional LayerNorm in front: Y = LN(X) (then A == Y) is written row block by row block */
    const weft_ct_norm *ln;
    const float *X;
    float *Y;
    float eps;
} shared_job;

static bool shares_q8(const weft_ct_linear *const *l, uint32_t count)
{
    for (uint32_t i = 0; i < count; ++i) {
        if (!l[i]->q8.packed || l[i]->q8.Kp != l[0]->q8.Kp || l[i]->in != l[0]->in) {
            return false;
        }
    }
    return true;
}

static void shared_rows(const shared_job *j, uint32_t begin, uint32_t end)
{
    const ct_state *s = j->s;
    const uint32_t kp = j->l[0]->q8.Kp, in = j->l[0]->in;
    int8_t *qa = s->qa + (size_t)begin * kp;
    float *qs = s->qa_scale + begin;
    for (uint32_t r0 = begin; r0 < end; r0 += CT_Q8_ROWS) {
        const uint32_t n = end - r0 < CT_Q8_ROWS ? end - r0 : CT_Q8_ROWS;
        if (j->ln) { /* lda == in here: the normed rows are packed */
            s->qk->layernorm_det(j->X + (size_t)r0 * in, j->Y + (size_t)r0 * in, n, in, in, j->ln->g, j->ln->b,
                                 j->eps);
        }
        s->qk->quantize_rows(j->A + (size_t)r0 * j->lda, n, in, j->lda, qa, kp, qs);
        for (uint32_t i = 0; i < j->count; ++i) {
            const weft_ct_linear *l = j->l[i];
            s->qk->gemm_q8(n, qa, kp, qs, &l->q8, l->b, j->C[i] + (size_t)r0 * l->out, l->out, WEFT_ACT_NONE,
                           false);
        }
    }
}

static void shared_chunk(uint32_t begin, uint32_t end, uint32_t worker, void *job_ptr)
{
    (void)worker;
    shared_rows(job_ptr, begin, end);
}

static void shared_run(const ct_state *s, uint32_t rows, shared_job *job)
{
    if (rows >= CT_PARALLEL_MIN_ROWS && s->ctx->parallel_for) {
        weft__parallel_for(s->ctx, shared_chunk, rows, CT_PARALLEL_CHUNK, job);
    } else {
        shared_rows(job, 0, rows);
    }
}

/* C[i] = A W_i^T + b_i for each layer; C[i] has stride l[i]->out. */
static void linear_shared(const ct_state *s, uint32_t rows, uint32_t count, const weft_ct_linear *const *l,
                          const float *A, uint32_t lda, float *const *C)
{
    if (rows == 0) {
        return;
    }
    if (s->prec != WEFT_PRECISION_INT8 || !shares_q8(l, count)) {
        for (uint32_t i = 0; i < count; ++i) {
            linear(s, rows, l[i], A, lda, C[i], l[i]->out, WEFT_ACT_NONE, false);
        }
        return;
    }
    shared_job job = {s, l, count, A, C, lda, NULL, NULL, NULL, 0.0f};
    shared_run(s, rows, &job);
    for (uint32_t i = 0; s->observer && i < count; ++i) {
        observe(s, rows, l[i], A, lda, C[i], l[i]->out, WEFT_ACT_NONE, false);
    }
}

static void norm(const ct_state *s, const weft_ct_norm *n, const float *X, float *Y, uint32_t rows, uint32_t d,
                 float eps)
{
    if (s->prec == WEFT_PRECISION_INT8) {
        s->qk->layernorm_det(X, Y, rows, d, d, n->g, n->b, eps);
    } else {
        s->k->layernorm(X, Y, rows, d, d, n->g, n->b, eps);
    }
}

static void ct_posembed(const ct_state *s, const float *x, uint32_t n, const float *freq, uint32_t nfreq, float *out,
                        uint32_t ldo)
{
    if (s->prec == WEFT_PRECISION_INT8) {
        s->qk->posembed_det(x, n, 3, freq, nfreq, out, ldo);
    } else {
        s->k->posembed(x, n, 3, freq, nfreq, out, ldo);
    }
}

static void ct_swiglu(const ct_state *s, const float *gate, const float *up, float *out, size_t n)
{
    if (s->prec == WEFT_PRECISION_INT8) {
        s->qk->swiglu_det(gate, up, out, n);
    } else {
        s->k->swiglu(gate, up, out, n);
    }
}

/* Y = LN(X) (rows x D, packed), then C[i] = Y W_i^T + b_i. On the int8 path without an observer
 * the norm, the quantisation and the GEMMs run row block by row block, so the normed rows are
 * read back from L1 (same bits: every step is per row). */
static void norm_linear_shared(const ct_state *s, const weft_ct_norm *n, const float *X, float *Y, uint32_t rows,
                               uint32_t count, const weft_ct_linear *const *l, float *const *C)
{
    const uint32_t D = s->c.D;
    if (s->prec != WEFT_PRECISION_INT8 || s->observer || rows == 0 || !shares_q8(l, count) || l[0]->in != D) {
        norm(s, n, X, Y, rows, D, s->c.ln_eps);
        linear_shared(s, rows, count, l, Y, D, C);
        return;
    }
    shared_job job = {s, l, count, Y, C, D, n, X, Y, s->c.ln_eps};
    shared_run(s, rows, &job);
}

/* Multi-head attention. The int8 path runs the deterministic kernel (the composition of in-order
 * products and the canonical softmax, fused per block of queries), so it is bit-identical on
 * every ISA; the others use the fused fp32 kernel. */
static void ct_attention(ct_state *s, const float *Q, const float *K, const float *V, uint32_t nq, uint32_t nk,
                         float scale, const uint8_t *mask, const float *key_bias, float *out)
{
    const uint32_t D = s->c.D, H = s->c.H, dh = D / H;
    if (s->prec != WEFT_PRECISION_INT8) {
        s->k->attention(Q, D, K, D, V, D, nq, nk, H, dh, scale, mask, key_bias, out, D, s->attn_scratch);
        return;
    }
    s->qk->attention_det(Q, D, K, D, V, D, nq, nk, H, dh, scale, mask, key_bias, out, D, s->att_s);
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Unique undirected mesh edges as a CSR adjacency in both directions. */
static weft_result build_csr(weft_garment *g, ct_state *s)
{
    size_t n = (size_t)g->triangle_count * 6;
    uint64_t *pairs = weft__alloc(g->ctx, n * sizeof(uint64_t));
    if (!pairs) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t t = 0; t < g->triangle_count; ++t) {
        const uint32_t *tri = g->triangles + 3 * (size_t)t;
        for (int e = 0; e < 3; ++e) {
            uint64_t a = tri[e], b = tri[(e + 1) % 3];
            pairs[6 * (size_t)t + 2 * e] = a << 32 | b;
            pairs[6 * (size_t)t + 2 * e + 1] = b << 32 | a;
        }
    }
    qsort(pairs, n, sizeof(uint64_t), cmp_u64);
    size_t u = 0;
    for (size_t i = 0; i < n; ++i) {
        if (u == 0 || pairs[i] != pairs[u - 1]) {
            pairs[u++] = pairs[i];
        }
    }
    s->rowptr = weft__alloc(g->ctx, ((size_t)s->N + 1) * sizeof(uint32_t));
    s->col = weft__alloc(g->ctx, (u ? u : 1) * sizeof(uint32_t));
    s->col_count = u ? u : 1;
    if (!s->rowptr || !s->col) {
        weft__free(g->ctx, pairs, n * sizeof(uint64_t));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t i = 0; i < u; ++i) {
        s->rowptr[(pairs[i] >> 32) + 1]++;
        s->col[i] = (uint32_t)(pairs[i] & 0xffffffffu);
    }
    for (uint32_t v = 0; v < s->N; ++v) {
        s->rowptr[v + 1] += s->rowptr[v];
    }
    weft__free(g->ctx, pairs, n * sizeof(uint64_t));
    return WEFT_OK;
}

static bool add_buf(weft_garment *g, ct_state *s, float **ptr, size_t floats)
{
    if (floats == 0) {
        floats = 1;
    }
    *ptr = weft__alloc(g->ctx, floats * sizeof(float));
    s->bufs[s->buf_count++] = (ct_buf){ptr, floats};
    return *ptr != NULL;
}

/* The instance's own S_{t+1} and its key (skin_eval). */
static bool skin_cache_alloc(weft_garment *g, ct_state *s)
{
    s->skin_key_set = false;
    return add_buf(g, s, &s->skin_last, (size_t)s->N * 3) &&
           add_buf(g, s, &s->skin_key, geo_skin_key_floats(s->skin));
}

static void batch_free(const weft_context *ctx, ct_batch *b)
{
    if (!b) {
        return;
    }
    float **big[6] = {&b->x, &b->xln, &b->xq, &b->xk, &b->xv, &b->xa};
    for (int i = 0; i < 6; ++i) {
        weft__free(ctx, *big[i], b->hkd * sizeof(float));
    }
    weft__free(ctx, b->xr, b->kd * sizeof(float));
    weft__free(ctx, b->xg, b->kd * sizeof(float));
    weft__free(ctx, b->wide, b->hkf * sizeof(float));
    weft__free(ctx, b->wide2, b->hkf * sizeof(float));
    weft__free(ctx, b->qa_store, b->qa_floats * sizeof(float));
    weft__free(ctx, b->qa_scale, b->rows * sizeof(float));
    weft__free(ctx, b, sizeof *b);
}

static void ct_destroy(weft_garment *g)
{
    ct_state *s = state_of(g);
    if (!s) {
        return;
    }
    batch_free(g->ctx, s->batch);
    if (g->asset) { /* an instance: its history and observer buffers; the rest is the asset's */
        for (uint32_t i = 0; i < s->buf_count; ++i) {
            weft__free(g->ctx, *s->bufs[i].ptr, s->bufs[i].floats * sizeof(float));
        }
        weft__free(g->ctx, s->obs_in, s->obs_floats * sizeof(float));
        weft__free(g->ctx, s->obs_out, s->obs_floats * sizeof(float));
        weft__free(g->ctx, s, sizeof *s);
        g->method_state = NULL;
        return;
    }
    if (!s->skin_shared) {
        geo_skin_destroy(g->ctx, s->skin);
    }
    for (uint32_t i = 0; i < s->buf_count; ++i) {
        weft__free(g->ctx, *s->bufs[i].ptr, s->bufs[i].floats * sizeof(float));
    }
    size_t hk = (size_t)s->c.history * s->c.K;
    weft__free(g->ctx, s->tmask, hk * hk);
    weft__free(g->ctx, s->rowptr, ((size_t)s->N + 1) * sizeof(uint32_t));
    weft__free(g->ctx, s->col, s->col_count * sizeof(uint32_t));
    weft__free(g->ctx, s->arena, s->arena_bytes);
    weft__free(g->ctx, s->obs_in, s->obs_floats * sizeof(float));
    weft__free(g->ctx, s->obs_out, s->obs_floats * sizeof(float));
    weft__crop_free(g->ctx, &s->crop);
    weft__free(g->ctx, s, sizeof *s);
    g->method_state = NULL;
}

static size_t max_sz(size_t a, size_t b) { return a > b ? a : b; }

/* Decoder rest tokens and query projections, and the encoder's learned-query projection: all
 * constant for the garment's life. */
static void precompute(weft_garment *g, ct_state *s)
{
    const weft_ct_config *c = &s->c;
    const uint32_t N = s->N, D = c->D, F = c->nfreq;
    double m[3] = {0, 0, 0};
    for (uint32_t i = 0; i < N; ++i) {
        for (int d = 0; d < 3; ++d) {
            m[d] += g->rest[3 * (size_t)i + d];
        }
    }
    float mf[3];
    for (int d = 0; d < 3; ++d) {
        mf[d] = (float)(m[d] / N);
    }
    for (uint32_t i = 0; i < N; ++i) {
        for (int d = 0; d < 3; ++d) {
            s->xc[3 * (size_t)i + d] = g->rest[3 * (size_t)i + d] - mf[d];
        }
    }
    ct_posembed(s, s->xc, N, s->w.freqs, F, s->feat, 6 * F);
    linear(s, N, &s->w.dec_rest.fc1, s->feat, 6 * F, s->dh, D, WEFT_ACT_GELU, false);
    linear(s, N, &s->w.dec_rest.fc2, s->dh, D, s->rest_tok, D, WEFT_ACT_NONE, false);
    norm(s, &s->w.dec_xattn.ln_q, s->rest_tok, s->dln, N, D, c->ln_eps);
    linear(s, N, &s->w.dec_xattn.q, s->dln, D, s->dec_q, D, WEFT_ACT_NONE, false);
    norm(s, &s->w.enc_xattn.ln_q, s->w.queries, s->z, c->K, D, c->ln_eps);
    linear(s, c->K, &s->w.enc_xattn.q, s->z, D, s->enc_q, D, WEFT_ACT_NONE, false);
}

/* Every linear layer of the bound weights (for building their reduced-precision forms). */
static uint32_t all_linears(weft_ct_weights *w, const weft_ct_config *c, weft_ct_linear **out)
{
    uint32_t n = 0;
    weft_ct_mlp *mlps[3] = {&w->enc_cloth, &w->enc_coll, &w->dec_rest};
    for (int i = 0; i < 3; ++i) {
        out[n++] = &mlps[i]->fc1;
        out[n++] = &mlps[i]->fc2;
    }
    for (uint32_t i = 0; i < c->gnn_layers; ++i) {
        out[n++] = &w->enc_gnn[i].fc1;
        out[n++] = &w->enc_gnn[i].fc2;
        out[n++] = &w->dec_gnn[i].fc1;
        out[n++] = &w->dec_gnn[i].fc2;
    }
    weft_ct_xattn *xs[2] = {&w->enc_xattn, &w->dec_xattn};
    for (int i = 0; i < 2; ++i) {
        out[n++] = &xs[i]->q;
        out[n++] = &xs[i]->k;
        out[n++] = &xs[i]->v;
        out[n++] = &xs[i]->o;
        out[n++] = &xs[i]->ff.fc1;
        out[n++] = &xs[i]->ff.fc2;
    }
    for (uint32_t l = 0; l < c->L; ++l) {
        weft_ct_layer *ly = &w->layers[l];
        weft_ct_linear *ll[7] = {&ly->q, &ly->k, &ly->v, &ly->o, &ly->gate, &ly->up, &ly->down};
        for (int i = 0; i < 7; ++i) {
            out[n++] = ll[i];
        }
    }
    out[n++] = &w->dec_head;
    return n;
}

#define CT_MAX_LINEARS (6u + 4u * WEFT_CT_MAX_GNN + 12u + 7u * WEFT_CT_MAX_LAYERS + 1u)

static size_t align64(size_t n) { return (n + 63u) & ~(size_t)63u; }

/* Runs in int8 (fp16) on those paths: wide enough, and not kept in fp32 by the file. */
static bool q8_eligible(const weft_ct_linear *l)
{
    return !l->keep_f32 && l->in >= WEFT_CT_Q8_MIN_DIM && l->out >= WEFT_CT_Q8_MIN_DIM;
}

/* Whether a layer needs an fp32 copy of its weight built: its file form is int8 or fp16 and
 * the garment's precision reads fp32 (fp32 itself, the fp16 path's small layers, the int8
 * path's quantiser input when the file is fp16, or its small layers). */
static bool needs_f32(const weft_ct_linear *l, weft_precision prec)
{
    if (l->w) {
        return false;
    }
    if (prec == WEFT_PRECISION_INT8) {
        return !(l->src_q8 && q8_eligible(l));
    }
    if (prec == WEFT_PRECISION_FP16) {
        return !(l->src_f16 && q8_eligible(l));
    }
    return true;
}

/* Bytes of the built forms of one layer at a precision. */
static size_t reduced_bytes(const weft_ct_linear *l, weft_precision prec)
{
    size_t bytes = needs_f32(l, prec) ? align64((size_t)l->in * l->out * sizeof(float)) : 0;
    if (prec == WEFT_PRECISION_INT8 && q8_eligible(l)) {
        size_t Np = weft_q8_pad_n(l->out), Kp = weft_q8_pad_k(l->in);
        bytes += align64(Np * Kp) + align64(Np * sizeof(float)) + align64(Np * sizeof(int32_t));
    } else if (prec == WEFT_PRECISION_INT8) {
        bytes += align64((size_t)l->in * l->out * sizeof(float));
    } else if (prec == WEFT_PRECISION_FP16 && q8_eligible(l)) {
        bytes += align64((size_t)l->in * l->out * sizeof(uint16_t));
    }
    return bytes;
}

/* Builds every layer's working forms in one arena. Weights are quantised exactly as the offline
 * quantiser does (per output channel, round half to even), and int8 files are packed as stored,
 * so an int8 garment gives the same bits whether its model file is fp32 or `weft quantize` int8;
 * likewise for fp16. Layers stored quantised are expanded to fp32 where the precision needs it. */
static weft_result build_reduced(weft_garment *g, ct_state *s)
{
    weft_ct_linear *lin[CT_MAX_LINEARS];
    uint32_t n = all_linears(&s->w, &s->c, lin);
    size_t bytes = 0, max_wq = 0;
    for (uint32_t i = 0; i < n; ++i) {
        bytes += reduced_bytes(lin[i], s->prec);
        max_wq = max_sz(max_wq, (size_t)lin[i]->in * lin[i]->out);
    }
    if (bytes == 0) {
        return WEFT_OK;
    }
    s->arena = weft__alloc(g->ctx, bytes);
    s->arena_bytes = bytes;
    int8_t *wq = s->prec == WEFT_PRECISION_INT8 ? weft__alloc(g->ctx, max_wq) : NULL;
    float *scale = s->prec == WEFT_PRECISION_INT8 ? weft__alloc(g->ctx, max_wq * sizeof(float)) : NULL;
    if (!s->arena || (s->prec == WEFT_PRECISION_INT8 && (!wq || !scale))) {
        weft__free(g->ctx, wq, max_wq);
        weft__free(g->ctx, scale, max_wq * sizeof(float));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    uint8_t *p = s->arena;
    for (uint32_t i = 0; i < n; ++i) {
        weft_ct_linear *l = lin[i];
        const uint32_t O = l->out, I = l->in;
        const size_t count = (size_t)O * I;
        const size_t layer_bytes = reduced_bytes(l, s->prec); /* before l changes */
        uint8_t *start = p;
        if (needs_f32(l, s->prec)) {
            float *w = (float *)p;
            for (size_t k = 0; k < count; ++k) {
                w[k] = l->src_q8 ? (float)l->src_q8[k] * l->src_scale[k / I] : weft_f16_to_f32(l->src_f16[k]);
            }
            l->w = w;
            p += align64(count * sizeof(float));
        }
        if (s->prec == WEFT_PRECISION_INT8 && q8_eligible(l)) {
            uint32_t Np = weft_q8_pad_n(O), Kp = weft_q8_pad_k(I);
            int8_t *packed = (int8_t *)p;
            float *sc = (float *)(p + align64((size_t)Np * Kp));
            int32_t *ws = (int32_t *)(p + align64((size_t)Np * Kp) + align64(Np * sizeof(float)));
            if (l->src_q8) {
                weft_q8_pack(l->src_q8, l->src_scale, O, I, packed, sc, ws);
            } else {
                weft_q8_quantize_weights(l->w, O, I, wq, scale); /* finite: checked at load */
                weft_q8_pack(wq, scale, O, I, packed, sc, ws);
            }
            l->q8 = (weft_q8_weights){O, I, Np, Kp, packed, sc, ws};
        } else if (s->prec == WEFT_PRECISION_INT8) {
            float *wt = (float *)p;
            for (uint32_t o = 0; o < O; ++o) {
                for (uint32_t k = 0; k < I; ++k) {
                    wt[(size_t)k * O + o] = l->w[(size_t)o * I + k];
                }
            }
            l->wt = wt;
        } else if (s->prec == WEFT_PRECISION_FP16 && q8_eligible(l)) {
            uint16_t *ht = (uint16_t *)p;
            for (uint32_t o = 0; o < O; ++o) {
                for (uint32_t k = 0; k < I; ++k) {
                    ht[(size_t)k * O + o] =
                        l->src_f16 ? l->src_f16[(size_t)o * I + k] : weft_f32_to_f16(l->w[(size_t)o * I + k]);
                }
            }
            l->ht = ht;
        }
        p = start + layer_bytes;
    }
    weft__free(g->ctx, wq, max_wq);
    weft__free(g->ctx, scale, max_wq * sizeof(float));
    return WEFT_OK;
}

static weft_result ct_create(weft_garment *g)
{
    const weft_qkernels *qk = NULL;
    if (g->precision != WEFT_PRECISION_FP32) {
        qk = weft_qkernels_for_isa(g->ctx->isa);
        if (!qk) {
            return weft__fail(WEFT_ERROR_UNSUPPORTED, "method 'model': no %s kernels for isa '%s'",
                              g->precision == WEFT_PRECISION_INT8 ? "int8" : "fp16", weft_isa_name(g->ctx->isa));
        }
    }
    weft_ct_config c;
    weft_ct_weights wb;
    weft_ct_weights *w = &wb;
    weft_result r = weft__ct_bind(g->model, &c, w);
    if (r != WEFT_OK) {
        return r;
    }
    if (c.vertex_count != 0 && c.vertex_count != g->vertex_count) {
        return weft__fail(WEFT_ERROR_TOPOLOGY_MISMATCH,
                          "method 'model': the model was trained for a %u-vertex garment, this one has %u",
                          c.vertex_count, g->vertex_count);
    }
    if (c.requires_collider && g->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER, "method 'model': the model needs a collider "
                                                  "(def.collider_vertex_count is 0)");
    }
    const bool skinned = c.prior == WEFT_CT_PRIOR_SKINNED;
    if (skinned && g->collider_vertex_count == 0) {
        return weft__fail(WEFT_ERROR_NO_COLLIDER, "method 'model': the model's prior 'skinned' follows the collider, "
                                                  "and the garment has none (def.collider_vertex_count is 0)");
    }
    ct_state *s = weft__alloc(g->ctx, sizeof *s);
    if (!s) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    s->c = c;
    s->w = *w;
    s->ctx = g->ctx;
    s->k = g->ctx->kernels;
    s->prec = g->precision;
    s->qk = qk;
    s->N = g->vertex_count;
    s->M = g->collider_triangle_count;
    g->method_state = s;

    /* a token cap bounds the kept triangles (either rule keeps at most the cap) */
    s->Mk = g->max_collider_tokens > 0 && g->max_collider_tokens < s->M ? g->max_collider_tokens : s->M;
    const size_t N = s->N, M = s->Mk, D = c.D, K = c.K, F = c.nfreq, hk = (size_t)c.history * c.K;
    const size_t ntok = N + M;
    const size_t wide_cols = max_sz(2 * D, c.ffn);
    bool ok = add_buf(g, s, &s->rest_tok, N * D) && add_buf(g, s, &s->dec_q, N * D) &&
              add_buf(g, s, &s->enc_q, K * D) && add_buf(g, s, &s->hist, hk * D) &&
              add_buf(g, s, &s->hist_new, hk * D) && add_buf(g, s, &s->xc, max_sz(N, 3) * 3) &&
              add_buf(g, s, &s->feat, N * (6 * F + 3)) && add_buf(g, s, &s->cfeat, M * (18 * F + 13)) &&
              add_buf(g, s, &s->tok, ntok * D) && add_buf(g, s, &s->tln, ntok * D) &&
              add_buf(g, s, &s->tk, ntok * D) && add_buf(g, s, &s->tv, ntok * D) &&
              add_buf(g, s, &s->key_bias, ntok) &&
              add_buf(g, s, &s->wide, max_sz(ntok, hk) * wide_cols) && add_buf(g, s, &s->wide2, hk * c.ffn) &&
              add_buf(g, s, &s->gcat, N * 2 * D) && add_buf(g, s, &s->z, K * D) && add_buf(g, s, &s->za, K * D) &&
              add_buf(g, s, &s->x, hk * D) && add_buf(g, s, &s->xln, hk * D) && add_buf(g, s, &s->xq, hk * D) &&
              add_buf(g, s, &s->xk, hk * D) && add_buf(g, s, &s->xv, hk * D) && add_buf(g, s, &s->xa, hk * D) &&
              add_buf(g, s, &s->dh, N * D) && add_buf(g, s, &s->da, N * D) && add_buf(g, s, &s->dln, N * D) &&
              add_buf(g, s, &s->out3, N * 3) &&
              (!skinned || (add_buf(g, s, &s->skin_cur, N * 3) && add_buf(g, s, &s->skin_next, N * 3)));
    if (ok) {
        memset(s->key_bias, 0, max_sz(ntok, 1) * sizeof(float));
        size_t a = weft_attention_scratch((uint32_t)K, (uint32_t)ntok);
        a = max_sz(a, weft_attention_scratch((uint32_t)hk, (uint32_t)hk));
        a = max_sz(a, weft_attention_scratch((uint32_t)N, (uint32_t)K));
        s->attn_scratch_floats = a;
        ok = add_buf(g, s, &s->attn_scratch, a);
    }
    if (ok && s->prec == WEFT_PRECISION_INT8) {
        /* int8 activations: the widest input of any layer, for the most rows any layer sees */
        const size_t rows = max_sz(max_sz(ntok, hk), N);
        const size_t kp = weft_q8_pad_k((uint32_t)max_sz(max_sz(6 * F + 3, 18 * F + 13), max_sz(2 * D, c.ffn)));
        const uint32_t dh = (uint32_t)(D / c.H);
        const size_t scores = weft_qk_attention_scratch((uint32_t)max_sz(ntok, max_sz(hk, K)), dh);
        ok = add_buf(g, s, &s->qa_store, (rows * kp + 3) / 4) && add_buf(g, s, &s->qa_scale, rows) &&
             add_buf(g, s, &s->att_s, scores);
    }
    s->qa = (int8_t *)s->qa_store;
    if (ok) {
        /* The garment's crop overrides the model's margin (a level-of-detail lever). */
        const float margin = g->crop_margin > 0.0f ? g->crop_margin : c.crop_margin;
        ok = weft__crop_init(g->ctx, &s->crop, margin, g->crop_rule, g->max_collider_tokens, g->collider_cap, s->N,
                             s->M, g->collider_vertex_count, g->collider_rest, g->collider_triangles) == WEFT_OK;
    }
    if (ok) {
        r = build_reduced(g, s);
        ok = r == WEFT_OK;
    }
    if (ok && c.history > 1) {
        s->tmask = weft__alloc(g->ctx, hk * hk);
        ok = s->tmask != NULL;
        for (size_t i = 0; ok && i < hk; ++i) {
            for (size_t j = 0; j < hk; ++j) {
                s->tmask[i * hk + j] = (uint8_t)(j / K <= i / K);
            }
        }
    }
    if (!ok) {
        ct_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    if ((r = build_csr(g, s)) != WEFT_OK) {
        ct_destroy(g);
        return r;
    }
    /* g->x is still the initial state here, as in lbs_create; the garment's own binding (tethers,
     * cuts) is made from the same state, so the prior shares it and hands S_{t+1} to the tethers. */
    if (skinned && g->skin) {
        s->skin = g->skin;
        s->skin_shared = true;
    } else if (skinned && (r = weft__garment_skin_create(g, "method 'model' (skinned prior)", &s->skin)) != WEFT_OK) {
        ct_destroy(g);
        return r;
    }
    if (skinned && !skin_cache_alloc(g, s)) {
        ct_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    precompute(g, s);
    s->hist_empty = true;
    return WEFT_OK;
}

/* An instance of an asset: the prototype's weights, tables, constant tokens, crop, skin binding
 * and step scratch; its own latent history (the only state a step carries to the next). */
static weft_result ct_instance(const weft_garment *proto, weft_garment *g)
{
    const ct_state *p = proto->method_state;
    ct_state *s = weft__alloc(g->ctx, sizeof *s);
    if (!s) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    *s = *p;
    s->buf_count = 0;
    s->batch = NULL;
    s->observer = NULL;
    s->observer_user = NULL;
    s->obs_in = s->obs_out = NULL;
    s->obs_floats = 0;
    s->hist = s->hist_new = NULL;
    g->method_state = s;
    const size_t hkd = (size_t)s->c.history * s->c.K * s->c.D;
    s->skin_last = s->skin_key = NULL;
    if (!add_buf(g, s, &s->hist, hkd) || !add_buf(g, s, &s->hist_new, hkd) || (s->skin && !skin_cache_alloc(g, s))) {
        ct_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    s->hist_empty = true;
    return WEFT_OK;
}

static void ct_reset(weft_garment *g) { state_of(g)->hist_empty = true; }

/* h <- h + MLP([h, mean of neighbours]) for each layer. */
static void gnn(ct_state *s, const weft_ct_mlp *layers, uint32_t count, float *h)
{
    const weft_kernels *k = s->k;
    const uint32_t N = s->N, D = s->c.D;
    for (uint32_t l = 0; l < count; ++l) {
        for (uint32_t i = 0; i < N; ++i) {
            memcpy(s->gcat + (size_t)i * 2 * D, h + (size_t)i * D, D * sizeof(float));
        }
        k->csr_aggregate(s->rowptr, s->col, N, h, D, D, s->gcat + D, 2 * D, true);
        linear(s, N, &layers[l].fc1, s->gcat, 2 * D, s->wide, D, WEFT_ACT_GELU, false);
        linear(s, N, &layers[l].fc2, s->wide, D, h, D, WEFT_ACT_NONE, true);
    }
}

/* x <- x + O(attn(Qp, K(LN y), V(LN y))); x <- x + FF(LN x). Qp is the precomputed or current
 * query projection (nq x D); y holds ny rows, weighted by key_bias (NULL: all alike). */
static void cross_block(ct_state *s, const weft_ct_xattn *a, const float *qp, uint32_t nq, float *x, const float *y,
                        uint32_t ny, const float *key_bias, float *yln, float *yk, float *yv, float *att, float *xln)
{
    const uint32_t D = s->c.D, H = s->c.H, dh = D / H;
    const weft_ct_linear *kv[2] = {&a->k, &a->v};
    float *const kv_out[2] = {yk, yv};
    norm_linear_shared(s, &a->ln_kv, y, yln, ny, 2, kv, kv_out);
    ct_attention(s, qp, yk, yv, nq, ny, 1.0f / sqrtf((float)dh), NULL, key_bias, att);
    linear(s, nq, &a->o, att, D, x, D, WEFT_ACT_NONE, true);
    norm(s, &a->ln_ff, x, xln, nq, D, s->c.ln_eps);
    linear(s, nq, &a->ff.fc1, xln, D, s->wide, 2 * D, WEFT_ACT_GELU, false);
    linear(s, nq, &a->ff.fc2, s->wide, 2 * D, x, D, WEFT_ACT_NONE, true);
}

static void centroid(const float *p, uint32_t n, float out[3])
{
    double m[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; ++i) {
        for (int d = 0; d < 3; ++d) {
            m[d] += p[3 * (size_t)i + d];
        }
    }
    for (int d = 0; d < 3; ++d) {
        out[d] = (float)(m[d] / n);
    }
}

/* Collider triangle features for the triangles the garment's crop keeps; returns the count. */
static uint32_t collider_features(weft_garment *g, ct_state *s, const float centre[3])
{
    const weft_ct_config *c = &s->c;
    const uint32_t F = c->nfreq, ld = 18 * F + 13;
    const float *cn = g->collider_next, *cp = g->collider_prev;
    const uint32_t count = weft__crop_select(&s->crop, g->x, s->N, cn, g->collider_triangles);
    uint32_t kept = 0;
    for (uint32_t k = 0; k < count; ++k) {
        const uint32_t *tri = g->collider_triangles + 3 * (size_t)s->crop.kept[k];
        const float *p[3] = {cn + 3 * (size_t)tri[0], cn + 3 * (size_t)tri[1], cn + 3 * (size_t)tri[2]};
        float *row = s->cfeat + (size_t)kept * ld;
        float corners[9];
        for (int j = 0; j < 3; ++j) {
            for (int d = 0; d < 3; ++d) {
                corners[3 * j + d] = p[j][d] - centre[d];
            }
        }
        ct_posembed(s, corners, 3, s->w.freqs, F, row, 6 * F);
        float *v = row + 18 * F;
        for (int j = 0; j < 3; ++j) {
            const float *q = cp + 3 * (size_t)tri[j];
            for (int d = 0; d < 3; ++d) {
                v[3 * j + d] = (p[j][d] - q[d]) * c->vel_scale;
            }
        }
        float e1[3], e2[3];
        for (int d = 0; d < 3; ++d) {
            e1[d] = p[1][d] - p[0][d];
            e2[d] = p[2][d] - p[0][d];
        }
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        float a2 = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] + 1e-20f);
        for (int d = 0; d < 3; ++d) {
            v[9 + d] = n[d] / a2;
        }
        v[12] = sqrtf(0.5f * a2) * c->area_scale;
        kept++;
    }
    return kept;
}

/* Encoder: X_t, V_t and the collider at t+1 into Z_t, then the temporal stream's input
 * s->x = [Z_{t-h+1..t}] + time embeddings (s->hist_new holds the window, committed on success). */
static void ct_encode(weft_garment *g, ct_state *s)
{
    const weft_ct_config *c = &s->c;
    const uint32_t N = s->N, D = c->D, K = c->K, F = c->nfreq;
    const weft_ct_weights *w = &s->w;

    /* ---- encoder: cloth vertex tokens ---- */
    float centre[3];
    centroid(g->x, N, centre);
    const uint32_t ldf = 6 * F + 3;
    for (uint32_t i = 0; i < N; ++i) {
        for (int d = 0; d < 3; ++d) {
            s->xc[3 * (size_t)i + d] = g->x[3 * (size_t)i + d] - centre[d];
        }
    }
    ct_posembed(s, s->xc, N, w->freqs, F, s->feat, ldf);
    for (uint32_t i = 0; i < N; ++i) {
        float *v = s->feat + (size_t)i * ldf + 6 * F;
        for (int d = 0; d < 3; ++d) {
            const size_t k = 3 * (size_t)i + d;
            v[d] = (g->x[k] - g->x_prev[k]) * c->vel_scale;
        }
    }
    linear(s, N, &w->enc_cloth.fc1, s->feat, ldf, s->wide, D, WEFT_ACT_GELU, false);
    linear(s, N, &w->enc_cloth.fc2, s->wide, D, s->tok, D, WEFT_ACT_NONE, false);
    gnn(s, w->enc_gnn, c->gnn_layers, s->tok);

    /* ---- encoder: collider triangle tokens (cropped to the garment's neighbourhood) ---- */
    uint32_t kept = 0;
    if (s->M > 0) {
        kept = collider_features(g, s, centre);
        g->stats.collider_tokens = kept;
        if (kept > 0) {
            linear(s, kept, &w->enc_coll.fc1, s->cfeat, 18 * F + 13, s->wide, D, WEFT_ACT_GELU, false);
            linear(s, kept, &w->enc_coll.fc2, s->wide, D, s->tok + (size_t)N * D, D, WEFT_ACT_NONE, false);
        }
    }

    /* ---- encoder: learned queries compress every token into Z_t ---- */
    memcpy(s->z, w->queries, (size_t)K * D * sizeof(float));
    /* a sampled crop: each collider token stands for crop.represented cropped triangles */
    const float *key_bias = NULL;
    if (kept > 0 && s->crop.represented != 1.0f) {
        const float b = logf(s->crop.represented);
        for (uint32_t k = 0; k < kept; ++k) {
            s->key_bias[N + k] = b;
        }
        key_bias = s->key_bias;
    }
    cross_block(s, &w->enc_xattn, s->enc_q, K, s->z, s->tok, N + kept, key_bias, s->tln, s->tk, s->tv, s->za,
                s->xln);

    /* ---- temporal transformer over the latent window (oldest first) ---- */
    const size_t frame = (size_t)K * D;
    if (s->hist_empty) {
        for (uint32_t h = 0; h < c->history; ++h) {
            memcpy(s->hist_new + h * frame, s->z, frame * sizeof(float));
        }
    } else {
        memcpy(s->hist_new, s->hist + frame, (c->history - 1) * frame * sizeof(float));
        memcpy(s->hist_new + (c->history - 1) * frame, s->z, frame * sizeof(float));
    }
    for (uint32_t h = 0; h < c->history; ++h) {
        for (uint32_t i = 0; i < K; ++i) {
            const float *src = s->hist_new + h * frame + (size_t)i * D;
            float *dst = s->x + h * frame + (size_t)i * D;
            const float *te = w->time_embed + (size_t)h * D;
            for (uint32_t d = 0; d < D; ++d) {
                dst[d] = src[d] + te[d];
            }
        }
    }
}

/* The temporal transformer's working rows for `count` garments stacked: member i owns rows
 * [i hk, (i + 1) hk) of x, xln, xk, xv and, in the last layer, rows [i K, (i + 1) K) of the
 * compact newest-frame buffers. One garment uses its own scratch (xr, xg unused). */
typedef struct ct_stream {
    float *x, *xln, *xq, *xk, *xv, *xa;     /* count hk x D */
    float *xr, *xg;                         /* count K x D: newest-frame residual and normed rows */
    float *wide, *wide2;                    /* count hk x ffn */
} ct_stream;

/* Runs the temporal layers over the stacked windows of `count` garments that share the model
 * and precision. Every linear runs once over all members' rows with `first`'s weights (identical
 * in every member: the same model built at the same precision), so weights are read once per
 * batch; attention runs per member on its own window. Rows are independent in every kernel, so
 * each member gets the bits it would get alone. z_next[i] receives member i's Z_{t+1}. */
static void ct_temporal(const ct_state *first, ct_state *const *members, uint32_t count, const ct_stream *st,
                        const float **z_next)
{
    const weft_ct_config *c = &first->c;
    const uint32_t D = c->D, K = c->K, H = c->H, dh = D / H, hk = c->history * K;
    const uint32_t R = count * hk;
    const float eps = c->ln_eps;
    const float scale = 1.0f / sqrtf((float)dh);
    for (uint32_t l = 0; l < c->L; ++l) {
        const weft_ct_layer *ly = &first->w.layers[l];
        /* Only the newest frame's tokens are read after the last layer: its queries suffice. */
        const bool last = l + 1 == c->L;
        const uint32_t r0 = last ? hk - K : 0, nq = last ? K : hk;
        norm(first, &ly->ln1, st->x, st->xln, R, D, eps);
        const float *qin = st->xln;
        float *xr = st->x;
        if (last && count == 1) {
            qin = st->xln + (size_t)r0 * D;
            xr = st->x + (size_t)r0 * D;
        } else if (last && r0 > 0) {
            for (uint32_t i = 0; i < count; ++i) {
                const size_t src = ((size_t)i * hk + r0) * D, dst = (size_t)i * K * D;
                memcpy(st->xg + dst, st->xln + src, (size_t)K * D * sizeof(float));
                memcpy(st->xr + dst, st->x + src, (size_t)K * D * sizeof(float));
            }
            qin = st->xg;
            xr = st->xr;
        }
        const uint32_t Q = count * nq;
        const weft_ct_linear *qkv[3] = {&ly->k, &ly->v, &ly->q};
        float *const qkv_out[3] = {st->xk, st->xv, st->xq};
        if (Q == R) { /* every row has a query: one quantisation for q, k and v */
            linear_shared(first, R, 3, qkv, st->xln, D, qkv_out);
        } else {
            linear(first, Q, &ly->q, qin, D, st->xq, D, WEFT_ACT_NONE, false);
            linear_shared(first, R, 2, qkv, st->xln, D, qkv_out);
        }
        for (uint32_t i = 0; i < count; ++i) {
            const size_t qo = (size_t)i * nq * D, ko = (size_t)i * hk * D;
            ct_attention(members[i], st->xq + qo, st->xk + ko, st->xv + ko, nq, hk, scale,
                         last ? NULL : members[i]->tmask, NULL, st->xa + qo);
        }
        linear(first, Q, &ly->o, st->xa, D, xr, D, WEFT_ACT_NONE, true);
        norm(first, &ly->ln2, xr, st->xln, Q, D, eps);
        const weft_ct_linear *gu[2] = {&ly->gate, &ly->up};
        float *const gu_out[2] = {st->wide, st->wide2};
        linear_shared(first, Q, 2, gu, st->xln, D, gu_out);
        ct_swiglu(first, st->wide, st->wide2, st->wide, (size_t)Q * c->ffn);
        linear(first, Q, &ly->down, st->wide, c->ffn, xr, D, WEFT_ACT_NONE, true);
        if (last) {
            for (uint32_t i = 0; i < count; ++i) {
                z_next[i] = xr + (size_t)i * nq * D;
            }
        }
    }
}

/* S_t and S_{t+1} of the skinned prior. S_t is the last step's S_{t+1} when the collider
 * vertices the binding reads are bitwise those it was evaluated from, and is evaluated otherwise
 * (the first step, weft_garment_set_state, a teleported collider, a level switch's replay). */
static weft_result skin_eval(const weft_garment *g, ct_state *s)
{
    const size_t n3 = (size_t)s->N * 3;
    weft_result r = WEFT_OK;
    if (s->skin_key_set && geo_skin_key_matches(s->skin, g->collider_prev, s->skin_key)) {
        memcpy(s->skin_cur, s->skin_last, n3 * sizeof(float)); /* bit-identical to evaluating it */
    } else {
        r = geo_skin_eval(s->skin, g->collider_triangles, g->collider_prev,
                          "method 'model': skinned prior, collider at t", s->skin_cur);
    }
    if (r == WEFT_OK) {
        r = geo_skin_eval(s->skin, g->collider_triangles, g->collider_next,
                       "method 'model': skinned prior, collider at t+1", s->skin_next);
    }
    s->skin_key_set = r == WEFT_OK;
    if (r == WEFT_OK) {
        memcpy(s->skin_last, s->skin_next, n3 * sizeof(float));
        geo_skin_key_store(s->skin, g->collider_next, s->skin_key);
    }
    return r;
}

/* The grasp prior plus the displacement: the carried velocity X_t + beta (X_t - X_{t-1}), each
 * vertex then pulled back to its rest distance from the pins' centroid when it is farther (a
 * long-range attachment to the hand; the rest distance never exceeds the path through the cloth),
 * as tools/train/model.py computes it; with attach_output the attachment bounds the sum, so the
 * network cannot carry a held cloth away from its hand either. */
static void grasp_output(weft_garment *g, const ct_state *s)
{
    const weft_ct_config *c = &s->c;
    float hand[3] = {0.0f, 0.0f, 0.0f}, hand_rest[3] = {0.0f, 0.0f, 0.0f};
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        const float *p = g->pin_targets + 3 * (size_t)k, *r = g->rest + 3 * (size_t)g->pin_indices[k];
        for (int j = 0; j < 3; ++j) {
            hand[j] += p[j];
            hand_rest[j] += r[j];
        }
    }
    for (int j = 0; j < 3 && g->pin_count > 0; ++j) {
        hand[j] /= (float)g->pin_count;
        hand_rest[j] /= (float)g->pin_count;
    }
    for (uint32_t v = 0; v < s->N; ++v) {
        const float *x = g->x + 3 * (size_t)v, *xp = g->x_prev + 3 * (size_t)v, *r = g->rest + 3 * (size_t)v;
        const float *o = s->out3 + 3 * (size_t)v;
        float y[3], d[3];
        for (int j = 0; j < 3; ++j) {
            y[j] = x[j] + c->prior_beta * (x[j] - xp[j]);
            if (c->attach_output) {
                y[j] += c->out_scale * o[j];
            }
            d[j] = y[j] - hand[j];
        }
        if (g->pin_count > 0) {
            const float e[3] = {r[0] - hand_rest[0], r[1] - hand_rest[1], r[2] - hand_rest[2]};
            const float reach = sqrtf(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
            const float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (len > reach) { /* len > reach >= 0 */
                for (int j = 0; j < 3; ++j) {
                    y[j] = hand[j] + d[j] * (reach / len);
                }
            }
        }
        float *out = g->x_next + 3 * (size_t)v;
        for (int j = 0; j < 3; ++j) {
            out[j] = c->attach_output ? y[j] : y[j] + c->out_scale * o[j];
        }
    }
}

/* X_{t+1} = prior + out_scale * displacement into g->x_next, the prior computed as
 * tools/train/model.py computes it. The one output of every precision and of batched steps. */
static weft_result ct_output(weft_garment *g, ct_state *s)
{
    const weft_ct_config *c = &s->c;
    if (c->prior == WEFT_CT_PRIOR_SKINNED) {
        weft_result r = skin_eval(g, s);
        if (r != WEFT_OK) {
            return r;
        }
        g->skinned_next = s->skin_shared ? s->skin_next : NULL; /* the tethers' targets */
    }
    if (c->prior == WEFT_CT_PRIOR_GRASP) {
        grasp_output(g, s);
        return WEFT_OK;
    }
    for (size_t i = 0; i < (size_t)s->N * 3; ++i) {
        float prior;
        if (c->prior == WEFT_CT_PRIOR_SKINNED) {
            /* decay 1 keeps the form the models shipped before it were trained with */
            prior = c->prior_decay == 1.0f ? g->x[i] + (s->skin_next[i] - s->skin_cur[i])
                                           : s->skin_next[i] + c->prior_decay * (g->x[i] - s->skin_cur[i]);
        } else {
            prior = g->x[i] + c->prior_beta * (g->x[i] - g->x_prev[i]) - (i % 3 == 1 ? c->gravity_step : 0.0f);
        }
        g->x_next[i] = prior + c->out_scale * s->out3[i];
    }
    return WEFT_OK;
}

/* Decoder and output: X_{t+1} into g->x_next from Z_{t+1}; commits the latent history when the
 * step succeeded (finite result, and the skinned prior evaluated). */
static weft_result ct_decode(weft_garment *g, ct_state *s, const float *z_next)
{
    const weft_ct_config *c = &s->c;
    const uint32_t N = s->N, D = c->D, K = c->K;
    const float eps = c->ln_eps;
    const weft_ct_weights *w = &s->w;

    /* ---- decoder: rest-shape queries read the predicted latents ---- */
    memcpy(s->dh, s->rest_tok, (size_t)N * D * sizeof(float));
    cross_block(s, &w->dec_xattn, s->dec_q, N, s->dh, z_next, K, NULL, s->xln, s->xk, s->xv, s->da, s->dln);
    if (c->dec_skip) {
        const size_t n = (size_t)N * D;
        for (size_t i = 0; i < n; ++i) {
            s->dh[i] += s->tok[i];
        }
    }
    gnn(s, w->dec_gnn, c->gnn_layers, s->dh);
    norm(s, &w->dec_ln, s->dh, s->dln, N, D, eps);
    linear(s, N, &w->dec_head, s->dln, D, s->out3, 3, WEFT_ACT_NONE, false);

    /* ---- X_{t+1} = prior + out_scale * displacement ---- */
    weft_result r = ct_output(g, s);
    if (r != WEFT_OK) {
        return r;
    }
    if (!weft__all_finite(g->x_next, (size_t)N * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "method 'model': the forward pass produced NaN or infinity; "
                                                 "state kept");
    }
    /* Commit the latent history only once the step has succeeded. */
    float *t = s->hist;
    s->hist = s->hist_new;
    s->hist_new = t;
    s->hist_empty = false;
    return WEFT_OK;
}

static weft_result ct_step(weft_garment *g)
{
    ct_state *s = state_of(g);
    if (s->observer) {
        /* The constant layers (rest tokens, query projections) are recomputed, bit for bit, so
         * the observer sees every layer once per step. */
        precompute(g, s);
    }
    ct_encode(g, s);
    const ct_stream st = {s->x, s->xln, s->xq, s->xk, s->xv, s->xa, NULL, NULL, s->wide, s->wide2};
    const float *z_next = NULL;
    ct_temporal(s, &s, 1, &st, &z_next);
    return ct_decode(g, s, z_next);
}

/* The first garment's batch scratch for n members; false (nothing changed) when it cannot be
 * allocated. */
static bool batch_reserve(weft_garment *g, ct_state *s, uint32_t n)
{
    if (s->batch && s->batch->capacity >= n) {
        return true;
    }
    const weft_ct_config *c = &s->c;
    const size_t hk = (size_t)c->history * c->K;
    ct_batch *b = weft__alloc(g->ctx, sizeof *b);
    if (!b) {
        return false;
    }
    b->capacity = n;
    b->rows = n * hk;
    b->hkd = b->rows * c->D;
    b->kd = (size_t)n * c->K * c->D;
    b->hkf = b->rows * c->ffn;
    b->qa_floats = 1;
    bool ok = true;
    float **big[6] = {&b->x, &b->xln, &b->xq, &b->xk, &b->xv, &b->xa};
    for (int i = 0; i < 6; ++i) {
        ok = ok && (*big[i] = weft__alloc(g->ctx, b->hkd * sizeof(float))) != NULL;
    }
    ok = ok && (b->xr = weft__alloc(g->ctx, b->kd * sizeof(float))) != NULL &&
         (b->xg = weft__alloc(g->ctx, b->kd * sizeof(float))) != NULL &&
         (b->wide = weft__alloc(g->ctx, b->hkf * sizeof(float))) != NULL &&
         (b->wide2 = weft__alloc(g->ctx, b->hkf * sizeof(float))) != NULL;
    if (ok && s->prec == WEFT_PRECISION_INT8) {
        const size_t kp = weft_q8_pad_k((uint32_t)max_sz(c->D, c->ffn));
        b->qa_floats = (b->rows * kp + 3) / 4;
        ok = (b->qa_store = weft__alloc(g->ctx, b->qa_floats * sizeof(float))) != NULL &&
             (b->qa_scale = weft__alloc(g->ctx, b->rows * sizeof(float))) != NULL;
    }
    if (!ok) {
        batch_free(g->ctx, b);
        return false;
    }
    batch_free(g->ctx, s->batch);
    s->batch = b;
    return true;
}

bool weft__ct_batchable(const weft_garment *g)
{
    const ct_state *s = g && g->method == WEFT_METHOD_MODEL ? g->method_state : NULL;
    /* An asset's instances share its step scratch, which a stacked step needs per member. */
    return s && !s->observer && !g->asset;
}

void weft__ct_step_group(weft_garment *const *garments, uint32_t count, weft_result *results)
{
    ct_state *first = count > 0 ? state_of(garments[0]) : NULL;
    if (count < 2 || count > WEFT_CT_GROUP_MAX || !batch_reserve(garments[0], first, count)) {
        /* one member, or no scratch for the stack: the same result garment by garment */
        for (uint32_t i = 0; i < count; ++i) {
            results[i] = ct_step(garments[i]);
        }
        return;
    }
    const ct_batch *b = first->batch;
    const size_t hkd = (size_t)first->c.history * first->c.K * first->c.D;
    ct_state *members[WEFT_CT_GROUP_MAX];
    for (uint32_t i = 0; i < count; ++i) {
        members[i] = state_of(garments[i]);
        ct_encode(garments[i], members[i]);
        memcpy(b->x + i * hkd, members[i]->x, hkd * sizeof(float));
    }
    /* The first garment's tables and weights with the batch's int8 activation scratch. */
    ct_state stacked = *first;
    stacked.qa = (int8_t *)b->qa_store;
    stacked.qa_scale = b->qa_scale;
    const ct_stream st = {b->x, b->xln, b->xq, b->xk, b->xv, b->xa, b->xr, b->xg, b->wide, b->wide2};
    const float *z_next[WEFT_CT_GROUP_MAX];
    ct_temporal(&stacked, members, count, &st, z_next);
    for (uint32_t i = 0; i < count; ++i) {
        results[i] = ct_decode(garments[i], members[i], z_next[i]);
    }
}

weft_result weft__ct_set_observer(weft_garment *g, weft_ct_observer_fn *fn, void *user)
{
    if (!g || g->method != WEFT_METHOD_MODEL || !g->method_state) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft__ct_set_observer: the garment is not of method 'model'");
    }
    ct_state *s = state_of(g);
    if (!fn) {
        weft__free(g->ctx, s->obs_in, s->obs_floats * sizeof(float));
        weft__free(g->ctx, s->obs_out, s->obs_floats * sizeof(float));
        s->obs_in = s->obs_out = NULL;
        s->obs_floats = 0;
        s->observer = NULL;
        s->observer_user = NULL;
        return WEFT_OK;
    }
    if (!s->obs_in) {
        weft_ct_linear *lin[CT_MAX_LINEARS];
        const uint32_t n = all_linears(&s->w, &s->c, lin);
        size_t width = 1;
        for (uint32_t i = 0; i < n; ++i) {
            width = max_sz(width, max_sz(lin[i]->in, lin[i]->out));
        }
        const size_t rows = max_sz(max_sz((size_t)s->N + s->Mk, (size_t)s->c.history * s->c.K), 1);
        const size_t floats = rows * width;
        float *in = weft__alloc(g->ctx, floats * sizeof(float));
        float *out = weft__alloc(g->ctx, floats * sizeof(float));
        if (!in || !out) {
            weft__free(g->ctx, in, floats * sizeof(float));
            weft__free(g->ctx, out, floats * sizeof(float));
            return WEFT_ERROR_OUT_OF_MEMORY;
        }
        s->obs_in = in;
        s->obs_out = out;
        s->obs_floats = floats;
    }
    s->observer = fn;
    s->observer_user = user;
    return WEFT_OK;
}

const weft_method_ops weft__method_model = {
    .name = "model",
    .supports_pins = false,
    .create = ct_create,
    .destroy = ct_destroy,
    .instance = ct_instance,
    .reset = ct_reset,
    .step = ct_step,
};
