/* weft quantize: fp32 model -> int8 or fp16 model, with calibration, optional SmoothQuant, a
 * per-layer error report and the end-to-end MVE change on a validation sequence. */
#include "quant.h"
#include "support_cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int weft_cmd_quantize(int argc, char **argv); /* the CLI registry declares it in main.c */
extern const char weft_cmd_quantize_help[];
const char weft_cmd_quantize_help[] = "quantise an fp32 model to int8 or fp16 (calibration, per-layer error report)";

#define MAX_LIST 64

static const char k_tool[] = "weft quantize";

static void usage(FILE *out)
{
    fprintf(out,
            "usage: weft quantize IN.safetensors OUT.safetensors [--format int8|fp16]\n"
            "                     [--calib SEQ_DIR|FOLDER|SPLIT_LIST]... [--calib-split train|val|test]\n"
            "                     [--calib-frames N] [--smoothquant ALPHA] [--max-layer-error E]\n"
            "                     [--val SEQ_DIR | --no-val] [--val-frames N] [--min-dim N] [--keep TENSOR]...\n"
            "                     [--report REPORT.json]\n"
            "       (--in IN and --out OUT are accepted too)\n"
            "Weights with both dimensions >= min-dim (1..1048576, default 16) are quantised; biases, norms,\n"
            "small layers and tensors named by --keep or the model's \"keep_fp32\" metadata stay fp32.\n"
            "--calib rolls the fp32 model out autoregressively over simgen sequences (a sequence folder, a\n"
            "folder of them filtered by --calib-split, or a split list file), records every layer's input\n"
            "range and measures its quantised output error; layers above --max-layer-error (1e-6..1e6,\n"
            "default %.3g) stay fp32. --calib-frames (1..16777216, default %u) frames are recorded in total.\n"
            "--smoothquant ALPHA in [0, 1] migrates activation outliers into the weights through the\n"
            "preceding LayerNorm, kept per norm only where it lowers the measured error.\n"
            "--val runs the fp32 and the quantised model on a sequence (default: %s) and reports the MVE\n"
            "ratio over --val-frames frames (0..16777216, default 0: the whole sequence). Each layer's\n"
            "decision is written as metadata \"quant.layer.<name>\".\n"
            "On any error nothing is written.\n",
            WEFT_QUANT_DEFAULT_MAX_LAYER_ERROR, WEFT_QUANT_DEFAULT_CALIB_FRAMES, weft_quant_default_val_dir());
}

static bool is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

int weft_cmd_quantize(int argc, char **argv)
{
    const char *in = NULL, *out = NULL, *report_path = NULL, *val = NULL;
    bool no_val = false;
    const char *keep[MAX_LIST + 1] = {0}, *calib[MAX_LIST + 1] = {0};
    int nkeep = 0, ncalib = 0;
    weft_quant_def def = weft_default_quant_def();
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--no-val") == 0) {
            no_val = true;
        } else if (a[0] != '-' || a[1] == '\0') {
            if (!in) {
                in = a;
            } else if (!out) {
                out = a;
            } else {
                fprintf(stderr, "weft quantize: unexpected argument '%s'\n", a);
                return 2;
            }
        } else if (!v) {
            fprintf(stderr, "weft quantize: %s needs a value\n", a);
            usage(stderr);
            return 2;
        } else if (strcmp(a, "--in") == 0) {
            in = v, ++i;
        } else if (strcmp(a, "--out") == 0) {
            out = v, ++i;
        } else if (strcmp(a, "--report") == 0) {
            report_path = v, ++i;
        } else if (strcmp(a, "--val") == 0) {
            val = v, ++i;
        } else if (strcmp(a, "--calib-split") == 0) {
            def.calib_split = v, ++i;
        } else if (strcmp(a, "--format") == 0) {
            if (strcmp(v, "int8") == 0) {
                def.format = WEFT_QUANT_INT8;
            } else if (strcmp(v, "fp16") == 0) {
                def.format = WEFT_QUANT_FP16;
            } else {
                fprintf(stderr, "weft quantize: unknown format '%s' (int8 or fp16)\n", v);
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--min-dim") == 0) {
            if (!cli_u32(k_tool, a, v, 1, 1u << 20, &def.min_dim)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--calib-frames") == 0) {
            if (!cli_u32(k_tool, a, v, 1, 1u << 24, &def.calib_frames)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--val-frames") == 0) {
            if (!cli_u32(k_tool, a, v, 0, 1u << 24, &def.val_frames)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--smoothquant") == 0) {
            if (!cli_float(k_tool, a, v, 0.0f, 1.0f, &def.smoothquant_alpha)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--max-layer-error") == 0) {
            if (!cli_double(k_tool, a, v, 1e-6, 1e6, &def.max_layer_error)) {
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--keep") == 0 && nkeep < MAX_LIST) {
            keep[nkeep++] = v, ++i;
        } else if (strcmp(a, "--calib") == 0 && ncalib < MAX_LIST) {
            calib[ncalib++] = v, ++i;
        } else {
            fprintf(stderr, "weft quantize: unexpected argument '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!in || !out) {
        usage(stderr);
        return 2;
    }
    if (def.smoothquant_alpha >= 0.0f && ncalib == 0) {
        fprintf(stderr, "weft quantize: --smoothquant needs --calib\n");
        return 2;
    }
    def.keep = keep;
    def.calib = ncalib ? calib : NULL;
    if (!no_val) {
        /* The committed sample sequence when it is there (running from a source tree). */
        def.val = val ? val : (is_dir(weft_quant_default_val_dir()) ? weft_quant_default_val_dir() : NULL);
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx;
    weft_result r = weft_context_create(&cdef, &ctx);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft quantize: %s: %s\n", weft_result_string(r), weft_last_error());
        return 1;
    }
    weft_quant_report report;
    r = weft_quantize_file(ctx, &def, in, out, &report);
    weft_context_destroy(ctx);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft quantize: %s: %s (nothing written)\n", weft_result_string(r), weft_last_error());
        return 1;
    }
    weft_quant_report_print(&report, stdout);
    if (report_path) {
        FILE *f = fopen(report_path, "w");
        if (!f) {
            fprintf(stderr, "weft quantize: cannot write report '%s'\n", report_path);
            weft_quant_report_free(&report);
            return 1;
        }
        weft_quant_report_write_json(&report, def.format, f);
        if (fclose(f) != 0) {
            fprintf(stderr, "weft quantize: cannot write report '%s'\n", report_path);
            weft_quant_report_free(&report);
            return 1;
        }
    }
    weft_quant_report_free(&report);
    return 0;
}
