/* FNOpt evaluation scenes shared by `weft fnopt` (tools/weft/cmd_fnopt.c, which implements
 * them) and `weft bench fnopt`: a square cloth hanging from handles that follow translation or
 * rotation trajectories, the XPBD ground truth, and the e3D / Chamfer metrics. */
#ifndef WEFT_FNOPT_SCENE_H
#define WEFT_FNOPT_SCENE_H

#include "weft.h"
#include "weft/fnopt.h"

typedef struct fnopt_scene_opts {
    uint32_t res;                /* grid res x res */
    float size_m;                /* side of the square cloth (1 m) */
    float fps;                   /* frames per second = FNOpt steps per second (60) */
    float speed;                 /* trajectory speed factor (1) */
    float amplitude_m;           /* translation per move (0.5 m); rotations turn 60 degrees */
    const char *motion;          /* xy, yz, xz, xyz, xyz3, xyz4, rot_h0, rot_h1 (+ "_opp") */
    const char *handles;         /* corners, diagonal, middle, corner-middle, corner-center,
                                    single-corner, single-middle, single-center */
    uint32_t frames;             /* 0: the whole trajectory */
} fnopt_scene_opts;

typedef struct fnopt_scene {
    fnopt_scene_opts o;
    uint32_t n, frames, handle_count;
    uint32_t handles[2];
    float *rest;                 /* n*3 world metres, Y up, centred on the initial cloth */
    float *traj;                 /* (frames + 1) * handle_count * 3, world metres */
    uint32_t *tris;              /* 2 (res-1)^2 triangles */
    uint32_t tri_count;
} fnopt_scene;

typedef struct fnopt_run_opts {
    weft_fnopt_optimizer optimizer;
    const weft_model *model;
    uint32_t iterations;
    float learning_rate;
    float Y, S, B;
    float repulsion;
    bool report_loss;            /* one extra loss evaluation per step (not in ms_per_frame) */
    weft_precision precision;    /* the learned optimizer's FNO arithmetic (FP32) */
    bool no_guard;               /* turn weft_fnopt_def.descent_guard off (the paper's rule) */
    float max_step;              /* weft_fnopt_def.max_step (0: off) */
} fnopt_run_opts;

typedef struct fnopt_run_result {
    uint32_t frames;             /* frames stepped */
    bool diverged;               /* a step failed or the cloth left a 100 m box */
    double ms_per_frame;         /* mean weft_fnopt_step wall time */
    double e3d;                  /* mean over frames (needs ground truth) */
    double chamfer;              /* mean over frames, m^2 (needs ground truth) */
    double loss;                 /* mean final loss per step (report_loss, else 0) */
    double max_strain;           /* largest |length - rest| / rest of a grid edge over all frames */
    double guard_acted;          /* share of steps where the descent guard committed an earlier iterate */
} fnopt_run_result;

weft_result fnopt_scene_make(const fnopt_scene_opts *o, fnopt_scene *s);
void fnopt_scene_free(fnopt_scene *s);
/* XPBD ground truth, frames * n * 3 floats (world), cached under data/fnopt/gt/. */
weft_result fnopt_scene_ground_truth(weft_context *ctx, const fnopt_scene *s, float **out);
/* "fp32", "fp16" or "int8"; false for anything else. */
bool fnopt_parse_precision(const char *s, weft_precision *out);
/* Runs FNOpt on the scene; gt may be NULL (timing only). positions_out (frames*n*3, world) may
 * be NULL. */
weft_result fnopt_scene_run(weft_context *ctx, const fnopt_scene *s, const fnopt_run_opts *r, const float *gt,
                            fnopt_run_result *out, float *positions_out);

#endif
