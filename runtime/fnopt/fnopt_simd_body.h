/* The FNO's spectral convolution and erf GELU, compiled once per kernel level
 * (fnopt_simd.c, fnopt_simd_avx2.c, fnopt_simd_avx512.c) so the compiler vectorizes the
 * channel loops for each. Bit-identical across the twins: the loops run along channels with no
 * cross-lane reduction (the per-mode channel mixing is a sequential sum the compiler keeps in
 * order), and every multiply is its own statement, so no compiler contracts a multiply-add into
 * a fused one (GCC does not in ISO C mode; clang's default contracts only inside one
 * expression). Include after defining FNOPT_SIMD_NAME(x) and FNOPT_SIMD_TABLE. */
#include "fnopt/fnopt_internal.h"

#include <string.h>

/* erf as a rational function of x^2 on [-4, 4] (odd numerator of degree 13, denominator of
 * degree 8; erf(4) is 1 to float precision). Branch-free, so the GELU loop vectorizes, which
 * calls to libm's erff prevent. Checked against libm's erf in tests. */
static inline float FNOPT_SIMD_NAME(erf)(float x)
{
    x = x < -4.0f ? -4.0f : (x > 4.0f ? 4.0f : x);
    const float x2 = x * x;
    float p = -2.72614225801306e-10f;
    p *= x2, p += 2.77068142495902e-08f;
    p *= x2, p -= 2.10102402082508e-06f;
    p *= x2, p -= 5.69250639462346e-05f;
    p *= x2, p -= 7.34990630326855e-04f;
    p *= x2, p -= 2.95459980854025e-03f;
    p *= x2, p -= 1.60960333262415e-02f;
    float q = -1.45660718464996e-05f;
    q *= x2, q -= 2.13374055278905e-04f;
    q *= x2, q -= 1.68282697438203e-03f;
    q *= x2, q -= 7.37332916720468e-03f;
    q *= x2, q -= 1.42647390514189e-02f;
    const float xp = x * p;
    return xp / q;
}

/* Exact GELU, x * Phi(x) with erf, as torch.nn.functional.gelu's default; the kernels' GELU is
 * the tanh approximation, which the trained weights were not fitted to. */
static void FNOPT_SIMD_NAME(gelu)(float *x, size_t count)
{
    for (size_t i = 0; i < count; ++i) {
        const float e = FNOPT_SIMD_NAME(erf)(x[i] * 0.70710678118654752f);
        const float hx = 0.5f * x[i];
        x[i] = hx * (1.0f + e);
    }
}

/* out[n][C] = SpectralConv_l(x[n][C]) for one sample (overwrites out). */
static void FNOPT_SIMD_NAME(spectral)(const fnopt_fno *F, uint32_t l, const float *x, float *out)
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
                    const float tr = c * xp[ch], ti = s * xp[ch];
                    r[ch] += tr;
                    im[ch] -= ti;
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
                    const float rc = r[ch] * c, is = im[ch] * s, ic = im[ch] * c, rs = r[ch] * s;
                    const float tr = rc + is, ti = ic - rs;
                    orr[ch] += tr;
                    oi[ch] += ti;
                }
            }
        }
    }
    /* channel mixing per mode: Y[o] = sum_i X[i] W[i][o] (complex), vectorized along o; each
     * output still sums i = 0, 1, ... in order from zero */
    const float *wr = F->spec_re + (size_t)l * FNOPT_MODES * C * C, *wi = F->spec_im + (size_t)l * FNOPT_MODES * C * C;
    memset(F->fy, 0, 2 * (size_t)FNOPT_MODES * C * sizeof(float));
    for (uint32_t md = 0; md < FNOPT_MODES; ++md) {
        const float *pr = xr + (size_t)md * C, *pi = xi + (size_t)md * C;
        float *oyr = yr + (size_t)md * C, *oyi = yi + (size_t)md * C;
        for (uint32_t i = 0; i < C; ++i) {
            const float *wri = wr + ((size_t)md * C + i) * C, *wii = wi + ((size_t)md * C + i) * C;
            const float xre = pr[i], xim = pi[i];
            for (uint32_t o = 0; o < C; ++o) {
                const float a = xre * wri[o], b = xim * wii[o], c = xre * wii[o], d = xim * wri[o];
                const float tr = a - b, ti = c + d;
                oyr[o] += tr;
                oyi[o] += ti;
            }
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
                    const float rc = r[ch] * c, is = im[ch] * s, rs = r[ch] * s, ic = im[ch] * c;
                    const float tr = rc - is, ti = rs + ic;
                    br[ch] += tr;
                    bi[ch] += ti;
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
                    const float bc = br[ch] * c, bs = bi[ch] * s;
                    const float t = bc - bs;
                    op[ch] += t;
                }
            }
        }
    }
}

const fnopt_simd FNOPT_SIMD_TABLE = {FNOPT_SIMD_NAME(spectral), FNOPT_SIMD_NAME(gelu), FNOPT_SIMD_NAME(erf)};
