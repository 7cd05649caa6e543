/* weft bench fnopt: ms per frame of FNOpt's learned optimizer and of the classical baselines on
 * the handle scene (xy translation, corner handles), at several resolutions and iteration
 * counts. CSV on stdout; docs/FNOPT.md records the figures. */
#include "../fnopt/fnopt_scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Next number of a comma-separated list; false at the end. */
static bool next_u32(const char **p, uint32_t *out)
{
    while (**p == ',') {
        (*p)++;
    }
    if (!**p) {
        return false;
    }
    char *end = NULL;
    *out = (uint32_t)strtoul(*p, &end, 10);
    *p = end && end != *p ? end : *p + strlen(*p);
    return true;
}

const char weft_bench_fnopt_help[] = "FNOpt ms/frame: learned optimizer vs GD/Adam/L-BFGS at 32/64/100";

int weft_bench_fnopt(int argc, char **argv)
{
    const char *model_path = "tools/fnopt/models/fnopt_32.safetensors";
    uint32_t frames = 20;
    const char *res_list = "32,64,100";
    const char *iters_list = "10";
    bool classical = true;
    for (int i = 1; i < argc; ++i) {
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(argv[i], "--model") == 0 && v) {
            model_path = v, ++i;
        } else if (strcmp(argv[i], "--frames") == 0 && v) {
            frames = (uint32_t)atoi(v), ++i;
        } else if (strcmp(argv[i], "--res") == 0 && v) {
            res_list = v, ++i;
        } else if (strcmp(argv[i], "--iters") == 0 && v) {
            iters_list = v, ++i;
        } else if (strcmp(argv[i], "--learned-only") == 0) {
            classical = false;
        } else {
            printf("usage: weft bench fnopt [--res 32,64,100] [--iters 10,100] [--frames 20] [--model PATH]"
                   " [--learned-only]\n");
            return strcmp(argv[i], "--help") == 0 ? 0 : 2;
        }
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_model *model = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK || weft_model_load_file(ctx, model_path, &model) != WEFT_OK) {
        fprintf(stderr, "weft bench fnopt: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    printf("# %s\n", weft_config_string());
    /* wall time is what a game sees; process CPU time is also printed because a shared machine
     * inflates wall time */
    printf("res,optimizer,iters,frames,ms_per_frame,cpu_ms_per_frame,ms_per_iteration\n");
    const char *rp = res_list;
    uint32_t res = 0;
    while (next_u32(&rp, &res)) {
        fnopt_scene_opts so = {.res = res, .size_m = 1.0f, .fps = 60.0f, .speed = 1.0f,
                               .amplitude_m = 0.5f, .motion = "xy", .handles = "corners", .frames = frames};
        fnopt_scene s;
        if (fnopt_scene_make(&so, &s) != WEFT_OK) {
            continue;
        }
        const char *ip = iters_list;
        uint32_t iters = 0;
        while (next_u32(&ip, &iters)) {
            const weft_fnopt_optimizer kinds[4] = {WEFT_FNOPT_LEARNED, WEFT_FNOPT_GD, WEFT_FNOPT_ADAM, WEFT_FNOPT_LBFGS};
            const char *names[4] = {"learned", "gd", "adam", "lbfgs"};
            for (int k = 0; k < (classical ? 4 : 1); ++k) {
                fnopt_run_opts ro = {.optimizer = kinds[k], .model = model, .iterations = iters,
                                     .learning_rate = kinds[k] == WEFT_FNOPT_LBFGS ? 1.0f : 0.01f,
                                     .Y = 1000.0f, .S = 8.0f, .B = 0.5f};
                fnopt_run_result r;
                clock_t c0 = clock();
                if (fnopt_scene_run(ctx, &s, &ro, NULL, &r, NULL) == WEFT_OK) {
                    double cpu = 1e3 * (double)(clock() - c0) / CLOCKS_PER_SEC / (r.frames ? r.frames : 1);
                    printf("%u,%s,%u,%u,%.3f,%.3f,%.4f\n", so.res, names[k], iters, r.frames, r.ms_per_frame, cpu,
                           r.ms_per_frame / iters);
                    fflush(stdout);
                }
            }
        }
        fnopt_scene_free(&s);
    }
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    return 0;
}
