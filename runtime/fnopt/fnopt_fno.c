/* The FNO of the learned optimizer (docs/FNOPT.md, "Network"), fp32.
 *
 * Activations are pixel-major, channels fastest: row (s*n + p) of a [batch*n][C] matrix is
 * pixel p of sample s, so every 1x1 convolution is one gemm through the context's kernels.
 * The spectral convolution keeps only 8 x 5 Fourier modes, so it is computed as direct DFT
 * sums against twiddle tables built at creation (no FFT), separably: along W, then along H. */
#include "fnopt/fnopt_internal.h"
#include "model/model.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI 6.283185307179586476925

/* erf as a rational function of x^2 on [-4, 4] (odd numerator of degree 13, denominator of
 * degree 8; erf(4) is 1 to float precision). Branch-free, so the GELU loop vectorizes, which
 * calls to libm's erff prevent. Checked against libm's erf in tests. */
static inline float erf_fast(float x)
{
    x = x < -4.0f ? -4.0f : (x > 4.0f ? 4.0f : x);
    const float x2 = x * x;
    float p = -2.72614225801306e-10f;
    p = p * x2 + 2.77068142495902e-08f;
    p = p * x2 - 2.10102402082508e-06f;
    p = p * x2 - 5.69250639462346e-05f;
    p = p * x2 - 7.34990630326855e-04f;
    p = p * x2 - 2.95459980854025e-03f;
    p = p * x2 - 1.60960333262415e-02f;
    float q = -1.45660718464996e-05f;
    q = q * x2 - 2.13374055278905e-04f;
    q = q * x2 - 1.68282697438203e-03f;
    q = q * x2 - 7.37332916720468e-03f;
    q = q * x2 - 1.42647390514189e-02f;
    return x * p / q;
}

float fnopt__erf(float x) { return erf_fast(x); }

/* Exact GELU, x * Phi(x) with erf, as torch.nn.functional.gelu's default; the kernels' GELU is
 * the tanh approximation, which the trained weights were not fitted to. */
static void gelu_erf(float *x, size_t count)
{
    for (size_t i = 0; i < count; ++i) {
        x[i] = 0.5f * x[i] * (1.0f + erf_fast(x[i] * 0.70710678118654752f));
    }
}

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

weft_result fnopt__fno_init(const weft_context *ctx, fnopt_fno *F, const fnopt_weights *wt, uint32_t h,
                            uint32_t w, uint32_t batch)
{
    memset(F, 0, sizeof *F);
    if (!ctx->kernels || !ctx->kernels->gemm) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_fnopt_create: the context's kernel table has no gemm");
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
    /* spectral weights [in][out][m][ky][2] -> [layer][mode][out][in], contiguous over `in` */
    for (uint32_t l = 0; l < wt->layers; ++l) {
        const float *src = wt->spec_w[l];
        for (uint32_t i = 0; i < C; ++i) {
            for (uint32_t o = 0; o < C; ++o) {
                for (uint32_t md = 0; md < FNOPT_MODES; ++md) {
                    size_t s = (((size_t)i * C + o) * FNOPT_MODES + md) * 2;
                    size_t d = (((size_t)l * FNOPT_MODES + md) * C + o) * C + i;
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
    return WEFT_OK;
}

void fnopt__fno_free(fnopt_fno *F)
{
    if (F->ctx && F->spec_re) {
        weft__free(F->ctx, F->spec_re, F->bytes);
    }
    memset(F, 0, sizeof *F);
}

/* out[n][C] = SpectralConv_l(x[n][C]) for one sample (overwrites out). */
static void spectral(fnopt_fno *F, uint32_t l, const float *x, float *out)
{
    const uint32_t h = F->h, w = F->w, C = F->wt.width;
    const uint32_t MW = FNOPT_MODES_W, MH = FNOPT_MODES_H;
    float *ar = F->fa, *ai = F->fa + (size_t)h * MW * C;              /* [h][ky][C] */
    float *xr = F->fx, *xi = F->fx + (size_t)FNOPT_MODES * C;         /* [m][ky][C] */
    float *yr = F->fy, *yi = F->fy + (size_t)FNOPT_MODES * C;
    /* forward along W: A[i][ky] = sum_j x[i][j] e^{-2 pi i ky j / w} */
    memset(F->fa, 0, 2 * (size_t)h * MW * C * sizeof(float));
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t ky = 0; ky < MW; ++ky) {
            float *r = ar + ((size_t)i * MW + ky) * C, *im = ai + ((size_t)i * MW + ky) * C;
            for (uint32_t j = 0; j < w; ++j) {
                const float c = F->tw_w_c[ky * w + j], s = F->tw_w_s[ky * w + j];
                const float *xp = x + ((size_t)i * w + j) * C;
                for (uint32_t ch = 0; ch < C; ++ch) {
                    r[ch] += c * xp[ch];
                    im[ch] -= s * xp[ch];
                }
            }
        }
    }
    /* forward along H with norm="forward" (1/(h w)): X[m][ky] = sum_i A[i][ky] e^{-2 pi i kx i / h} */
    const float norm = 1.0f / (float)((size_t)h * w);
    memset(F->fx, 0, 2 * (size_t)FNOPT_MODES * C * sizeof(float));
    for (uint32_t m = 0; m < MH; ++m) {
        for (uint32_t i = 0; i < h; ++i) {
            const float c = F->tw_h_c[m * h + i] * norm, s = F->tw_h_s[m * h + i] * norm;
            for (uint32_t ky = 0; ky < MW; ++ky) {
                const float *r = ar + ((size_t)i * MW + ky) * C, *im = ai + ((size_t)i * MW + ky) * C;
                float *orr = xr + ((size_t)m * MW + ky) * C, *oi = xi + ((size_t)m * MW + ky) * C;
                for (uint32_t ch = 0; ch < C; ++ch) {
                    orr[ch] += r[ch] * c + im[ch] * s;
                    oi[ch] += im[ch] * c - r[ch] * s;
                }
            }
        }
    }
    /* channel mixing per mode: Y[o] = sum_i X[i] W[i][o] (complex) */
    const float *wr = F->spec_re + (size_t)l * FNOPT_MODES * C * C, *wi = F->spec_im + (size_t)l * FNOPT_MODES * C * C;
    for (uint32_t md = 0; md < FNOPT_MODES; ++md) {
        const float *pr = xr + (size_t)md * C, *pi = xi + (size_t)md * C;
        for (uint32_t o = 0; o < C; ++o) {
            const float *wro = wr + ((size_t)md * C + o) * C, *wio = wi + ((size_t)md * C + o) * C;
            float sr = 0.0f, si = 0.0f;
            for (uint32_t i = 0; i < C; ++i) {
                sr += pr[i] * wro[i] - pi[i] * wio[i];
                si += pr[i] * wio[i] + pi[i] * wro[i];
            }
            yr[(size_t)md * C + o] = sr;
            yi[(size_t)md * C + o] = si;
        }
    }
    /* inverse along H: B[i][ky] = sum_m Y[m][ky] e^{+2 pi i kx i / h} (reuses the A buffer) */
    memset(F->fa, 0, 2 * (size_t)h * MW * C * sizeof(float));
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t m = 0; m < MH; ++m) {
            const float c = F->tw_h_c[m * h + i], s = F->tw_h_s[m * h + i];
            for (uint32_t ky = 0; ky < MW; ++ky) {
                const float *r = yr + ((size_t)m * MW + ky) * C, *im = yi + ((size_t)m * MW + ky) * C;
                float *br = ar + ((size_t)i * MW + ky) * C, *bi = ai + ((size_t)i * MW + ky) * C;
                for (uint32_t ch = 0; ch < C; ++ch) {
                    br[ch] += r[ch] * c - im[ch] * s;
                    bi[ch] += r[ch] * s + im[ch] * c;
                }
            }
        }
    }
    /* inverse along W, complex-to-real: out = sum_ky c_ky Re(B e^{+2 pi i ky j / w}), c_0 = 1,
     * c_ky = 2 otherwise; the imaginary part of the ky = 0 column drops out */
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            float *op = out + ((size_t)i * w + j) * C;
            const float *br0 = ar + (size_t)i * MW * C;
            for (uint32_t ch = 0; ch < C; ++ch) {
                op[ch] = br0[ch];
            }
            for (uint32_t ky = 1; ky < MW; ++ky) {
                const float c = 2.0f * F->tw_w_c[ky * w + j], s = 2.0f * F->tw_w_s[ky * w + j];
                const float *br = ar + ((size_t)i * MW + ky) * C, *bi = ai + ((size_t)i * MW + ky) * C;
                for (uint32_t ch = 0; ch < C; ++ch) {
                    op[ch] += br[ch] * c - bi[ch] * s;
                }
            }
        }
    }
}

void fnopt__fno_forward(fnopt_fno *F, const float *z, float *u, float *d)
{
    const weft_kernels *K = F->ctx->kernels;
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
    K->gemm(M, wt->lifting, cin, F->in, cin, wt->lift0_w, cin, wt->lift0_b, F->big, wt->lifting, WEFT_ACT_NONE,
            false);
    gelu_erf(F->big, (size_t)M * wt->lifting);
    K->gemm(M, C, wt->lifting, F->big, wt->lifting, wt->lift1_w, wt->lifting, wt->lift1_b, F->hA, C, WEFT_ACT_NONE,
            false);
    float *h = F->hA, *o = F->hB;
    for (uint32_t l = 0; l < wt->layers; ++l) {
        for (uint32_t s = 0; s < B; ++s) {
            spectral(F, l, h + (size_t)s * n * C, o + (size_t)s * n * C);
        }
        /* o += h Wskip^T + bias (the skip has no bias of its own; the spectral bias rides here) */
        K->gemm(M, C, C, h, C, wt->skip_w[l], C, wt->spec_b[l], o, C, WEFT_ACT_NONE, true);
        if (l + 1 < wt->layers) {
            gelu_erf(o, (size_t)M * C);
        }
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
    K->gemm(M, wt->projection, C, h, C, wt->proj0_w, C, wt->proj0_b, F->big, wt->projection, WEFT_ACT_NONE, false);
    gelu_erf(F->big, (size_t)M * wt->projection);
    K->gemm(M, 1, wt->projection, F->big, wt->projection, wt->proj1_w, wt->projection, wt->proj1_b, u, 1,
            WEFT_ACT_NONE, false);
    K->gemm(B, 1, C, F->feat, C, wt->head_w, C, wt->head_b, d, 1, WEFT_ACT_NONE, false);
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
                                uint32_t w)
{
    memset(Lo, 0, sizeof *Lo);
    size_t n = (size_t)h * w;
    weft_result r = fnopt__fno_init(ctx, &Lo->fno, wt, h, w, 3);
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
