/* weft_fnopt: the grid cloth object. A step minimises the backward-Euler potential over the
 * acceleration with K optimizer iterations, then commits v += a, x += v and the handles. The
 * new state is built in scratch buffers and swapped in only when it is finite. */
#include "fnopt/fnopt_internal.h"

#include <math.h>
#include <string.h>

struct weft_fnopt {
    weft_context *ctx;
    uint32_t h, w, n;
    weft_fnopt_optimizer optimizer;
    uint32_t iterations;
    bool report_loss;
    bool descent_guard;

    float *x, *v, *x_new, *v_new;       /* 3n each */
    float *acc, *grad;                  /* 3n each */
    uint8_t *mask, *seen;               /* n each */
    float *bc;                          /* 3n: handle targets */
    uint32_t *handles;                  /* n: current handle indices */
    uint32_t handle_count;

    fnopt_loss loss;
    fnopt_loss_input in;

    fnopt_learned learned;
    float *backup;                      /* 6n: g_prev and s_prev before the step */
    float *best;                        /* 3n: the step's lowest-loss acceleration (descent guard) */
    fnopt_classic classic;

    weft_fnopt_stats stats;
};

weft_fnopt_def weft_default_fnopt_def(void)
{
    weft_fnopt_def d = {0};
    d.height = 32;
    d.width = 32;
    d.stretch = 1000.0f;
    d.shear = 8.0f;
    d.bend = 0.5f;
    d.gravity[2] = -9.76f * 31.0f / (50.0f * 50.0f);
    d.repulsion = 0.0f;
    d.repulsion_threshold = 0.5f;
    d.optimizer = WEFT_FNOPT_LEARNED;
    d.iterations = 10;
    d.learning_rate = 0.01f;
    d.adam_beta1 = 0.9f;
    d.adam_beta2 = 0.999f;
    d.lbfgs_history = 10;
    d.descent_guard = true;
    d.max_step = 0.5f;
    d.internal_cookie = WEFT_DEF_COOKIE;
    return d;
}

float weft_fnopt_acceleration(float accel_m_s2, uint32_t res, float size_m, float steps_per_second)
{
    if (res < 2 || !(size_m > 0.0f) || !(steps_per_second > 0.0f)) {
        return 0.0f;
    }
    return accel_m_s2 * ((float)(res - 1) / size_m) / (steps_per_second * steps_per_second);
}

static bool finite3(const float *g) { return isfinite(g[0]) && isfinite(g[1]) && isfinite(g[2]); }

static weft_result check_material(const char *fn, float Y, float S, float B)
{
    if (!(isfinite(Y) && Y >= 0.0f) || !(isfinite(S) && S >= 0.0f) || !(isfinite(B) && B >= 0.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: stretch/shear/bend (%g, %g, %g) must be finite and >= 0",
                          fn, (double)Y, (double)S, (double)B);
    }
    return WEFT_OK;
}

void weft_fnopt_destroy(weft_fnopt *f)
{
    if (!f) {
        return;
    }
    weft_context *ctx = f->ctx;
    size_t n = f->n;
    weft__free(ctx, f->x, 3 * n * sizeof(float));
    weft__free(ctx, f->v, 3 * n * sizeof(float));
    weft__free(ctx, f->x_new, 3 * n * sizeof(float));
    weft__free(ctx, f->v_new, 3 * n * sizeof(float));
    weft__free(ctx, f->acc, 3 * n * sizeof(float));
    weft__free(ctx, f->grad, 3 * n * sizeof(float));
    weft__free(ctx, f->bc, 3 * n * sizeof(float));
    weft__free(ctx, f->mask, n);
    weft__free(ctx, f->seen, n);
    weft__free(ctx, f->handles, n * sizeof(uint32_t));
    weft__free(ctx, f->backup, 6 * n * sizeof(float));
    weft__free(ctx, f->best, 3 * n * sizeof(float));
    if (f->loss.mass) {
        fnopt__loss_free(ctx, &f->loss);
    }
    if (f->learned.g_prev) {
        fnopt__learned_free(ctx, &f->learned);
    }
    fnopt__classic_free(ctx, &f->classic);
    weft__free(ctx, f, sizeof *f);
}

weft_result weft_fnopt_create(weft_context *ctx, const weft_fnopt_def *def, weft_fnopt **out)
{
    static const char fn[] = "weft_fnopt_create";
    if (!ctx || !def || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: context, def and out must not be NULL", fn);
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: def was not initialised with weft_default_fnopt_def()", fn);
    }
    if (def->height < 10 || def->width < 10 || def->height > 4096 || def->width > 4096) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: height and width must be in [10, 4096] (got %ux%u)", fn,
                          def->height, def->width);
    }
    weft_result r = check_material(fn, def->stretch, def->shear, def->bend);
    if (r != WEFT_OK) {
        return r;
    }
    if (!finite3(def->gravity)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: gravity is not finite", fn);
    }
    if (!(isfinite(def->repulsion) && def->repulsion >= 0.0f) ||
        !(isfinite(def->repulsion_threshold) && def->repulsion_threshold > 0.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: repulsion must be >= 0 and repulsion_threshold > 0", fn);
    }
    if ((unsigned)def->optimizer >= WEFT_FNOPT_OPTIMIZER_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: optimizer %d out of range", fn, (int)def->optimizer);
    }
    if ((unsigned)def->precision >= WEFT_PRECISION_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: precision %d out of range", fn, (int)def->precision);
    }
    if (def->iterations < 1 || def->iterations > 100000) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: iterations must be in [1, 100000] (got %u)", fn,
                          def->iterations);
    }
    if (!(isfinite(def->max_step) && def->max_step >= 0.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: max_step must be finite and >= 0", fn);
    }
    if (def->optimizer != WEFT_FNOPT_LEARNED) {
        if (!(isfinite(def->learning_rate) && def->learning_rate > 0.0f)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: learning_rate must be finite and > 0", fn);
        }
        if (!(def->adam_beta1 >= 0.0f && def->adam_beta1 < 1.0f && def->adam_beta2 >= 0.0f && def->adam_beta2 < 1.0f)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: adam_beta1/adam_beta2 must be in [0, 1)", fn);
        }
        if (def->optimizer == WEFT_FNOPT_LBFGS && (def->lbfgs_history < 1 || def->lbfgs_history > 1000)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: lbfgs_history must be in [1, 1000]", fn);
        }
    }
    const size_t n = (size_t)def->height * def->width;
    if (def->initial_positions && !weft__all_finite(def->initial_positions, 3 * n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: initial_positions holds NaN or infinity", fn);
    }
    if (def->initial_velocities && !weft__all_finite(def->initial_velocities, 3 * n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: initial_velocities holds NaN or infinity", fn);
    }
    fnopt_weights wt;
    if (def->optimizer == WEFT_FNOPT_LEARNED) {
        if (!def->model) {
            return weft__fail(WEFT_ERROR_NO_MODEL, "%s: the learned optimizer needs def.model (an 'fnopt' model)", fn);
        }
        r = fnopt__weights_from_model(def->model, &wt);
        if (r != WEFT_OK) {
            return r;
        }
    }

    weft_fnopt *f = weft__alloc(ctx, sizeof *f);
    if (!f) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "%s: out of memory", fn);
    }
    f->ctx = ctx;
    f->h = def->height;
    f->w = def->width;
    f->n = (uint32_t)n;
    f->optimizer = def->optimizer;
    f->iterations = def->iterations;
    f->report_loss = def->report_loss;
    f->descent_guard = def->descent_guard;
    f->x = weft__alloc(ctx, 3 * n * sizeof(float));
    f->v = weft__alloc(ctx, 3 * n * sizeof(float));
    f->x_new = weft__alloc(ctx, 3 * n * sizeof(float));
    f->v_new = weft__alloc(ctx, 3 * n * sizeof(float));
    f->acc = weft__alloc(ctx, 3 * n * sizeof(float));
    f->grad = weft__alloc(ctx, 3 * n * sizeof(float));
    f->bc = weft__alloc(ctx, 3 * n * sizeof(float));
    f->mask = weft__alloc(ctx, n);
    f->seen = weft__alloc(ctx, n);
    f->handles = weft__alloc(ctx, n * sizeof(uint32_t));
    f->backup = weft__alloc(ctx, 6 * n * sizeof(float));
    f->best = weft__alloc(ctx, 3 * n * sizeof(float));
    if (!f->x || !f->v || !f->x_new || !f->v_new || !f->acc || !f->grad || !f->bc || !f->mask || !f->seen ||
        !f->handles || !f->backup || !f->best) {
        weft_fnopt_destroy(f);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "%s: out of memory for the %ux%u state", fn, f->h, f->w);
    }
    r = fnopt__loss_init(ctx, &f->loss, f->h, f->w);
    if (r == WEFT_OK && def->optimizer == WEFT_FNOPT_LEARNED) {
        r = fnopt__learned_init(ctx, &f->learned, &wt, f->h, f->w, def->precision);
        f->learned.max_scale = def->max_step;
    }
    if (r == WEFT_OK && def->optimizer != WEFT_FNOPT_LEARNED) {
        r = fnopt__classic_init(ctx, &f->classic, def->optimizer, 3 * f->n, def->lbfgs_history, def->learning_rate,
                                def->adam_beta1, def->adam_beta2);
    }
    if (r != WEFT_OK) {
        weft_fnopt_destroy(f);
        return r;
    }
    if (def->initial_positions) {
        memcpy(f->x, def->initial_positions, 3 * n * sizeof(float));
    } else {
        for (uint32_t i = 0; i < f->h; ++i) {
            for (uint32_t j = 0; j < f->w; ++j) {
                float *p = f->x + 3 * ((size_t)i * f->w + j);
                p[0] = (float)i - 0.5f * (float)(f->h - 1);
                p[1] = 0.0f;
                p[2] = -(float)j;
            }
        }
    }
    if (def->initial_velocities) {
        memcpy(f->v, def->initial_velocities, 3 * n * sizeof(float));
    }
    f->in = (fnopt_loss_input){
        .x = f->x, .v = f->v, .mask = f->mask, .bc = f->bc,
        .Y = def->stretch, .S = def->shear, .B = def->bend,
        .gravity = {def->gravity[0], def->gravity[1], def->gravity[2]},
        .k_rep = def->repulsion, .rep_thres = def->repulsion_threshold,
    };
    *out = f;
    return WEFT_OK;
}

weft_result weft_fnopt_set_state(weft_fnopt *f, const float *positions, const float *velocities)
{
    if (!f || !positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_set_state: cloth and positions must not be NULL");
    }
    size_t n3 = 3 * (size_t)f->n;
    if (!weft__all_finite(positions, n3) || (velocities && !weft__all_finite(velocities, n3))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_fnopt_set_state: positions or velocities hold NaN or infinity");
    }
    memcpy(f->x, positions, n3 * sizeof(float));
    if (velocities) {
        memcpy(f->v, velocities, n3 * sizeof(float));
    } else {
        memset(f->v, 0, n3 * sizeof(float));
    }
    if (f->optimizer == WEFT_FNOPT_LEARNED) {
        fnopt__learned_reset(&f->learned);
    }
    f->stats = (weft_fnopt_stats){0};
    return WEFT_OK;
}

weft_result weft_fnopt_set_handles(weft_fnopt *f, const uint32_t *indices, const float *targets, uint32_t count)
{
    static const char fn[] = "weft_fnopt_set_handles";
    if (!f || (count > 0 && (!indices || !targets))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: cloth, indices and targets must not be NULL", fn);
    }
    if (count > f->n) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "%s: %u handles for %u vertices", fn, count, f->n);
    }
    if (count > 0 && !weft__all_finite(targets, 3 * (size_t)count)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "%s: targets hold NaN or infinity", fn);
    }
    /* validate everything before touching the object: range, then duplicates */
    weft_result r = WEFT_OK;
    uint32_t marked = 0;
    for (; marked < count; ++marked) {
        uint32_t id = indices[marked];
        if (id >= f->n) {
            r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: indices[%u] = %u is not below %u", fn, marked, id, f->n);
            break;
        }
        if (f->seen[id]) {
            r = weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: vertex %u appears twice", fn, id);
            break;
        }
        f->seen[id] = 1;
    }
    for (uint32_t k = 0; k < marked; ++k) {
        f->seen[indices[k]] = 0;
    }
    if (r != WEFT_OK) {
        return r;
    }
    for (uint32_t k = 0; k < f->handle_count; ++k) {
        f->mask[f->handles[k]] = 0;
    }
    for (uint32_t k = 0; k < count; ++k) {
        uint32_t id = indices[k];
        f->handles[k] = id;
        f->mask[id] = 1;
        memcpy(f->bc + 3 * (size_t)id, targets + 3 * (size_t)k, 3 * sizeof(float));
    }
    f->handle_count = count;
    return WEFT_OK;
}

weft_result weft_fnopt_set_material(weft_fnopt *f, float stretch, float shear, float bend)
{
    if (!f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_set_material: cloth must not be NULL");
    }
    weft_result r = check_material("weft_fnopt_set_material", stretch, shear, bend);
    if (r == WEFT_OK) {
        f->in.Y = stretch;
        f->in.S = shear;
        f->in.B = bend;
    }
    return r;
}

weft_result weft_fnopt_set_gravity(weft_fnopt *f, const float gravity[3])
{
    if (!f || !gravity) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_set_gravity: cloth and gravity must not be NULL");
    }
    if (!finite3(gravity)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_fnopt_set_gravity: gravity is not finite");
    }
    memcpy(f->in.gravity, gravity, 3 * sizeof(float));
    return WEFT_OK;
}

weft_result weft_fnopt_loss(weft_fnopt *f, const float *acc, double *out_loss, float *out_grad)
{
    if (!f || !out_loss) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_loss: cloth and out_loss must not be NULL");
    }
    if (acc && !weft__all_finite(acc, 3 * (size_t)f->n)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_fnopt_loss: acc holds NaN or infinity");
    }
    *out_loss = fnopt__loss_eval(&f->loss, &f->in, acc, out_grad);
    return WEFT_OK;
}

weft_result weft_fnopt_step(weft_fnopt *f)
{
    if (!f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_fnopt_step: cloth must not be NULL");
    }
    const double t0 = weft__now_ms();
    const size_t n = f->n, n3 = 3 * n;
    memset(f->acc, 0, n3 * sizeof(float));
    float saved_scale[3] = {0};
    if (f->optimizer == WEFT_FNOPT_LEARNED) {
        /* the recurrent state persists across steps; keep it so a failed step can be undone */
        memcpy(f->backup, f->learned.g_prev, n3 * sizeof(float));
        memcpy(f->backup + n3, f->learned.s_prev, n3 * sizeof(float));
        memcpy(saved_scale, f->learned.scale, sizeof saved_scale);
    } else {
        fnopt__classic_reset(&f->classic);
    }
    /* the descent guard remembers the lowest-loss iterate (a = 0 is iterate 0) */
    double first = 0.0, lowest = INFINITY;
    uint32_t committed = f->iterations;
    for (uint32_t k = 0; k < f->iterations; ++k) {
        double l = fnopt__loss_eval(&f->loss, &f->in, f->acc, f->grad);
        if (k == 0) {
            first = l;
        }
        if (f->descent_guard && l < lowest) {
            lowest = l;
            committed = k;
            memcpy(f->best, f->acc, n3 * sizeof(float));
        }
        if (f->optimizer == WEFT_FNOPT_LEARNED) {
            fnopt__learned_update(&f->learned, f->grad, f->acc);
        } else {
            fnopt__classic_update(&f->classic, f->grad, f->acc);
        }
    }
    if (f->descent_guard) {
        /* the last iterate costs one more loss value, without its gradient; it is committed
         * unless an earlier iterate (or a = 0) had a lower loss or it is not finite */
        double l = fnopt__loss_eval(&f->loss, &f->in, f->acc, NULL);
        if (l <= lowest || !(lowest < INFINITY)) {
            committed = f->iterations;
        } else {
            /* the optimizer's recurrent state stays where its iterations took it: restoring
             * the state of the committed iterate measured worse (docs/FNOPT.md) */
            memcpy(f->acc, f->best, n3 * sizeof(float));
        }
    }
    double final_loss = 0.0, gnorm = 0.0;
    double t_report = weft__now_ms();
    if (f->report_loss) {
        final_loss = fnopt__loss_eval(&f->loss, &f->in, f->acc, f->grad);
        for (size_t q = 0; q < n3; ++q) {
            gnorm += (double)f->grad[q] * f->grad[q];
        }
        gnorm = sqrt(gnorm);
    }
    t_report = weft__now_ms() - t_report; /* diagnostics are not part of the step's cost */
    for (size_t q = 0; q < n3; ++q) {
        f->v_new[q] = f->v[q] + f->acc[q];
        f->x_new[q] = f->x[q] + f->v_new[q];
    }
    for (uint32_t k = 0; k < f->handle_count; ++k) {
        size_t id = f->handles[k];
        for (int c = 0; c < 3; ++c) {
            f->v_new[3 * id + c] = f->bc[3 * id + c] - f->x[3 * id + c];
            f->x_new[3 * id + c] = f->bc[3 * id + c];
        }
    }
    if (!weft__all_finite(f->x_new, n3) || !weft__all_finite(f->v_new, n3)) {
        if (f->optimizer == WEFT_FNOPT_LEARNED) {
            memcpy(f->learned.g_prev, f->backup, n3 * sizeof(float));
            memcpy(f->learned.s_prev, f->backup + n3, n3 * sizeof(float));
            memcpy(f->learned.scale, saved_scale, sizeof saved_scale);
        }
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_fnopt_step: the solve produced NaN or infinity at frame %llu",
                          (unsigned long long)f->stats.frame);
    }
    float *t = f->x;
    f->x = f->x_new;
    f->x_new = t;
    t = f->v;
    f->v = f->v_new;
    f->v_new = t;
    f->in.x = f->x;
    f->in.v = f->v;
    f->stats.frame++;
    f->stats.loss_first = first;
    f->stats.loss_final = final_loss;
    f->stats.grad_norm_final = gnorm;
    f->stats.committed_iterate = committed;
    f->stats.step_ms = weft__now_ms() - t0 - t_report;
    return WEFT_OK;
}

const float *weft_fnopt_positions(const weft_fnopt *f) { return f ? f->x : NULL; }
const float *weft_fnopt_velocities(const weft_fnopt *f) { return f ? f->v : NULL; }
weft_fnopt_stats weft_fnopt_get_stats(const weft_fnopt *f)
{
    weft_fnopt_stats s = {0};
    return f ? f->stats : s;
}

const fnopt_learned *fnopt__learned_state(const weft_fnopt *f)
{
    return f && f->optimizer == WEFT_FNOPT_LEARNED ? &f->learned : NULL;
}
