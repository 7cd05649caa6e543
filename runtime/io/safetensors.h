/* safetensors: reader with full validation, and a writer.
 *
 * File layout: u64 little-endian N, N bytes of UTF-8 JSON header, then the data section.
 * The header maps tensor names to {"dtype", "shape", "data_offsets": [begin, end]} with offsets
 * relative to the data section, plus an optional "__metadata__" object of string values.
 * docs/MODEL_FORMAT.md lists every rule the reader enforces and the result each one returns.
 *
 * The reader works in two steps so that files can be streamed: weft__st_header_length() checks
 * the first 8 bytes against the file size, weft__st_parse_header() validates the JSON against
 * the size of the data section. Nothing is trusted until both succeed. */
#ifndef WEFT_IO_SAFETENSORS_H
#define WEFT_IO_SAFETENSORS_H

#include "core/core.h"

#define WEFT_ST_MAX_RANK 8u
#define WEFT_ST_MAX_HEADER 100000000u  /* bytes, the reference reader's cap */
#define WEFT_ST_MAX_DEPTH 16u          /* JSON nesting; a valid header needs 3 */
#define WEFT_ST_MAX_EXACT 9007199254740992.0 /* 2^53: integers at or above are not exact in JSON */

typedef enum weft_dtype {
    WEFT_DTYPE_F32 = 0,
    WEFT_DTYPE_F16,
    WEFT_DTYPE_BF16,
    WEFT_DTYPE_I8,
    WEFT_DTYPE_I32,
    WEFT_DTYPE_U8,
    WEFT_DTYPE_COUNT
} weft_dtype;

/* Bytes per element (0 for an invalid dtype). */
size_t weft__dtype_size(weft_dtype dtype);
/* The safetensors spelling, e.g. "BF16"; "?" for an invalid dtype. */
const char *weft__dtype_name(weft_dtype dtype);
/* Parses a safetensors dtype string; false for anything weft does not read. */
bool weft__dtype_parse(const char *name, weft_dtype *out);

typedef struct weft_st_entry {
    const char *name;                   /* points into weft_st_header.strings */
    weft_dtype dtype;
    uint32_t rank;
    uint64_t shape[WEFT_ST_MAX_RANK];   /* outermost first; unused dims are 0 */
    uint64_t count;                     /* elements: product of shape (1 for rank 0) */
    uint64_t begin, end;                /* byte range inside the data section */
} weft_st_entry;

typedef struct weft_st_meta {
    const char *key;                    /* points into weft_st_header.strings */
    const char *value;
} weft_st_meta;

/* A validated header. Entries are sorted by begin offset (so they tile the data section in
 * order); metadata keeps file order. All memory comes from the context allocator. */
typedef struct weft_st_header {
    weft_st_entry *entries;
    uint32_t entry_count;
    weft_st_meta *meta;
    uint32_t meta_count;
    char *strings;                      /* every name, key and value, NUL-terminated */
    size_t strings_size;
    uint64_t data_size;                 /* bytes in the data section */
} weft_st_header;

/* Reads N from the first bytes of a file of `file_size` bytes (`prefix` holds
 * min(file_size, 8) bytes). Fails with FILE_TRUNCATED when the file has fewer than 8 bytes and
 * HEADER_TOO_LARGE when N is over the cap or does not fit in the file. */
weft_result weft__st_header_length(const uint8_t *prefix, uint64_t file_size, uint64_t *out_header_size);

/* Validates the JSON header (`json`, `size` bytes, not NUL-terminated) of a file whose data
 * section has `data_size` bytes. On success *out owns its memory (free with
 * weft__st_header_free); on failure *out is untouched and the last error names the tensor. */
weft_result weft__st_parse_header(const weft_context *ctx, const char *json, size_t size, uint64_t data_size,
                                  weft_st_header *out);
void weft__st_header_free(const weft_context *ctx, weft_st_header *header);

/* Screens JSON text before cJSON parses it: starts with '{', valid UTF-8, no NUL byte or
 * escaped NUL (cJSON would cut a string short there), nesting within WEFT_ST_MAX_DEPTH so the
 * recursive parser stays shallow. Fails with `code`, the message starting with `what`. */
weft_result weft__json_screen(const uint8_t *text, size_t size, weft_result code, const char *what);

/* Both steps over a whole file in memory. *out_data points into `bytes` (the data section). */
weft_result weft__st_parse_memory(const weft_context *ctx, const void *bytes, size_t size, weft_st_header *out,
                                  const uint8_t **out_data);

/* ---------------------------------------------------------------------------------------- */
/* Writer (runtime/io/safetensors_write.c): for the quantiser, tools and tests.               */

typedef struct weft_st_tensor_in {
    const char *name;                   /* UTF-8, unique, not "__metadata__" */
    weft_dtype dtype;
    uint32_t rank;                      /* <= WEFT_ST_MAX_RANK */
    const uint64_t *shape;              /* rank dims; may be NULL when rank is 0 */
    const void *data;                   /* count * dtype size bytes, little-endian */
} weft_st_tensor_in;

/* Writes a file the reader accepts: header padded with spaces so the data starts 8-aligned,
 * tensors laid out by descending element size then name (each aligned to its element size),
 * metadata as given (keys unique, values UTF-8 strings). The byte image is returned in
 * *out_bytes (weft__alloc'd: release with weft__free(ctx, *out_bytes, *out_size)). */
weft_result weft__st_write_memory(const weft_context *ctx, const weft_st_tensor_in *tensors, uint32_t tensor_count,
                                  const weft_st_meta *meta, uint32_t meta_count, void **out_bytes,
                                  size_t *out_size);
/* Same image written to `path` through a temporary file renamed into place, so a failed write
 * never leaves a partial file under the final name. */
weft_result weft__st_write_file(const weft_context *ctx, const char *path, const weft_st_tensor_in *tensors,
                                uint32_t tensor_count, const weft_st_meta *meta, uint32_t meta_count);

#endif
