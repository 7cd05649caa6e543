/* `weft bench model`: the learned model's end-to-end step on a game-like scene. A T-shirt from
 * the wardrobe at about 1k and 4k vertices on the default avatar, which is also the collider,
 * walking (so velocities are non-zero). For each shipped model and precision: ms per frame on one
 * thread, the multiply-accumulates actually done per frame (counted through the calibration
 * observer from the real token counts), GMAC/s, their ratio to the fp32 FMA and int8
 * dot-product peaks measured in the same run, the largest per-frame GEMM alone against those
 * peaks, PyTorch eager on the same model file and inputs, and the per-character cost of batched
 * stepping (weft_garments_step) at 1, 8 and 64 characters. */
#define _POSIX_C_SOURCE 200809L

#include "kernels/kernels_internal.h"
#include "kernels/qkernels.h"
#include "model/transformer.h"
#include "support_bench.h"
#include "support_cli.h"
#include "support_peaks.h"
#include "weft.h"
#include "weft/body.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

const char weft_bench_model_help[] =
    "model ms/frame fp32/fp16/int8 at 1k/4k vertices, GMAC/s vs peaks, PyTorch eager, batched crowds "
    "[--quick] [--md] [--no-torch] [--avatar-vertices N]";

/* ---------------------------------------------------------------------------------------- */
/* Scene: avatar, walking motion, T-shirt at one resolution                                  */

typedef struct scene {
    weft_cloth_mesh *shirt;
    uint32_t V, F, Vc, Fc;
    const uint32_t *ctri;
    float *coll;    /* frames x Vc x 3: the posed avatar per frame */
    float *x0, *x1; /* the shirt skinned to frames 0 and 1 */
    uint32_t frames;
} scene;

static bool scene_make(weft_context *ctx, const weft_body *avatar, weft_cloth_resolution res, uint32_t frames,
                       scene *s)
{
    memset(s, 0, sizeof *s);
    weft_cloth_def cd = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    cd.resolution = res;
    weft_result r = weft_cloth_create(ctx, &cd, avatar, &s->shirt);
    if (r != WEFT_OK) {
        fprintf(stderr, "weft bench model: T-shirt: %s\n", weft_last_error());
        return false;
    }
    s->V = s->shirt->vertex_count;
    s->F = s->shirt->triangle_count;
    s->Vc = weft_body_vertex_count(avatar);
    s->Fc = weft_body_triangle_count(avatar);
    s->ctri = weft_body_triangles(avatar);
    s->frames = frames;
    s->coll = malloc((size_t)frames * s->Vc * 3 * sizeof(float));
    s->x0 = malloc((size_t)s->V * 3 * sizeof(float));
    s->x1 = malloc((size_t)s->V * 3 * sizeof(float));
    if (!s->coll || !s->x0 || !s->x1) {
        return false;
    }
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    for (uint32_t f = 0; f < frames; ++f) {
        weft_pose pose;
        if (weft_motion_sample(&md, f / 60.0, &pose) != WEFT_OK ||
            weft_body_pose(avatar, &pose, s->coll + (size_t)f * s->Vc * 3, NULL) != WEFT_OK) {
            return false;
        }
        if (f < 2 && weft_body_skin_points(avatar, &pose, s->shirt->positions, s->shirt->weights, s->V,
                                           f == 0 ? s->x0 : s->x1) != WEFT_OK) {
            return false;
        }
    }
    return true;
}

static void scene_free(scene *s)
{
    weft_cloth_destroy(s->shirt);
    free(s->coll);
    free(s->x0);
    free(s->x1);
}

static const float *coll_frame(const scene *s, uint32_t f) { return s->coll + (size_t)f * s->Vc * 3; }

/* The scene's shirt placed at frame 1 (skinned to it, bound to the collider there), CCD off. */
static weft_garment_def scene_garment_def(const scene *s, weft_method method)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.ccd.enabled = false; /* the model alone: CCD has its own benchmark (weft bench ccd) */
    d.rest_positions = s->shirt->positions;
    d.vertex_count = s->V;
    d.triangles = s->shirt->triangles;
    d.triangle_count = s->F;
    d.collider_rest_positions = coll_frame(s, 1);
    d.collider_vertex_count = s->Vc;
    d.collider_triangles = s->ctri;
    d.collider_triangle_count = s->Fc;
    d.initial_positions = s->x1;
    return d;
}

/* A garment of the model placed at frame 1 (moving: X_0 != X_1). */
static weft_garment *garment_make(weft_context *ctx, const scene *s, const weft_model *m, weft_precision p)
{
    weft_garment_def d = scene_garment_def(s, WEFT_METHOD_MODEL);
    d.model = m;
    d.precision = p;
    weft_garment *g = NULL;
    if (weft_garment_create(ctx, &d, &g) != WEFT_OK || weft_garment_set_state(g, s->x1, s->x0) != WEFT_OK) {
        fprintf(stderr, "weft bench model: garment: %s\n", weft_last_error());
        weft_garment_destroy(g);
        return NULL;
    }
    return g;
}

/* ---------------------------------------------------------------------------------------- */
/* Work per frame, counted by the calibration observer                                        */

typedef struct mac_count {
    double linear_macs;
    double coll_rows; /* collider tokens kept (rows of enc_coll.fc1), summed over frames */
} mac_count;

static void count_layer(const char *name, const float *in, uint32_t rows, uint32_t in_cols, const float *out,
                        uint32_t out_cols, void *user)
{
    (void)in;
    (void)out;
    mac_count *c = user;
    if (!bench_ct_layer_per_step(name)) { /* constant per garment: computed once at creation */
        return;
    }
    c->linear_macs += (double)rows * in_cols * out_cols;
    if (strcmp(name, "enc_coll.fc1") == 0) {
        c->coll_rows += rows;
    }
}

/* Multiply-accumulates per frame over `frames` frames from frame 1: every linear layer's rows x
 * in x out as run, plus attention (QK^T and PV: 2 x queries x keys x D per block). */
static double macs_per_frame(weft_context *ctx, const scene *s, const weft_model *m, weft_precision p,
                             uint32_t frames, double *kept_per_frame)
{
    weft_ct_config c;
    if (weft__ct_bind(m, &c, NULL) != WEFT_OK) {
        return 0;
    }
    weft_garment *g = garment_make(ctx, s, m, p);
    mac_count mc = {0, 0};
    if (!g || weft__ct_set_observer(g, count_layer, &mc) != WEFT_OK) {
        weft_garment_destroy(g);
        return 0;
    }
    for (uint32_t k = 0; k < frames; ++k) {
        if (weft_garment_set_collider(g, coll_frame(s, 2 + k)) != WEFT_OK || weft_garment_step(g) != WEFT_OK) {
            weft_garment_destroy(g);
            return 0;
        }
    }
    weft_garment_destroy(g);
    const double N = s->V, D = c.D, K = c.K, hk = (double)c.history * c.K;
    const double kept = mc.coll_rows / frames;
    double attn = 2.0 * K * (N + kept) * D + 2.0 * N * K * D;
    for (uint32_t l = 0; l < c.L; ++l) {
        attn += 2.0 * (l + 1 == c.L ? K : hk) * hk * D;
    }
    *kept_per_frame = kept;
    return mc.linear_macs / frames + attn;
}

/* ---------------------------------------------------------------------------------------- */
/* Timing                                                                                     */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, uint32_t n)
{
    qsort(v, n, sizeof *v, cmp_double);
    return n == 0 ? NAN : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Median wall and thread-CPU ms of weft_garment_step over `timed` frames after `warm` frames
 * (collider upload not timed: the host has it ready in a game). */
static void time_steps(const scene *s, weft_garment *g, uint32_t warm, uint32_t timed, double *wall_ms,
                       double *cpu_ms)
{
    double *t = malloc(2 * (size_t)timed * sizeof(double));
    *wall_ms = *cpu_ms = NAN;
    if (!t) {
        return;
    }
    for (uint32_t k = 0; k < warm + timed; ++k) {
        if (weft_garment_set_collider(g, coll_frame(s, 2 + k)) != WEFT_OK) {
            free(t);
            return;
        }
        const double t0 = bench_now_s(), c0 = bench_cpu_now_s();
        weft_result r = weft_garment_step(g);
        const double dc = bench_cpu_now_s() - c0, dt = bench_now_s() - t0;
        if (r != WEFT_OK) {
            fprintf(stderr, "weft bench model: step: %s\n", weft_last_error());
            free(t);
            return;
        }
        if (k >= warm) {
            t[k - warm] = dt * 1e3;
            t[timed + k - warm] = dc * 1e3;
        }
    }
    *wall_ms = median(t, timed);
    *cpu_ms = median(t + timed, timed);
    free(t);
}

/* Per-character thread-CPU ms of a crowd of n garments: batched (one weft_garments_step) and one
 * by one (n x weft_garment_step), alternating frame by frame. */
static void time_crowd(const scene *s, weft_garment **gs, uint32_t n, uint32_t warm, uint32_t timed, double *batched,
                       double *alone)
{
    double *tb = malloc(timed * sizeof(double)), *ta = malloc(timed * sizeof(double));
    *batched = *alone = NAN;
    bool ok = tb && ta;
    for (uint32_t k = 0; ok && k < warm + timed; ++k) {
        for (int mode = 0; mode < 2 && ok; ++mode) {
            for (uint32_t i = 0; i < n; ++i) {
                ok = ok && weft_garment_set_collider(gs[i], coll_frame(s, 2 + 2 * k + (uint32_t)mode)) == WEFT_OK;
            }
            const double t0 = bench_cpu_now_s();
            if (mode == 0) {
                ok = ok && weft_garments_step(gs, n) == WEFT_OK;
            } else {
                for (uint32_t i = 0; i < n && ok; ++i) {
                    ok = weft_garment_step(gs[i]) == WEFT_OK;
                }
            }
            const double dt = (bench_cpu_now_s() - t0) * 1e3 / n;
            if (k >= warm) {
                (mode == 0 ? tb : ta)[k - warm] = dt;
            }
        }
    }
    if (!ok) {
        fprintf(stderr, "weft bench model: crowd step: %s\n", weft_last_error());
    } else {
        *batched = median(tb, timed);
        *alone = median(ta, timed);
    }
    free(tb);
    free(ta);
}

/* ---------------------------------------------------------------------------------------- */
/* PyTorch eager baseline                                                                     */

static bool write_npy(const char *dir, const char *name, const void *data, const char *descr, uint32_t rank,
                      const size_t *shape)
{
    char path[1200], header[256];
    snprintf(path, sizeof path, "%s/%s.npy", dir, name);
    int n = snprintf(header, sizeof header, "{'descr': '%s', 'fortran_order': False, 'shape': (", descr);
    size_t count = 1;
    for (uint32_t i = 0; i < rank; ++i) {
        n += snprintf(header + n, sizeof header - (size_t)n, "%zu, ", shape[i]);
        count *= shape[i];
    }
    n += snprintf(header + n, sizeof header - (size_t)n, "), }");
    /* magic (6) + version (2) + length (2) + header + '\n', padded to 64 bytes */
    size_t total = (10 + (size_t)n + 1 + 63) / 64 * 64;
    size_t hlen = total - 10;
    FILE *f = fopen(path, "wb");
    if (!f) {
        return false;
    }
    unsigned char pre[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (unsigned char)(hlen & 0xff),
                             (unsigned char)(hlen >> 8)};
    bool ok = fwrite(pre, 1, 10, f) == 10 && fwrite(header, 1, (size_t)n, f) == (size_t)n;
    for (size_t i = (size_t)n; ok && i < hlen - 1; ++i) {
        ok = fputc(' ', f) != EOF;
    }
    ok = ok && fputc('\n', f) != EOF && fwrite(data, 4, count, f) == count;
    return fclose(f) == 0 && ok;
}

/* S_f, the skinned prior's S track (frames x V x 3 into out): the LBS method bound as the model
 * garments are, stepped onto the collider at f. */
static bool skin_track(weft_context *ctx, const scene *s, float *out)
{
    const weft_garment_def d = scene_garment_def(s, WEFT_METHOD_LBS);
    weft_garment *lbs = NULL;
    bool ok = weft_garment_create(ctx, &d, &lbs) == WEFT_OK;
    for (uint32_t f = 0; ok && f < s->frames; ++f) {
        ok = weft_garment_set_collider(lbs, coll_frame(s, f)) == WEFT_OK && weft_garment_step(lbs) == WEFT_OK;
        if (ok) {
            memcpy(out + (size_t)f * s->V * 3, weft_garment_positions(lbs), (size_t)s->V * 3 * sizeof(float));
        }
    }
    if (!ok) {
        fprintf(stderr, "weft bench model: the S track: %s\n", weft_last_error());
    }
    weft_garment_destroy(lbs);
    return ok;
}

/* PyTorch's inputs as .npy files under dir, the S track among them. */
static bool write_inputs(weft_context *ctx, const scene *s, const char *dir)
{
    const size_t v3[2] = {s->V, 3}, f3[2] = {s->F, 3}, c3[2] = {s->Fc, 3}, cs[3] = {s->frames, s->Vc, 3},
                 ss[3] = {s->frames, s->V, 3};
    float *skin = malloc((size_t)s->frames * s->V * 3 * sizeof(float));
    const bool ok = skin && skin_track(ctx, s, skin) && write_npy(dir, "rest", s->shirt->positions, "<f4", 2, v3) &&
                    write_npy(dir, "faces", s->shirt->triangles, "<u4", 2, f3) &&
                    write_npy(dir, "ctri", s->ctri, "<u4", 2, c3) &&
                    write_npy(dir, "colliders", s->coll, "<f4", 3, cs) && write_npy(dir, "x0", s->x0, "<f4", 2, v3) &&
                    write_npy(dir, "x1", s->x1, "<f4", 2, v3) && write_npy(dir, "skin", skin, "<f4", 3, ss);
    free(skin);
    return ok;
}

static void remove_inputs(const char *dir)
{
    static const char *const names[] = {"rest", "faces", "ctri", "colliders", "x0", "x1", "skin"};
    char path[1200];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
        snprintf(path, sizeof path, "%s/%s.npy", dir, names[i]);
        remove(path);
    }
}

/* Median thread-CPU ms/frame of the PyTorch rollout, NAN when it could not run (why says why). */
static double torch_ms(const char *script, const char *model, const char *dir, uint32_t warm, uint32_t timed,
                       char *why, size_t why_cap)
{
    char fr[16], wu[16];
    snprintf(fr, sizeof fr, "%u", timed);
    snprintf(wu, sizeof wu, "%u", warm);
    const char *argv[] = {"/usr/bin/python3", script, "--model", model, "--inputs", dir, "--frames", fr, "--warmup",
                          wu, NULL};
    char *out = NULL;
    int rc = bench_spawn(argv, &out, why, why_cap);
    double ms = NAN;
    const char *p = out ? strstr(out, "\"cpu_ms_per_frame\":") : NULL;
    if (rc != 0 || !p || sscanf(p + 19, "%lf", &ms) != 1) {
        ms = NAN;
    }
    free(out);
    return ms;
}

/* ---------------------------------------------------------------------------------------- */

static bool find_models_dir(char *out, size_t cap)
{
    snprintf(out, cap, "tools/train/models");
    char probe[1200];
    snprintf(probe, sizeof probe, "%s/game.safetensors", out);
    if (bench_file_exists(probe)) {
        return true;
    }
    char exe[1024];
    if (!bench_self_exe(exe, sizeof exe)) {
        return false;
    }
    for (int up = 0; up < 3; ++up) {
        char *sl = strrchr(exe, '/');
        if (!sl) {
            return false;
        }
        *sl = '\0';
    }
    snprintf(out, cap, "%.900s/tools/train/models", exe);
    snprintf(probe, sizeof probe, "%s/game.safetensors", out);
    return bench_file_exists(probe);
}

typedef struct row {
    const char *model;
    uint32_t verts;
    const char *prec;
    double wall, ms, gmac_frame, kept, torch; /* ms: thread CPU */
    bool int8;                                /* compared with the int8 dot peak, else the FMA peak */
} row;

#define MAX_ROWS 16

enum { OPT_QUICK = 1, OPT_MD, OPT_NO_TORCH, OPT_AVATAR_VERTICES };

static const cli_option k_options[] = {
    {"quick", NULL, OPT_QUICK, "fewer frames and shorter timings (faster, noisier)"},
    {"md", NULL, OPT_MD, "Markdown report"},
    {"no-torch", NULL, OPT_NO_TORCH, "skip the PyTorch eager column"},
    {"avatar-vertices", "N", OPT_AVATAR_VERTICES, "the avatar mesh's size aimed at, 2000..40000 (default 8000)"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench model",
    .synopsis = "weft bench model [--quick] [--md] [--no-torch] [--avatar-vertices N]",
    .about = "The learned model's end-to-end step: ms/frame at fp32/fp16/int8 and 1k/4k vertices, GMAC/s against\n"
             "the measured peaks, PyTorch eager, batched crowds.",
    .options = k_options,
};

int weft_bench_model(int argc, char **argv)
{
    bool quick = false, md = false, torch = true;
    weft_avatar_def ad = weft_default_avatar_def();
    cli_parser cp;
    cli_start(&cp, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&cp, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return cp.exit;
        case OPT_AVATAR_VERTICES:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 2000, 40000, &ad.target_vertices)) {
                return 2;
            }
            break;
        case OPT_QUICK:
            quick = true;
            break;
        case OPT_MD:
            md = true;
            break;
        case OPT_NO_TORCH:
            torch = false;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&cp) != 0) {
        return 2;
    }
    const uint32_t warm = quick ? 3 : 10, timed = quick ? 15 : 60;
    const uint32_t crowd_warm = quick ? 2 : 4, crowd_timed = quick ? 5 : 15;
    const double min_time = quick ? 0.05 : 0.3;
    const uint32_t frames = 2 + warm + timed > 2 + 2 * (crowd_warm + crowd_timed) + 1
                                ? 2 + warm + timed
                                : 2 + 2 * (crowd_warm + crowd_timed) + 1;
    char models_dir[1024], script[1200], exe[1024];
    if (!find_models_dir(models_dir, sizeof models_dir)) {
        fprintf(stderr, "weft bench model: tools/train/models/game.safetensors not found (run from the repository)\n");
        return 1;
    }
    if (torch && !(bench_self_exe(exe, sizeof exe) && bench_find_script(exe, "torch_model_bench.py", script,
                                                                         sizeof script))) {
        fprintf(stderr, "weft bench model: tools/bench/torch_model_bench.py not found; PyTorch column skipped\n");
        torch = false;
    }

    weft_context_def cdef = weft_default_context_def(); /* no parallel_for: one thread */
    weft_context *ctx = NULL;
    weft_body *avatar = NULL;
    if (weft_context_create(&cdef, &ctx) != WEFT_OK || weft_avatar_create(ctx, &ad, &avatar) != WEFT_OK) {
        fprintf(stderr, "weft bench model: %s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    const weft_isa isa = weft_context_isa(ctx);
    const weft_qkernels *q = weft_qkernels_for_isa(isa);
    const weft_kernels *kt = weft_kernels_for_isa(isa);
    peak_fn *dot = NULL, *fma = weft__peak_fma_scalar;
    if (q) {
        bench_variant_peaks(q->variant, &dot, &fma);
    }
    /* GMAC/s of the probes (fp32 FMA lanes; int8 products); measured again at the end, keeping
     * the higher figure, so a clock ramp or a busy neighbour does not flatter the ratios */
    double fma_peak = bench_peak_rate(fma, min_time) * 1e-9;
    double dot_peak = dot ? bench_peak_rate(dot, min_time) * 1e-9 : NAN;

    static const weft_cloth_resolution res[2] = {WEFT_CLOTH_RES_1K, WEFT_CLOTH_RES_4K};
    static const char *const stems[2] = {"game", "garment"};
    static const char *const pnames[3] = {"fp32", "fp16", "int8"};
    static const weft_precision precs[3] = {WEFT_PRECISION_FP32, WEFT_PRECISION_FP16, WEFT_PRECISION_INT8};
    row rows[MAX_ROWS];
    uint32_t nrows = 0;
    scene scenes[2];
    bool have[2] = {false, false};
    char tmpdir[] = "/tmp/weft_bench_model_XXXXXX";
    bool have_tmp = torch && mkdtemp(tmpdir) != NULL;
    bool failed = torch && !have_tmp; /* any model, garment or PyTorch run that could not be measured */
    bench_gemm_probe probes[2] = {{NAN, NAN, NAN, NAN}, {NAN, NAN, NAN, NAN}};
    uint32_t probe_shape[2][3] = {{0, 0, 0}, {0, 0, 0}};
    for (int r = 0; r < 2; ++r) {
        have[r] = scene_make(ctx, avatar, res[r], frames, &scenes[r]);
        if (!have[r]) {
            continue;
        }
        const scene *s = &scenes[r];
        bool inputs = have_tmp && write_inputs(ctx, s, tmpdir);
        if (have_tmp && !inputs) {
            fprintf(stderr, "weft bench model: could not write PyTorch's inputs under %s\n", tmpdir);
            failed = true;
        }
        for (int mi = 0; mi < 2; ++mi) {
            char base[256], path[1200];
            snprintf(base, sizeof base, "%s.safetensors", stems[mi]);
            double t_torch = NAN;
            if (inputs) {
                char why[240] = "";
                snprintf(path, sizeof path, "%.900s/%.250s", models_dir, base);
                t_torch = torch_ms(script, path, tmpdir, warm, timed, why, sizeof why);
                if (isnan(t_torch)) {
                    fprintf(stderr, "weft bench model: PyTorch %s: %s\n", stems[mi], why);
                    failed = true;
                }
            }
            for (int pi = 0; pi < 3; ++pi) {
                bench_model_file(models_dir, stems[mi], base, pnames[pi], path, sizeof path);
                weft_model *m = NULL;
                if (weft_model_load_file(ctx, path, &m) != WEFT_OK) {
                    fprintf(stderr, "weft bench model: %s: %s\n", path, weft_last_error());
                    failed = true;
                    continue;
                }
                weft_garment *g = garment_make(ctx, s, m, precs[pi]);
                failed = failed || !g;
                double kept = 0;
                const double macs = macs_per_frame(ctx, s, m, precs[pi], warm + timed, &kept);
                double wall = NAN, ms = NAN;
                if (g) {
                    time_steps(s, g, warm, timed, &wall, &ms);
                }
                weft_garment_destroy(g);
                if (mi == 0 && pi == 0) {
                    weft_ct_config c;
                    if (weft__ct_bind(m, &c, NULL) == WEFT_OK && q && kt) {
                        probe_shape[r][0] = s->V;
                        probe_shape[r][1] = c.D;
                        probe_shape[r][2] = 2 * c.D;
                        probes[r] = bench_probe_gemm(q, kt, s->V, c.D, 2 * c.D, min_time);
                    }
                }
                weft_model_destroy(m);
                if (nrows < MAX_ROWS) {
                    rows[nrows++] = (row){stems[mi], s->V, pnames[pi], wall, ms, macs * 1e-9, kept, t_torch, pi == 2};
                }
            }
        }
        if (inputs) {
            remove_inputs(tmpdir);
        }
    }
    if (have_tmp) {
        rmdir(tmpdir);
    }

    /* Crowds: the game model at 1k vertices, int8 and fp32, 1 / 8 / 64 characters. */
    typedef struct crowd_row {
        const char *prec;
        uint32_t n;
        double batched, alone;
    } crowd_row;
    crowd_row crowd[6];
    uint32_t ncrowd = 0;
    if (have[0]) {
        char path[1200];
        for (int pi = 0; pi < 3; pi += 2) {
            bench_model_file(models_dir, "game", "game.safetensors", pnames[pi], path, sizeof path);
            weft_model *m = NULL;
            if (weft_model_load_file(ctx, path, &m) != WEFT_OK) {
                continue;
            }
            weft_garment *gs[64] = {NULL};
            uint32_t made = 0;
            while (made < 64 && (gs[made] = garment_make(ctx, &scenes[0], m, precs[pi])) != NULL) {
                made++;
            }
            static const uint32_t counts[3] = {1, 8, 64};
            for (int ci = 0; ci < 3 && made == 64; ++ci) {
                double b, a;
                for (uint32_t i = 0; i < counts[ci]; ++i) {
                    weft_garment_set_state(gs[i], scenes[0].x1, scenes[0].x0);
                }
                time_crowd(&scenes[0], gs, counts[ci], crowd_warm, crowd_timed, &b, &a);
                crowd[ncrowd++] = (crowd_row){pnames[pi], counts[ci], b, a};
            }
            for (uint32_t i = 0; i < made; ++i) {
                weft_garment_destroy(gs[i]);
            }
            weft_model_destroy(m);
        }
    }

    fma_peak = fmax(fma_peak, bench_peak_rate(fma, min_time) * 1e-9);
    if (dot) {
        dot_peak = fmax(dot_peak, bench_peak_rate(dot, min_time) * 1e-9);
    }

    /* ---- report: only of a run that measured everything it set out to ---- */
    for (int r = 0; r < 2; ++r) {
        failed = failed || !have[r];
    }
    if (failed) {
        fprintf(stderr, "weft bench model: failed (above); no table written\n");
        for (int r = 0; r < 2; ++r) {
            scene_free(&scenes[r]); /* scene_make leaves a scene it could not finish freeable */
        }
        weft_body_destroy(avatar);
        weft_context_destroy(ctx);
        return 1;
    }
    /* ---- report ---- */
    const char *dot_name = q ? q->variant : "none";
    if (md) {
        char avatar_opt[48] = "";
        if (ad.target_vertices != weft_default_avatar_def().target_vertices) {
            snprintf(avatar_opt, sizeof avatar_opt, " --avatar-vertices %u", ad.target_vertices);
        }
        printf("Measured by `build/bin/weft bench model%s%s --md` (%s), one thread, T-shirt on the avatar "
               "(%u vertices, %u triangles; walking; the avatar is the collider), CCD off. Times are medians over %u "
               "frames after %u warm-up frames, in CPU time of the stepping thread (wall time shown too: on a shared "
               "machine it also counts time other processes held the core); peaks are measured the same way.\n\n",
               quick ? " --quick" : "", avatar_opt, weft_config_string(), weft_body_vertex_count(avatar),
               weft_body_triangle_count(avatar), timed, warm);
        printf("Peaks in this run: fp32 FMA %.1f GMAC/s (%s level), int8 dot product %.1f GMAC/s (%s).\n\n", fma_peak,
               weft_isa_name(isa), dot_peak, dot_name);
        printf("| model | vertices | precision | CPU ms/frame | wall ms/frame | GMAC/frame | GMAC/s | of peak | "
               "speed vs fp32 | PyTorch CPU ms | weft speed-up vs PyTorch |\n"
               "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    } else {
        printf("%s\npeaks: fp32 FMA %.1f GMAC/s (%s), int8 dot %.1f GMAC/s (%s)\n", weft_config_string(), fma_peak,
               weft_isa_name(isa), dot_peak, dot_name);
        printf("%-8s %6s %-5s %8s %8s %9s %8s %8s %8s %9s %9s\n", "model", "verts", "prec", "cpu ms", "wall ms",
               "GMAC/frm", "GMAC/s", "of peak", "vs fp32", "torch ms", "speed-up");
    }
    for (uint32_t i = 0; i < nrows; ++i) {
        const row *w = &rows[i];
        const double gmacs = w->gmac_frame / (w->ms * 1e-3);
        const double peak = w->int8 ? dot_peak : fma_peak;
        double fp32_ms = NAN;
        for (uint32_t j = 0; j < nrows; ++j) {
            if (rows[j].model == w->model && rows[j].verts == w->verts && strcmp(rows[j].prec, "fp32") == 0) {
                fp32_ms = rows[j].ms;
            }
        }
        if (md) {
            printf("| %s | %u | %s | %.3f | %.3f | %.4f | %.2f | %.1f%% | %.2fx | %.2f | %.1fx |\n", w->model, w->verts,
                   w->prec, w->ms, w->wall, w->gmac_frame, gmacs, 100.0 * gmacs / peak, fp32_ms / w->ms,
                   w->torch, w->torch / w->ms);
        } else {
            printf("%-8s %6u %-5s %8.3f %8.3f %9.4f %8.2f %7.1f%% %7.2fx %9.2f %8.1fx\n", w->model, w->verts, w->prec,
                   w->ms, w->wall, w->gmac_frame, gmacs, 100.0 * gmacs / peak, fp32_ms / w->ms, w->torch,
                   w->torch / w->ms);
        }
    }
    if (md) {
        printf("\nCollider tokens kept after cropping (per frame, mean): ");
        for (uint32_t i = 0; i < nrows; ++i) {
            if (strcmp(rows[i].prec, "fp32") == 0) {
                printf("%s %u: %.0f%s", rows[i].model, rows[i].verts, rows[i].kept, i + 3 < nrows ? "; " : ".\n");
            }
        }
        printf("\nLargest per-frame GEMM alone (GNN fc1 of the game model: vertices x 2D -> D):\n\n");
        printf("| shape (M x K -> N) | int8 GMAC/s | of int8 peak | fp32 GMAC/s | of fp32 peak |\n"
               "|---|---:|---:|---:|---:|\n");
    } else {
        printf("largest per-frame GEMM alone (game GNN fc1):\n");
    }
    for (int r = 0; r < 2; ++r) {
        if (!have[r]) {
            continue;
        }
        const bench_gemm_probe *p = &probes[r];
        if (md) {
            printf("| %u x %u -> %u | %.2f | %.1f%% | %.2f | %.1f%% |\n", probe_shape[r][0], probe_shape[r][2],
                   probe_shape[r][1], p->i8_gmacs, 100.0 * p->i8_gmacs / dot_peak, p->f32_gmacs,
                   100.0 * p->f32_gmacs / fma_peak);
        } else {
            printf("  %5u x %3u -> %3u  int8 %7.2f GMAC/s (%5.1f%% of peak)  fp32 %7.2f GMAC/s (%5.1f%% of peak)\n",
                   probe_shape[r][0], probe_shape[r][2], probe_shape[r][1], p->i8_gmacs,
                   100.0 * p->i8_gmacs / dot_peak, p->f32_gmacs, 100.0 * p->f32_gmacs / fma_peak);
        }
    }
    if (md) {
        printf("\nBatched stepping (`weft_garments_step`), game model, T-shirt at %u vertices, per character:\n\n",
               have[0] ? scenes[0].V : 0);
        printf("| precision | characters | batched CPU ms/character | one by one CPU ms/character | "
               "batched / one by one |\n"
               "|---|---:|---:|---:|---:|\n");
    } else {
        printf("crowd (game, 1k): precision characters batched-ms/char alone-ms/char\n");
    }
    for (uint32_t i = 0; i < ncrowd; ++i) {
        if (md) {
            printf("| %s | %u | %.3f | %.3f | %.2f |\n", crowd[i].prec, crowd[i].n, crowd[i].batched, crowd[i].alone,
                   crowd[i].batched / crowd[i].alone);
        } else {
            printf("  %-5s %3u %9.3f %9.3f\n", crowd[i].prec, crowd[i].n, crowd[i].batched, crowd[i].alone);
        }
    }
    for (int r = 0; r < 2; ++r) {
        scene_free(&scenes[r]);
    }
    weft_body_destroy(avatar);
    weft_context_destroy(ctx);
    return nrows > 0 ? 0 : 1;
}
