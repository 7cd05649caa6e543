/* weft bench kernels: single-thread throughput of every fp32 kernel of every level this CPU
 * runs, at the cloth model's shapes, next to the measured peak of the same level (an fp32 FMA
 * loop on independent register chains) and the int8 dot-product peaks the quantised path can
 * reach. Each kernel's ratio to its level's fp32 peak says how much of the machine it uses. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "weft.h"

#include "cpu/cpu.h"
#include "kernels/kernels.h"
#include "kernels/kernels_internal.h"

#include "support_cli.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int weft_bench_kernels(int argc, char **argv); /* the CLI registry declares it in main.c */
extern const char weft_bench_kernels_help[];
const char weft_bench_kernels_help[] =
    "fp32 kernel throughput per ISA vs measured FMA / int8-dot peaks [--quick] [--isa NAME] [--json|--md]";

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* ---------------------------------------------------------------------------------------- */
/* Timing                                                                                    */

typedef struct bench_job bench_job;
typedef void bench_run_fn(const bench_job *job);

typedef enum job_kind { JOB_GEMM, JOB_ATTN, JOB_LAYERNORM, JOB_CSR, JOB_GELU, JOB_SOFTMAX } job_kind;

struct bench_job {
    const char *name;
    const char *shape;
    job_kind kind;
    uint32_t a, b, c, d; /* shape parameters, meaning per kind */
    double flops;        /* per call, by the flop model documented in print_notes() */
    double bytes;        /* minimum bytes moved per call */
    /* bound at run time */
    const weft_kernels *k;
    float *x, *y, *z, *w, *scratch;
    uint32_t *rowptr, *col;
    uint8_t *mask;
};

static void run_job(const bench_job *j)
{
    switch (j->kind) {
    case JOB_GEMM:
        j->k->gemm(j->a, j->b, j->c, j->x, j->c, j->w, j->c, j->z, j->y, j->b, WEFT_ACT_NONE, false);
        break;
    case JOB_ATTN: {
        const uint32_t width = j->c * j->d;
        j->k->attention(j->x, width, j->w, width, j->z, width, j->a, j->b, j->c, j->d, 1.0f / sqrtf((float)j->d),
                        NULL, NULL, j->y, width, j->scratch);
        break;
    }
    case JOB_LAYERNORM:
        j->k->layernorm(j->x, j->y, j->a, j->b, j->b, j->w, j->z, 1e-5f);
        break;
    case JOB_CSR:
        j->k->csr_aggregate(j->rowptr, j->col, j->a, j->x, j->c, j->c, j->y, j->c, true);
        break;
    case JOB_GELU:
        memcpy(j->y, j->x, (size_t)j->a * sizeof(float));
        j->k->gelu(j->y, j->a);
        break;
    case JOB_SOFTMAX:
        memcpy(j->y, j->x, (size_t)j->a * j->b * sizeof(float));
        j->k->softmax_rows(j->y, j->a, j->b, j->b);
        break;
    }
}

/* Best time per call over `trials` trials of enough calls to fill min_time / trials each. */
static double time_best(const bench_job *j, double min_time)
{
    const int trials = 5;
    run_job(j); /* warm caches and page in the buffers */
    double t0 = now_s();
    run_job(j);
    double one = now_s() - t0;
    if (one <= 0.0) {
        one = 1e-9;
    }
    long reps = (long)(min_time / trials / one);
    if (reps < 1) {
        reps = 1;
    }
    double best = 1e30;
    for (int t = 0; t < trials; ++t) {
        t0 = now_s();
        for (long r = 0; r < reps; ++r) {
            run_job(j);
        }
        const double per = (now_s() - t0) / (double)reps;
        best = per < best ? per : best;
    }
    return best;
}

typedef uint64_t peak_fn(uint64_t iters);

/* Measured multiply-accumulates per second of a peak probe (best of 5). */
static double peak_rate(peak_fn *fn, double min_time)
{
    uint64_t iters = 1000;
    double t = 0.0;
    for (;;) {
        const double t0 = now_s();
        fn(iters);
        t = now_s() - t0;
        if (t > min_time / 10.0 || iters > (1ull << 40)) {
            break;
        }
        iters *= 4;
    }
    double best = 0.0;
    for (int trial = 0; trial < 5; ++trial) {
        const double t0 = now_s();
        const uint64_t macs = fn(iters);
        const double dt = now_s() - t0;
        const double rate = (double)macs / (dt > 0.0 ? dt : 1e-9);
        best = rate > best ? rate : best;
    }
    return best;
}

/* ---------------------------------------------------------------------------------------- */
/* Jobs at the model's shapes                                                                */

static bench_job make_gemm(const char *name, uint32_t M, uint32_t N, uint32_t K)
{
    bench_job j = {.name = name, .kind = JOB_GEMM, .a = M, .b = N, .c = K};
    j.flops = 2.0 * M * N * K;
    j.bytes = 4.0 * ((double)M * K + (double)N * K + (double)M * N);
    return j;
}

static bench_job make_attn(const char *name, uint32_t nq, uint32_t nk, uint32_t heads, uint32_t dh)
{
    bench_job j = {.name = name, .kind = JOB_ATTN, .a = nq, .b = nk, .c = heads, .d = dh};
    j.flops = 4.0 * nq * nk * heads * dh; /* Q.K^T and P.V */
    j.bytes = 4.0 * ((double)nq * 2 + (double)nk * 2) * heads * dh;
    return j;
}

static bench_job make_rows(const char *name, job_kind kind, uint32_t rows, uint32_t cols, double flops_per_elem)
{
    bench_job j = {.name = name, .kind = kind, .a = rows, .b = cols};
    j.flops = flops_per_elem * rows * cols;
    j.bytes = 8.0 * rows * cols;
    return j;
}

static bench_job make_csr(const char *name, uint32_t rows, uint32_t deg, uint32_t dim)
{
    bench_job j = {.name = name, .kind = JOB_CSR, .a = rows, .b = deg, .c = dim};
    j.flops = (double)rows * deg * dim; /* one add per gathered float */
    j.bytes = 4.0 * ((double)rows * deg * dim + (double)rows * dim);
    return j;
}

static float *alloc_floats(size_t n, unsigned seed)
{
    float *p = (float *)aligned_alloc(64, ((n * sizeof(float)) + 63) & ~(size_t)63);
    if (!p) {
        return NULL;
    }
    unsigned s = seed * 2654435761u + 1u;
    for (size_t i = 0; i < n; ++i) {
        s = s * 1664525u + 1013904223u;
        p[i] = (float)(s >> 8) / 16777216.0f * 2.0f - 1.0f;
    }
    return p;
}

/* Allocates the buffers a job needs (shared across levels). Returns false on allocation failure. */
static bool bind_job(bench_job *j)
{
    size_t nx = 0, ny = 0, nz = 0, nw = 0, ns = 0;
    switch (j->kind) {
    case JOB_GEMM:
        nx = (size_t)j->a * j->c;
        nw = (size_t)j->b * j->c;
        ny = (size_t)j->a * j->b;
        nz = j->b;
        break;
    case JOB_ATTN:
        nx = (size_t)j->a * j->c * j->d;
        ny = nx;
        nw = (size_t)j->b * j->c * j->d;
        nz = nw;
        ns = weft_attention_scratch(j->a, j->b);
        break;
    case JOB_LAYERNORM:
        nx = ny = (size_t)j->a * j->b;
        nw = nz = j->b;
        break;
    case JOB_SOFTMAX:
    case JOB_GELU:
        nx = ny = (size_t)j->a * (j->kind == JOB_SOFTMAX ? j->b : 1u);
        break;
    case JOB_CSR: {
        nx = (size_t)j->a * j->c;
        ny = nx;
        j->rowptr = (uint32_t *)malloc(((size_t)j->a + 1) * sizeof(uint32_t));
        j->col = (uint32_t *)malloc((size_t)j->a * j->b * sizeof(uint32_t));
        if (!j->rowptr || !j->col) {
            return false;
        }
        /* a mesh-like neighbourhood: mostly nearby rows, as in a vertex ordering with locality */
        unsigned s = 12345u;
        for (uint32_t r = 0; r <= j->a; ++r) {
            j->rowptr[r] = r * j->b;
        }
        for (uint32_t r = 0; r < j->a; ++r) {
            for (uint32_t e = 0; e < j->b; ++e) {
                s = s * 1664525u + 1013904223u;
                const int off = (int)(s >> 24) % 129 - 64;
                const int c = (int)r + off;
                j->col[(size_t)r * j->b + e] = (uint32_t)(c < 0 ? -c : (c >= (int)j->a ? 2 * (int)j->a - 2 - c : c));
            }
        }
        break;
    }
    }
    j->x = alloc_floats(nx ? nx : 1, 1);
    j->y = alloc_floats(ny ? ny : 1, 2);
    j->z = alloc_floats(nz ? nz : 1, 3);
    j->w = alloc_floats(nw ? nw : 1, 4);
    j->scratch = alloc_floats(ns ? ns : 1, 5);
    return j->x && j->y && j->z && j->w && j->scratch;
}

static void free_job(bench_job *j)
{
    free(j->x);
    free(j->y);
    free(j->z);
    free(j->w);
    free(j->scratch);
    free(j->rowptr);
    free(j->col);
}

/* ---------------------------------------------------------------------------------------- */
/* Results and output                                                                        */

typedef struct level_result {
    weft_isa isa;
    double fma_gflops; /* fp32 peak, 2 flops per FMA lane */
} level_result;

typedef struct dot_result {
    const char *name;
    double gops; /* int8 peak, 2 ops per product */
} dot_result;

typedef struct kernel_result {
    const bench_job *job;
    weft_isa isa;
    double seconds, gflops, gbs, ratio;
} kernel_result;

enum { MAX_LEVELS = 4, MAX_JOBS = 16, MAX_DOTS = 4 };

/* fp32 FMA peak of each level; keeps the highest of this and any earlier measurement. */
static void measure_fma_peaks(level_result *levels, int nlevels, double min_time)
{
    for (int l = 0; l < nlevels; ++l) {
        peak_fn *fn = weft__peak_fma_scalar;
#if defined(__x86_64__)
        if (levels[l].isa == WEFT_ISA_AVX2) {
            fn = weft__peak_fma_avx2;
        } else if (levels[l].isa == WEFT_ISA_AVX512) {
            fn = weft__peak_fma_avx512;
        }
#endif
#if defined(__aarch64__)
        if (levels[l].isa == WEFT_ISA_NEON) {
            fn = weft__peak_fma_neon;
        }
#endif
        const double g = 2.0 * peak_rate(fn, min_time) * 1e-9;
        levels[l].fma_gflops = g > levels[l].fma_gflops ? g : levels[l].fma_gflops;
    }
}

static void cpu_model(char *buf, size_t cap)
{
    snprintf(buf, cap, "unknown CPU");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f) {
        return;
    }
    char line[512];
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "model name", 10) == 0) {
            const char *p = strchr(line, ':');
            if (p) {
                p++;
                while (*p == ' ') {
                    p++;
                }
                snprintf(buf, cap, "%s", p);
                buf[strcspn(buf, "\n")] = '\0';
            }
            break;
        }
    }
    fclose(f);
}

static void print_json_string(const char *str)
{
    putchar('"');
    for (const unsigned char *p = (const unsigned char *)str; *p; ++p) {
        if (*p == '"' || *p == '\\') {
            printf("\\%c", *p);
        } else if (*p < 0x20) {
            printf("\\u%04x", *p);
        } else {
            putchar(*p);
        }
    }
    putchar('"');
}

static void print_notes(FILE *o, const char *prefix)
{
    fprintf(o, "%sFlop models: GEMM 2MNK; attention 4 nq nk heads dh (Q.K^T and P.V; the softmax is not\n", prefix);
    fprintf(o, "%scounted); layernorm 8 per element; softmax 4 per element; gelu 1 per element (so its\n", prefix);
    fprintf(o, "%sGFLOP/s reads as Gelem/s); csr_aggregate 1 add per gathered float. The ratio is to the\n", prefix);
    fprintf(o, "%sfp32 FMA peak of the same level; layernorm, softmax, gelu and csr_aggregate are bound by\n", prefix);
    fprintf(o, "%smemory or by the exp, not by FMA, so their ratio shows headroom rather than a target.\n", prefix);
    fprintf(o, "%sgelu and softmax work in place, so their times include restoring the input (a memcpy).\n", prefix);
}

/* The descriptive part of docs/KERNELS.md; the figures after it are measured on each run, so
 * `weft bench kernels --md > docs/KERNELS.md` regenerates the whole page. */
static const char *const k_doc_intro[] = {
    "# Kernels\n"
    "\n",
    "<!-- Generated by `weft bench kernels --md > docs/KERNELS.md`; edit tools/weft/bench_kernels.c. -->\n"
    "\n",
    "The fp32 compute kernels behind the learned cloth model (`runtime/kernels/kernels.h`): GEMM with\n"
    "bias, fused activation and accumulate; row softmax; layernorm; rmsnorm; gelu (tanh form); silu;\n"
    "swiglu; sinusoidal position embedding; CSR neighbour aggregation; multi-head attention with an\n"
    "optional byte mask.\n"
    "\n",
    "## Levels and dispatch\n"
    "\n",
    "`runtime/cpu/cpu.c` detects features once (`pthread_once`): cpuid leaves 1 and 7 plus `xgetbv`\n"
    "(a feature counts only when the OS saves its registers: XMM|YMM for AVX, plus opmask/ZMM state for\n"
    "AVX-512), and `getauxval(AT_HWCAP)` on AArch64. Levels: `scalar` (the oracles), `avx2` (AVX2 + FMA +\n"
    "F16C), `avx512` (F/DQ/BW/VL), `neon`. `WEFT_ISA=scalar|avx2|avx512|neon|auto` forces a level for\n"
    "contexts created with `WEFT_ISA_AUTO`; an unknown value is `WEFT_ERROR_INVALID_ARGUMENT`, a level\n"
    "the CPU or build lacks is `WEFT_ERROR_UNSUPPORTED`. `weft_kernels_for_isa()` returns a table only\n"
    "when it is built and the CPU runs it.\n"
    "\n",
    "## Structure\n"
    "\n",
    "- `kernels_scalar.c`: the oracles, plain C in the most direct order of operations, sharing no code\n"
    "  with the SIMD body. Every test compares against them.\n"
    "- `simd_avx2.h`, `simd_avx512.h`, `simd_neon.h`, `simd_scalar.h`: one small vector layer per ISA\n"
    "  (vector and mask types, loads/stores with zero-filled tails that never touch memory past the\n"
    "  data, FMA, compares, selects, 2^n, horizontal sum/max, an in-register VW x VW transpose) and the\n"
    "  GEMM register tile for that ISA.\n"
    "- `kernels_body.h`: the one body (exp, sigmoid, gelu, sin/cos, GEMM micro-kernel and driver,\n"
    "  attention, row and elementwise kernels), included by `kernels_avx2.c`, `kernels_avx512.c`,\n"
    "  `kernels_neon.c` and `kernels_generic.c` (the body over one-lane plain-C vectors: never\n"
    "  dispatched, but tested everywhere so the body's tiling and tails are checked even where no\n"
    "  SIMD level runs).\n"
    "- `peak_*.c`: the throughput probes this benchmark compares against.\n"
    "\n",
    "## GEMM\n"
    "\n",
    "`C = act(A W^T + bias (+ C))`, W in nn.Linear layout `[N][K]`. One NR-wide panel of W^T\n"
    "(K blocks of 256) is packed on the stack (32 KiB on AVX-512; no allocation) with the in-register\n"
    "transpose, then every MR-row tile of A runs against it with the accumulators in registers for the\n"
    "whole K block: AVX-512 12 x 32 (24 zmm accumulators), AVX2 6 x 16, NEON 8 x 12. Row remainders\n"
    "use 8/4/2/1-row instances of the same tile; column tails use masked loads and stores. Bias,\n"
    "accumulate and the activation are applied in the tile's epilogue on the last K block. M < 4 takes\n"
    "the GEMV path: dot products along K with max(VW, 8) rows of W in flight (W streams once per row\n"
    "of A), reduced VW at a time by the in-register transpose. N <= 4 (an output layer such as xyz)\n"
    "uses the same dot-product form with the roles of A and W swapped, since a register tile would be\n"
    "mostly padding.\n"
    "\n",
    "## Attention\n"
    "\n",
    "Per head, the keys are transposed once (chunks of 64 dimensions); queries go in blocks of 48 and\n"
    "keys in blocks of 256. For each block pair, `S = Q K^T` and `O += P V` run on the GEMM register\n"
    "tiles, with an online softmax in between (running row max and sum; earlier output rescaled when\n"
    "the max grows), and each row is divided by its sum at the end. The score tile is therefore at most\n"
    "48 x 256 whatever nk is, which serves both of the model's regimes: many queries x few keys\n"
    "(decoder) and few queries x many keys (encoder). A row whose every key is masked yields zeros.\n"
    "With dh = 32 each score costs one exp per 64 multiply-adds and Q.K^T runs tiles only 32 terms\n"
    "deep; the softmax (not counted in the flop figures below) and those short tiles make the gap\n"
    "between the attention and GEMM ratios.\n"
    "`weft_attention_scratch(nq, nk)` = score tile + 2 x 48 row states + 64 x pad(nk) transposed keys.\n"
    "\n",
    "## Accuracy\n"
    "\n",
    "Vector transcendentals (in `kernels_body.h`): exp by Cody-Waite reduction (ln 2 split in two) and a\n"
    "degree-6 polynomial, exactly 0 below -87.3 (so masked -inf scores give 0) and saturating at\n"
    "exp(88.37); sigmoid as 1 / (1 + exp(-x)), the reciprocal by a hardware estimate refined with Newton\n"
    "steps on x86 (a divide on NEON); gelu as x * sigmoid(2u), which equals 0.5 x (1 + tanh u) without\n"
    "its cancellation; sin/cos by reduction modulo pi/2 in three FMA steps\n"
    "for |x| <= 8192 (libm per lane beyond). Worst errors measured by `kernels.rowwise`\n"
    "(`test_transcendental_accuracy`, against double-precision libm; identical on every level):\n"
    "\n",
    "| function | range | worst error |\n"
    "|---|---|---:|\n"
    "| sigmoid (through silu) | x in [-80, 0] | 2.3e-7 relative |\n"
    "| gelu | x in [-8, 8] | 5.2e-6 relative (rounding of u in float: exp(-2u) moves by 2u x 6e-8) |\n"
    "| sin, cos (through posembed) | abs(x) <= 1000 | 8.9e-8 absolute |\n"
    "\n",
    "Tolerances of the SIMD-vs-oracle tests (tests/kernels), `|got - want| <= atol + rtol * scale`:\n"
    "\n",
    "| kernel | atol | rtol | scale |\n"
    "|---|---:|---:|---|\n"
    "| gemm | 1e-6 | 1.2e-7 x (K + 4) | the same GEMM on absolute values (sum of abs(a w) + abs(bias) + abs(c)) |\n"
    "| attention | 2e-5 | 0 | outputs are convex combinations of V, abs(V) <= 1 |\n"
    "| softmax | 1e-7 | 2e-6 | abs(want) |\n"
    "| layernorm, rmsnorm | 2e-6 | 2e-6 | abs(want) |\n"
    "| gelu, silu, swiglu | 1e-7 | 2e-6 | abs(want) |\n"
    "| posembed | 1e-6 | 0 | arguments up to abs 1.6e3 (libm fallback beyond 8192 included) |\n"
    "| csr_aggregate | 0 | 1e-5 | sum of abs(x) over the neighbours |\n"
    "\n",
    "## Tests\n"
    "\n",
    "- `cpu.dispatch`: WEFT_ISA forcing (setenv), unknown values, unavailable levels, explicit levels,\n"
    "  the feature string, concurrent first detection, and on x86 Linux the detected flags against\n"
    "  `/proc/cpuinfo`.\n"
    "- `kernels.gemm`, `kernels.attention`, `kernels.rowwise`: every kernel of every level the CPU runs\n"
    "  (plus the generic body) against the oracle at awkward sizes (1, 3, 17, 31, 33, 257, ... for\n"
    "  M/N/K, rows/cols, nq/nk, heads, dh), padded strides whose padding must survive, guard zones around\n"
    "  every output and the attention scratch, in-place use, -inf and fully masked rows, empty CSR rows.\n"
    "\n",
    "AArch64 NEON, cross-built and run under qemu-user:\n"
    "\n",
    "```\n"
    "cmake -S . -B build-arm -DCMAKE_TOOLCHAIN_FILE=cmake/aarch64-linux-gnu.cmake -DWEFT_KERNELS_ONLY=ON\n"
    "cmake --build build-arm -j2 && ctest --test-dir build-arm -R 'cpu|kernels'\n"
    "```\n",
    NULL};

enum { OPT_QUICK = 1, OPT_ISA, OPT_JSON, OPT_MD };

static const cli_option k_options[] = {
    {"quick", NULL, OPT_QUICK, "short timings (about 10x faster, noisier)"},
    {"isa", "scalar|avx2|avx512|neon", OPT_ISA, "only this level (default: every level this CPU runs)"},
    {"md", NULL, OPT_MD, "Markdown report (docs/KERNELS.md is made from it)"},
    {"json", NULL, OPT_JSON, "one JSON object (not with --md)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench kernels",
    .synopsis = "weft bench kernels [--quick] [--isa scalar|avx2|avx512|neon] [--json | --md]",
    .about = "Single-thread throughput of every fp32 kernel of every level this CPU runs, at the cloth model's\n"
             "shapes, next to the measured fp32 FMA and int8 dot-product peaks of the same level.",
    .options = k_options,
};

int weft_bench_kernels(int argc, char **argv)
{
    bool quick = false, json = false, md = false;
    const char *only = NULL;
    cli_parser cp;
    cli_start(&cp, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cp, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return cp.exit;
        case OPT_QUICK:
            quick = true;
            break;
        case OPT_JSON:
            json = true;
            break;
        case OPT_MD:
            md = true;
            break;
        case OPT_ISA:
            only = v;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&cp) != 0) {
        return 2;
    }
    if (json && md) {
        fprintf(stderr, "weft bench kernels: --json and --md are exclusive\n");
        return 2;
    }
    const double min_time = quick ? 0.05 : 0.5;

    /* levels to run */
    level_result levels[MAX_LEVELS];
    int nlevels = 0;
    static const weft_isa all[] = {WEFT_ISA_SCALAR, WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; ++i) {
        if (!weft_kernels_for_isa(all[i])) {
            continue;
        }
        if (only && strcmp(only, weft_isa_name(all[i])) != 0) {
            continue;
        }
        levels[nlevels++] = (level_result){.isa = all[i]};
    }
    if (nlevels == 0) {
        fprintf(stderr, "weft bench kernels: level '%s' is not available here (features: %s)\n", only ? only : "?",
                weft_cpu_features_string());
        return 1;
    }

    /* peaks (measured again after the kernels; the higher figure is kept, so a clock ramp or a
     * noisy neighbour during one measurement cannot inflate the ratios) */
    const weft_cpu_features *f = weft_cpu_features_get();
    measure_fma_peaks(levels, nlevels, min_time);
    dot_result dots[MAX_DOTS] = {{NULL, 0.0}};
    int ndots = 0;
#if defined(__x86_64__)
    if (f->avx2) {
        dots[ndots++] = (dot_result){"avx2 vpmaddubsw+vpmaddwd", 2.0 * peak_rate(weft__peak_dot_avx2, min_time) * 1e-9};
    }
    if (f->avxvnni) {
        dots[ndots++] = (dot_result){"avx-vnni vpdpbusd ymm", 2.0 * peak_rate(weft__peak_dot_avxvnni, min_time) * 1e-9};
    }
    if (f->avx512vnni && f->avx512bw && f->avx512vl) {
        dots[ndots++] = (dot_result){"avx512-vnni vpdpbusd zmm", 2.0 * peak_rate(weft__peak_dot_avx512, min_time) * 1e-9};
    }
#endif
#if defined(__aarch64__)
    if (f->asimddp) {
        dots[ndots++] = (dot_result){"neon sdot", 2.0 * peak_rate(weft__peak_dot_neon, min_time) * 1e-9};
    }
#endif

    /* kernels */
    bench_job jobs[MAX_JOBS];
    int njobs = 0;
    jobs[njobs++] = make_gemm("gemm", 4096, 64, 64);
    jobs[njobs++] = make_gemm("gemm", 4096, 128, 128);
    jobs[njobs++] = make_gemm("gemm", 64, 256, 256);
    jobs[njobs++] = make_gemm("gemv", 1, 256, 256);
    jobs[njobs++] = make_gemm("gemm narrow", 4096, 3, 128);
    jobs[njobs++] = make_attn("attention", 4096, 64, 4, 32);
    jobs[njobs++] = make_attn("attention", 64, 4096, 4, 32);
    jobs[njobs++] = make_rows("layernorm", JOB_LAYERNORM, 4096, 128, 8.0);
    jobs[njobs++] = make_rows("softmax", JOB_SOFTMAX, 4096, 64, 4.0);
    jobs[njobs++] = make_rows("gelu", JOB_GELU, 4096 * 128, 1, 1.0);
    jobs[njobs++] = make_csr("csr_aggregate", 4096, 6, 128);
    static char shapes[MAX_JOBS][64];
    for (int i = 0; i < njobs; ++i) {
        bench_job *j = &jobs[i];
        switch (j->kind) {
        case JOB_GEMM:
            snprintf(shapes[i], sizeof shapes[i], "%ux%ux%u", j->a, j->b, j->c);
            break;
        case JOB_ATTN:
            snprintf(shapes[i], sizeof shapes[i], "q%u k%u h%u d%u", j->a, j->b, j->c, j->d);
            break;
        case JOB_CSR:
            snprintf(shapes[i], sizeof shapes[i], "%u rows deg %u x %u", j->a, j->b, j->c);
            break;
        case JOB_GELU:
            snprintf(shapes[i], sizeof shapes[i], "%u", j->a);
            break;
        default:
            snprintf(shapes[i], sizeof shapes[i], "%ux%u", j->a, j->b);
            break;
        }
        j->shape = shapes[i];
        if (!bind_job(j)) {
            fprintf(stderr, "weft bench kernels: out of memory\n");
            for (int t = 0; t <= i; ++t) {
                free_job(&jobs[t]);
            }
            return 1;
        }
    }
    kernel_result results[MAX_LEVELS * MAX_JOBS];
    int nres = 0;
    for (int l = 0; l < nlevels; ++l) {
        const weft_kernels *k = weft_kernels_for_isa(levels[l].isa);
        for (int i = 0; i < njobs; ++i) {
            jobs[i].k = k;
            const double s = time_best(&jobs[i], min_time);
            const double gf = jobs[i].flops / s * 1e-9;
            results[nres++] = (kernel_result){.job = &jobs[i], .isa = levels[l].isa, .seconds = s, .gflops = gf,
                                              .gbs = jobs[i].bytes / s * 1e-9, .ratio = gf / levels[l].fma_gflops};
        }
    }

    measure_fma_peaks(levels, nlevels, min_time);
    for (int r = 0; r < nres; ++r) {
        for (int l = 0; l < nlevels; ++l) {
            if (levels[l].isa == results[r].isa) {
                results[r].ratio = results[r].gflops / levels[l].fma_gflops;
            }
        }
    }

    char model[256];
    cpu_model(model, sizeof model);
    if (json) {
        printf("{\n  \"config\": ");
        print_json_string(weft_config_string());
        printf(",\n  \"cpu\": ");
        print_json_string(model);
        printf(",\n  \"quick\": %s,\n  \"fp32_peak_gflops\": {", quick ? "true" : "false");
        for (int l = 0; l < nlevels; ++l) {
            printf("%s\"%s\": %.2f", l ? ", " : "", weft_isa_name(levels[l].isa), levels[l].fma_gflops);
        }
        printf("},\n  \"int8_peak_gops\": {");
        for (int d = 0; d < ndots; ++d) {
            printf("%s\"%s\": %.2f", d ? ", " : "", dots[d].name, dots[d].gops);
        }
        printf("},\n  \"kernels\": [\n");
        for (int r = 0; r < nres; ++r) {
            const kernel_result *x = &results[r];
            printf("    {\"kernel\": \"%s\", \"shape\": \"%s\", \"isa\": \"%s\", \"us\": %.3f, \"gflops\": %.3f, "
                   "\"gbytes_per_s\": %.3f, \"ratio_to_peak\": %.4f}%s\n",
                   x->job->name, x->job->shape, weft_isa_name(x->isa), x->seconds * 1e6, x->gflops, x->gbs, x->ratio,
                   r + 1 < nres ? "," : "");
        }
        printf("  ]\n}\n");
    } else if (md) {
        for (const char *const *part = k_doc_intro; *part; ++part) {
            fputs(*part, stdout);
        }
        printf("\n## Measured figures\n\n");
        printf("Generated by `weft bench kernels --md%s` on %s, single thread; `%s`.\n", quick ? " --quick" : "", model,
               weft_config_string());
        printf("Times are thread CPU time, best of 5 trials (robust on a shared machine); GB/s counts the minimum\n"
               "bytes each call must move.\n\n");
        printf("### Peaks\n\n| level | fp32 FMA peak (GFLOP/s) |\n|---|---:|\n");
        for (int l = 0; l < nlevels; ++l) {
            printf("| %s | %.1f |\n", weft_isa_name(levels[l].isa), levels[l].fma_gflops);
        }
        printf("\n| int8 dot product | peak (GOPS, 2 per product) |\n|---|---:|\n");
        for (int d = 0; d < ndots; ++d) {
            printf("| %s | %.1f |\n", dots[d].name, dots[d].gops);
        }
        printf("\n### Kernels\n\n| kernel | shape | level | time (us) | GFLOP/s | GB/s | of fp32 peak |\n"
               "|---|---|---|---:|---:|---:|---:|\n");
        for (int r = 0; r < nres; ++r) {
            const kernel_result *x = &results[r];
            printf("| %s | %s | %s | %.1f | %.2f | %.1f | %.1f%% |\n", x->job->name, x->job->shape,
                   weft_isa_name(x->isa), x->seconds * 1e6, x->gflops, x->gbs, 100.0 * x->ratio);
        }
        printf("\n");
        print_notes(stdout, "");
        printf("\nThe int8, fp16 and deterministic fp32 kernels of the reduced-precision model paths\n"
               "(`runtime/kernels/qkernels*.c`) are described and measured in [QKERNELS.md](QKERNELS.md).\n");
    } else {
        printf("%s\n%s\n\n", model, weft_config_string());
        for (int l = 0; l < nlevels; ++l) {
            printf("peak fp32 FMA  %-8s %9.1f GFLOP/s\n", weft_isa_name(levels[l].isa), levels[l].fma_gflops);
        }
        for (int d = 0; d < ndots; ++d) {
            printf("peak int8 dot  %-26s %9.1f GOPS\n", dots[d].name, dots[d].gops);
        }
        printf("\n%-14s %-22s %-7s %11s %10s %8s %8s\n", "kernel", "shape", "level", "time us", "GFLOP/s", "GB/s",
               "of peak");
        for (int r = 0; r < nres; ++r) {
            const kernel_result *x = &results[r];
            printf("%-14s %-22s %-7s %11.1f %10.2f %8.1f %7.1f%%\n", x->job->name, x->job->shape,
                   weft_isa_name(x->isa), x->seconds * 1e6, x->gflops, x->gbs, 100.0 * x->ratio);
        }
        printf("\n");
        print_notes(stdout, "");
    }
    for (int i = 0; i < njobs; ++i) {
        free_job(&jobs[i]);
    }
    return 0;
}
