/* FNOpt internals: the physics loss with its analytic gradient, the FNO network and the
 * optimizers. Everything here works on buffers sized at creation; nothing allocates per step. */
#ifndef WEFT_FNOPT_INTERNAL_H
#define WEFT_FNOPT_INTERNAL_H

#include "core/core.h"
#include "kernels/qkernels.h"
#include "weft/fnopt.h"

/* ---- physics loss (fnopt_loss.c) -------------------------------------------------------- */

#define FNOPT_REP_RES 32u   /* the repulsion term works on a 32 x 32 resampling */

typedef struct fnopt_loss {
    uint32_t h, w, n;           /* n = h*w */
    float *mass;                /* n: lumped mass 1 / 0.5 / 0.25 */
    /* scratch, sized at creation */
    double *xn;                 /* 3n: candidate positions x + v + a (handles = targets) */
    double *uI, *lI, *gI;       /* I-edges (i,j)->(i+1,j): unit (3), length (1), dL/de (3) */
    double *uJ, *lJ, *gJ;       /* J-edges (i,j)->(i,j+1) */
    double *gx;                 /* 3n: dL/dx_new */
    double *rp, *rg;            /* repulsion: 3*32*32 resampled points and their gradient */
} fnopt_loss;

/* Everything the loss reads besides a. */
typedef struct fnopt_loss_input {
    const float *x, *v;         /* 3n */
    const uint8_t *mask;        /* n: 1 at handles */
    const float *bc;            /* 3n: handle targets (read where mask) */
    float Y, S, B;
    float gravity[3];
    float k_rep, rep_thres;
} fnopt_loss_input;

weft_result fnopt__loss_init(const weft_context *ctx, fnopt_loss *L, uint32_t h, uint32_t w);
void fnopt__loss_free(const weft_context *ctx, fnopt_loss *L);
/* L(acc) of one sample; writes dL/dacc into grad (3n) when grad is not NULL. acc NULL = 0. */
double fnopt__loss_eval(fnopt_loss *L, const fnopt_loss_input *in, const float *acc, float *grad);
/* Internal energy (stretch + shear + bend) of positions p (3n floats). */
double fnopt__internal_energy(fnopt_loss *L, const float *p, float Y, float S, float B);

/* ---- FNO network (fnopt_fno.c) --------------------------------------------------------- */

#define FNOPT_MODES_H 8u
#define FNOPT_MODES_W 5u
#define FNOPT_MODES (FNOPT_MODES_H * FNOPT_MODES_W)
#define FNOPT_MAX_LAYERS 8u

/* Weights as exported by tools/fnopt/fnopt_torch.py (PyTorch layouts, fp32). */
typedef struct fnopt_weights {
    uint32_t width, lifting, projection, layers, scale_layer, in_channels;
    const float *lift0_w, *lift0_b;     /* [lifting][in+2], [lifting] */
    const float *lift1_w, *lift1_b;     /* [width][lifting], [width] */
    const float *spec_w[FNOPT_MAX_LAYERS]; /* [in][out][8][5][2] (re, im) */
    const float *spec_b[FNOPT_MAX_LAYERS]; /* [width] */
    const float *skip_w[FNOPT_MAX_LAYERS]; /* [width][width] */
    const float *proj0_w, *proj0_b;     /* [projection][width], [projection] */
    const float *proj1_w, *proj1_b;     /* [1][projection], [1] */
    const float *head_w, *head_b;       /* [1][width], [1] */
    float initial_scale;
} fnopt_weights;

/* A 1x1 layer at reduced precision, converted at creation: fp16 weights as [K][N] for gemm_f16,
 * int8 weights packed for gemm_q8, or fp32 [K][N] for gemm_det (the small layers that the int8
 * path keeps in fp32). Exactly one of the three is set. */
typedef struct fnopt_layer {
    uint32_t n_out, k_in;
    const float *bias;
    uint16_t *w16;
    float *w32t;
    weft_q8_weights q8;
    int8_t *q8_packed;
    float *q8_scale;
    int32_t *q8_wsum;
} fnopt_layer;

enum { FNOPT_L_LIFT0, FNOPT_L_LIFT1, FNOPT_L_PROJ0, FNOPT_L_PROJ1, FNOPT_L_HEAD, FNOPT_L_SKIP0 };
#define FNOPT_MAX_DENSE (FNOPT_L_SKIP0 + FNOPT_MAX_LAYERS)

typedef struct fnopt_fno fnopt_fno;

/* Per-level twins of the FNO's spectral convolution and GELU (fnopt_simd_body.h). */
typedef struct fnopt_simd {
    /* out[n][C] = SpectralConv_l(x[n][C]) for one sample (overwrites out) */
    void (*spectral)(const fnopt_fno *F, uint32_t l, const float *x, float *out);
    void (*gelu)(float *x, size_t count);   /* exact (erf) GELU in place */
    float (*erf)(float x);                  /* the erf approximation the GELU uses */
} fnopt_simd;

extern const fnopt_simd fnopt__simd_generic;
#if defined(__x86_64__) || defined(_M_X64)
extern const fnopt_simd fnopt__simd_avx2, fnopt__simd_avx512;
#endif

struct fnopt_fno {
    const weft_context *ctx;
    const fnopt_simd *simd;
    fnopt_weights wt;
    uint32_t h, w, n, batch;            /* batch = samples per forward (3: x, y, z) */
    weft_precision prec;
    const weft_qkernels *qk;            /* FP16 / INT8: the deterministic kernels */
    fnopt_layer dense[FNOPT_MAX_DENSE]; /* FP16 / INT8: converted 1x1 layers */
    int8_t *qa;                         /* INT8: quantised activations [batch*n][qa_ld] */
    float *qa_scale;                    /* INT8: [batch*n] */
    uint32_t qa_ld;
    size_t dense_bytes;                 /* bytes of the conversions above (for the report) */
    float *spec_re, *spec_im;           /* per layer [mode][in][out], rearranged at creation */
    float *tw_h_c, *tw_h_s;             /* [8][h]: cos/sin(2 pi kx i / h), kx = m - 4 */
    float *tw_w_c, *tw_w_s;             /* [5][w]: cos/sin(2 pi ky j / w) */
    float *grid;                        /* [n][2]: i/(h-1), j/(w-1) */
    float *in;                          /* [batch*n][in+2] */
    float *big;                         /* [batch*n][max(lifting, projection)] */
    float *hA, *hB;                     /* [batch*n][width] */
    float *fa, *fx, *fy;                /* spectral scratch: [h][5][width] x2 (re, im), [40][width] x2 */
    float *feat;                        /* [batch][width] amax features */
    size_t bytes;
};

/* Checks shapes from the model's tensors and copies the spectral weights into compute layout.
 * prec FP16: every 1x1 layer with fp16 weights (gemm_f16); INT8: the lifting's second layer, the
 * skips and the first projection layer with int8 weights and activations (gemm_q8), the rest in
 * deterministic fp32 (gemm_det). The spectral convolution stays fp32 in every precision. */
weft_result fnopt__fno_init(const weft_context *ctx, fnopt_fno *F, const fnopt_weights *wt, uint32_t h,
                            uint32_t w, uint32_t batch, weft_precision prec);
void fnopt__fno_free(fnopt_fno *F);
/* z: [batch][n][in_channels] (pixel-major, channel fastest). u: [batch][n], d: [batch]. */
void fnopt__fno_forward(fnopt_fno *F, const float *z, float *u, float *d);
/* Binds an "fnopt" weft_model's tensors into wt (validating names, dtypes and shapes). */
weft_result fnopt__weights_from_model(const weft_model *model, fnopt_weights *wt);

/* Learned-optimizer recurrent state for the three components. */
typedef struct fnopt_learned {
    fnopt_fno fno;
    float *g_prev, *s_prev;             /* [3][n] */
    float scale[3];
    float max_scale;                    /* cap on scale (weft_fnopt_def.max_step); 0: none */
    float *z, *u;                       /* [3][n][3], [3][n] */
    float d[3];
} fnopt_learned;

weft_result fnopt__learned_init(const weft_context *ctx, fnopt_learned *Lo, const fnopt_weights *wt,
                                uint32_t h, uint32_t w, weft_precision prec);
void fnopt__learned_free(const weft_context *ctx, fnopt_learned *Lo);
void fnopt__learned_reset(fnopt_learned *Lo);
/* One update: reads grad (3n, AoS xyz), adds the step to acc (3n). */
void fnopt__learned_update(fnopt_learned *Lo, const float *grad, float *acc);

/* ---- classical optimizers (fnopt_optim.c) ------------------------------------------------ */

typedef struct fnopt_classic {
    weft_fnopt_optimizer kind;
    uint32_t n3, history;
    float lr, beta1, beta2;
    uint32_t t;                         /* iteration within the step */
    float *m, *v;                       /* Adam moments; L-BFGS: previous acc and gradient */
    float *s, *y;                       /* L-BFGS pairs [history][n3] */
    double *rho, *alpha;
    float *dir;
    uint32_t count, head;
} fnopt_classic;

weft_result fnopt__classic_init(const weft_context *ctx, fnopt_classic *C, weft_fnopt_optimizer kind,
                                uint32_t n3, uint32_t history, float lr, float beta1, float beta2);
void fnopt__classic_free(const weft_context *ctx, fnopt_classic *C);
void fnopt__classic_reset(fnopt_classic *C);
void fnopt__classic_update(fnopt_classic *C, const float *grad, float *acc);

/* ---- exposed for tests ------------------------------------------------------------------- */

/* The erf approximation the FNO's GELU uses. */
float fnopt__erf(float x);

/* The learned optimizer's state (for parity tests against PyTorch). */
const fnopt_learned *fnopt__learned_state(const weft_fnopt *cloth);

#endif
