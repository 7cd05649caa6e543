/* Internal pieces of the quantiser shared between its files. */
#ifndef WEFT_QUANT_INTERNAL_H
#define WEFT_QUANT_INTERNAL_H

#include "quant.h"

#include "io/safetensors.h"
#include "model/model.h"

/* One simgen sequence, as `weft eval` reads it. */
typedef struct quant_seq {
    float *rest, *pos, *cpos;           /* [V,3], [T,V,3], [T,Vc,3] (cpos NULL without collider) */
    uint32_t *faces, *cfaces;           /* [F,3], [Fc,3] */
    uint32_t V, F, T, Vc, Fc;
    float *pinned;                      /* [T,V] non-zero where a vertex is pinned (pinned.npy), or NULL */
    uint32_t *pin_index;                /* [V] scratch for quant_seq_set_pins */
    float *pin_target;                  /* [V,3] scratch */
} quant_seq;

/* Loads and checks a sequence folder: meta.json must parse, arrays must have matching shapes,
 * finite values and in-range indices. Fails with IO, FORMAT, SIZE_MISMATCH or NOT_FINITE. */
weft_result quant_seq_load(const char *dir, quant_seq *s);
void quant_seq_free(quant_seq *s);

/* Pins the vertices pinned in frame t to that frame's positions before the step to t, as `weft eval
 * --pins all` does, so calibration and the error report roll out what the models are measured on
 * (a grasped sheet follows its gripper); nothing for a sequence without pinned.npy. */
weft_result quant_seq_set_pins(weft_garment *g, const quant_seq *s, uint32_t t);

/* Expands calibration arguments (sequence folders, folders of them, split lists) into sequence
 * folders; split filters folders of sequences. Free with quant_list_free. */
weft_result quant_seq_expand(const char *const *args, const char *split, char ***out, uint32_t *count);
void quant_list_free(char **list, uint32_t count);

/* Whole-file read: into the context's allocator (release with weft__free(ctx, p, size)), or
 * malloc'd memory when ctx is NULL. */
weft_result quant_read_all(weft_context *ctx, const char *path, void **out, size_t *size);

/* Calibration of a clothtransformer model held in a safetensors buffer. */
typedef struct quant_calib quant_calib;

/* A linear layer's per-input-channel statistics and error sums. */
typedef struct quant_layer_stats {
    char name[128];
    uint32_t out, in;
    bool eligible;                      /* quantised unless its error says otherwise */
    uint64_t rows;
    float *ch_absmax;                   /* in */
    double absmax, p999, channel_ratio;
    double err_num, err_den;            /* sums of |Y_q - Y|^2 and |Y|^2 */
} quant_layer_stats;

/* Rolls the fp32 model in `bytes` out over the sequences and records every linear layer.
 * eligible(name, out, in, user) says which layers to measure the quantised error of. */
typedef bool quant_eligible_fn(const char *name, uint32_t out, uint32_t in, void *user);
weft_result quant_calibrate(weft_context *ctx, const void *bytes, size_t size, weft_quant_format format,
                            char *const *seqs, uint32_t seq_count, uint32_t total_frames, quant_eligible_fn *eligible,
                            void *eligible_user, quant_layer_stats **out, uint32_t *out_count, uint32_t *frames_seen);
void quant_stats_free(quant_layer_stats *stats, uint32_t count);
const quant_layer_stats *quant_stats_find(const quant_layer_stats *stats, uint32_t count, const char *name);

/* SmoothQuant groups: a LayerNorm and the layers that read its output. */
#define QUANT_MAX_GROUP 3
typedef struct quant_smooth_group {
    char ln[128];
    char layers[QUANT_MAX_GROUP][128];
    uint32_t count;
} quant_smooth_group;

/* The clothtransformer's LayerNorm -> linear groups present in the model (mirrors the forward
 * pass in runtime/model/transformer.c). Returns the count (at most cap). */
uint32_t quant_smooth_groups(const weft_model *m, quant_smooth_group *out, uint32_t cap);

/* Migrates one group inside a safetensors image (h describes it, data is its writable data
 * section) with the calibrated per-channel maxima. Returns false, image untouched, when a tensor
 * is missing, a layer was never observed, or a factor is not finite and positive. */
bool quant_smooth_apply_group(const weft_st_header *h, uint8_t *data, const quant_smooth_group *g,
                              const quant_layer_stats *stats, uint32_t stat_count, float alpha);

#endif
