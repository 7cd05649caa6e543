/* Shared helpers for the FNOpt tests: a context, golden-file tensors and small scenes. */
#ifndef FNOPT_TEST_UTIL_H
#define FNOPT_TEST_UTIL_H

#include "fnopt/fnopt_internal.h"
#include "model/model.h"
#include "test.h"
#include "weft/fnopt.h"

#define FNOPT_MODEL_PATH WEFT_SOURCE_DIR "/tools/fnopt/models/fnopt_32.safetensors"
#define FNOPT_DATA(name) WEFT_SOURCE_DIR "/tests/fnopt/data/" name

static inline weft_context *fnopt_test_context(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_result r = weft_context_create(&def, &ctx);
    if (r != WEFT_OK) {
        fprintf(stderr, "context: %s\n", weft_last_error());
        exit(1);
    }
    return ctx;
}

/* Float data of a golden tensor with exactly `count` elements, or NULL (and a failed check). */
static inline const float *fnopt_golden(const weft_model *m, const char *name, uint64_t count)
{
    const weft_tensor *t = weft__model_find(m, name);
    CHECK_MSG(t != NULL, "golden tensor '%s' missing", name);
    if (!t) {
        return NULL;
    }
    CHECK_MSG(t->dtype == WEFT_DTYPE_F32 && t->count == count, "golden tensor '%s': %llu elements, expected %llu",
              name, (unsigned long long)t->count, (unsigned long long)count);
    return t->dtype == WEFT_DTYPE_F32 && t->count == count ? t->data : NULL;
}

/* max |a - b| over n floats, and max |b| for relative checks. */
static inline double fnopt_max_diff(const float *a, const float *b, size_t n, double *max_ref)
{
    double d = 0.0, m = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double e = fabs((double)a[i] - (double)b[i]);
        e = isnan(e) ? INFINITY : e; /* NaN must not pass as a zero difference */
        d = e > d ? e : d;
        m = fabs((double)b[i]) > m ? fabs((double)b[i]) : m;
    }
    if (max_ref) {
        *max_ref = m;
    }
    return d;
}

/* A counting allocator for the context's allocator hook: the step paths must allocate nothing. */
typedef struct counting {
    size_t allocs, live;
} counting;

static inline void *count_alloc(size_t size, size_t alignment, void *user)
{
    counting *c = user;
    c->allocs++;
    c->live++;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static inline void count_free(void *ptr, size_t size, void *user)
{
    (void)size;
    counting *c = user;
    if (ptr) {
        c->live--;
    }
    free(ptr);
}

#endif
