/* CPU feature detection (cpuid + xgetbv on x86, HWCAP on AArch64) and kernel-level choice. */
#ifndef WEFT_CPU_H
#define WEFT_CPU_H

#include "weft.h"

typedef struct weft_cpu_features {
    /* x86: each flag is set only when the OS also saves the registers (xgetbv). */
    bool sse41, avx2, fma, f16c;
    bool avx512f, avx512dq, avx512bw, avx512vl, avx512vnni, avxvnni, avx512bf16;
    /* AArch64 */
    bool neon, asimddp, fp16;
} weft_cpu_features;

/* Detected once (thread-safe), then cached. */
const weft_cpu_features *weft_cpu_features_get(void);

/* Space-separated list of detected features, e.g. "avx2 fma f16c avx512f". */
const char *weft_cpu_features_string(void);

/* The best level this CPU (and this build) runs. */
weft_isa weft_cpu_best_isa(void);
bool weft_cpu_isa_supported(weft_isa isa);

/* Resolves a requested level: AUTO reads the WEFT_ISA environment variable
 * (scalar|avx2|avx512|neon) and otherwise picks the best. Fails with WEFT_ERROR_UNSUPPORTED
 * when the level (requested or forced) is not available, and WEFT_ERROR_INVALID_ARGUMENT for an
 * unknown WEFT_ISA value. */
weft_result weft_cpu_resolve_isa(weft_isa requested, weft_isa *out_isa);

#endif
