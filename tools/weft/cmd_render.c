/* weft render: the avatar render sample, plus golden-image maintenance and the docs sheet.
 *
 *   weft render [sample options]                  avatar + garment + motion -> PNG frames
 *   weft render --update-goldens [--golden-dir D] re-render the PNGs in tests/golden
 *   weft render --check-goldens [--golden-dir D]  compare without writing (diffs to --out)
 *   weft render --docs-sheet PATH [--tile N]      docs/img/avatar_contact_sheet.png
 *   weft render --seq DIR --sheet OUT.png [--frames 0,60,120] [--tile N] [--columns N]
 *               [--yaw DEG] [--pitch DEG] [--no-caption]
 *                                                 contact sheet of a simgen sequence folder
 */
#include "weft.h"

#include "support_cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int weft_cmd_render(int argc, char **argv); /* the CLI registry declares it in main.c */
const char weft_cmd_render_help[] =
    "render the avatar wearing a garment through a motion (PNG frames); sequence contact sheets; golden images";

/* WEFT_HAVE_RENDER comes with the weft_render library (samples/common), absent when the
 * samples are not built. */
#if WEFT_HAVE_RENDER
#include "weft_sample.h"
#include "weft_scenes.h"
#include "core/core.h"

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

/* "N" (square, h = 0) or "WxH", digits only, each 64..1024. */
static bool parse_tile(const char *s, uint32_t *w, uint32_t *h)
{
    uint32_t v[2] = {0, 0};
    int n = 0;
    for (;;) {
        size_t digits = strspn(s, "0123456789");
        if (digits == 0 || digits > 4) {
            return false;
        }
        for (size_t k = 0; k < digits; ++k) {
            v[n] = v[n] * 10u + (uint32_t)(s[k] - '0');
        }
        if (v[n] < 64 || v[n] > 1024) {
            return false;
        }
        s += digits;
        ++n;
        if (*s == '\0') {
            break;
        }
        if (*s != 'x' || n == 2) {
            return false;
        }
        ++s;
    }
    *w = v[0];
    *h = n == 2 ? v[1] : 0;
    return true;
}

/* weft render --seq: the options left after the shared ones are only --yaw and --pitch. */
static int sequence_sheet(weft_seq_sheet_options *o, const char *frames, int nrest, char **rest)
{
    if (!o->out_path) {
        fprintf(stderr, "weft render: --seq needs --sheet OUT.png\n");
        return 2;
    }
    for (int i = 1; i < nrest; ++i) {
        bool yaw = strcmp(rest[i], "--yaw") == 0, pitch = strcmp(rest[i], "--pitch") == 0;
        if ((yaw || pitch) && i + 1 < nrest) {
            const float limit = yaw ? 360.0f : 85.0f;
            if (!cli_float("weft render", rest[i], rest[i + 1], -limit, limit, yaw ? &o->yaw : &o->pitch)) {
                return 2;
            }
            ++i;
        } else {
            fprintf(stderr, "weft render: option '%s' does not apply to --seq (see weft render --help)\n", rest[i]);
            return 2;
        }
    }
    if (frames && weft_seq_sheet_parse_frames(frames, o) != WEFT_OK) {
        fprintf(stderr, "weft render: %s\n", weft_last_error());
        return 2;
    }
    weft_seq_sheet_info info;
    double t0 = weft__now_ms();
    if (weft_seq_sheet_render(o, &info) != WEFT_OK) {
        fprintf(stderr, "weft render: %s\n", weft_last_error());
        return 1;
    }
    double ms = weft__now_ms() - t0;
    printf("%s: %s%s%u frames, cloth %u vertices, collider %u vertices (%u floor triangles drawn as the ground)\n",
           o->seq_dir, info.description, info.description[0] ? "; " : "", info.sequence_frames, info.cloth_vertices,
           info.collider_vertices, info.ground_triangles);
    if (info.accepted == 0) {
        printf("WARNING: the validator rejected this sequence (%u hits): it is not ground truth\n", info.validator_hits);
    } else if (info.validated == 0) {
        printf("WARNING: this sequence was written without the validator (--no-validate): it is not certified\n");
    } else if (info.accepted != 1 || info.validated != 1) {
        printf("WARNING: meta.json has no validator verdict\n");
    }
    printf("wrote %s (%ux%u, frames", o->out_path, info.width, info.height);
    for (uint32_t i = 0; i < info.frame_count; ++i) {
        printf("%s%u", i ? "," : " ", info.frames[i]);
    }
    printf(") in %.0f ms\n", ms);
    return 0;
}

int weft_cmd_render(int argc, char **argv)
{
    const char *golden_dir = "tests/golden";
    const char *docs_sheet = NULL;
    uint32_t tile = 200;
    const char *tile_text = NULL;
    int golden_mode = 0; /* 1 update, 2 check */
    weft_seq_sheet_options seq;
    weft_seq_sheet_default_options(&seq);
    const char *seq_frames = NULL;
    /* --frames means a frame list with --seq and a frame count for the avatar sample */
    bool seq_mode = false;
    for (int i = 1; i < argc; ++i) {
        seq_mode |= strcmp(argv[i], "--seq") == 0;
    }
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
            /* --seq takes N or WxH (checked below), the docs sheet a square tile */
            tile_text = argv[++i];
            if (!seq_mode && !cli_u32("weft render", argv[i - 1], tile_text, 64, 1024, &tile)) {
                free(rest);
                return 2;
            }
        } else if (strcmp(argv[i], "--seq") == 0 && i + 1 < argc) {
            seq.seq_dir = argv[++i];
        } else if (strcmp(argv[i], "--sheet") == 0 && i + 1 < argc) {
            seq.out_path = argv[++i];
        } else if (strcmp(argv[i], "--frames") == 0 && i + 1 < argc && seq_mode) {
            seq_frames = argv[++i];
        } else if (strcmp(argv[i], "--columns") == 0 && i + 1 < argc) {
            if (!cli_u32("weft render", argv[i], argv[i + 1], 1, WEFT_SEQ_SHEET_MAX_FRAMES, &seq.columns)) {
                free(rest);
                return 2;
            }
            ++i;
        } else if (strcmp(argv[i], "--no-caption") == 0) {
            seq.caption = false;
        } else {
            if (strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
                out_dir = argv[i + 1];
            }
            rest[nrest++] = argv[i];
        }
    }
    int status;
    if (seq_mode) {
        if (!seq.seq_dir) {
            fprintf(stderr, "weft render: --seq needs a sequence folder\n");
            free(rest);
            return 2;
        }
        uint32_t w = 0, h = 0;
        if (tile_text && !parse_tile(tile_text, &w, &h)) {
            fprintf(stderr, "weft render: --tile wants N or WxH pixels, each in [64, 1024], got '%s'\n", tile_text);
            free(rest);
            return 2;
        }
        if (tile_text) {
            seq.tile = w;
            seq.tile_height = h;
        }
        status = sequence_sheet(&seq, seq_frames, nrest, rest);
    } else if (golden_mode) {
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
                    "  --docs-sheet PATH       render the avatar/garment/pose contact sheet (--tile N, 64..1024,\n"
                    "                          default 200)\n"
                    "  --seq DIR --sheet PNG   contact sheet of a simgen sequence folder: --frames 0,60,120 (default\n"
                    "                          0, T/4, T/2, 3T/4, T-1), --tile N or WxH, each 64..1024 (default\n"
                    "                          240, 240x320 for garments), --columns N (1..32),\n"
                    "                          --yaw DEG (-360..360) / --pitch DEG (-85..85) (default per\n"
                    "                          scenario), --no-caption\n");
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
