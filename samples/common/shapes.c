/* Procedural test geometry: a UV sphere and a cloth sheet draped over it. Positions are closed
 * form, so renders of them are reproducible anywhere without a simulator. */
#include "weft_scenes.h"
#include "core/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SHAPES_PI 3.14159265358979f

void weft_render_mesh_free(weft_render_mesh *m)
{
    if (!m) {
        return;
    }
    free(m->positions);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

static weft_result mesh_alloc(weft_render_mesh *m, uint32_t vertex_count, uint32_t triangle_count)
{
    memset(m, 0, sizeof *m);
    m->positions = malloc((size_t)vertex_count * 3 * sizeof(float));
    m->triangles = malloc((size_t)triangle_count * 3 * sizeof(uint32_t));
    if (!m->positions || !m->triangles) {
        weft_render_mesh_free(m);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "procedural mesh: out of memory");
    }
    m->vertex_count = vertex_count;
    m->triangle_count = triangle_count;
    return WEFT_OK;
}

weft_result weft_render_make_sphere(const float center[3], float radius, uint32_t rings, uint32_t segments,
                                    weft_render_mesh *out_mesh)
{
    if (!center || !out_mesh || !(radius > 0.0f) || !isfinite(radius) || rings < 2 || segments < 3 || rings > 1024 ||
        segments > 1024) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_make_sphere: need radius > 0, 2..1024 rings, 3..1024 segments");
    }
    /* poles are single vertices, so the mesh is closed with no degenerate triangles */
    uint32_t nv = 2 + (rings - 1) * segments;
    uint32_t nt = 2 * segments * (rings - 1);
    weft_render_mesh m;
    weft_result res = mesh_alloc(&m, nv, nt);
    if (res != WEFT_OK) {
        return res;
    }
    float *p = m.positions;
    p[0] = center[0];
    p[1] = center[1] + radius;
    p[2] = center[2];
    for (uint32_t r = 1; r < rings; ++r) {
        float theta = SHAPES_PI * (float)r / (float)rings;
        for (uint32_t s = 0; s < segments; ++s) {
            float phi = 2.0f * SHAPES_PI * (float)s / (float)segments;
            float *q = p + 3 * (1 + (size_t)(r - 1) * segments + s);
            q[0] = center[0] + radius * sinf(theta) * sinf(phi);
            q[1] = center[1] + radius * cosf(theta);
            q[2] = center[2] + radius * sinf(theta) * cosf(phi);
        }
    }
    float *bottom = p + 3 * (size_t)(nv - 1);
    bottom[0] = center[0];
    bottom[1] = center[1] - radius;
    bottom[2] = center[2];
    uint32_t *t = m.triangles;
    for (uint32_t s = 0; s < segments; ++s) {
        uint32_t s1 = (s + 1) % segments;
        *t++ = 0;
        *t++ = 1 + s;
        *t++ = 1 + s1;
    }
    for (uint32_t r = 1; r + 1 < rings; ++r) {
        uint32_t a0 = 1 + (r - 1) * segments, b0 = 1 + r * segments;
        for (uint32_t s = 0; s < segments; ++s) {
            uint32_t s1 = (s + 1) % segments;
            *t++ = a0 + s;
            *t++ = b0 + s;
            *t++ = b0 + s1;
            *t++ = a0 + s;
            *t++ = b0 + s1;
            *t++ = a0 + s1;
        }
    }
    uint32_t last = 1 + (rings - 2) * segments;
    for (uint32_t s = 0; s < segments; ++s) {
        uint32_t s1 = (s + 1) % segments;
        *t++ = last + s;
        *t++ = nv - 1;
        *t++ = last + s1;
    }
    *out_mesh = m;
    return WEFT_OK;
}

weft_result weft_render_make_draped_sheet(const float center[3], float radius, float size, uint32_t n,
                                          weft_render_mesh *out_mesh)
{
    if (!center || !out_mesh || !(radius > 0.0f) || !(size > 0.0f) || !isfinite(radius) || !isfinite(size) || n < 2 ||
        n > 1024) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_render_make_draped_sheet: need radius > 0, size > 0, n in 2..1024");
    }
    weft_render_mesh m;
    weft_result res = mesh_alloc(&m, n * n, 2 * (n - 1) * (n - 1));
    if (res != WEFT_OK) {
        return res;
    }
    /* The sheet keeps its radial arc length: it hugs the sphere (1 cm off the surface) down to
     * the equator, then hangs, flaring out slightly with a 20 cm decay length. Eight folds
     * absorb the circumference the flat sheet has in excess of the cylinder it hangs on; they
     * only bulge outwards (never into the sphere) and grow with the free length. */
    const float lift = radius + 0.01f;
    const float s_c = lift * 0.5f * SHAPES_PI;
    const float flare = 0.22f, flare_len = 0.2f;
    const int folds = 8;
    for (uint32_t j = 0; j < n; ++j) {
        for (uint32_t i = 0; i < n; ++i) {
            float u = size * ((float)i / (float)(n - 1) - 0.5f);
            float v = size * ((float)j / (float)(n - 1) - 0.5f);
            float s = sqrtf(u * u + v * v);
            float phi = atan2f(v, u);
            float radial, y;
            if (s <= s_c) {
                float theta = s / lift;
                radial = lift * sinf(theta);
                y = lift * cosf(theta);
            } else {
                /* direction angle below horizontal: 90 degrees at the equator, easing outwards;
                 * closed-form integral of (sin(flare*(1-e^(-t/L))), -cos(...)) by midpoints */
                radial = lift;
                y = 0.0f;
                float t = s - s_c;
                const int steps = 48;
                float h = t / (float)steps;
                for (int k = 0; k < steps; ++k) {
                    float tm = ((float)k + 0.5f) * h;
                    float out = flare * (1.0f - expf(-tm / flare_len));
                    radial += h * sinf(out);
                    y -= h * cosf(out);
                }
                float amp = 0.16f * t;
                radial += amp * (0.5f + 0.5f * sinf((float)folds * phi));
            }
            float *p = m.positions + 3 * ((size_t)j * n + i);
            p[0] = center[0] + radial * cosf(phi);
            p[1] = center[1] + y;
            p[2] = center[2] + radial * sinf(phi);
        }
    }
    /* counter-clockwise seen from +Y (the sheet's front is its outer, upper side) */
    uint32_t *t = m.triangles;
    for (uint32_t j = 0; j + 1 < n; ++j) {
        for (uint32_t i = 0; i + 1 < n; ++i) {
            uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
            *t++ = a;
            *t++ = c;
            *t++ = b;
            *t++ = b;
            *t++ = c;
            *t++ = d;
        }
    }
    *out_mesh = m;
    return WEFT_OK;
}
