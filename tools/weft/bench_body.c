/* weft bench body: avatar build time, pose (LBS) time per frame, garment build times and
 * vertex counts at every resolution, LBS placement time per garment frame; with --self-contact,
 * how often each procedural motion makes the skinned avatar intersect itself. */
#include "weft.h"
#include "weft/body.h"
#include "weft/ccd.h"

#include "support_cli.h"

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

/* Skinned-body self-intersection per motion: LBS folds the armpit and the groin, and cloth caught
 * in such a fold cannot be made penetration-free (docs/REFSIM.md, Bad input), so these frames
 * are where reference sequences get rejected. For the avatar shapes the dataset draws at their
 * extremes (girth and chest 0.85/1.15 and 1.15, shoulders 0.9/1.1), each motion at amplitude
 * 0.6 and 1, speed 1, one period at 60 Hz, with the arms as drawn and 0.3 rad wider: the share
 * of frames with intersecting body triangles (exact predicates, triangles sharing no vertex) and
 * the most pairs in a frame. */
static int self_contact(weft_context *ctx)
{
    static const float shapes[3][3] = {{0.85f, 0.9f, 0.9f}, {1.0f, 1.0f, 1.0f}, {1.15f, 1.15f, 1.1f}};
    static const char *shape_names[3] = {"slim", "default", "broad"};
    printf("| motion | amplitude | arms | %s | %s | %s |\n|---|---:|---|---:|---:|---:|\n", shape_names[0],
           shape_names[1], shape_names[2]);
    weft_body *bodies[3] = {NULL, NULL, NULL};
    weft_ccd_world *worlds[3] = {NULL, NULL, NULL};
    float *x = NULL;
    int rc = 0;
    for (int k = 0; k < 3 && rc == 0; ++k) {
        weft_avatar_def ad = weft_default_avatar_def();
        ad.girth = shapes[k][0];
        ad.chest = shapes[k][1];
        ad.shoulder_width = shapes[k][2];
        ad.target_vertices = 4000; /* as the garment scenario */
        weft_ccd_world_def wd = weft_default_ccd_world_def();
        if (weft_avatar_create(ctx, &ad, &bodies[k]) != WEFT_OK) {
            rc = 1;
            break;
        }
        wd.cloth_triangles = weft_body_triangles(bodies[k]);
        wd.cloth_triangle_count = weft_body_triangle_count(bodies[k]);
        wd.cloth_vertex_count = weft_body_vertex_count(bodies[k]);
        rc = weft_ccd_world_create(ctx, &wd, &worlds[k]) == WEFT_OK ? 0 : 1;
    }
    uint32_t nmax = 0;
    for (int k = 0; k < 3 && rc == 0; ++k) {
        nmax = weft_body_vertex_count(bodies[k]) > nmax ? weft_body_vertex_count(bodies[k]) : nmax;
    }
    x = rc == 0 ? malloc((size_t)nmax * 3 * sizeof(float)) : NULL;
    rc = rc == 0 && !x ? 1 : rc;
    static const float amplitudes[2] = {0.6f, 1.0f};
    for (int m = 0; m < WEFT_MOTION_COUNT && rc == 0; ++m) {
        if (m == WEFT_MOTION_FLIP) {
            continue; /* not drawn by the dataset */
        }
        for (int a = 0; a < 2 && rc == 0; ++a) {
            for (int spread = 0; spread < 2 && rc == 0; ++spread) {
                printf("| %s | %.1f | %s |", weft_motion_name((weft_motion)m), amplitudes[a], spread ? "+0.3 rad" : "as drawn");
                for (int k = 0; k < 3 && rc == 0; ++k) {
                    weft_motion_def md = weft_default_motion_def((weft_motion)m);
                    md.amplitude = amplitudes[a];
                    md.arm_spread = spread ? 0.3f : 0.0f;
                    const int frames = (int)(weft_motion_period(&md) * 60.0 + 0.5);
                    int hit_frames = 0;
                    uint32_t most = 0;
                    for (int f = 0; f < frames && rc == 0; ++f) {
                        weft_pose pose;
                        weft_ccd_intersections in;
                        rc = weft_motion_sample(&md, f / 60.0, &pose) == WEFT_OK &&
                                     weft_body_pose(bodies[k], &pose, x, NULL) == WEFT_OK &&
                                     weft_ccd_intersect_frame(worlds[k], x, NULL, &in) == WEFT_OK
                                 ? 0
                                 : 1;
                        hit_frames += rc == 0 && in.cloth_cloth > 0;
                        most = rc == 0 && in.cloth_cloth > most ? in.cloth_cloth : most;
                    }
                    printf(" %.0f %% (%u) |", 100.0 * hit_frames / (frames > 0 ? frames : 1), most);
                }
                printf("\n");
            }
        }
    }
    if (rc != 0) {
        fprintf(stderr, "bench body: %s\n", weft_last_error());
    }
    free(x);
    for (int k = 0; k < 3; ++k) {
        weft_ccd_world_destroy(worlds[k]);
        weft_body_destroy(bodies[k]);
    }
    return rc;
}

enum { OPT_FRAMES = 1, OPT_SELF_CONTACT };

static const cli_option k_options[] = {
    {"frames", "N", OPT_FRAMES,
     "frames of the walk posed and timed, 1..1000000 (default 600; the garment\n"
     "skinning is timed over N/10 of them)"},
    {"self-contact", NULL, OPT_SELF_CONTACT,
     "instead: per procedural motion, the share of frames in which the skinned\n"
     "avatar intersects itself (slim, default and broad shapes; amplitude 0.6\n"
     "and 1; arms as drawn and 0.3 rad wider), as a Markdown table"},
    {0},
};

static const cli_command k_command = {
    .tool = "weft bench body",
    .synopsis = "weft bench body [--frames N] [--self-contact]",
    .about = "Times the avatar build, the walk's motion sampling and pose (LBS) per frame, and every garment\n"
             "at every resolution: build time, vertex and triangle counts, LBS placement per frame.",
    .options = k_options,
    .notes = NULL,
};

int weft_bench_body(int argc, char **argv)
{
    uint32_t frame_count = 600;
    bool contact = false;
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_FRAMES:
            if (!cli_u32(k_command.tool, cli_name(&k_command, id), v, 1, 1000000, &frame_count)) {
                return 2;
            }
            break;
        case OPT_SELF_CONTACT:
            contact = true;
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    const int frames = (int)frame_count;
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "%s\n", weft_last_error());
        return 1;
    }
    printf("%s\n", weft_config_string());
    if (contact) {
        int rc = self_contact(ctx);
        weft_context_destroy(ctx);
        return rc;
    }
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
