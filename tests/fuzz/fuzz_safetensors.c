/* Fuzz target for the model loader: arbitrary bytes -> weft_model_load_memory.
 *
 * Accepted inputs are exercised further: every tensor byte is read (so ASan sees any bad
 * pointer), lookups and config accessors run on every name, and the model is written back with
 * weft's writer and reloaded, which must give the same tensors. Rejected inputs must explain
 * themselves in weft_last_error(). Any violated property aborts, which the fuzzer reports.
 *
 * Built two ways (tests/fuzz/CMakeLists.txt): with libFuzzer (WEFT_BUILD_FUZZ=ON, clang), and as
 * the ctest fuzz.safetensors_replay together with replay_main.c. */
#include "io/safetensors.h"
#include "model/model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(cond)                                                                         \
    do {                                                                                      \
        if (!(cond)) {                                                                        \
            fprintf(stderr, "fuzz_safetensors: property failed: %s (%s:%d)\n", #cond, __FILE__, \
                    __LINE__);                                                                \
            abort();                                                                          \
        }                                                                                     \
    } while (0)

static weft_context *context(void)
{
    static weft_context *ctx;
    if (!ctx) {
        weft_context_def def = weft_default_context_def();
        REQUIRE(weft_context_create(&def, &ctx) == WEFT_OK);
    }
    return ctx;
}

static void same_tensors(const weft_model *a, const weft_model *b)
{
    REQUIRE(a->tensor_count == b->tensor_count);
    for (uint32_t i = 0; i < a->tensor_count; ++i) {
        const weft_tensor *x = &a->tensors[i], *y = &b->tensors[i];
        REQUIRE(strcmp(x->name, y->name) == 0);
        REQUIRE(x->dtype == y->dtype && x->rank == y->rank && x->bytes == y->bytes);
        REQUIRE(memcmp(x->shape, y->shape, sizeof x->shape) == 0);
        REQUIRE(memcmp(x->data, y->data, (size_t)x->bytes) == 0);
    }
    REQUIRE(a->meta_count == b->meta_count);
    for (uint32_t i = 0; i < a->meta_count; ++i) {
        REQUIRE(strcmp(a->meta[i].value, weft__model_metadata(b, a->meta[i].key)) == 0);
    }
}

static void exercise(weft_context *ctx, const weft_model *m)
{
    weft_model_info info = weft_model_get_info(m);
    REQUIRE(info.name && info.architecture && info.tensor_count == m->tensor_count);
    uint64_t bytes = 0;
    unsigned sum = 0;
    for (uint32_t i = 0; i < m->tensor_count; ++i) {
        const weft_tensor *t = &m->tensors[i];
        REQUIRE(((uintptr_t)t->data & (WEFT_ALIGN - 1)) == 0);
        REQUIRE(weft__model_find(m, t->name) == t);
        REQUIRE(weft__model_require(m, t->name, t->dtype, t->rank, t->shape, NULL) == WEFT_OK);
        const uint8_t *p = t->data;
        for (uint64_t k = 0; k < t->bytes; ++k) {
            sum += p[k];
        }
        bytes += t->bytes;
    }
    REQUIRE(bytes == info.weight_bytes);
    for (uint32_t i = 0; i < m->config_count; ++i) {
        const weft_config_value *c = &m->config[i];
        REQUIRE(weft__model_config_find(m, c->key) == c);
        double d;
        int64_t v;
        REQUIRE((weft__model_config_number(m, c->key, &d) == WEFT_OK) == (c->kind == WEFT_CONFIG_NUMBER));
        (void)weft__model_config_int(m, c->key, &v);
    }

    /* Write back and reload: the writer must accept whatever the reader accepted. */
    weft_st_tensor_in *in = m->tensor_count ? malloc(m->tensor_count * sizeof *in) : NULL;
    REQUIRE(m->tensor_count == 0 || in);
    for (uint32_t i = 0; i < m->tensor_count; ++i) {
        const weft_tensor *t = &m->tensors[i];
        in[i] = (weft_st_tensor_in){t->name, t->dtype, t->rank, t->shape, t->data};
    }
    void *image = NULL;
    size_t size = 0;
    weft_result r = weft__st_write_memory(ctx, in, m->tensor_count, m->meta, m->meta_count, &image, &size);
    free(in);
    if (r == WEFT_ERROR_HEADER_TOO_LARGE) {
        return; /* escapes can grow a header near the cap past it */
    }
    REQUIRE(r == WEFT_OK);
    weft_model *again = NULL;
    r = weft_model_load_memory(ctx, image, size, &again);
    REQUIRE(r == WEFT_OK);
    same_tensors(m, again);
    weft_model_destroy(again);
    weft__free(ctx, image, size);
    (void)sum;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const uint8_t empty[1];
    weft_context *ctx = context();
    weft_model *m = NULL;
    weft__clear_error();
    weft_result r = weft_model_load_memory(ctx, size ? data : empty, size, &m);
    if (r == WEFT_OK) {
        REQUIRE(m != NULL);
        exercise(ctx, m);
        weft_model_destroy(m);
    } else {
        REQUIRE(m == NULL);
        REQUIRE(r > WEFT_OK && r < WEFT_RESULT_COUNT);
        REQUIRE(weft_last_error()[0] != '\0');
    }
    return 0;
}
