/* weft bench qkernels: single-thread throughput of the int8, fp16 and deterministic-fp32
 * matrix products of every variant this CPU runs, at the cloth model's shapes, in one run with
 * the measured int8 dot-product and fp32 FMA peaks and the fp32 GEMM of the same level, so the
 * printed ratios (int8 / fp32 speed, fraction of peak) are measured side by side. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "weft.h"

#include "cpu/cpu.h"
#include "kernels/kernels.h"
#include "kernels/kernels_internal.h"
#include "kernels/qkernels.h"
#include "support_cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int weft_bench_qkernels(int argc, char **argv); /* the CLI registry declares it in main.c */
extern const char weft_bench_qkernels_help[];
const char weft_bench_qkernels_help[] =
    "int8 / fp16 / deterministic GEMM per variant vs int8-dot and FMA peaks [--quick] [--md]";

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

typedef struct shape {
    uint32_t M, N, K;
    const char *what;
} shape;

/* Vertex-token MLPs (M = vertices), latent layers (M = K latents), and a single-row GEMV. */
static const shape g_shapes[] = {
    {4096, 128, 128, "vertex MLP 4k x 128 x 128"},
    {1024, 128, 128, "vertex MLP 1k x 128 x 128"},
    {64, 256, 256, "latent layer 64 x 256 x 256"},
    {64, 1024, 256, "latent SwiGLU 64 x 1024 x 256"},
    {1, 256, 256, "GEMV 1 x 256 x 256"},
};
#define NSHAPES (sizeof g_shapes / sizeof g_shapes[0])

typedef struct op {
    const weft_qkernels *q;
    const weft_kernels *k;
    const shape *s;
    float *X, *Wt, *W, *bias, *C;
    uint16_t *Wh;
    int8_t *Q;
    float *qs;
    weft_q8_weights w8;
} op;

typedef void op_fn(const op *o);

static void run_q8(const op *o)
{
    uint32_t Kp = weft_q8_pad_k(o->s->K);
    o->q->quantize_rows(o->X, o->s->M, o->s->K, o->s->K, o->Q, Kp, o->qs);
    o->q->gemm_q8(o->s->M, o->Q, Kp, o->qs, &o->w8, o->bias, o->C, o->s->N, WEFT_ACT_NONE, false);
}
static void run_f16(const op *o)
{
    o->q->gemm_f16(o->s->M, o->s->N, o->s->K, o->X, o->s->K, o->Wh, o->s->N, o->bias, o->C, o->s->N, WEFT_ACT_NONE,
                   false);
}
static void run_det(const op *o)
{
    o->q->gemm_det(o->s->M, o->s->N, o->s->K, o->X, o->s->K, o->Wt, o->s->N, o->bias, o->C, o->s->N, WEFT_ACT_NONE,
                   false);
}
static void run_f32(const op *o)
{
    o->k->gemm(o->s->M, o->s->N, o->s->K, o->X, o->s->K, o->W, o->s->K, o->bias, o->C, o->s->N, WEFT_ACT_NONE, false);
}

/* Seconds per call: repeat until min_time has passed, best of 3 rounds. */
static double time_op(op_fn *fn, const op *o, double min_time)
{
    fn(o);
    double best = 1e30;
    for (int round = 0; round < 3; ++round) {
        uint64_t calls = 0;
        double t0 = now_s(), t;
        do {
            fn(o);
            calls++;
            t = now_s() - t0;
        } while (t < min_time);
        best = t / (double)calls < best ? t / (double)calls : best;
    }
    return best;
}

typedef uint64_t peak_fn(uint64_t iters);

static double peak_rate(peak_fn *fn, double min_time)
{
    double best = 0;
    for (int round = 0; round < 3; ++round) {
        uint64_t iters = 1 << 16, ops = 0;
        double t0 = now_s(), t;
        do {
            ops += fn(iters);
            t = now_s() - t0;
        } while (t < min_time);
        best = (double)ops / t > best ? (double)ops / t : best;
    }
    return best;
}

/* The int8 peak probe and fp32 FMA probe that match a variant. */
static void variant_peaks(const weft_qkernels *q, peak_fn **dot, peak_fn **fma)
{
    *dot = NULL;
    *fma = weft__peak_fma_scalar;
#if defined(__x86_64__)
    if (strcmp(q->variant, "avx512-vnni") == 0) {
        *dot = weft__peak_dot_avx512;
        *fma = weft__peak_fma_avx512;
    } else if (strcmp(q->variant, "avx-vnni") == 0) {
        *dot = weft__peak_dot_avxvnni;
        *fma = weft__peak_fma_avx2;
    } else if (strcmp(q->variant, "avx2-maddubs") == 0) {
        *dot = weft__peak_dot_avx2;
        *fma = weft__peak_fma_avx2;
    }
#endif
#if defined(__aarch64__)
    if (strcmp(q->variant, "neon-sdot") == 0) {
        *dot = weft__peak_dot_neon;
        *fma = weft__peak_fma_neon;
    }
#endif
}

enum { OPT_QUICK = 1, OPT_MD };

static const cli_option k_options[] = {
    {"quick", NULL, OPT_QUICK, "time each kernel for 0.02 s a round instead of 0.2 s (best of 3 rounds)"},
    {"md", NULL, OPT_MD,
     "print the table as Markdown (for the docs) with a note on what it\n"
     "measures"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench qkernels",
    .synopsis = "weft bench qkernels [--quick] [--md]",
    .about = "Single-thread int8 / fp16 / deterministic-fp32 GEMM throughput of every variant this CPU runs, at\n"
             "the cloth model's shapes, against the measured int8 dot-product and fp32 FMA peaks and the fp32\n"
             "GEMM of the same level.",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_qkernels(int argc, char **argv)
{
    bool quick = false, md = false;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *val;
    for (int id; (id = cli_next(&parser, &val)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_QUICK:
            quick = true;
            break;
        case OPT_MD:
            md = true;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    const double min_time = quick ? 0.02 : 0.2;
    const weft_qkernels *variants[8];
    uint32_t nv = weft_qkernels_variants(variants, 8);
    nv = nv > 8 ? 8 : nv;
    if (md) {
        printf("Measured by `build/bin/weft bench qkernels --md` (%s), one thread.\n\n", weft_config_string());
        printf("| variant | shape | int8 GOPS | of int8 peak | fp16 GFLOP/s | det fp32 GFLOP/s | fp32 GFLOP/s | "
               "int8 / fp32 speed |\n|---|---|---:|---:|---:|---:|---:|---:|\n");
    } else {
        printf("%s\n%-14s %-30s %10s %8s %10s %10s %10s %8s\n", weft_config_string(), "variant", "shape", "int8 GOPS",
               "of peak", "fp16 GF/s", "det GF/s", "fp32 GF/s", "i8/fp32");
    }
    for (uint32_t v = 0; v < nv; ++v) {
        const weft_qkernels *q = variants[v];
        if (strcmp(q->variant, "generic-body") == 0) {
            continue; /* a test vehicle, never dispatched */
        }
        const weft_kernels *k = weft_kernels_for_isa(q->isa);
        peak_fn *dot, *fma;
        variant_peaks(q, &dot, &fma);
        double dot_peak = dot ? 2.0 * peak_rate(dot, min_time) : 0.0;
        for (size_t si = 0; si < NSHAPES; ++si) {
            const shape *s = &g_shapes[si];
            if (strcmp(q->variant, "scalar") == 0 && s->M > 1024) {
                continue; /* the oracle is slow by design */
            }
            op o = {.q = q, .k = k, .s = s};
            size_t xk = (size_t)s->M * s->K, nk = (size_t)s->N * s->K;
            o.X = malloc(xk * sizeof(float));
            o.W = malloc(nk * sizeof(float));
            o.Wt = malloc(nk * sizeof(float));
            o.Wh = malloc(nk * sizeof(uint16_t));
            o.bias = calloc(s->N, sizeof(float));
            o.C = malloc((size_t)s->M * s->N * sizeof(float));
            o.Q = malloc((size_t)s->M * weft_q8_pad_k(s->K));
            o.qs = malloc(s->M * sizeof(float));
            int8_t *wq = malloc(nk), *packed = malloc((size_t)weft_q8_pad_n(s->N) * weft_q8_pad_k(s->K));
            float *scale = malloc(s->N * sizeof(float)), *pscale = malloc(weft_q8_pad_n(s->N) * sizeof(float));
            int32_t *wsum = malloc(weft_q8_pad_n(s->N) * sizeof(int32_t));
            uint32_t seed = 12345;
            for (size_t i = 0; i < xk; ++i) {
                seed = seed * 1664525u + 1013904223u;
                o.X[i] = (float)(seed >> 8) / 16777216.0f - 0.5f;
            }
            for (size_t i = 0; i < nk; ++i) {
                seed = seed * 1664525u + 1013904223u;
                o.W[i] = (float)(seed >> 8) / 16777216.0f - 0.5f;
            }
            for (uint32_t n = 0; n < s->N; ++n) {
                for (uint32_t kk = 0; kk < s->K; ++kk) {
                    o.Wt[(size_t)kk * s->N + n] = o.W[(size_t)n * s->K + kk];
                    o.Wh[(size_t)kk * s->N + n] = weft_f32_to_f16(o.W[(size_t)n * s->K + kk]);
                }
            }
            weft_q8_quantize_weights(o.W, s->N, s->K, wq, scale);
            weft_q8_pack(wq, scale, s->N, s->K, packed, pscale, wsum);
            o.w8 = (weft_q8_weights){s->N, s->K, weft_q8_pad_n(s->N), weft_q8_pad_k(s->K), packed, pscale, wsum};
            double macs = (double)s->M * s->N * s->K;
            double t_q8 = time_op(run_q8, &o, min_time);
            double t_f16 = time_op(run_f16, &o, min_time);
            double t_det = time_op(run_det, &o, min_time);
            double t_f32 = k ? time_op(run_f32, &o, min_time) : 0.0;
            double gops = 2.0 * macs / t_q8 * 1e-9;
            double of_peak = dot_peak > 0 ? 2.0 * macs / t_q8 / dot_peak : 0.0;
            double f16 = 2.0 * macs / t_f16 * 1e-9, det = 2.0 * macs / t_det * 1e-9;
            double f32 = t_f32 > 0 ? 2.0 * macs / t_f32 * 1e-9 : 0.0;
            double speed = t_f32 > 0 ? t_f32 / t_q8 : 0.0;
            if (md) {
                printf("| %s | %s | %.1f | %.0f%% | %.1f | %.1f | %.1f | %.2fx |\n", q->variant, s->what, gops,
                       100.0 * of_peak, f16, det, f32, speed);
            } else {
                printf("%-14s %-30s %10.1f %7.0f%% %10.1f %10.1f %10.1f %7.2fx\n", q->variant, s->what, gops,
                       100.0 * of_peak, f16, det, f32, speed);
            }
            free(o.X); free(o.W); free(o.Wt); free(o.Wh); free(o.bias); free(o.C); free(o.Q); free(o.qs);
            free(wq); free(packed); free(scale); free(pscale); free(wsum);
        }
    }
    if (md) {
        printf("\nint8 GOPS count 2 operations per multiply-accumulate and include the per-row activation\n"
               "quantisation; \"of int8 peak\" divides by the variant's own dot-product probe (vpdpbusd, or\n"
               "vpmaddubsw + vpmaddwd for AVX2). fp32 is the fp32 kernel table of the same ISA level.\n");
    }
    return 0;
}
