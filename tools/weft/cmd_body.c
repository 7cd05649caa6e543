/* weft body: builds the default avatar (and a garment or sheet), optionally poses it with a
 * procedural motion, prints counts and timings, and writes Wavefront OBJ for inspection. */
#include "weft.h"
#include "support_cli.h"
#include "weft/body.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

const char weft_cmd_body_help[] = "build the avatar and garments, write OBJ (weft body --obj out.obj --garment tshirt --res 4k)";

static double now_ms(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

enum {
    OPT_OBJ = 1, OPT_GARMENT, OPT_RES, OPT_MOTION, OPT_TIME, OPT_TPOSE, OPT_HEIGHT, OPT_GIRTH, OPT_LEGS, OPT_SHOULDERS,
    OPT_HIPS, OPT_VERTICES,
};

static const cli_option k_options[] = {
    {"obj", "PATH", OPT_OBJ, "write the avatar (and the garment as a second object) as OBJ"},
    {"garment", "KIND", OPT_GARMENT, "tshirt | skirt | dress | sheet | sheet_irregular"},
    {"res", "RES", OPT_RES, "1k | 4k | 16k | 40k (default 4k)"},
    {"motion", "NAME", OPT_MOTION, "pose with idle | walk | run | jump | dance | arm_raise | flip"},
    {"time", "SECONDS", OPT_TIME, "time in the motion, 0..1e6 (default 0)"},
    {"tpose", NULL, OPT_TPOSE, "pose with the zero (T) pose instead of the bind (A) pose"},
    {"height", "M", OPT_HEIGHT, "avatar shape: standing height in metres, 0..100"},
    {"girth", "G", OPT_GIRTH, "avatar shape: limb and torso thickness scale, 0..100"},
    {"legs", "F", OPT_LEGS, "avatar shape: hip joint height / height, 0..100"},
    {"shoulders", "S", OPT_SHOULDERS, "avatar shape: shoulder span scale, 0..100"},
    {"hips", "H", OPT_HIPS, "avatar shape: hip span and volume scale, 0..100"},
    {"vertices", "N", OPT_VERTICES, "avatar shape: mesh size aimed at, 1..10000000"},
    {0},
};

static void notes(FILE *out)
{
    const weft_avatar_def d = weft_default_avatar_def();
    fprintf(out,
            "Avatar shape defaults: --height %.2f --girth %.2f --legs %.2f --shoulders %.2f --hips %.2f\n"
            "--vertices %u.\n",
            (double)d.height, (double)d.girth, (double)d.leg_fraction, (double)d.shoulder_width, (double)d.hip_width,
            d.target_vertices);
}

static const cli_command k_command = {
    .tool = "weft body",
    .synopsis = "weft body [options]",
    .about = "Builds the default avatar (and a garment or sheet), optionally poses it with a procedural motion,\n"
             "prints counts and timings, and writes Wavefront OBJ for inspection.",
    .options = k_options,
    .notes = notes,
};

static int write_obj(const char *path, const float *bv, uint32_t bn, const uint32_t *bt, uint32_t btn, const float *gv,
                     const float *guv, uint32_t gn, const uint32_t *gt, uint32_t gtn)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "weft body: cannot write '%s'\n", path);
        return 1;
    }
    fprintf(f, "# weft body\no avatar\n");
    for (uint32_t i = 0; i < bn; ++i) {
        fprintf(f, "v %.6f %.6f %.6f\n", (double)bv[3 * i], (double)bv[3 * i + 1], (double)bv[3 * i + 2]);
    }
    for (uint32_t i = 0; i < btn; ++i) {
        fprintf(f, "f %u %u %u\n", bt[3 * i] + 1, bt[3 * i + 1] + 1, bt[3 * i + 2] + 1);
    }
    if (gn) {
        fprintf(f, "o garment\n");
        for (uint32_t i = 0; i < gn; ++i) {
            fprintf(f, "v %.6f %.6f %.6f\n", (double)gv[3 * i], (double)gv[3 * i + 1], (double)gv[3 * i + 2]);
        }
        for (uint32_t i = 0; i < gn; ++i) {
            fprintf(f, "vt %.6f %.6f\n", (double)guv[2 * i], (double)guv[2 * i + 1]);
        }
        for (uint32_t i = 0; i < gtn; ++i) {
            uint32_t a = gt[3 * i] + 1 + bn, b = gt[3 * i + 1] + 1 + bn, c = gt[3 * i + 2] + 1 + bn;
            fprintf(f, "f %u/%u %u/%u %u/%u\n", a, a - bn, b, b - bn, c, c - bn);
        }
    }
    int bad = ferror(f);
    if (fclose(f) != 0 || bad) {
        fprintf(stderr, "weft body: error writing '%s'\n", path);
        return 1;
    }
    return 0;
}

int weft_cmd_body(int argc, char **argv)
{
    const char *obj = NULL, *garment = NULL, *res = "4k", *motion = NULL;
    double t = 0;
    bool tpose = false;
    weft_avatar_def ad = weft_default_avatar_def();
    cli_parser parser;
    cli_start(&parser, &k_command, argc, argv);
    const char *v;
    for (int id; (id = cli_next(&parser, &v)) != CLI_END;) {
        const char *a = cli_name(&k_command, id);
        float *shape = NULL;
        switch (id) {
        case CLI_STOP:
            return parser.exit;
        case OPT_TPOSE:
            tpose = true;
            break;
        case OPT_OBJ:
            obj = v;
            break;
        case OPT_GARMENT:
            garment = v;
            break;
        case OPT_RES:
            res = v;
            break;
        case OPT_MOTION:
            motion = v;
            break;
        case OPT_TIME: {
            float tf = 0.0f;
            if (!cli_float(k_command.tool, a, v, 0.0f, 1e6f, &tf)) {
                return 2;
            }
            t = tf;
            break;
        }
        case OPT_HEIGHT:
            shape = &ad.height;
            break;
        case OPT_GIRTH:
            shape = &ad.girth;
            break;
        case OPT_LEGS:
            shape = &ad.leg_fraction;
            break;
        case OPT_SHOULDERS:
            shape = &ad.shoulder_width;
            break;
        case OPT_HIPS:
            shape = &ad.hip_width;
            break;
        case OPT_VERTICES:
            if (!cli_u32(k_command.tool, a, v, 1, 10000000, &ad.target_vertices)) {
                return 2;
            }
            break;
        default:
            return cli_fail(&k_command, "internal error: an option without a case");
        }
        if (shape && !cli_float(k_command.tool, a, v, 0.0f, 100.0f, shape)) {
            return 2;
        }
    }
    if (cli_no_rest(&parser) != 0) {
        return 2;
    }
    /* Names first, so a typo fails before the avatar is built. */
    weft_cloth_kind kind = WEFT_CLOTH_SHEET;
    weft_cloth_resolution cres = WEFT_CLOTH_RES_4K;
    weft_motion mkind = WEFT_MOTION_IDLE;
    if ((garment && weft_cloth_kind_from_name(garment, &kind) != WEFT_OK) ||
        weft_cloth_resolution_from_name(res, &cres) != WEFT_OK || (motion && weft_motion_from_name(motion, &mkind) != WEFT_OK)) {
        fprintf(stderr, "weft body: %s\n", weft_last_error());
        return 2;
    }
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    if (weft_context_create(&cd, &ctx) != WEFT_OK) {
        fprintf(stderr, "weft body: %s\n", weft_last_error());
        return 1;
    }
    int rc = 1;
    weft_body *body = NULL;
    weft_cloth_mesh *cloth = NULL;
    float *posed = NULL, *posed_cloth = NULL;
    double t0 = now_ms();
    if (weft_avatar_create(ctx, &ad, &body) != WEFT_OK) {
        fprintf(stderr, "weft body: avatar: %s\n", weft_last_error());
        goto out;
    }
    double t1 = now_ms();
    printf("avatar: %u vertices, %u triangles, built in %.1f ms\n", weft_body_vertex_count(body), weft_body_triangle_count(body),
           t1 - t0);
    if (garment) {
        weft_cloth_def def = weft_default_cloth_def(kind);
        def.resolution = cres;
        double g0 = now_ms();
        if (weft_cloth_create(ctx, &def, body, &cloth) != WEFT_OK) {
            fprintf(stderr, "weft body: %s: %s\n", garment, weft_last_error());
            goto out;
        }
        printf("%s %s: %u vertices, %u triangles, built in %.1f ms\n", garment, res, cloth->vertex_count, cloth->triangle_count,
               now_ms() - g0);
    }
    weft_pose pose;
    weft_body_bind_pose(body, &pose);
    if (tpose) {
        memset(&pose, 0, sizeof pose);
    }
    if (motion) {
        weft_motion_def md = weft_default_motion_def(mkind);
        md.height = ad.height;
        if (weft_motion_sample(&md, t, &pose) != WEFT_OK) {
            fprintf(stderr, "weft body: %s\n", weft_last_error());
            goto out;
        }
    }
    uint32_t nv = weft_body_vertex_count(body);
    posed = malloc((size_t)nv * 3 * sizeof(float));
    if (!posed) {
        goto out;
    }
    double p0 = now_ms();
    if (weft_body_pose(body, &pose, posed, NULL) != WEFT_OK) {
        fprintf(stderr, "weft body: %s\n", weft_last_error());
        goto out;
    }
    printf("pose: %.3f ms\n", now_ms() - p0);
    if (cloth) {
        posed_cloth = malloc((size_t)cloth->vertex_count * 3 * sizeof(float));
        if (!posed_cloth) {
            goto out;
        }
        if (cloth->weights) {
            if (weft_body_skin_points(body, &pose, cloth->positions, cloth->weights, cloth->vertex_count, posed_cloth) != WEFT_OK) {
                fprintf(stderr, "weft body: %s\n", weft_last_error());
                goto out;
            }
        } else {
            memcpy(posed_cloth, cloth->positions, (size_t)cloth->vertex_count * 3 * sizeof(float));
        }
    }
    rc = 0;
    if (obj) {
        rc = write_obj(obj, posed, nv, weft_body_triangles(body), weft_body_triangle_count(body), posed_cloth,
                       cloth ? cloth->uvs : NULL, cloth ? cloth->vertex_count : 0, cloth ? cloth->triangles : NULL,
                       cloth ? cloth->triangle_count : 0);
        if (rc == 0) {
            printf("wrote %s\n", obj);
        }
    }
out:
    free(posed);
    free(posed_cloth);
    weft_cloth_destroy(cloth);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
    return rc;
}
