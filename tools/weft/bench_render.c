/* weft bench render: time the OSMesa renderer on the golden scenes.
 *
 *   weft bench render [--size N] [--repeats N] [--supersample N] [--deterministic]
 *
 *   --size 16..4096 pixels (256), --repeats 1..10000 (10), --supersample 1..4 (2)
 *
 * Mesa picks its driver once per process, so one run measures either llvmpipe (default) or
 * softpipe (--deterministic, what the golden tests use). */
#include "weft.h"

#include "support_cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int weft_bench_render(int argc, char **argv); /* the CLI registry declares it in main.c */
const char weft_bench_render_help[] = "time the off-screen renderer on the golden scenes (llvmpipe or softpipe)";

#if WEFT_HAVE_RENDER
#include "core/core.h"
#include "weft_scenes.h"

int weft_bench_render(int argc, char **argv)
{
    uint32_t size = 256, repeats = 10, supersample = 2;
    bool deterministic = false;
    for (int i = 1; i < argc; ++i) {
        /* the renderer takes 16..4096 pixels a side and supersamples 1..4 times */
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--size") == 0 && v) {
            if (!cli_u32("weft bench render", a, v, 16, 4096, &size)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--repeats") == 0 && v) {
            if (!cli_u32("weft bench render", a, v, 1, 10000, &repeats)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--supersample") == 0 && v) {
            if (!cli_u32("weft bench render", a, v, 1, 4, &supersample)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--deterministic") == 0) {
            deterministic = true;
        } else {
            fprintf(stderr, "usage: weft bench render [--size 16..4096 (256)] [--repeats 1..10000 (10)]\n"
                            "                         [--supersample 1..4 (2)] [--deterministic]\n");
            return 2;
        }
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft bench render: %s\n", weft_last_error());
        return 1;
    }
    weft_render_def def = weft_default_render_def();
    def.width = def.height = size;
    def.supersample = supersample;
    def.deterministic = deterministic;
    weft_renderer *r = NULL;
    if (weft_renderer_create(&def, &r) != WEFT_OK) {
        fprintf(stderr, "weft bench render: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    printf("driver %s, %ux%u, supersample %u, %u repeats\n", deterministic ? "softpipe" : "llvmpipe (Mesa default)", size,
           size, supersample, repeats);
    printf("%-20s %9s %9s %9s\n", "scene", "mean ms", "min ms", "max ms");
    int status = 0;
    for (uint32_t s = 0; s < weft_golden_scene_count(); ++s) {
        /* the first render builds the scene (meshes, camera); later ones redraw it */
        if (weft_golden_scene_render(s, ctx, r) != WEFT_OK) {
            fprintf(stderr, "%s: %s\n", weft_golden_scene_name(s), weft_last_error());
            status = 1;
            continue;
        }
        double sum = 0, lo = 1e30, hi = 0;
        for (uint32_t k = 0; k < repeats; ++k) {
            double t0 = weft__now_ms();
            if (weft_renderer_render(r) != WEFT_OK) {
                fprintf(stderr, "%s: %s\n", weft_golden_scene_name(s), weft_last_error());
                status = 1;
                break;
            }
            double dt = weft__now_ms() - t0;
            sum += dt;
            lo = dt < lo ? dt : lo;
            hi = dt > hi ? dt : hi;
        }
        printf("%-20s %9.2f %9.2f %9.2f\n", weft_golden_scene_name(s), sum / repeats, lo, hi);
    }
    weft_renderer_destroy(r);
    weft_context_destroy(ctx);
    return status;
}

#else

int weft_bench_render(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    fprintf(stderr, "weft bench render: this weft was built without the samples\n");
    return 1;
}

#endif
