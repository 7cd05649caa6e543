/* weft render: the avatar render sample, plus golden-image maintenance and the docs sheet.
 *
 *   weft render [sample options]                  avatar + garment + motion -> PNG frames
 *   weft render --update-goldens [--golden-dir D] re-render the PNGs in tests/golden
 *   weft render --check-goldens [--golden-dir D]  compare without writing (diffs to --out)
 *   weft render --docs-sheet PATH [--tile N]      docs/img/avatar_contact_sheet.png
 */
#include "weft.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int weft_cmd_render(int argc, char **argv); /* the CLI registry declares it in main.c */
const char weft_cmd_render_help[] = "render the avatar wearing a garment through a motion (PNG frames); golden images";

/* WEFT_HAVE_RENDER comes with the weft_render library (samples/common), absent when the
 * samples are not built. */
#if WEFT_HAVE_RENDER
#include "weft_sample.h"
#include "weft_scenes.h"

static int goldens(const char *dir, const char *out_dir, bool update)
{
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft render: %s\n", weft_last_error());
        return 1;
    }
    int status = 0;
    for (uint32_t i = 0; i < weft_golden_scene_count(); ++i) {
        weft_golden_outcome o;
        weft_result r = weft_golden_check(i, ctx, dir, out_dir, update, &o);
        if (r != WEFT_OK) {
            fprintf(stderr, "%-20s error: %s\n", weft_golden_scene_name(i), weft_last_error());
            status = 1;
            continue;
        }
        if (o.updated) {
            printf("%-20s wrote %s  (%s)\n", weft_golden_scene_name(i), o.golden_path, weft_golden_scene_description(i));
        } else {
            printf("%-20s %s: %llu pixels over %u counts (%.4f%%, limit %.2f%%), max diff %u%s%s\n",
                   weft_golden_scene_name(i), o.passed ? "ok" : "FAILED", (unsigned long long)o.diff.pixels_over,
                   WEFT_GOLDEN_CHANNEL_TOLERANCE, 100.0 * o.diff.fraction_over, 100.0 * WEFT_GOLDEN_MAX_FRACTION,
                   o.diff.max_channel_diff, o.passed ? "" : ", diff: ", o.passed ? "" : o.diff_path);
            status |= !o.passed;
        }
    }
    weft_context_destroy(ctx);
    return status;
}

int weft_cmd_render(int argc, char **argv)
{
    const char *golden_dir = "tests/golden";
    const char *docs_sheet = NULL;
    uint32_t tile = 200;
    int golden_mode = 0; /* 1 update, 2 check */
    /* weft-specific options first; the rest go to the sample's parser */
    char **rest = malloc((size_t)argc * sizeof *rest);
    if (!rest) {
        return 1;
    }
    int nrest = 0;
    rest[nrest++] = argv[0];
    const char *out_dir = ".";
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--update-goldens") == 0) {
            golden_mode = 1;
        } else if (strcmp(argv[i], "--check-goldens") == 0) {
            golden_mode = 2;
        } else if (strcmp(argv[i], "--golden-dir") == 0 && i + 1 < argc) {
            golden_dir = argv[++i];
        } else if (strcmp(argv[i], "--docs-sheet") == 0 && i + 1 < argc) {
            docs_sheet = argv[++i];
        } else if (strcmp(argv[i], "--tile") == 0 && i + 1 < argc) {
            tile = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else {
            if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
                out_dir = argv[i + 1];
            }
            rest[nrest++] = argv[i];
        }
    }
    int status;
    if (golden_mode) {
        status = goldens(golden_dir, out_dir, golden_mode == 1);
    } else if (docs_sheet) {
        status = weft_avatar_sample_docs_sheet(docs_sheet, tile);
    } else {
        weft_avatar_sample_options options;
        weft_avatar_sample_default_options(&options);
        int parsed = weft_avatar_sample_parse(nrest, rest, 1, &options);
        if (parsed != 0) {
            weft_avatar_sample_usage(parsed == 1 ? stdout : stderr, "weft render");
            FILE *out = parsed == 1 ? stdout : stderr;
            fprintf(out,
                    "  --update-goldens        re-render the golden images into --golden-dir (default tests/golden)\n"
                    "  --check-goldens         compare with the goldens; diffs go to --out\n"
                    "  --docs-sheet PATH       render the avatar/garment/pose contact sheet (--tile N, default 200)\n");
            free(rest);
            return parsed == 1 ? 0 : 2;
        }
        status = weft_avatar_sample_run(&options);
    }
    free(rest);
    return status;
}
#else

int weft_cmd_render(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    fprintf(stderr, "weft render: this weft was built without the samples (WEFT_BUILD_SAMPLES=OFF)\n");
    return 1;
}

#endif
