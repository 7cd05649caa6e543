/* weft bench fnopt: ms per frame of FNOpt's learned optimizer (at fp32, fp16 and int8) and of
 * the classical baselines on the handle scene (xy translation, corner handles), at several
 * resolutions and iteration counts, with the e3D of each run against the fp32 learned run and,
 * with --gt, against the XPBD reference. CSV on stdout; docs/FNOPT.md records the figures. */
#include "../fnopt/fnopt_scene.h"
#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* e3D (docs/FNOPT.md) of `frames` frames of positions against a reference trajectory, both in
 * world metres with the origin at the cloth's initial centre; NaN without frames. */
static double traj_e3d(const float *pos, const float *ref, uint32_t frames, size_t n3)
{
    double sum = 0.0;
    for (uint32_t f = 0; f < frames; ++f) {
        double num = 0.0, den = 0.0;
        for (size_t q = 0; q < n3; ++q) {
            double d = (double)pos[(size_t)f * n3 + q] - ref[(size_t)f * n3 + q];
            num += d * d;
            den += (double)ref[(size_t)f * n3 + q] * ref[(size_t)f * n3 + q];
        }
        sum += sqrt(num) / sqrt(den > 0 ? den : 1e-30);
    }
    return frames ? sum / frames : NAN;
}

const char weft_bench_fnopt_help[] =
    "FNOpt ms/frame and e3D: learned optimizer (fp32/fp16/int8) vs GD/Adam/L-BFGS at 32/64/100";

enum { OPT_MODEL = 1, OPT_FRAMES, OPT_RES, OPT_ITERS, OPT_LEARNED_ONLY, OPT_PRECISION, OPT_GT, OPT_MATERIAL };

static const cli_option k_options[] = {
    {"res", "32,64,100", OPT_RES, "up to 16 grid resolutions, each 10..1024 (default 32,64,100)"},
    {"iters", "10,100", OPT_ITERS, "up to 16 inner iteration counts, each 1..10000 (default 10)"},
    {"frames", "N", OPT_FRAMES, "frames per run, 0..100000 (0: the whole trajectory; default 20)"},
    {"model", "PATH", OPT_MODEL, "the FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors)"},
    {"learned-only", NULL, OPT_LEARNED_ONLY, "skip the classical optimizers (GD, Adam, L-BFGS)"},
    {"precision", "fp32,fp16,int8", OPT_PRECISION, "the learned optimizer's precisions (default fp32)"},
    {"material", "Y,S,B", OPT_MATERIAL, "the energy coefficients, each 0..1e6 (default 1000,8,0.5)"},
    {"gt", NULL, OPT_GT, "also the e3D against the XPBD reference (cached under data/fnopt/gt/)"},
    {0},
};

static void notes(FILE *out)
{
    fprintf(out, "CSV columns:\n"
                 "  e3d_vs_fp32: against the fp32 learned run at the same res and iters (run first)\n"
                 "  e3d_xpbd:    against the XPBD reference (--gt; cached under data/fnopt/gt/)\n");
}

static const cli_command k_command = {
    .tool = "weft bench fnopt",
    .synopsis = "weft bench fnopt [--res 32,64,100] [--iters 10,100] [--frames 20] [--model PATH]\n"
                "                 [--learned-only] [--precision fp32,fp16,int8] [--material Y,S,B] [--gt]",
    .about = "FNOpt ms/frame and e3D: the learned optimizer (fp32/fp16/int8) against GD, Adam and L-BFGS on the\n"
             "handle scene. CSV on stdout.",
    .options = k_options,
    .notes = notes,
};

int weft_bench_fnopt(int argc, char **argv)
{
    const char *model_path = "tools/fnopt/models/fnopt_32.safetensors";
    uint32_t frames = 20;
    uint32_t res_list[16] = {32, 64, 100}, iters_list[16] = {10};
    size_t res_count = 3, iters_count = 1;
    bool classical = true, with_gt = false;
    const char *prec_list = "fp32";
    float Y = 1000.0f, S = 8.0f, B = 0.5f;
    cli_parser cp;
    cli_start(&cp, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cp, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return cp.exit;
        case OPT_MODEL:
            model_path = v;
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, a, v, 0, 100000, &frames)) {
                return 2;
            }
            break;
        case OPT_RES:
            if (!cli_u32_list(k_command.tool, a, v, 10, 1024, res_list, 16, &res_count)) {
                return 2;
            }
            break;
        case OPT_ITERS:
            if (!cli_u32_list(k_command.tool, a, v, 1, 10000, iters_list, 16, &iters_count)) {
                return 2;
            }
            break;
        case OPT_LEARNED_ONLY:
            classical = false;
            break;
        case OPT_PRECISION:
            prec_list = v;
            break;
        case OPT_GT:
            with_gt = true;
            break;
        case OPT_MATERIAL: {
            float m[3];
            if (!cli_floats(k_command.tool, a, v, 0.0f, 1e6f, m, 3)) {
                return 2;
            }
            Y = m[0], S = m[1], B = m[2];
            break;
        }
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&cp) != 0) {
        return 2;
    }
    weft_precision precs[WEFT_PRECISION_COUNT];
    uint32_t prec_count = 0;
    for (const char *p = prec_list; *p && prec_count < WEFT_PRECISION_COUNT;) {
        char name[8] = {0};
        size_t len = strcspn(p, ",");
        if (len >= sizeof name) {
            len = sizeof name - 1;
        }
        memcpy(name, p, len);
        if (!fnopt_parse_precision(name, &precs[prec_count])) {
            fprintf(stderr, "weft bench fnopt: unknown precision '%s' (fp32, fp16, int8)\n", name);
            return 2;
        }
        ++prec_count;
        p += strcspn(p, ",");
        p += *p == ',';
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_model *model = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK || weft_model_load_file_as(ctx, model_path, "fnopt", &model) != WEFT_OK) {
        fprintf(stderr, "weft bench fnopt: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    printf("# %s\n", weft_config_string());
    /* wall time is what a game sees; process CPU time is also printed because a shared machine
     * inflates wall time */
    printf("res,optimizer,precision,iters,frames,ms_per_frame,cpu_ms_per_frame,ms_per_iteration,e3d_vs_fp32,"
           "e3d_xpbd\n");
    static const char *prec_names[WEFT_PRECISION_COUNT] = {"fp32", "fp16", "int8"};
    for (size_t ri = 0; ri < res_count; ++ri) {
        const uint32_t res = res_list[ri];
        fnopt_scene_opts so = {.res = res, .size_m = 1.0f, .fps = 60.0f, .speed = 1.0f,
                               .amplitude_m = 0.5f, .motion = "xy", .handles = "corners", .frames = frames};
        fnopt_scene s;
        if (fnopt_scene_make(&so, &s) != WEFT_OK) {
            continue;
        }
        float *gt = NULL;
        if (with_gt && fnopt_scene_ground_truth(ctx, &s, &gt) != WEFT_OK) {
            fprintf(stderr, "weft bench fnopt: no XPBD reference at %u: %s\n", res, weft_last_error());
        }
        const size_t traj_floats = (size_t)s.frames * s.n * 3;
        float *ref = malloc(traj_floats * sizeof(float)), *pos = malloc(traj_floats * sizeof(float));
        for (size_t ii = 0; ref && pos && ii < iters_count; ++ii) {
            const uint32_t iters = iters_list[ii];
            bool have_ref = false;
            const weft_fnopt_optimizer kinds[4] = {WEFT_FNOPT_LEARNED, WEFT_FNOPT_GD, WEFT_FNOPT_ADAM, WEFT_FNOPT_LBFGS};
            const char *names[4] = {"learned", "gd", "adam", "lbfgs"};
            /* the learned optimizer once per precision (fp32 first when listed), then the classical ones */
            for (uint32_t run = 0; run < prec_count + (classical ? 3u : 0u); ++run) {
                const int k = run < prec_count ? 0 : (int)(run - prec_count) + 1;
                const weft_precision prec = run < prec_count ? precs[run] : WEFT_PRECISION_FP32;
                fnopt_run_opts ro = {.optimizer = kinds[k], .model = model, .iterations = iters,
                                     .learning_rate = kinds[k] == WEFT_FNOPT_LBFGS ? 1.0f : 0.01f,
                                     .Y = Y, .S = S, .B = B, .precision = prec,
                                     .max_step = weft_default_fnopt_def().max_step};
                fnopt_run_result r;
                clock_t c0 = clock();
                if (fnopt_scene_run(ctx, &s, &ro, NULL, &r, pos) != WEFT_OK) {
                    continue;
                }
                double cpu = 1e3 * (double)(clock() - c0) / CLOCKS_PER_SEC / (r.frames ? r.frames : 1);
                double e_ref = NAN, e_gt = NAN;
                if (k == 0 && prec == WEFT_PRECISION_FP32 && !r.diverged) {
                    memcpy(ref, pos, traj_floats * sizeof(float));
                    have_ref = true;
                } else if (have_ref && !r.diverged) {
                    e_ref = traj_e3d(pos, ref, r.frames, (size_t)s.n * 3);
                }
                if (gt && !r.diverged) {
                    e_gt = traj_e3d(pos, gt, r.frames, (size_t)s.n * 3);
                }
                printf("%u,%s,%s,%u,%u,%.3f,%.3f,%.4f,%.4g,%.4g\n", so.res, names[k], prec_names[prec], iters, r.frames,
                       r.ms_per_frame, cpu, r.ms_per_frame / iters, e_ref, e_gt);
                fflush(stdout);
            }
        }
        free(ref);
        free(pos);
        free(gt);
        fnopt_scene_free(&s);
    }
    weft_model_destroy(model);
    weft_context_destroy(ctx);
    return 0;
}
