/* weft bench xpbd: solver cost per frame at S = 5, 10, 20, 40 (and 80) substeps, one core,
 * and each run's error against the S = 40 and S = 80 references (the classical half of the
 * speed-versus-accuracy chart). Scene: a sheet of about --vertices vertices dropped onto a
 * box on the ground, so contacts and self-contacts are part of the cost. `--only S` runs one
 * substep count with a trajectory hash, for checking that a speedup changes nothing. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime, CLOCK_THREAD_CPUTIME_ID */
#include "weft.h"
#include "xpbd/scene.h"

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
const char weft_bench_xpbd_help[] = "XPBD ms/frame and error vs S=40/S=80 for S = 5, 10, 20, 40 (sheet on a box)";

typedef struct run_out {
    float *traj;      /* frames * nv * 3 */
    double ms_frame;  /* mean wall time per frame (solver only) */
    double cpu_frame; /* mean thread CPU time per frame */
    double max_strain;
    double passes, rebuilds; /* proximity passes and candidate-list rebuilds per frame */
} run_out;

static int run(weft_context *ctx, const xmesh *cloth, const float *init, const xmesh *col, uint32_t S, uint32_t frames,
               run_out *out)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = WEFT_METHOD_XPBD;
    gd.substeps = S;
    gd.ccd = false;
    gd.rest_positions = cloth->pos;
    gd.vertex_count = cloth->nv;
    gd.triangles = cloth->tris;
    gd.triangle_count = cloth->nt;
    gd.initial_positions = init;
    gd.collider_rest_positions = col->pos;
    gd.collider_vertex_count = col->nv;
    gd.collider_triangles = col->tris;
    gd.collider_triangle_count = col->nt;
    weft_garment *g = NULL;
    if (weft_garment_create(ctx, &gd, &g) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
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
        weft_garment_set_collider(g, col->pos);
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
    return 0;
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

int weft_bench_xpbd(int argc, char **argv)
{
    uint32_t vertices = 4096, frames = 60, only = 0;
    bool with80 = true;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--vertices") == 0 && i + 1 < argc) {
            vertices = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--frames") == 0 && i + 1 < argc) {
            frames = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--no-80") == 0) {
            with80 = false;
        } else if (strcmp(argv[i], "--only") == 0 && i + 1 < argc) {
            only = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else {
            fprintf(stderr, "usage: weft bench xpbd [--vertices N (4096)] [--frames T (60)] [--no-80] [--only S]\n"
                            "  --only S  run S substeps alone: cost, proximity-pass counters and a hash of the\n"
                            "            trajectory (equal hashes: bit-identical output, for checking speedups)\n");
            return strcmp(argv[i], "--help") == 0 ? 0 : 2;
        }
    }
    if (vertices < 64 || frames < 1 || (only != 0 && (only > 1000))) {
        fprintf(stderr, "bench xpbd: --vertices >= 64, --frames >= 1, --only 1..1000\n");
        return 2;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "bench xpbd: %s\n", weft_last_error());
        return 1;
    }
    /* 1 m square sheet 15 cm above a 40 x 20 x 40 cm box standing on the ground. */
    xmesh cloth = {0}, col = {0};
    double c[3] = {0, 0.1, 0}, half[3] = {0.2, 0.1, 0.2};
    if (!xsheet_make(&cloth, XSHEET_RECT, 1.0, 1.0, vertices) || !xshape_ground(&col, 3.0) ||
        !xshape_box(&col, c, half, 0.3)) {
        fprintf(stderr, "bench xpbd: out of memory\n");
        return 1;
    }
    float *init = malloc(sizeof(float) * 3 * cloth.nv);
    for (uint32_t i = 0; i < cloth.nv; ++i) {
        init[3 * i] = cloth.pos[3 * i];
        init[3 * i + 1] = cloth.pos[3 * i + 1] + 0.35f;
        init[3 * i + 2] = cloth.pos[3 * i + 2];
    }
    static const uint32_t steps[] = {5, 10, 20, 40, 80};
    uint32_t nruns = with80 ? 5 : 4;
    run_out out[5] = {{0}};
    printf("# weft bench xpbd: %u-vertex sheet dropped on a box, %u frames, one core\n", cloth.nv, frames);
    printf("# %s\n", weft_config_string());
    if (only != 0) {
        int rc = run(ctx, &cloth, init, &col, only, frames, &out[0]);
        if (rc == 0) {
            /* FNV-1a over the trajectory's bytes. */
            uint64_t hash = 1469598103934665603ull;
            const unsigned char *b = (const unsigned char *)out[0].traj;
            for (size_t i = 0; i < sizeof(float) * 3 * (size_t)cloth.nv * frames; ++i) {
                hash = (hash ^ b[i]) * 1099511628211ull;
            }
            printf("| substeps | CPU ms/frame | CPU ms/substep | wall ms/frame | max strain |\n|---|---|---|---|---|\n");
            printf("| %u | %.1f | %.2f | %.1f | %.2f %% |\n", only, out[0].cpu_frame, out[0].cpu_frame / only,
                   out[0].ms_frame, 100.0 * out[0].max_strain);
            printf("# per frame: %.2f proximity passes, %.2f pair-list rebuilds\n", out[0].passes, out[0].rebuilds);
            printf("# trajectory hash %016llx\n", (unsigned long long)hash);
        }
        free(out[0].traj);
        free(init);
        xmesh_free(&cloth);
        xmesh_free(&col);
        weft_context_destroy(ctx);
        return rc;
    }
    for (uint32_t k = 0; k < nruns; ++k) {
        if (run(ctx, &cloth, init, &col, steps[k], frames, &out[k]) != 0) {
            return 1;
        }
        fprintf(stderr, "S = %u done\n", steps[k]);
    }
    printf("| substeps | CPU ms/frame | CPU ms/substep | wall ms/frame | RMSE vs S=40 (mm) | RMSE vs S=80 (mm) | max strain |\n");
    printf("|---|---|---|---|---|---|---|\n");
    for (uint32_t k = 0; k < nruns; ++k) {
        double e40 = 1000.0 * rmse(out[k].traj, out[3].traj, cloth.nv, frames);
        printf("| %u | %.1f | %.2f | %.1f | %.2f | ", steps[k], out[k].cpu_frame, out[k].cpu_frame / steps[k],
               out[k].ms_frame, e40);
        if (with80) {
            printf("%.2f |", 1000.0 * rmse(out[k].traj, out[4].traj, cloth.nv, frames));
        } else {
            printf("- |");
        }
        printf(" %.2f %% |\n", 100.0 * out[k].max_strain);
    }
    for (uint32_t k = 0; k < nruns; ++k) {
        free(out[k].traj);
    }
    free(init);
    xmesh_free(&cloth);
    xmesh_free(&col);
    weft_context_destroy(ctx);
    return 0;
}
