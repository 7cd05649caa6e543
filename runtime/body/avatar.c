/* weft's own mannequin: an implicit surface (smooth union of tapered, elliptic capsules along
 * the SMPL-24 bones in an A-pose) polygonised with surface nets, relaxed onto the surface,
 * with skinning weights from the part each vertex belongs to, diffused along the mesh. */
#include "body/body_internal.h"
#include "body/mesh.h"

#include <math.h>
#include <string.h>

/* SMPL neutral rest joints (T-pose, metres), left/right symmetrised; see docs/BODY.md. */
static const float g_base_joints[WEFT_BODY_JOINTS][3] = {
    {0.0f, -0.223f, 0.028f},      {0.069f, -0.3145f, 0.0225f},  {-0.069f, -0.3145f, 0.0225f},
    {0.0f, -0.114f, 0.002f},      {0.105f, -0.693f, 0.016f},    {-0.105f, -0.693f, 0.016f},
    {0.0f, 0.021f, 0.003f},       {0.090f, -1.0915f, -0.027f},  {-0.090f, -1.0915f, -0.027f},
    {0.0f, 0.074f, 0.028f},       {0.116f, -1.1435f, 0.094f},   {-0.116f, -1.1435f, 0.094f},
    {0.0f, 0.288f, -0.015f},      {0.0805f, 0.1945f, -0.0085f}, {-0.0805f, 0.1945f, -0.0085f},
    {0.0f, 0.353f, 0.036f},       {0.1735f, 0.2255f, -0.0175f}, {-0.1735f, 0.2255f, -0.0175f},
    {0.4305f, 0.2125f, -0.042f},  {-0.4305f, 0.2125f, -0.042f}, {0.6825f, 0.221f, -0.0455f},
    {-0.6825f, 0.221f, -0.0455f}, {0.767f, 0.214f, -0.058f},    {-0.767f, 0.214f, -0.058f}};

#define BASE_ANKLE_HEIGHT 0.075f /* ankle joint above the sole */
#define BASE_CROWN 0.17f         /* crown above the head joint */
#define WEIGHT_SIGMA 0.015f      /* metres: how fast a part's influence fades past the nearest */

weft_avatar_def weft_default_avatar_def(void)
{
    weft_avatar_def def;
    memset(&def, 0, sizeof def);
    def.height = 1.70f;
    def.girth = 1.0f;
    def.leg_fraction = 0.50f;
    def.shoulder_width = 1.0f;
    def.hip_width = 1.0f;
    def.chest = 1.0f;
    def.arm_angle_deg = 45.0f;
    def.target_vertices = 8000;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

static bool in_range(float v, float lo, float hi) { return isfinite(v) && v >= lo && v <= hi; }

static weft_result validate(const weft_avatar_def *d)
{
    if (d->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "avatar def: not made by weft_default_avatar_def()");
    }
    const struct {
        const char *name;
        float v, lo, hi;
    } fields[] = {{"height", d->height, 1.0f, 2.3f},           {"girth", d->girth, 0.7f, 1.3f},
                  {"leg_fraction", d->leg_fraction, 0.42f, 0.58f}, {"shoulder_width", d->shoulder_width, 0.8f, 1.25f},
                  {"hip_width", d->hip_width, 0.8f, 1.3f},      {"chest", d->chest, 0.8f, 1.3f},
                  {"arm_angle_deg", d->arm_angle_deg, 0.0f, 60.0f}};
    for (size_t i = 0; i < sizeof fields / sizeof fields[0]; ++i) {
        if (!isfinite(fields[i].v)) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "avatar def: %s is not finite", fields[i].name);
        }
        if (!in_range(fields[i].v, fields[i].lo, fields[i].hi)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "avatar def: %s = %g outside [%g, %g]", fields[i].name,
                              (double)fields[i].v, (double)fields[i].lo, (double)fields[i].hi);
        }
    }
    if (d->target_vertices < 2000 || d->target_vertices > 40000) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "avatar def: target_vertices = %u outside [2000, 40000]",
                          d->target_vertices);
    }
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Skeleton                                                                                   */

static bool is_leg(uint32_t j)
{
    return j == 1 || j == 2 || j == 4 || j == 5 || j == 7 || j == 8 || j == 10 || j == 11;
}

static bool is_arm(uint32_t j) { return j >= 16 || j == 13 || j == 14; }

/* T-pose joints for the def, soles at y = 0, pelvis at x = z = 0. */
static void rest_joints(const weft_avatar_def *d, float out[WEFT_BODY_JOINTS][3])
{
    float j[WEFT_BODY_JOINTS][3];
    memcpy(j, g_base_joints, sizeof j);
    const float pz = j[0][2];
    for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
        j[k][2] -= pz;
    }
    const float sole = j[7][1] - BASE_ANKLE_HEIGHT, crown = j[15][1] + BASE_CROWN;
    const float h0 = crown - sole, hip_y = j[1][1];
    const float leg0 = hip_y - sole, upper0 = crown - hip_y;
    /* Legs stretched to the asked fraction, the upper body scaled to keep the height. */
    const float leg_scale = d->leg_fraction * h0 / leg0;
    const float upper_scale = (h0 - d->leg_fraction * h0) / upper0;
    for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
        if (is_leg(k)) {
            j[k][1] = hip_y + (j[k][1] - hip_y) * leg_scale;
        } else if (k != 0) {
            for (int a = 0; a < 3; ++a) {
                float c = a == 1 ? hip_y : 0.0f;
                j[k][a] = c + (j[k][a] - c) * upper_scale;
            }
        }
    }
    /* Widths: shift whole limbs sideways so bone lengths stay. */
    float hip_dx = j[1][0] * (d->hip_width - 1.0f);
    float sh_dx = j[13][0] * (d->shoulder_width - 1.0f) + (j[16][0] - j[13][0]) * (d->shoulder_width - 1.0f);
    for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
        float side = j[k][0] > 0 ? 1.0f : -1.0f;
        if (is_leg(k)) {
            j[k][0] += side * hip_dx;
        } else if (k == 13 || k == 14) {
            j[k][0] *= d->shoulder_width;
        } else if (is_arm(k)) {
            j[k][0] += side * sh_dx;
        }
    }
    const float new_sole = j[7][1] - BASE_ANKLE_HEIGHT * leg_scale;
    const float s = d->height / h0;
    for (uint32_t k = 0; k < WEFT_BODY_JOINTS; ++k) {
        out[k][0] = j[k][0] * s;
        out[k][1] = (j[k][1] - new_sole) * s;
        out[k][2] = j[k][2] * s;
    }
}

static void a_pose(float arm_angle_deg, weft_pose *pose)
{
    memset(pose, 0, sizeof *pose);
    float a = arm_angle_deg * 3.14159265f / 180.0f;
    /* The left arm points along +X: a negative turn about Z lowers it; mirrored on the right. */
    pose->rotations[3 * WEFT_JOINT_LEFT_SHOULDER + 2] = -a;
    pose->rotations[3 * WEFT_JOINT_RIGHT_SHOULDER + 2] = a;
}

/* ---------------------------------------------------------------------------------------- */
/* Implicit surface                                                                           */

static float part_value(const weft_avatar_part *p, const float *x, float *h_out)
{
    float ax[3] = {x[0] - p->a[0], x[1] - p->a[1], x[2] - p->a[2]};
    float h = (ax[0] * p->ab[0] + ax[1] * p->ab[1] + ax[2] * p->ab[2]) * p->inv_l2;
    h = h < 0 ? 0 : h > 1 ? 1 : h;
    float q[3] = {ax[0] - h * p->ab[0], ax[1] - h * p->ab[1], ax[2] - h * p->ab[2]};
    /* q split into the axis part and the two cross-section directions; the latter scaled. */
    float qu = q[0] * p->u[0] + q[1] * p->u[1] + q[2] * p->u[2];
    float qs = (q[0] * p->side[0] + q[1] * p->side[1] + q[2] * p->side[2]) * p->inv_sx;
    float qt = (q[0] * p->t[0] + q[1] * p->t[1] + q[2] * p->t[2]) * p->inv_sz;
    float d = sqrtf(qu * qu + qs * qs + qt * qt);
    if (h_out) {
        *h_out = h;
    }
    return (d - (p->ra + h * (p->rb - p->ra))) * p->smin;
}

/* A lower bound of part_value: the point's distance to the bounding sphere, shrunk by the
 * largest cross-section scale. */
static float part_lower_bound(const weft_avatar_part *p, const float *x)
{
    float dx = x[0] - p->center[0], dy = x[1] - p->center[1], dz = x[2] - p->center[2];
    float d = sqrtf(dx * dx + dy * dy + dz * dz) - p->bound;
    return d / p->smax * p->smin;
}

static void part_prepare(weft_avatar_part *p)
{
    float l2 = 0;
    for (int k = 0; k < 3; ++k) {
        p->ab[k] = p->b[k] - p->a[k];
        l2 += p->ab[k] * p->ab[k];
    }
    float l = sqrtf(l2);
    p->inv_l2 = l2 > 0 ? 1.0f / l2 : 0.0f;
    if (l > 0) {
        for (int k = 0; k < 3; ++k) {
            p->u[k] = p->ab[k] / l;
        }
    } else {
        /* A sphere: the axis is any direction perpendicular to side. */
        float alt[3] = {fabsf(p->side[0]) < 0.9f ? 1.0f : 0.0f, fabsf(p->side[0]) < 0.9f ? 0.0f : 1.0f, 0.0f};
        float dp = alt[0] * p->side[0] + alt[1] * p->side[1] + alt[2] * p->side[2];
        for (int k = 0; k < 3; ++k) {
            p->u[k] = alt[k] - dp * p->side[k];
        }
        float n = sqrtf(p->u[0] * p->u[0] + p->u[1] * p->u[1] + p->u[2] * p->u[2]);
        for (int k = 0; k < 3; ++k) {
            p->u[k] /= n;
        }
    }
    p->t[0] = p->u[1] * p->side[2] - p->u[2] * p->side[1];
    p->t[1] = p->u[2] * p->side[0] - p->u[0] * p->side[2];
    p->t[2] = p->u[0] * p->side[1] - p->u[1] * p->side[0];
    p->inv_sx = 1.0f / p->sx;
    p->inv_sz = 1.0f / p->sz;
    p->smin = fminf(p->sx, p->sz);
    p->smax = fmaxf(1.0f, fmaxf(p->sx, p->sz));
    for (int k = 0; k < 3; ++k) {
        p->center[k] = 0.5f * (p->a[k] + p->b[k]);
    }
    p->bound = 0.5f * l + fmaxf(p->ra, p->rb) * p->smax;
}

static float smooth_min(float a, float b, float k)
{
    if (k <= 0) {
        return a < b ? a : b;
    }
    float h = k - fabsf(a - b);
    h = h > 0 ? h : 0;
    return (a < b ? a : b) - h * h * 0.25f / k;
}

float weft__avatar_field(const weft_avatar_shape *shape, const float *p, uint32_t *part_out)
{
    float f = 1e9f, best = 1e9f;
    uint32_t best_part = 0;
    for (uint32_t i = 0; i < shape->part_count; ++i) {
        /* smooth_min(f, v, k) == f whenever v >= f + k: skip parts that cannot reach. */
        if (i > 0) {
            float lb = part_lower_bound(&shape->parts[i], p);
            if (lb >= f + shape->parts[i].blend && lb >= best) {
                continue;
            }
        }
        float v = part_value(&shape->parts[i], p, NULL);
        f = i == 0 ? v : smooth_min(f, v, shape->parts[i].blend);
        if (v < best) {
            best = v;
            best_part = i;
        }
    }
    if (part_out) {
        *part_out = best_part;
    }
    return f;
}

float weft__avatar_field_masked(const weft_avatar_shape *shape, const float *p, uint32_t joint_mask)
{
    float f = 1e9f;
    bool first = true;
    for (uint32_t i = 0; i < shape->part_count; ++i) {
        if (!(joint_mask & (1u << shape->parts[i].joint))) {
            continue;
        }
        if (!first && part_lower_bound(&shape->parts[i], p) >= f + shape->parts[i].blend) {
            continue;
        }
        float v = part_value(&shape->parts[i], p, NULL);
        f = first ? v : smooth_min(f, v, shape->parts[i].blend);
        first = false;
    }
    return f;
}

static float field_fn(const void *user, const float *p) { return weft__avatar_field(user, p, NULL); }

static void normalize3(float *v)
{
    float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0) {
        v[0] /= l, v[1] /= l, v[2] /= l;
    }
}

typedef struct part_spec {
    float a[3], b[3];
    float ra, rb, sx, sz, blend;
    float side[3];
    uint8_t joint, joint_b;
} part_spec;

static void add_part(weft_avatar_shape *s, const part_spec *ps)
{
    if (s->part_count >= WEFT_AVATAR_MAX_PARTS) {
        return;
    }
    weft_avatar_part *p = &s->parts[s->part_count++];
    memcpy(p->a, ps->a, sizeof p->a);
    memcpy(p->b, ps->b, sizeof p->b);
    p->ra = ps->ra, p->rb = ps->rb;
    p->sx = ps->sx > 0 ? ps->sx : 1.0f;
    p->sz = ps->sz > 0 ? ps->sz : 1.0f;
    p->blend = ps->blend;
    p->joint = ps->joint;
    p->joint_b = ps->joint_b;
    /* side must be perpendicular to the axis: Gram-Schmidt it against a->b. */
    float u[3] = {p->b[0] - p->a[0], p->b[1] - p->a[1], p->b[2] - p->a[2]};
    normalize3(u);
    float sd[3] = {ps->side[0], ps->side[1], ps->side[2]};
    float dp = sd[0] * u[0] + sd[1] * u[1] + sd[2] * u[2];
    sd[0] -= dp * u[0], sd[1] -= dp * u[1], sd[2] -= dp * u[2];
    normalize3(sd);
    memcpy(p->side, sd, sizeof sd);
    part_prepare(p);
}

static void lerp3(const float *a, const float *b, float t, float *out)
{
    for (int k = 0; k < 3; ++k) {
        out[k] = a[k] + t * (b[k] - a[k]);
    }
}

/* Body parts in the bind pose. Radii are for a 1.70 m body of girth 1, scaled by r. */
static void build_parts(weft_avatar_shape *s, const float (*J)[3])
{
    const weft_avatar_def *d = &s->def;
    const float r = d->height / 1.70f * d->girth;
    const float L = d->height / 1.70f; /* lengths that do not follow girth */
    const float hw = d->hip_width, ch = d->chest;
    s->part_count = 0;
    const float X[3] = {1, 0, 0}, Y[3] = {0, 1, 0}, Z[3] = {0, 0, 1};
    part_spec p;

    /* Torso: one elliptic capsule per spine bone, wide across X, shallower along Z. */
    p = (part_spec){.ra = 0.105f * r * hw, .rb = 0.100f * r, .sx = 1.45f, .sz = 1.0f, .blend = 0, .joint = 0, .joint_b = 3};
    memcpy(p.a, J[0], sizeof p.a);
    p.a[1] -= 0.03f * L;
    memcpy(p.b, J[3], sizeof p.b);
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    p = (part_spec){.ra = 0.100f * r, .rb = 0.105f * r, .sx = 1.4f, .sz = 0.95f, .blend = 0.06f * L, .joint = 3, .joint_b = 6};
    memcpy(p.a, J[3], sizeof p.a);
    memcpy(p.b, J[6], sizeof p.b);
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    p = (part_spec){.ra = 0.110f * r, .rb = 0.115f * r, .sx = 1.45f, .sz = 0.98f * ch, .blend = 0.06f * L, .joint = 6, .joint_b = 9};
    memcpy(p.a, J[6], sizeof p.a);
    memcpy(p.b, J[9], sizeof p.b);
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    /* Rib cage up to the shoulders. */
    p = (part_spec){.ra = 0.115f * r, .rb = 0.095f * r, .sx = 1.5f, .sz = 0.95f * ch, .blend = 0.06f * L, .joint = 9, .joint_b = 9};
    memcpy(p.a, J[9], sizeof p.a);
    lerp3(J[9], J[12], 0.55f, p.b);
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    /* Pectorals: a flattened bar across the front of the chest. */
    p = (part_spec){.ra = 0.055f * r * ch, .rb = 0.055f * r * ch, .sx = 1.0f, .sz = 0.8f, .blend = 0.05f * L, .joint = 9, .joint_b = 9};
    for (int k = 0; k < 3; ++k) {
        p.a[k] = J[9][k];
        p.b[k] = J[9][k];
    }
    p.a[0] = -0.07f * L * d->shoulder_width, p.b[0] = 0.07f * L * d->shoulder_width;
    p.a[1] = p.b[1] = J[9][1] + 0.04f * L;
    p.a[2] = p.b[2] = J[9][2] + 0.035f * r * ch;
    memcpy(p.side, Y, sizeof p.side);
    add_part(s, &p);
    /* Hips and buttocks. */
    p = (part_spec){.ra = 0.095f * r * hw, .rb = 0.095f * r * hw, .sx = 1.0f, .sz = 1.05f, .blend = 0.06f * L, .joint = 0, .joint_b = 0};
    memcpy(p.a, J[2], sizeof p.a);
    memcpy(p.b, J[1], sizeof p.b);
    p.a[1] += 0.035f * L, p.b[1] += 0.035f * L;
    p.a[2] -= 0.01f * L, p.b[2] -= 0.01f * L;
    memcpy(p.side, Y, sizeof p.side);
    add_part(s, &p);

    /* Shoulder girdle: collar bones out to the arm roots. */
    for (int side = 0; side < 2; ++side) {
        int collar = 13 + side, sh = 16 + side;
        p = (part_spec){.ra = 0.065f * r, .rb = 0.055f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.05f * L, .joint = (uint8_t)collar,
                        .joint_b = (uint8_t)sh};
        lerp3(J[9], J[12], 0.45f, p.a);
        p.a[0] = J[collar][0] * 0.4f;
        memcpy(p.b, J[sh], sizeof p.b);
        memcpy(p.side, Z, sizeof p.side);
        add_part(s, &p);
    }
    /* Neck and head. */
    p = (part_spec){.ra = 0.055f * r, .rb = 0.050f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.03f * L, .joint = 12, .joint_b = 15};
    lerp3(J[9], J[12], 0.6f, p.a);
    memcpy(p.b, J[15], sizeof p.b);
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    const float head_r = 0.088f * L;
    p = (part_spec){.ra = head_r * 0.95f, .rb = head_r, .sx = 0.9f, .sz = 1.0f, .blend = 0.03f * L, .joint = 15, .joint_b = 15};
    memcpy(p.a, J[15], sizeof p.a);
    p.a[1] += 0.02f * L, p.a[2] += 0.01f * L;
    memcpy(p.b, J[15], sizeof p.b);
    p.b[1] += BASE_CROWN * L - head_r, p.b[2] -= 0.005f * L;
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    /* Jaw and nose give the head a front. */
    p = (part_spec){.ra = 0.05f * L, .rb = 0.045f * L, .sx = 1.2f, .sz = 1.0f, .blend = 0.03f * L, .joint = 15, .joint_b = 15};
    memcpy(p.a, J[15], sizeof p.a);
    p.a[1] += 0.02f * L, p.a[2] += 0.03f * L;
    memcpy(p.b, p.a, sizeof p.b);
    p.b[1] -= 0.01f * L, p.b[2] += 0.03f * L;
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);
    p = (part_spec){.ra = 0.012f * L, .rb = 0.016f * L, .sx = 1.0f, .sz = 1.0f, .blend = 0.015f * L, .joint = 15, .joint_b = 15};
    memcpy(p.a, J[15], sizeof p.a);
    p.a[1] += 0.09f * L, p.a[2] += 0.08f * L;
    memcpy(p.b, p.a, sizeof p.b);
    p.b[1] -= 0.03f * L, p.b[2] += 0.012f * L;
    memcpy(p.side, X, sizeof p.side);
    add_part(s, &p);

    for (int side = 0; side < 2; ++side) {
        int sh = 16 + side, el = 18 + side, wr = 20 + side, hd = 22 + side;
        float sign = side == 0 ? 1.0f : -1.0f;
        /* Upper arm, forearm. */
        p = (part_spec){.ra = 0.050f * r, .rb = 0.040f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.04f * L, .joint = (uint8_t)sh,
                        .joint_b = (uint8_t)el};
        memcpy(p.a, J[sh], sizeof p.a);
        memcpy(p.b, J[el], sizeof p.b);
        memcpy(p.side, Z, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.040f * r, .rb = 0.028f * r, .sx = 1.0f, .sz = 1.15f, .blend = 0.02f * L, .joint = (uint8_t)el,
                        .joint_b = (uint8_t)wr};
        memcpy(p.a, J[el], sizeof p.a);
        memcpy(p.b, J[wr], sizeof p.b);
        memcpy(p.side, Z, sizeof p.side);
        add_part(s, &p);
        /* Hand: a flat mitten (palm + fingers) with the thumb forward. The palm faces the
         * body, so its width runs along Z and its thickness across the arm in the XY plane. */
        float dir[3] = {J[hd][0] - J[wr][0], J[hd][1] - J[wr][1], J[hd][2] - J[wr][2]};
        normalize3(dir);
        p = (part_spec){.ra = 0.032f * L, .rb = 0.034f * L, .sx = 1.35f, .sz = 0.55f, .blend = 0.02f * L, .joint = (uint8_t)wr,
                        .joint_b = (uint8_t)hd};
        for (int k = 0; k < 3; ++k) {
            p.a[k] = J[wr][k] + 0.015f * L * dir[k];
            p.b[k] = J[hd][k];
        }
        memcpy(p.side, Z, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.030f * L, .rb = 0.022f * L, .sx = 1.35f, .sz = 0.5f, .blend = 0.02f * L, .joint = (uint8_t)hd,
                        .joint_b = (uint8_t)hd};
        for (int k = 0; k < 3; ++k) {
            p.a[k] = J[hd][k];
            p.b[k] = J[hd][k] + 0.075f * L * dir[k];
        }
        memcpy(p.side, Z, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.0135f * L, .rb = 0.0115f * L, .sx = 1.0f, .sz = 1.0f, .blend = 0.008f * L, .joint = (uint8_t)wr,
                        .joint_b = (uint8_t)wr};
        for (int k = 0; k < 3; ++k) {
            p.a[k] = J[wr][k] + 0.03f * L * dir[k];
            p.b[k] = J[wr][k] + 0.075f * L * dir[k];
        }
        p.a[2] += 0.03f * L, p.b[2] += 0.06f * L;
        memcpy(p.side, X, sizeof p.side);
        (void)sign;
        add_part(s, &p);
    }
    for (int side = 0; side < 2; ++side) {
        int hip = 1 + side, kn = 4 + side, an = 7 + side, ft = 10 + side;
        /* Thigh, shin (with a calf), foot. */
        p = (part_spec){.ra = 0.078f * r * (0.5f + 0.5f * hw), .rb = 0.052f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.03f * L,
                        .joint = (uint8_t)hip, .joint_b = (uint8_t)kn};
        memcpy(p.a, J[hip], sizeof p.a);
        memcpy(p.b, J[kn], sizeof p.b);
        memcpy(p.side, X, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.052f * r, .rb = 0.037f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.02f * L, .joint = (uint8_t)kn,
                        .joint_b = (uint8_t)an};
        memcpy(p.a, J[kn], sizeof p.a);
        memcpy(p.b, J[an], sizeof p.b);
        memcpy(p.side, X, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.050f * r, .rb = 0.038f * r, .sx = 1.0f, .sz = 1.0f, .blend = 0.04f * L, .joint = (uint8_t)kn,
                        .joint_b = (uint8_t)an};
        lerp3(J[kn], J[an], 0.15f, p.a);
        lerp3(J[kn], J[an], 0.55f, p.b);
        p.a[2] -= 0.015f * r, p.b[2] -= 0.015f * r;
        memcpy(p.side, X, sizeof p.side);
        add_part(s, &p);
        /* Foot from the heel to the toes; sole flat-ish (thin along Y). */
        p = (part_spec){.ra = 0.036f * L, .rb = 0.036f * L, .sx = 1.1f, .sz = 0.8f, .blend = 0.03f * L, .joint = (uint8_t)an,
                        .joint_b = (uint8_t)ft};
        memcpy(p.a, J[an], sizeof p.a);
        p.a[1] -= 0.045f * L, p.a[2] -= 0.035f * L;
        memcpy(p.b, J[ft], sizeof p.b);
        p.b[1] = p.a[1] - 0.002f * L;
        memcpy(p.side, X, sizeof p.side);
        add_part(s, &p);
        p = (part_spec){.ra = 0.034f * L, .rb = 0.026f * L, .sx = 1.25f, .sz = 0.75f, .blend = 0.02f * L, .joint = (uint8_t)ft,
                        .joint_b = (uint8_t)ft};
        memcpy(p.a, J[ft], sizeof p.a);
        p.a[1] -= 0.047f * L - 0.002f * L;
        p.a[1] = J[an][1] - 0.047f * L;
        memcpy(p.b, p.a, sizeof p.b);
        p.b[2] += 0.06f * L;
        p.b[1] -= 0.002f * L;
        memcpy(p.side, X, sizeof p.side);
        add_part(s, &p);
    }
}

/* ---------------------------------------------------------------------------------------- */
/* Skinning weights                                                                           */

static float smoothstep(float e0, float e1, float x)
{
    float t = (x - e0) / (e1 - e0);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3 - 2 * t);
}

void weft__avatar_point_weights(const weft_avatar_shape *shape, const float *p, float *out)
{
    memset(out, 0, WEFT_BODY_JOINTS * sizeof(float));
    float values[WEFT_AVATAR_MAX_PARTS], hs[WEFT_AVATAR_MAX_PARTS];
    float best = 1e9f;
    for (uint32_t i = 0; i < shape->part_count; ++i) {
        values[i] = part_value(&shape->parts[i], p, &hs[i]);
        best = values[i] < best ? values[i] : best;
    }
    float total = 0;
    for (uint32_t i = 0; i < shape->part_count; ++i) {
        float w = expf(-(values[i] - best) / WEIGHT_SIGMA);
        if (w < 1e-4f) {
            continue;
        }
        const weft_avatar_part *pt = &shape->parts[i];
        /* Along a bone, hand over to the child joint in the last fifth so that the joint
         * itself is shared half and half. */
        float to_child = pt->joint_b != pt->joint ? 0.5f * smoothstep(0.75f, 1.0f, hs[i]) : 0.0f;
        int32_t parent = weft__smpl_parents[pt->joint];
        float to_parent = parent >= 0 && pt->joint != 0 && pt->joint != 9 && pt->joint != 15
                              ? 0.5f * smoothstep(0.25f, 0.0f, hs[i])
                              : 0.0f;
        out[pt->joint] += w * (1.0f - to_child - to_parent);
        out[pt->joint_b] += w * to_child;
        if (parent >= 0) {
            out[parent] += w * to_parent;
        }
        total += w;
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        out[j] /= total;
    }
}

/* Diffuses weights along the mesh (Jacobi averaging), then drops tiny weights and
 * renormalises: neighbouring vertices get close weights, so skinning bends smoothly. */
static weft_result diffuse_weights(const weft_context *ctx, const weft__adjacency *adj, float *w, uint32_t nv, int iterations)
{
    size_t bytes = (size_t)nv * WEFT_BODY_JOINTS * sizeof(float);
    float *tmp = weft__alloc(ctx, bytes);
    if (!tmp) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (int it = 0; it < iterations; ++it) {
        for (uint32_t i = 0; i < nv; ++i) {
            float *o = tmp + (size_t)i * WEFT_BODY_JOINTS;
            const float *self = w + (size_t)i * WEFT_BODY_JOINTS;
            uint32_t b = adj->offsets[i], e = adj->offsets[i + 1];
            float inv = e > b ? 0.5f / (float)(e - b) : 0.0f;
            for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
                o[j] = e > b ? 0.5f * self[j] : self[j];
            }
            for (uint32_t k = b; k < e; ++k) {
                const float *n = w + (size_t)adj->neighbours[k] * WEFT_BODY_JOINTS;
                for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
                    o[j] += inv * n[j];
                }
            }
        }
        memcpy(w, tmp, bytes);
    }
    weft__free(ctx, tmp, bytes);
    for (uint32_t i = 0; i < nv; ++i) {
        float *o = w + (size_t)i * WEFT_BODY_JOINTS;
        float sum = 0;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            o[j] = o[j] < 1e-3f ? 0.0f : o[j];
            sum += o[j];
        }
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            o[j] /= sum;
        }
    }
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */

static void parts_bounds(const weft_avatar_shape *s, float lo[3], float hi[3])
{
    for (int a = 0; a < 3; ++a) {
        lo[a] = 1e9f;
        hi[a] = -1e9f;
    }
    for (uint32_t i = 0; i < s->part_count; ++i) {
        const weft_avatar_part *p = &s->parts[i];
        float r = (p->ra > p->rb ? p->ra : p->rb) * (p->sx > p->sz ? (p->sx > 1 ? p->sx : 1) : (p->sz > 1 ? p->sz : 1));
        for (int a = 0; a < 3; ++a) {
            float mn = p->a[a] < p->b[a] ? p->a[a] : p->b[a], mx = p->a[a] > p->b[a] ? p->a[a] : p->b[a];
            lo[a] = mn - r < lo[a] ? mn - r : lo[a];
            hi[a] = mx + r > hi[a] ? mx + r : hi[a];
        }
    }
}

static void translate_shape(weft_avatar_shape *s, float dy)
{
    for (uint32_t i = 0; i < s->part_count; ++i) {
        s->parts[i].a[1] += dy;
        s->parts[i].b[1] += dy;
        part_prepare(&s->parts[i]);
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        s->bind_joints[3 * j + 1] += dy;
    }
}

static weft_result polygonise(const weft_context *ctx, const weft_avatar_shape *s, float h, weft__mesh *mesh)
{
    float lo[3], hi[3];
    parts_bounds(s, lo, hi);
    for (int a = 0; a < 3; ++a) {
        /* Two cells of margin; an offset of a third of a cell keeps grid points off the
         * symmetry plane x = 0 so the mesh has no needle-thin quads there. */
        lo[a] -= 2.0f * h + 0.37f * h;
        hi[a] += 2.0f * h;
    }
    weft__mesh_init(mesh, ctx);
    return weft__surface_nets(mesh, field_fn, s, lo, hi, h);
}

weft_result weft_avatar_create(weft_context *context, const weft_avatar_def *def, weft_body **out_body)
{
    if (!context || !def || !out_body) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_avatar_create: NULL argument");
    }
    weft_result r = validate(def);
    if (r != WEFT_OK) {
        return r;
    }
    weft_avatar_shape *shape = weft__alloc(context, sizeof *shape);
    if (!shape) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    shape->def = *def;
    float joints[WEFT_BODY_JOINTS][3];
    rest_joints(def, joints);
    weft_pose bind;
    a_pose(def->arm_angle_deg, &bind);
    mat4 world[WEFT_BODY_JOINTS];
    weft__forward_kinematics(weft__smpl_parents, &joints[0][0], &bind, world);
    float bj[WEFT_BODY_JOINTS][3];
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        bj[j][0] = world[j][3][0], bj[j][1] = world[j][3][1], bj[j][2] = world[j][3][2];
        memcpy(shape->bind_joints + 3 * j, bj[j], sizeof bj[j]);
    }
    build_parts(shape, (const float(*)[3])bj);

    /* Grid spacing from the target: surface nets give about one vertex per h^2 of area. */
    const float scale = def->height / 1.70f;
    const float area = 1.85f * scale * scale * (0.6f + 0.4f * def->girth);
    float h = sqrtf(area / (float)def->target_vertices);
    weft__mesh mesh;
    r = polygonise(context, shape, h, &mesh);
    if (r == WEFT_OK && mesh.nv > 0) {
        /* One correction of the spacing from the measured count. */
        float ratio = sqrtf((float)mesh.nv / (float)def->target_vertices);
        if (ratio > 1.08f || ratio < 0.92f) {
            weft__mesh_free(&mesh);
            h *= ratio;
            r = polygonise(context, shape, h, &mesh);
        }
    }
    if (r != WEFT_OK) {
        weft__mesh_free(&mesh);
        weft__free(context, shape, sizeof *shape);
        return r;
    }
    weft__adjacency adj;
    r = weft__adjacency_build(context, &mesh, &adj);
    if (r != WEFT_OK) {
        weft__mesh_free(&mesh);
        weft__free(context, shape, sizeof *shape);
        return r;
    }
    weft__project_to_field(&mesh, field_fn, shape, h, 6);
    weft__relax(&mesh, &adj, field_fn, shape, h, 4);
    /* A closed genus-0 skin is part of the contract: parts that touch (thick thighs meeting
     * again at the knees, hands on the hips) would give handles. Report, never return one. */
    weft__mesh_topology topo;
    r = weft__mesh_topology_of(context, mesh.v, mesh.nv, mesh.t, mesh.nt, &topo);
    if (r == WEFT_OK && (topo.euler != 2 || topo.components != 1 || topo.boundary_edges || topo.nonmanifold_edges ||
                         topo.nonmanifold_vertices || topo.misoriented_edges)) {
        r = weft__fail(WEFT_ERROR_DEGENERATE_MESH,
                       "avatar: the parts touch for this shape (Euler characteristic %lld, %u components); lower girth "
                       "or hip_width, or raise target_vertices",
                       (long long)topo.euler, topo.components);
    }
    if (r != WEFT_OK) {
        weft__adjacency_free(context, &adj);
        weft__mesh_free(&mesh);
        weft__free(context, shape, sizeof *shape);
        return r;
    }

    /* Feet on the ground: shift the surface, the parts and the joints together. */
    float min_y = 1e9f;
    for (uint32_t i = 0; i < mesh.nv; ++i) {
        min_y = mesh.v[3 * i + 1] < min_y ? mesh.v[3 * i + 1] : min_y;
    }
    for (uint32_t i = 0; i < mesh.nv; ++i) {
        mesh.v[3 * i + 1] -= min_y;
    }
    translate_shape(shape, -min_y);
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        joints[j][1] -= min_y;
    }
    bind.translation[1] = 0;

    size_t wbytes = (size_t)mesh.nv * WEFT_BODY_JOINTS * sizeof(float);
    float *weights = weft__alloc(context, wbytes);
    if (!weights) {
        weft__adjacency_free(context, &adj);
        weft__mesh_free(&mesh);
        weft__free(context, shape, sizeof *shape);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t i = 0; i < mesh.nv; ++i) {
        weft__avatar_point_weights(shape, mesh.v + 3 * i, weights + (size_t)i * WEFT_BODY_JOINTS);
    }
    r = diffuse_weights(context, &adj, weights, mesh.nv, 8);
    weft__adjacency_free(context, &adj);

    if (r == WEFT_OK) {
        weft_body_def bdef = weft_default_body_def();
        bdef.vertices = mesh.v;
        bdef.vertex_count = mesh.nv;
        bdef.triangles = mesh.t;
        bdef.triangle_count = mesh.nt;
        bdef.weights = weights;
        bdef.joints = &joints[0][0];
        bdef.bind_pose = &bind;
        weft_body *body = NULL;
        r = weft_body_create(context, &bdef, &body);
        if (r == WEFT_OK) {
            body->avatar = shape;
            shape = NULL;
            *out_body = body;
        }
    }
    weft__free(context, weights, wbytes);
    weft__mesh_free(&mesh);
    weft__free(context, shape, sizeof *shape);
    return r;
}

weft_result weft_avatar_distance(const weft_body *body, const float *points, uint32_t count, float *out_distance)
{
    if (!body || (count && (!points || !out_distance))) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_avatar_distance: NULL argument");
    }
    if (!body->avatar) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_avatar_distance: the body was not made by weft_avatar_create");
    }
    for (uint32_t i = 0; i < count; ++i) {
        out_distance[i] = weft__avatar_field(body->avatar, points + 3 * i, NULL);
    }
    return WEFT_OK;
}
