/* weft bench render: time the OSMesa renderer on the golden scenes.
 *
 *   weft bench render [--size N] [--repeats N] [--supersample N] [--deterministic]
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

enum { OPT_SIZE = 1, OPT_REPEATS, OPT_SUPERSAMPLE, OPT_DETERMINISTIC };

/* the renderer takes 16..4096 pixels a side and supersamples 1..4 times */
static const cli_option k_options[] = {
    {"size", "N", OPT_SIZE, "image width and height in pixels, 16..4096 (default 256)"},
    {"repeats", "N", OPT_REPEATS, "timed renders per scene, 1..10000 (default 10)"},
    {"supersample", "N", OPT_SUPERSAMPLE, "supersampling factor, 1..4 (default 2)"},
    {"deterministic", NULL, OPT_DETERMINISTIC,
     "render with Mesa's softpipe, what the golden tests use, instead of\n"
     "llvmpipe"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench render",
    .synopsis = "weft bench render [--size N] [--repeats N] [--supersample N] [--deterministic]",
    .about = "Times the OSMesa off-screen renderer on the golden scenes: mean, min and max ms per scene.\n"
             "Mesa picks its driver once per process, so one run measures either llvmpipe (default) or\n"
             "softpipe (--deterministic).",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_render(int argc, char **argv)
{
    uint32_t size = 256, repeats = 10, supersample = 2;
    bool deterministic = false;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_SIZE:
            if (!cli_u32(k_command.tool, a, v, 16, 4096, &size)) {
                return 2;
            }
            break;
        case OPT_REPEATS:
            if (!cli_u32(k_command.tool, a, v, 1, 10000, &repeats)) {
                return 2;
            }
            break;
        case OPT_SUPERSAMPLE:
            if (!cli_u32(k_command.tool, a, v, 1, 4, &supersample)) {
                return 2;
            }
            break;
        case OPT_DETERMINISTIC:
            deterministic = true;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
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
