/* The FNOpt physics loss (docs/FNOPT.md, "Loss") and its analytic gradient with respect to the
 * acceleration. Computed in double from fp32 inputs: the terms are means over thousands of
 * edges and the optimizers compare losses across iterations, so the sums must not drift. */
#include "fnopt/fnopt_internal.h"

#include <math.h>
#include <string.h>

/* The acos clamp of the reference code, 1 - 1e-7 rounded to float32 (0.99999988): angles under
 * about 4.9e-4 rad give zero gradient, so a straight grid line has no bending force. */
static const double k_cos_max = 0.99999988079071044921875;
static const double k_half_pi = 1.57079632679489661923;

weft_result fnopt__loss_init(const weft_context *ctx, fnopt_loss *L, uint32_t h, uint32_t w)
{
    memset(L, 0, sizeof *L);
    L->h = h;
    L->w = w;
    L->n = h * w;
    size_t n = L->n, nI = (size_t)(h - 1) * w, nJ = (size_t)h * (w - 1);
    size_t nr = (size_t)FNOPT_REP_RES * FNOPT_REP_RES;
    L->mass = weft__alloc(ctx, n * sizeof(float));
    L->xn = weft__alloc(ctx, 3 * n * sizeof(double));
    L->uI = weft__alloc(ctx, 3 * nI * sizeof(double));
    L->lI = weft__alloc(ctx, nI * sizeof(double));
    L->gI = weft__alloc(ctx, 3 * nI * sizeof(double));
    L->uJ = weft__alloc(ctx, 3 * nJ * sizeof(double));
    L->lJ = weft__alloc(ctx, nJ * sizeof(double));
    L->gJ = weft__alloc(ctx, 3 * nJ * sizeof(double));
    L->gx = weft__alloc(ctx, 3 * n * sizeof(double));
    L->rp = weft__alloc(ctx, 3 * nr * sizeof(double));
    L->rg = weft__alloc(ctx, 3 * nr * sizeof(double));
    if (!L->mass || !L->xn || !L->uI || !L->lI || !L->gI || !L->uJ || !L->lJ || !L->gJ || !L->gx || !L->rp ||
        !L->rg) {
        fnopt__loss_free(ctx, L);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory for the %ux%u loss", h, w);
    }
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            float mi = (i == 0 || i == h - 1) ? 0.5f : 1.0f;
            float mj = (j == 0 || j == w - 1) ? 0.5f : 1.0f;
            L->mass[i * w + j] = mi * mj;
        }
    }
    return WEFT_OK;
}

void fnopt__loss_free(const weft_context *ctx, fnopt_loss *L)
{
    size_t n = L->n, nI = (size_t)(L->h - 1) * L->w, nJ = (size_t)L->h * (L->w - 1);
    size_t nr = (size_t)FNOPT_REP_RES * FNOPT_REP_RES;
    weft__free(ctx, L->mass, n * sizeof(float));
    weft__free(ctx, L->xn, 3 * n * sizeof(double));
    weft__free(ctx, L->uI, 3 * nI * sizeof(double));
    weft__free(ctx, L->lI, nI * sizeof(double));
    weft__free(ctx, L->gI, 3 * nI * sizeof(double));
    weft__free(ctx, L->uJ, 3 * nJ * sizeof(double));
    weft__free(ctx, L->lJ, nJ * sizeof(double));
    weft__free(ctx, L->gJ, 3 * nJ * sizeof(double));
    weft__free(ctx, L->gx, 3 * n * sizeof(double));
    weft__free(ctx, L->rp, 3 * nr * sizeof(double));
    weft__free(ctx, L->rg, 3 * nr * sizeof(double));
    memset(L, 0, sizeof *L);
}

/* Edge from vertex a to b: unit vector (e / max(|e|, 1e-12)) and length. */
static inline void edge(const double *xn, size_t a, size_t b, double *u, double *len)
{
    double e0 = xn[3 * b] - xn[3 * a], e1 = xn[3 * b + 1] - xn[3 * a + 1], e2 = xn[3 * b + 2] - xn[3 * a + 2];
    double l = sqrt(e0 * e0 + e1 * e1 + e2 * e2);
    double inv = 1.0 / (l > 1e-12 ? l : 1e-12);
    u[0] = e0 * inv;
    u[1] = e1 * inv;
    u[2] = e2 * inv;
    *len = l;
}

/* Angle between unit vectors p and q (lengths lp, lq); adds coef * d(outer(theta))/d edge to
 * gp, gq, where outer is (theta - pi/2)^2 (shear) or theta^2 (bend). Returns outer(theta). */
static inline double angle_term(const double *p, double lp, const double *q, double lq, double coef, bool shear,
                                double *gp, double *gq, bool want_grad)
{
    double c = p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    double cc = c > k_cos_max ? k_cos_max : (c < -k_cos_max ? -k_cos_max : c);
    double th = acos(cc);
    double r = shear ? th - k_half_pi : th;
    if (want_grad && cc == c) {
        /* d outer/d theta * d theta/d c; the clamp blocks the gradient outside its range */
        double dc = coef * 2.0 * r * (-1.0 / sqrt(1.0 - c * c));
        double ip = dc / (lp > 1e-12 ? lp : 1e-12), iq = dc / (lq > 1e-12 ? lq : 1e-12);
        for (int k = 0; k < 3; ++k) {
            gp[k] += ip * (q[k] - c * p[k]);
            gq[k] += iq * (p[k] - c * q[k]);
        }
    }
    return r * r;
}

/* Bilinear resampling of the h x w grid onto R x R with align_corners semantics: sample (a, b)
 * sits at grid coordinate (a (h-1)/(R-1), b (w-1)/(R-1)). */
static void rep_sample_coords(uint32_t a, uint32_t size, uint32_t *i0, double *t)
{
    double s = (double)a * (double)(size - 1) / (double)(FNOPT_REP_RES - 1);
    uint32_t i = (uint32_t)floor(s);
    if (i >= size - 1) {
        i = size - 2;
    }
    *i0 = i;
    *t = s - (double)i;
}

static double repulsion(fnopt_loss *L, double k, double thres, bool want_grad)
{
    const uint32_t R = FNOPT_REP_RES, NR = R * R;
    const uint32_t h = L->h, w = L->w;
    double *rp = L->rp, *rg = L->rg;
    for (uint32_t a = 0; a < R; ++a) {
        uint32_t i0;
        double ti;
        rep_sample_coords(a, h, &i0, &ti);
        for (uint32_t b = 0; b < R; ++b) {
            uint32_t j0;
            double tj;
            rep_sample_coords(b, w, &j0, &tj);
            const double *p00 = L->xn + 3 * ((size_t)i0 * w + j0), *p01 = p00 + 3;
            const double *p10 = p00 + 3 * (size_t)w, *p11 = p10 + 3;
            for (int c = 0; c < 3; ++c) {
                double top = p00[c] * (1 - tj) + p01[c] * tj, bot = p10[c] * (1 - tj) + p11[c] * tj;
                rp[3 * (a * R + b) + c] = top * (1 - ti) + bot * ti;
            }
        }
    }
    if (want_grad) {
        memset(rg, 0, 3 * (size_t)NR * sizeof(double));
    }
    double t2 = thres * thres, e = 0.0;
    for (uint32_t p = 0; p < NR; ++p) {
        int pi = (int)(p / R), pj = (int)(p % R);
        for (uint32_t q = p + 1; q < NR; ++q) {
            int di = (int)(q / R) - pi, dj = (int)(q % R) - pj;
            /* triangle-mesh neighbours (horizontal, vertical, the (i,j)-(i+1,j+1) diagonal) are
             * excluded: they are close by construction */
            if ((di == 0 && dj == 1) || (di == 1 && (dj == 0 || dj == 1))) {
                continue;
            }
            double d0 = rp[3 * p] - rp[3 * q], d1 = rp[3 * p + 1] - rp[3 * q + 1], d2 = rp[3 * p + 2] - rp[3 * q + 2];
            double dd = d0 * d0 + d1 * d1 + d2 * d2 + 1e-8;
            if (dd >= t2) {
                continue;
            }
            e += -2.0 * log(dd); /* both orderings of the pair */
            if (want_grad) {
                double s = -4.0 * k / dd;
                rg[3 * p] += s * d0;
                rg[3 * p + 1] += s * d1;
                rg[3 * p + 2] += s * d2;
                rg[3 * q] -= s * d0;
                rg[3 * q + 1] -= s * d1;
                rg[3 * q + 2] -= s * d2;
            }
        }
    }
    if (want_grad) {
        /* transpose of the bilinear resampling */
        for (uint32_t a = 0; a < R; ++a) {
            uint32_t i0;
            double ti;
            rep_sample_coords(a, h, &i0, &ti);
            for (uint32_t b = 0; b < R; ++b) {
                uint32_t j0;
                double tj;
                rep_sample_coords(b, w, &j0, &tj);
                double *g00 = L->gx + 3 * ((size_t)i0 * w + j0), *g01 = g00 + 3;
                double *g10 = g00 + 3 * (size_t)w, *g11 = g10 + 3;
                const double *g = rg + 3 * (a * R + b);
                for (int c = 0; c < 3; ++c) {
                    g00[c] += g[c] * (1 - ti) * (1 - tj);
                    g01[c] += g[c] * (1 - ti) * tj;
                    g10[c] += g[c] * ti * (1 - tj);
                    g11[c] += g[c] * ti * tj;
                }
            }
        }
    }
    return k * e;
}

/* Stretch + shear + bend of L->xn; accumulates dE/dx into L->gx when want_grad. */
static double energy(fnopt_loss *L, double Y, double S, double B, bool want_grad)
{
    const uint32_t h = L->h, w = L->w;
    const double n = (double)L->n;
    const size_t nI = (size_t)(h - 1) * w, nJ = (size_t)h * (w - 1);
    for (uint32_t i = 0; i + 1 < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            size_t e = (size_t)i * w + j;
            edge(L->xn, e, e + w, L->uI + 3 * e, L->lI + e);
        }
    }
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j + 1 < w; ++j) {
            size_t e = (size_t)i * (w - 1) + j, a = (size_t)i * w + j;
            edge(L->xn, a, a + 1, L->uJ + 3 * e, L->lJ + e);
        }
    }
    if (want_grad) {
        memset(L->gI, 0, 3 * nI * sizeof(double));
        memset(L->gJ, 0, 3 * nJ * sizeof(double));
    }
    /* stretch: Y * (mean over I-edges + mean over J-edges) of (|e| - 1)^2 */
    double sI = 0.0, sJ = 0.0;
    const double cI = 1.0 / (double)nI, cJ = 1.0 / (double)nJ;
    for (size_t e = 0; e < nI; ++e) {
        double r = L->lI[e] - 1.0;
        sI += r * r;
        if (want_grad) {
            double gs = 2.0 * Y * cI * r;
            for (int k = 0; k < 3; ++k) {
                L->gI[3 * e + k] += gs * L->uI[3 * e + k];
            }
        }
    }
    for (size_t e = 0; e < nJ; ++e) {
        double r = L->lJ[e] - 1.0;
        sJ += r * r;
        if (want_grad) {
            double gs = 2.0 * Y * cJ * r;
            for (int k = 0; k < 3; ++k) {
                L->gJ[3 * e + k] += gs * L->uJ[3 * e + k];
            }
        }
    }
    double total = Y * (sI * cI + sJ * cJ);
    /* shear: the four corner angles of each quad, (theta - pi/2)^2 */
    const double cs = S / n;
    double shear = 0.0;
    for (uint32_t i = 0; i + 1 < h; ++i) {
        for (uint32_t j = 0; j + 1 < w; ++j) {
            size_t a = (size_t)i * w + j, b = a + 1;                       /* I(i,j), I(i,j+1) */
            size_t c = (size_t)i * (w - 1) + j, d = c + (w - 1);           /* J(i,j), J(i+1,j) */
            const size_t ie[4] = {a, a, b, b}, je[4] = {c, d, c, d};
            for (int q = 0; q < 4; ++q) {
                shear += angle_term(L->uI + 3 * ie[q], L->lI[ie[q]], L->uJ + 3 * je[q], L->lJ[je[q]], cs, true,
                                    L->gI + 3 * ie[q], L->gJ + 3 * je[q], want_grad);
            }
        }
    }
    total += cs * shear;
    /* bend: angle between consecutive edges along each grid line, theta^2 */
    const double cb = B / n;
    double bend = 0.0;
    for (uint32_t i = 0; i + 2 < h; ++i) {
        for (uint32_t j = 0; j < w; ++j) {
            size_t e0 = (size_t)i * w + j, e1 = e0 + w;
            bend += angle_term(L->uI + 3 * e1, L->lI[e1], L->uI + 3 * e0, L->lI[e0], cb, false, L->gI + 3 * e1,
                               L->gI + 3 * e0, want_grad);
        }
    }
    for (uint32_t i = 0; i < h; ++i) {
        for (uint32_t j = 0; j + 2 < w; ++j) {
            size_t e0 = (size_t)i * (w - 1) + j, e1 = e0 + 1;
            bend += angle_term(L->uJ + 3 * e1, L->lJ[e1], L->uJ + 3 * e0, L->lJ[e0], cb, false, L->gJ + 3 * e1,
                               L->gJ + 3 * e0, want_grad);
        }
    }
    total += cb * bend;
    if (want_grad) {
        /* edge e = x_b - x_a: +dE/de to b, -dE/de to a */
        for (uint32_t i = 0; i + 1 < h; ++i) {
            for (uint32_t j = 0; j < w; ++j) {
                size_t e = (size_t)i * w + j;
                for (int k = 0; k < 3; ++k) {
                    L->gx[3 * (e + w) + k] += L->gI[3 * e + k];
                    L->gx[3 * e + k] -= L->gI[3 * e + k];
                }
            }
        }
        for (uint32_t i = 0; i < h; ++i) {
            for (uint32_t j = 0; j + 1 < w; ++j) {
                size_t e = (size_t)i * (w - 1) + j, a = (size_t)i * w + j;
                for (int k = 0; k < 3; ++k) {
                    L->gx[3 * (a + 1) + k] += L->gJ[3 * e + k];
                    L->gx[3 * a + k] -= L->gJ[3 * e + k];
                }
            }
        }
    }
    return total;
}

double fnopt__loss_eval(fnopt_loss *L, const fnopt_loss_input *in, const float *acc, float *grad)
{
    const size_t n = L->n;
    const bool want_grad = grad != NULL;
    for (size_t v = 0; v < n; ++v) {
        for (int k = 0; k < 3; ++k) {
            size_t q = 3 * v + k;
            /* summed in double: the acos clamp makes the bending gradient jump where an angle
             * crosses about 4.9e-4 rad, so fp32 rounding of x + v + a would flip angles across it */
            double xn = (double)in->x[q] + (double)in->v[q] + (acc ? (double)acc[q] : 0.0);
            L->xn[q] = in->mask[v] ? (double)in->bc[q] : xn;
        }
    }
    if (want_grad) {
        memset(L->gx, 0, 3 * n * sizeof(double));
    }
    double total = energy(L, in->Y, in->S, in->B, want_grad);
    if (in->k_rep > 0.0f) {
        total += repulsion(L, in->k_rep, in->rep_thres, want_grad);
    }
    /* inertia 1/(2N) sum M |a|^2 and external work -1/N sum M a.g */
    const double invn = 1.0 / (double)n;
    double inert = 0.0, ext = 0.0;
    for (size_t v = 0; v < n; ++v) {
        double m = L->mass[v];
        for (int k = 0; k < 3; ++k) {
            double a = acc ? acc[3 * v + k] : 0.0;
            inert += m * a * a;
            ext += m * a * in->gravity[k];
            if (want_grad) {
                double gpos = in->mask[v] ? 0.0 : L->gx[3 * v + k];
                grad[3 * v + k] = (float)(gpos + m * invn * (a - in->gravity[k]));
            }
        }
    }
    total += 0.5 * invn * inert - invn * ext;
    return total;
}

double fnopt__internal_energy(fnopt_loss *L, const float *p, float Y, float S, float B)
{
    for (size_t q = 0; q < 3 * (size_t)L->n; ++q) {
        L->xn[q] = p[q];
    }
    return energy(L, Y, S, B, false);
}
