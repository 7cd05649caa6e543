#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "core/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

void *weft__alloc(const weft_context *ctx, size_t size)
{
    if (size == 0) {
        size = 1;
    }
    size_t rounded = (size + WEFT_ALIGN - 1) & ~(size_t)(WEFT_ALIGN - 1);
    if (rounded < size) {
        weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "allocation of %zu bytes overflows", size);
        return NULL;
    }
    void *p = ctx->allocator.alloc(rounded, WEFT_ALIGN, ctx->allocator.user);
    if (!p) {
        weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "allocator returned NULL for %zu bytes", rounded);
        return NULL;
    }
    memset(p, 0, rounded);
    return p;
}

void weft__free(const weft_context *ctx, void *ptr, size_t size)
{
    if (!ptr) {
        return;
    }
    if (size == 0) {
        size = 1;
    }
    size_t rounded = (size + WEFT_ALIGN - 1) & ~(size_t)(WEFT_ALIGN - 1);
    ctx->allocator.free(ptr, rounded, ctx->allocator.user);
}

void weft__parallel_for(const weft_context *ctx, weft_task_fn *task, uint32_t count, uint32_t min_chunk,
                        void *task_context)
{
    if (count == 0) {
        return;
    }
    if (ctx->parallel_for && count > min_chunk) {
        ctx->parallel_for(task, count, min_chunk ? min_chunk : 1, task_context, ctx->parallel_for_user);
    } else {
        task(0, count, 0, task_context);
    }
}

bool weft__all_finite(const float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        if (!isfinite(x[i])) {
            return false;
        }
    }
    return true;
}

size_t weft__first_outside(const float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        if (!(fabsf(x[i]) <= WEFT_MAX_COORDINATE)) {
            return i;
        }
    }
    return SIZE_MAX;
}

double weft__now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}
