/* weft bench xpbd: solver cost per frame at S = 5, 10, 20, 40 (and 80) substeps, one core,
 * and each run's error against the S = 40 and S = 80 references (the classical half of the
 * speed-versus-accuracy chart). Scenes: `sheet`, a sheet of about --vertices vertices dropped
 * onto a box on the ground, so contacts and self-contacts are part of the cost; `tshirt`, a
 * T-shirt of about --vertices vertices on the default avatar, draped once at S = 40 as simgen
 * drapes it and then stepped through the avatar's motion from that same state at every S.
 * `--only S` runs one substep count with a trajectory hash, for checking that a speedup changes
 * nothing. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime, CLOCK_THREAD_CPUTIME_ID */
#include "weft.h"
#include "weft/sim.h"
#include "scene.h"

#include "support_cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* CPU time of the calling thread in ms: on a shared machine wall time mostly measures the
 * other processes, so the table reports both. */
static double thread_cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int weft_bench_xpbd(int argc, char **argv); /* the CLI registry declares it in main.c */
const char weft_bench_xpbd_help[] = "XPBD ms/frame and error vs S=40/S=80 for S = 5, 10, 20, 40 (sheet on a box, or a T-shirt on the avatar)";

typedef struct run_out {
    float *traj;      /* frames * nv * 3 */
    double ms_frame;  /* mean wall time per frame (solver only) */
    double cpu_frame; /* mean thread CPU time per frame */
    double max_strain;
    double passes, rebuilds; /* proximity passes and candidate-list rebuilds per frame */
    uint32_t cut_frames;     /* frames with intersecting triangles (cloth-cloth or cloth-collider) */
} run_out;

/* What a run steps: the cloth, its state at the start (positions and the frame before), and the
 * collider at the start and after each of the frames (frames + 1 poses; stride 0: it stands). */
typedef struct bench_scene {
    const xmesh *cloth, *col;
    const float *x0, *x_prev;
    const float *col_seq;
    size_t col_stride; /* floats from one pose to the next */
} bench_scene;

/* fast: WEFT_METHOD_XPBD_FAST instead of the reference solver. */
static int run(weft_context *ctx, const bench_scene *sc, uint32_t S, uint32_t frames, bool fast, run_out *out)
{
    const xmesh *cloth = sc->cloth, *col = sc->col;
    weft_garment_def gd = weft_default_garment_def();
    gd.method = fast ? WEFT_METHOD_XPBD_FAST : WEFT_METHOD_XPBD;
    gd.substeps = S;
    gd.ccd.enabled = false;
    gd.rest_positions = cloth->pos;
    gd.vertex_count = cloth->nv;
    gd.triangles = cloth->tris;
    gd.triangle_count = cloth->nt;
    gd.initial_positions = sc->x0;
    gd.collider_rest_positions = col->pos;
    gd.collider_vertex_count = col->nv;
    gd.collider_triangles = col->tris;
    gd.collider_triangle_count = col->nt;
    weft_garment *g = NULL;
    if (weft_garment_create(ctx, &gd, &g) != WEFT_OK || weft_garment_set_state(g, sc->x0, sc->x_prev) != WEFT_OK ||
        weft_garment_set_collider_current(g, sc->col_seq) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
        weft_garment_destroy(g);
        return 1;
    }
    out->traj = malloc(sizeof(float) * 3 * cloth->nv * frames);
    if (!out->traj) {
        weft_garment_destroy(g);
        return 1;
    }
    double total = 0.0, cpu = 0.0;
    out->max_strain = 0.0;
    for (uint32_t f = 0; f < frames; ++f) {
        weft_garment_set_collider(g, sc->col_seq + (size_t)(f + 1) * sc->col_stride);
        double c0 = thread_cpu_ms();
        weft_result r = weft_garment_step(g);
        cpu += thread_cpu_ms() - c0;
        if (r != WEFT_OK) {
            fprintf(stderr, "bench xpbd: step failed: %s\n", weft_last_error());
            weft_garment_destroy(g);
            return 1;
        }
        total += weft_garment_stats(g).step_ms;
        memcpy(out->traj + (size_t)f * cloth->nv * 3, weft_garment_positions(g), sizeof(float) * 3 * cloth->nv);
        xpbd_frame_stats st = weft__xpbd_last_stats(g);
        out->max_strain = st.max_strain > out->max_strain ? st.max_strain : out->max_strain;
        out->passes += (double)st.detections / frames;
        out->rebuilds += (double)st.pair_rebuilds / frames;
    }
    out->ms_frame = total / frames;
    out->cpu_frame = cpu / frames;
    weft_garment_destroy(g);
    /* After the timing: the validator's exact triangle-triangle test on every frame. */
    weft_sim_validator *v = NULL;
    if (weft_sim_validator_create(ctx, cloth->tris, cloth->nt, cloth->nv, col->tris, col->nt, col->nv, &v) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
        return 1;
    }
    out->cut_frames = 0;
    for (uint32_t f = 0; f < frames; ++f) {
        const float *x0 = f ? out->traj + (size_t)(f - 1) * cloth->nv * 3 : sc->x0, *x1 = out->traj + (size_t)f * cloth->nv * 3;
        weft_sim_validation res;
        if (weft_sim_validator_check(v, x0, x1, sc->col_seq + (size_t)f * sc->col_stride,
                                     sc->col_seq + (size_t)(f + 1) * sc->col_stride, &res) != WEFT_OK) {
            fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
            weft_sim_validator_destroy(v);
            return 1;
        }
        out->cut_frames += res.intersection_hits > 0;
    }
    weft_sim_validator_destroy(v);
    return 0;
}

/* The T-shirt scene: simgen's garment scenario with the garment set to a T-shirt (avatar and
 * motion from the seed), draped over its pre-roll at S = 40 (the ground truth's setting, with
 * simgen's extra substeps for a fast body). Fills x0/x_prev with the draped state and col_seq
 * with the body at the end of the drape and after each of `frames` frames of motion. */
static int drape_tshirt(weft_context *ctx, uint32_t vertices, uint64_t seed, uint32_t frames, xscene *xs, float **x0,
                        float **x_prev, float **col_seq)
{
    weft_sim_sequence_def def = weft_sim_default_sequence_def();
    def.scenario = WEFT_SIM_SCENARIO_GARMENT;
    def.cloth_vertices = vertices;
    def.seed = seed;
    def.garment_kind = WEFT_CLOTH_TSHIRT;
    if (xscene_build(ctx, xs, &def, seed, NULL) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
        return 1;
    }
    const uint32_t nv = xs->cloth.nv, nc = xs->collider.nv;
    *x0 = malloc(sizeof(float) * 3 * nv);
    *x_prev = malloc(sizeof(float) * 3 * nv);
    *col_seq = malloc(sizeof(float) * 3 * nc * ((size_t)frames + 1));
    uint32_t *pin_idx = malloc(sizeof(uint32_t) * nv);
    float *pin_tgt = malloc(sizeof(float) * 3 * nv), *c = malloc(sizeof(float) * 3 * nc);
    const weft_garment_def gd = xscene_garment_def(xs, 40, def.fast_collider_factor);
    weft_garment *g = NULL;
    int rc = (*x0 && *x_prev && *col_seq && pin_idx && pin_tgt && c && weft_garment_create(ctx, &gd, &g) == WEFT_OK)
                 ? 0
                 : 1;
    for (uint32_t f = 1; rc == 0 && f <= xs->preroll; ++f) {
        xscene_collider_at(xs, f, c);
        const uint32_t np = xscene_pins_at(xs, f, c, pin_idx, pin_tgt);
        if (weft_garment_set_collider(g, c) != WEFT_OK || weft_garment_set_pins(g, pin_idx, pin_tgt, np) != WEFT_OK ||
            weft_garment_step(g) != WEFT_OK) {
            rc = 1;
        } else if (f + 1 == xs->preroll) {
            memcpy(*x_prev, weft_garment_positions(g), sizeof(float) * 3 * nv);
        }
    }
    if (rc == 0) {
        memcpy(*x0, weft_garment_positions(g), sizeof(float) * 3 * nv);
        for (uint32_t f = 0; f <= frames; ++f) {
            xscene_collider_at(xs, xs->preroll + f, *col_seq + (size_t)f * nc * 3);
        }
    } else {
        fprintf(stderr, "bench xpbd: draping the T-shirt failed: %s\n", weft_last_error());
    }
    weft_garment_destroy(g);
    free(pin_idx);
    free(pin_tgt);
    free(c);
    return rc;
}

/* RMS vertex distance, averaged over all frames. */
static double rmse(const float *a, const float *b, size_t nv, uint32_t frames)
{
    double s = 0.0;
    for (size_t i = 0; i < nv * frames; ++i) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        s += dx * dx + dy * dy + dz * dz;
    }
    return sqrt(s / ((double)nv * frames));
}

enum { OPT_SCENE = 1, OPT_VERTICES, OPT_FRAMES, OPT_NO_80, OPT_ONLY, OPT_SEED, OPT_FAST };

static const cli_option k_options[] = {
    {"scene", "sheet|tshirt", OPT_SCENE,
     "sheet: a sheet dropped onto a box (default); tshirt: a T-shirt on the\n"
     "default avatar (body and motion drawn from --seed), draped once at\n"
     "S = 40, then T frames of the motion at every S from that draped state"},
    {"vertices", "N", OPT_VERTICES, "about N cloth vertices, 64..200000 (default 4096)"},
    {"frames", "T", OPT_FRAMES, "frames per run, 1..100000 (default 60)"},
    {"no-80", NULL, OPT_NO_80, "skip S = 80 (and the error against it)"},
    {"only", "S", OPT_ONLY,
     "run S substeps alone, 1..1000: cost, proximity-pass counters and a hash\n"
     "of the trajectory (equal hashes: bit-identical output, for checking\n"
     "speedups)"},
    {"seed", "X", OPT_SEED, "the tshirt scene's body and motion, 0..2^64-1 (default 1)"},
    {"fast", NULL, OPT_FAST,
     "also run the fast method (WEFT_METHOD_XPBD_FAST: game-style collision\n"
     "projection) at each S, scored against the reference's S = 40 and 80;\n"
     "with --only, the fast method alone"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench xpbd",
    .synopsis = "weft bench xpbd [--scene sheet|tshirt] [--vertices N] [--frames T] [--no-80] [--only S]\n"
                "                [--seed X] [--fast]",
    .about = "XPBD solver cost per frame at S = 5, 10, 20, 40 (and 80) substeps, one core, and each run's error\n"
             "against the S = 40 and S = 80 references.",
    .options = k_options,
};

int weft_bench_xpbd(int argc, char **argv)
{
    uint32_t vertices = 4096, frames = 60, only = 0;
    unsigned long long seed = 1;
    bool with80 = true, tshirt = false;
    bool fast = false;
    cli_parser p;
    cli_start(&p, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&p, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        switch (id) {
        case CLI_STOP:
            return p.exit;
        case OPT_VERTICES:
            if (!cli_u32(k_command.tool, a, v, 64, 200000, &vertices)) {
                return 2;
            }
            break;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, a, v, 1, 100000, &frames)) {
                return 2;
            }
            break;
        case OPT_NO_80:
            with80 = false;
            break;
        case OPT_FAST:
            fast = true;
            break;
        case OPT_ONLY:
            if (!cli_u32(k_command.tool, a, v, 1, 1000, &only)) {
                return 2;
            }
            break;
        case OPT_SEED: {
            uint64_t sd = 0;
            if (!cli_u64(k_command.tool, a, v, 0, UINT64_MAX, &sd)) {
                return 2;
            }
            seed = sd;
            break;
        }
        case OPT_SCENE:
            if (strcmp(v, "sheet") != 0 && strcmp(v, "tshirt") != 0) {
                fprintf(stderr, "weft bench xpbd: --scene wants sheet or tshirt, got '%s'\n", v);
                return 2;
            }
            tshirt = strcmp(v, "tshirt") == 0;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&p) != 0) {
        return 2;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
        return 1;
    }
    xmesh sheet = {0}, box = {0};
    xscene xs = {0};
    float *x0 = NULL, *x_prev = NULL, *col_seq = NULL;
    bench_scene sc = {0};
    int rc = 0;
    if (tshirt) {
        rc = drape_tshirt(ctx, vertices, seed, frames, &xs, &x0, &x_prev, &col_seq);
        sc = (bench_scene){&xs.cloth, &xs.collider, x0, x_prev, col_seq, 3 * (size_t)xs.collider.nv};
        if (rc == 0) {
            printf("# weft bench xpbd: %s; %u-vertex T-shirt draped for %u frames at S = 40, then %u frames of "
                   "the motion at each S, one core\n",
                   xs.description, xs.cloth.nv, xs.preroll, frames);
        }
    } else {
        /* 1 m square sheet 35 cm above the ground, over a 40 x 20 x 40 cm box standing on it. */
        double c[3] = {0, 0.1, 0}, half[3] = {0.2, 0.1, 0.2};
        x0 = NULL;
        if (!xsheet_make(&sheet, XSHEET_RECT, 1.0, 1.0, vertices) || !xshape_ground(&box, 3.0) ||
            !xshape_box(&box, c, half, 0.3) || !(x0 = malloc(sizeof(float) * 3 * sheet.nv))) {
            fprintf(stderr, "bench xpbd: out of memory\n");
            rc = 1;
        } else {
            for (uint32_t i = 0; i < sheet.nv; ++i) {
                x0[3 * i] = sheet.pos[3 * i];
                x0[3 * i + 1] = sheet.pos[3 * i + 1] + 0.35f;
                x0[3 * i + 2] = sheet.pos[3 * i + 2];
            }
            sc = (bench_scene){&sheet, &box, x0, x0, box.pos, 0};
            printf("# weft bench xpbd: %u-vertex sheet dropped on a box, %u frames, one core\n", sheet.nv, frames);
        }
    }
    static const uint32_t steps[] = {5, 10, 20, 40, 80};
    /* Reference runs first (the error's baselines are runs 3 and 4), then the fast ones. */
    const uint32_t nref = only ? (fast ? 0 : 1) : with80 ? 5 : 4;
    const uint32_t nfast = !fast ? 0 : only ? 1 : nref;
    run_out out[10] = {{0}};
    if (rc == 0) {
        printf("# %s\n", weft_config_string());
    }
    for (uint32_t k = 0; rc == 0 && k < nref + nfast; ++k) {
        const bool is_fast = k >= nref;
        const uint32_t S = only ? only : steps[is_fast ? k - nref : k];
        rc = run(ctx, &sc, S, frames, is_fast, &out[k]);
        if (rc == 0 && !only) {
            fprintf(stderr, "%s S = %u done\n", is_fast ? "xpbd-fast" : "xpbd", S);
        }
    }
    const size_t nv = sc.cloth ? sc.cloth->nv : 0;
    if (rc == 0 && only) {
        /* FNV-1a over the trajectory's bytes. */
        uint64_t hash = 1469598103934665603ull;
        const unsigned char *b = (const unsigned char *)out[0].traj;
        for (size_t i = 0; i < sizeof(float) * 3 * nv * frames; ++i) {
            hash = (hash ^ b[i]) * 1099511628211ull;
        }
        printf("| method | substeps | CPU ms/frame | CPU ms/substep | wall ms/frame | max strain | intersecting frames |\n"
               "|---|---|---|---|---|---|---|\n");
        printf("| %s | %u | %.1f | %.2f | %.1f | %.2f %% | %u of %u |\n", fast ? "xpbd-fast" : "xpbd", only,
               out[0].cpu_frame, out[0].cpu_frame / only, out[0].ms_frame, 100.0 * out[0].max_strain, out[0].cut_frames,
               frames);
        if (!fast) {
            printf("# per frame: %.2f proximity passes, %.2f pair-list rebuilds\n", out[0].passes, out[0].rebuilds);
        }
        printf("# trajectory hash %016llx\n", (unsigned long long)hash);
    } else if (rc == 0) {
        printf("| method | substeps | CPU ms/frame | CPU ms/substep | wall ms/frame | RMSE vs S=40 (mm) | RMSE vs S=80 (mm) | "
               "max strain | intersecting frames |\n");
        printf("|---|---|---|---|---|---|---|---|---|\n");
        for (uint32_t k = 0; k < nref + nfast; ++k) {
            const bool is_fast = k >= nref;
            const uint32_t S = steps[is_fast ? k - nref : k];
            double e40 = 1000.0 * rmse(out[k].traj, out[3].traj, nv, frames);
            printf("| %s | %u | %.1f | %.2f | %.1f | %.2f | ", is_fast ? "xpbd-fast" : "xpbd", S, out[k].cpu_frame,
                   out[k].cpu_frame / S, out[k].ms_frame, e40);
            if (with80) {
                printf("%.2f |", 1000.0 * rmse(out[k].traj, out[4].traj, nv, frames));
            } else {
                printf("- |");
            }
            printf(" %.2f %% | %u of %u |\n", 100.0 * out[k].max_strain, out[k].cut_frames, frames);
        }
    }
    for (uint32_t k = 0; k < nref + nfast; ++k) {
        free(out[k].traj);
    }
    free(x0);
    free(x_prev);
    free(col_seq);
    xmesh_free(&sheet);
    xmesh_free(&box);
    if (tshirt) {
        xscene_free(&xs);
    }
    weft_context_destroy(ctx);
    return rc;
}
