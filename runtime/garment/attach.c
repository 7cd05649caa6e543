/* Long-range attachments: every vertex within (1 + slack) x its rest path length from the
 * pinned vertex nearest to it along the rest shape's edges. The anchors are a multi-source
 * shortest-path search (Dijkstra, an indexed binary heap in scratch made at creation) from the
 * pinned vertices, run when the pinned vertex list changes; the clamp is one pass over the
 * vertices. The edge path is never shorter than the straight rest distance, so a cloth at rest
 * is never moved. */
#include "garment/garment.h"
#include "geometry/geometry.h"

#include <math.h>

#define ATTACH_NONE UINT32_MAX

weft_result weft__attach_create(weft_garment *g)
{
    /* the rest mesh's edges (geometry's topology, validated at creation), as a CSR graph */
    geo_topo topo;
    weft_result r = geo_topo_create(g->ctx, &topo, g->triangles, g->triangle_count, g->vertex_count, NULL);
    if (r != WEFT_OK) {
        return r;
    }
    const size_t m = (size_t)topo.edge_count * 2; /* each edge from both ends */
    g->attach_start = weft__alloc(g->ctx, ((size_t)g->vertex_count + 1) * sizeof(uint32_t));
    g->attach_next = weft__alloc(g->ctx, m * sizeof(uint32_t));
    g->attach_length = weft__alloc(g->ctx, m * sizeof(float));
    if (!g->attach_start || !g->attach_next || !g->attach_length) {
        geo_topo_destroy(g->ctx, &topo);
        weft__attach_destroy(g);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t e = 0; e < topo.edge_count; ++e) { /* degrees, then starts */
        g->attach_start[topo.edges[2 * (size_t)e] + 1]++;
        g->attach_start[topo.edges[2 * (size_t)e + 1] + 1]++;
    }
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        g->attach_start[v + 1] += g->attach_start[v];
    }
    for (uint32_t e = 0; e < topo.edge_count; ++e) { /* fill, each start advancing to the next */
        const uint32_t a = topo.edges[2 * (size_t)e], b = topo.edges[2 * (size_t)e + 1];
        const float *p = g->rest + 3 * (size_t)a, *q = g->rest + 3 * (size_t)b;
        const float d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
        const float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        const uint32_t sa = g->attach_start[a]++, sb = g->attach_start[b]++;
        g->attach_next[sa] = b, g->attach_length[sa] = len;
        g->attach_next[sb] = a, g->attach_length[sb] = len;
    }
    for (uint32_t v = g->vertex_count; v > 0; --v) { /* shift the advanced starts back */
        g->attach_start[v] = g->attach_start[v - 1];
    }
    g->attach_start[0] = 0;
    geo_topo_destroy(g->ctx, &topo);
    return WEFT_OK;
}

void weft__attach_destroy(weft_garment *g)
{
    if (g->attach_start) {
        const size_t m = g->attach_start[g->vertex_count];
        weft__free(g->ctx, g->attach_next, m * sizeof(uint32_t));
        weft__free(g->ctx, g->attach_length, m * sizeof(float));
    }
    weft__free(g->ctx, g->attach_start, ((size_t)g->vertex_count + 1) * sizeof(uint32_t));
    g->attach_start = NULL;
    g->attach_next = NULL;
    g->attach_length = NULL;
}

bool weft__attach_alloc_state(weft_garment *g)
{
    g->attach_pin = g->attach_heap = g->attach_where = NULL;
    g->attach_limit = NULL;
    if (!g->attach_start) {
        return true;
    }
    const size_t n = g->vertex_count;
    g->attach_pin = weft__alloc(g->ctx, n * sizeof(uint32_t));
    g->attach_limit = weft__alloc(g->ctx, n * sizeof(float));
    g->attach_heap = weft__alloc(g->ctx, n * sizeof(uint32_t));
    g->attach_where = weft__alloc(g->ctx, n * sizeof(uint32_t));
    if (!g->attach_pin || !g->attach_limit || !g->attach_heap || !g->attach_where) {
        return false;
    }
    for (size_t v = 0; v < n; ++v) {
        g->attach_pin[v] = ATTACH_NONE; /* nothing pinned yet */
    }
    return true;
}

void weft__attach_free_state(weft_garment *g)
{
    const size_t n = g->vertex_count;
    weft__free(g->ctx, g->attach_pin, n * sizeof(uint32_t));
    weft__free(g->ctx, g->attach_limit, n * sizeof(float));
    weft__free(g->ctx, g->attach_heap, n * sizeof(uint32_t));
    weft__free(g->ctx, g->attach_where, n * sizeof(uint32_t));
    g->attach_pin = g->attach_heap = g->attach_where = NULL;
    g->attach_limit = NULL;
}

/* The indexed min-heap on attach_limit (the tentative path lengths). */
static void heap_swap(weft_garment *g, uint32_t i, uint32_t j)
{
    uint32_t *h = g->attach_heap;
    const uint32_t a = h[i], b = h[j];
    h[i] = b, h[j] = a;
    g->attach_where[b] = i;
    g->attach_where[a] = j;
}

static void heap_up(weft_garment *g, uint32_t i)
{
    const float *key = g->attach_limit;
    while (i > 0) {
        const uint32_t parent = (i - 1) / 2;
        if (!(key[g->attach_heap[i]] < key[g->attach_heap[parent]])) {
            break;
        }
        heap_swap(g, i, parent);
        i = parent;
    }
}

static void heap_down(weft_garment *g, uint32_t i, uint32_t size)
{
    const float *key = g->attach_limit;
    for (;;) {
        const uint32_t l = 2 * i + 1, r = l + 1;
        uint32_t least = i;
        if (l < size && key[g->attach_heap[l]] < key[g->attach_heap[least]]) {
            least = l;
        }
        if (r < size && key[g->attach_heap[r]] < key[g->attach_heap[least]]) {
            least = r;
        }
        if (least == i) {
            return;
        }
        heap_swap(g, i, least);
        i = least;
    }
}

void weft__attach_anchor(weft_garment *g)
{
    if (!g->attach_pin) {
        return;
    }
    const uint32_t n = g->vertex_count;
    float *dist = g->attach_limit;
    for (uint32_t v = 0; v < n; ++v) {
        dist[v] = INFINITY;
        g->attach_pin[v] = ATTACH_NONE;
        g->attach_where[v] = ATTACH_NONE;
    }
    uint32_t size = 0;
    for (uint32_t k = 0; k < g->pin_count; ++k) {
        const uint32_t v = g->pin_indices[k];
        g->attach_pin[v] = k; /* a vertex pinned twice takes its last target, as the pins do */
        if (g->attach_where[v] == ATTACH_NONE) {
            dist[v] = 0.0f;
            g->attach_heap[size] = v;
            g->attach_where[v] = size++; /* all keys 0: already a heap */
        }
    }
    while (size > 0) {
        const uint32_t u = g->attach_heap[0];
        heap_swap(g, 0, --size);
        heap_down(g, 0, size);
        for (uint32_t e = g->attach_start[u]; e < g->attach_start[u + 1]; ++e) {
            const uint32_t w = g->attach_next[e];
            const float d = dist[u] + g->attach_length[e];
            if (d < dist[w]) {
                const bool queued = dist[w] != INFINITY; /* settled vertices never improve */
                dist[w] = d;
                g->attach_pin[w] = g->attach_pin[u];
                if (!queued) {
                    g->attach_heap[size] = w;
                    g->attach_where[w] = size++;
                }
                heap_up(g, g->attach_where[w]);
            }
        }
    }
    const float scale = 1.0f + g->attach_slack;
    for (uint32_t v = 0; v < n; ++v) {
        dist[v] *= scale; /* unreached vertices stay at infinity, never clamped */
    }
}

uint32_t weft__attach_clamp(weft_garment *g)
{
    if (!g->attach_pin || g->pin_count == 0) {
        return 0;
    }
    uint32_t clamped = 0;
    for (uint32_t i = 0; i < g->vertex_count; ++i) {
        const uint32_t k = g->attach_pin[i];
        if (k == ATTACH_NONE) {
            continue;
        }
        clamped += weft__clamp_to_sphere(g->x_next + 3 * (size_t)i, g->pin_targets + 3 * (size_t)k,
                                         g->attach_limit[i]);
    }
    return clamped;
}
