/* The FNO of the learned optimizer (docs/FNOPT.md, *Formulation (as implemented)*), in fp32, fp16 or int8.
 *
 * Activations are pixel-major, channels fastest: row (s*n + p) of a [batch*n][C] matrix is
 * pixel p of sample s, so every 1x1 convolution is one gemm through the context's kernels.
 * The spectral convolution keeps only 8 x 5 Fourier modes, so it is computed as direct DFT
 * sums against twiddle tables built at creation (no FFT), separably: along W, then along H.
 * At FP16 / INT8 the 1x1 layers run through the deterministic quantisation kernels (qkernels.h)
 * with weights converted once here; everything else is the same code in every precision. */
#include "fnopt/fnopt_internal.h"
#include "model/model.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI 6.283185307179586476925

/* The spectral convolution and the erf GELU by kernel level (fnopt_simd_body.h): the same
 * operations in the same order in every twin, so the choice changes speed, not bits. */
static const fnopt_simd *simd_for(weft_isa isa)
{
#if defined(__x86_64__) || defined(_M_X64)
    if (isa == WEFT_ISA_AVX512) {
        return &fnopt__simd_avx512;
    }
    if (isa == WEFT_ISA_AVX2) {
        return &fnopt__simd_avx2;
    }
#endif
    (void)isa;
    return &fnopt__simd_generic;
}

float fnopt__erf(float x) { return fnopt__simd_generic.erf(x); }

static size_t fno_floats(uint32_t h, uint32_t w, uint32_t batch, const fnopt_weights *wt, size_t *parts)
{
    size_t n = (size_t)h * w, C = wt->width, big = wt->lifting > wt->projection ? wt->lifting : wt->projection;
    parts[0] = (size_t)wt->layers * FNOPT_MODES * C * C;     /* spec_re, spec_im each */
    parts[1] = (size_t)FNOPT_MODES_H * h;                    /* tw_h_c, tw_h_s each */
    parts[2] = (size_t)FNOPT_MODES_W * w;                    /* tw_w_c, tw_w_s each */
    parts[3] = 2 * n;                                        /* grid */
    parts[4] = batch * n * (wt->in_channels + 2);            /* in */
    parts[5] = batch * n * big;                              /* big */
    parts[6] = batch * n * C;                                /* hA, hB each */
    parts[7] = (size_t)h * FNOPT_MODES_W * C;                /* fa re+im -> 2x */
    parts[8] = (size_t)FNOPT_MODES * C;                      /* fx, fy: re+im -> 2x each */
    parts[9] = (size_t)batch * C;                            /* feat */
    return 2 * parts[0] + 2 * parts[1] + 2 * parts[2] + parts[3] + parts[4] + parts[5] + 2 * parts[6] +
           2 * parts[7] + 4 * parts[8] + parts[9];
}

/* fp32 weights, bias and shape of 1x1 layer `id`. */
static void dense_source(const fnopt_weights *wt, uint32_t id, const float **W, const float **b, uint32_t *n_out,
                         uint32_t *k_in)
{
    const uint32_t C = wt->width;
    switch (id) {
    case FNOPT_L_LIFT0: *W = wt->lift0_w, *b = wt->lift0_b, *n_out = wt->lifting, *k_in = wt->in_channels + 2; break;
    case FNOPT_L_LIFT1: *W = wt->lift1_w, *b = wt->lift1_b, *n_out = C, *k_in = wt->lifting; break;
    case FNOPT_L_PROJ0: *W = wt->proj0_w, *b = wt->proj0_b, *n_out = wt->projection, *k_in = C; break;
    case FNOPT_L_PROJ1: *W = wt->proj1_w, *b = wt->proj1_b, *n_out = 1, *k_in = wt->projection; break;
    case FNOPT_L_HEAD: *W = wt->head_w, *b = wt->head_b, *n_out = 1, *k_in = C; break;
    default: *W = wt->skip_w[id - FNOPT_L_SKIP0], *b = wt->spec_b[id - FNOPT_L_SKIP0], *n_out = C, *k_in = C; break;
    }
}

/* INT8 quantises the wide layers (lifting 256 -> 64, the skips, projection 64 -> 64: 96 % of the
 * 1x1 multiply-adds). The first lifting layer stays fp32: its input mixes the soft-clipped
 * optimizer channels (up to 10) with the grid embedding in [0, 1], which one per-row int8 scale
 * would resolve to 13 levels; the two 1-output layers are negligible. */
static bool dense_is_int8(uint32_t id) { return id == FNOPT_L_LIFT1 || id == FNOPT_L_PROJ0 || id >= FNOPT_L_SKIP0; }

static void dense_free(const weft_context *ctx, fnopt_layer *l)
{
    const size_t N = l->n_out, K = l->k_in, Np = weft_q8_pad_n(l->n_out), Kp = weft_q8_pad_k(l->k_in);
    weft__free(ctx, l->w16, N * K * sizeof(uint16_t));
    weft__free(ctx, l->w32t, N * K * sizeof(float));
    weft__free(ctx, l->q8_packed, Np * Kp);
    weft__free(ctx, l->q8_scale, Np * sizeof(float));
    weft__free(ctx, l->q8_wsum, Np * sizeof(int32_t));
    memset(l, 0, sizeof *l);
}

/* Converts layer `id` for F->prec; returns the bytes it holds, 0 when out of memory. */
static size_t dense_convert(fnopt_fno *F, uint32_t id)
{
    const weft_context *ctx = F->ctx;
    fnopt_layer *l = &F->dense[id];
    const float *W = NULL;
    dense_source(&F->wt, id, &W, &l->bias, &l->n_out, &l->k_in);
    const size_t N = l->n_out, K = l->k_in;
    if (F->prec == WEFT_PRECISION_FP16) {
        /* gemm_f16 reads B[K][N]; weights outside fp16's range become inf and are caught below */
        if (!(l->w16 = weft__alloc(ctx, N * K * sizeof(uint16_t)))) {
            return 0;
        }
        for (size_t o = 0; o < N; ++o) {
            for (size_t k = 0; k < K; ++k) {
                l->w16[k * N + o] = weft_f32_to_f16(W[o * K + k]);
            }
        }
        return N * K * sizeof(uint16_t);
    }
    if (!dense_is_int8(id)) {
        if (!(l->w32t = weft__alloc(ctx, N * K * sizeof(float)))) {
            return 0;
        }
        for (size_t o = 0; o < N; ++o) {
            for (size_t k = 0; k < K; ++k) {
                l->w32t[k * N + o] = W[o * K + k];
            }
        }
        return N * K * sizeof(float);
    }
    const size_t Np = weft_q8_pad_n(l->n_out), Kp = weft_q8_pad_k(l->k_in);
    int8_t *wq = weft__alloc(ctx, N * K);
    float *sc = weft__alloc(ctx, N * sizeof(float));
    l->q8_packed = weft__alloc(ctx, Np * Kp);
    l->q8_scale = weft__alloc(ctx, Np * sizeof(float));
    l->q8_wsum = weft__alloc(ctx, Np * sizeof(int32_t));
    bool ok = wq && sc && l->q8_packed && l->q8_scale && l->q8_wsum &&
              weft_q8_quantize_weights(W, l->n_out, l->k_in, wq, sc);
    if (ok) {
        weft_q8_pack(wq, sc, l->n_out, l->k_in, l->q8_packed, l->q8_scale, l->q8_wsum);
        l->q8 = (weft_q8_weights){.N = l->n_out, .K = l->k_in, .Np = (uint32_t)Np, .Kp = (uint32_t)Kp,
                                  .packed = l->q8_packed, .scale = l->q8_scale, .wsum = l->q8_wsum};
    }
    weft__free(ctx, wq, N * K);
    weft__free(ctx, sc, N * sizeof(float));
    return ok ? Np * Kp + Np * (sizeof(float) + sizeof(int32_t)) : 0;
}

static void dense_free_all(fnopt_fno *F)
{
    for (uint32_t id = 0; id < FNOPT_MAX_DENSE; ++id) {
        dense_free(F->ctx, &F->dense[id]);
    }
    if (F->qa) {
        weft__free(F->ctx, F->qa, (size_t)F->batch * F->n * F->qa_ld);
        weft__free(F->ctx, F->qa_scale, (size_t)F->batch * F->n * sizeof(float));
    }
    F->qa = NULL;
    F->qa_scale = NULL;
}

static weft_result dense_init(fnopt_fno *F)
{
    if (F->prec == WEFT_PRECISION_FP32) {
        return WEFT_OK;
    }
    F->qk = weft_qkernels_for_isa(F->ctx->isa);
    if (!F->qk) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_fnopt_create: no fp16/int8 kernels for ISA %s",
                          weft_isa_name(F->ctx->isa));
    }
    const uint32_t count = FNOPT_L_SKIP0 + F->wt.layers;
    for (uint32_t id = 0; id < count; ++id) {
        size_t b = dense_convert(F, id);
        if (!b) {
            dense_free_all(F);
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory converting the FNO weights");
        }
        F->dense_bytes += b;
        if (F->dense[id].w16) {
            for (size_t i = 0; i < (size_t)F->dense[id].n_out * F->dense[id].k_in; ++i) {
                if (!isfinite(weft_f16_to_f32(F->dense[id].w16[i]))) {
                    dense_free_all(F);
                    return weft__fail(WEFT_ERROR_NOT_FINITE,
                                      "weft_fnopt_create: an FNO weight exceeds the fp16 range (65504)");
                }
            }
        }
    }
    if (F->prec == WEFT_PRECISION_INT8) {
        const uint32_t kmax = F->wt.lifting > F->wt.width ? F->wt.lifting : F->wt.width;
        F->qa_ld = weft_q8_pad_k(kmax > F->wt.projection ? kmax : F->wt.projection);
        F->qa = weft__alloc(F->ctx, (size_t)F->batch * F->n * F->qa_ld);
        F->qa_scale = weft__alloc(F->ctx, (size_t)F->batch * F->n * sizeof(float));
        if (!F->qa || !F->qa_scale) {
            dense_free_all(F);
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory for int8 activations");
        }
        F->dense_bytes += (size_t)F->batch * F->n * (F->qa_ld + sizeof(float));
    }
    return WEFT_OK;
}

/* C[M][N] = act(A W_id^T + b (+ C)) at the object's precision, act = GELU when `gelu`. FP32
 * applies the exact (erf) GELU the network was trained with, as a second pass. FP16 / INT8 fuse
 * the deterministic kernels' tanh-form GELU (at most 4.7e-4 from the exact one) into the
 * product's epilogue, which saves that pass over the activations (the 256-wide lifting ones
 * are the largest tensor of the forward). */
static void dense(const fnopt_fno *F, uint32_t id, uint32_t M, const float *A, uint32_t lda, float *C, uint32_t ldc,
                  bool accumulate, bool gelu)
{
    if (F->prec == WEFT_PRECISION_FP32) {
        const float *W = NULL, *b = NULL;
        uint32_t N = 0, K = 0;
        dense_source(&F->wt, id, &W, &b, &N, &K);
        F->ctx->kernels->gemm(M, N, K, A, lda, W, K, b, C, ldc, WEFT_ACT_NONE, accumulate);
        if (gelu) {
            for (uint32_t m = 0; m < M; ++m) {
                F->simd->gelu(C + (size_t)m * ldc, N);
            }
        }
        return;
    }
    const fnopt_layer *l = &F->dense[id];
    const weft_activation act = gelu ? WEFT_ACT_GELU : WEFT_ACT_NONE;
    if (l->q8_packed) {
        F->qk->quantize_rows(A, M, l->k_in, lda, F->qa, F->qa_ld, F->qa_scale);
        F->qk->gemm_q8(M, F->qa, F->qa_ld, F->qa_scale, &l->q8, l->bias, C, ldc, act, accumulate);
    } else if (l->w16) {
        F->qk->gemm_f16(M, l->n_out, l->k_in, A, lda, l->w16, l->n_out, l->bias, C, ldc, act, accumulate);
    } else {
        F->qk->gemm_det(M, l->n_out, l->k_in, A, lda, l->w32t, l->n_out, l->bias, C, ldc, act, accumulate);
    }
}

weft_result fnopt__fno_init(const weft_context *ctx, fnopt_fno *F, const fnopt_weights *wt, uint32_t h,
                            uint32_t w, uint32_t batch, weft_precision prec)
{
    memset(F, 0, sizeof *F);
    if (!ctx->kernels || !ctx->kernels->gemm) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_fnopt_create: the context's kernel table has no gemm");
    }
    if ((unsigned)prec >= WEFT_PRECISION_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_create: precision %d out of range", (int)prec);
    }
    if (w < 2 * FNOPT_MODES_W || h < FNOPT_MODES_H + 2) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_fnopt_create: the FNO keeps 8 x 5 modes and needs height >= 10 and width >= 10 "
                          "(got %ux%u)", h, w);
    }
    F->ctx = ctx;
    F->wt = *wt;
    F->h = h;
    F->w = w;
    F->n = h * w;
    F->batch = batch;
    F->prec = prec;
    F->simd = simd_for(ctx->isa);
    size_t parts[10];
    size_t total = fno_floats(h, w, batch, wt, parts);
    F->bytes = total * sizeof(float);
    float *mem = weft__alloc(ctx, F->bytes);
    if (!mem) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory for the FNO (%zu bytes)", F->bytes);
    }
    float *p = mem;
    F->spec_re = p, p += parts[0];
    F->spec_im = p, p += parts[0];
    F->tw_h_c = p, p += parts[1];
    F->tw_h_s = p, p += parts[1];
    F->tw_w_c = p, p += parts[2];
    F->tw_w_s = p, p += parts[2];
    F->grid = p, p += parts[3];
    F->in = p, p += parts[4];
    F->big = p, p += parts[5];
    F->hA = p, p += parts[6];
    F->hB = p, p += parts[6];
    F->fa = p, p += 2 * parts[7];
    F->fx = p, p += 2 * parts[8];
    F->fy = p, p += 2 * parts[8];
    F->feat = p;

    const uint32_t C = wt->width, half = FNOPT_MODES_H / 2;
    /* spectral weights [in][out][m][ky][2] -> [layer][mode][in][out], contiguous over `out` */
    for (uint32_t l = 0; l < wt->layers; ++l) {
        const float *src = wt->spec_w[l];
        for (uint32_t i = 0; i < C; ++i) {
            for (uint32_t o = 0; o < C; ++o) {
                for (uint32_t md = 0; md < FNOPT_MODES; ++md) {
                    size_t s = (((size_t)i * C + o) * FNOPT_MODES + md) * 2;
                    size_t d = (((size_t)l * FNOPT_MODES + md) * C + i) * C + o;
                    F->spec_re[d] = src[s];
                    F->spec_im[d] = src[s + 1];
                }
            }
        }
    }
    /* twiddles; the phase is reduced mod the period in integers before the double cos/sin */
    for (uint32_t m = 0; m < FNOPT_MODES_H; ++m) {
        int kx = (int)m - (int)half;
        for (uint32_t i = 0; i < h; ++i) {
            long ph = ((long)kx * (long)i) % (long)h;
            double a = TWO_PI * (double)ph / (double)h;
            F->tw_h_c[m * h + i] = (float)cos(a);
            F->tw_h_s[m * h + i] = (float)sin(a);
        }
    }
    for (uint32_t ky = 0; ky < FNOPT_MODES_W; ++ky) {
        for (uint32_t j = 0; j < w; ++j) {
            long ph = ((long)ky * (long)j) % (long)w;
            double a = TWO_PI * (double)ph / (double)w;
            F->tw_w_c[ky * w + j] = (float)cos(a);
            F->tw_w_s[ky * w + j] = (float)sin(a);
        }
    }
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            F->grid[2 * ((size_t)i * w + j)] = (float)((double)i / (double)(h - 1));
            F->grid[2 * ((size_t)i * w + j) + 1] = (float)((double)j / (double)(w - 1));
        }
    }
    weft_result r = dense_init(F);
    if (r != WEFT_OK) {
        weft__free(ctx, F->spec_re, F->bytes);
        memset(F, 0, sizeof *F);
    }
    return r;
}

void fnopt__fno_free(fnopt_fno *F)
{
    if (F->ctx) {
        dense_free_all(F);
    }
    if (F->ctx && F->spec_re) {
        weft__free(F->ctx, F->spec_re, F->bytes);
    }
    memset(F, 0, sizeof *F);
}

void fnopt__fno_forward(fnopt_fno *F, const float *z, float *u, float *d)
{
    const fnopt_weights *wt = &F->wt;
    const uint32_t n = F->n, B = F->batch, C = wt->width, cin = wt->in_channels + 2;
    const uint32_t M = B * n;
    /* lifting input: the optimizer's channels, then the (i/(h-1), j/(w-1)) grid embedding */
    for (uint32_t s = 0; s < B; ++s) {
        for (uint32_t p = 0; p < n; ++p) {
            float *row = F->in + ((size_t)s * n + p) * cin;
            const float *zr = z + ((size_t)s * n + p) * wt->in_channels;
            for (uint32_t c = 0; c < wt->in_channels; ++c) {
                row[c] = zr[c];
            }
            row[wt->in_channels] = F->grid[2 * p];
            row[wt->in_channels + 1] = F->grid[2 * p + 1];
        }
    }
    dense(F, FNOPT_L_LIFT0, M, F->in, cin, F->big, wt->lifting, false, true);
    dense(F, FNOPT_L_LIFT1, M, F->big, wt->lifting, F->hA, C, false, false);
    float *h = F->hA, *o = F->hB;
    for (uint32_t l = 0; l < wt->layers; ++l) {
        for (uint32_t s = 0; s < B; ++s) {
            F->simd->spectral(F, l, h + (size_t)s * n * C, o + (size_t)s * n * C);
        }
        /* o += h Wskip^T + bias (the skip has no bias of its own; the spectral bias rides here) */
        dense(F, FNOPT_L_SKIP0 + l, M, h, C, o, C, true, l + 1 < wt->layers);
        if (l == wt->scale_layer) {
            for (uint32_t s = 0; s < B; ++s) {
                float *f = F->feat + (size_t)s * C;
                const float *src = o + (size_t)s * n * C;
                for (uint32_t c = 0; c < C; ++c) {
                    f[c] = src[c];
                }
                for (uint32_t p = 1; p < n; ++p) {
                    for (uint32_t c = 0; c < C; ++c) {
                        f[c] = src[(size_t)p * C + c] > f[c] ? src[(size_t)p * C + c] : f[c];
                    }
                }
            }
        }
        float *t = h;
        h = o;
        o = t;
    }
    dense(F, FNOPT_L_PROJ0, M, h, C, F->big, wt->projection, false, true);
    dense(F, FNOPT_L_PROJ1, M, F->big, wt->projection, u, 1, false, false);
    dense(F, FNOPT_L_HEAD, B, F->feat, C, d, 1, false, false);
}

/* ---- binding an "fnopt" model ----------------------------------------------------------- */

static weft_result need(const weft_model *m, const char *name, const float **out, uint32_t rank, const uint64_t *dims)
{
    const weft_tensor *t = NULL;
    weft_result r = weft__model_require(m, name, WEFT_DTYPE_F32, rank, dims, &t);
    if (r == WEFT_OK) {
        if (!weft__all_finite(t->data, t->count)) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "fnopt model: tensor '%s' holds NaN or infinity", name);
        }
        *out = t->data;
    }
    return r;
}

weft_result fnopt__weights_from_model(const weft_model *model, fnopt_weights *wt)
{
    memset(wt, 0, sizeof *wt);
    const char *arch = weft__model_metadata(model, "architecture");
    if (!arch || strcmp(arch, "fnopt") != 0) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "weft_fnopt_create: model architecture is '%s', expected 'fnopt'",
                          arch ? arch : "(none)");
    }
    uint32_t mh = 0, mw = 0;
    weft_result r = weft__model_config_u32(model, "width", 1, 4096, &wt->width);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "lifting_channels", 1, 1u << 16, &wt->lifting);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "projection_channels", 1, 1u << 16, &wt->projection);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "n_layers", 1, FNOPT_MAX_LAYERS, &wt->layers);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "scale_feature_layer", 0, FNOPT_MAX_LAYERS - 1, &wt->scale_layer);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "in_channels", 3, 3, &wt->in_channels);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "modes_h", FNOPT_MODES_H, FNOPT_MODES_H, &mh);
    if (r == WEFT_OK) r = weft__model_config_u32(model, "modes_w", FNOPT_MODES_W, FNOPT_MODES_W, &mw);
    double scale = 0.0;
    if (r == WEFT_OK) r = weft__model_config_number(model, "initial_scale", &scale);
    if (r != WEFT_OK) {
        return r;
    }
    if (wt->scale_layer >= wt->layers) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "fnopt model: scale_feature_layer %u >= n_layers %u",
                          wt->scale_layer, wt->layers);
    }
    if (!(scale > 0.0 && scale < 1e6)) {
        return weft__fail(WEFT_ERROR_BAD_METADATA, "fnopt model: initial_scale %g must be in (0, 1e6)", scale);
    }
    wt->initial_scale = (float)scale;
    const uint64_t C = wt->width, Lf = wt->lifting, P = wt->projection;
    r = need(model, "lift0.weight", &wt->lift0_w, 2, (const uint64_t[]){Lf, wt->in_channels + 2});
    if (r == WEFT_OK) r = need(model, "lift0.bias", &wt->lift0_b, 1, (const uint64_t[]){Lf});
    if (r == WEFT_OK) r = need(model, "lift1.weight", &wt->lift1_w, 2, (const uint64_t[]){C, Lf});
    if (r == WEFT_OK) r = need(model, "lift1.bias", &wt->lift1_b, 1, (const uint64_t[]){C});
    for (uint32_t l = 0; l < wt->layers && r == WEFT_OK; ++l) {
        char name[64];
        snprintf(name, sizeof name, "blocks.%u.spectral.weight", l);
        r = need(model, name, &wt->spec_w[l], 5, (const uint64_t[]){C, C, FNOPT_MODES_H, FNOPT_MODES_W, 2});
        if (r == WEFT_OK) {
            snprintf(name, sizeof name, "blocks.%u.bias", l);
            r = need(model, name, &wt->spec_b[l], 1, (const uint64_t[]){C});
        }
        if (r == WEFT_OK) {
            snprintf(name, sizeof name, "blocks.%u.skip.weight", l);
            r = need(model, name, &wt->skip_w[l], 2, (const uint64_t[]){C, C});
        }
    }
    if (r == WEFT_OK) r = need(model, "proj0.weight", &wt->proj0_w, 2, (const uint64_t[]){P, C});
    if (r == WEFT_OK) r = need(model, "proj0.bias", &wt->proj0_b, 1, (const uint64_t[]){P});
    if (r == WEFT_OK) r = need(model, "proj1.weight", &wt->proj1_w, 2, (const uint64_t[]){1, P});
    if (r == WEFT_OK) r = need(model, "proj1.bias", &wt->proj1_b, 1, (const uint64_t[]){1});
    if (r == WEFT_OK) r = need(model, "head.weight", &wt->head_w, 2, (const uint64_t[]){1, C});
    if (r == WEFT_OK) r = need(model, "head.bias", &wt->head_b, 1, (const uint64_t[]){1});
    return r;
}

/* ---- the learned-optimizer wrapper ------------------------------------------------------- */

weft_result fnopt__learned_init(const weft_context *ctx, fnopt_learned *Lo, const fnopt_weights *wt, uint32_t h,
                                uint32_t w, weft_precision prec)
{
    memset(Lo, 0, sizeof *Lo);
    size_t n = (size_t)h * w;
    weft_result r = fnopt__fno_init(ctx, &Lo->fno, wt, h, w, 3, prec);
    if (r != WEFT_OK) {
        return r;
    }
    Lo->g_prev = weft__alloc(ctx, 3 * n * sizeof(float));
    Lo->s_prev = weft__alloc(ctx, 3 * n * sizeof(float));
    Lo->z = weft__alloc(ctx, 9 * n * sizeof(float));
    Lo->u = weft__alloc(ctx, 3 * n * sizeof(float));
    if (!Lo->g_prev || !Lo->s_prev || !Lo->z || !Lo->u) {
        fnopt__learned_free(ctx, Lo);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory for the optimizer state");
    }
    fnopt__learned_reset(Lo);
    return WEFT_OK;
}

void fnopt__learned_free(const weft_context *ctx, fnopt_learned *Lo)
{
    size_t n = Lo->fno.n;
    weft__free(ctx, Lo->g_prev, 3 * n * sizeof(float));
    weft__free(ctx, Lo->s_prev, 3 * n * sizeof(float));
    weft__free(ctx, Lo->z, 9 * n * sizeof(float));
    weft__free(ctx, Lo->u, 3 * n * sizeof(float));
    fnopt__fno_free(&Lo->fno);
    memset(Lo, 0, sizeof *Lo);
}

void fnopt__learned_reset(fnopt_learned *Lo)
{
    size_t n = Lo->fno.n;
    memset(Lo->g_prev, 0, 3 * n * sizeof(float));
    memset(Lo->s_prev, 0, 3 * n * sizeof(float));
    for (int c = 0; c < 3; ++c) {
        Lo->scale[c] = Lo->fno.wt.initial_scale;
    }
}

static double rms_or_tiny(const float *x, size_t n, size_t stride)
{
    double s = 0.0;
    for (size_t i = 0; i < n; ++i) {
        s += (double)x[i * stride] * x[i * stride];
    }
    double r = sqrt(s);
    /* max(||x||, 1e-40) / sqrt(n): the floor keeps an all-zero history finite. Kept in double:
     * in float the floor is denormal and its reciprocal overflows. */
    return (r > 1e-40 ? r : 1e-40) / sqrt((double)n);
}

/* 10 tanh(x / std / 10): soft clip at +-10 standard deviations. */
static inline float soft(float x, double inv_std) { return 10.0f * tanhf((float)((double)x * inv_std * 0.1)); }

void fnopt__learned_update(fnopt_learned *Lo, const float *grad, float *acc)
{
    const size_t n = Lo->fno.n;
    /* the x, y and z components are three independent one-channel samples */
    for (size_t c = 0; c < 3; ++c) {
        const float *gp = Lo->g_prev + c * n, *sp = Lo->s_prev + c * n;
        const double ig = 1.0 / rms_or_tiny(grad + c, n, 3), is = 1.0 / rms_or_tiny(sp, n, 1);
        float *z = Lo->z + c * n * 3;
        for (size_t p = 0; p < n; ++p) {
            z[3 * p] = soft(grad[3 * p + c], ig);
            z[3 * p + 1] = soft(gp[p], ig);   /* the previous gradient, on the current scale */
            z[3 * p + 2] = soft(sp[p], is);
        }
    }
    fnopt__fno_forward(&Lo->fno, Lo->z, Lo->u, Lo->d);
    for (size_t c = 0; c < 3; ++c) {
        /* the scale moves by a factor in [e^-3, e^1]; d = 0 shrinks it by e^-1 */
        float e = 2.0f * tanhf(Lo->d[c] * 0.5f) - 1.0f;
        float scale = Lo->scale[c] * expf(e);
        if (Lo->max_scale > 0.0f && scale > Lo->max_scale) {
            scale = Lo->max_scale; /* the trust region (weft_fnopt_def.max_step) */
        }
        Lo->scale[c] = scale;
        float *gp = Lo->g_prev + c * n, *sp = Lo->s_prev + c * n;
        const float *u = Lo->u + c * n;
        for (size_t p = 0; p < n; ++p) {
            float step = tanhf(u[p]) * scale;
            acc[3 * p + c] += step;
            sp[p] = step;
            gp[p] = grad[3 * p + c];
        }
    }
}
