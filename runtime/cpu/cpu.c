/* CPU feature detection and kernel-level choice.
 *
 * x86-64: cpuid leaves 1 and 7 give what the silicon has; xgetbv(XCR0) tells which register
 * files the OS saves on context switch. A feature counts only when both agree (an AVX-512 CPU
 * under an OS that does not save ZMM state must not run AVX-512 code).
 * AArch64: getauxval(AT_HWCAP) reports what the kernel exposes to user space. */
#define _GNU_SOURCE 1 /* getauxval on glibc; harmless elsewhere */
#include "cpu/cpu.h"
#include "core/core.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__)
#include <cpuid.h>
#elif defined(__aarch64__) && defined(__linux__)
#include <sys/auxv.h>
#endif

static weft_cpu_features g_features;
static char g_features_string[256];
static pthread_once_t g_once = PTHREAD_ONCE_INIT;

#if defined(__x86_64__)
static uint64_t read_xcr0(void)
{
    uint32_t lo, hi;
    /* xgetbv with ecx = 0 (XCR0); encoded as bytes so no -mxsave is needed. */
    __asm__ volatile(".byte 0x0f, 0x01, 0xd0" : "=a"(lo), "=d"(hi) : "c"(0));
    return ((uint64_t)hi << 32) | lo;
}

static void detect_x86(weft_cpu_features *f)
{
    unsigned a, b, c, d;
    if (!__get_cpuid(0, &a, &b, &c, &d)) {
        return;
    }
    const unsigned max_leaf = a;
    if (!__get_cpuid(1, &a, &b, &c, &d)) {
        return;
    }
    const bool osxsave = (c >> 27) & 1u;
    const bool cpu_sse41 = (c >> 19) & 1u, cpu_fma = (c >> 12) & 1u, cpu_f16c = (c >> 29) & 1u;
    const bool cpu_avx = (c >> 28) & 1u;

    bool os_ymm = false, os_zmm = false;
    if (osxsave) {
        const uint64_t xcr0 = read_xcr0();
        os_ymm = (xcr0 & 0x6u) == 0x6u;    /* XMM | YMM */
        os_zmm = (xcr0 & 0xe6u) == 0xe6u;  /* XMM | YMM | opmask | ZMM_Hi256 | Hi16_ZMM */
    }
    f->sse41 = cpu_sse41;
    f->fma = cpu_fma && cpu_avx && os_ymm;
    f->f16c = cpu_f16c && cpu_avx && os_ymm;

    if (max_leaf < 7) {
        return;
    }
    __cpuid_count(7, 0, a, b, c, d);
    const unsigned max_sub7 = a;
    f->avx2 = ((b >> 5) & 1u) && cpu_avx && os_ymm;
    f->avx512f = ((b >> 16) & 1u) && os_zmm;
    f->avx512dq = ((b >> 17) & 1u) && f->avx512f;
    f->avx512bw = ((b >> 30) & 1u) && f->avx512f;
    f->avx512vl = ((b >> 31) & 1u) && f->avx512f;
    f->avx512vnni = ((c >> 11) & 1u) && f->avx512f;
    if (max_sub7 >= 1) {
        __cpuid_count(7, 1, a, b, c, d);
        f->avxvnni = ((a >> 4) & 1u) && f->avx2;
        f->avx512bf16 = ((a >> 5) & 1u) && f->avx512f;
    }
}
#endif

#if defined(__aarch64__)
static void detect_arm64(weft_cpu_features *f)
{
    /* Advanced SIMD is mandatory on AArch64 Linux; HWCAP adds the optional extensions. */
    f->neon = true;
#if defined(__linux__)
    const unsigned long hw = getauxval(AT_HWCAP);
    f->fp16 = (hw & (1ul << 9)) && (hw & (1ul << 10)); /* HWCAP_FPHP | HWCAP_ASIMDHP */
    f->asimddp = (hw & (1ul << 20)) != 0;              /* HWCAP_ASIMDDP */
#endif
}
#endif

static void append(char *buf, size_t cap, bool on, const char *name)
{
    if (!on) {
        return;
    }
    size_t len = strlen(buf);
    snprintf(buf + len, cap - len, "%s%s", len ? " " : "", name);
}

static void detect_once(void)
{
    weft_cpu_features f;
    memset(&f, 0, sizeof f);
#if defined(__x86_64__)
    detect_x86(&f);
#elif defined(__aarch64__)
    detect_arm64(&f);
#endif
    char *s = g_features_string;
    const size_t cap = sizeof g_features_string;
    s[0] = '\0';
    append(s, cap, f.sse41, "sse4.1");
    append(s, cap, f.avx2, "avx2");
    append(s, cap, f.fma, "fma");
    append(s, cap, f.f16c, "f16c");
    append(s, cap, f.avx512f, "avx512f");
    append(s, cap, f.avx512dq, "avx512dq");
    append(s, cap, f.avx512bw, "avx512bw");
    append(s, cap, f.avx512vl, "avx512vl");
    append(s, cap, f.avx512vnni, "avx512vnni");
    append(s, cap, f.avxvnni, "avxvnni");
    append(s, cap, f.avx512bf16, "avx512bf16");
    append(s, cap, f.neon, "neon");
    append(s, cap, f.asimddp, "asimddp");
    append(s, cap, f.fp16, "fp16");
    if (!s[0]) {
        snprintf(s, cap, "none");
    }
    g_features = f;
}

const weft_cpu_features *weft_cpu_features_get(void)
{
    pthread_once(&g_once, detect_once);
    return &g_features;
}

const char *weft_cpu_features_string(void)
{
    pthread_once(&g_once, detect_once);
    return g_features_string;
}

bool weft_cpu_isa_supported(weft_isa isa)
{
    const weft_cpu_features *f = weft_cpu_features_get();
    switch (isa) {
    case WEFT_ISA_SCALAR:
        return true;
#if defined(__x86_64__)
    /* The AVX2 table is compiled with -mavx2 -mfma -mf16c; the AVX-512 one adds F/BW/VL/DQ. */
    case WEFT_ISA_AVX2:
        return f->avx2 && f->fma && f->f16c;
    case WEFT_ISA_AVX512:
        return f->avx2 && f->fma && f->f16c && f->avx512f && f->avx512bw && f->avx512vl && f->avx512dq;
#endif
#if defined(__aarch64__)
    case WEFT_ISA_NEON:
        return f->neon;
#endif
    default:
        return false;
    }
}

weft_isa weft_cpu_best_isa(void)
{
    static const weft_isa order[] = {WEFT_ISA_AVX512, WEFT_ISA_AVX2, WEFT_ISA_NEON};
    for (size_t i = 0; i < sizeof order / sizeof order[0]; ++i) {
        if (weft_cpu_isa_supported(order[i])) {
            return order[i];
        }
    }
    return WEFT_ISA_SCALAR;
}

weft_result weft_cpu_resolve_isa(weft_isa requested, weft_isa *out_isa)
{
    if (!out_isa) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_cpu_resolve_isa: out_isa is NULL");
    }
    if ((unsigned)requested >= WEFT_ISA_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "isa %d out of range", (int)requested);
    }
    weft_isa isa = requested;
    if (isa == WEFT_ISA_AUTO) {
        /* Read every time (not cached) so tests and benchmarks can switch levels with setenv. */
        const char *env = getenv("WEFT_ISA");
        if (env && env[0]) {
            static const struct {
                const char *name;
                weft_isa isa;
            } names[] = {{"scalar", WEFT_ISA_SCALAR},
                         {"avx2", WEFT_ISA_AVX2},
                         {"avx512", WEFT_ISA_AVX512},
                         {"neon", WEFT_ISA_NEON},
                         {"auto", WEFT_ISA_AUTO}};
            bool found = false;
            for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
                if (strcmp(env, names[i].name) == 0) {
                    isa = names[i].isa;
                    found = true;
                    break;
                }
            }
            if (!found) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                                  "WEFT_ISA='%.32s' is not one of scalar, avx2, avx512, neon, auto", env);
            }
            if (isa != WEFT_ISA_AUTO && !weft_cpu_isa_supported(isa)) {
                return weft__fail(WEFT_ERROR_UNSUPPORTED, "WEFT_ISA=%s: this CPU or build lacks it (detected: %s)",
                                  env, weft_cpu_features_string());
            }
        }
        if (isa == WEFT_ISA_AUTO) {
            isa = weft_cpu_best_isa();
        }
    } else if (!weft_cpu_isa_supported(isa)) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "isa '%s' is not available: this CPU or build lacks it (detected: %s)",
                          weft_isa_name(isa), weft_cpu_features_string());
    }
    *out_isa = isa;
    return WEFT_OK;
}
