/* BVH import through assimp and retargeting onto SMPL-24. See bvh.h for the method. */
#define _POSIX_C_SOURCE 200809L

#include "bvh.h"
#include "core/core.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#define BVH_MAX_FILE_BYTES (256ull << 20)
#define BVH_MAX_FRAMES 2000000u
#define BVH_MAX_CHANNELS 6000u
#define BVH_MAX_NODES 1024u
#define BVH_MAX_ROOT_M 10000.0f /* metres a retargeted root may be from the start (or the origin) */
#define BVH_NONE UINT32_MAX

/* SMPL-neutral rest joints (assets.md §1, from the SMPL humanoid MJCF offsets) with the soles
 * moved from y = -1.2 to y = 0. */
static const float k_default_rest[WEFT_BODY_JOINTS * 3] = {
    -0.002f, 0.977f, 0.028f,  0.068f, 0.885f, 0.021f,  -0.070f, 0.886f, 0.024f,  -0.004f, 1.086f, 0.002f,
    0.102f, 0.510f, 0.017f,   -0.108f, 0.504f, 0.015f, 0.001f, 1.221f, 0.003f,   0.088f, 0.112f, -0.027f,
    -0.092f, 0.105f, -0.027f, 0.003f, 1.274f, 0.028f,  0.115f, 0.056f, 0.092f,   -0.117f, 0.057f, 0.096f,
    -0.000f, 1.488f, -0.015f, 0.082f, 1.396f, -0.006f, -0.079f, 1.393f, -0.011f, 0.005f, 1.553f, 0.036f,
    0.172f, 1.426f, -0.015f,  -0.175f, 1.425f, -0.020f, 0.432f, 1.413f, -0.043f, -0.429f, 1.412f, -0.041f,
    0.681f, 1.422f, -0.044f,  -0.684f, 1.420f, -0.047f, 0.765f, 1.414f, -0.059f, -0.769f, 1.414f, -0.057f,
};

static const int32_t k_parents[WEFT_BODY_JOINTS] = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};

/* The child whose direction defines each SMPL bone for the rest correction; -1: none (the
 * pelvis has three children, ends have none). */
static const int32_t k_bone_child[WEFT_BODY_JOINTS] = {-1, 4, 5, 6, 7, 8, 9, 10, 11, 12, -1, -1,
                                                       15, 16, 17, -1, 18, 19, 20, 21, 22, 23, -1, -1};

/* Joint-name tables, one row per skeleton family, in SMPL joint order; NULL = no counterpart. */
#define BVH_FAMILIES 6
#define BVH_MIN_MAPPED 21 /* a skeleton with fewer SMPL joints found is refused, naming the missing */
static const char *const k_family_names[BVH_FAMILIES] = {"CMU/MotionBuilder", "Hips/Ab/Chest/LeftCollar", "SMPL",
                                                         "SMPL (short)", "CMU/3ds Max", "Mixamo"};
static const char *const k_names[BVH_FAMILIES][WEFT_BODY_JOINTS] = {
    /* CMU / MotionBuilder */
    {"Hips", "LeftUpLeg", "RightUpLeg", "LowerBack", "LeftLeg", "RightLeg", "Spine", "LeftFoot", "RightFoot", "Spine1",
     "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm",
     "RightForeArm", "LeftHand", "RightHand", "LeftFingerBase", "RightFingerBase"},
    /* collar naming */
    {"Hips", "LeftHip", "RightHip", "Ab", "LeftKnee", "RightKnee", "Chest", "LeftAnkle", "RightAnkle", "Chest2",
     "LeftToes", "RightToes", "Neck", "LeftCollar", "RightCollar", "Head", "LeftShoulder", "RightShoulder", "LeftElbow",
     "RightElbow", "LeftWrist", "RightWrist", "LeftHand", "RightHand"},
    /* SMPL */
    {"pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle", "right_ankle",
     "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
     "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hand", "right_hand"},
    /* SMPL, short names */
    {"Pelvis", "L_Hip", "R_Hip", "Spine1", "L_Knee", "R_Knee", "Spine2", "L_Ankle", "R_Ankle", "Spine3", "L_Foot",
     "R_Foot", "Neck", "L_Collar", "R_Collar", "Head", "L_Shoulder", "R_Shoulder", "L_Elbow", "R_Elbow", "L_Wrist",
     "R_Wrist", "L_Hand", "R_Hand"},
    /* CMU, 3ds Max-friendly naming (lowerneck > Neck > Head; lhand/LFingers/LThumb at the wrist) */
    {"Hips", "LeftHip", "RightHip", "lowerback", "LeftKnee", "RightKnee", "Chest", "LeftAnkle", "RightAnkle", "Chest2",
     "LeftToe", "RightToe", "lowerneck", "LeftCollar", "RightCollar", "Head", "LeftShoulder", "RightShoulder",
     "LeftElbow", "RightElbow", "LeftWrist", "RightWrist", "lhand", "rhand"},
    /* Mixamo (any "mixamorig:"-style namespace prefix is ignored when matching) */
    {"Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1", "LeftFoot", "RightFoot", "Spine2",
     "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm", "RightArm", "LeftForeArm",
     "RightForeArm", "LeftHand", "RightHand", "LeftHandMiddle1", "RightHandMiddle1"},
};

weft_bvh_def weft_default_bvh_def(void)
{
    weft_bvh_def def = {0};
    def.fps = 60.0f;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

const float *weft_bvh_default_rest_joints(void) { return k_default_rest; }

/* ---------------------------------------------------------------------------------------- */
/* Small rotation helpers (double precision: a clip composes long chains of rotations).        */

typedef struct m3 {
    double m[3][3]; /* row-major */
} m3;

static m3 m3_identity(void)
{
    m3 r = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    return r;
}

static m3 m3_mul(const m3 *a, const m3 *b)
{
    m3 r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.m[i][j] = a->m[i][0] * b->m[0][j] + a->m[i][1] * b->m[1][j] + a->m[i][2] * b->m[2][j];
        }
    }
    return r;
}

static m3 m3_transpose(const m3 *a)
{
    m3 r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.m[i][j] = a->m[j][i];
        }
    }
    return r;
}

static void m3_apply(const m3 *a, const double v[3], double out[3])
{
    for (int i = 0; i < 3; ++i) {
        out[i] = a->m[i][0] * v[0] + a->m[i][1] * v[1] + a->m[i][2] * v[2];
    }
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* How far the frame's lowest foot joint (ankle or toe, either side) is above its rest height:
 * forward kinematics of the target skeleton from its world rotations and the pelvis at
 * rest + (0, ty, 0) (only heights matter). */
static double foot_lift(const float *rest, const m3 *target_world, double ty)
{
    double pos[WEFT_BODY_JOINTS][3];
    pos[0][0] = rest[0], pos[0][1] = rest[1] + ty, pos[0][2] = rest[2];
    double lowest = INFINITY;
    for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
        const int32_t p = k_parents[j];
        const double bone[3] = {(double)rest[3 * j] - rest[3 * p], (double)rest[3 * j + 1] - rest[3 * p + 1],
                                (double)rest[3 * j + 2] - rest[3 * p + 2]};
        double d[3];
        m3_apply(&target_world[p], bone, d);
        for (int k = 0; k < 3; ++k) {
            pos[j][k] = pos[p][k] + d[k];
        }
        if (j == WEFT_JOINT_LEFT_ANKLE || j == WEFT_JOINT_RIGHT_ANKLE || j == WEFT_JOINT_LEFT_FOOT ||
            j == WEFT_JOINT_RIGHT_FOOT) {
            const double h = pos[j][1] - rest[3 * j + 1];
            lowest = h < lowest ? h : lowest;
        }
    }
    return lowest;
}

static m3 m3_from_quat(double w, double x, double y, double z)
{
    double n = sqrt(w * w + x * x + y * y + z * z);
    m3 r = m3_identity();
    if (!(n > 1e-12)) {
        return r;
    }
    w /= n;
    x /= n;
    y /= n;
    z /= n;
    r.m[0][0] = 1 - 2 * (y * y + z * z);
    r.m[0][1] = 2 * (x * y - w * z);
    r.m[0][2] = 2 * (x * z + w * y);
    r.m[1][0] = 2 * (x * y + w * z);
    r.m[1][1] = 1 - 2 * (x * x + z * z);
    r.m[1][2] = 2 * (y * z - w * x);
    r.m[2][0] = 2 * (x * z - w * y);
    r.m[2][1] = 2 * (y * z + w * x);
    r.m[2][2] = 1 - 2 * (x * x + y * y);
    return r;
}

/* Rotation part of an assimp node matrix (row-major, may carry scale): normalised columns. */
static m3 m3_from_ai(const struct aiMatrix4x4 *t)
{
    m3 r = {{{t->a1, t->a2, t->a3}, {t->b1, t->b2, t->b3}, {t->c1, t->c2, t->c3}}};
    for (int j = 0; j < 3; ++j) {
        double len = sqrt(r.m[0][j] * r.m[0][j] + r.m[1][j] * r.m[1][j] + r.m[2][j] * r.m[2][j]);
        if (len > 1e-12) {
            for (int i = 0; i < 3; ++i) {
                r.m[i][j] /= len;
            }
        }
    }
    return r;
}

/* Smallest rotation taking unit direction a onto unit direction b. */
static m3 m3_between(const double a_in[3], const double b_in[3])
{
    double la = sqrt(a_in[0] * a_in[0] + a_in[1] * a_in[1] + a_in[2] * a_in[2]);
    double lb = sqrt(b_in[0] * b_in[0] + b_in[1] * b_in[1] + b_in[2] * b_in[2]);
    if (!(la > 1e-9) || !(lb > 1e-9)) {
        return m3_identity();
    }
    double a[3] = {a_in[0] / la, a_in[1] / la, a_in[2] / la}, b[3] = {b_in[0] / lb, b_in[1] / lb, b_in[2] / lb};
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if (d < -0.999999) {
        return m3_identity(); /* opposite directions: the rests disagree too much to correct */
    }
    /* quaternion (1 + d, c) normalised */
    return m3_from_quat(1.0 + d, c[0], c[1], c[2]);
}

static void m3_to_axis_angle(const m3 *r, float out[3])
{
    const double(*m)[3] = r->m;
    double w, x, y, z;
    double tr = m[0][0] + m[1][1] + m[2][2];
    if (tr > 0) {
        double s = sqrt(tr + 1.0) * 2;
        w = 0.25 * s;
        x = (m[2][1] - m[1][2]) / s;
        y = (m[0][2] - m[2][0]) / s;
        z = (m[1][0] - m[0][1]) / s;
    } else if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
        double s = sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2;
        w = (m[2][1] - m[1][2]) / s;
        x = 0.25 * s;
        y = (m[0][1] + m[1][0]) / s;
        z = (m[0][2] + m[2][0]) / s;
    } else if (m[1][1] > m[2][2]) {
        double s = sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2;
        w = (m[0][2] - m[2][0]) / s;
        x = (m[0][1] + m[1][0]) / s;
        y = 0.25 * s;
        z = (m[1][2] + m[2][1]) / s;
    } else {
        double s = sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2;
        w = (m[1][0] - m[0][1]) / s;
        x = (m[0][2] + m[2][0]) / s;
        y = (m[1][2] + m[2][1]) / s;
        z = 0.25 * s;
    }
    if (w < 0) {
        w = -w;
        x = -x;
        y = -y;
        z = -z;
    }
    double vn = sqrt(x * x + y * y + z * z);
    if (vn < 1e-12) {
        out[0] = (float)(2 * x);
        out[1] = (float)(2 * y);
        out[2] = (float)(2 * z);
        return;
    }
    double angle = 2.0 * atan2(vn, w);
    out[0] = (float)(x / vn * angle);
    out[1] = (float)(y / vn * angle);
    out[2] = (float)(z / vn * angle);
}

/* ---------------------------------------------------------------------------------------- */
/* Text pre-check: assimp's BVH reader is lenient about the motion block, so the counts and
 * values are verified here first, with messages that say what is wrong.                      */

static const char *skip_space(const char *p, const char *end)
{
    while (p < end && isspace((unsigned char)*p)) {
        ++p;
    }
    return p;
}

static const char *next_token(const char *p, const char *end, const char **tok_end)
{
    p = skip_space(p, end);
    const char *q = p;
    while (q < end && !isspace((unsigned char)*q)) {
        ++q;
    }
    *tok_end = q;
    return p;
}

static bool token_is(const char *t, const char *te, const char *word)
{
    size_t n = strlen(word);
    return (size_t)(te - t) == n && memcmp(t, word, n) == 0;
}

/* Parses a number token; false when it is not entirely a number. */
static bool parse_number(const char *t, const char *te, double *out)
{
    char buf[64];
    size_t n = (size_t)(te - t);
    if (n == 0 || n >= sizeof buf) {
        return false;
    }
    memcpy(buf, t, n);
    buf[n] = '\0';
    char *endp = NULL;
    errno = 0;
    double v = strtod(buf, &endp);
    if (endp != buf + n) {
        return false;
    }
    *out = v;
    return true;
}

static weft_result precheck(const char *text, size_t size, uint32_t *out_frames, double *out_frame_time)
{
    const char *end = text + size;
    const char *te;
    const char *t = next_token(text, end, &te);
    if (!token_is(t, te, "HIERARCHY")) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: the file does not start with HIERARCHY");
    }
    uint64_t channels = 0;
    uint32_t joints = 0;
    int depth = 0;
    for (;;) {
        t = next_token(te, end, &te);
        if (t == end) {
            return weft__fail(WEFT_ERROR_FORMAT, "BVH: no MOTION section");
        }
        if (token_is(t, te, "MOTION")) {
            break;
        }
        if (token_is(t, te, "{")) {
            depth++;
        } else if (token_is(t, te, "}")) {
            if (--depth < 0) {
                return weft__fail(WEFT_ERROR_FORMAT, "BVH: unbalanced '}' in HIERARCHY");
            }
        } else if (token_is(t, te, "ROOT") || token_is(t, te, "JOINT")) {
            if (++joints > BVH_MAX_NODES) {
                return weft__fail(WEFT_ERROR_FORMAT, "BVH: more than %u joints", BVH_MAX_NODES);
            }
        } else if (token_is(t, te, "CHANNELS")) {
            t = next_token(te, end, &te);
            double n;
            if (!parse_number(t, te, &n) || n < 0 || n > 6 || n != floor(n)) {
                return weft__fail(WEFT_ERROR_FORMAT, "BVH: CHANNELS count is not an integer in 0..6");
            }
            channels += (uint64_t)n;
        } else if (token_is(t, te, "OFFSET")) {
            for (int k = 0; k < 3; ++k) {
                t = next_token(te, end, &te);
                double v;
                if (!parse_number(t, te, &v)) {
                    return weft__fail(WEFT_ERROR_FORMAT, "BVH: OFFSET needs three numbers");
                }
                if (!isfinite(v)) {
                    return weft__fail(WEFT_ERROR_NOT_FINITE, "BVH: OFFSET contains NaN or infinity");
                }
            }
        }
    }
    if (depth != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: unbalanced braces in HIERARCHY");
    }
    if (joints == 0 || channels == 0 || channels > BVH_MAX_CHANNELS) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: %u joints with %llu channels (need 1..%u channels)", joints,
                          (unsigned long long)channels, BVH_MAX_CHANNELS);
    }
    t = next_token(te, end, &te);
    if (!token_is(t, te, "Frames:")) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: 'Frames:' missing after MOTION");
    }
    t = next_token(te, end, &te);
    double frames;
    if (!parse_number(t, te, &frames) || frames < 1 || frames > BVH_MAX_FRAMES || frames != floor(frames)) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: Frames must be an integer in 1..%u", BVH_MAX_FRAMES);
    }
    t = next_token(te, end, &te);
    const char *t2e;
    const char *t2 = next_token(te, end, &t2e);
    if (!token_is(t, te, "Frame") || !token_is(t2, t2e, "Time:")) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: 'Frame Time:' missing after Frames");
    }
    t = next_token(t2e, end, &te);
    double frame_time;
    if (!parse_number(t, te, &frame_time)) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: Frame Time is not a number");
    }
    if (!(frame_time > 1e-5 && frame_time <= 1.0)) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: Frame Time %g outside (0.00001, 1] seconds", frame_time);
    }
    uint64_t expected = (uint64_t)frames * channels, count = 0;
    for (;;) {
        t = next_token(te, end, &te);
        if (t == end) {
            break;
        }
        double v;
        if (!parse_number(t, te, &v)) {
            return weft__fail(WEFT_ERROR_FORMAT, "BVH: motion value %llu is not a number", (unsigned long long)count);
        }
        if (!isfinite(v)) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "BVH: motion value %llu (frame %llu) is NaN or infinite",
                              (unsigned long long)count, (unsigned long long)(count / channels));
        }
        count++;
    }
    /* Some exporters write more whole frames than Frames declares (Debian's Boxing_Toes.bvh
     * has one extra); those are ignored, as assimp does. Partial frames are an error. */
    if (count < expected || count % channels != 0) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH,
                          "BVH: MOTION holds %llu values, Frames (%u) x channels (%llu) = %llu", (unsigned long long)count,
                          (uint32_t)frames, (unsigned long long)channels, (unsigned long long)expected);
    }
    *out_frames = (uint32_t)frames;
    *out_frame_time = frame_time;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Skeleton from the assimp scene.                                                            */

typedef struct bvh_node {
    const struct aiNode *ai;
    uint32_t parent;                /* BVH_NONE for the scene root */
    const struct aiNodeAnim *anim;  /* NULL: the node keeps its rest transform */
    m3 rest_local;
    double rest_offset[3];
    m3 rest_world;
    double rest_pos[3];             /* world position in the rest pose */
} bvh_node;

typedef struct bvh_skel {
    bvh_node nodes[BVH_MAX_NODES];
    uint32_t count;
    uint32_t map[WEFT_BODY_JOINTS]; /* SMPL joint -> node, BVH_NONE when unmapped */
} bvh_skel;

static weft_result collect_nodes(bvh_skel *s, const struct aiNode *n, uint32_t parent)
{
    if (s->count >= BVH_MAX_NODES) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: more than %u nodes", BVH_MAX_NODES);
    }
    uint32_t id = s->count++;
    bvh_node *b = &s->nodes[id];
    b->ai = n;
    b->parent = parent;
    b->rest_local = m3_from_ai(&n->mTransformation);
    b->rest_offset[0] = n->mTransformation.a4;
    b->rest_offset[1] = n->mTransformation.b4;
    b->rest_offset[2] = n->mTransformation.c4;
    if (parent == BVH_NONE) {
        b->rest_world = b->rest_local;
        memcpy(b->rest_pos, b->rest_offset, sizeof b->rest_pos);
    } else {
        const bvh_node *p = &s->nodes[parent];
        b->rest_world = m3_mul(&p->rest_world, &b->rest_local);
        double off[3];
        m3_apply(&p->rest_world, b->rest_offset, off);
        for (int k = 0; k < 3; ++k) {
            b->rest_pos[k] = p->rest_pos[k] + off[k];
        }
    }
    for (unsigned c = 0; c < n->mNumChildren; ++c) {
        weft_result res = collect_nodes(s, n->mChildren[c], id);
        if (res != WEFT_OK) {
            return res;
        }
    }
    return WEFT_OK;
}

/* A node's name without a namespace prefix ("mixamorig:Hips" -> "Hips"). */
static const char *bare_name(const char *name)
{
    const char *colon = strrchr(name, ':');
    return colon ? colon + 1 : name;
}

static uint32_t find_node(const bvh_skel *s, const char *name)
{
    for (uint32_t i = 0; i < s->count; ++i) {
        if (strcmp(bare_name(s->nodes[i].ai->mName.data), name) == 0) {
            return i;
        }
    }
    return BVH_NONE;
}

/* The user's joint map: every name given must be a joint of the file. */
static weft_result map_joints_from(bvh_skel *s, const char *const *joint_map, uint32_t *out_mapped)
{
    uint32_t mapped = 0;
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        const char *name = joint_map[j];
        if (!name || !name[0]) {
            s->map[j] = BVH_NONE;
            continue;
        }
        s->map[j] = find_node(s, bare_name(name));
        if (s->map[j] == BVH_NONE) {
            return weft__fail(WEFT_ERROR_FORMAT, "BVH: the joint map names '%s' for SMPL %s, but the file has no such joint",
                              name, weft_joint_name(j));
        }
        mapped++;
    }
    if (mapped < BVH_MIN_MAPPED) {
        char missing[512] = "";
        size_t len = 0;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS && len < sizeof missing; ++j) {
            if (s->map[j] == BVH_NONE) {
                int n = snprintf(missing + len, sizeof missing - len, "%s%s", len ? ", " : "", weft_joint_name(j));
                len += n > 0 ? (size_t)n : 0;
            }
        }
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: the joint map drives %u of 24 SMPL joints (at least %u needed); "
                          "unmapped: %s", mapped, BVH_MIN_MAPPED, missing);
    }
    *out_mapped = mapped;
    return WEFT_OK;
}

/* Chooses the naming family with the most matches (ties to the earlier family), or takes the
 * user's joint map, and fills s->map; fills the report when given. */
static weft_result map_joints(bvh_skel *s, const char *const *joint_map, weft_bvh_report *report)
{
    uint32_t best = 0, best_hits = 0;
    for (uint32_t f = 0; f < BVH_FAMILIES && !joint_map; ++f) {
        uint32_t hits = 0;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            hits += k_names[f][j] && find_node(s, k_names[f][j]) != BVH_NONE;
        }
        if (hits > best_hits) {
            best_hits = hits;
            best = f;
        }
    }
    uint32_t mapped = 0;
    if (joint_map) {
        weft_result r = map_joints_from(s, joint_map, &mapped);
        if (r != WEFT_OK) {
            return r;
        }
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS && !joint_map; ++j) {
        s->map[j] = k_names[best][j] ? find_node(s, k_names[best][j]) : BVH_NONE;
        mapped += s->map[j] != BVH_NONE;
    }
    if (mapped < BVH_MIN_MAPPED) {
        char missing[512] = "";
        size_t len = 0;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS && len < sizeof missing; ++j) {
            if (s->map[j] == BVH_NONE) {
                int n = snprintf(missing + len, sizeof missing - len, "%s%s (%s)", len ? ", " : "", weft_joint_name(j),
                                 k_names[best][j] ? k_names[best][j] : "-");
                len += n > 0 ? (size_t)n : 0;
            }
        }
        return weft__fail(WEFT_ERROR_FORMAT,
                          "BVH: skeleton not recognised well enough: the closest naming, %s, finds %u of 24 joints "
                          "(at least %u needed); missing SMPL joints (the names looked for): %s. Known namings: "
                          "CMU/MotionBuilder, CMU/3ds Max, Hips/Ab/Chest/LeftCollar, Mixamo, SMPL",
                          k_family_names[best], mapped, BVH_MIN_MAPPED, missing);
    }
    if (report) {
        memset(report, 0, sizeof *report);
        report->naming = joint_map ? "joint map" : k_family_names[best];
        report->mapped = mapped;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            if (s->map[j] != BVH_NONE) {
                snprintf(report->source[j], sizeof report->source[j], "%.63s", s->nodes[s->map[j]].ai->mName.data);
            }
        }
    }
    static const weft_joint required[] = {WEFT_JOINT_PELVIS,     WEFT_JOINT_LEFT_HIP,      WEFT_JOINT_RIGHT_HIP,
                                          WEFT_JOINT_LEFT_KNEE,  WEFT_JOINT_RIGHT_KNEE,    WEFT_JOINT_LEFT_ANKLE,
                                          WEFT_JOINT_RIGHT_ANKLE, WEFT_JOINT_LEFT_SHOULDER, WEFT_JOINT_RIGHT_SHOULDER,
                                          WEFT_JOINT_LEFT_ELBOW, WEFT_JOINT_RIGHT_ELBOW};
    for (size_t i = 0; i < sizeof required / sizeof required[0]; ++i) {
        if (s->map[required[i]] == BVH_NONE) {
            return weft__fail(WEFT_ERROR_FORMAT,
                              "BVH: skeleton not recognised: no joint for SMPL '%s' (%s)", weft_joint_name((uint32_t)required[i]),
                              joint_map ? "the joint map must name one"
                                        : "known namings: CMU/MotionBuilder, CMU/3ds Max, Hips/Ab/Chest/LeftCollar, Mixamo, "
                                          "SMPL; or pass a joint map");
        }
    }
    /* Every mapped joint must descend from the mapped pelvis, or world deltas mean nothing. */
    for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
        if (s->map[j] == BVH_NONE) {
            continue;
        }
        uint32_t n = s->map[j];
        while (n != BVH_NONE && n != s->map[0]) {
            n = s->nodes[n].parent;
        }
        if (n == BVH_NONE) {
            return weft__fail(WEFT_ERROR_FORMAT, "BVH: joint '%s' (SMPL %s) is not below the root joint",
                              s->nodes[s->map[j]].ai->mName.data, weft_joint_name(j));
        }
    }
    return WEFT_OK;
}

static const struct aiNodeAnim *find_channel(const struct aiAnimation *a, const char *name)
{
    for (unsigned c = 0; c < a->mNumChannels; ++c) {
        if (strcmp(a->mChannels[c]->mNodeName.data, name) == 0) {
            return a->mChannels[c];
        }
    }
    return NULL;
}

static double leg_length(const double *hip, const double *knee, const double *ankle)
{
    double a = 0, b = 0;
    for (int k = 0; k < 3; ++k) {
        a += (knee[k] - hip[k]) * (knee[k] - hip[k]);
        b += (ankle[k] - knee[k]) * (ankle[k] - knee[k]);
    }
    return sqrt(a) + sqrt(b);
}

/* ---------------------------------------------------------------------------------------- */

static weft_result retarget(weft_context *ctx, const struct aiScene *scene, const weft_bvh_def *def, uint32_t text_frames,
                            double frame_time, bvh_skel *s, weft_clip **out_src)
{
    if (!scene->mRootNode || scene->mNumAnimations < 1 || !scene->mAnimations[0] || scene->mAnimations[0]->mNumChannels == 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: assimp found no skeleton animation");
    }
    const struct aiAnimation *anim = scene->mAnimations[0];
    s->count = 0;
    weft_result res = collect_nodes(s, scene->mRootNode, BVH_NONE);
    if (res != WEFT_OK) {
        return res;
    }
    res = map_joints(s, def->joint_map, def->report);
    if (res != WEFT_OK) {
        return res;
    }
    for (uint32_t i = 0; i < s->count; ++i) {
        s->nodes[i].anim = find_channel(anim, s->nodes[i].ai->mName.data);
        const struct aiNodeAnim *ch = s->nodes[i].anim;
        /* joints without position channels get one constant position key from assimp */
        if (ch && (ch->mNumRotationKeys != text_frames || (ch->mNumPositionKeys > 1 && ch->mNumPositionKeys != text_frames))) {
            return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "BVH: channel '%s' has %u rotation / %u position keys for %u frames",
                              ch->mNodeName.data, ch->mNumRotationKeys, ch->mNumPositionKeys, text_frames);
        }
    }
    uint32_t root = s->map[WEFT_JOINT_PELVIS];
    if (!s->nodes[root].anim || s->nodes[root].anim->mNumPositionKeys != text_frames) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: the root joint '%s' has no position channels", s->nodes[root].ai->mName.data);
    }

    const float *rest = def->rest_joints ? def->rest_joints : k_default_rest;
    /* Translation scale: target leg / source leg (also converts units), or the given unit. */
    double scale = def->unit_scale;
    if (scale == 0.0) {
        double tl = 0, sl = 0;
        for (int side = 0; side < 2; ++side) {
            uint32_t hip = side ? WEFT_JOINT_RIGHT_HIP : WEFT_JOINT_LEFT_HIP;
            uint32_t knee = side ? WEFT_JOINT_RIGHT_KNEE : WEFT_JOINT_LEFT_KNEE;
            uint32_t ankle = side ? WEFT_JOINT_RIGHT_ANKLE : WEFT_JOINT_LEFT_ANKLE;
            double th[3], tk[3], ta[3];
            for (int k = 0; k < 3; ++k) {
                th[k] = rest[3 * hip + k];
                tk[k] = rest[3 * knee + k];
                ta[k] = rest[3 * ankle + k];
            }
            tl += leg_length(th, tk, ta);
            sl += leg_length(s->nodes[s->map[hip]].rest_pos, s->nodes[s->map[knee]].rest_pos, s->nodes[s->map[ankle]].rest_pos);
        }
        if (!(sl > 1e-9) || !(tl > 1e-6)) {
            return weft__fail(WEFT_ERROR_FORMAT, "BVH: the source skeleton has zero-length legs");
        }
        scale = tl / sl;
    }

    /* Rest corrections C_j: SMPL rest bone direction -> source rest bone direction. */
    m3 correction[WEFT_BODY_JOINTS];
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        correction[j] = m3_identity();
        int32_t c = k_bone_child[j];
        if (c < 0 || s->map[j] == BVH_NONE || s->map[c] == BVH_NONE) {
            continue;
        }
        double src_dir[3], dst_dir[3];
        for (int k = 0; k < 3; ++k) {
            src_dir[k] = s->nodes[s->map[c]].rest_pos[k] - s->nodes[s->map[j]].rest_pos[k];
            dst_dir[k] = (double)rest[3 * c + k] - (double)rest[3 * j + k];
        }
        correction[j] = m3_between(dst_dir, src_dir);
    }

    uint32_t first = def->first_frame;
    if (first >= text_frames) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "BVH: first_frame %u beyond the clip's %u frames", first, text_frames);
    }
    uint32_t frames = text_frames - first;
    if (def->max_frames && def->max_frames < frames) {
        frames = def->max_frames;
    }
    weft_clip *clip = NULL;
    res = weft_clip_create(ctx, frames, (float)(1.0 / frame_time), &clip);
    if (res != WEFT_OK) {
        return res;
    }
    clip->loops = false;

    m3 *world = malloc((size_t)s->count * sizeof *world);
    if (!world) {
        weft_clip_destroy(clip);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "BVH: out of memory");
    }
    /* each frame's lowest foot joint (ankles, toes) above its own height at rest, for the floor */
    double *lift = malloc((size_t)frames * sizeof *lift);
    if (!lift) {
        free(world);
        weft_clip_destroy(clip);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "BVH: out of memory");
    }
    double origin_xz[2] = {0, 0};
    for (uint32_t f = 0; f < frames; ++f) {
        uint32_t key = first + f;
        double root_pos[3] = {0, 0, 0};
        for (uint32_t i = 0; i < s->count; ++i) {
            bvh_node *n = &s->nodes[i];
            m3 local = n->rest_local;
            double offset[3] = {n->rest_offset[0], n->rest_offset[1], n->rest_offset[2]};
            if (n->anim) {
                const struct aiQuaternion *q = &n->anim->mRotationKeys[key].mValue;
                local = m3_from_quat(q->w, q->x, q->y, q->z);
                if (n->anim->mNumPositionKeys) {
                    uint32_t pk = n->anim->mNumPositionKeys == 1 ? 0 : key;
                    const struct aiVector3D *p = &n->anim->mPositionKeys[pk].mValue;
                    offset[0] = p->x;
                    offset[1] = p->y;
                    offset[2] = p->z;
                }
            }
            if (n->parent == BVH_NONE) {
                world[i] = local;
            } else {
                world[i] = m3_mul(&world[n->parent], &local);
            }
            if (i == root) {
                /* world position of the root: parents above it keep their rest transforms */
                double off[3] = {offset[0], offset[1], offset[2]};
                if (n->parent != BVH_NONE) {
                    m3_apply(&s->nodes[n->parent].rest_world, offset, off);
                    for (int k = 0; k < 3; ++k) {
                        off[k] += s->nodes[n->parent].rest_pos[k];
                    }
                }
                memcpy(root_pos, off, sizeof root_pos);
            }
        }
        m3 target_world[WEFT_BODY_JOINTS];
        float *aa = clip->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            int32_t p = k_parents[j];
            if (s->map[j] == BVH_NONE) {
                target_world[j] = p >= 0 ? target_world[p] : m3_identity();
            } else {
                const bvh_node *n = &s->nodes[s->map[j]];
                m3 rest_inv = m3_transpose(&n->rest_world);
                m3 delta = m3_mul(&world[s->map[j]], &rest_inv);
                target_world[j] = m3_mul(&delta, &correction[j]);
            }
            m3 local;
            if (p < 0) {
                local = target_world[j];
            } else {
                m3 parent_inv = m3_transpose(&target_world[p]);
                local = m3_mul(&parent_inv, &target_world[j]);
            }
            m3_to_axis_angle(&local, aa + 3 * j);
        }
        if (f == 0) {
            origin_xz[0] = root_pos[0];
            origin_xz[1] = root_pos[2];
        }
        float *tr = clip->translations + (size_t)f * 3;
        double x = def->keep_horizontal_origin ? root_pos[0] : root_pos[0] - origin_xz[0];
        double z = def->keep_horizontal_origin ? root_pos[2] : root_pos[2] - origin_xz[1];
        /* the pelvis lands at the scaled source hips; horizontal start above the origin */
        tr[0] = (float)(scale * x - (def->keep_horizontal_origin ? rest[0] : 0.0));
        tr[1] = (float)(scale * root_pos[1] - rest[1]);
        tr[2] = (float)(scale * z - (def->keep_horizontal_origin ? rest[2] : 0.0));
        lift[f] = foot_lift(rest, target_world, tr[1]);
    }
    free(world);
    if (!def->keep_source_height) {
        /* Feet on the target's floor: one vertical shift for the whole clip, so that the 5th
         * percentile of the frames' lowest foot joint stands where that joint stands at rest
         * (mocap floors are rarely at y = 0; jumps and crouches keep their heights). */
        qsort(lift, frames, sizeof *lift, cmp_double);
        const double floor_lift = lift[(size_t)(0.05 * (double)(frames - 1) + 0.5)];
        for (uint32_t f = 0; isfinite(floor_lift) && f < frames; ++f) {
            clip->translations[(size_t)f * 3 + 1] -= (float)floor_lift;
        }
    }
    free(lift);
    if (!weft__all_finite(clip->rotations, (size_t)frames * WEFT_POSE_ROTATION_FLOATS) ||
        !weft__all_finite(clip->translations, (size_t)frames * 3)) {
        weft_clip_destroy(clip);
        return weft__fail(WEFT_ERROR_NOT_FINITE, "BVH: retargeted motion is not finite");
    }
    /* A root farther than BVH_MAX_ROOT_M from the start is no motion a body can follow (and
     * would make every later step's geometry absurd): refused, naming the frame. */
    for (uint32_t f = 0; f < frames; ++f) {
        const float *tr = clip->translations + (size_t)f * 3;
        for (int k = 0; k < 3; ++k) {
            if (fabsf(tr[k]) > BVH_MAX_ROOT_M) {
                const double v = tr[k];
                weft_clip_destroy(clip);
                return weft__fail(WEFT_ERROR_FORMAT,
                                  "BVH: root translation %g m at frame %u is beyond the %g m a clip may range from its "
                                  "start",
                                  v, f, (double)BVH_MAX_ROOT_M);
            }
        }
    }
    *out_src = clip;
    return WEFT_OK;
}

weft_result weft_bvh_load_memory(weft_context *context, const void *data, size_t size, const weft_bvh_def *def,
                                 weft_clip **out_clip)
{
    if (!context || !data || !def || !out_clip) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_load: context, data, def and out_clip are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_load: def was not initialised with weft_default_bvh_def()");
    }
    if (!(def->fps >= 1.0f && def->fps <= 1000.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_load: fps must be in 1..1000");
    }
    if (!(def->unit_scale >= 0.0f) || !isfinite(def->unit_scale)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_load: unit_scale must be finite and >= 0");
    }
    if (def->rest_joints && !weft__all_finite(def->rest_joints, WEFT_BODY_JOINTS * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_bvh_load: rest_joints contain NaN or infinity");
    }
    if (size == 0 || size > BVH_MAX_FILE_BYTES) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: %zu bytes (need 1..%llu)", size, (unsigned long long)BVH_MAX_FILE_BYTES);
    }
    if (memchr(data, '\0', size)) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: the file contains NUL bytes (not a text BVH)");
    }
    uint32_t frames = 0;
    double frame_time = 0;
    weft_result res = precheck(data, size, &frames, &frame_time);
    if (res != WEFT_OK) {
        return res;
    }
    const struct aiScene *scene = aiImportFileFromMemory(data, (unsigned)size, aiProcess_ValidateDataStructure, "bvh");
    if (!scene) {
        return weft__fail(WEFT_ERROR_FORMAT, "BVH: assimp could not read the file: %s", aiGetErrorString());
    }
    bvh_skel *skel = malloc(sizeof *skel);
    if (!skel) {
        aiReleaseImport(scene);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "BVH: out of memory");
    }
    weft_clip *src = NULL;
    res = retarget(context, scene, def, frames, frame_time, skel, &src);
    free(skel);
    aiReleaseImport(scene);
    if (res != WEFT_OK) {
        return res;
    }
    weft_clip *out = NULL;
    if (src->frame_count == 1 || fabsf(src->fps - def->fps) < 1e-4f * def->fps) {
        /* A source within 1e-4 of the requested rate (a 60 Hz file whose Frame Time is rounded,
         * 0.0166666) keeps its frames, labelled at the requested rate as promised: the frames
         * drift by less than 0.4 s an hour. */
        out = src;
        out->fps = def->fps;
    } else {
        res = weft_clip_resample(src, def->fps, &out);
        weft_clip_destroy(src);
        if (res != WEFT_OK) {
            return res;
        }
    }
    out->loops = false;
    *out_clip = out;
    return WEFT_OK;
}

/* Reads a whole BVH file, plain or gzip-compressed (the mocap library ships .bvh.gz), into a
 * malloc'd buffer of at most BVH_MAX_FILE_BYTES. */
static weft_result read_bvh_file(const char *path, char **out_buf, size_t *out_len)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        return weft__fail(WEFT_ERROR_IO, "BVH: cannot open '%s': %s", path, strerror(errno));
    }
    if (!S_ISREG(st.st_mode)) {
        return weft__fail(WEFT_ERROR_IO, "BVH: '%s' is not a regular file", path);
    }
    gzFile f = gzopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "BVH: cannot open '%s': %s", path, strerror(errno));
    }
    size_t cap = 1u << 20, len = 0;
    char *buf = malloc(cap);
    weft_result res = buf ? WEFT_OK : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "BVH: out of memory reading '%s'", path);
    while (res == WEFT_OK) {
        if (len == cap) {
            if (cap >= BVH_MAX_FILE_BYTES) {
                res = weft__fail(WEFT_ERROR_IO, "BVH: '%s' holds more than %llu bytes", path,
                                 (unsigned long long)BVH_MAX_FILE_BYTES);
                break;
            }
            size_t ncap = cap * 2 < BVH_MAX_FILE_BYTES ? cap * 2 : (size_t)BVH_MAX_FILE_BYTES;
            char *nb = realloc(buf, ncap);
            if (!nb) {
                res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "BVH: out of memory for %zu bytes", ncap);
                break;
            }
            buf = nb;
            cap = ncap;
        }
        size_t want_bytes = cap - len < (1u << 30) ? cap - len : (1u << 30);
        int got = gzread(f, buf + len, (unsigned)want_bytes);
        if (got < 0) {
            int zerr = 0;
            const char *msg = gzerror(f, &zerr);
            res = weft__fail(WEFT_ERROR_IO, "BVH: cannot read '%s': %s", path, msg ? msg : "read error");
            break;
        }
        if (got == 0) {
            break;
        }
        len += (size_t)got;
    }
    gzclose(f);
    if (res == WEFT_OK && len == 0) {
        res = weft__fail(WEFT_ERROR_FORMAT, "BVH: '%s' is empty", path);
    }
    if (res != WEFT_OK) {
        free(buf);
        return res;
    }
    *out_buf = buf;
    *out_len = len;
    return WEFT_OK;
}

weft_result weft_bvh_load_file(weft_context *context, const char *path, const weft_bvh_def *def, weft_clip **out_clip)
{
    if (!path) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_load_file: path is NULL");
    }
    char *buf = NULL;
    size_t len = 0;
    weft_result rr = read_bvh_file(path, &buf, &len);
    if (rr != WEFT_OK) {
        return rr;
    }
    weft_clip *clip = NULL;
    weft_result res = weft_bvh_load_memory(context, buf, len, def, &clip);
    free(buf);
    if (res != WEFT_OK) {
        return res;
    }
    /* name the clip after the file's stem */
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t n = strcspn(base, ".");
    n = n < sizeof clip->name - 1 ? n : sizeof clip->name - 1;
    memcpy(clip->name, base, n);
    clip->name[n] = '\0';
    *out_clip = clip;
    return WEFT_OK;
}

weft_result weft_bvh_read_joint_map(const char *path, weft_bvh_joint_map *out)
{
    if (!path || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_bvh_read_joint_map: path and out are required");
    }
    FILE *f = fopen(path, "r");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "joint map: cannot open '%s': %s", path, strerror(errno));
    }
    weft_bvh_joint_map map;
    memset(&map, 0, sizeof map);
    char line[512];
    weft_result r = WEFT_OK;
    for (size_t number = 1; r == WEFT_OK && fgets(line, sizeof line, f); ++number) {
        line[strcspn(line, "#\r\n")] = '\0';
        char smpl[128], source[128], extra[2];
        int fields = sscanf(line, "%127s %127s %1s", smpl, source, extra);
        if (fields <= 0) {
            continue; /* blank or comment */
        }
        if (fields != 2) {
            r = weft__fail(WEFT_ERROR_FORMAT, "joint map '%s' line %zu: expected 'smpl_joint source_joint'", path, number);
            break;
        }
        uint32_t j = 0;
        while (j < WEFT_BODY_JOINTS && strcmp(weft_joint_name(j), smpl) != 0) {
            j++;
        }
        if (j == WEFT_BODY_JOINTS) {
            r = weft__fail(WEFT_ERROR_FORMAT, "joint map '%s' line %zu: '%s' is not an SMPL joint (pelvis, left_hip, ..., "
                           "right_hand)", path, number, smpl);
        } else if (map.names[j][0]) {
            r = weft__fail(WEFT_ERROR_FORMAT, "joint map '%s' line %zu: SMPL joint %s is mapped twice", path, number, smpl);
        } else if (strlen(source) >= sizeof map.names[j]) {
            r = weft__fail(WEFT_ERROR_FORMAT, "joint map '%s' line %zu: joint name longer than 63 characters", path, number);
        } else {
            snprintf(map.names[j], sizeof map.names[j], "%s", source);
        }
    }
    if (r == WEFT_OK && ferror(f)) {
        r = weft__fail(WEFT_ERROR_IO, "joint map: reading '%s' failed (is it a folder?)", path);
    }
    fclose(f);
    if (r != WEFT_OK) {
        return r;
    }
    memcpy(out->names, map.names, sizeof map.names);
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        out->entries[j] = out->names[j];
    }
    return WEFT_OK;
}
