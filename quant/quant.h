/* The offline quantiser: fp32 safetensors in, int8 or fp16 safetensors out, with a per-layer
 * decision (quantised or kept in fp32, and why) written into the file and an error report.
 *
 * Eligible: rank-2 tensors named "*.weight" (layer weights, PyTorch's [out][in] layout).
 * int8: each eligible weight W[N][K] becomes "<name>.q8" (I8, per-output-channel symmetric in
 * [-127, 127], round to nearest even) plus "<name>.scale" (F32 [N]). fp16: the same weights are
 * stored as F16 under their own name (range-checked: |w| <= 65504). Everything else stays F32:
 * biases and norm parameters (1-D), tiny layers (K or N below the minimum, where the int8
 * kernels gain nothing and the error is largest), tensors the forward pass uses as activations
 * (learned queries, embeddings: names listed in the metadata key "keep_fp32", comma-separated,
 * or in weft_quant_def.keep), and, with calibration, layers whose measured activation error is
 * above weft_quant_def.max_layer_error.
 *
 * Calibration (clothtransformer models): the fp32 model is rolled out autoregressively through
 * the runtime over simgen sequences, and every linear layer's input is recorded (abs max per
 * input channel and per tensor, 99.9th percentile) and its output error measured: the layer run
 * with quantised weights and activations exactly as the runtime runs it (int8: per-token int8
 * activations x per-channel int8 weights, int32 accumulation; fp16: fp16 weights, fp32
 * activations) against a double-precision fp32 reference on the same inputs. SmoothQuant
 * (optional) moves activation outliers into the weights: s_j = max|X_j|^a / max|W_j|^(1-a),
 * W' = W diag(s), and 1/s is folded into the gain and bias of the LayerNorm that produces the
 * layer's input (only there; layers fed by anything else are left alone and say why). */
#ifndef WEFT_QUANT_H
#define WEFT_QUANT_H

#include "weft.h"

#include <stdio.h>

#define WEFT_QUANT_FORMAT_VERSION 2

/* Default --max-layer-error: see docs/QUANTIZATION.md for the measurement behind it. */
#define WEFT_QUANT_DEFAULT_MAX_LAYER_ERROR 0.05
#define WEFT_QUANT_DEFAULT_CALIB_FRAMES 256u

typedef enum weft_quant_format {
    WEFT_QUANT_INT8 = 0,
    WEFT_QUANT_FP16,
} weft_quant_format;

typedef struct weft_quant_def {
    weft_quant_format format;
    uint32_t min_dim;            /* weights with K or N below this stay fp32 (default 16) */
    const char *const *keep;     /* extra tensor names to keep in fp32 (NULL-terminated, may be NULL) */

    /* Calibration: simgen sequence folders (meta.json + cloth_pos.npy ...), folders holding
     * such folders, or split lists (text files naming one sequence folder per line, relative to
     * the list's folder or its parent). NULL-terminated; NULL or empty: no calibration. */
    const char *const *calib;
    const char *calib_split;     /* for folders of sequences: "train", "val" or "test" (NULL: all) */
    uint32_t calib_frames;       /* frames recorded in total, spread over the sequences (default 256) */
    float smoothquant_alpha;     /* migration strength in [0, 1]; negative: off (default) */
    double max_layer_error;      /* a layer whose activation error exceeds this stays fp32 */

    /* End-to-end check: MVE of the fp32 and the quantised model on this sequence (NULL: none). */
    const char *val;
    uint32_t val_frames;         /* predicted frames scored (0: the whole sequence) */
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

/* One linear layer (a "<name>.weight" of rank 2) and its calibration. */
typedef struct weft_quant_layer_report {
    char name[128];              /* the weight's name without ".weight" */
    uint32_t out, in;
    char decision[48];           /* written as "quant.layer.<name>": "int8", "fp16", "fp32:tiny",
                                    "fp32:error=0.083", "fp32:request", "fp32:range" */
    double weight_error;         /* ||W - deq(Q(W))||_F / ||W||_F of the weights as stored */
    /* Calibration (all negative when there was none, or the layer was never run). */
    uint64_t rows;               /* input rows seen */
    double absmax;               /* max |x| over the input (before smoothing) */
    double p999;                 /* 99.9th percentile of |x| (histogram, 2% resolution) */
    double channel_ratio;        /* max over channels of absmax / median channel absmax: outliers */
    double act_error;            /* ||Y_q - Y||_F / ||Y||_F with the stored (smoothed) weights */
    double act_error_plain;      /* the same without smoothing */
    char smooth[200];            /* what SmoothQuant did with this layer and why */
    float *channel_absmax;       /* in entries (NULL without calibration) */
} weft_quant_layer_report;

typedef struct weft_quant_e2e {
    bool measured;
    char val[256];               /* the validation sequence folder */
    uint32_t frames;             /* predicted frames scored */
    double mve_fp32_cm, mve_quant_cm, ratio;
} weft_quant_e2e;

typedef struct weft_quant_report {
    weft_quant_tensor_report *tensors;
    uint32_t tensor_count;
    uint32_t quantized_count;
    uint64_t bytes_in, bytes_out;
    weft_quant_layer_report *layers;
    uint32_t layer_count;
    uint32_t calib_sequences, calib_frames;
    float smoothquant_alpha;     /* negative: off */
    double max_layer_error;
    weft_quant_e2e e2e;
} weft_quant_report;

weft_quant_def weft_default_quant_def(void);

/* Quantises the model file at in_path into out_path. Checks everything first (F32 only, finite,
 * not already quantised, output different from input, calibration and validation sequences
 * readable); on any failure nothing is written. *report (optional) receives per-tensor and
 * per-layer errors; free it with weft_quant_report_free. */
weft_result weft_quantize_file(weft_context *ctx, const weft_quant_def *def, const char *in_path,
                               const char *out_path, weft_quant_report *report);

/* Same on memory buffers (the output is weft_quant_buffer_free'd by the caller). */
weft_result weft_quantize_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                 void **out, size_t *out_size, weft_quant_report *report);
void weft_quant_buffer_free(weft_context *ctx, void *buffer, size_t size);

/* The SmoothQuant step alone: calibrates on def->calib and returns the migrated fp32 model
 * (same tensors and metadata plus "smoothquant"), which computes the same function as the input
 * up to fp32 rounding. Needs def->calib and def->smoothquant_alpha in [0, 1]. */
weft_result weft_quant_smooth_memory(weft_context *ctx, const weft_quant_def *def, const void *in, size_t in_size,
                                     void **out, size_t *out_size);

/* Mean vertex error (cm) of an autoregressive rollout of `model` at `precision` over the
 * sequence folder `dir` (started from its first two frames, CCD off), as `weft eval` scores it.
 * max_frames 0: the whole sequence. */
weft_result weft_quant_rollout_mve(weft_context *ctx, const weft_model *model, weft_precision precision,
                                   const char *dir, uint32_t max_frames, double *mve_cm, uint32_t *frames);

/* The committed validation sequence of this source tree (tests/data/sample_seq). */
const char *weft_quant_default_val_dir(void);

void weft_quant_report_free(weft_quant_report *report);
/* The report as JSON (one object: format, tensors[], layers[], calibration, e2e, totals). */
void weft_quant_report_write_json(const weft_quant_report *report, weft_quant_format format, FILE *out);
/* The per-layer table and the end-to-end line, for people. */
void weft_quant_report_print(const weft_quant_report *report, FILE *out);

#endif
