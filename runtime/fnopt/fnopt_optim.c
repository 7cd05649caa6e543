/* Classical optimizers on the FNOpt loss, the baselines of docs/FNOPT.md: gradient descent,
 * Adam and L-BFGS. Each restarts at every time step (a starts at 0, so old moments or curvature
 * pairs describe a different problem). */
#include "fnopt/fnopt_internal.h"

#include <math.h>
#include <string.h>

weft_result fnopt__classic_init(const weft_context *ctx, fnopt_classic *C, weft_fnopt_optimizer kind,
                                uint32_t n3, uint32_t history, float lr, float beta1, float beta2)
{
    memset(C, 0, sizeof *C);
    C->kind = kind;
    C->n3 = n3;
    C->history = kind == WEFT_FNOPT_LBFGS ? history : 0;
    C->lr = lr;
    C->beta1 = beta1;
    C->beta2 = beta2;
    bool ok = true;
    if (kind == WEFT_FNOPT_ADAM || kind == WEFT_FNOPT_LBFGS) {
        C->m = weft__alloc(ctx, n3 * sizeof(float));
        C->v = weft__alloc(ctx, n3 * sizeof(float));
        ok = C->m && C->v;
    }
    if (ok && kind == WEFT_FNOPT_LBFGS) {
        C->s = weft__alloc(ctx, (size_t)history * n3 * sizeof(float));
        C->y = weft__alloc(ctx, (size_t)history * n3 * sizeof(float));
        C->rho = weft__alloc(ctx, history * sizeof(double));
        C->alpha = weft__alloc(ctx, history * sizeof(double));
        C->dir = weft__alloc(ctx, n3 * sizeof(float));
        ok = C->s && C->y && C->rho && C->alpha && C->dir;
    }
    if (!ok) {
        fnopt__classic_free(ctx, C);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_fnopt_create: out of memory for the optimizer");
    }
    return WEFT_OK;
}

void fnopt__classic_free(const weft_context *ctx, fnopt_classic *C)
{
    size_t n3 = C->n3, hi = C->history;
    weft__free(ctx, C->m, n3 * sizeof(float));
    weft__free(ctx, C->v, n3 * sizeof(float));
    weft__free(ctx, C->s, hi * n3 * sizeof(float));
    weft__free(ctx, C->y, hi * n3 * sizeof(float));
    weft__free(ctx, C->rho, hi * sizeof(double));
    weft__free(ctx, C->alpha, hi * sizeof(double));
    weft__free(ctx, C->dir, n3 * sizeof(float));
    memset(C, 0, sizeof *C);
}

void fnopt__classic_reset(fnopt_classic *C)
{
    C->t = 0;
    C->count = 0;
    C->head = 0;
    if (C->m) {
        memset(C->m, 0, C->n3 * sizeof(float));
        memset(C->v, 0, C->n3 * sizeof(float));
    }
}

static double dot(const float *a, const float *b, size_t n)
{
    double s = 0.0;
    for (size_t i = 0; i < n; ++i) {
        s += (double)a[i] * b[i];
    }
    return s;
}

/* L-BFGS with a fixed step and no line search, as torch.optim.LBFGS with line_search_fn=None:
 * the first step is lr * min(1, 1/|g|_1) along -g, later ones lr along the two-loop direction
 * with the initial Hessian scaled by s.y / y.y. m holds the previous acc, v the previous gradient. */
static void lbfgs(fnopt_classic *C, const float *g, float *acc)
{
    const size_t n = C->n3;
    if (C->t > 0) {
        uint32_t slot = C->head;
        float *s = C->s + (size_t)slot * n, *y = C->y + (size_t)slot * n;
        for (size_t i = 0; i < n; ++i) {
            s[i] = acc[i] - C->m[i];
            y[i] = g[i] - C->v[i];
        }
        double ys = dot(y, s, n);
        if (ys > 1e-10) { /* keep only pairs with positive curvature */
            C->rho[slot] = 1.0 / ys;
            C->head = (C->head + 1) % C->history;
            if (C->count < C->history) {
                C->count++;
            }
        }
    }
    double step = C->lr;
    if (C->count == 0) {
        double l1 = 0.0;
        for (size_t i = 0; i < n; ++i) {
            l1 += fabs(g[i]);
            C->dir[i] = -g[i];
        }
        if (C->t == 0 && l1 > 1.0) {
            step = C->lr / l1;
        }
    } else {
        for (size_t i = 0; i < n; ++i) {
            C->dir[i] = -g[i];
        }
        /* newest to oldest */
        for (uint32_t k = 0; k < C->count; ++k) {
            uint32_t slot = (C->head + C->history - 1 - k) % C->history;
            const float *s = C->s + (size_t)slot * n, *y = C->y + (size_t)slot * n;
            double a = C->rho[slot] * dot(s, C->dir, n);
            C->alpha[slot] = a;
            for (size_t i = 0; i < n; ++i) {
                C->dir[i] -= (float)(a * y[i]);
            }
        }
        uint32_t newest = (C->head + C->history - 1) % C->history;
        const float *sn = C->s + (size_t)newest * n, *yn = C->y + (size_t)newest * n;
        double gamma = dot(sn, yn, n) / dot(yn, yn, n);
        for (size_t i = 0; i < n; ++i) {
            C->dir[i] = (float)(C->dir[i] * gamma);
        }
        for (uint32_t k = C->count; k-- > 0;) {
            uint32_t slot = (C->head + C->history - 1 - k) % C->history;
            const float *s = C->s + (size_t)slot * n, *y = C->y + (size_t)slot * n;
            double b = C->rho[slot] * dot(y, C->dir, n);
            double coef = C->alpha[slot] - b;
            for (size_t i = 0; i < n; ++i) {
                C->dir[i] += (float)(coef * s[i]);
            }
        }
    }
    memcpy(C->m, acc, n * sizeof(float));
    memcpy(C->v, g, n * sizeof(float));
    for (size_t i = 0; i < n; ++i) {
        acc[i] += (float)(step * C->dir[i]);
    }
}

void fnopt__classic_update(fnopt_classic *C, const float *g, float *acc)
{
    const size_t n = C->n3;
    switch (C->kind) {
    case WEFT_FNOPT_GD:
        for (size_t i = 0; i < n; ++i) {
            acc[i] -= C->lr * g[i];
        }
        break;
    case WEFT_FNOPT_ADAM: {
        /* Kingma & Ba with bias correction */
        const float b1 = C->beta1, b2 = C->beta2;
        const double t = (double)C->t + 1.0;
        const float c1 = (float)(1.0 / (1.0 - pow(b1, t))), c2 = (float)(1.0 / (1.0 - pow(b2, t)));
        for (size_t i = 0; i < n; ++i) {
            C->m[i] = b1 * C->m[i] + (1.0f - b1) * g[i];
            C->v[i] = b2 * C->v[i] + (1.0f - b2) * g[i] * g[i];
            acc[i] -= C->lr * (C->m[i] * c1) / (sqrtf(C->v[i] * c2) + 1e-8f);
        }
        break;
    }
    case WEFT_FNOPT_LBFGS:
        lbfgs(C, g, acc);
        break;
    default:
        break;
    }
    C->t++;
}
