/* SMPL-24 skeleton and the skinned body: shape blend shapes, pose blend shapes, forward
 * kinematics and linear blend skinning into caller buffers. */
#include "body/body_internal.h"

#include <math.h>
#include <string.h>

const int32_t weft__smpl_parents[WEFT_BODY_JOINTS] = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8,
                                                      9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};

static const char *const g_joint_names[WEFT_BODY_JOINTS] = {
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
    "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_hand", "right_hand"};

const char *weft_joint_name(uint32_t joint)
{
    return joint < WEFT_BODY_JOINTS ? g_joint_names[joint] : NULL;
}

int32_t weft_joint_parent(uint32_t joint)
{
    return joint < WEFT_BODY_JOINTS ? weft__smpl_parents[joint] : -1;
}

void weft__axis_angle_to_mat3(const float *aa, mat3 out)
{
    /* Computed in double: poses come from long kinematic chains and the numpy cross-check
     * works in float64. */
    double x = aa[0], y = aa[1], z = aa[2];
    double theta = sqrt(x * x + y * y + z * z);
    double s, c1; /* sin(theta)/theta and (1-cos(theta))/theta^2 */
    if (theta < 1e-4) {
        double t2 = theta * theta;
        s = 1.0 - t2 / 6.0;
        c1 = 0.5 - t2 / 24.0;
    } else {
        s = sin(theta) / theta;
        c1 = (1.0 - cos(theta)) / (theta * theta);
    }
    double c = 1.0 - c1 * theta * theta;
    /* R = c I + s [k]x + c1 k k^T with k the unnormalised axis; cglm is column-major. */
    out[0][0] = (float)(c + c1 * x * x);
    out[0][1] = (float)(c1 * x * y + s * z);
    out[0][2] = (float)(c1 * x * z - s * y);
    out[1][0] = (float)(c1 * x * y - s * z);
    out[1][1] = (float)(c + c1 * y * y);
    out[1][2] = (float)(c1 * y * z + s * x);
    out[2][0] = (float)(c1 * x * z + s * y);
    out[2][1] = (float)(c1 * y * z - s * x);
    out[2][2] = (float)(c + c1 * z * z);
}

void weft__forward_kinematics(const int32_t *parents, const float *joints, const weft_pose *pose,
                              mat4 out_world[WEFT_BODY_JOINTS])
{
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        mat3 r;
        weft__axis_angle_to_mat3(pose->rotations + 3 * j, r);
        mat4 local;
        glm_mat4_identity(local);
        glm_mat4_ins3(r, local);
        int32_t p = parents[j];
        if (p < 0) {
            local[3][0] = joints[3 * j + 0] + pose->translation[0];
            local[3][1] = joints[3 * j + 1] + pose->translation[1];
            local[3][2] = joints[3 * j + 2] + pose->translation[2];
            glm_mat4_copy(local, out_world[j]);
        } else {
            local[3][0] = joints[3 * j + 0] - joints[3 * p + 0];
            local[3][1] = joints[3 * j + 1] - joints[3 * p + 1];
            local[3][2] = joints[3 * j + 2] - joints[3 * p + 2];
            glm_mat4_mul(out_world[p], local, out_world[j]);
        }
    }
}

void weft__skinning_matrices(const weft_body *body, const weft_pose *pose, mat4 out[WEFT_BODY_JOINTS],
                             mat4 out_world[WEFT_BODY_JOINTS])
{
    weft__forward_kinematics(body->parents, body->joints, pose, out_world);
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        glm_mat4_mul(out_world[j], (vec4 *)body->inverse_bind[j], out[j]);
    }
}

/* Inverse bind matrices: inverse of each joint's world transform in the bind pose. For the
 * zero pose that is a pure translation by -J. */
static void update_inverse_bind(weft_body *body)
{
    weft_pose bind;
    if (body->has_bind_pose) {
        bind = body->bind_pose;
    } else {
        memset(&bind, 0, sizeof bind);
    }
    mat4 world[WEFT_BODY_JOINTS];
    weft__forward_kinematics(body->parents, body->joints, &bind, world);
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        /* Rigid transform: inverse = [R^T | -R^T t]. */
        mat4 inv;
        glm_mat4_identity(inv);
        for (int c = 0; c < 3; ++c) {
            for (int r = 0; r < 3; ++r) {
                inv[c][r] = world[j][r][c];
            }
        }
        for (int r = 0; r < 3; ++r) {
            inv[3][r] = -(inv[0][r] * world[j][3][0] + inv[1][r] * world[j][3][1] + inv[2][r] * world[j][3][2]);
        }
        glm_mat4_copy(inv, body->inverse_bind[j]);
    }
}

static void regress_joints(weft_body *body)
{
    const uint32_t n = body->vertex_count;
    const float *v = body->shaped_vertices;
    if (body->j_regressor) {
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            double acc[3] = {0, 0, 0};
            const float *row = body->j_regressor + (size_t)j * n;
            for (uint32_t i = 0; i < n; ++i) {
                if (row[i] != 0.0f) {
                    acc[0] += (double)row[i] * v[3 * i + 0];
                    acc[1] += (double)row[i] * v[3 * i + 1];
                    acc[2] += (double)row[i] * v[3 * i + 2];
                }
            }
            for (int k = 0; k < 3; ++k) {
                body->joints[3 * j + k] = (float)acc[k];
            }
        }
    } else if (body->csr_indptr) {
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            double acc[3] = {0, 0, 0};
            for (uint32_t e = body->csr_indptr[j]; e < body->csr_indptr[j + 1]; ++e) {
                uint32_t i = body->csr_indices[e];
                acc[0] += (double)body->csr_data[e] * v[3 * i + 0];
                acc[1] += (double)body->csr_data[e] * v[3 * i + 1];
                acc[2] += (double)body->csr_data[e] * v[3 * i + 2];
            }
            for (int k = 0; k < 3; ++k) {
                body->joints[3 * j + k] = (float)acc[k];
            }
        }
    }
}

weft_body_def weft_default_body_def(void)
{
    weft_body_def def;
    memset(&def, 0, sizeof def);
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

static void *dup_array(weft_context *ctx, const void *src, size_t bytes)
{
    void *p = weft__alloc(ctx, bytes);
    if (p && src) {
        memcpy(p, src, bytes);
    }
    return p;
}

static weft_result validate_def(const weft_body_def *def)
{
    if (!def->vertices || !def->triangles || !def->weights) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: vertices, triangles and weights are required");
    }
    if (def->vertex_count < 3 || def->triangle_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: vertex_count %u / triangle_count %u too small",
                          def->vertex_count, def->triangle_count);
    }
    if (def->vertex_count > 10000000u || def->triangle_count > 20000000u || def->shape_count > 4096u) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: counts beyond limits (vertices %u, triangles %u, shapes %u)",
                          def->vertex_count, def->triangle_count, def->shape_count);
    }
    int sources = (def->joints != NULL) + (def->j_regressor != NULL) + (def->j_regressor_indptr != NULL);
    if (sources != 1) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "body def: give exactly one of joints, j_regressor or the CSR regressor (got %d)", sources);
    }
    if (def->j_regressor_indptr && (!def->j_regressor_indices || !def->j_regressor_data)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: CSR regressor needs indptr, indices and data");
    }
    if (def->bind_pose && !def->joints) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: bind_pose needs explicit joints, not a regressor");
    }
    if (def->bind_pose && def->posedirs) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: posedirs assume a zero bind pose");
    }
    if ((def->shapedirs == NULL) != (def->shape_count == 0)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: shapedirs and shape_count must be given together");
    }
    const size_t nv = def->vertex_count;
    if (!weft__all_finite(def->vertices, nv * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: vertices contain NaN or infinity");
    }
    if (!weft__all_finite(def->weights, nv * WEFT_BODY_JOINTS)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: weights contain NaN or infinity");
    }
    for (size_t i = 0; i < nv; ++i) {
        double sum = 0;
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            float w = def->weights[i * WEFT_BODY_JOINTS + j];
            if (w < 0.0f) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: weights[%zu][%u] = %g is negative", i, j, (double)w);
            }
            sum += w;
        }
        if (fabs(sum - 1.0) > 1e-3) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: weights of vertex %zu sum to %g, not 1", i, sum);
        }
    }
    for (size_t t = 0; t < def->triangle_count; ++t) {
        const uint32_t *tri = def->triangles + 3 * t;
        if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "body def: triangle %zu has an index out of range", t);
        }
        if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "body def: triangle %zu repeats a vertex", t);
        }
        vec3 e1, e2, n;
        glm_vec3_sub((float *)def->vertices + 3 * tri[1], (float *)def->vertices + 3 * tri[0], e1);
        glm_vec3_sub((float *)def->vertices + 3 * tri[2], (float *)def->vertices + 3 * tri[0], e2);
        glm_vec3_cross(e1, e2, n);
        if (glm_vec3_norm(n) <= 0.0f) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "body def: triangle %zu has zero area", t);
        }
    }
    const int32_t *parents = def->parents ? def->parents : weft__smpl_parents;
    if (parents[0] != -1) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: parents[0] = %d, the root must be -1", parents[0]);
    }
    for (int32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
        if (parents[j] < 0 || parents[j] >= j) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: parents[%d] = %d must be in [0, %d)", j, parents[j], j);
        }
    }
    if (def->joints && !weft__all_finite(def->joints, WEFT_BODY_JOINTS * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: joints contain NaN or infinity");
    }
    if (def->j_regressor && !weft__all_finite(def->j_regressor, nv * WEFT_BODY_JOINTS)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: j_regressor contains NaN or infinity");
    }
    if (def->j_regressor_indptr) {
        const uint32_t *ip = def->j_regressor_indptr;
        if (ip[0] != 0 || ip[WEFT_BODY_JOINTS] != def->j_regressor_nnz) {
            return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "body def: CSR indptr must run from 0 to nnz = %u (got %u..%u)",
                              def->j_regressor_nnz, ip[0], ip[WEFT_BODY_JOINTS]);
        }
        for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            if (ip[j + 1] < ip[j]) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: CSR indptr decreases at row %u", j);
            }
        }
        for (uint32_t e = 0; e < def->j_regressor_nnz; ++e) {
            if (def->j_regressor_indices[e] >= nv) {
                return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "body def: CSR index %u = %u out of range (%zu vertices)", e,
                                  def->j_regressor_indices[e], nv);
            }
        }
        if (!weft__all_finite(def->j_regressor_data, def->j_regressor_nnz)) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: CSR regressor data contains NaN or infinity");
        }
    }
    if (def->shapedirs && !weft__all_finite(def->shapedirs, nv * 3 * def->shape_count)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: shapedirs contain NaN or infinity");
    }
    if (def->posedirs && !weft__all_finite(def->posedirs, nv * 3 * WEFT_POSE_BLEND_FLOATS)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: posedirs contain NaN or infinity");
    }
    if (def->bind_pose && (!weft__all_finite(def->bind_pose->rotations, WEFT_POSE_ROTATION_FLOATS) ||
                           !weft__all_finite(def->bind_pose->translation, 3))) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: bind_pose contains NaN or infinity");
    }
    return WEFT_OK;
}

void weft_body_destroy(weft_body *body)
{
    if (!body) {
        return;
    }
    weft_context *ctx = body->context;
    size_t nv = body->vertex_count;
    weft__free(ctx, body->template_vertices, nv * 3 * sizeof(float));
    weft__free(ctx, body->shaped_vertices, nv * 3 * sizeof(float));
    weft__free(ctx, body->triangles, (size_t)body->triangle_count * 3 * sizeof(uint32_t));
    weft__free(ctx, body->weights, nv * WEFT_BODY_JOINTS * sizeof(float));
    weft__free(ctx, body->shapedirs, nv * 3 * body->shape_count * sizeof(float));
    weft__free(ctx, body->posedirs, nv * 3 * WEFT_POSE_BLEND_FLOATS * sizeof(float));
    weft__free(ctx, body->j_regressor, nv * WEFT_BODY_JOINTS * sizeof(float));
    weft__free(ctx, body->csr_indptr, (WEFT_BODY_JOINTS + 1) * sizeof(uint32_t));
    weft__free(ctx, body->csr_indices, (size_t)body->csr_nnz * sizeof(uint32_t));
    weft__free(ctx, body->csr_data, (size_t)body->csr_nnz * sizeof(float));
    weft__free(ctx, body->avatar, sizeof(weft_avatar_shape));
    weft__free(ctx, body, sizeof *body);
}

weft_result weft_body_create(weft_context *context, const weft_body_def *def, weft_body **out_body)
{
    if (!context || !def || !out_body) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_create: NULL argument");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_create: def not made by weft_default_body_def()");
    }
    weft_result r = validate_def(def);
    if (r != WEFT_OK) {
        return r;
    }
    weft_body *b = weft__alloc(context, sizeof *b);
    if (!b) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    const size_t nv = def->vertex_count;
    b->context = context;
    b->vertex_count = def->vertex_count;
    b->triangle_count = def->triangle_count;
    b->shape_count = def->shape_count;
    b->template_vertices = dup_array(context, def->vertices, nv * 3 * sizeof(float));
    b->shaped_vertices = dup_array(context, def->vertices, nv * 3 * sizeof(float));
    b->triangles = dup_array(context, def->triangles, (size_t)def->triangle_count * 3 * sizeof(uint32_t));
    b->weights = dup_array(context, def->weights, nv * WEFT_BODY_JOINTS * sizeof(float));
    bool ok = b->template_vertices && b->shaped_vertices && b->triangles && b->weights;
    if (ok && def->shapedirs) {
        ok = (b->shapedirs = dup_array(context, def->shapedirs, nv * 3 * def->shape_count * sizeof(float))) != NULL;
    }
    if (ok && def->posedirs) {
        ok = (b->posedirs = dup_array(context, def->posedirs, nv * 3 * WEFT_POSE_BLEND_FLOATS * sizeof(float))) != NULL;
    }
    if (ok && def->j_regressor) {
        ok = (b->j_regressor = dup_array(context, def->j_regressor, nv * WEFT_BODY_JOINTS * sizeof(float))) != NULL;
    }
    if (ok && def->j_regressor_indptr) {
        b->csr_nnz = def->j_regressor_nnz;
        b->csr_indptr = dup_array(context, def->j_regressor_indptr, (WEFT_BODY_JOINTS + 1) * sizeof(uint32_t));
        b->csr_indices = dup_array(context, def->j_regressor_indices, (size_t)b->csr_nnz * sizeof(uint32_t));
        b->csr_data = dup_array(context, def->j_regressor_data, (size_t)b->csr_nnz * sizeof(float));
        ok = b->csr_indptr && b->csr_indices && b->csr_data;
    }
    if (!ok) {
        weft_body_destroy(b);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    memcpy(b->parents, def->parents ? def->parents : weft__smpl_parents, sizeof b->parents);
    if (def->joints) {
        memcpy(b->joints, def->joints, sizeof b->joints);
    } else {
        regress_joints(b);
        if (!weft__all_finite(b->joints, WEFT_BODY_JOINTS * 3)) {
            weft_body_destroy(b);
            return weft__fail(WEFT_ERROR_NOT_FINITE, "body def: regressed joints are not finite");
        }
    }
    if (def->bind_pose) {
        b->has_bind_pose = true;
        b->bind_pose = *def->bind_pose;
    }
    update_inverse_bind(b);
    *out_body = b;
    return WEFT_OK;
}

uint32_t weft_body_vertex_count(const weft_body *body) { return body ? body->vertex_count : 0; }
uint32_t weft_body_triangle_count(const weft_body *body) { return body ? body->triangle_count : 0; }
const uint32_t *weft_body_triangles(const weft_body *body) { return body ? body->triangles : NULL; }
const float *weft_body_rest_vertices(const weft_body *body) { return body ? body->shaped_vertices : NULL; }
const float *weft_body_weights(const weft_body *body) { return body ? body->weights : NULL; }
const float *weft_body_rest_joints(const weft_body *body) { return body ? body->joints : NULL; }

weft_result weft_body_triangle_parts(const weft_body *body, uint8_t *out_parts, uint32_t count)
{
    if (!body || !out_parts) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_triangle_parts: body and out_parts are required");
    }
    const uint32_t nt = weft_body_triangle_count(body);
    if (count != nt) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_body_triangle_parts: count %u, the body has %u triangles",
                          count, nt);
    }
    const uint32_t *tris = weft_body_triangles(body);
    for (uint32_t t = 0; t < nt; ++t) {
        float sum[WEFT_BODY_JOINTS] = {0};
        for (int k = 0; k < 3; ++k) {
            const float *w = body->weights + (size_t)tris[3 * (size_t)t + k] * WEFT_BODY_JOINTS;
            for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
                sum[j] += w[j];
            }
        }
        uint32_t best = 0;
        for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
            best = sum[j] > sum[best] ? j : best;
        }
        out_parts[t] = (uint8_t)best;
    }
    return WEFT_OK;
}
uint32_t weft_body_shape_count(const weft_body *body) { return body ? body->shape_count : 0; }

void weft_body_bind_pose(const weft_body *body, weft_pose *out_pose)
{
    if (!out_pose) {
        return;
    }
    if (body && body->has_bind_pose) {
        *out_pose = body->bind_pose;
    } else {
        memset(out_pose, 0, sizeof *out_pose);
    }
}

weft_result weft_body_set_shape(weft_body *body, const float *betas, uint32_t count)
{
    if (!body || (count && !betas)) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_set_shape: NULL argument");
    }
    if (count > body->shape_count) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_body_set_shape: %u betas, the body has %u shape directions",
                          count, body->shape_count);
    }
    if (count && !weft__all_finite(betas, count)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_body_set_shape: betas contain NaN or infinity");
    }
    const size_t n3 = (size_t)body->vertex_count * 3;
    for (size_t i = 0; i < n3; ++i) {
        double v = body->template_vertices[i];
        const float *dirs = body->shapedirs ? body->shapedirs + i * body->shape_count : NULL;
        for (uint32_t k = 0; k < count; ++k) {
            v += (double)dirs[k] * betas[k];
        }
        body->shaped_vertices[i] = (float)v;
    }
    regress_joints(body);
    update_inverse_bind(body);
    return WEFT_OK;
}

static bool pose_finite(const weft_pose *pose)
{
    return weft__all_finite(pose->rotations, WEFT_POSE_ROTATION_FLOATS) && weft__all_finite(pose->translation, 3);
}

/* p' = sum_j w_j A_j p, with the blended matrix built only from non-zero weights. */
static void skin_point(const mat4 *skin, const float *w, const float *p, float *out)
{
    float m[12] = {0};
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        float wj = w[j];
        if (wj == 0.0f) {
            continue;
        }
        for (int c = 0; c < 4; ++c) {
            m[3 * c + 0] += wj * skin[j][c][0];
            m[3 * c + 1] += wj * skin[j][c][1];
            m[3 * c + 2] += wj * skin[j][c][2];
        }
    }
    float x = p[0], y = p[1], z = p[2];
    out[0] = m[0] * x + m[3] * y + m[6] * z + m[9];
    out[1] = m[1] * x + m[4] * y + m[7] * z + m[10];
    out[2] = m[2] * x + m[5] * y + m[8] * z + m[11];
}

weft_result weft_body_pose(const weft_body *body, const weft_pose *pose, float *out_vertices,
                           float *out_joint_transforms)
{
    if (!body || !pose) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_pose: NULL argument");
    }
    if (!pose_finite(pose)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_body_pose: pose contains NaN or infinity");
    }
    mat4 skin[WEFT_BODY_JOINTS], world[WEFT_BODY_JOINTS];
    weft__skinning_matrices(body, pose, skin, world);
    if (out_vertices) {
        float blend[WEFT_POSE_BLEND_FLOATS];
        if (body->posedirs) {
            for (uint32_t j = 1; j < WEFT_BODY_JOINTS; ++j) {
                mat3 r;
                weft__axis_angle_to_mat3(pose->rotations + 3 * j, r);
                /* Row-major flattening of R - I, as numpy's reshape of a (3, 3) array. */
                for (int row = 0; row < 3; ++row) {
                    for (int col = 0; col < 3; ++col) {
                        blend[9 * (j - 1) + 3 * row + col] = r[col][row] - (row == col ? 1.0f : 0.0f);
                    }
                }
            }
        }
        for (uint32_t i = 0; i < body->vertex_count; ++i) {
            float v[3] = {body->shaped_vertices[3 * i], body->shaped_vertices[3 * i + 1], body->shaped_vertices[3 * i + 2]};
            if (body->posedirs) {
                for (int k = 0; k < 3; ++k) {
                    const float *dirs = body->posedirs + ((size_t)i * 3 + (size_t)k) * WEFT_POSE_BLEND_FLOATS;
                    float acc = 0.0f;
                    for (uint32_t q = 0; q < WEFT_POSE_BLEND_FLOATS; ++q) {
                        acc += dirs[q] * blend[q];
                    }
                    v[k] += acc;
                }
            }
            skin_point((const mat4 *)skin, body->weights + (size_t)i * WEFT_BODY_JOINTS, v, out_vertices + 3 * (size_t)i);
        }
    }
    if (out_joint_transforms) {
        memcpy(out_joint_transforms, world, sizeof world);
    }
    return WEFT_OK;
}

weft_result weft_body_skin_points(const weft_body *body, const weft_pose *pose, const float *rest_points,
                                  const float *weights, uint32_t count, float *out_points)
{
    if (!body || !pose || !rest_points || !weights || !out_points) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_skin_points: NULL argument");
    }
    if (!pose_finite(pose)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_body_skin_points: pose contains NaN or infinity");
    }
    if (rest_points == out_points) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_body_skin_points: out_points aliases rest_points");
    }
    mat4 skin[WEFT_BODY_JOINTS], world[WEFT_BODY_JOINTS];
    weft__skinning_matrices(body, pose, skin, world);
    for (uint32_t i = 0; i < count; ++i) {
        skin_point((const mat4 *)skin, weights + (size_t)i * WEFT_BODY_JOINTS, rest_points + 3 * (size_t)i,
                   out_points + 3 * (size_t)i);
    }
    return WEFT_OK;
}
