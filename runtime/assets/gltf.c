/* Skinned-mesh import through assimp and a glTF 2.0 writer for weft bodies. See gltf.h. */
#define _POSIX_C_SOURCE 200809L

#include "gltf.h"
#include "assimp_check.h"
#include "isolate.h"
#include "core/core.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SKIN_MAX_ENTRY 1.0e6f /* largest skinning-matrix entry accepted (metres / scale) */
#define SKIN_MAX_NODES 4096u
#define SKIN_MAX_FRAMES 100000u
#define SKIN_MAX_VERTICES (1u << 24)

/* ---------------------------------------------------------------------------------------- */
/* Column-major 4x4 helpers in double.                                                        */

static void mat_mul(const double a[16], const double b[16], double out[16])
{
    double r[16];
    for (int c = 0; c < 4; ++c) {
        for (int row = 0; row < 4; ++row) {
            r[4 * c + row] = a[row] * b[4 * c] + a[4 + row] * b[4 * c + 1] + a[8 + row] * b[4 * c + 2] + a[12 + row] * b[4 * c + 3];
        }
    }
    memcpy(out, r, sizeof r);
}

/* assimp matrices are row-major (a1..a4 is the first row). */
/* The inverse of an affine column-major matrix (last row 0 0 0 1); false when singular. */
static bool mat_affine_inverse(const double m[16], double out[16])
{
    const double a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
    const double A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
    const double det = a * A + b * B + c * C;
    if (!(fabs(det) > 1e-30) || !isfinite(det)) {
        return false;
    }
    const double r[9] = {A / det, -(b * i - c * h) / det, (b * f - c * e) / det,
                         B / det, (a * i - c * g) / det,  -(a * f - c * d) / det,
                         C / det, -(a * h - b * g) / det, (a * e - b * d) / det};
    /* r is row-major (r[3 row + col]); out column-major */
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) {
            out[4 * col + row] = r[3 * row + col];
        }
        out[12 + row] = -(r[3 * row] * m[12] + r[3 * row + 1] * m[13] + r[3 * row + 2] * m[14]);
        out[4 * row + 3] = 0.0;
    }
    out[15] = 1.0;
    return true;
}

static void mat_from_ai(const struct aiMatrix4x4 *t, double m[16])
{
    const float rows[4][4] = {{t->a1, t->a2, t->a3, t->a4}, {t->b1, t->b2, t->b3, t->b4}, {t->c1, t->c2, t->c3, t->c4},
                              {t->d1, t->d2, t->d3, t->d4}};
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) {
            m[4 * c + r] = rows[r][c];
        }
    }
}

/* M = T * R * S from a translation, a unit quaternion (x, y, z, w) and a scale. */
static void mat_from_trs(const double t[3], const double q[4], const double s[3], double m[16])
{
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + w * z),     2 * (x * z - w * y),
                   2 * (x * y - w * z),     1 - 2 * (x * x + z * z), 2 * (y * z + w * x),
                   2 * (x * z + w * y),     2 * (y * z - w * x),     1 - 2 * (x * x + y * y)}; /* columns */
    for (int c = 0; c < 3; ++c) {
        for (int row = 0; row < 3; ++row) {
            m[4 * c + row] = r[3 * c + row] * s[c];
        }
        m[4 * c + 3] = 0.0;
    }
    m[12] = t[0];
    m[13] = t[1];
    m[14] = t[2];
    m[15] = 1.0;
}

static void quat_normalize(double q[4])
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (n > 1e-12) {
        for (int k = 0; k < 4; ++k) {
            q[k] /= n;
        }
    } else {
        q[0] = q[1] = q[2] = 0.0;
        q[3] = 1.0;
    }
}

static void quat_slerp(const double a[4], const double b_in[4], double u, double out[4])
{
    double b[4] = {b_in[0], b_in[1], b_in[2], b_in[3]};
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    if (d < 0) {
        d = -d;
        for (int k = 0; k < 4; ++k) {
            b[k] = -b[k];
        }
    }
    double wa = 1.0 - u, wb = u;
    if (d < 0.9995) {
        double th = acos(d);
        wa = sin((1.0 - u) * th) / sin(th);
        wb = sin(u * th) / sin(th);
    }
    for (int k = 0; k < 4; ++k) {
        out[k] = wa * a[k] + wb * b[k];
    }
    quat_normalize(out);
}

/* ---------------------------------------------------------------------------------------- */
/* Import                                                                                     */

typedef struct skin_node {
    const struct aiNode *ai;
    int32_t parent;
    double t[3], q[4], s[3];            /* rest TRS; q is x y z w */
    const struct aiNodeAnim *channel;
    int32_t joint;                      /* joint index, or -1 */
} skin_node;

static weft_result collect(skin_node *nodes, uint32_t *count, const struct aiNode *n, int32_t parent)
{
    if (*count >= SKIN_MAX_NODES) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: more than %u nodes", SKIN_MAX_NODES);
    }
    uint32_t id = (*count)++;
    skin_node *s = &nodes[id];
    memset(s, 0, sizeof *s);
    s->ai = n;
    s->parent = parent;
    s->joint = -1;
    struct aiVector3D scale, pos;
    struct aiQuaternion rot;
    aiDecomposeMatrix(&n->mTransformation, &scale, &rot, &pos);
    s->t[0] = pos.x, s->t[1] = pos.y, s->t[2] = pos.z;
    s->q[0] = rot.x, s->q[1] = rot.y, s->q[2] = rot.z, s->q[3] = rot.w;
    s->s[0] = scale.x, s->s[1] = scale.y, s->s[2] = scale.z;
    for (int k = 0; k < 3; ++k) {
        if (!isfinite(s->t[k]) || !isfinite(s->s[k])) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh: node '%s' has a non-finite transform", n->mName.data);
        }
    }
    quat_normalize(s->q);
    for (unsigned c = 0; c < n->mNumChildren; ++c) {
        weft_result r = collect(nodes, count, n->mChildren[c], (int32_t)id);
        if (r != WEFT_OK) {
            return r;
        }
    }
    return WEFT_OK;
}

static int32_t node_by_name(const skin_node *nodes, uint32_t count, const char *name)
{
    for (uint32_t i = 0; i < count; ++i) {
        if (strcmp(nodes[i].ai->mName.data, name) == 0) {
            return (int32_t)i;
        }
    }
    return -1;
}

/* Index of the last key with time <= t (0 when t is before the first). */
static unsigned key_before_vec(const struct aiVectorKey *k, unsigned n, double t)
{
    unsigned lo = 0, hi = n;
    while (hi - lo > 1) {
        unsigned mid = (lo + hi) / 2;
        if (k[mid].mTime <= t) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

static unsigned key_before_quat(const struct aiQuatKey *k, unsigned n, double t)
{
    unsigned lo = 0, hi = n;
    while (hi - lo > 1) {
        unsigned mid = (lo + hi) / 2;
        if (k[mid].mTime <= t) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

static void sample_vec(const struct aiVectorKey *k, unsigned n, double t, const double fallback[3], double out[3])
{
    if (n == 0) {
        memcpy(out, fallback, 3 * sizeof(double));
        return;
    }
    unsigned i = key_before_vec(k, n, t);
    if (i + 1 >= n || t <= k[i].mTime) {
        out[0] = k[i].mValue.x, out[1] = k[i].mValue.y, out[2] = k[i].mValue.z;
        return;
    }
    double span = k[i + 1].mTime - k[i].mTime;
    double u = span > 0 ? (t - k[i].mTime) / span : 0.0;
    out[0] = k[i].mValue.x + u * (k[i + 1].mValue.x - k[i].mValue.x);
    out[1] = k[i].mValue.y + u * (k[i + 1].mValue.y - k[i].mValue.y);
    out[2] = k[i].mValue.z + u * (k[i + 1].mValue.z - k[i].mValue.z);
}

static void sample_quat(const struct aiQuatKey *k, unsigned n, double t, const double fallback[4], double out[4])
{
    if (n == 0) {
        memcpy(out, fallback, 4 * sizeof(double));
        return;
    }
    unsigned i = key_before_quat(k, n, t);
    double a[4] = {k[i].mValue.x, k[i].mValue.y, k[i].mValue.z, k[i].mValue.w};
    quat_normalize(a);
    if (i + 1 >= n || t <= k[i].mTime) {
        memcpy(out, a, sizeof a);
        return;
    }
    double b[4] = {k[i + 1].mValue.x, k[i + 1].mValue.y, k[i + 1].mValue.z, k[i + 1].mValue.w};
    quat_normalize(b);
    double span = k[i + 1].mTime - k[i].mTime;
    quat_slerp(a, b, span > 0 ? (t - k[i].mTime) / span : 0.0, out);
}

void weft_skinned_asset_destroy(weft_skinned_asset *a)
{
    if (!a) {
        return;
    }
    free(a->positions);
    free(a->triangles);
    free(a->joint_indices);
    free(a->joint_weights);
    free(a->joint_names);
    free(a->parents);
    free(a->skin_matrices);
    free(a->local_rotations);
    free(a->local_translations);
    free(a->rest_rotations);
    free(a->rest_translations);
    free(a->bind_matrices);
    free(a);
}

/* Inserts (joint, w) into a vertex's four slots, keeping the largest weights. */
static void add_influence(uint32_t *idx, float *w, uint32_t joint, float weight)
{
    int smallest = 0;
    for (int k = 0; k < 4; ++k) {
        if (w[k] < w[smallest]) {
            smallest = k;
        }
    }
    if (weight > w[smallest]) {
        w[smallest] = weight;
        idx[smallest] = joint;
    }
}

static weft_result import_scene(const struct aiScene *scene, float fps, skin_node *nodes, weft_skinned_asset *a)
{
    uint32_t node_count = 0;
    if (!scene->mRootNode) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: the file has no node hierarchy");
    }
    weft_result res = collect(nodes, &node_count, scene->mRootNode, -1);
    if (res != WEFT_OK) {
        return res;
    }
    /* Sizes: every triangle of every mesh that has bones. */
    uint64_t nv = 0, nt = 0;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const struct aiMesh *mesh = scene->mMeshes[m];
        if (!mesh || mesh->mNumBones == 0) {
            continue;
        }
        nv += mesh->mNumVertices;
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            nt += mesh->mFaces[f].mNumIndices == 3;
        }
    }
    if (nv == 0 || nt == 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: the file has no skinned triangle mesh");
    }
    if (nv > SKIN_MAX_VERTICES || nt > 4ull * SKIN_MAX_VERTICES) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: %llu vertices is too many", (unsigned long long)nv);
    }
    a->vertex_count = (uint32_t)nv;
    a->triangle_count = (uint32_t)nt;
    a->positions = malloc(nv * 3 * sizeof(float));
    a->triangles = malloc(nt * 3 * sizeof(uint32_t));
    a->joint_indices = calloc(nv * 4, sizeof(uint32_t));
    a->joint_weights = calloc(nv * 4, sizeof(float));
    a->joint_names = calloc(WEFT_SKIN_MAX_JOINTS, sizeof *a->joint_names);
    double(*inverse_bind)[16] = calloc(WEFT_SKIN_MAX_JOINTS, sizeof *inverse_bind);
    int32_t *joint_node = calloc(WEFT_SKIN_MAX_JOINTS, sizeof *joint_node);
    if (!a->positions || !a->triangles || !a->joint_indices || !a->joint_weights || !a->joint_names || !inverse_bind ||
        !joint_node) {
        free(inverse_bind);
        free(joint_node);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
    }
    uint32_t vbase = 0, tcount = 0, joints = 0;
    res = WEFT_OK;
    for (unsigned m = 0; m < scene->mNumMeshes && res == WEFT_OK; ++m) {
        const struct aiMesh *mesh = scene->mMeshes[m];
        if (!mesh || mesh->mNumBones == 0) {
            continue;
        }
        for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
            float *p = a->positions + 3 * (size_t)(vbase + v);
            p[0] = mesh->mVertices[v].x, p[1] = mesh->mVertices[v].y, p[2] = mesh->mVertices[v].z;
        }
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const struct aiFace *face = &mesh->mFaces[f];
            if (face->mNumIndices != 3) {
                continue; /* points and lines carry no surface */
            }
            for (int k = 0; k < 3; ++k) {
                if (face->mIndices[k] >= mesh->mNumVertices) {
                    res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: mesh %u face %u index out of range", m, f);
                }
                a->triangles[3 * (size_t)tcount + (size_t)k] = vbase + face->mIndices[k];
            }
            tcount++;
        }
        for (unsigned b = 0; b < mesh->mNumBones && res == WEFT_OK; ++b) {
            const struct aiBone *bone = mesh->mBones[b];
            int32_t node = node_by_name(nodes, node_count, bone->mName.data);
            if (node < 0) {
                res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: bone '%s' has no node", bone->mName.data);
                break;
            }
            int32_t joint = nodes[node].joint;
            if (joint < 0) {
                if (joints >= WEFT_SKIN_MAX_JOINTS) {
                    res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: more than %u joints", WEFT_SKIN_MAX_JOINTS);
                    break;
                }
                joint = (int32_t)joints++;
                nodes[node].joint = joint;
                joint_node[joint] = node;
                size_t name_len = strnlen(bone->mName.data, WEFT_SKIN_NAME - 1);
                memcpy(a->joint_names[joint], bone->mName.data, name_len); /* calloc'd: stays terminated */
                mat_from_ai(&bone->mOffsetMatrix, inverse_bind[joint]);
                for (int k = 0; k < 16; ++k) {
                    if (!isfinite(inverse_bind[joint][k])) {
                        res = weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh: bone '%s' inverse bind matrix is not finite",
                                         bone->mName.data);
                    }
                }
            }
            for (unsigned w = 0; w < bone->mNumWeights && res == WEFT_OK; ++w) {
                const struct aiVertexWeight *vw = &bone->mWeights[w];
                if (vw->mVertexId >= mesh->mNumVertices) {
                    res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: bone '%s' weights vertex %u of %u", bone->mName.data,
                                     vw->mVertexId, mesh->mNumVertices);
                } else if (!isfinite(vw->mWeight) || vw->mWeight < 0.0f) {
                    res = weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh: bone '%s' has a negative or non-finite weight",
                                     bone->mName.data);
                } else if (vw->mWeight > 0.0f) {
                    size_t v = vbase + vw->mVertexId;
                    add_influence(a->joint_indices + 4 * v, a->joint_weights + 4 * v, (uint32_t)joint, vw->mWeight);
                }
            }
        }
        vbase += mesh->mNumVertices;
    }
    const size_t bad_position = res == WEFT_OK ? weft__first_outside(a->positions, nv * 3) : SIZE_MAX;
    if (bad_position != SIZE_MAX) {
        res = weft__fail(WEFT_ERROR_NOT_FINITE,
                         "skinned mesh: vertex %zu has coordinate %g (NaN, infinite or beyond +-%g m, "
                         "WEFT_MAX_COORDINATE)",
                         bad_position / 3, (double)a->positions[bad_position], (double)WEFT_MAX_COORDINATE);
    }
    for (uint32_t v = 0; v < a->vertex_count && res == WEFT_OK; ++v) {
        float *w = a->joint_weights + 4 * (size_t)v;
        float sum = w[0] + w[1] + w[2] + w[3];
        if (!(sum > 1e-6f)) {
            res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: vertex %u has no skin weights", v);
            break;
        }
        for (int k = 0; k < 4; ++k) {
            w[k] /= sum;
        }
    }
    a->joint_count = joints;
    if (res == WEFT_OK) {
        a->parents = malloc(joints * sizeof(int32_t));
        a->rest_rotations = malloc(joints * 4 * sizeof(float));
        a->rest_translations = malloc(joints * 3 * sizeof(float));
        if (!a->parents || !a->rest_rotations || !a->rest_translations) {
            res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
        }
    }
    if (res == WEFT_OK) {
        for (uint32_t j = 0; j < joints; ++j) {
            const skin_node *n = &nodes[joint_node[j]];
            int32_t p = n->parent;
            while (p >= 0 && nodes[p].joint < 0) {
                p = nodes[p].parent;
            }
            a->parents[j] = p >= 0 ? nodes[p].joint : -1;
            for (int k = 0; k < 4; ++k) {
                a->rest_rotations[4 * j + (uint32_t)k] = (float)n->q[k];
            }
            for (int k = 0; k < 3; ++k) {
                a->rest_translations[3 * j + (uint32_t)k] = (float)n->t[k];
            }
        }
    }
    if (res == WEFT_OK) {
        a->bind_matrices = malloc(joints * 16 * sizeof(float));
        if (!a->bind_matrices) {
            res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
        }
        for (uint32_t j = 0; j < joints && res == WEFT_OK; ++j) {
            double bind[16];
            if (!mat_affine_inverse(inverse_bind[j], bind)) {
                res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: bone '%s' has a singular inverse bind matrix",
                                 a->joint_names[j]);
            }
            for (int k = 0; k < 16 && res == WEFT_OK; ++k) {
                a->bind_matrices[16 * j + (uint32_t)k] = (float)bind[k];
            }
        }
    }

    /* Animation: the first one, sampled at fps over its duration. */
    const struct aiAnimation *anim = res == WEFT_OK && scene->mNumAnimations > 0 ? scene->mAnimations[0] : NULL;
    double tps = anim && anim->mTicksPerSecond > 0 ? anim->mTicksPerSecond : 25.0; /* assimp's documented default */
    double duration = anim ? anim->mDuration / tps : 0.0;
    if (anim && (!isfinite(duration) || duration < 0 || duration * fps > SKIN_MAX_FRAMES)) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: animation duration %g s is out of range", duration);
    }
    if (res == WEFT_OK && anim) {
        for (unsigned c = 0; c < anim->mNumChannels; ++c) {
            const struct aiNodeAnim *ch = anim->mChannels[c];
            int32_t node = node_by_name(nodes, node_count, ch->mNodeName.data);
            if (node >= 0) {
                nodes[node].channel = ch;
            }
        }
    }
    /* only once the duration passed the range check: a refused one may not fit in 32 bits */
    uint32_t frames = res == WEFT_OK && anim ? (uint32_t)floor(duration * fps + 1e-6) + 1 : 1;
    a->frame_count = frames;
    a->fps = fps;
    double(*global)[16] = NULL;
    if (res == WEFT_OK) {
        a->skin_matrices = malloc((size_t)frames * joints * 16 * sizeof(float));
        a->local_rotations = malloc((size_t)frames * joints * 4 * sizeof(float));
        a->local_translations = malloc((size_t)frames * joints * 3 * sizeof(float));
        global = malloc(node_count * sizeof *global);
        if (!a->skin_matrices || !a->local_rotations || !a->local_translations || !global) {
            res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory for %u frames", frames);
        }
    }
    for (uint32_t f = 0; f < frames && res == WEFT_OK; ++f) {
        double ticks = (double)f / fps * tps;
        for (uint32_t i = 0; i < node_count; ++i) {
            const skin_node *n = &nodes[i];
            double t[3], q[4], s[3], local[16];
            const struct aiNodeAnim *ch = n->channel;
            if (ch) {
                sample_vec(ch->mPositionKeys, ch->mNumPositionKeys, ticks, n->t, t);
                sample_quat(ch->mRotationKeys, ch->mNumRotationKeys, ticks, n->q, q);
                sample_vec(ch->mScalingKeys, ch->mNumScalingKeys, ticks, n->s, s);
            } else {
                memcpy(t, n->t, sizeof t);
                memcpy(q, n->q, sizeof q);
                memcpy(s, n->s, sizeof s);
            }
            mat_from_trs(t, q, s, local);
            if (n->parent < 0) {
                memcpy(global[i], local, sizeof local);
            } else {
                mat_mul(global[n->parent], local, global[i]);
            }
            if (n->joint >= 0) {
                size_t j = (size_t)f * joints + (size_t)n->joint;
                for (int k = 0; k < 4; ++k) {
                    a->local_rotations[4 * j + (size_t)k] = (float)q[k];
                }
                for (int k = 0; k < 3; ++k) {
                    a->local_translations[3 * j + (size_t)k] = (float)t[k];
                }
            }
        }
        for (uint32_t j = 0; j < joints; ++j) {
            double m[16];
            mat_mul(global[joint_node[j]], inverse_bind[j], m);
            float *dst = a->skin_matrices + ((size_t)f * joints + j) * 16;
            for (int k = 0; k < 16; ++k) {
                dst[k] = (float)m[k];
            }
        }
    }
    if (res == WEFT_OK && (!weft__all_finite(a->skin_matrices, (size_t)frames * joints * 16) ||
                           !weft__all_finite(a->local_rotations, (size_t)frames * joints * 4))) {
        res = weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh: the animation produces non-finite transforms");
    }
    /* Skinning sums weighted products of these with positions within WEFT_MAX_COORDINATE: entries
     * beyond SKIN_MAX_ENTRY (a joint moved or scaled absurdly far) could overflow float there. */
    for (size_t i = 0; res == WEFT_OK && i < (size_t)frames * joints * 16; ++i) {
        if (!(fabsf(a->skin_matrices[i]) <= SKIN_MAX_ENTRY)) {
            res = weft__fail(WEFT_ERROR_FORMAT,
                             "skinned mesh: frame %zu moves or scales joint %zu absurdly (a skinning matrix entry of "
                             "%g, beyond %g)",
                             i / ((size_t)joints * 16), i / 16 % joints, (double)a->skin_matrices[i],
                             (double)SKIN_MAX_ENTRY);
        }
    }
    free(global);
    free(inverse_bind);
    free(joint_node);
    return res;
}

/* Reads the file with assimp and converts it, in this process. */
static weft_result import_in_process(weft_context *context, const char *path, float fps, weft_skinned_asset **out_asset)
{
    /* Triangulate splits polygons (FBX quads) without reordering vertices */
    const struct aiScene *scene = aiImportFile(path, aiProcess_ValidateDataStructure | aiProcess_Triangulate);
    if (!scene) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: assimp could not read '%s': %s", path, aiGetErrorString());
    }
    weft_skinned_asset *a = calloc(1, sizeof *a);
    skin_node *nodes = malloc(SKIN_MAX_NODES * sizeof *nodes);
    if (!a || !nodes) {
        free(a);
        free(nodes);
        aiReleaseImport(scene);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
    }
    a->context = context;
    weft_result res = import_scene(scene, fps, nodes, a);
    free(nodes);
    aiReleaseImport(scene);
    if (res != WEFT_OK) {
        weft_skinned_asset_destroy(a);
        return res;
    }
    *out_asset = a;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* The import in a child process (isolate.h). The child writes one record:                     */
/*   'A'                      assimp returned (anything after this is weft's own code)        */
/*   'E' i32 code u32 n msg   refused, with weft's message                                    */
/*   'K' u32 V T J F f32 fps  then the asset's arrays in struct order (names as J * 64 bytes)  */
/*   'Z'                      end                                                              */
/* The parent decodes it as untrusted input and checks the asset again.                        */

static struct {
    double seconds;
    uint64_t address_space_bytes;
    bool strict;
} g_import_limits = {300.0, 16ull << 30, false};

void weft__skinned_import_limits(double seconds, bool strict)
{
    g_import_limits.seconds = seconds > 0 ? seconds : 300.0;
    g_import_limits.strict = strict;
}

typedef struct import_job {
    weft_context *context;
    const char *path;
    float fps;
} import_job;

static bool put(int fd, const void *p, size_t n)
{
    return weft__write_all(fd, p, n);
}

static void import_child(void *arg, int fd)
{
    const import_job *job = arg;
    const struct aiScene *scene = aiImportFile(job->path, aiProcess_ValidateDataStructure | aiProcess_Triangulate);
    if (!put(fd, "A", 1)) {
        return;
    }
    weft_skinned_asset *a = NULL;
    weft_result res;
    if (!scene) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: assimp could not read '%s': %s", job->path, aiGetErrorString());
    } else {
        a = calloc(1, sizeof *a);
        skin_node *nodes = malloc(SKIN_MAX_NODES * sizeof *nodes);
        res = a && nodes ? import_scene(scene, job->fps, nodes, a)
                         : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
        /* the child exits next: nothing is released */
    }
    if (res != WEFT_OK) {
        const char *msg = weft_last_error();
        int32_t code = (int32_t)res;
        uint32_t n = (uint32_t)strlen(msg);
        (void)(put(fd, "E", 1) && put(fd, &code, 4) && put(fd, &n, 4) && put(fd, msg, n) && put(fd, "Z", 1));
        return;
    }
    const uint32_t head[4] = {a->vertex_count, a->triangle_count, a->joint_count, a->frame_count};
    const size_t v = a->vertex_count, t = a->triangle_count, j = a->joint_count, fj = (size_t)a->frame_count * j;
    (void)(put(fd, "K", 1) && put(fd, head, sizeof head) && put(fd, &a->fps, 4) &&
           put(fd, a->positions, v * 3 * 4) && put(fd, a->triangles, t * 3 * 4) && put(fd, a->joint_indices, v * 4 * 4) &&
           put(fd, a->joint_weights, v * 4 * 4) && put(fd, a->joint_names, j * WEFT_SKIN_NAME) &&
           put(fd, a->parents, j * 4) && put(fd, a->skin_matrices, fj * 16 * 4) && put(fd, a->local_rotations, fj * 4 * 4) &&
           put(fd, a->local_translations, fj * 3 * 4) && put(fd, a->rest_rotations, j * 4 * 4) &&
           put(fd, a->rest_translations, j * 3 * 4) && put(fd, a->bind_matrices, j * 16 * 4) && put(fd, "Z", 1));
}

typedef struct reader {
    const uint8_t *p, *end;
} reader;

static bool take(reader *r, void *dst, size_t n)
{
    if ((size_t)(r->end - r->p) < n) {
        return false;
    }
    memcpy(dst, r->p, n);
    r->p += n;
    return true;
}

/* Allocates an array of n elements of `size` bytes and fills it from the record. */
static bool take_array(reader *r, void **dst, size_t n, size_t size)
{
    if (n > (size_t)(r->end - r->p) / size) {
        return false;
    }
    *dst = malloc(n * size > 0 ? n * size : 1);
    return *dst && take(r, *dst, n * size);
}

/* The asset's invariants (gltf.h), checked on what the child sent. */
static weft_result check_decoded(const weft_skinned_asset *a, const char *path)
{
    const size_t nv = a->vertex_count, nj = a->joint_count, fj = (size_t)a->frame_count * nj;
    if (weft__first_outside(a->positions, nv * 3) != SIZE_MAX) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh '%s': a bind-pose position is not finite or beyond %g m",
                          path, (double)WEFT_MAX_COORDINATE);
    }
    for (size_t i = 0; i < (size_t)a->triangle_count * 3; ++i) {
        if (a->triangles[i] >= a->vertex_count) {
            return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': triangle %zu names vertex %u of %u", path, i / 3,
                              a->triangles[i], a->vertex_count);
        }
    }
    for (size_t v = 0; v < nv; ++v) {
        double sum = 0.0;
        for (size_t k = 0; k < 4; ++k) {
            const float w = a->joint_weights[4 * v + k];
            if (!(w >= 0.0f && w <= 1.0f) || a->joint_indices[4 * v + k] >= nj) {
                return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': vertex %zu has a bad joint weight or index", path, v);
            }
            sum += w;
        }
        if (!(fabs(sum - 1.0) < 1e-4)) {
            return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the weights of vertex %zu sum to %g", path, v, sum);
        }
    }
    for (uint32_t j = 0; j < nj; ++j) {
        if (memchr(a->joint_names[j], '\0', WEFT_SKIN_NAME) == NULL || a->parents[j] < -1 ||
            a->parents[j] >= (int32_t)nj || a->parents[j] == (int32_t)j) {
            return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': joint %u has a bad name or parent", path, j);
        }
    }
    if (!weft__all_finite(a->rest_rotations, nj * 4) || !weft__all_finite(a->rest_translations, nj * 3) ||
        !weft__all_finite(a->bind_matrices, nj * 16) ||
        !weft__all_finite(a->local_rotations, fj * 4) || !weft__all_finite(a->local_translations, fj * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "skinned mesh '%s': a joint transform is not finite", path);
    }
    for (size_t i = 0; i < fj * 16; ++i) {
        if (!(fabsf(a->skin_matrices[i]) <= SKIN_MAX_ENTRY)) {
            return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': a skinning matrix entry is %g (beyond %g)", path,
                              (double)a->skin_matrices[i], (double)SKIN_MAX_ENTRY);
        }
    }
    return WEFT_OK;
}

static weft_result decode(weft_context *context, const char *path, float fps, const uint8_t *bytes, size_t size,
                          weft_skinned_asset **out_asset)
{
    reader r = {bytes + 1, bytes + size}; /* after 'A' */
    uint8_t tag = 0;
    if (!take(&r, &tag, 1) || (tag != 'E' && tag != 'K')) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the importer's output is malformed", path);
    }
    if (tag == 'E') {
        int32_t code = 0;
        uint32_t n = 0;
        char msg[512];
        if (!take(&r, &code, 4) || !take(&r, &n, 4) || n >= sizeof msg || !take(&r, msg, n) || !take(&r, &tag, 1) ||
            tag != 'Z' || r.p != r.end || code <= (int32_t)WEFT_OK || code >= 64) {
            return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the importer's output is malformed", path);
        }
        msg[n] = '\0';
        return weft__fail((weft_result)code, "%s", msg);
    }
    uint32_t head[4];
    float got_fps = 0.0f;
    if (!take(&r, head, sizeof head) || !take(&r, &got_fps, 4)) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the importer's output is malformed", path);
    }
    if (head[0] == 0 || head[0] > SKIN_MAX_VERTICES || head[1] == 0 || head[1] > 4u * SKIN_MAX_VERTICES ||
        head[2] == 0 || head[2] > WEFT_SKIN_MAX_JOINTS || head[3] == 0 || head[3] > SKIN_MAX_FRAMES || got_fps != fps) {
        return weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the importer's output has impossible sizes", path);
    }
    weft_skinned_asset *a = calloc(1, sizeof *a);
    if (!a) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: out of memory");
    }
    a->context = context;
    a->vertex_count = head[0], a->triangle_count = head[1], a->joint_count = head[2], a->frame_count = head[3];
    a->fps = fps;
    const size_t v = head[0], t = head[1], j = head[2], fj = (size_t)head[3] * j;
    void *names = NULL;
    bool ok = take_array(&r, (void **)&a->positions, v * 3, 4) && take_array(&r, (void **)&a->triangles, t * 3, 4) &&
              take_array(&r, (void **)&a->joint_indices, v * 4, 4) && take_array(&r, (void **)&a->joint_weights, v * 4, 4) &&
              take_array(&r, &names, j, WEFT_SKIN_NAME);
    if (ok) {
        /* names are kept at the importer's full capacity, as import_scene allocates them */
        a->joint_names = calloc(WEFT_SKIN_MAX_JOINTS, sizeof *a->joint_names);
        ok = a->joint_names != NULL;
        if (ok) {
            memcpy(a->joint_names, names, j * WEFT_SKIN_NAME);
        }
    }
    free(names);
    ok = ok && take_array(&r, (void **)&a->parents, j, 4) && take_array(&r, (void **)&a->skin_matrices, fj * 16, 4) &&
         take_array(&r, (void **)&a->local_rotations, fj * 4, 4) &&
         take_array(&r, (void **)&a->local_translations, fj * 3, 4) && take_array(&r, (void **)&a->rest_rotations, j * 4, 4) &&
         take_array(&r, (void **)&a->rest_translations, j * 3, 4) && take_array(&r, (void **)&a->bind_matrices, j * 16, 4) &&
         take(&r, &tag, 1) && tag == 'Z' && r.p == r.end;
    weft_result res = ok ? check_decoded(a, path)
                         : weft__fail(WEFT_ERROR_FORMAT, "skinned mesh '%s': the importer's output is malformed", path);
    if (res != WEFT_OK) {
        weft_skinned_asset_destroy(a);
        return res;
    }
    *out_asset = a;
    return WEFT_OK;
}

static weft_result import_isolated(weft_context *context, const char *path, float fps, weft_skinned_asset **out_asset)
{
    import_job job = {context, path, fps};
    const weft__isolated_limits limits = {g_import_limits.seconds, g_import_limits.address_space_bytes, (size_t)4 << 30};
    weft__isolated_run run;
    weft__run_isolated(import_child, &job, &limits, &run);
    const bool assimp_returned = run.size >= 1 && run.bytes[0] == 'A';
    const bool complete = run.size >= 2 && run.bytes[run.size - 1] == 'Z';
    weft_result res;
    if (run.end == WEFT__ISOLATED_NO_CHILD) {
        res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "skinned mesh: could not start the importer's process: %s",
                         strerror(run.code));
    } else if (run.end == WEFT__ISOLATED_TIMED_OUT) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: reading '%s' took longer than %g s; the file is refused", path,
                         g_import_limits.seconds);
    } else if (run.end == WEFT__ISOLATED_TOO_LARGE) {
        res = weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: '%s' imports to more than 4 GiB; the file is refused", path);
    } else if (run.end == WEFT__ISOLATED_EXITED && assimp_returned && complete) {
        res = decode(context, path, fps, run.bytes, run.size, out_asset);
    } else {
        /* the importer's process ended without a whole answer */
        char how[64];
        if (run.end == WEFT__ISOLATED_SIGNALLED) {
            snprintf(how, sizeof how, "signal %d%s", run.code,
                     run.code == 9 ? ", possibly out of memory" : run.code == 11 ? ", a bad memory access" :
                                                                 run.code == 6 ? ", an abort" : "");
        } else {
            snprintf(how, sizeof how, "exit status %d", run.code);
        }
        if (assimp_returned && g_import_limits.strict) {
            fprintf(stderr, "weft: converting '%s' after assimp read it ended the importer's process (%s)\n", path, how);
            abort(); /* weft's own code failed: a defect the fuzzer must see */
        }
        res = assimp_returned
                  ? weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: converting '%s' failed in its process (%s); the file is refused",
                               path, how)
                  : weft__fail(WEFT_ERROR_FORMAT, "skinned mesh: assimp failed reading '%s' (%s); the file is refused", path,
                               how);
    }
    free(run.bytes);
    return res;
}

weft_result weft_skinned_load_file(weft_context *context, const char *path, float fps, weft_skinned_asset **out_asset)
{
    if (!context || !path || !out_asset) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_skinned_load_file: context, path and out_asset are required");
    }
    if (!(fps >= 1.0f && fps <= 1000.0f)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_skinned_load_file: fps must be in 1..1000");
    }
    /* opens the file (IO errors) and refuses inputs assimp 5.2 is known to crash on */
    weft_result checked = weft__assimp_check_file(path);
    if (checked != WEFT_OK) {
        return checked;
    }
    /* assimp reads the file in a child process: its crashes, hangs and runaway allocations on
     * malformed files end the child, not the caller */
    return weft__isolation_available() ? import_isolated(context, path, fps, out_asset)
                                       : import_in_process(context, path, fps, out_asset);
}

weft_result weft_skinned_pose(const weft_skinned_asset *a, uint32_t frame, float *out)
{
    if (!a || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_skinned_pose: asset and out_positions are required");
    }
    if (frame >= a->frame_count) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_skinned_pose: frame %u >= frame count %u", frame, a->frame_count);
    }
    const float *mats = a->skin_matrices + (size_t)frame * a->joint_count * 16;
    for (uint32_t v = 0; v < a->vertex_count; ++v) {
        const float *p = a->positions + 3 * (size_t)v;
        double acc[3] = {0, 0, 0};
        for (int k = 0; k < 4; ++k) {
            float w = a->joint_weights[4 * (size_t)v + (size_t)k];
            if (w == 0.0f) {
                continue;
            }
            const float *m = mats + 16 * (size_t)a->joint_indices[4 * (size_t)v + (size_t)k];
            for (int r = 0; r < 3; ++r) {
                acc[r] += w * ((double)m[r] * p[0] + (double)m[4 + r] * p[1] + (double)m[8 + r] * p[2] + m[12 + r]);
            }
        }
        out[3 * (size_t)v + 0] = (float)acc[0];
        out[3 * (size_t)v + 1] = (float)acc[1];
        out[3 * (size_t)v + 2] = (float)acc[2];
    }
    return WEFT_OK;
}

/* SMPL names in the two common spellings. */
static const char *const k_smpl_short[WEFT_BODY_JOINTS] = {
    "Pelvis", "L_Hip", "R_Hip", "Spine1", "L_Knee", "R_Knee", "Spine2", "L_Ankle", "R_Ankle", "Spine3", "L_Foot", "R_Foot",
    "Neck", "L_Collar", "R_Collar", "Head", "L_Shoulder", "R_Shoulder", "L_Elbow", "R_Elbow", "L_Wrist", "R_Wrist", "L_Hand", "R_Hand"};

weft_result weft_skinned_to_clip(weft_context *context, const weft_skinned_asset *a, weft_clip **out_clip)
{
    if (!context || !a || !out_clip) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_skinned_to_clip: context, asset and out_clip are required");
    }
    if (a->joint_count != WEFT_BODY_JOINTS) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_skinned_to_clip: the skeleton has %u joints, an SMPL clip needs 24",
                          a->joint_count);
    }
    uint32_t map[WEFT_BODY_JOINTS];
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        map[j] = UINT32_MAX;
        for (uint32_t i = 0; i < a->joint_count; ++i) {
            if (strcmp(a->joint_names[i], weft_joint_name(j)) == 0 || strcmp(a->joint_names[i], k_smpl_short[j]) == 0) {
                map[j] = i;
            }
        }
        if (map[j] == UINT32_MAX) {
            return weft__fail(WEFT_ERROR_FORMAT, "weft_skinned_to_clip: no joint named '%s' or '%s'", weft_joint_name(j),
                              k_smpl_short[j]);
        }
    }
    for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
        int32_t p = a->parents[map[j]];
        if (p < 0 || (uint32_t)p != map[weft_joint_parent(j)]) {
            return weft__fail(WEFT_ERROR_FORMAT, "weft_skinned_to_clip: joint '%s' is not a child of '%s'", weft_joint_name(j),
                              weft_joint_name((uint32_t)weft_joint_parent(j)));
        }
    }
    weft_clip *clip = NULL;
    weft_result res = weft_clip_create(context, a->frame_count, a->fps, &clip);
    if (res != WEFT_OK) {
        return res;
    }
    for (uint32_t f = 0; f < a->frame_count; ++f) {
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            uint32_t i = map[j];
            const float *q = a->local_rotations + ((size_t)f * a->joint_count + i) * 4;
            const float *r = a->rest_rotations + 4 * (size_t)i;
            /* relative = conj(rest) * q, both x y z w */
            double rw = r[3], rx = -r[0], ry = -r[1], rz = -r[2];
            double w = rw * q[3] - rx * q[0] - ry * q[1] - rz * q[2];
            double x = rw * q[0] + rx * q[3] + ry * q[2] - rz * q[1];
            double y = rw * q[1] - rx * q[2] + ry * q[3] + rz * q[0];
            double z = rw * q[2] + rx * q[1] - ry * q[0] + rz * q[3];
            if (w < 0) {
                w = -w, x = -x, y = -y, z = -z;
            }
            double vn = sqrt(x * x + y * y + z * z);
            double scale = vn > 1e-12 ? 2.0 * atan2(vn, w) / vn : 2.0;
            float *aa = clip->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS + 3 * j;
            aa[0] = (float)(x * scale);
            aa[1] = (float)(y * scale);
            aa[2] = (float)(z * scale);
        }
        const float *t = a->local_translations + ((size_t)f * a->joint_count + map[0]) * 3;
        const float *t0 = a->rest_translations + 3 * (size_t)map[0];
        for (int k = 0; k < 3; ++k) {
            clip->translations[3 * (size_t)f + (size_t)k] = t[k] - t0[k];
        }
    }
    *out_clip = clip;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* glTF writer                                                                                */

typedef struct bin_view {
    size_t offset, length;
} bin_view;

static void aa_to_quat_xyzw(const float *aa, float q[4])
{
    double th = sqrt((double)aa[0] * aa[0] + (double)aa[1] * aa[1] + (double)aa[2] * aa[2]);
    double s = th > 1e-12 ? sin(0.5 * th) / th : 0.5;
    q[0] = (float)(aa[0] * s);
    q[1] = (float)(aa[1] * s);
    q[2] = (float)(aa[2] * s);
    q[3] = (float)cos(0.5 * th);
}

weft_result weft_gltf_write_body(const char *gltf_path, const weft_body *body, const weft_clip *clip)
{
    if (!gltf_path || !body) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_gltf_write_body: path and body are required");
    }
    size_t plen = strlen(gltf_path);
    if (plen < 6 || strcmp(gltf_path + plen - 5, ".gltf") != 0 || plen > 900) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_gltf_write_body: the path must end in .gltf");
    }
    if (clip && (clip->frame_count == 0 || !(clip->fps > 0.0f) ||
                 !weft__all_finite(clip->rotations, (size_t)clip->frame_count * WEFT_POSE_ROTATION_FLOATS) ||
                 !weft__all_finite(clip->translations, (size_t)clip->frame_count * 3))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_gltf_write_body: the clip is empty or not finite");
    }
    char bin_path[1024];
    snprintf(bin_path, sizeof bin_path, "%.*s.bin", (int)(plen - 5), gltf_path);
    const char *bin_name = strrchr(bin_path, '/');
    bin_name = bin_name ? bin_name + 1 : bin_path;

    const uint32_t nv = weft_body_vertex_count(body), nt = weft_body_triangle_count(body), nj = WEFT_BODY_JOINTS;
    const float *verts = weft_body_rest_vertices(body);
    const float *weights = weft_body_weights(body);
    const float *joints = weft_body_rest_joints(body);
    const uint32_t frames = clip ? clip->frame_count : 0;
    weft_pose bind;
    weft_body_bind_pose(body, &bind);
    float bind_world[WEFT_BODY_JOINTS * 16];
    weft_result res = weft_body_pose(body, &bind, NULL, bind_world);
    if (res != WEFT_OK) {
        return res;
    }

    bin_view v_pos, v_idx, v_jnt, v_wgt, v_ibm, v_time = {0, 0}, v_rot = {0, 0}, v_tr = {0, 0};
    size_t off = 0;
    v_pos = (bin_view){off, (size_t)nv * 12};
    off += v_pos.length;
    v_idx = (bin_view){off, (size_t)nt * 12};
    off += v_idx.length;
    v_jnt = (bin_view){off, (size_t)nv * 8};
    off += v_jnt.length;
    v_wgt = (bin_view){off, (size_t)nv * 16};
    off += v_wgt.length;
    v_ibm = (bin_view){off, (size_t)nj * 64};
    off += v_ibm.length;
    if (frames) {
        v_time = (bin_view){off, (size_t)frames * 4};
        off += v_time.length;
        v_rot = (bin_view){off, (size_t)frames * nj * 16};
        off += v_rot.length;
        v_tr = (bin_view){off, (size_t)frames * 12};
        off += v_tr.length;
    }
    uint8_t *bin = malloc(off);
    if (!bin) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_gltf_write_body: out of memory for %zu bytes", off);
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    memcpy(bin + v_pos.offset, verts, v_pos.length);
    for (uint32_t v = 0; v < nv; ++v) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = fminf(lo[k], verts[3 * v + (uint32_t)k]);
            hi[k] = fmaxf(hi[k], verts[3 * v + (uint32_t)k]);
        }
    }
    memcpy(bin + v_idx.offset, weft_body_triangles(body), v_idx.length);
    for (uint32_t v = 0; v < nv; ++v) {
        uint32_t idx[4] = {0, 0, 0, 0};
        float w[4] = {0, 0, 0, 0};
        for (uint32_t j = 0; j < nj; ++j) {
            add_influence(idx, w, j, weights[(size_t)v * nj + j]);
        }
        float sum = w[0] + w[1] + w[2] + w[3];
        uint16_t j16[4];
        for (int k = 0; k < 4; ++k) {
            w[k] = sum > 0 ? w[k] / sum : (k == 0 ? 1.0f : 0.0f);
            j16[k] = (uint16_t)idx[k];
        }
        memcpy(bin + v_jnt.offset + (size_t)v * 8, j16, 8);
        memcpy(bin + v_wgt.offset + (size_t)v * 16, w, 16);
    }
    /* inverse of each rigid bind transform: [R^T, -R^T t] */
    for (uint32_t j = 0; j < nj; ++j) {
        const float *m = bind_world + 16 * j;
        float inv[16] = {0};
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) {
                inv[4 * c + r] = m[4 * r + c];
            }
        }
        for (int r = 0; r < 3; ++r) {
            inv[12 + r] = -(inv[r] * m[12] + inv[4 + r] * m[13] + inv[8 + r] * m[14]);
        }
        inv[15] = 1.0f;
        memcpy(bin + v_ibm.offset + 64 * (size_t)j, inv, 64);
    }
    for (uint32_t f = 0; f < frames; ++f) {
        float t = (float)f / clip->fps;
        memcpy(bin + v_time.offset + 4 * (size_t)f, &t, 4);
        for (uint32_t j = 0; j < nj; ++j) {
            float q[4];
            aa_to_quat_xyzw(clip->rotations + (size_t)f * WEFT_POSE_ROTATION_FLOATS + 3 * j, q);
            memcpy(bin + v_rot.offset + ((size_t)j * frames + f) * 16, q, 16);
        }
        float tr[3];
        for (int k = 0; k < 3; ++k) {
            tr[k] = joints[k] + clip->translations[3 * (size_t)f + (size_t)k];
        }
        memcpy(bin + v_tr.offset + 12 * (size_t)f, tr, 12);
    }

    FILE *bf = fopen(bin_path, "wb");
    if (!bf) {
        free(bin);
        return weft__fail(WEFT_ERROR_IO, "weft_gltf_write_body: cannot write '%s': %s", bin_path, strerror(errno));
    }
    bool ok = fwrite(bin, 1, off, bf) == off;
    ok = (fclose(bf) == 0) && ok;
    free(bin);
    FILE *gf = ok ? fopen(gltf_path, "w") : NULL;
    if (!gf) {
        remove(bin_path);
        return weft__fail(WEFT_ERROR_IO, "weft_gltf_write_body: cannot write '%s'", ok ? gltf_path : bin_path);
    }
    fprintf(gf, "{\n  \"asset\": {\"version\": \"2.0\", \"generator\": \"weft\"},\n  \"scene\": 0,\n");
    fprintf(gf, "  \"scenes\": [{\"nodes\": [0, %u]}],\n  \"nodes\": [\n", nj);
    for (uint32_t j = 0; j < nj; ++j) {
        int32_t p = weft_joint_parent(j);
        float t[3];
        for (int k = 0; k < 3; ++k) {
            t[k] = p < 0 ? joints[k] : joints[3 * j + (uint32_t)k] - joints[3 * (uint32_t)p + (uint32_t)k];
        }
        fprintf(gf, "    {\"name\": \"%s\", \"translation\": [%.9g, %.9g, %.9g]", weft_joint_name(j), (double)t[0],
                (double)t[1], (double)t[2]);
        bool first = true;
        for (uint32_t c = 0; c < nj; ++c) {
            if (weft_joint_parent(c) == (int32_t)j) {
                fprintf(gf, "%s%u", first ? ", \"children\": [" : ", ", c);
                first = false;
            }
        }
        fprintf(gf, "%s},\n", first ? "" : "]");
    }
    fprintf(gf, "    {\"name\": \"body\", \"mesh\": 0, \"skin\": 0}\n  ],\n");
    fprintf(gf, "  \"skins\": [{\"inverseBindMatrices\": 4, \"skeleton\": 0, \"joints\": [");
    for (uint32_t j = 0; j < nj; ++j) {
        fprintf(gf, "%u%s", j, j + 1 < nj ? ", " : "]}],\n");
    }
    fprintf(gf, "  \"meshes\": [{\"name\": \"body\", \"primitives\": [{\"attributes\": {\"POSITION\": 0, \"JOINTS_0\": 2, "
                "\"WEIGHTS_0\": 3}, \"indices\": 1, \"mode\": 4}]}],\n");
    fprintf(gf, "  \"buffers\": [{\"uri\": \"%s\", \"byteLength\": %zu}],\n  \"bufferViews\": [\n", bin_name, off);
    const bin_view views[8] = {v_pos, v_idx, v_jnt, v_wgt, v_ibm, v_time, v_rot, v_tr};
    uint32_t view_count = frames ? 8 : 5;
    for (uint32_t i = 0; i < view_count; ++i) {
        fprintf(gf, "    {\"buffer\": 0, \"byteOffset\": %zu, \"byteLength\": %zu%s}%s\n", views[i].offset, views[i].length,
                i == 0 || i == 2 || i == 3 ? ", \"target\": 34962" : i == 1 ? ", \"target\": 34963" : "",
                i + 1 < view_count ? "," : "");
    }
    fprintf(gf, "  ],\n  \"accessors\": [\n");
    fprintf(gf, "    {\"bufferView\": 0, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC3\", \"min\": [%.9g, %.9g, %.9g], "
                "\"max\": [%.9g, %.9g, %.9g]},\n",
            nv, (double)lo[0], (double)lo[1], (double)lo[2], (double)hi[0], (double)hi[1], (double)hi[2]);
    fprintf(gf, "    {\"bufferView\": 1, \"componentType\": 5125, \"count\": %u, \"type\": \"SCALAR\"},\n", nt * 3);
    fprintf(gf, "    {\"bufferView\": 2, \"componentType\": 5123, \"count\": %u, \"type\": \"VEC4\"},\n", nv);
    fprintf(gf, "    {\"bufferView\": 3, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC4\"},\n", nv);
    fprintf(gf, "    {\"bufferView\": 4, \"componentType\": 5126, \"count\": %u, \"type\": \"MAT4\"}%s\n", nj, frames ? "," : "");
    if (frames) {
        double tmax = (double)(frames - 1) / clip->fps;
        fprintf(gf, "    {\"bufferView\": 5, \"componentType\": 5126, \"count\": %u, \"type\": \"SCALAR\", \"min\": [0], "
                    "\"max\": [%.9g]},\n",
                frames, tmax);
        for (uint32_t j = 0; j < nj; ++j) {
            fprintf(gf, "    {\"bufferView\": 6, \"byteOffset\": %zu, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC4\"},\n",
                    (size_t)j * frames * 16, frames);
        }
        fprintf(gf, "    {\"bufferView\": 7, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC3\"}\n", frames);
        fprintf(gf, "  ],\n  \"animations\": [{\"name\": \"motion\", \"samplers\": [\n");
        for (uint32_t j = 0; j <= nj; ++j) {
            fprintf(gf, "    {\"input\": 5, \"output\": %u, \"interpolation\": \"LINEAR\"}%s\n", 5 + 1 + j, j < nj ? "," : "");
        }
        fprintf(gf, "  ], \"channels\": [\n");
        for (uint32_t j = 0; j < nj; ++j) {
            fprintf(gf, "    {\"sampler\": %u, \"target\": {\"node\": %u, \"path\": \"rotation\"}},\n", j, j);
        }
        fprintf(gf, "    {\"sampler\": %u, \"target\": {\"node\": 0, \"path\": \"translation\"}}\n  ]}]\n}\n", nj);
    } else {
        fprintf(gf, "  ]\n}\n");
    }
    ok = !ferror(gf);
    ok = (fclose(gf) == 0) && ok;
    if (!ok) {
        remove(gltf_path);
        remove(bin_path);
        return weft__fail(WEFT_ERROR_IO, "weft_gltf_write_body: writing '%s' failed", gltf_path);
    }
    return WEFT_OK;
}
