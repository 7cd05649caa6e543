/* NumPy .npz archives (a zip of .npy arrays) and the SMPL model loader built on them.
 * Part of weft_assets. Every reader validates the whole input before anything is used and
 * returns WEFT_ERROR_FORMAT (or IO / OUT_OF_MEMORY) with a message naming the entry. */
#ifndef WEFT_ASSETS_NPZ_H
#define WEFT_ASSETS_NPZ_H

#include "weft.h"
#include "weft/body.h"
#include "weft/motion.h"

#define WEFT_NPY_MAX_DIMS 8

typedef enum weft_npy_dtype {
    WEFT_NPY_UNSUPPORTED = 0, /* well-formed but not numeric (strings, objects, big-endian) */
    WEFT_NPY_F4,
    WEFT_NPY_F8,
    WEFT_NPY_I1,
    WEFT_NPY_U1,
    WEFT_NPY_I2,
    WEFT_NPY_U2,
    WEFT_NPY_I4,
    WEFT_NPY_U4,
    WEFT_NPY_I8,
    WEFT_NPY_U8,
    WEFT_NPY_B1
} weft_npy_dtype;

typedef struct weft_npy_array {
    char name[128];           /* entry name without ".npy" */
    char descr[16];           /* the dtype string as written, e.g. "<f8" */
    weft_npy_dtype dtype;
    uint32_t item_size;
    uint32_t ndim;
    uint64_t shape[WEFT_NPY_MAX_DIMS];
    uint64_t count;           /* product of shape */
    bool fortran_order;
    const uint8_t *data;      /* count * item_size bytes, little-endian */
} weft_npy_array;

typedef struct weft_npz weft_npz;

/* Parses one .npy image (header and payload size) without copying. `name` is used in errors. */
weft_result weft_npy_parse(const void *bytes, size_t size, const char *name, weft_npy_array *out);

/* Reads a whole archive; the bytes are copied (memory variant) and may be freed afterwards. */
weft_result weft_npz_read_file(weft_context *context, const char *path, weft_npz **out_npz);
weft_result weft_npz_read_memory(weft_context *context, const void *bytes, size_t size, weft_npz **out_npz);
void weft_npz_destroy(weft_npz *npz);
uint32_t weft_npz_count(const weft_npz *npz);
const weft_npy_array *weft_npz_array(const weft_npz *npz, uint32_t index);
/* NULL when absent. */
const weft_npy_array *weft_npz_find(const weft_npz *npz, const char *name);

/* Converts a numeric array to float32 in C (row-major) order whatever its storage order.
 * out has count floats. Integers convert exactly up to 2^24. Non-finite -> NOT_FINITE. */
weft_result weft_npy_to_f32(const weft_npy_array *array, float *out, uint64_t count);
/* Integer (or integral float) array to int64 in C order. */
weft_result weft_npy_to_i64(const weft_npy_array *array, int64_t *out, uint64_t count);

/* weft_smpl_load_npz_file / _memory: include/weft/motion.h. */
/* Same, from an archive already read. */
weft_result weft_smpl_body_from_npz(weft_context *context, const weft_npz *npz, weft_body **out_body);

#endif
