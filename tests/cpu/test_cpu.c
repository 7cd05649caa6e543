/* CPU feature detection and level choice: WEFT_ISA forcing, unknown and unavailable levels,
 * the feature string, the kernel tables, thread-safe first detection, and (on x86 Linux) the
 * cpuid/xgetbv result against the kernel's own /proc/cpuinfo flags. */
#define _POSIX_C_SOURCE 200809L /* setenv, unsetenv */
#include "test.h"

#include "core/core.h"
#include "cpu/cpu.h"
#include "kernels/kernels.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

static bool has_word(const char *list, const char *word)
{
    const size_t n = strlen(word);
    for (const char *p = list; (p = strstr(p, word)) != NULL; p += n) {
        const bool start = p == list || p[-1] == ' ';
        const bool end = p[n] == '\0' || p[n] == ' ' || p[n] == '\n';
        if (start && end) {
            return true;
        }
    }
    return false;
}

static void test_feature_string_matches_flags(void)
{
    const weft_cpu_features *f = weft_cpu_features_get();
    const char *s = weft_cpu_features_string();
    CHECK(s != NULL && s[0] != '\0');
    printf("features: %s\n", s);
    CHECK_EQ_INT(has_word(s, "avx2"), f->avx2);
    CHECK_EQ_INT(has_word(s, "fma"), f->fma);
    CHECK_EQ_INT(has_word(s, "f16c"), f->f16c);
    CHECK_EQ_INT(has_word(s, "avx512f"), f->avx512f);
    CHECK_EQ_INT(has_word(s, "avx512bw"), f->avx512bw);
    CHECK_EQ_INT(has_word(s, "avx512vl"), f->avx512vl);
    CHECK_EQ_INT(has_word(s, "avx512vnni"), f->avx512vnni);
    CHECK_EQ_INT(has_word(s, "avxvnni"), f->avxvnni);
    CHECK_EQ_INT(has_word(s, "avx512bf16"), f->avx512bf16);
    CHECK_EQ_INT(has_word(s, "neon"), f->neon);
    CHECK_EQ_INT(has_word(s, "asimddp"), f->asimddp);
    /* dependent features never appear without their base */
    CHECK(!f->avx512bw || f->avx512f);
    CHECK(!f->avx512vnni || f->avx512f);
    CHECK(!f->avxvnni || f->avx2);
#if defined(__x86_64__)
    CHECK(!f->neon && !f->asimddp);
#elif defined(__aarch64__)
    CHECK(f->neon);
    CHECK(!f->avx2 && !f->avx512f);
#endif
    CHECK(strstr(weft_config_string(), s) != NULL);
}

#if defined(__x86_64__) && defined(__linux__)
/* The kernel reports a flag only when it also enables the state, like our xgetbv check. */
static void test_x86_against_proc_cpuinfo(void)
{
    FILE *fp = fopen("/proc/cpuinfo", "r");
    if (!fp) {
        printf("no /proc/cpuinfo; skipped\n");
        CHECK(true);
        return;
    }
    static char line[8192];
    bool found = false;
    while (fgets(line, sizeof line, fp)) {
        if (strncmp(line, "flags", 5) == 0) {
            found = true;
            break;
        }
    }
    fclose(fp);
    CHECK(found);
    if (!found) {
        return;
    }
    const char *flags = strchr(line, ':');
    CHECK(flags != NULL);
    if (!flags) {
        return;
    }
    const weft_cpu_features *f = weft_cpu_features_get();
    CHECK_EQ_INT(f->sse41, has_word(flags, "sse4_1"));
    CHECK_EQ_INT(f->avx2, has_word(flags, "avx2"));
    CHECK_EQ_INT(f->fma, has_word(flags, "fma"));
    CHECK_EQ_INT(f->f16c, has_word(flags, "f16c"));
    CHECK_EQ_INT(f->avx512f, has_word(flags, "avx512f"));
    CHECK_EQ_INT(f->avx512dq, has_word(flags, "avx512dq"));
    CHECK_EQ_INT(f->avx512bw, has_word(flags, "avx512bw"));
    CHECK_EQ_INT(f->avx512vl, has_word(flags, "avx512vl"));
    CHECK_EQ_INT(f->avx512vnni, has_word(flags, "avx512_vnni"));
    CHECK_EQ_INT(f->avxvnni, has_word(flags, "avx_vnni"));
    CHECK_EQ_INT(f->avx512bf16, has_word(flags, "avx512_bf16"));
}
#endif

static void test_env_forcing(void)
{
    weft_isa isa = WEFT_ISA_AUTO;
    unsetenv("WEFT_ISA");
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_OK);
    CHECK(isa == weft_cpu_best_isa());
    CHECK(isa != WEFT_ISA_AUTO);

    setenv("WEFT_ISA", "scalar", 1);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_OK);
    CHECK(isa == WEFT_ISA_SCALAR);
    /* a context made with AUTO follows the variable */
    weft_context *ctx = NULL;
    weft_context_def def = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    if (ctx) {
        CHECK(weft_context_isa(ctx) == WEFT_ISA_SCALAR);
        CHECK(ctx->kernels == weft_kernels_for_isa(WEFT_ISA_SCALAR));
        weft_context_destroy(ctx);
    }

    setenv("WEFT_ISA", "auto", 1);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_OK);
    CHECK(isa == weft_cpu_best_isa());

    /* every level the CPU has can be forced; the others fail as unsupported */
    static const struct {
        const char *name;
        weft_isa isa;
    } levels[] = {{"avx2", WEFT_ISA_AVX2}, {"avx512", WEFT_ISA_AVX512}, {"neon", WEFT_ISA_NEON}};
    for (size_t i = 0; i < sizeof levels / sizeof levels[0]; ++i) {
        setenv("WEFT_ISA", levels[i].name, 1);
        isa = WEFT_ISA_COUNT;
        if (weft_cpu_isa_supported(levels[i].isa)) {
            CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_OK);
            CHECK(isa == levels[i].isa);
            const weft_kernels *k = weft_kernels_for_isa(levels[i].isa);
            CHECK(k != NULL && k->isa == levels[i].isa);
        } else {
            CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_ERROR_UNSUPPORTED);
            CHECK(isa == WEFT_ISA_COUNT); /* untouched on failure */
            CHECK(strstr(weft_last_error(), "WEFT_ISA") != NULL);
            CHECK(weft_kernels_for_isa(levels[i].isa) == NULL);
            weft_context *c2 = NULL;
            CHECK_RESULT(weft_context_create(&def, &c2), WEFT_ERROR_UNSUPPORTED);
            CHECK(c2 == NULL);
        }
    }
#if defined(__x86_64__)
    setenv("WEFT_ISA", "neon", 1);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_ERROR_UNSUPPORTED);
#elif defined(__aarch64__)
    setenv("WEFT_ISA", "avx512", 1);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_ERROR_UNSUPPORTED);
#endif
    unsetenv("WEFT_ISA");
}

static void test_bad_values(void)
{
    weft_isa isa = WEFT_ISA_COUNT;
    static const char *bad[] = {"AVX2", "sse", "avx512 ", "x", "scalar2"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        setenv("WEFT_ISA", bad[i], 1);
        CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_ERROR_INVALID_ARGUMENT);
        CHECK(isa == WEFT_ISA_COUNT);
        CHECK(strstr(weft_last_error(), "WEFT_ISA") != NULL);
    }
    /* an explicit level ignores the variable */
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_SCALAR, &isa), WEFT_OK);
    CHECK(isa == WEFT_ISA_SCALAR);
    unsetenv("WEFT_ISA");
    CHECK_RESULT(weft_cpu_resolve_isa((weft_isa)99, &isa), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    /* empty means unset */
    setenv("WEFT_ISA", "", 1);
    CHECK_RESULT(weft_cpu_resolve_isa(WEFT_ISA_AUTO, &isa), WEFT_OK);
    CHECK(isa == weft_cpu_best_isa());
    unsetenv("WEFT_ISA");
}

static void test_explicit_levels(void)
{
    for (int i = WEFT_ISA_SCALAR; i < WEFT_ISA_COUNT; ++i) {
        const weft_isa want = (weft_isa)i;
        weft_isa isa = WEFT_ISA_COUNT;
        const weft_kernels *k = weft_kernels_for_isa(want);
        if (weft_cpu_isa_supported(want)) {
            CHECK_RESULT(weft_cpu_resolve_isa(want, &isa), WEFT_OK);
            CHECK(isa == want);
            CHECK(k != NULL);
            if (k) {
                CHECK(k->isa == want);
                CHECK(k->gemm && k->softmax_rows && k->layernorm && k->rmsnorm && k->gelu && k->silu && k->swiglu &&
                      k->posembed && k->csr_aggregate && k->attention);
            }
            weft_context_def def = weft_default_context_def();
            def.isa = want;
            weft_context *ctx = NULL;
            CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
            if (ctx) {
                CHECK(weft_context_isa(ctx) == want);
                weft_context_destroy(ctx);
            }
        } else {
            CHECK_RESULT(weft_cpu_resolve_isa(want, &isa), WEFT_ERROR_UNSUPPORTED);
            CHECK(isa == WEFT_ISA_COUNT);
            CHECK(k == NULL);
        }
    }
    CHECK(weft_cpu_isa_supported(WEFT_ISA_SCALAR));
    CHECK(weft_cpu_isa_supported(weft_cpu_best_isa()));
    CHECK(!weft_cpu_isa_supported(WEFT_ISA_AUTO));
    CHECK(!weft_cpu_isa_supported(WEFT_ISA_COUNT));
#if defined(__x86_64__)
    CHECK(!weft_cpu_isa_supported(WEFT_ISA_NEON));
    /* this machine class (x86-64 with AVX2) must not silently fall back to scalar */
    if (weft_cpu_features_get()->avx2 && weft_cpu_features_get()->fma && weft_cpu_features_get()->f16c) {
        CHECK(weft_cpu_best_isa() != WEFT_ISA_SCALAR);
    }
#endif
}

enum { NTHREADS = 8 };
static const weft_cpu_features *g_seen[NTHREADS];
static const char *g_seen_s[NTHREADS];

static void *probe(void *arg)
{
    const size_t i = (size_t)arg;
    g_seen[i] = weft_cpu_features_get();
    g_seen_s[i] = weft_cpu_features_string();
    return NULL;
}

/* Runs in its own process image first (ctest runs each case in one process, but this case is
 * listed first so detection has not happened yet): all threads must see one result. */
static void test_concurrent_first_detection(void)
{
    pthread_t th[NTHREADS];
    int started = 0;
    for (size_t i = 0; i < NTHREADS; ++i) {
        if (pthread_create(&th[i], NULL, probe, (void *)i) == 0) {
            started++;
        } else {
            break;
        }
    }
    for (int i = 0; i < started; ++i) {
        pthread_join(th[i], NULL);
    }
    CHECK(started > 1);
    for (int i = 0; i < started; ++i) {
        CHECK(g_seen[i] == weft_cpu_features_get());
        CHECK(g_seen_s[i] != NULL && strcmp(g_seen_s[i], weft_cpu_features_string()) == 0);
    }
}

#if defined(__x86_64__) && defined(__linux__)
#define X86_CASES TEST_CASE(test_x86_against_proc_cpuinfo),
#else
#define X86_CASES
#endif

TEST_MAIN(TEST_CASE(test_concurrent_first_detection), TEST_CASE(test_feature_string_matches_flags), X86_CASES
          TEST_CASE(test_env_forcing), TEST_CASE(test_bad_values), TEST_CASE(test_explicit_levels))
