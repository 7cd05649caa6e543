/* Internal services every runtime concept uses: allocation through the context's allocator,
 * error reporting into the thread's last-error buffer, and the parallel-for hook. */
#ifndef WEFT_CORE_H
#define WEFT_CORE_H

#include "weft.h"
#include "kernels/kernels.h"

#include <stdarg.h>

#define WEFT_DEF_COOKIE 0x57454654u /* "WEFT": marks a def made by a weft_default_*_def() */
#define WEFT_ALIGN 64u              /* alignment of every weft buffer (a cache line, one zmm) */

struct weft_context {
    weft_allocator allocator;
    weft_parallel_for_fn *parallel_for;
    void *parallel_for_user;
    uint32_t max_workers;
    weft_isa isa;
    const weft_kernels *kernels;
};

/* Allocation: 64-byte aligned, zero-filled; NULL on failure (and the last error is set). */
void *weft__alloc(const weft_context *ctx, size_t size);
void weft__free(const weft_context *ctx, void *ptr, size_t size);

/* Sets the calling thread's last error and returns `result`, so callers can write
 *   return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "tensor '%s': ...", name); */
weft_result weft__fail(weft_result result, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void weft__clear_error(void);

/* Runs task over [0, count) through the host's job hook, or serially. */
void weft__parallel_for(const weft_context *ctx, weft_task_fn *task, uint32_t count, uint32_t min_chunk,
                        void *task_context);

/* Checked 64-bit arithmetic for sizes read from files. Return false on overflow. */
static inline bool weft__mul_u64(uint64_t a, uint64_t b, uint64_t *out) { return !__builtin_mul_overflow(a, b, out); }
static inline bool weft__add_u64(uint64_t a, uint64_t b, uint64_t *out) { return !__builtin_add_overflow(a, b, out); }

/* True when all n floats are finite. */
bool weft__all_finite(const float *x, size_t n);

/* Index of the first of n floats that is not finite or beyond +-WEFT_MAX_COORDINATE, or
 * SIZE_MAX when all are within range. */
size_t weft__first_outside(const float *x, size_t n);

/* Monotonic clock in milliseconds. */
double weft__now_ms(void);

#endif
