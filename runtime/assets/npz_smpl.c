/* SMPL model from an .npz archive: maps the arrays onto weft_body_def after checking every
 * shape against the vertex and joint counts. */
#include "npz.h"

#include "core/core.h"

#include <stdio.h>
#include <string.h>

typedef struct scratch {
    weft_context *ctx;
    void *ptr[16];
    size_t size[16];
    int count;
} scratch;

static void *scratch_alloc(scratch *s, size_t bytes)
{
    if (s->count >= 16) {
        return NULL;
    }
    void *p = weft__alloc(s->ctx, bytes);
    if (p) {
        s->ptr[s->count] = p;
        s->size[s->count] = bytes;
        s->count++;
    }
    return p;
}

static void scratch_free(scratch *s)
{
    for (int i = 0; i < s->count; ++i) {
        weft__free(s->ctx, s->ptr[i], s->size[i]);
    }
    s->count = 0;
}

static weft_result need(const weft_npz *npz, const char *name, const weft_npy_array **out)
{
    *out = weft_npz_find(npz, name);
    if (!*out) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: array '%s' is missing", name);
    }
    if ((*out)->dtype == WEFT_NPY_UNSUPPORTED) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: array '%s' has non-numeric dtype '%s'", name, (*out)->descr);
    }
    return WEFT_OK;
}

static weft_result check_shape(const weft_npy_array *a, uint32_t ndim, const uint64_t *shape)
{
    bool ok = a->ndim == ndim;
    for (uint32_t d = 0; ok && d < ndim; ++d) {
        ok = shape[d] == 0 || a->shape[d] == shape[d];
    }
    if (!ok) {
        char got[96] = "", want[96] = "";
        size_t g = 0, w = 0;
        for (uint32_t d = 0; d < a->ndim && g < sizeof got - 24; ++d) {
            g += (size_t)snprintf(got + g, sizeof got - g, d ? ", %llu" : "%llu", (unsigned long long)a->shape[d]);
        }
        for (uint32_t d = 0; d < ndim && w < sizeof want - 24; ++d) {
            if (shape[d]) {
                w += (size_t)snprintf(want + w, sizeof want - w, d ? ", %llu" : "%llu", (unsigned long long)shape[d]);
            } else {
                w += (size_t)snprintf(want + w, sizeof want - w, d ? ", *" : "*");
            }
        }
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: array '%s' has shape (%s), expected (%s)", a->name, got, want);
    }
    return WEFT_OK;
}

static weft_result to_f32(scratch *s, const weft_npy_array *a, float **out)
{
    *out = scratch_alloc(s, (size_t)a->count * sizeof(float));
    if (!*out) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    return weft_npy_to_f32(a, *out, a->count);
}

static weft_result to_u32_indices(scratch *s, const weft_npy_array *a, uint64_t limit, uint32_t **out)
{
    int64_t *tmp = scratch_alloc(s, (size_t)a->count * sizeof(int64_t));
    *out = scratch_alloc(s, (size_t)a->count * sizeof(uint32_t));
    if (!tmp || !*out) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    weft_result r = weft_npy_to_i64(a, tmp, a->count);
    if (r != WEFT_OK) {
        return r;
    }
    for (uint64_t i = 0; i < a->count; ++i) {
        if (tmp[i] < 0 || (uint64_t)tmp[i] >= limit) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: '%s'[%llu] = %lld is out of range [0, %llu)", a->name,
                              (unsigned long long)i, (long long)tmp[i], (unsigned long long)limit);
        }
        (*out)[i] = (uint32_t)tmp[i];
    }
    return WEFT_OK;
}

/* scipy sparse stored as J_regressor_{data,indices,indptr,shape}: CSR (indptr has rows+1
 * entries) or CSC (cols+1), converted to CSR rows of joints. */
static weft_result sparse_regressor(scratch *s, const weft_npz *npz, uint32_t nv, weft_body_def *def)
{
    const weft_npy_array *data, *indices, *indptr, *shape;
    weft_result r;
    if ((r = need(npz, "J_regressor_data", &data)) != WEFT_OK || (r = need(npz, "J_regressor_indices", &indices)) != WEFT_OK ||
        (r = need(npz, "J_regressor_indptr", &indptr)) != WEFT_OK || (r = need(npz, "J_regressor_shape", &shape)) != WEFT_OK) {
        return r;
    }
    int64_t dims[2];
    if (shape->ndim != 1 || shape->count != 2) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: 'J_regressor_shape' must hold 2 integers");
    }
    if ((r = weft_npy_to_i64(shape, dims, 2)) != WEFT_OK) {
        return r;
    }
    if (dims[0] != WEFT_BODY_JOINTS || dims[1] != (int64_t)nv) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor is %lld x %lld, expected %d x %u (joints x vertices)",
                          (long long)dims[0], (long long)dims[1], WEFT_BODY_JOINTS, nv);
    }
    if (data->ndim != 1 || indices->ndim != 1 || indptr->ndim != 1 || data->count != indices->count ||
        data->count > (uint64_t)WEFT_BODY_JOINTS * nv) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor_data / _indices must be 1-D of equal length <= %llu",
                          (unsigned long long)WEFT_BODY_JOINTS * nv);
    }
    const uint32_t nnz = (uint32_t)data->count;
    bool csr = indptr->count == WEFT_BODY_JOINTS + 1;
    bool csc = indptr->count == (uint64_t)nv + 1;
    if (!csr && !csc) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor_indptr has %llu entries, expected %d (CSR) or %u (CSC)",
                          (unsigned long long)indptr->count, WEFT_BODY_JOINTS + 1, nv + 1);
    }
    float *vals;
    uint32_t *idx, *ptr;
    if ((r = to_f32(s, data, &vals)) != WEFT_OK || (r = to_u32_indices(s, indices, csr ? nv : WEFT_BODY_JOINTS, &idx)) != WEFT_OK ||
        (r = to_u32_indices(s, indptr, (uint64_t)nnz + 1, &ptr)) != WEFT_OK) {
        return r;
    }
    uint64_t nptr = indptr->count;
    if (ptr[0] != 0 || ptr[nptr - 1] != nnz) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor_indptr must run from 0 to %u", nnz);
    }
    for (uint64_t i = 1; i < nptr; ++i) {
        if (ptr[i] < ptr[i - 1]) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor_indptr decreases at %llu", (unsigned long long)i);
        }
    }
    if (csr) {
        def->j_regressor_indptr = ptr;
        def->j_regressor_indices = idx;
        def->j_regressor_data = vals;
        def->j_regressor_nnz = nnz;
        return WEFT_OK;
    }
    /* CSC -> CSR: count per row, prefix sum, scatter (columns come out sorted). */
    uint32_t *rptr = scratch_alloc(s, (WEFT_BODY_JOINTS + 1) * sizeof(uint32_t));
    uint32_t *ridx = scratch_alloc(s, (size_t)nnz * sizeof(uint32_t) + 4);
    float *rval = scratch_alloc(s, (size_t)nnz * sizeof(float) + 4);
    if (!rptr || !ridx || !rval) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t e = 0; e < nnz; ++e) {
        rptr[idx[e] + 1]++;
    }
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        rptr[j + 1] += rptr[j];
    }
    uint32_t fill[WEFT_BODY_JOINTS];
    memcpy(fill, rptr, sizeof fill);
    for (uint32_t col = 0; col < nv; ++col) {
        for (uint32_t e = ptr[col]; e < ptr[col + 1]; ++e) {
            uint32_t row = idx[e];
            ridx[fill[row]] = col;
            rval[fill[row]] = vals[e];
            fill[row]++;
        }
    }
    def->j_regressor_indptr = rptr;
    def->j_regressor_indices = ridx;
    def->j_regressor_data = rval;
    def->j_regressor_nnz = nnz;
    return WEFT_OK;
}

static weft_result build(scratch *s, const weft_npz *npz, weft_context *context, weft_body **out_body)
{
    const weft_npy_array *vt, *f, *w;
    weft_result r;
    if ((r = need(npz, "v_template", &vt)) != WEFT_OK || (r = need(npz, "f", &f)) != WEFT_OK ||
        (r = need(npz, "weights", &w)) != WEFT_OK) {
        return r;
    }
    if ((r = check_shape(vt, 2, (const uint64_t[]){0, 3})) != WEFT_OK) {
        return r;
    }
    if (vt->shape[0] < 3 || vt->shape[0] > 10000000u) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: v_template has %llu vertices", (unsigned long long)vt->shape[0]);
    }
    const uint32_t nv = (uint32_t)vt->shape[0];
    if ((r = check_shape(f, 2, (const uint64_t[]){0, 3})) != WEFT_OK) {
        return r;
    }
    if (f->shape[0] == 0 || f->shape[0] > 20000000u) {
        return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: f has %llu triangles", (unsigned long long)f->shape[0]);
    }
    if ((r = check_shape(w, 2, (const uint64_t[]){nv, WEFT_BODY_JOINTS})) != WEFT_OK) {
        return r;
    }
    weft_body_def def = weft_default_body_def();
    float *vertices, *weights;
    uint32_t *tris;
    if ((r = to_f32(s, vt, &vertices)) != WEFT_OK || (r = to_f32(s, w, &weights)) != WEFT_OK ||
        (r = to_u32_indices(s, f, nv, &tris)) != WEFT_OK) {
        return r;
    }
    def.vertices = vertices;
    def.vertex_count = nv;
    def.triangles = tris;
    def.triangle_count = (uint32_t)f->shape[0];
    def.weights = weights;

    const weft_npy_array *jr = weft_npz_find(npz, "J_regressor");
    if (jr) {
        if (jr->dtype == WEFT_NPY_UNSUPPORTED) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: J_regressor has non-numeric dtype '%s' (a pickled sparse "
                                                 "matrix? store it dense or as J_regressor_data/indices/indptr/shape)",
                              jr->descr);
        }
        if ((r = check_shape(jr, 2, (const uint64_t[]){WEFT_BODY_JOINTS, nv})) != WEFT_OK) {
            return r;
        }
        float *reg;
        if ((r = to_f32(s, jr, &reg)) != WEFT_OK) {
            return r;
        }
        def.j_regressor = reg;
    } else if ((r = sparse_regressor(s, npz, nv, &def)) != WEFT_OK) {
        return r;
    }

    int32_t parents[WEFT_BODY_JOINTS];
    const weft_npy_array *kt = weft_npz_find(npz, "kintree_table");
    if (kt) {
        if (kt->ndim != 2 || kt->shape[0] != 2) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: kintree_table must be (2, joints)");
        }
        if (kt->shape[1] != WEFT_BODY_JOINTS) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: kintree_table has %llu joints, weft supports SMPL's %d",
                              (unsigned long long)kt->shape[1], WEFT_BODY_JOINTS);
        }
        int64_t table[2 * WEFT_BODY_JOINTS];
        if ((r = weft_npy_to_i64(kt, table, 2 * WEFT_BODY_JOINTS)) != WEFT_OK) {
            return r;
        }
        for (int32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
            int64_t parent = table[j], id = table[WEFT_BODY_JOINTS + j];
            if (id != j) {
                return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: kintree_table[1][%d] = %lld, joints must be listed in order",
                                  j, (long long)id);
            }
            if (j == 0) {
                /* The root's parent is stored as -1 or as the unsigned 2^32 - 1. */
                if (parent != -1 && parent != 4294967295LL) {
                    return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: kintree_table root parent is %lld", (long long)parent);
                }
                parents[0] = -1;
            } else {
                if (parent < 0 || parent >= j) {
                    return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: kintree_table parent of joint %d is %lld", j,
                                      (long long)parent);
                }
                parents[j] = (int32_t)parent;
            }
        }
        def.parents = parents;
    }

    const weft_npy_array *sd = weft_npz_find(npz, "shapedirs");
    if (sd) {
        if ((r = check_shape(sd, 3, (const uint64_t[]){nv, 3, 0})) != WEFT_OK) {
            return r;
        }
        if (sd->shape[2] == 0 || sd->shape[2] > 4096) {
            return weft__fail(WEFT_ERROR_FORMAT, "smpl npz: shapedirs has %llu shape directions",
                              (unsigned long long)sd->shape[2]);
        }
        float *dirs;
        if ((r = to_f32(s, sd, &dirs)) != WEFT_OK) {
            return r;
        }
        def.shapedirs = dirs;
        def.shape_count = (uint32_t)sd->shape[2];
    }
    const weft_npy_array *pd = weft_npz_find(npz, "posedirs");
    if (pd) {
        if ((r = check_shape(pd, 3, (const uint64_t[]){nv, 3, WEFT_POSE_BLEND_FLOATS})) != WEFT_OK) {
            return r;
        }
        float *dirs;
        if ((r = to_f32(s, pd, &dirs)) != WEFT_OK) {
            return r;
        }
        def.posedirs = dirs;
    }
    r = weft_body_create(context, &def, out_body);
    if (r != WEFT_OK && r != WEFT_ERROR_OUT_OF_MEMORY) {
        /* Keep the body validator's message but report it as a malformed file. */
        char msg[512];
        snprintf(msg, sizeof msg, "%s", weft_last_error());
        return weft__fail(r == WEFT_ERROR_NOT_FINITE ? r : WEFT_ERROR_FORMAT, "smpl npz: %s", msg);
    }
    return r;
}

weft_result weft_smpl_body_from_npz(weft_context *context, const weft_npz *npz, weft_body **out_body)
{
    if (!context || !npz || !out_body) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_smpl_body_from_npz: NULL argument");
    }
    scratch s = {.ctx = context};
    weft_result r = build(&s, npz, context, out_body);
    scratch_free(&s);
    return r;
}

weft_result weft_smpl_load_npz_memory(weft_context *context, const void *bytes, size_t size, weft_body **out_body)
{
    weft_npz *npz = NULL;
    weft_result r = weft_npz_read_memory(context, bytes, size, &npz);
    if (r == WEFT_OK) {
        r = weft_smpl_body_from_npz(context, npz, out_body);
        weft_npz_destroy(npz);
    }
    return r;
}

weft_result weft_smpl_load_npz_file(weft_context *context, const char *path, weft_body **out_body)
{
    weft_npz *npz = NULL;
    weft_result r = weft_npz_read_file(context, path, &npz);
    if (r == WEFT_OK) {
        r = weft_smpl_body_from_npz(context, npz, out_body);
        weft_npz_destroy(npz);
    }
    return r;
}
