/* weft quantize: fp32 model -> int8 or fp16 model, with a per-tensor error report. */
#include "quant.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int weft_cmd_quantize(int argc, char **argv); /* the CLI registry declares it in main.c */
extern const char weft_cmd_quantize_help[];
const char weft_cmd_quantize_help[] = "quantise an fp32 model to int8 or fp16 (per-tensor error report)";

static void usage(FILE *out)
{
    fprintf(out, "usage: weft quantize --in MODEL.safetensors --out OUT.safetensors [--format int8|fp16]\n"
                 "                     [--min-dim N] [--keep TENSOR]... [--report REPORT.json]\n"
                 "Weights with both dimensions >= min-dim (default 16) are quantised; biases, norms, small\n"
                 "layers and tensors named by --keep or the model's \"keep_fp32\" metadata stay fp32.\n"
                 "On any error nothing is written.\n");
}

int weft_cmd_quantize(int argc, char **argv)
{
    const char *in = NULL, *out = NULL, *report_path = NULL;
    const char *keep[64] = {0};
    int nkeep = 0;
    weft_quant_def def = weft_default_quant_def();
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--in") == 0 && v) {
            in = v, ++i;
        } else if (strcmp(a, "--out") == 0 && v) {
            out = v, ++i;
        } else if (strcmp(a, "--report") == 0 && v) {
            report_path = v, ++i;
        } else if (strcmp(a, "--format") == 0 && v) {
            if (strcmp(v, "int8") == 0) {
                def.format = WEFT_QUANT_INT8;
            } else if (strcmp(v, "fp16") == 0) {
                def.format = WEFT_QUANT_FP16;
            } else {
                fprintf(stderr, "weft quantize: unknown format '%s' (int8 or fp16)\n", v);
                return 2;
            }
            ++i;
        } else if (strcmp(a, "--min-dim") == 0 && v) {
            char *end;
            long n = strtol(v, &end, 10);
            if (*end || n < 1 || n > 1 << 20) {
                fprintf(stderr, "weft quantize: bad --min-dim '%s'\n", v);
                return 2;
            }
            def.min_dim = (uint32_t)n, ++i;
        } else if (strcmp(a, "--keep") == 0 && v && nkeep < 63) {
            keep[nkeep++] = v, ++i;
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
    def.keep = keep;
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
    printf("%-48s %-28s %10s %12s %12s\n", "tensor", "scheme", "elements", "rel_rms_err", "max_abs_err");
    for (uint32_t i = 0; i < report.tensor_count; ++i) {
        const weft_quant_tensor_report *t = &report.tensors[i];
        printf("%-48s %-28s %10llu %12.3e %12.3e\n", t->name, t->scheme, (unsigned long long)t->count, t->rel_error,
               t->error_max);
    }
    printf("%u of %u tensors quantised, %llu -> %llu bytes (%.2fx smaller)\n", report.quantized_count,
           report.tensor_count, (unsigned long long)report.bytes_in, (unsigned long long)report.bytes_out,
           (double)report.bytes_in / (double)report.bytes_out);
    if (report_path) {
        FILE *f = fopen(report_path, "w");
        if (!f) {
            fprintf(stderr, "weft quantize: cannot write report '%s'\n", report_path);
            weft_quant_report_free(&report);
            return 1;
        }
        weft_quant_report_write_json(&report, def.format, f);
        fclose(f);
    }
    weft_quant_report_free(&report);
    return 0;
}
