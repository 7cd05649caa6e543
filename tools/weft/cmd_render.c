/* weft render: the avatar render sample, plus golden-image maintenance and the docs sheet.
 *
 *   weft render [sample options]                  avatar + garment + motion -> PNG frames
 *   weft render --update-goldens [--golden-dir D] re-render the PNGs in tests/golden
 *   weft render --check-goldens [--golden-dir D]  compare without writing (diffs to --out)
 *   weft render --docs-sheet PATH [--tile N]      docs/img/avatar_contact_sheet.png
 *   weft render --seq DIR --sheet OUT.png [--frames 0,60,120] [--tile N] [--columns N]
 *               [--yaw DEG] [--pitch DEG] [--no-caption]
 *                                                 contact sheet of a simgen sequence folder
 *
 * The sample's options (samples/common/avatar_sample.c, weft_avatar_sample_option_table) and
 * weft render's own are one option table; the sample's are applied once the mode is known. */
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

/* weft render's own options; the sample's (weft_avatar_sample_option_table) are listed with them,
 * in one table for getopt_long and the help. Their ids lie above the sample's and above getopt's
 * ':', '?' and 'h'. */
enum {
    OPT_UPDATE_GOLDENS = 200, OPT_CHECK_GOLDENS, OPT_GOLDEN_DIR, OPT_DOCS_SHEET, OPT_TILE, OPT_SEQ, OPT_COLUMNS,
    OPT_NO_CAPTION,
};
_Static_assert(WEFT_AVATAR_SAMPLE_OPTION_ID_END <= OPT_UPDATE_GOLDENS, "weft render's option ids follow the sample's");

static const cli_option k_render_options[] = {
    {"update-goldens", NULL, OPT_UPDATE_GOLDENS, "re-render the golden images into --golden-dir"},
    {"check-goldens", NULL, OPT_CHECK_GOLDENS, "compare with the goldens; diffs go to --out (default .)"},
    {"golden-dir", "DIR", OPT_GOLDEN_DIR, "the golden images (default tests/golden)"},
    {"docs-sheet", "PATH", OPT_DOCS_SHEET, "render the avatar/garment/pose contact sheet"},
    {"tile", "N|WxH", OPT_TILE,
     "with --docs-sheet: N, 64..1024 (default 200); with --seq: N or WxH, each\n"
     "64..1024 (default 240, 240x320 for garments)"},
    {"seq", "DIR", OPT_SEQ,
     "contact sheet of a simgen sequence folder into --sheet PNG; --sheet,\n"
     "--frames, --yaw and --pitch then mean other things (below)"},
    {"columns", "N", OPT_COLUMNS, "with --seq: tiles per row, 1..32 (default: all in one row up to 6)"},
    {"no-caption", NULL, OPT_NO_CAPTION, "with --seq: no caption strip"},
    {0},
};

/* The sample's options, then weft render's: filled by weft_cmd_render. */
static cli_option g_options[CLI_MAX_OPTIONS + 1];

static void notes(FILE *out)
{
    fprintf(out, "With --seq: --sheet PNG is the sheet to write, --frames 0,60,120 the frames drawn (default 0,\n"
                 "T/4, T/2, 3T/4, T-1), --yaw DEG -360..360 and --pitch DEG -85..85 (default per scenario); no\n"
                 "other sample option applies. --update-goldens, --check-goldens and --docs-sheet take only\n"
                 "--golden-dir, --out and --tile; the sample's other options are ignored there.\n");
}

static const cli_command k_command = {
    .tool = "weft render",
    .synopsis = "weft render [sample options]\n"
                "weft render --update-goldens|--check-goldens [--golden-dir DIR] [--out DIR]\n"
                "weft render --docs-sheet PATH [--tile N]\n"
                "weft render --seq DIR --sheet OUT.png [--frames 0,60,120] [--tile N|WxH] [--columns N]\n"
                "            [--yaw DEG] [--pitch DEG] [--no-caption]",
    .about = "Renders the avatar wearing a garment through a motion (the avatar render sample, its options\n"
             "from --motion to --crowd-budget): PNG frames and a contact sheet. Also re-renders or checks\n"
             "the golden images of tests/golden, renders the docs contact sheet\n"
             "(docs/img/avatar_contact_sheet.png) and contact sheets of simgen sequence folders.",
    .options = g_options,
    .notes = notes,
};

/* Lists the sample's options and weft render's in g_options; false if they do not fit. */
static bool merge_options(void)
{
    size_t n = 0;
    for (const weft_sample_option *e = weft_avatar_sample_option_table; e->name; ++e) {
        if (n == CLI_MAX_OPTIONS) {
            return false;
        }
        g_options[n++] = (cli_option){e->name, e->value, e->id, e->help};
    }
    for (const cli_option *e = k_render_options; e->name; ++e) {
        if (n == CLI_MAX_OPTIONS) {
            return false;
        }
        g_options[n++] = *e;
    }
    g_options[n] = (cli_option){0};
    return true;
}

/* Whether option `id` is the sample's --NAME. */
static bool is_option(int id, const char *name)
{
    return strcmp(cli_name(&k_command, id) + 2, name) == 0;
}

/* weft render --seq, its options checked. */
static int sequence_sheet(weft_seq_sheet_options *o, const char *frames)
{
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

/* One of the sample's options, kept until the mode is known (--frames, --sheet, --yaw and --pitch
 * mean other things with --seq). */
typedef struct sample_arg {
    int id;
    const char *value;
} sample_arg;

static int render(int argc, char **argv, sample_arg *sample_args)
{
    const char *golden_dir = "tests/golden";
    const char *docs_sheet = NULL;
    uint32_t tile = 200;
    const char *tile_text = NULL;
    int golden_mode = 0; /* 1 update, 2 check */
    weft_seq_sheet_options seq;
    weft_seq_sheet_default_options(&seq);
    bool seq_mode = false;
    int nsample = 0;
    cli_parser p;
    cli_start(&p, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&p, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return p.exit;
        case OPT_UPDATE_GOLDENS:
            golden_mode = 1;
            break;
        case OPT_CHECK_GOLDENS:
            golden_mode = 2;
            break;
        case OPT_GOLDEN_DIR:
            golden_dir = v;
            break;
        case OPT_DOCS_SHEET:
            docs_sheet = v;
            break;
        case OPT_TILE:
            tile_text = v; /* N or WxH with --seq, N for the docs sheet: checked once the mode is known */
            break;
        case OPT_SEQ:
            seq.seq_dir = v;
            seq_mode = true;
            break;
        case OPT_COLUMNS:
            if (!cli_u32(k_command.tool, a, v, 1, WEFT_SEQ_SHEET_MAX_FRAMES, &seq.columns)) {
                return 2;
            }
            break;
        case OPT_NO_CAPTION:
            seq.caption = false;
            break;
        default:
            if (id < 1 || id >= WEFT_AVATAR_SAMPLE_OPTION_ID_END) {
                return cli_fail(&k_command, "internal error: an option without a case");
            }
            sample_args[nsample++] = (sample_arg){id, v};
            break;
        }
    }
    if (cli_no_rest(&p) != 0) {
        return 2;
    }
    if (!seq_mode && tile_text && !cli_u32(k_command.tool, "--tile", tile_text, 64, 1024, &tile)) {
        return 2;
    }
    if (seq_mode) {
        const char *seq_frames = NULL;
        for (int k = 0; k < nsample; ++k) {
            const int id = sample_args[k].id;
            const char *value = sample_args[k].value;
            if (is_option(id, "frames")) {
                seq_frames = value;
            } else if (is_option(id, "sheet")) {
                seq.out_path = value;
            } else if (is_option(id, "yaw") || is_option(id, "pitch")) {
                const bool yaw = is_option(id, "yaw");
                const float limit = yaw ? 360.0f : 85.0f;
                if (!cli_float(k_command.tool, cli_name(&k_command, id), value, -limit, limit,
                               yaw ? &seq.yaw : &seq.pitch)) {
                    return 2;
                }
            } else {
                fprintf(stderr, "weft render: option '%s' does not apply to --seq (see weft render --help)\n",
                        cli_name(&k_command, id));
                return 2;
            }
        }
        uint32_t w = 0, h = 0;
        if (tile_text && !parse_tile(tile_text, &w, &h)) {
            fprintf(stderr, "weft render: --tile wants N or WxH pixels, each in [64, 1024], got '%s'\n", tile_text);
            return 2;
        }
        if (tile_text) {
            seq.tile = w;
            seq.tile_height = h;
        }
        if (!seq.out_path) {
            fprintf(stderr, "weft render: --seq needs --sheet OUT.png\n");
            return 2;
        }
        return sequence_sheet(&seq, seq_frames);
    }
    if (golden_mode) {
        const char *out_dir = ".";
        for (int k = 0; k < nsample; ++k) {
            if (is_option(sample_args[k].id, "out")) {
                out_dir = sample_args[k].value;
            }
        }
        return goldens(golden_dir, out_dir, golden_mode == 1);
    }
    if (docs_sheet) {
        return weft_avatar_sample_docs_sheet(docs_sheet, tile);
    }
    weft_avatar_sample_options options;
    weft_avatar_sample_default_options(&options);
    for (int k = 0; k < nsample; ++k) {
        if (!weft_avatar_sample_apply(sample_args[k].id, sample_args[k].value, &options)) {
            char what[512];
            snprintf(what, sizeof what, "bad value '%s' for %s", sample_args[k].value ? sample_args[k].value : "",
                     cli_name(&k_command, sample_args[k].id));
            return cli_fail(&k_command, what);
        }
    }
    return weft_avatar_sample_run(&options);
}

int weft_cmd_render(int argc, char **argv)
{
    if (!merge_options()) {
        return cli_fail(&k_command, "internal error: too many options");
    }
    sample_arg *sample_args = malloc((size_t)(argc > 0 ? argc : 1) * sizeof *sample_args);
    if (!sample_args) {
        fprintf(stderr, "weft render: out of memory\n");
        return 1;
    }
    const int status = render(argc, argv, sample_args);
    free(sample_args);
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
