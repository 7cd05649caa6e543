/*
 * weft/fnopt.h — grid cloth stepped by the FNOpt learned optimizer (or a classical one).
 *
 * A rectangular H x W sheet (capes, flags, banners, curtains) whose time step is the minimum of
 * a backward-Euler incremental potential over the per-vertex acceleration a:
 *
 *   L(a) = E_stretch + E_shear + E_bend (at x + v + a) + 1/(2N) sum M a^2 - 1/N sum M a.g (+ k M_rep)
 *
 * Each step runs K inner iterations (default 10) of an optimizer on dL/da, then
 * v <- v + a, x <- x + v, handles <- targets. The learned optimizer is a Fourier neural operator
 * trained only on this loss (tools/fnopt/train.py); GD, Adam and L-BFGS run on the same loss
 * for comparison. docs/FNOPT.md has the formulation, the measurements and the commands.
 *
 * Units: GRID UNITS. The rest edge length is 1 and one step is dt = 1. For a square cloth of
 * side s metres sampled at res x res, one metre is Lc = (res-1)/s units; with T steps per
 * second, an acceleration of g m/s^2 is g*Lc/T^2 units/step^2 (weft_fnopt_acceleration()).
 * Vertex (i, j), i in [0, H), j in [0, W), has index i*W + j; positions are xyz triplets.
 *
 * Typical use:
 *
 *   weft_fnopt_def def = weft_default_fnopt_def();
 *   def.height = def.width = 32;
 *   def.model = model;                          // weft_model_load_file(..., "fnopt_32.safetensors")
 *   weft_fnopt *cloth;
 *   weft_fnopt_create(ctx, &def, &cloth);
 *   uint32_t handles[2] = {0, 31 * 32};
 *   every frame:
 *     weft_fnopt_set_handles(cloth, handles, targets_for_this_frame, 2);
 *     weft_fnopt_step(cloth);
 *     draw(weft_fnopt_positions(cloth));
 *
 * Memory: every buffer is sized in weft_fnopt_create(); set_handles and step allocate nothing.
 * Threads: one object per thread at a time. Errors: weft_result, state untouched on failure.
 */
#ifndef WEFT_FNOPT_H
#define WEFT_FNOPT_H

#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct weft_fnopt weft_fnopt;

typedef enum weft_fnopt_optimizer {
    WEFT_FNOPT_LEARNED = 0,   /* the FNO learned optimizer (needs def.model, architecture "fnopt") */
    WEFT_FNOPT_GD,            /* a <- a - lr * g */
    WEFT_FNOPT_ADAM,          /* Adam with lr, beta1, beta2; moments restart every step */
    WEFT_FNOPT_LBFGS,         /* L-BFGS two-loop recursion, fixed step lr, no line search;
                                 history restarts every step */
    WEFT_FNOPT_OPTIMIZER_COUNT
} weft_fnopt_optimizer;

typedef struct weft_fnopt_def {
    uint32_t height, width;             /* grid size, each >= 10 */
    /* Initial state, height*width*3 each, grid units. NULL positions: a flat sheet hanging
     * in the x-z plane, p(i,j) = (i - (H-1)/2, 0, -j), so row j = 0 is the top edge.
     * NULL velocities: at rest. Copied. */
    const float *initial_positions;
    const float *initial_velocities;

    /* Material in grid units (the paper's inference values): stretch Y 1000, shear S 8,
     * bend B 0.5. All >= 0 and finite. */
    float stretch, shear, bend;
    /* External acceleration, grid units per step^2. Default (0, 0, -0.121): 9.76 m/s^2 down -z
     * for a 1 m cloth at 32 x 32 and 50 steps/s, the paper's setting. */
    float gravity[3];
    /* Repulsion (self-collision barrier on a 32 x 32 resampling of the cloth): weight k and
     * distance threshold in grid units. k = 0 (default) turns it off. */
    float repulsion;
    float repulsion_threshold;          /* default 0.5 */

    weft_fnopt_optimizer optimizer;     /* default WEFT_FNOPT_LEARNED */
    const weft_model *model;            /* LEARNED: an "fnopt" model; must outlive the object */
    uint32_t iterations;                /* inner iterations per step, K >= 1 (default 10) */
    float learning_rate;                /* GD/Adam/L-BFGS step size (default 0.01; L-BFGS is
                                           usually best near 1, docs/FNOPT.md has a sweep) */
    float adam_beta1, adam_beta2;       /* default 0.9, 0.999 */
    uint32_t lbfgs_history;             /* L-BFGS pairs kept, >= 1 (default 10) */
    /* Evaluate the loss once more after the last iteration so weft_fnopt_stats.loss_final is
     * filled (costs one extra gradient evaluation per step). Default false. */
    bool report_loss;
    /* Descent guard (default true): the step commits the iterate with the lowest loss among
     * a = 0 and the K optimizer iterates, instead of always the last one. The iterations
     * themselves are not changed (the learned optimizer climbs on purpose within a step, then
     * descends); the guard costs one loss evaluation without gradient per step. So a committed
     * acceleration never has a higher loss than a = 0, which keeps rollouts stable where the
     * optimizer alone ends a step on an overshoot (finer grids, faster handles, reduced
     * precision; docs/FNOPT.md). false commits the last iterate: the paper's rule (the PyTorch
     * parity goldens). */
    bool descent_guard;
    /* LEARNED: trust region, grid units (default 0.5, half a rest edge). The learned optimizer's
     * step is tanh(u) * scale with a scale it grows or shrinks by up to e^1 / e^-3 an iteration
     * and carries across steps; max_step caps that scale, so no iteration moves a vertex's
     * acceleration by more than max_step. Where the scale runs away (finer grids than the
     * training's, where gravity and handle speeds are larger in grid units) the cap keeps the
     * rollout on the converged solution; where it does not bind the result is unchanged.
     * 0 turns it off (the paper's rule). docs/FNOPT.md has the measurements. */
    float max_step;
    /* LEARNED: arithmetic of the FNO's 1x1 layers, converted from the fp32 model at creation.
     * FP16: fp16 weights, fp32 accumulation. INT8: int8 weights and per-row int8 activations in
     * the wide layers (lifting 256 -> 64, skips, projection 64 -> 64), int32 accumulation. Both run
     * on the deterministic kernels with the tanh form of GELU fused in, so a step gives the
     * same bits on every ISA. The spectral convolution and the loss stay fp32/double. Default
     * FP32. docs/FNOPT.md has the accuracy bound and the speed of each (on an AVX-512 CPU fp32
     * is the fastest; int8 is faster at the AVX2 level). */
    weft_precision precision;
    uint32_t internal_cookie;           /* set by weft_default_fnopt_def(); do not touch */
} weft_fnopt_def;

typedef struct weft_fnopt_stats {
    uint64_t frame;                     /* steps since creation or the last set_state */
    double step_ms;                     /* wall time of the last step (without report_loss) */
    double loss_first;                  /* L at a = 0 in the last step */
    double loss_final;                  /* L at the final a (only with def.report_loss) */
    double grad_norm_final;             /* |dL/da| at the final a (only with def.report_loss) */
    /* The iterate the last step committed: K = the optimizer's last; below K the descent
     * guard chose an earlier one with a lower loss (0: a = 0). */
    uint32_t committed_iterate;
} weft_fnopt_stats;

WEFT_API weft_fnopt_def weft_default_fnopt_def(void);

/* Validates the def (sizes, finite material and state, model architecture and tensor shapes)
 * and sizes every buffer. */
WEFT_API weft_result weft_fnopt_create(weft_context *context, const weft_fnopt_def *def, weft_fnopt **out);
WEFT_API void weft_fnopt_destroy(weft_fnopt *cloth);

/* Replaces positions and velocities (velocities may be NULL: at rest) and restarts the
 * optimizer's recurrent state. */
WEFT_API weft_result weft_fnopt_set_state(weft_fnopt *cloth, const float *positions, const float *velocities);

/* Handles: vertices whose positions at the end of the next step are given (count*3 floats).
 * They stay in force until the next call; count 0 releases all. A handle's velocity after the
 * step is its displacement over the step. Indices must be distinct and < H*W. */
WEFT_API weft_result weft_fnopt_set_handles(weft_fnopt *cloth, const uint32_t *indices, const float *targets,
                                            uint32_t count);

/* Material and gravity can change between steps (material fitting, wind gusts). */
WEFT_API weft_result weft_fnopt_set_material(weft_fnopt *cloth, float stretch, float shear, float bend);
WEFT_API weft_result weft_fnopt_set_gravity(weft_fnopt *cloth, const float gravity[3]);

/* One time step: K optimizer iterations, then the state update. Fails with
 * WEFT_ERROR_NOT_FINITE (state unchanged) if the solve produced NaN or infinity. */
WEFT_API weft_result weft_fnopt_step(weft_fnopt *cloth);

/* Positions / velocities, height*width*3 floats in grid units, valid until the next step,
 * set_state or destroy. */
WEFT_API const float *weft_fnopt_positions(const weft_fnopt *cloth);
WEFT_API const float *weft_fnopt_velocities(const weft_fnopt *cloth);
WEFT_API weft_fnopt_stats weft_fnopt_get_stats(const weft_fnopt *cloth);

/* The loss of the next step at acceleration `acc` (H*W*3, NULL = 0) with the current state,
 * handles, material and gravity, and optionally its gradient dL/da (H*W*3). For tools and
 * tests; the state and the optimizer are not changed. */
WEFT_API weft_result weft_fnopt_loss(weft_fnopt *cloth, const float *acc, double *out_loss, float *out_grad);

/* Unit conversion: grid units per step^2 for an acceleration in m/s^2, a res-vertex edge
 * spanning size_m metres, and steps_per_second steps per second. */
WEFT_API float weft_fnopt_acceleration(float accel_m_s2, uint32_t res, float size_m, float steps_per_second);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_FNOPT_H */
