/* The model object: validated tensors from a safetensors file, its metadata, and the
 * architecture config parsed from the metadata key "config".
 *
 * This is the internal API the forward passes use. They validate what they need when a model is
 * loaded (through the architecture table in model.c) or when a garment is created, e.g.
 *
 *   int64_t latents;
 *   const weft_tensor *w;
 *   weft_result r = weft__model_config_int(model, "latent_count", &latents);
 *   if (r == WEFT_OK)
 *       r = WEFT_MODEL_REQUIRE(model, "encoder.proj.weight", WEFT_DTYPE_F32, &w, (uint64_t)latents, 64);
 *
 * Every failure names the tensor or config key in weft_last_error(). */
#ifndef WEFT_MODEL_H
#define WEFT_MODEL_H

#include "core/core.h"
#include "io/safetensors.h"

/* One tensor. data is 64-byte aligned, little-endian, row-major (shape outermost first). */
typedef struct weft_tensor {
    const char *name;
    weft_dtype dtype;
    uint32_t rank;
    uint64_t shape[WEFT_ST_MAX_RANK];   /* unused dims are 0 */
    uint64_t count;                     /* elements (1 for rank 0) */
    uint64_t bytes;                     /* count * dtype size */
    const void *data;                   /* never NULL, even for empty tensors */
} weft_tensor;

typedef enum weft_config_kind {
    WEFT_CONFIG_NUMBER = 0,
    WEFT_CONFIG_BOOL,
    WEFT_CONFIG_STRING,
    WEFT_CONFIG_ARRAY,                  /* a list of numbers */
} weft_config_kind;

typedef struct weft_config_value {
    const char *key;
    weft_config_kind kind;
    double number;                      /* NUMBER; BOOL as 0 or 1 */
    const char *string;                 /* STRING */
    const double *array;                /* ARRAY */
    uint32_t array_count;
} weft_config_value;

/* Architecture hook: run at load for files whose metadata "architecture" matches `name`. */
typedef weft_result weft__arch_validate_fn(const weft_model *model);
typedef struct weft__architecture {
    const char *name;
    bool needs_config;                  /* metadata "config" must be present */
    weft__arch_validate_fn *validate;   /* tensor/config checks; NULL: none beyond the file rules */
} weft__architecture;

enum {
    WEFT__DEPLOY_STRAIN_LIMIT = 1,
    WEFT__DEPLOY_TETHER_DISTANCE = 2,
    WEFT__DEPLOY_PUSH = 4,
    WEFT__DEPLOY_CCD = 8,
};

struct weft_model {
    weft_context *ctx;
    weft_tensor *tensors;               /* sorted by name */
    uint32_t tensor_count;
    weft_st_meta *meta;                 /* file order */
    uint32_t meta_count;
    weft_config_value *config;          /* sorted by key */
    uint32_t config_count;
    double *config_numbers;             /* storage for ARRAY values */
    size_t config_numbers_count;
    char *strings;                      /* names, metadata, config keys and strings */
    size_t strings_size;
    char *config_strings;
    size_t config_strings_size;
    void *data;                         /* every tensor, each at a 64-byte aligned offset */
    size_t data_bytes;
    const weft__architecture *arch;     /* NULL: generic weights file */
    weft_model_info info;
    /* metadata "deploy": the settings the model is meant to run with (weft_model_garment_def) */
    uint32_t deploy_set;                /* WEFT__DEPLOY_* bits: the keys the file gives */
    float deploy_strain_limit, deploy_tether_distance, deploy_push;
    bool deploy_ccd;
};

/* Known architectures (the table in model.c); NULL for an unknown name. */
const weft__architecture *weft__architecture_find(const char *name);

/* Tensor by exact name, or NULL (no error set). */
const weft_tensor *weft__model_find(const weft_model *model, const char *name);

/* Any dimension: matches every size in weft__model_require. */
#define WEFT_DIM_ANY UINT64_MAX

/* The tensor `name` with this dtype and shape (dims[i] may be WEFT_DIM_ANY). Fails with
 * MISSING_TENSOR, TENSOR_DTYPE or TENSOR_SHAPE, naming the tensor and what was expected.
 * *out may be NULL when only the check is wanted. */
weft_result weft__model_require(const weft_model *model, const char *name, weft_dtype dtype, uint32_t rank,
                                const uint64_t *dims, const weft_tensor **out);

/* weft__model_require with the dims listed inline (rank = their count, at least one):
 *   WEFT_MODEL_REQUIRE(m, "head.bias", WEFT_DTYPE_F32, &t, 64) */
#define WEFT_MODEL_REQUIRE(model, name, dtype, out, ...)                                               \
    weft__model_require((model), (name), (dtype),                                                      \
                        (uint32_t)(sizeof((const uint64_t[]){__VA_ARGS__}) / sizeof(uint64_t)),         \
                        (const uint64_t[]){__VA_ARGS__}, (out))

/* Metadata value for `key`, or NULL when absent. */
const char *weft__model_metadata(const weft_model *model, const char *key);

/* Config lookups. Absent keys and values of the wrong kind fail with BAD_METADATA naming the key. */
const weft_config_value *weft__model_config_find(const weft_model *model, const char *key);
weft_result weft__model_config_number(const weft_model *model, const char *key, double *out);
/* An integral number in [-2^53, 2^53]. */
weft_result weft__model_config_int(const weft_model *model, const char *key, int64_t *out);
/* An integer in [min, max]: the usual check for a layer width or a count. */
weft_result weft__model_config_u32(const weft_model *model, const char *key, uint32_t min, uint32_t max,
                                   uint32_t *out);
weft_result weft__model_config_bool(const weft_model *model, const char *key, bool *out);
weft_result weft__model_config_string(const weft_model *model, const char *key, const char **out);
weft_result weft__model_config_array(const weft_model *model, const char *key, const double **out,
                                     uint32_t *out_count);

#endif
