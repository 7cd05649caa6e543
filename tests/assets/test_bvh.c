/* BVH import and retargeting: synthetic clips with known answers, the CMU clips Debian's
 * assimp-testmodels installs, malformed files, and a mutation fuzz loop. */
#define _POSIX_C_SOURCE 200809L

#include "test.h"
#include "bvh.h"

#include <stdarg.h>
#include <stdint.h>
#include <zlib.h>

#define CMU_DIR "/usr/share/assimp/models/BVH/"
#define PI_D 3.14159265358979323846

static weft_context *g_ctx;

static bool all_finite(const float *x, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        if (!isfinite(x[i])) {
            return false;
        }
    }
    return true;
}

/* ---------------------------------------------------------------------------------------- */
/* Independent forward kinematics: Rodrigues + chain walk, double precision.                  */

static void rodrigues(const float *aa, double r[3][3])
{
    double x = aa[0], y = aa[1], z = aa[2];
    double th = sqrt(x * x + y * y + z * z);
    double c = cos(th), s = sin(th), t = 1 - c;
    if (th < 1e-12) {
        double id[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        memcpy(r, id, sizeof id);
        return;
    }
    x /= th;
    y /= th;
    z /= th;
    r[0][0] = c + x * x * t;
    r[0][1] = x * y * t - z * s;
    r[0][2] = x * z * t + y * s;
    r[1][0] = y * x * t + z * s;
    r[1][1] = c + y * y * t;
    r[1][2] = y * z * t - x * s;
    r[2][0] = z * x * t - y * s;
    r[2][1] = z * y * t + x * s;
    r[2][2] = c + z * z * t;
}

static void fk(const weft_pose *pose, const float *rest, double out_pos[24][3])
{
    double world[24][3][3];
    for (int j = 0; j < 24; ++j) {
        double local[3][3];
        rodrigues(pose->rotations + 3 * j, local);
        int p = weft_joint_parent((uint32_t)j);
        if (p < 0) {
            memcpy(world[j], local, sizeof local);
            for (int k = 0; k < 3; ++k) {
                out_pos[j][k] = rest[k] + pose->translation[k];
            }
            continue;
        }
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) {
                world[j][a][b] = world[p][a][0] * local[0][b] + world[p][a][1] * local[1][b] + world[p][a][2] * local[2][b];
            }
        }
        double off[3] = {rest[3 * j] - rest[3 * p], rest[3 * j + 1] - rest[3 * p + 1], rest[3 * j + 2] - rest[3 * p + 2]};
        for (int k = 0; k < 3; ++k) {
            out_pos[j][k] = out_pos[p][k] + world[p][k][0] * off[0] + world[p][k][1] * off[1] + world[p][k][2] * off[2];
        }
    }
}

/* ---------------------------------------------------------------------------------------- */
/* A BVH written in SMPL joint names whose offsets are the default rest joints, so retargeting
 * has no rest correction and local rotations must come back as written.                     */

typedef struct text_buf {
    char *data;
    size_t len, cap;
} text_buf;

static void tb_printf(text_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void tb_printf(text_buf *b, const char *fmt, ...)
{
    va_list ap;
    for (;;) {
        va_start(ap, fmt);
        int n = vsnprintf(b->data ? b->data + b->len : NULL, b->data ? b->cap - b->len : 0, fmt, ap);
        va_end(ap);
        if (b->data && b->len + (size_t)n < b->cap) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = b->cap ? b->cap * 2 : 4096;
        while (cap < b->len + (size_t)n + 1) {
            cap *= 2;
        }
        b->data = realloc(b->data, cap);
        b->cap = cap;
    }
}

static void write_joint(text_buf *b, const float *rest, int j, int depth)
{
    int p = weft_joint_parent((uint32_t)j);
    double off[3] = {0, 0, 0};
    if (p >= 0) {
        for (int k = 0; k < 3; ++k) {
            off[k] = rest[3 * j + k] - rest[3 * p + k];
        }
    } else {
        for (int k = 0; k < 3; ++k) {
            off[k] = rest[k];
        }
    }
    tb_printf(b, "%*s%s %s\n%*s{\n%*sOFFSET %.6f %.6f %.6f\n", 2 * depth, "", p < 0 ? "ROOT" : "JOINT",
              weft_joint_name((uint32_t)j), 2 * depth, "", 2 * depth + 2, "", off[0], off[1], off[2]);
    tb_printf(b, "%*sCHANNELS %s\n", 2 * depth + 2, "",
              p < 0 ? "6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" : "3 Zrotation Yrotation Xrotation");
    bool child = false;
    for (int c = 0; c < 24; ++c) {
        if (weft_joint_parent((uint32_t)c) == j) {
            write_joint(b, rest, c, depth + 1);
            child = true;
        }
    }
    if (!child) {
        tb_printf(b, "%*sEnd Site\n%*s{\n%*sOFFSET 0.0 0.05 0.0\n%*s}\n", 2 * depth + 2, "", 2 * depth + 2, "",
                  2 * depth + 4, "", 2 * depth + 2, "");
    }
    tb_printf(b, "%*s}\n", 2 * depth, "");
}

/* frames: rows of 3 + 72 values (root position, then Z Y X degrees per joint in tree order). */
static text_buf smpl_bvh(const float *rest, const double *values, int frames, double frame_time)
{
    text_buf b = {0};
    tb_printf(&b, "HIERARCHY\n");
    write_joint(&b, rest, 0, 0);
    tb_printf(&b, "MOTION\nFrames: %d\nFrame Time: %.6f\n", frames, frame_time);
    for (int f = 0; f < frames; ++f) {
        for (int i = 0; i < 75; ++i) {
            tb_printf(&b, "%.6f%c", values[75 * f + i], i == 74 ? '\n' : ' ');
        }
    }
    return b;
}

/* Joint order in the file: depth-first from the pelvis, children in index order. */
static int tree_order(int out[24])
{
    int n = 0, stack[24], sp = 0;
    stack[sp++] = 0;
    while (sp) {
        int j = stack[--sp];
        out[n++] = j;
        for (int c = 23; c >= 0; --c) {
            if (weft_joint_parent((uint32_t)c) == j) {
                stack[sp++] = c;
            }
        }
    }
    return n;
}

static void set_zyx(double *frame, int joint, double z, double y, double x)
{
    int order[24];
    tree_order(order);
    for (int i = 0; i < 24; ++i) {
        if (order[i] == joint) {
            frame[3 + 3 * i + 0] = z;
            frame[3 + 3 * i + 1] = y;
            frame[3 + 3 * i + 2] = x;
        }
    }
}

static double *synthetic_frames(const float *rest, int frames)
{
    double *v = calloc((size_t)frames * 75, sizeof(double));
    for (int f = 0; f < frames; ++f) {
        double *row = v + 75 * f;
        double a = (double)f / (double)(frames > 1 ? frames - 1 : 1);
        row[0] = 0.3 * a + 0.1; /* drifts in x from 0.1 */
        row[1] = rest[1] + 0.05 * a;
        row[2] = -0.2;
        set_zyx(row, WEFT_JOINT_LEFT_SHOULDER, -90.0 * a, 0, 0);
        set_zyx(row, WEFT_JOINT_LEFT_KNEE, 0, 0, 60.0 * a);
        set_zyx(row, WEFT_JOINT_RIGHT_ELBOW, 0, 45.0 * a, 0);
        set_zyx(row, WEFT_JOINT_PELVIS, 0, 30.0 * a, 0);
    }
    return v;
}

static void test_synthetic_exact(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    double *vals = synthetic_frames(rest, 3);
    text_buf b = smpl_bvh(rest, vals, 3, 1.0 / 30.0);
    weft_bvh_def def = weft_default_bvh_def();
    def.unit_scale = 1.0f; /* the file is in metres */
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, b.data, b.len, &def, &clip), WEFT_OK);
    if (clip) {
        /* 2 intervals of 1/30 s at 60 Hz */
        CHECK_EQ_INT(clip->frame_count, 5);
        CHECK_NEAR(clip->fps, 60.0, 1e-4);
        weft_pose pose;
        CHECK_RESULT(weft_clip_sample(clip, 2.0 / 30.0, &pose), WEFT_OK);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_LEFT_SHOULDER + 2], -PI_D / 2, 1e-4);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_LEFT_SHOULDER + 0], 0.0, 1e-4);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_LEFT_KNEE + 0], PI_D / 3, 1e-4);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_RIGHT_ELBOW + 1], PI_D / 4, 1e-4);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_PELVIS + 1], PI_D / 6, 1e-4);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_HEAD + 0], 0.0, 1e-5);
        /* the root path starts above the origin and keeps its height above the floor */
        CHECK_NEAR(pose.translation[0], 0.3, 1e-4);
        CHECK_NEAR(pose.translation[1], 0.05, 1e-4);
        CHECK_NEAR(pose.translation[2], 0.0, 1e-4);
        /* halfway between the 30 Hz frames: slerp gives half the angle */
        CHECK_RESULT(weft_clip_sample(clip, 0.5 / 30.0, &pose), WEFT_OK);
        CHECK_NEAR(pose.rotations[3 * WEFT_JOINT_LEFT_SHOULDER + 2], -PI_D / 8, 1e-3);
        weft_clip_destroy(clip);
    }
    /* keep_horizontal_origin keeps the source's X/Z */
    def.keep_horizontal_origin = true;
    clip = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, b.data, b.len, &def, &clip), WEFT_OK);
    if (clip) {
        double pos[24][3];
        weft_pose pose;
        CHECK_RESULT(weft_clip_sample(clip, 0.0, &pose), WEFT_OK);
        fk(&pose, rest, pos);
        CHECK_NEAR(pos[0][0], 0.1, 1e-4);
        CHECK_NEAR(pos[0][1], rest[1], 1e-4);
        CHECK_NEAR(pos[0][2], -0.2, 1e-4);
        weft_clip_destroy(clip);
    }
    free(b.data);
    free(vals);
}

/* The lowest foot joint's (ankle or toe) height above its rest height, by the test's own FK. */
static double lowest_foot_lift(const weft_pose *pose, const float *rest)
{
    static const int feet[4] = {WEFT_JOINT_LEFT_ANKLE, WEFT_JOINT_RIGHT_ANKLE, WEFT_JOINT_LEFT_FOOT, WEFT_JOINT_RIGHT_FOOT};
    double pos[24][3], lowest = INFINITY;
    fk(pose, rest, pos);
    for (int i = 0; i < 4; ++i) {
        lowest = fmin(lowest, pos[feet[i]][1] - rest[3 * feet[i] + 1]);
    }
    return lowest;
}

static int cmp_double_asc(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The clip stands on the target's floor whatever the source's floor height: the synthetic clip
 * sunk 0.3 m (and raised 0.7 m) loads to the same root path as the original, whose feet rest on
 * y = 0; keep_source_height keeps the source's offset. */
static void test_floor_placement(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    const int frames = 5;
    double *vals = synthetic_frames(rest, frames);
    text_buf b0 = smpl_bvh(rest, vals, frames, 1.0 / 60.0);
    const double shifts[2] = {-0.3, 0.7};
    weft_bvh_def def = weft_default_bvh_def();
    def.unit_scale = 1.0f;
    weft_clip *ref = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, b0.data, b0.len, &def, &ref), WEFT_OK);
    for (int s = 0; s < 2 && ref; ++s) {
        for (int f = 0; f < frames; ++f) {
            vals[75 * f + 1] += shifts[s] - (s ? shifts[s - 1] : 0.0);
        }
        text_buf b = smpl_bvh(rest, vals, frames, 1.0 / 60.0);
        for (int keep = 0; keep < 2; ++keep) {
            def.keep_source_height = keep;
            weft_clip *clip = NULL;
            CHECK_RESULT(weft_bvh_load_memory(g_ctx, b.data, b.len, &def, &clip), WEFT_OK);
            for (uint32_t f = 0; clip && f < clip->frame_count; ++f) {
                const float *t = clip->translations + 3 * f, *t0 = ref->translations + 3 * f;
                CHECK_NEAR(t[0], t0[0], 1e-5);
                CHECK_NEAR(t[1], t0[1] + (keep ? shifts[s] : 0.0), 1e-5);
                CHECK_NEAR(t[2], t0[2], 1e-5);
            }
            weft_clip_destroy(clip);
        }
        free(b.data);
    }
    weft_clip_destroy(ref);
    free(b0.data);
    free(vals);
}

/* Rest correction: a source whose rest pose has the left arm 45 degrees down (an A-pose) while
 * the SMPL rest is a T-pose. Retargeting matches bone directions (twist about a bone is not
 * observable from joint positions), so the check is on posed joint positions: the source's rest
 * frame must put the SMPL arm 45 degrees down, and a source motion that lifts the arm back to
 * horizontal must put it where the SMPL rest has it. */
static void test_rest_correction(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    float apose[72];
    memcpy(apose, rest, sizeof apose);
    const int arm[3] = {WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_LEFT_WRIST, WEFT_JOINT_LEFT_HAND};
    const float *pivot = rest + 3 * WEFT_JOINT_LEFT_SHOULDER;
    const double c = cos(-PI_D / 4), sn = sin(-PI_D / 4);
    for (int i = 0; i < 3; ++i) {
        const float *p = rest + 3 * arm[i];
        double dx = p[0] - pivot[0], dy = p[1] - pivot[1];
        apose[3 * arm[i] + 0] = (float)(pivot[0] + c * dx - sn * dy);
        apose[3 * arm[i] + 1] = (float)(pivot[1] + sn * dx + c * dy);
    }
    double *vals = calloc(2 * 75, sizeof(double));
    vals[1] = vals[75 + 1] = rest[1];
    set_zyx(vals + 75, WEFT_JOINT_LEFT_SHOULDER, 45.0, 0, 0); /* frame 1: arm back to horizontal */
    text_buf b = smpl_bvh(apose, vals, 2, 1.0 / 60.0);
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, b.data, b.len, &def, &clip), WEFT_OK);
    if (clip) {
        for (int f = 0; f < 2; ++f) {
            weft_pose pose;
            memcpy(pose.rotations, clip->rotations + 72 * f, sizeof pose.rotations);
            memcpy(pose.translation, clip->translations + 3 * f, sizeof pose.translation);
            double pos[24][3];
            fk(&pose, rest, pos);
            const float *want = f == 0 ? apose : rest; /* rest frame: A-pose arm; frame 1: T-pose arm */
            for (int i = 0; i < 3; ++i) {
                for (int k = 0; k < 3; ++k) {
                    CHECK_NEAR(pos[arm[i]][k], want[3 * arm[i] + k], 1e-4);
                }
            }
            for (int k = 0; k < 3; ++k) { /* the other arm is untouched */
                CHECK_NEAR(pos[WEFT_JOINT_RIGHT_HAND][k], rest[3 * WEFT_JOINT_RIGHT_HAND + k], 1e-4);
            }
        }
        weft_clip_destroy(clip);
    }
    free(b.data);
    free(vals);
}

/* Leg-length scaling: the same file against a body twice as big doubles the root path. */
static void test_translation_scale(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    double *vals = synthetic_frames(rest, 3);
    text_buf b = smpl_bvh(rest, vals, 3, 1.0 / 60.0);
    float big[72];
    for (int i = 0; i < 72; ++i) {
        big[i] = 2.0f * rest[i];
    }
    weft_bvh_def def = weft_default_bvh_def();
    def.rest_joints = big;
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, b.data, b.len, &def, &clip), WEFT_OK);
    if (clip) {
        CHECK_EQ_INT(clip->frame_count, 3);
        const float *last = clip->translations + 3 * 2;
        CHECK_NEAR(last[0], 2.0 * 0.3, 1e-4);
        CHECK_NEAR(last[1] + big[1], 2.0 * (rest[1] + 0.05), 1e-4); /* pelvis height doubles */
        weft_clip_destroy(clip);
    }
    free(b.data);
    free(vals);
}

/* ---------------------------------------------------------------------------------------- */
/* The Debian CMU clips.                                                                      */

static void check_cmu_clip_on(const char *file, double min_seconds, const float *rest)
{
    weft_bvh_def def = weft_default_bvh_def();
    def.rest_joints = rest;
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, file, &def, &clip), WEFT_OK);
    if (!clip) {
        return;
    }
    double seconds = (double)(clip->frame_count - 1) / clip->fps;
    printf("%s: %u frames at %.0f Hz (%.2f s), name '%s'\n", file, clip->frame_count, (double)clip->fps, seconds, clip->name);
    CHECK_NEAR(clip->fps, 60.0, 1e-4);
    CHECK(seconds >= min_seconds);
    CHECK(all_finite(clip->rotations, (size_t)clip->frame_count * 72));
    /* Plausibility of the retargeted body, by independent FK: the pelvis stays at human hip
     * height on average, the lowest ankle touches the floor, the head is above the pelvis in
     * most frames and the left hip stays on the body's left (+X in the pelvis frame). */
    double pelvis_sum = 0, min_ankle = 1e9;
    uint32_t head_up = 0, left_ok = 0;
    for (uint32_t f = 0; f < clip->frame_count; ++f) {
        weft_pose pose;
        memcpy(pose.rotations, clip->rotations + (size_t)72 * f, sizeof pose.rotations);
        memcpy(pose.translation, clip->translations + (size_t)3 * f, sizeof pose.translation);
        double p[24][3];
        fk(&pose, rest, p);
        pelvis_sum += p[0][1];
        min_ankle = fmin(min_ankle, fmin(p[WEFT_JOINT_LEFT_ANKLE][1], p[WEFT_JOINT_RIGHT_ANKLE][1]));
        head_up += p[WEFT_JOINT_HEAD][1] > p[0][1] + 0.3;
        double pelvis_r[3][3];
        rodrigues(pose.rotations, pelvis_r);
        double d[3] = {p[WEFT_JOINT_LEFT_HIP][0] - p[0][0], p[WEFT_JOINT_LEFT_HIP][1] - p[0][1], p[WEFT_JOINT_LEFT_HIP][2] - p[0][2]};
        double local_x = pelvis_r[0][0] * d[0] + pelvis_r[1][0] * d[1] + pelvis_r[2][0] * d[2];
        left_ok += local_x > 0.0;
    }
    double pelvis_mean = pelvis_sum / clip->frame_count;
    printf("  pelvis mean height %.3f m, lowest ankle %.3f m, head above pelvis %.1f%%\n", pelvis_mean, min_ankle,
           100.0 * head_up / clip->frame_count);
    CHECK(pelvis_mean > 0.6 && pelvis_mean < 1.2);
    CHECK(min_ankle > -0.08 && min_ankle < 0.2);
    CHECK(head_up > clip->frame_count * 9 / 10);
    CHECK_EQ_INT(left_ok, clip->frame_count);
    weft_clip_destroy(clip);
}

static void check_cmu_clip(const char *file, double min_seconds)
{
    check_cmu_clip_on(file, min_seconds, weft_bvh_default_rest_joints());
}

/* The same plausibility on weft's own avatar (its zero-pose joints, feet on y = 0), which is
 * what the render sample drives. */
static void test_cmu_on_avatar(void)
{
    weft_body *body = NULL;
    weft_avatar_def adef = weft_default_avatar_def();
    adef.target_vertices = 2000;
    CHECK_RESULT(weft_avatar_create(g_ctx, &adef, &body), WEFT_OK);
    if (body) {
        check_cmu_clip_on(CMU_DIR "01_01.bvh", 20.0, weft_body_rest_joints(body));
        weft_body_destroy(body);
    }
}


/* ---------------------------------------------------------------------------------------- */
/* Joint angles against the file's own forward kinematics.                                    */

#define REF_MAX_JOINTS 64

/* A BVH read independently of the importer (no assimp): hierarchy, channels, frames. */
typedef struct ref_bvh {
    uint32_t n, frames;
    char name[REF_MAX_JOINTS][32];
    int parent[REF_MAX_JOINTS];
    double offset[REF_MAX_JOINTS][3];
    int nch[REF_MAX_JOINTS], ch[REF_MAX_JOINTS][6], ch0[REF_MAX_JOINTS]; /* channel kinds, first column */
    uint32_t columns;
    double frame_time;
    double *values; /* frames * columns */
} ref_bvh;

/* Channel kinds: 0..2 X/Y/Z position, 3..5 X/Y/Z rotation. */
static int ref_channel(const char *t)
{
    static const char *const k[6] = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
    for (int i = 0; i < 6; ++i) {
        if (!strcmp(t, k[i])) {
            return i;
        }
    }
    return -1;
}

static bool ref_bvh_read(const char *path, ref_bvh *b)
{
    memset(b, 0, sizeof *b);
    FILE *f = fopen(path, "r");
    if (!f) {
        return false;
    }
    char tok[64];
    int stack[REF_MAX_JOINTS + 2], depth = 0, current = -1;
    bool end_site = false, ok = true;
    while (ok && fscanf(f, "%63s", tok) == 1 && strcmp(tok, "MOTION") != 0) {
        if (!strcmp(tok, "ROOT") || !strcmp(tok, "JOINT")) {
            ok = b->n < REF_MAX_JOINTS && fscanf(f, "%31s", b->name[b->n]) == 1;
            b->parent[b->n] = current;
            current = (int)b->n++;
        } else if (!strcmp(tok, "End")) {
            ok = fscanf(f, "%63s", tok) == 1; /* Site */
            end_site = true;
        } else if (!strcmp(tok, "{")) {
            stack[depth++] = end_site ? -2 : current;
        } else if (!strcmp(tok, "}")) {
            const int closed = stack[--depth];
            end_site = false;
            if (closed >= 0) {
                current = b->parent[closed];
            }
        } else if (!strcmp(tok, "OFFSET")) {
            double o[3];
            ok = fscanf(f, "%lf %lf %lf", &o[0], &o[1], &o[2]) == 3;
            if (!end_site) {
                memcpy(b->offset[current], o, sizeof o);
            }
        } else if (!strcmp(tok, "CHANNELS")) {
            ok = fscanf(f, "%d", &b->nch[current]) == 1 && b->nch[current] <= 6;
            b->ch0[current] = (int)b->columns;
            for (int c = 0; ok && c < b->nch[current]; ++c) {
                ok = fscanf(f, "%63s", tok) == 1 && (b->ch[current][c] = ref_channel(tok)) >= 0;
            }
            b->columns += (uint32_t)b->nch[current];
        }
    }
    double dt = 0;
    ok = ok && fscanf(f, " Frames: %u Frame Time: %lf", &b->frames, &dt) == 2 && b->frames > 0 && dt > 0;
    b->frame_time = dt;
    b->values = ok ? malloc(sizeof(double) * b->frames * b->columns) : NULL;
    for (size_t i = 0; ok && b->values && i < (size_t)b->frames * b->columns; ++i) {
        ok = fscanf(f, "%lf", &b->values[i]) == 1;
    }
    fclose(f);
    return ok && b->values;
}

static int ref_find(const ref_bvh *b, const char *name)
{
    for (uint32_t j = 0; j < b->n; ++j) {
        if (!strcmp(b->name[j], name)) {
            return (int)j;
        }
    }
    return -1;
}

static void mat_mul(double a[3][3], double b[3][3], double out[3][3])
{
    double t[3][3];
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            t[i][k] = a[i][0] * b[0][k] + a[i][1] * b[1][k] + a[i][2] * b[2][k];
        }
    }
    memcpy(out, t, sizeof t);
}

/* World joint positions of frame f: R = R_parent * (the channel rotations in file order). */
static void ref_fk(const ref_bvh *b, uint32_t f, double pos[REF_MAX_JOINTS][3])
{
    double world[REF_MAX_JOINTS][3][3];
    const double *v = b->values + (size_t)f * b->columns;
    for (uint32_t j = 0; j < b->n; ++j) {
        double r[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, t[3] = {0, 0, 0};
        for (int c = 0; c < b->nch[j]; ++c) {
            const double x = v[b->ch0[j] + c];
            const int kind = b->ch[j][c];
            if (kind < 3) {
                t[kind] = x;
                continue;
            }
            const double a = x * PI_D / 180.0, cs = cos(a), sn = sin(a);
            double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
            const int p = (kind - 3 + 1) % 3, q = (kind - 3 + 2) % 3; /* the plane the axis turns */
            e[p][p] = cs, e[p][q] = -sn, e[q][p] = sn, e[q][q] = cs;
            mat_mul(r, e, r);
        }
        const int pj = b->parent[j];
        if (pj < 0) {
            memcpy(world[j], r, sizeof r);
            for (int k = 0; k < 3; ++k) {
                pos[j][k] = t[k] + b->offset[j][k];
            }
            continue;
        }
        mat_mul(world[pj], r, world[j]);
        for (int k = 0; k < 3; ++k) {
            pos[j][k] = pos[pj][k] + world[pj][k][0] * b->offset[j][0] + world[pj][k][1] * b->offset[j][1] +
                        world[pj][k][2] * b->offset[j][2];
        }
    }
}

/* Angle in degrees between the bones a0 -> a1 and b0 -> b1. */
static double bone_angle(const double a0[3], const double a1[3], const double b0[3], const double b1[3])
{
    double u[3], w[3], uu = 0, ww = 0, uw = 0;
    for (int k = 0; k < 3; ++k) {
        u[k] = a1[k] - a0[k];
        w[k] = b1[k] - b0[k];
        uu += u[k] * u[k];
        ww += w[k] * w[k];
        uw += u[k] * w[k];
    }
    const double c = uw / sqrt(uu * ww);
    return acos(c > 1 ? 1 : c < -1 ? -1 : c) * 180.0 / PI_D;
}

/* Retargeting matches bone directions, so every angle between two bones (an elbow's bend, a
 * knee's, an upper arm against the trunk) is the file's own, whatever the two skeletons' rest
 * poses: a CMU file read and forward-kinematised here without assimp, against the retargeted
 * clip's SMPL joints, over all its frames. Returns the worst angle error (degrees). */
static double check_joint_angles(const char *path, const char *label, bool verbose)
{
    ref_bvh b;
    if (!ref_bvh_read(path, &b)) {
        printf("no %s: skipped\n", path);
        return 0.0;
    }
    weft_bvh_def def = weft_default_bvh_def();
    def.fps = (float)(1.0 / b.frame_time); /* the file's own rate: frame f here is frame f there */
    weft_clip *clip = NULL;
    double worst_all = 0.0;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, path, &def, &clip), WEFT_OK);
    /* bones as (CMU joint, CMU joint, SMPL joint, SMPL joint) */
    static const struct {
        const char *what, *a0, *a1, *b0, *b1;
        int s[4];
    } pairs[] = {
        {"left elbow", "LeftArm", "LeftForeArm", "LeftForeArm", "LeftHand",
         {WEFT_JOINT_LEFT_SHOULDER, WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_LEFT_WRIST}},
        {"right elbow", "RightArm", "RightForeArm", "RightForeArm", "RightHand",
         {WEFT_JOINT_RIGHT_SHOULDER, WEFT_JOINT_RIGHT_ELBOW, WEFT_JOINT_RIGHT_ELBOW, WEFT_JOINT_RIGHT_WRIST}},
        {"left knee", "LeftUpLeg", "LeftLeg", "LeftLeg", "LeftFoot",
         {WEFT_JOINT_LEFT_HIP, WEFT_JOINT_LEFT_KNEE, WEFT_JOINT_LEFT_KNEE, WEFT_JOINT_LEFT_ANKLE}},
        {"right knee", "RightUpLeg", "RightLeg", "RightLeg", "RightFoot",
         {WEFT_JOINT_RIGHT_HIP, WEFT_JOINT_RIGHT_KNEE, WEFT_JOINT_RIGHT_KNEE, WEFT_JOINT_RIGHT_ANKLE}},
        {"left upper arm to right upper arm", "LeftArm", "LeftForeArm", "RightArm", "RightForeArm",
         {WEFT_JOINT_LEFT_SHOULDER, WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_RIGHT_SHOULDER, WEFT_JOINT_RIGHT_ELBOW}},
        {"left thigh to right shin", "LeftUpLeg", "LeftLeg", "RightLeg", "RightFoot",
         {WEFT_JOINT_LEFT_HIP, WEFT_JOINT_LEFT_KNEE, WEFT_JOINT_RIGHT_KNEE, WEFT_JOINT_RIGHT_ANKLE}},
        {"left forearm to right thigh", "LeftForeArm", "LeftHand", "RightUpLeg", "RightLeg",
         {WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_LEFT_WRIST, WEFT_JOINT_RIGHT_HIP, WEFT_JOINT_RIGHT_KNEE}},
    };
    const size_t np = sizeof pairs / sizeof pairs[0];
    int idx[16][4];
    bool found = true;
    for (size_t i = 0; i < np; ++i) {
        const char *n[4] = {pairs[i].a0, pairs[i].a1, pairs[i].b0, pairs[i].b1};
        for (int k = 0; k < 4; ++k) {
            idx[i][k] = ref_find(&b, n[k]);
            found &= idx[i][k] >= 0;
        }
    }
    CHECK(found);
    if (clip && found) {
        CHECK_EQ_INT(clip->frame_count, b.frames);
        const float *rest = weft_bvh_default_rest_joints();
        double worst[16] = {0}, sum[16] = {0};
        const uint32_t frames = clip->frame_count < b.frames ? clip->frame_count : b.frames;
        for (uint32_t f = 0; f < frames; ++f) {
            double rp[REF_MAX_JOINTS][3], sp[24][3];
            ref_fk(&b, f, rp);
            weft_pose pose;
            memcpy(pose.rotations, clip->rotations + (size_t)72 * f, sizeof pose.rotations);
            memcpy(pose.translation, clip->translations + (size_t)3 * f, sizeof pose.translation);
            fk(&pose, rest, sp);
            for (size_t i = 0; i < np; ++i) {
                const double want = bone_angle(rp[idx[i][0]], rp[idx[i][1]], rp[idx[i][2]], rp[idx[i][3]]);
                const double got = bone_angle(sp[pairs[i].s[0]], sp[pairs[i].s[1]], sp[pairs[i].s[2]], sp[pairs[i].s[3]]);
                const double e = fabs(got - want);
                worst[i] = fmax(worst[i], e);
                sum[i] += e;
            }
        }
        for (size_t i = 0; i < np; ++i) {
            if (verbose) {
                printf("  %-36s mean %.5f deg, worst %.5f deg over %u frames\n", pairs[i].what, sum[i] / frames,
                       worst[i], frames);
            }
            CHECK_MSG(worst[i] < 0.05, "%s %s: worst %.3f deg", label, pairs[i].what, worst[i]);
            worst_all = fmax(worst_all, worst[i]);
        }
    }
    weft_clip_destroy(clip);
    free(b.values);
    return worst_all;
}

static void test_joint_angles_match_the_file(void) { check_joint_angles(CMU_DIR "01_01.bvh", "01_01", true); }

/* The same for every clip of the mocap library's test split (inflated to build/tests first). */
static void test_joint_angles_test_split(void)
{
    FILE *list = fopen(WEFT_SOURCE_DIR "/samples/mocap/clips.csv", "r");
    CHECK(list != NULL);
    char line[2048];
    int clips = 0;
    double worst = 0.0;
    while (list && fgets(line, sizeof line, list)) {
        char *comma = strchr(line, ',');
        if (!comma || strncmp(comma + 1, "test,", 5) != 0) {
            continue;
        }
        *comma = '\0';
        char gz[3072], plain[3072];
        snprintf(gz, sizeof gz, "%s/samples/mocap/%.1023s", WEFT_SOURCE_DIR, line);
        const char *base = strrchr(line, '/') ? strrchr(line, '/') + 1 : line;
        snprintf(plain, sizeof plain, "%s/tests/angles_%.200s", WEFT_BINARY_DIR, base);
        char *dot = strstr(plain, ".gz");
        if (dot) {
            *dot = '\0';
        }
        gzFile in = gzopen(gz, "rb");
        FILE *out = fopen(plain, "wb");
        CHECK(in && out);
        char buf[65536];
        int got;
        while (in && out && (got = gzread(in, buf, sizeof buf)) > 0) {
            fwrite(buf, 1, (size_t)got, out);
        }
        if (in) {
            gzclose(in);
        }
        if (out) {
            fclose(out);
        }
        worst = fmax(worst, check_joint_angles(plain, base, false));
        remove(plain);
        ++clips;
    }
    if (list) {
        fclose(list);
    }
    printf("  bone angles of %d test clips against their files: worst %.5f deg\n", clips, worst);
    CHECK_EQ_INT(clips, 17);
}

static void test_cmu_01_01(void) { check_cmu_clip(CMU_DIR "01_01.bvh", 20.0); }
static void test_cmu_01_03(void) { check_cmu_clip(CMU_DIR "01_03.bvh", 30.0); }
static void test_boxing_toes(void) { check_cmu_clip(CMU_DIR "Boxing_Toes.bvh", 25.0); }

/* ---------------------------------------------------------------------------------------- */
/* Bad input.                                                                                 */

static void expect_fail(const char *text, weft_result expected, const char *what)
{
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *sentinel = (weft_clip *)(uintptr_t)0x1234;
    weft_clip *clip = sentinel;
    weft_result r = weft_bvh_load_memory(g_ctx, text, strlen(text), &def, &clip);
    CHECK_MSG(r == expected, "%s: got %s (%s), expected %s", what, weft_result_string(r), weft_last_error(),
              weft_result_string(expected));
    CHECK_MSG(clip == sentinel, "%s: out_clip was written on failure", what);
    CHECK_MSG(weft_last_error()[0] != '\0', "%s: no message", what);
    if (r == expected) {
        printf("  %-28s -> %s\n", what, weft_last_error());
    }
}

static char *replace_once(const char *s, const char *find, const char *repl)
{
    const char *at = strstr(s, find);
    size_t n = strlen(s), nf = strlen(find), nr = strlen(repl);
    char *out = malloc(n - nf + nr + 1);
    if (!at) {
        memcpy(out, s, n + 1);
        return out;
    }
    size_t pre = (size_t)(at - s);
    memcpy(out, s, pre);
    memcpy(out + pre, repl, nr);
    memcpy(out + pre + nr, at + nf, n - pre - nf + 1);
    return out;
}

static void test_bad_input(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    double *vals = synthetic_frames(rest, 2);
    text_buf b = smpl_bvh(rest, vals, 2, 1.0 / 30.0);
    tb_printf(&b, "%s", ""); /* make sure it is terminated */
    const char *good = b.data;
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *clip = NULL;

    CHECK_RESULT(weft_bvh_load_memory(NULL, good, strlen(good), &def, &clip), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, NULL, 10, &def, &clip), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, good, 0, &def, &clip), WEFT_ERROR_FORMAT);
    weft_bvh_def raw = {0};
    raw.fps = 60.0f;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, good, strlen(good), &raw, &clip), WEFT_ERROR_INVALID_ARGUMENT);
    def.fps = NAN;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, good, strlen(good), &def, &clip), WEFT_ERROR_INVALID_ARGUMENT);
    def = weft_default_bvh_def();
    float nan_rest[72];
    memcpy(nan_rest, rest, sizeof nan_rest);
    nan_rest[40] = NAN;
    def.rest_joints = nan_rest;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, good, strlen(good), &def, &clip), WEFT_ERROR_NOT_FINITE);
    def = weft_default_bvh_def();
    def.first_frame = 7;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, good, strlen(good), &def, &clip), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_bvh_load_file(g_ctx, "/nonexistent/weft.bvh", &def, &clip), WEFT_ERROR_IO);

    expect_fail("", WEFT_ERROR_FORMAT, "empty");
    expect_fail("this is not a bvh file", WEFT_ERROR_FORMAT, "garbage");
    char *s;
    s = replace_once(good, "MOTION", "NOTION");
    expect_fail(s, WEFT_ERROR_FORMAT, "no MOTION");
    free(s);
    s = replace_once(good, "Frames: 2", "Frames: 0");
    expect_fail(s, WEFT_ERROR_FORMAT, "zero frames");
    free(s);
    s = replace_once(good, "Frames: 2", "Frames: 3");
    expect_fail(s, WEFT_ERROR_SIZE_MISMATCH, "frames x channels mismatch");
    free(s);
    s = replace_once(good, "Frame Time: 0.033333", "Frame Time: 0");
    expect_fail(s, WEFT_ERROR_FORMAT, "zero frame time");
    free(s);
    s = replace_once(good, "Frame Time: 0.033333", "Frame Time: nan");
    expect_fail(s, WEFT_ERROR_FORMAT, "NaN frame time");
    free(s);
    /* a NaN in the motion values: the first value after the frame time */
    const char *motion = strstr(good, "Frame Time:");
    const char *line = strchr(motion, '\n') + 1;
    const char *value_end = strchr(line, ' ');
    size_t pre = (size_t)(line - good);
    s = malloc(strlen(good) + 8);
    memcpy(s, good, pre);
    strcpy(s + pre, "nan");
    strcat(s, value_end);
    expect_fail(s, WEFT_ERROR_NOT_FINITE, "NaN motion value");
    free(s);
    /* a root 1e30 units away: finite, but no motion a body can follow; refused by name */
    s = malloc(strlen(good) + 8);
    memcpy(s, good, pre);
    strcpy(s + pre, "1e30");
    strcat(s, value_end);
    expect_fail(s, WEFT_ERROR_FORMAT, "absurd root translation");
    CHECK(strstr(weft_last_error(), "root translation") != NULL);
    free(s);
    s = replace_once(good, "OFFSET ", "OFFSET inf ");
    expect_fail(s, WEFT_ERROR_NOT_FINITE, "infinite offset");
    free(s);
    s = replace_once(good, "CHANNELS 3", "CHANNELS 9");
    expect_fail(s, WEFT_ERROR_FORMAT, "bad channel count");
    free(s);
    s = replace_once(good, "}\n", "");
    expect_fail(s, WEFT_ERROR_FORMAT, "unbalanced braces");
    free(s);
    /* an unknown skeleton: rename the left knee so no naming family covers the legs */
    s = replace_once(good, "JOINT left_knee", "JOINT knee_L");
    expect_fail(s, WEFT_ERROR_FORMAT, "unknown skeleton");
    free(s);
    /* truncated halfway through the motion block */
    s = malloc(strlen(good) + 1);
    strcpy(s, good);
    s[strlen(good) - 40] = '\0';
    expect_fail(s, WEFT_ERROR_SIZE_MISMATCH, "truncated motion");
    free(s);
    free(b.data);
    free(vals);
}

/* ---------------------------------------------------------------------------------------- */
/* Mutation fuzzing: corrupted copies of a small SMPL-named BVH and of the head of 01_01 must
 * either load into a finite clip or fail with a message; never crash or leak (ASan build).   */

static char *cmu_head(int frames)
{
    FILE *f = fopen(CMU_DIR "01_01.bvh", "rb");
    if (!f) {
        return NULL;
    }
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    char *motion = strstr(buf, "MOTION");
    if (!motion) {
        return NULL;
    }
    char *data = strstr(motion, "Frame Time:");
    data = strchr(data, '\n') + 1;
    text_buf out = {0};
    tb_printf(&out, "%.*sMOTION\nFrames: %d\nFrame Time: .0083333\n", (int)(motion - buf), buf, frames);
    char *p = data;
    for (int i = 0; i < frames; ++i) {
        char *nl = strchr(p, '\n');
        if (!nl) {
            free(out.data);
            return NULL;
        }
        tb_printf(&out, "%.*s\n", (int)(nl - p), p);
        p = nl + 1;
    }
    return out.data;
}

static void mutate(test_rng *rng, const char *src, size_t n, char *dst, size_t *out_n)
{
    memcpy(dst, src, n);
    size_t m = n;
    int kind = (int)(test_rng_u32(rng) % 5);
    int edits = 1 + (int)(test_rng_u32(rng) % 4);
    static const char alphabet[] = "0123456789.-+eE {}\n\tnaifHIERARCHYMOTIONJOINTCHANNELSOFFSET:";
    for (int e = 0; e < edits && m > 1; ++e) {
        size_t at = test_rng_u32(rng) % m;
        switch (kind) {
        case 0: /* replace a byte */
            dst[at] = alphabet[test_rng_u32(rng) % (sizeof alphabet - 1)];
            break;
        case 1: /* truncate */
            m = at + 1;
            break;
        case 2: { /* delete a span */
            size_t len = 1 + test_rng_u32(rng) % 16;
            len = at + len > m ? m - at : len;
            memmove(dst + at, dst + at + len, m - at - len);
            m -= len;
            break;
        }
        case 3: /* swap digits for a huge number */
            if (m + 12 < n + 64) {
                memmove(dst + at + 12, dst + at, m - at);
                memcpy(dst + at, "999999999999", 12);
                m += 12;
            }
            break;
        default: /* insert a sign or exponent */
            if (m + 1 < n + 64) {
                memmove(dst + at + 1, dst + at, m - at);
                dst[at] = "-e+"[test_rng_u32(rng) % 3];
                m += 1;
            }
            break;
        }
    }
    *out_n = m;
}

static void fuzz_source(const char *src, int iterations, unsigned long long seed)
{
    size_t n = strlen(src);
    char *buf = malloc(n + 64);
    test_rng rng = {seed};
    int ok = 0, failed = 0;
    weft_bvh_def def = weft_default_bvh_def();
    for (int it = 0; it < iterations; ++it) {
        size_t m;
        mutate(&rng, src, n, buf, &m);
        weft_clip *clip = NULL;
        weft_result r = weft_bvh_load_memory(g_ctx, buf, m, &def, &clip);
        if (r == WEFT_OK) {
            ok++;
            CHECK(clip && clip->frame_count > 0);
            if (clip) {
                CHECK(all_finite(clip->rotations, (size_t)clip->frame_count * 72));
                CHECK(all_finite(clip->translations, (size_t)clip->frame_count * 3));
            }
            weft_clip_destroy(clip);
        } else {
            failed++;
            CHECK(clip == NULL);
            CHECK(weft_last_error()[0] != '\0');
        }
    }
    printf("fuzz: %d mutations loaded, %d rejected with a message\n", ok, failed);
    CHECK(failed > 0);
    free(buf);
}

static void test_fuzz_synthetic(void)
{
    const float *rest = weft_bvh_default_rest_joints();
    double *vals = synthetic_frames(rest, 4);
    text_buf b = smpl_bvh(rest, vals, 4, 1.0 / 30.0);
    fuzz_source(b.data, 300, 0x9e3779b97f4a7c15ull);
    free(b.data);
    free(vals);
}

static void test_fuzz_cmu(void)
{
    char *head = cmu_head(24);
    CHECK(head != NULL);
    if (head) {
        fuzz_source(head, 200, 0xd1b54a32d192ed03ull);
        free(head);
    }
}

/* ---------------------------------------------------------------------------------------- */
/* The mocap library (samples/mocap): gzip-compressed clips read as they are.                 */

#define MOCAP_DIR WEFT_SOURCE_DIR "/samples/mocap/clips/"

/* A .bvh.gz loads to exactly the clip its inflated text gives through the memory loader. */
static void test_mocap_gz_equals_plain(void)
{
    const char *path = MOCAP_DIR "walk_cmu07_01.bvh.gz";
    gzFile f = gzopen(path, "rb");
    CHECK(f != NULL);
    if (!f) {
        return;
    }
    size_t cap = 4u << 20, len = 0;
    char *text = malloc(cap);
    int got;
    while (text && (got = gzread(f, text + len, (unsigned)(cap - len))) > 0) {
        len += (size_t)got;
    }
    gzclose(f);
    CHECK(len > 1000 && len < cap);
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *a = NULL, *b = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, path, &def, &a), WEFT_OK);
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &b), WEFT_OK);
    if (a && b) {
        CHECK_EQ_INT(a->frame_count, b->frame_count);
        CHECK(a->frame_count == b->frame_count &&
              memcmp(a->rotations, b->rotations, (size_t)a->frame_count * 72 * sizeof(float)) == 0 &&
              memcmp(a->translations, b->translations, (size_t)a->frame_count * 3 * sizeof(float)) == 0);
        CHECK(strcmp(a->name, "walk_cmu07_01") == 0);
    }
    weft_clip_destroy(a);
    weft_clip_destroy(b);
    free(text);
}

/* Every clip of the library's test split loads, at 60 fps, with finite poses and a root that
 * stays within 50 m of the start. */
static void test_mocap_test_split_loads(void)
{
    FILE *f = fopen(WEFT_SOURCE_DIR "/samples/mocap/clips.csv", "r");
    CHECK(f != NULL);
    if (!f) {
        return;
    }
    char line[2048];
    int clips = 0;
    while (fgets(line, sizeof line, f)) {
        char *comma = strchr(line, ',');
        if (!comma || strncmp(comma + 1, "test,", 5) != 0) {
            continue;
        }
        *comma = '\0';
        char path[3072];
        snprintf(path, sizeof path, "%s/samples/mocap/%.1023s", WEFT_SOURCE_DIR, line);
        weft_bvh_def def = weft_default_bvh_def();
        weft_clip *c = NULL;
        CHECK_MSG(weft_bvh_load_file(g_ctx, path, &def, &c) == WEFT_OK, "%s: %s", path, weft_last_error());
        if (c) {
            CHECK_MSG(fabsf(c->fps - 60.0f) < 1e-3f && c->frame_count > 60, "%s: %u frames at %g fps", path, c->frame_count, (double)c->fps);
            CHECK(all_finite(c->rotations, (size_t)c->frame_count * 72));
            CHECK(all_finite(c->translations, (size_t)c->frame_count * 3));
            for (uint32_t k = 0; k < c->frame_count; ++k) {
                const float *t = c->translations + 3 * (size_t)k;
                CHECK_MSG(fabsf(t[0]) < 50.0f && fabsf(t[1]) < 50.0f && fabsf(t[2]) < 50.0f, "%s frame %u", path, k);
                if (!(fabsf(t[0]) < 50.0f && fabsf(t[1]) < 50.0f && fabsf(t[2]) < 50.0f)) {
                    break;
                }
            }
            /* on the floor (the library's floors are not at y = 0): the 5th percentile of the
             * lowest foot joint stands at its rest height, and no frame sinks a foot 10 cm */
            double *lift = malloc(c->frame_count * sizeof *lift);
            for (uint32_t k = 0; lift && k < c->frame_count; ++k) {
                weft_pose pose;
                CHECK_RESULT(weft_clip_sample(c, (double)k / 60.0, &pose), WEFT_OK);
                lift[k] = lowest_foot_lift(&pose, weft_bvh_default_rest_joints());
            }
            if (lift) {
                qsort(lift, c->frame_count, sizeof *lift, cmp_double_asc);
                const double p5 = lift[(size_t)(0.05 * (double)(c->frame_count - 1) + 0.5)];
                CHECK_MSG(fabs(p5) < 1e-3 && lift[0] > -0.10, "%s: lowest foot 5th percentile %.4f m, min %.4f m", path,
                          p5, lift[0]);
            }
            free(lift);
            /* how far the clip was moved: against the source's own floor (keep_source_height) */
            weft_bvh_def keep = weft_default_bvh_def();
            keep.keep_source_height = true;
            weft_clip *src = NULL;
            CHECK_RESULT(weft_bvh_load_file(g_ctx, path, &keep, &src), WEFT_OK);
            if (src) {
                printf("  %-28s stood on the floor: raised %+.1f cm\n", strrchr(path, '/') + 1,
                       100.0 * (double)(c->translations[1] - src->translations[1]));
            }
            weft_clip_destroy(src);
            ++clips;
        }
        weft_clip_destroy(c);
    }
    fclose(f);
    CHECK_EQ_INT(clips, 17);
}

/* The library clip's text with its joints renamed: `pairs` maps MotionBuilder names to another
 * naming, applied to the ROOT/JOINT lines only (one pass, so chains of renames do not mix). */
static char *renamed_clip(const char *gz_path, const char *const (*pairs)[2], size_t npairs, const char *prefix,
                          size_t *out_len)
{
    gzFile f = gzopen(gz_path, "rb");
    if (!f) {
        return NULL;
    }
    size_t cap = 8u << 20, len = 0;
    char *text = malloc(cap);
    int got;
    while (text && (got = gzread(f, text + len, (unsigned)(cap - len - 1))) > 0) {
        len += (size_t)got;
    }
    gzclose(f);
    if (!text) {
        return NULL;
    }
    text[len] = '\0';
    char *out = malloc(len * 2 + 4096);
    size_t o = 0;
    for (const char *p = text; *p;) {
        const char *eol = strchr(p, '\n');
        size_t n = eol ? (size_t)(eol - p) + 1 : strlen(p);
        const char *kw = p;
        while (*kw == ' ' || *kw == '\t') {
            ++kw;
        }
        const bool joint = !strncmp(kw, "JOINT ", 6) || !strncmp(kw, "ROOT ", 5);
        if (joint) {
            const char *name = strchr(kw, ' ') + 1;
            size_t nl = strcspn(name, " \t\r\n");
            const char *repl = NULL;
            for (size_t k = 0; k < npairs && !repl; ++k) {
                if (strlen(pairs[k][0]) == nl && !strncmp(name, pairs[k][0], nl)) {
                    repl = pairs[k][1];
                }
            }
            memcpy(out + o, p, (size_t)(name - p));
            o += (size_t)(name - p);
            o += (size_t)sprintf(out + o, "%s%s", prefix, repl ? repl : "");
            if (!repl) {
                memcpy(out + o, name, nl);
                o += nl;
            }
            memcpy(out + o, name + nl, n - (size_t)(name + nl - p));
            o += n - (size_t)(name + nl - p);
        } else {
            memcpy(out + o, p, n);
            o += n;
        }
        p += n;
    }
    free(text);
    *out_len = o;
    return out;
}

/* A library clip renamed to CMU's 3ds Max naming and to Mixamo's (with its namespace prefix)
 * retargets to exactly the avatar pose its MotionBuilder original gives, and the report names
 * the naming and every source joint. */
static void test_namings_retarget_identically(void)
{
    static const char *const max_names[][2] = {
        {"LeftUpLeg", "LeftHip"},       {"RightUpLeg", "RightHip"},       {"LeftLeg", "LeftKnee"},
        {"RightLeg", "RightKnee"},      {"LeftFoot", "LeftAnkle"},        {"RightFoot", "RightAnkle"},
        {"LeftToeBase", "LeftToe"},     {"RightToeBase", "RightToe"},     {"LowerBack", "lowerback"},
        {"Spine", "Chest"},             {"Spine1", "Chest2"},             {"Neck", "lowerneck"},
        {"Neck1", "Neck"},              {"LeftShoulder", "LeftCollar"},   {"RightShoulder", "RightCollar"},
        {"LeftArm", "LeftShoulder"},    {"RightArm", "RightShoulder"},    {"LeftForeArm", "LeftElbow"},
        {"RightForeArm", "RightElbow"}, {"LeftHand", "LeftWrist"},        {"RightHand", "RightWrist"},
        {"LeftFingerBase", "lhand"},    {"RightFingerBase", "rhand"},     {"LeftHandIndex1", "LFingers"},
        {"RightHandIndex1", "RFingers"}};
    static const char *const mixamo_names[][2] = {
        {"LowerBack", "Spine"}, {"Spine", "Spine1"}, {"Spine1", "Spine2"}, {"LeftFingerBase", "LeftHandMiddle1"},
        {"RightFingerBase", "RightHandMiddle1"}, {"Neck1", "NeckTwist"}, {"LHipJoint", "LHip"}, {"RHipJoint", "RHip"}};
    const char *path = MOCAP_DIR "gesture_cmu02_10_b.bvh.gz";
    weft_bvh_def def = weft_default_bvh_def();
    weft_bvh_report rep;
    def.report = &rep;
    weft_clip *ref = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, path, &def, &ref), WEFT_OK);
    CHECK(ref && strcmp(rep.naming, "CMU/MotionBuilder") == 0 && rep.mapped == 24);
    struct {
        const char *const (*pairs)[2];
        size_t n;
        const char *prefix, *naming;
    } cases[] = {{max_names, sizeof max_names / sizeof max_names[0], "", "CMU/3ds Max"},
                 {mixamo_names, sizeof mixamo_names / sizeof mixamo_names[0], "mixamorig:", "Mixamo"}};
    for (size_t c = 0; c < 2 && ref; ++c) {
        size_t len = 0;
        char *text = renamed_clip(path, cases[c].pairs, cases[c].n, cases[c].prefix, &len);
        CHECK(text != NULL);
        weft_clip *clip = NULL;
        CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_OK);
        if (clip) {
            CHECK_MSG(strcmp(rep.naming, cases[c].naming) == 0, "naming '%s', expected '%s'", rep.naming, cases[c].naming);
            CHECK_EQ_INT(rep.mapped, 24);
            CHECK_EQ_INT(clip->frame_count, ref->frame_count);
            double worst = 0.0;
            for (size_t k = 0; clip->frame_count == ref->frame_count && k < (size_t)ref->frame_count * 72; ++k) {
                worst = fmax(worst, fabs((double)clip->rotations[k] - ref->rotations[k]));
            }
            CHECK_MSG(worst < 1e-6, "%s: rotations differ by %g rad", cases[c].naming, worst);
            CHECK(memcmp(clip->translations, ref->translations, (size_t)ref->frame_count * 3 * sizeof(float)) == 0);
        }
        if (c == 0 && clip) { /* the 3ds Max report names the 3ds Max joints */
            CHECK(strcmp(rep.source[WEFT_JOINT_SPINE1], "lowerback") == 0);
            CHECK(strcmp(rep.source[WEFT_JOINT_LEFT_HAND], "lhand") == 0);
            CHECK(strcmp(rep.source[WEFT_JOINT_LEFT_FOOT], "LeftToe") == 0);
        }
        weft_clip_destroy(clip);
        free(text);
    }
    weft_clip_destroy(ref);
}

/* A skeleton half of whose joints have names no naming knows is refused, naming what is missing;
 * the caller's clip is left alone. */
static void test_unknown_skeleton_names_the_missing(void)
{
    static const char *const odd[][2] = {{"LeftUpLeg", "thigh_l"}, {"RightUpLeg", "thigh_r"}, {"LeftLeg", "calf_l"},
                                         {"RightLeg", "calf_r"},   {"LeftFoot", "foot_l"},    {"RightFoot", "foot_r"}};
    size_t len = 0;
    char *text = renamed_clip(MOCAP_DIR "walk_cmu07_01.bvh.gz", odd, sizeof odd / sizeof odd[0], "", &len);
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *clip = (weft_clip *)(uintptr_t)1;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_ERROR_FORMAT);
    CHECK(clip == (weft_clip *)(uintptr_t)1);
    CHECK_MSG(strstr(weft_last_error(), "left_knee (LeftLeg)") != NULL && strstr(weft_last_error(), "18 of 24") != NULL,
              "%s", weft_last_error());
    free(text);
}

/* A skeleton no naming table knows (every joint renamed to a rig's own names) retargets through
 * a joint map file exactly as its MotionBuilder original does through the tables; map files
 * with mistakes are refused naming the line or the joint. */
static void test_joint_map_file(void)
{
    static const char *const rig[][2] = {
        {"Hips", "root_jnt"},         {"LeftUpLeg", "thigh.L"},       {"RightUpLeg", "thigh.R"},
        {"LowerBack", "spine_01"},    {"LeftLeg", "shin.L"},          {"RightLeg", "shin.R"},
        {"Spine", "spine_02"},        {"LeftFoot", "foot.L"},         {"RightFoot", "foot.R"},
        {"Spine1", "spine_03"},       {"LeftToeBase", "toe.L"},       {"RightToeBase", "toe.R"},
        {"Neck", "neck_01"},          {"LeftShoulder", "clavicle.L"}, {"RightShoulder", "clavicle.R"},
        {"Head", "head_jnt"},         {"LeftArm", "upper_arm.L"},     {"RightArm", "upper_arm.R"},
        {"LeftForeArm", "forearm.L"}, {"RightForeArm", "forearm.R"},  {"LeftHand", "hand.L"},
        {"RightHand", "hand.R"},      {"LeftFingerBase", "palm.L"},   {"RightFingerBase", "palm.R"}};
    const char *path = MOCAP_DIR "gesture_cmu02_10_b.bvh.gz";
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *ref = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, path, &def, &ref), WEFT_OK);
    size_t len = 0;
    char *text = renamed_clip(path, rig, sizeof rig / sizeof rig[0], "", &len);
    CHECK(text != NULL);
    /* the tables alone do not know it */
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "or pass a joint map") != NULL || strstr(weft_last_error(), "of 24") != NULL);
    const char *map_path = WEFT_BINARY_DIR "/tests/rig_joint_map.txt";
    FILE *f = fopen(map_path, "w");
    CHECK(f != NULL);
    if (f) {
        fprintf(f, "# SMPL joint   rig joint\n\n");
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            fprintf(f, "%s\t%s   # %u\n", weft_joint_name(j), rig[j][1], j);
        }
        fclose(f);
    }
    weft_bvh_joint_map map;
    CHECK_RESULT(weft_bvh_read_joint_map(map_path, &map), WEFT_OK);
    CHECK(strcmp(map.entries[WEFT_JOINT_LEFT_ELBOW], "forearm.L") == 0);
    weft_bvh_report rep;
    def.report = &rep;
    def.joint_map = map.entries;
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_OK);
    if (clip && ref) {
        CHECK(strcmp(rep.naming, "joint map") == 0 && rep.mapped == 24);
        CHECK(strcmp(rep.source[WEFT_JOINT_SPINE1], "spine_01") == 0);
        CHECK_EQ_INT(clip->frame_count, ref->frame_count);
        double worst = 0.0;
        for (size_t k = 0; clip->frame_count == ref->frame_count && k < (size_t)ref->frame_count * 72; ++k) {
            worst = fmax(worst, fabs((double)clip->rotations[k] - ref->rotations[k]));
        }
        CHECK_MSG(worst < 1e-6, "joint map: rotations differ by %g rad", worst);
        CHECK(memcmp(clip->translations, ref->translations, (size_t)ref->frame_count * 3 * sizeof(float)) == 0);
    }
    weft_clip_destroy(clip);
    clip = (weft_clip *)(uintptr_t)1;
    /* a map naming a joint the file lacks */
    map.entries[WEFT_JOINT_LEFT_KNEE] = "knee_left";
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_ERROR_FORMAT);
    CHECK(clip == (weft_clip *)(uintptr_t)1);
    CHECK_MSG(strstr(weft_last_error(), "'knee_left'") && strstr(weft_last_error(), "left_knee"), "%s", weft_last_error());
    /* too few joints: the legs left out */
    map.entries[WEFT_JOINT_LEFT_KNEE] = "";
    map.entries[WEFT_JOINT_RIGHT_KNEE] = NULL;
    map.entries[WEFT_JOINT_LEFT_ANKLE] = "";
    map.entries[WEFT_JOINT_RIGHT_ANKLE] = "";
    CHECK_RESULT(weft_bvh_load_memory(g_ctx, text, len, &def, &clip), WEFT_ERROR_FORMAT);
    CHECK_MSG(strstr(weft_last_error(), "20 of 24") && strstr(weft_last_error(), "right_knee"), "%s", weft_last_error());
    /* map files with mistakes */
    static const char *const bad[][2] = {{"left_hip thigh.L\nleft_elbo forearm.L\n", "line 2"},
                                         {"left_hip thigh.L\nleft_hip thigh.R\n", "mapped twice"},
                                         {"left_hip\n", "line 1"},
                                         {"left_hip thigh.L extra\n", "line 1"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        f = fopen(map_path, "w");
        if (f) {
            fputs(bad[i][0], f);
            fclose(f);
        }
        weft_bvh_joint_map untouched;
        memset(&untouched, 0x5a, sizeof untouched);
        CHECK_RESULT(weft_bvh_read_joint_map(map_path, &untouched), WEFT_ERROR_FORMAT);
        CHECK_MSG(strstr(weft_last_error(), bad[i][1]) != NULL, "case %zu: %s", i, weft_last_error());
        CHECK(((unsigned char *)&untouched)[0] == 0x5a);
    }
    CHECK_RESULT(weft_bvh_read_joint_map(WEFT_BINARY_DIR "/tests/no_such_map.txt", &map), WEFT_ERROR_IO);
    free(text);
    weft_clip_destroy(ref);
}

/* A directory is refused by name, not reported as a huge file. */
static void test_bvh_path_is_a_directory(void)
{
    weft_bvh_def def = weft_default_bvh_def();
    weft_clip *c = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, MOCAP_DIR, &def, &c), WEFT_ERROR_IO);
    CHECK(strstr(weft_last_error(), "not a regular file") != NULL);
    CHECK(c == NULL);
}

static void setup(void)
{
    weft_context_def cdef = weft_default_context_def();
    cdef.isa = WEFT_ISA_SCALAR;
    CHECK_RESULT(weft_context_create(&cdef, &g_ctx), WEFT_OK);
}

static void teardown(void) { weft_context_destroy(g_ctx); }

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_synthetic_exact), TEST_CASE(test_rest_correction), TEST_CASE(test_translation_scale), TEST_CASE(test_floor_placement), TEST_CASE(test_cmu_01_01),
          TEST_CASE(test_cmu_01_03), TEST_CASE(test_boxing_toes), TEST_CASE(test_cmu_on_avatar), TEST_CASE(test_bad_input), TEST_CASE(test_fuzz_synthetic),
          TEST_CASE(test_fuzz_cmu), TEST_CASE(test_mocap_gz_equals_plain), TEST_CASE(test_mocap_test_split_loads),
          TEST_CASE(test_bvh_path_is_a_directory), TEST_CASE(test_namings_retarget_identically), TEST_CASE(test_joint_map_file), TEST_CASE(test_joint_angles_test_split),
          TEST_CASE(test_unknown_skeleton_names_the_missing), TEST_CASE(test_joint_angles_match_the_file),
          TEST_CASE(teardown))
