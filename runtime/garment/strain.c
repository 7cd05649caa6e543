/* Strain limiting of a step's output (every method): edges longer than (1 + limit) x rest are
 * shortened by Gauss-Seidel sweeps, each endpoint moving by its share (pinned vertices and those
 * glued by radius-0 tethers do not move). Learned steps and tether clamps move vertices one by one,
 * so neighbours can end a step far apart; this restores the cloth's near-inextensibility cheaply
 * (a few sweeps over the edges, no allocation) before CCD, which then works on a sane mesh. */
#include "garment/garment.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y ? 1 : 0);
}

weft_result weft__strain_create(weft_garment *g)
{
    size_t n = (size_t)g->triangle_count * 3;
    uint64_t *keys = weft__alloc(g->ctx, n * sizeof *keys);
    if (!keys) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t i = 0; i < n; ++i) {
        uint32_t a = g->triangles[i], b = g->triangles[i - i % 3 + (i % 3 + 1) % 3];
        keys[i] = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
    }
    qsort(keys, n, sizeof *keys, cmp_u64);
    uint32_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        m += i == 0 || keys[i] != keys[i - 1];
    }
    g->strain_edges = weft__alloc(g->ctx, (size_t)m * 2 * sizeof(uint32_t));
    g->strain_rest = weft__alloc(g->ctx, (size_t)m * sizeof(float));
    g->strain_fixed = weft__alloc(g->ctx, g->vertex_count);
    if (!g->strain_edges || !g->strain_rest || !g->strain_fixed) {
        weft__free(g->ctx, keys, n * sizeof *keys);
        weft__strain_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    g->strain_edge_count = m;
    for (uint32_t i = 0; i < g->vertex_count; ++i) {
        g->strain_fixed[i] = g->tether_radius && g->tether_radius[i] == 0.0f; /* glued for good */
    }
    uint32_t e = 0;
    for (size_t i = 0; i < n; ++i) {
        if (i > 0 && keys[i] == keys[i - 1]) {
            continue;
        }
        uint32_t a = (uint32_t)(keys[i] >> 32), b = (uint32_t)keys[i];
        const float *p = g->rest + 3 * (size_t)a, *q = g->rest + 3 * (size_t)b;
        float d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        g->strain_edges[2 * e] = a;
        g->strain_edges[2 * e + 1] = b;
        g->strain_rest[e] = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        e++;
    }
    weft__free(g->ctx, keys, n * sizeof *keys);
    return WEFT_OK;
}

void weft__strain_destroy(weft_garment *g)
{
    weft__free(g->ctx, g->strain_edges, (size_t)g->strain_edge_count * 2 * sizeof(uint32_t));
    weft__free(g->ctx, g->strain_rest, (size_t)g->strain_edge_count * sizeof(float));
    weft__free(g->ctx, g->strain_fixed, g->vertex_count);
    g->strain_edges = NULL;
    g->strain_rest = NULL;
    g->strain_fixed = NULL;
    g->strain_edge_count = 0;
}

void weft__strain_limit(weft_garment *g)
{
    /* Bit 0: glued by a radius-0 tether (set at creation); bit 1: pinned this step. */
    uint8_t *fixed = g->strain_fixed;
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        fixed[g->pin_indices[k]] |= 2;
    }
    const float grow = 1.0f + g->strain_limit;
    float *x = g->x_next;
    uint32_t over = 0;
    for (uint32_t sweep = 0; sweep < g->strain_iterations; ++sweep) {
        uint32_t n = 0;
        for (uint32_t e = 0; e < g->strain_edge_count; ++e) {
            uint32_t a = g->strain_edges[2 * e], b = g->strain_edges[2 * e + 1];
            float *p = x + 3 * (size_t)a, *q = x + 3 * (size_t)b;
            float d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
            float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            float cap = grow * g->strain_rest[e];
            if (!(len > cap)) {
                continue;
            }
            n++;
            float wa = fixed[a] ? 0.0f : 1.0f, wb = fixed[b] ? 0.0f : 1.0f;
            if (wa + wb == 0.0f) {
                continue;
            }
            float s = (len - cap) / (len * (wa + wb)); /* len > cap >= 0 */
            for (int k = 0; k < 3; ++k) {
                p[k] += wa * s * d[k];
                q[k] -= wb * s * d[k];
            }
        }
        if (sweep == 0) {
            over = n;
        }
        if (n == 0) {
            break;
        }
    }
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        fixed[g->pin_indices[k]] &= 1;
    }
    g->stats.strain_limited_edges = over;
}
