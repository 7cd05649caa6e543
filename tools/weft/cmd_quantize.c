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

enum {
    OPT_IN = 1, OPT_OUT, OPT_FORMAT, OPT_CALIB, OPT_CALIB_SPLIT, OPT_CALIB_FRAMES, OPT_SMOOTHQUANT,
    OPT_MAX_LAYER_ERROR, OPT_VAL, OPT_NO_VAL, OPT_VAL_FRAMES, OPT_MIN_DIM, OPT_KEEP, OPT_REPORT,
};

static const cli_option k_options[] = {
    {"format", "int8|fp16", OPT_FORMAT, "the quantised format (default int8)"},
    {"calib", "SEQ_DIR|FOLDER|LIST", OPT_CALIB,
     "calibrate on simgen sequences: a sequence folder, a folder of them (filtered\n"
     "by --calib-split) or a split list file; repeatable (up to 64)"},
    {"calib-split", "train|val|test", OPT_CALIB_SPLIT, "the split a --calib folder is filtered by"},
    {"calib-frames", "N", OPT_CALIB_FRAMES, "frames recorded in total, 1..16777216"},
    {"smoothquant", "ALPHA", OPT_SMOOTHQUANT,
     "in [0, 1]: migrate activation outliers into the weights through the\n"
     "preceding LayerNorm, kept per norm only where it lowers the measured error\n"
     "(needs --calib)"},
    {"max-layer-error", "E", OPT_MAX_LAYER_ERROR, "layers whose quantised output error is above E stay fp32 (1e-6..1e6)"},
    {"val", "SEQ_DIR", OPT_VAL, "the validation sequence of the MVE ratio"},
    {"no-val", NULL, OPT_NO_VAL, "skip the validation"},
    {"val-frames", "N", OPT_VAL_FRAMES, "validation frames, 0..16777216 (default 0: the whole sequence)"},
    {"min-dim", "N", OPT_MIN_DIM, "quantise weights with both dimensions >= N, 1..1048576 (default 16)"},
    {"keep", "TENSOR", OPT_KEEP, "keep this tensor fp32; repeatable (up to 64)"},
    {"report", "REPORT.json", OPT_REPORT, "write the per-layer report as JSON"},
    {"in", "IN", OPT_IN, NULL},
    {"out", "OUT", OPT_OUT, NULL},
    {0},
};

static void notes(FILE *out)
{
    fprintf(out,
            "IN and OUT may also be given as --in IN and --out OUT.\n"
            "Biases, norms, small layers and tensors named by --keep or the model's \"keep_fp32\" metadata\n"
            "stay fp32. --calib rolls the fp32 model out autoregressively over the sequences, records every\n"
            "layer's input range and measures its quantised output error; layers above --max-layer-error\n"
            "(default %.3g) stay fp32. --calib-frames defaults to %u. --val runs the fp32 and the quantised\n"
            "model on a sequence and reports the MVE ratio; its default is\n  %s\n"
            "Each layer's decision is written as metadata \"quant.layer.<name>\". On any error nothing is\n"
            "written.\n",
            WEFT_QUANT_DEFAULT_MAX_LAYER_ERROR, WEFT_QUANT_DEFAULT_CALIB_FRAMES, weft_quant_default_val_dir());
}

static const cli_command k_command = {
    .tool = "weft quantize",
    .synopsis = "weft quantize IN.safetensors OUT.safetensors [options]",
    .about = "Quantises an fp32 model to int8 or fp16 (calibration, per-layer error report).",
    .options = k_options,
    .notes = notes,
};

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
    cli_parser p;
    cli_start(&p, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&p, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return p.exit;
        case OPT_IN:
            in = v;
            break;
        case OPT_OUT:
            out = v;
            break;
        case OPT_REPORT:
            report_path = v;
            break;
        case OPT_VAL:
            val = v;
            break;
        case OPT_NO_VAL:
            no_val = true;
            break;
        case OPT_CALIB_SPLIT:
            def.calib_split = v;
            break;
        case OPT_FORMAT:
            if (strcmp(v, "int8") == 0) {
                def.format = WEFT_QUANT_INT8;
            } else if (strcmp(v, "fp16") == 0) {
                def.format = WEFT_QUANT_FP16;
            } else {
                fprintf(stderr, "weft quantize: unknown format '%s' (int8 or fp16)\n", v);
                return 2;
            }
            break;
        case OPT_MIN_DIM:
            if (!cli_u32(k_tool, a, v, 1, 1u << 20, &def.min_dim)) {
                return 2;
            }
            break;
        case OPT_CALIB_FRAMES:
            if (!cli_u32(k_tool, a, v, 1, 1u << 24, &def.calib_frames)) {
                return 2;
            }
            break;
        case OPT_VAL_FRAMES:
            if (!cli_u32(k_tool, a, v, 0, 1u << 24, &def.val_frames)) {
                return 2;
            }
            break;
        case OPT_SMOOTHQUANT:
            if (!cli_float(k_tool, a, v, 0.0f, 1.0f, &def.smoothquant_alpha)) {
                return 2;
            }
            break;
        case OPT_MAX_LAYER_ERROR:
            if (!cli_double(k_tool, a, v, 1e-6, 1e6, &def.max_layer_error)) {
                return 2;
            }
            break;
        case OPT_KEEP:
        case OPT_CALIB:
            if ((id == OPT_KEEP ? nkeep : ncalib) >= MAX_LIST) {
                return cli_fail(&k_command, id == OPT_KEEP ? "more than 64 --keep" : "more than 64 --calib");
            }
            if (id == OPT_KEEP) {
                keep[nkeep++] = v;
            } else {
                calib[ncalib++] = v;
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    char **rest;
    const int nrest = cli_rest(&p, &rest);
    for (int k = 0; k < nrest; ++k) {
        if (!in) {
            in = rest[k];
        } else if (!out) {
            out = rest[k];
        } else {
            fprintf(stderr, "weft quantize: unexpected argument '%s'\n", rest[k]);
            return 2;
        }
    }
    if (!in || !out) {
        return cli_fail(&k_command, "IN and OUT are required");
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
