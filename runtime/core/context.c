#include "core/core.h"
#include "cpu/cpu.h"

#include <stdio.h>
#include <stdlib.h>

#ifndef WEFT_VERSION_STRING_BUILD
#define WEFT_VERSION_STRING_BUILD "0.0.0"
#endif

static void *default_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}

static void default_free(void *ptr, size_t size, void *user)
{
    (void)size;
    (void)user;
    free(ptr);
}

const char *weft_version_string(void) { return WEFT_VERSION_STRING_BUILD; }

const char *weft_isa_name(weft_isa isa)
{
    switch (isa) {
    case WEFT_ISA_AUTO: return "auto";
    case WEFT_ISA_SCALAR: return "scalar";
    case WEFT_ISA_AVX2: return "avx2";
    case WEFT_ISA_AVX512: return "avx512";
    case WEFT_ISA_NEON: return "neon";
    default: return "unknown";
    }
}

const char *weft_config_string(void)
{
    static _Thread_local char buf[512];
    weft_isa isa = WEFT_ISA_SCALAR;
    if (weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa) != WEFT_OK) {
        isa = weft_cpu_best_isa();
    }
#if defined(__clang__)
    const char *compiler = "clang-" __clang_version__;
#elif defined(__GNUC__)
    const char *compiler = "gcc-" __VERSION__;
#else
    const char *compiler = "unknown-compiler";
#endif
    snprintf(buf, sizeof buf, "weft %s %s isa=%s (%s)", WEFT_VERSION_STRING_BUILD, compiler, weft_isa_name(isa),
             weft_cpu_features_string());
    return buf;
}

weft_context_def weft_default_context_def(void)
{
    weft_context_def def = {0};
    def.allocator.alloc = default_alloc;
    def.allocator.free = default_free;
    def.max_workers = 1;
    def.isa = WEFT_ISA_AUTO;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

weft_result weft_context_create(const weft_context_def *def, weft_context **out_context)
{
    if (!def || !out_context) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_context_create: def and out_context must not be NULL");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_context_create: def was not initialised with weft_default_context_def()");
    }
    if ((def->allocator.alloc == NULL) != (def->allocator.free == NULL)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_context_create: allocator needs both alloc and free");
    }
    if (def->max_workers == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_context_create: max_workers must be >= 1");
    }
    if ((unsigned)def->isa >= WEFT_ISA_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_context_create: isa %d out of range", (int)def->isa);
    }
    weft_isa isa;
    weft_result r = weft_cpu_resolve_isa(def->isa, &isa);
    if (r != WEFT_OK) {
        return r;
    }
    const weft_kernels *kernels = weft_kernels_for_isa(isa);
    if (!kernels) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_context_create: no kernels for isa '%s' in this build",
                          weft_isa_name(isa));
    }
    weft_allocator allocator = def->allocator;
    if (!allocator.alloc) {
        allocator.alloc = default_alloc;
        allocator.free = default_free;
    }
    weft_context *ctx = allocator.alloc(sizeof *ctx, WEFT_ALIGN, allocator.user);
    if (!ctx) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_context_create: allocator returned NULL");
    }
    *ctx = (weft_context){
        .allocator = allocator,
        .parallel_for = def->parallel_for,
        .parallel_for_user = def->parallel_for_user,
        .max_workers = def->max_workers,
        .isa = isa,
        .kernels = kernels,
    };
    *out_context = ctx;
    return WEFT_OK;
}

void weft_context_destroy(weft_context *context)
{
    if (!context) {
        return;
    }
    weft_allocator a = context->allocator;
    a.free(context, sizeof *context, a.user);
}

weft_isa weft_context_isa(const weft_context *context) { return context ? context->isa : WEFT_ISA_SCALAR; }
