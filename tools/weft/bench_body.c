/* weft bench body: avatar build time, pose (LBS) time per frame, garment build times and
 * vertex counts at every resolution, LBS placement time per garment frame. */
#include "weft.h"
#include "weft/body.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const char weft_bench_body_help[] = "avatar / garment build times, pose and skinning time per frame";

static double now_ms(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

int weft_bench_body(int argc, char **argv)
{
    int frames = 600;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--frames") == 0 && i + 1 < argc) {
            frames = atoi(argv[++i]);
        } else {
            fprintf(stderr, "usage: weft bench body [--frames N]\n");
            return 2;
        }
    }
    frames = frames < 1 ? 1 : frames;
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "%s\n", weft_last_error());
        return 1;
    }
    printf("%s\n", weft_config_string());
    weft_avatar_def ad = weft_default_avatar_def();
    weft_body *body = NULL;
    double t0 = now_ms();
    if (weft_avatar_create(ctx, &ad, &body) != WEFT_OK) {
        fprintf(stderr, "%s\n", weft_last_error());
        weft_context_destroy(ctx);
        return 1;
    }
    uint32_t nv = weft_body_vertex_count(body);
    printf("avatar build          %8.1f ms   %u vertices, %u triangles\n", now_ms() - t0, nv, weft_body_triangle_count(body));
    float *out = malloc((size_t)nv * 3 * sizeof(float));
    weft_motion_def walk = weft_default_motion_def(WEFT_MOTION_WALK);
    weft_pose pose;
    double t_sample = 0, t_pose = 0;
    for (int f = 0; f < frames; ++f) {
        double a = now_ms();
        weft_motion_sample(&walk, f / 60.0, &pose);
        double b = now_ms();
        weft_body_pose(body, &pose, out, NULL);
        double c = now_ms();
        t_sample += b - a;
        t_pose += c - b;
    }
    printf("motion sample (walk)  %8.4f ms / frame\n", t_sample / frames);
    printf("avatar pose (LBS)     %8.4f ms / frame\n", t_pose / frames);
    free(out);
    for (int k = 0; k < WEFT_CLOTH_COUNT; ++k) {
        for (int r = 0; r < WEFT_CLOTH_RES_COUNT; ++r) {
            weft_cloth_def def = weft_default_cloth_def((weft_cloth_kind)k);
            def.resolution = (weft_cloth_resolution)r;
            weft_cloth_mesh *m = NULL;
            double g0 = now_ms();
            if (weft_cloth_create(ctx, &def, body, &m) != WEFT_OK) {
                fprintf(stderr, "%s\n", weft_last_error());
                continue;
            }
            double g1 = now_ms();
            double skin = 0;
            if (m->weights) {
                float *gp = malloc((size_t)m->vertex_count * 3 * sizeof(float));
                int reps = frames / 10 > 0 ? frames / 10 : 1;
                double s0 = now_ms();
                for (int f = 0; f < reps; ++f) {
                    weft_motion_sample(&walk, f / 60.0, &pose);
                    weft_body_skin_points(body, &pose, m->positions, m->weights, m->vertex_count, gp);
                }
                skin = (now_ms() - s0) / reps;
                free(gp);
            }
            printf("%-16s %-3s %8.1f ms   %6u vertices %6u triangles", weft_cloth_kind_name((weft_cloth_kind)k),
                   weft_cloth_resolution_name((weft_cloth_resolution)r), g1 - g0, m->vertex_count, m->triangle_count);
            if (m->weights) {
                printf("   LBS %.3f ms / frame", skin);
            }
            printf("\n");
            weft_cloth_destroy(m);
        }
    }
    weft_body_destroy(body);
    weft_context_destroy(ctx);
    return 0;
}
