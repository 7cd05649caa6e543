/* Small meshes for the XPBD tests: a regular sheet, a closed box, two meshes joined into one, and
 * the garment def of a cloth over a collider. */
#ifndef WEFT_TEST_XPBD_SCENE_H
#define WEFT_TEST_XPBD_SCENE_H

#include "weft.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct test_mesh {
    float *pos;
    uint32_t *tris;
    uint32_t nv, nt;
} test_mesh;

static inline void test_mesh_free(test_mesh *m)
{
    free(m->pos);
    free(m->tris);
    m->pos = NULL;
    m->tris = NULL;
}

/* nx x nz vertices spanning sx x sz metres in the XZ plane at height y, centred at (cx, cz). */
static inline test_mesh test_sheet(uint32_t nx, uint32_t nz, float sx, float sz, float cx, float y, float cz)
{
    test_mesh m = {0};
    m.nv = nx * nz;
    m.nt = 2 * (nx - 1) * (nz - 1);
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.tris = malloc(sizeof(uint32_t) * 3 * m.nt);
    for (uint32_t j = 0; j < nz; ++j) {
        for (uint32_t i = 0; i < nx; ++i) {
            float *p = m.pos + 3 * (j * nx + i);
            p[0] = cx + sx * ((float)i / (float)(nx - 1) - 0.5f);
            p[1] = y;
            p[2] = cz + sz * ((float)j / (float)(nz - 1) - 0.5f);
        }
    }
    uint32_t t = 0;
    for (uint32_t j = 0; j + 1 < nz; ++j) {
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t a = j * nx + i, b = a + 1, c = a + nx, d = c + 1;
            /* counter-clockwise seen from +Y */
            uint32_t *q = m.tris + 6 * t++;
            if ((i + j) & 1) {
                q[0] = a, q[1] = c, q[2] = b, q[3] = b, q[4] = c, q[5] = d;
            } else {
                q[0] = a, q[1] = c, q[2] = d, q[3] = a, q[4] = d, q[5] = b;
            }
        }
    }
    return m;
}

/* Axis-aligned box [lo, hi], 8 vertices, 12 outward-facing triangles. */
static inline test_mesh test_box(const float lo[3], const float hi[3])
{
    test_mesh m = {0};
    m.nv = 8;
    m.nt = 12;
    m.pos = malloc(sizeof(float) * 24);
    m.tris = malloc(sizeof(uint32_t) * 36);
    for (uint32_t i = 0; i < 8; ++i) {
        m.pos[3 * i + 0] = (i & 1) ? hi[0] : lo[0];
        m.pos[3 * i + 1] = (i & 2) ? hi[1] : lo[1];
        m.pos[3 * i + 2] = (i & 4) ? hi[2] : lo[2];
    }
    static const uint32_t t[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    for (int i = 0; i < 36; ++i) {
        m.tris[i] = t[i];
    }
    return m;
}

/* a and b as one mesh (b's vertices after a's); the parts are not freed. pos/tris are NULL when
 * out of memory. */
static inline test_mesh test_mesh_join(const test_mesh *a, const test_mesh *b)
{
    test_mesh m = {0};
    m.nv = a->nv + b->nv;
    m.nt = a->nt + b->nt;
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.tris = malloc(sizeof(uint32_t) * 3 * m.nt);
    if (!m.pos || !m.tris) {
        test_mesh_free(&m);
        return m;
    }
    memcpy(m.pos, a->pos, sizeof(float) * 3 * a->nv);
    memcpy(m.pos + 3 * a->nv, b->pos, sizeof(float) * 3 * b->nv);
    memcpy(m.tris, a->tris, sizeof(uint32_t) * 3 * a->nt);
    for (uint32_t i = 0; i < 3 * b->nt; ++i) {
        m.tris[3 * a->nt + i] = b->tris[i] + a->nv;
    }
    return m;
}

/* A garment of `method` at `substeps` for cloth over collider (NULL: none), CCD off. */
static inline weft_garment_def test_garment_def(weft_method method, const test_mesh *cloth, const test_mesh *collider,
                                                uint32_t substeps)
{
    weft_garment_def gd = weft_default_garment_def();
    gd.method = method;
    gd.substeps = substeps;
    gd.ccd.enabled = false;
    gd.rest_positions = cloth->pos;
    gd.vertex_count = cloth->nv;
    gd.triangles = cloth->tris;
    gd.triangle_count = cloth->nt;
    if (collider) {
        gd.collider_rest_positions = collider->pos;
        gd.collider_vertex_count = collider->nv;
        gd.collider_triangles = collider->tris;
        gd.collider_triangle_count = collider->nt;
    }
    return gd;
}

/* The lifting box of the fast-collider cases: over frames 3..11 the box rises 6 cm a frame
 * (3.6 m/s); returns this frame's rise. */
static inline float test_lift_box(test_mesh *box, int frame)
{
    const float rise = frame >= 3 && frame < 12 ? 0.06f : 0.0f;
    for (uint32_t k = 0; k < box->nv; ++k) {
        box->pos[3 * k + 1] += rise;
    }
    return rise;
}

/* The two-layer cases (two 15 x 15 sheets of 0.4 m, the upper one 2 cm above, fallen onto a box
 * whose top is at 0.2 m): the lower sheet's centre height and the lowest height of the upper
 * sheet over the box's middle. */
static inline void test_two_layer_heights(const float *x, uint32_t lower_nv, uint32_t upper_nv, float *centre_lower,
                                          float *upper_min)
{
    *centre_lower = x[3 * (7 * 15 + 7) + 1];
    *upper_min = 1e9f;
    for (uint32_t i = 0; i < upper_nv; ++i) {
        const float *p = x + 3 * (lower_nv + i);
        if (p[0] > -0.05f && p[0] < 0.05f && p[2] > -0.05f && p[2] < 0.05f && p[1] < *upper_min) {
            *upper_min = p[1];
        }
    }
}

#endif
