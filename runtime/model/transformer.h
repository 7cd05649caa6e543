/* The ClothTransformer forward pass (fp32, fp16 weights, int8) and the WEFT_METHOD_MODEL garment
 * method.
 *
 * The architecture and tensor names are defined by tools/train/model.py; docs/MODEL.md describes
 * the data flow. A model file is checked once against its config (every tensor, shape and value)
 * by weft__ct_validate; a garment then precomputes everything that depends only on the model and
 * its rest shape, and sizes all scratch, so that a step allocates nothing. */
#ifndef WEFT_MODEL_TRANSFORMER_H
#define WEFT_MODEL_TRANSFORMER_H

#include "garment/garment.h"
#include "model/model.h"
#include "kernels/qkernels.h"

#define WEFT_CT_ARCHITECTURE "clothtransformer"
#define WEFT_CT_MAX_GNN 8u
#define WEFT_CT_MAX_LAYERS 64u

/* The residual's prior (config "prior"): X_{t+1} = prior + out_scale * displacement. */
typedef enum weft_ct_prior {
    WEFT_CT_PRIOR_SKINNED,              /* "skinned": X_t + S_{t+1} - S_t, S the LBS method's
                                           binding (runtime/geometry/skin.c) on the collider; with
                                           prior_decay a < 1, S_{t+1} + a (X_t - S_t) */
    WEFT_CT_PRIOR_BALLISTIC,            /* "ballistic": X_t + prior_beta (X_t - X_{t-1}) - gravity_step Y:
                                           free fall is in the prior, the network adds contact
                                           (prior_beta 1 and gravity_step 0: the inertial
                                           2 X_t - X_{t-1}; prior_beta 0: X_t) */
    WEFT_CT_PRIOR_GRASP,                /* "grasp": X_t + prior_beta (X_t - X_{t-1}), each vertex then
                                           kept within its rest distance of the pins' centroid
                                           (weft_garment_set_pins: vertex i_k to P_k at t+1), a
                                           long-range attachment: a held cloth hangs from its hand */
    WEFT_CT_PRIOR_COUNT
} weft_ct_prior;

typedef struct weft_ct_config {
    uint32_t K, D, L, H, history, ffn, nfreq, gnn_layers;
    float vel_scale, area_scale, out_scale, crop_margin, ln_eps;
    weft_ct_prior prior;
    float prior_beta, gravity_step;     /* the ballistic prior's terms, prior_beta also the grasp
                                           prior's (optional keys: 1, 9.81/3600 m) */
    float prior_decay;                  /* the skinned prior's kept offset (optional key: 1) */
    bool attach_output;                 /* grasp prior: the attachment bounds prior + displacement
                                           (optional key: false, the prior alone) */
    bool dec_skip;
    bool requires_collider;             /* trained only with colliders */
    uint32_t vertex_count;              /* 0: any garment; else the one mesh it was trained for */
} weft_ct_config;

/* Longest layer name ("enc_xattn.ff.fc1", "tmp.63.gate", ...) with room to spare. */
#define WEFT_CT_NAME_MAX 48u

typedef struct weft_ct_linear {
    char name[WEFT_CT_NAME_MAX];        /* the weight's tensor name without ".weight" */
    const float *w, *b;                 /* w[out][in], b[out]; w is NULL until built when the file
                                           stores the weight in int8 or fp16 */
    uint32_t out, in;
    /* The quantiser's per-layer decision ("quant.layer.<name>" = "fp32:...") keeps this layer in
     * fp32 at every precision (its int8 error was too large, or it was asked for). */
    bool keep_f32;
    /* The weight as stored in a quantised file (`weft quantize`): int8 "<name>.q8" + "<name>.scale",
     * or fp16 "<name>" (at most one is set; neither for fp32 files). */
    const int8_t *src_q8;
    const float *src_scale;
    const uint16_t *src_f16;
    /* Reduced-precision forms, built per garment at creation (empty when unused):
     * int8 layers with both sizes >= WEFT_CT_Q8_MIN_DIM use q8; smaller int8 layers use the
     * deterministic fp32 product on wt = W^T; fp16 layers use ht = W^T in binary16. */
    weft_q8_weights q8;
    const float *wt;                    /* in x out */
    const uint16_t *ht;                 /* in x out */
} weft_ct_linear;

/* Layers narrower than this stay in (deterministic) fp32 on the int8 path, and in fp32 on the
 * fp16 path: the 3-wide output head gains nothing from int8 and loses the most accuracy. */
#define WEFT_CT_Q8_MIN_DIM 16u

typedef struct weft_ct_norm {
    const float *g, *b;
} weft_ct_norm;

typedef struct weft_ct_mlp {
    weft_ct_linear fc1, fc2;
} weft_ct_mlp;

typedef struct weft_ct_xattn {
    weft_ct_norm ln_q, ln_kv, ln_ff;
    weft_ct_linear q, k, v, o;
    weft_ct_mlp ff;
} weft_ct_xattn;

typedef struct weft_ct_layer {
    weft_ct_norm ln1, ln2;
    weft_ct_linear q, k, v, o, gate, up, down;
} weft_ct_layer;

typedef struct weft_ct_weights {
    const float *freqs;                 /* nfreq */
    weft_ct_mlp enc_cloth, enc_coll, dec_rest;
    weft_ct_mlp enc_gnn[WEFT_CT_MAX_GNN], dec_gnn[WEFT_CT_MAX_GNN];
    const float *queries;               /* K x D */
    const float *time_embed;            /* history x D */
    weft_ct_xattn enc_xattn, dec_xattn;
    weft_ct_layer layers[WEFT_CT_MAX_LAYERS];
    weft_ct_norm dec_ln;
    weft_ct_linear dec_head;
} weft_ct_weights;

/* Reads the config and binds every tensor, checking names, dtypes, shapes and finiteness.
 * Fails with BAD_METADATA, MISSING_TENSOR, TENSOR_SHAPE, TENSOR_DTYPE or NOT_FINITE, naming the
 * key or tensor. Either output may be NULL. */
weft_result weft__ct_bind(const weft_model *model, weft_ct_config *out_config, weft_ct_weights *out_weights);

/* Load-time hook for the architecture table: weft__ct_bind without outputs. */
weft_result weft__ct_validate(const weft_model *model);

/* Whether a garment of this model binds itself to the collider at creation (the skinned prior),
 * as the LBS method does: a level switch must then bind to the pose of now. False for models of
 * another architecture or without a valid "prior". */
bool weft__ct_binds_collider(const weft_model *model);

/* Called after every linear layer of the forward pass (fp32 activations, before any fused
 * residual add is visible to the caller: `in` is the layer input, `out` its output). `name` is
 * the weight tensor's name in the model file without ".weight" (e.g. "layers.0.q"). */
typedef void weft_ct_observer_fn(const char *name, const float *in, uint32_t rows, uint32_t in_cols,
                                 const float *out, uint32_t out_cols, void *user);
/* (This architecture names its layers as tools/train/model.py does: "enc_cloth.fc1",
 * "enc_gnn.0.mlp.fc2", "enc_xattn.k", "tmp.0.q", "tmp.1.gate", "dec_head", ... Layers constant
 * for a garment, such as "dec_rest.fc1" and the cross-attention query projections, are run
 * again at each observed step so that every layer is seen once per step; `out` includes the
 * layer's activation, e.g. GELU after "*.fc1".) */
/* Installs (fn != NULL) or removes the observer of a garment of method MODEL; returns
 * WEFT_ERROR_INVALID_ARGUMENT for other methods. Not for per-frame use in games (calibration). */
weft_result weft__ct_set_observer(weft_garment *g, weft_ct_observer_fn *fn, void *user);

/* Batched stepping (weft_garments_step). Garments of method MODEL that share model, precision
 * and context are stepped together: their temporal transformers run as one stack of rows per
 * linear layer. */
#define WEFT_CT_GROUP_MAX 64u
/* Method MODEL, created, and no observer installed (observed garments are stepped alone). */
bool weft__ct_batchable(const weft_garment *g);
/* The method step of each of `count` (<= WEFT_CT_GROUP_MAX) batchable garments sharing model,
 * precision and context, each with its collider set: writes g->x_next and results[i] exactly as
 * weft__method_model.step would, bit for bit. The first garment keeps the stacked scratch
 * (allocated on its first group of this size or larger); when that allocation fails the
 * garments are stepped one by one instead. */
void weft__ct_step_group(weft_garment *const *garments, uint32_t count, weft_result *results);

/* The garment method (registered in runtime/garment/methods.c). */
extern const weft_method_ops weft__method_model;

#endif
