/* A small scene shared by the collider-crop tests: an 8 x 8 cloth sheet (0.05 m spacing, 98
 * triangles) above a 20 x 20 floor grid (0.05 m spacing from -0.3 m, capped at 600 triangles).
 * How far apart they are decides how much of the floor a crop margin reaches. */
#ifndef WEFT_TESTS_SHEET_FLOOR_SCENE_H
#define WEFT_TESTS_SHEET_FLOOR_SCENE_H

#include <stdint.h>

typedef struct sheet_floor {
    float rest[3 * 64];
    uint32_t tris[3 * 98];
    float floor[3 * 400];
    uint32_t ftris[3 * 600];
    uint32_t nv, nt, nf, nft;
} sheet_floor;

/* Grid of nx x nz points (row-major, spacing h from (x0, y, z0)) and its two triangles per cell,
 * at most max_tris triangles. */
static inline void sheet_floor_grid(float *pos, uint32_t *tris, uint32_t nx, uint32_t nz, float x0, float y,
                                    float z0, float h, uint32_t max_tris, uint32_t *out_nv, uint32_t *out_nt)
{
    uint32_t nv = 0, nt = 0;
    for (uint32_t j = 0; j < nz; ++j) {
        for (uint32_t i = 0; i < nx; ++i) {
            float *p = pos + 3 * nv++;
            p[0] = x0 + h * (float)i, p[1] = y, p[2] = z0 + h * (float)j;
        }
    }
    for (uint32_t j = 0; j + 1 < nz && nt < max_tris; ++j) {
        for (uint32_t i = 0; i + 1 < nx && nt < max_tris; ++i) {
            const uint32_t a = j * nx + i;
            uint32_t *t = tris + 3 * nt;
            t[0] = a, t[1] = a + nx, t[2] = a + 1;
            t[3] = a + 1, t[4] = a + nx, t[5] = a + nx + 1;
            nt += 2;
        }
    }
    *out_nv = nv;
    *out_nt = nt;
}

static inline void sheet_floor_make(sheet_floor *s, float sheet_y, float floor_y)
{
    sheet_floor_grid(s->rest, s->tris, 8, 8, 0.0f, sheet_y, 0.0f, 0.05f, 98, &s->nv, &s->nt);
    sheet_floor_grid(s->floor, s->ftris, 20, 20, -0.3f, floor_y, -0.3f, 0.05f, 600, &s->nf, &s->nft);
}

#endif
