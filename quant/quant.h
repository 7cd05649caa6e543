/* The offline quantiser: fp32 safetensors in, int8 or fp16 safetensors out, with a per-tensor
 * decision (quantised or kept in fp32, and why) written into the file and an error report.
 *
 * Eligible: rank-2 tensors named "*.weight" (layer weights, PyTorch's [out][in] layout).
 * int8: each eligible weight W[N][K] becomes "<name>.q8" (I8, per-output-channel symmetric in
 * [-127, 127], round to nearest even) plus "<name>.scale" (F32 [N]). fp16: the same weights are
 * stored as F16 under their own name (range-checked: |w| <= 65504). Everything else stays F32:
 * biases and norm parameters (1-D), tiny layers (K or N below the minimum, where the int8
 * kernels gain nothing and the error is largest), and tensors the forward pass uses as
 * activations (learned queries, embeddings): names listed in the metadata key "keep_fp32"
 * (comma-separated) or in weft_quant_def.keep. */
#ifndef WEFT_QUANT_H
#define WEFT_QUANT_H

#include "weft.h"

#include <stdio.h>

#define WEFT_QUANT_FORMAT_VERSION 1

typedef enum weft_quant_format {
    WEFT_QUANT_INT8 = 0,
    WEFT_QUANT_FP16,
} weft_quant_format;

typedef struct weft_quant_def {
    weft_quant_format format;
    uint32_t min_dim;            /* weights with K or N below this stay fp32 (default 16) */
    const char *const *keep;     /* extra tensor names to keep in fp32 (NULL-terminated, may be NULL) */
    uint32_t internal_cookie;
} weft_quant_def;

/* One tensor's outcome, for the report. */
typedef struct weft_quant_tensor_report {
    char name[128];
    char scheme[48];             /* "int8-per-channel", "fp16", or "fp32 (reason)" */
    uint64_t count;
    double weight_rms;           /* RMS of the fp32 weights */
    double error_rms;            /* RMS of (dequantised - fp32); 0 when kept */
    double error_max;            /* max |dequantised - fp32| */
    double rel_error;            /* error_rms / weight_rms (0 when the weights are all zero) */
} weft_quant_tensor_report;

typedef struct weft_quant_report {
    weft_quant_tensor_report *tensors;
    uint32_t tensor_count;
    uint32_t quantized_count;
    uint64_t bytes_in, bytes_out;
} weft_quant_report;

weft_quant_def weft_default_quant_def(void);

/* Quantises the model file at in_path into out_path. Checks everything first (F32 only, finite,
 * not already quantised, output different from input); on any failure nothing is written.
 * *report (optional) receives per-tensor errors; free it with weft_quant_report_free. */
weft_result weft_quantize_file(weft_context *ctx, const weft_quant_def *def, const char *in_path,
                               const char *out_path, weft_quant_report *report);

/* Same on memory buffers (the output is weft_quant_buffer_free'd by the caller). */
weft_result weft_quantize_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                 void **out, size_t *out_size, weft_quant_report *report);
void weft_quant_buffer_free(weft_context *ctx, void *buffer, size_t size);

void weft_quant_report_free(weft_quant_report *report);
/* The report as JSON (one object: format, tensors[], totals). */
void weft_quant_report_write_json(const weft_quant_report *report, weft_quant_format format, FILE *out);

#endif
