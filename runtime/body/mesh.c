/* Mesh helpers used to build the avatar and garments. Creation-time only: they allocate. */
#include "body/mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void weft__mesh_init(weft__mesh *m, const weft_context *ctx)
{
    memset(m, 0, sizeof *m);
    m->ctx = ctx;
}

void weft__mesh_free(weft__mesh *m)
{
    weft__free(m->ctx, m->v, (size_t)m->cap_v * 3 * sizeof(float));
    weft__free(m->ctx, m->t, (size_t)m->cap_t * 3 * sizeof(uint32_t));
    m->v = NULL;
    m->t = NULL;
    m->nv = m->nt = m->cap_v = m->cap_t = 0;
}

static bool grow(const weft_context *ctx, void **p, uint32_t *cap, uint32_t need, size_t item)
{
    if (need <= *cap) {
        return true;
    }
    uint64_t n = *cap ? *cap : 1024;
    while (n < need) {
        n *= 2;
    }
    if (n > 0x7fffffffu) {
        return false;
    }
    void *q = weft__alloc(ctx, (size_t)n * item);
    if (!q) {
        return false;
    }
    if (*p) {
        memcpy(q, *p, (size_t)*cap * item);
        weft__free(ctx, *p, (size_t)*cap * item);
    }
    *p = q;
    *cap = (uint32_t)n;
    return true;
}

bool weft__mesh_reserve(weft__mesh *m, uint32_t vertices, uint32_t triangles)
{
    return grow(m->ctx, (void **)&m->v, &m->cap_v, vertices, 3 * sizeof(float)) &&
           grow(m->ctx, (void **)&m->t, &m->cap_t, triangles, 3 * sizeof(uint32_t));
}

uint32_t weft__mesh_add_vertex(weft__mesh *m, float x, float y, float z)
{
    if (!grow(m->ctx, (void **)&m->v, &m->cap_v, m->nv + 1, 3 * sizeof(float))) {
        return UINT32_MAX;
    }
    m->v[3 * m->nv + 0] = x;
    m->v[3 * m->nv + 1] = y;
    m->v[3 * m->nv + 2] = z;
    return m->nv++;
}

bool weft__mesh_add_triangle(weft__mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (!grow(m->ctx, (void **)&m->t, &m->cap_t, m->nt + 1, 3 * sizeof(uint32_t))) {
        return false;
    }
    m->t[3 * m->nt + 0] = a;
    m->t[3 * m->nt + 1] = b;
    m->t[3 * m->nt + 2] = c;
    m->nt++;
    return true;
}

static float dist2(const float *a, const float *b)
{
    float dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

static bool add_quad(weft__mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t d, bool flip)
{
    if (flip) {
        uint32_t tmp = b;
        b = d;
        d = tmp;
    }
    if (dist2(m->v + 3 * a, m->v + 3 * c) <= dist2(m->v + 3 * b, m->v + 3 * d)) {
        return weft__mesh_add_triangle(m, a, b, c) && weft__mesh_add_triangle(m, a, c, d);
    }
    return weft__mesh_add_triangle(m, a, b, d) && weft__mesh_add_triangle(m, b, c, d);
}

/* Cube corners c = x + 2y + 4z; corners joined by a cube edge differ in one bit. A cell
 * gives a manifold surface-nets vertex when its inside corners and its outside corners are
 * each edge-connected (this also rules out ambiguous faces). */
static bool cell_is_simple(unsigned mask)
{
    for (int side = 0; side < 2; ++side) {
        unsigned set = side ? (~mask & 0xffu) : mask;
        if (!set) {
            continue;
        }
        unsigned seen = set & (~set + 1u); /* lowest corner of the set */
        for (int grow_step = 0; grow_step < 8; ++grow_step) {
            unsigned next = seen;
            for (int c = 0; c < 8; ++c) {
                if (seen & (1u << c)) {
                    next |= ((1u << (c ^ 1)) | (1u << (c ^ 2)) | (1u << (c ^ 4))) & set;
                }
            }
            if (next == seen) {
                break;
            }
            seen = next;
        }
        if (seen != set) {
            return false;
        }
    }
    return true;
}

weft_result weft__surface_nets(weft__mesh *out, weft__field_fn *field, const void *user, const float lo[3],
                               const float hi[3], float h)
{
    uint32_t n[3];
    for (int a = 0; a < 3; ++a) {
        float cells = ceilf((hi[a] - lo[a]) / h);
        if (!(cells >= 2.0f) || cells > 2000.0f) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "surface nets: %g cells along axis %d", (double)cells, a);
        }
        n[a] = (uint32_t)cells + 1;
    }
    const size_t points = (size_t)n[0] * n[1] * n[2];
    if (points > 64u * 1024u * 1024u) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "surface nets: grid of %zu points is too large", points);
    }
    const weft_context *ctx = out->ctx;
    float *f = weft__alloc(ctx, points * sizeof(float));
    uint32_t *cell_vertex = weft__alloc(ctx, points * sizeof(uint32_t));
    if (!f || !cell_vertex) {
        weft__free(ctx, f, points * sizeof(float));
        weft__free(ctx, cell_vertex, points * sizeof(uint32_t));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
#define IDX(i, j, k) ((size_t)(i) + (size_t)n[0] * ((size_t)(j) + (size_t)n[1] * (size_t)(k)))
    for (uint32_t k = 0; k < n[2]; ++k) {
        for (uint32_t j = 0; j < n[1]; ++j) {
            for (uint32_t i = 0; i < n[0]; ++i) {
                float p[3] = {lo[0] + h * (float)i, lo[1] + h * (float)j, lo[2] + h * (float)k};
                float v = field(user, p);
                /* Exact zeros would make a vertex both inside and outside; push them out. */
                f[IDX(i, j, k)] = v == 0.0f ? 1e-7f : v;
            }
        }
    }
    /* Cells whose corner signs would give a non-manifold vertex (thin parts, creases finer
     * than the grid): move the outside corner nearest the surface just inside, until
     * every cell is simple. The surface moves by less than a cell there. */
    bool simple[256];
    for (unsigned m = 0; m < 256; ++m) {
        simple[m] = cell_is_simple(m);
    }
    for (int pass = 0; pass < 64; ++pass) {
        uint32_t flips = 0;
        for (uint32_t k = 0; k + 1 < n[2]; ++k) {
            for (uint32_t j = 0; j + 1 < n[1]; ++j) {
                for (uint32_t i = 0; i + 1 < n[0]; ++i) {
                    unsigned mask = 0;
                    size_t best = 0;
                    float best_abs = 1e30f;
                    for (unsigned c = 0; c < 8; ++c) {
                        size_t id = IDX(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                        mask |= (unsigned)(f[id] < 0.0f) << c;
                        if (f[id] >= 0.0f && f[id] < best_abs) {
                            best_abs = f[id];
                            best = id;
                        }
                    }
                    /* Only outside -> inside: monotone, so the passes terminate. */
                    if (!simple[mask]) {
                        f[best] = -1e-6f * h;
                        flips++;
                    }
                }
            }
        }
        if (flips == 0) {
            break;
        }
    }
    weft_result result = WEFT_OK;
    static const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
    static const int edge[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    for (uint32_t k = 0; k + 1 < n[2] && result == WEFT_OK; ++k) {
        for (uint32_t j = 0; j + 1 < n[1] && result == WEFT_OK; ++j) {
            for (uint32_t i = 0; i + 1 < n[0]; ++i) {
                float cv[8];
                int inside = 0;
                for (int c = 0; c < 8; ++c) {
                    cv[c] = f[IDX(i + corner[c][0], j + corner[c][1], k + corner[c][2])];
                    inside += cv[c] < 0.0f;
                }
                cell_vertex[IDX(i, j, k)] = UINT32_MAX;
                if (inside == 0 || inside == 8) {
                    continue;
                }
                float acc[3] = {0, 0, 0};
                int crossings = 0;
                for (int e = 0; e < 12; ++e) {
                    float a = cv[edge[e][0]], b = cv[edge[e][1]];
                    if ((a < 0.0f) == (b < 0.0f)) {
                        continue;
                    }
                    float t = a / (a - b);
                    for (int d = 0; d < 3; ++d) {
                        acc[d] += (float)corner[edge[e][0]][d] + t * (float)(corner[edge[e][1]][d] - corner[edge[e][0]][d]);
                    }
                    crossings++;
                }
                uint32_t id = weft__mesh_add_vertex(out, lo[0] + h * ((float)i + acc[0] / (float)crossings),
                                                    lo[1] + h * ((float)j + acc[1] / (float)crossings),
                                                    lo[2] + h * ((float)k + acc[2] / (float)crossings));
                if (id == UINT32_MAX) {
                    result = WEFT_ERROR_OUT_OF_MEMORY;
                    break;
                }
                cell_vertex[IDX(i, j, k)] = id;
            }
        }
    }
    /* One quad per sign-changing grid edge, joining the four cells around it. */
    for (uint32_t k = 1; k + 1 < n[2] && result == WEFT_OK; ++k) {
        for (uint32_t j = 1; j + 1 < n[1] && result == WEFT_OK; ++j) {
            for (uint32_t i = 1; i + 1 < n[0]; ++i) {
                bool in0 = f[IDX(i, j, k)] < 0.0f;
                bool ok = true;
                if (in0 != (f[IDX(i + 1, j, k)] < 0.0f)) {
                    ok = add_quad(out, cell_vertex[IDX(i, j - 1, k - 1)], cell_vertex[IDX(i, j, k - 1)],
                                  cell_vertex[IDX(i, j, k)], cell_vertex[IDX(i, j - 1, k)], !in0);
                }
                if (ok && in0 != (f[IDX(i, j + 1, k)] < 0.0f)) {
                    ok = add_quad(out, cell_vertex[IDX(i - 1, j, k - 1)], cell_vertex[IDX(i - 1, j, k)],
                                  cell_vertex[IDX(i, j, k)], cell_vertex[IDX(i, j, k - 1)], !in0);
                }
                if (ok && in0 != (f[IDX(i, j, k + 1)] < 0.0f)) {
                    ok = add_quad(out, cell_vertex[IDX(i - 1, j - 1, k)], cell_vertex[IDX(i, j - 1, k)],
                                  cell_vertex[IDX(i, j, k)], cell_vertex[IDX(i - 1, j, k)], !in0);
                }
                if (!ok) {
                    result = WEFT_ERROR_OUT_OF_MEMORY;
                    break;
                }
            }
        }
    }
#undef IDX
    weft__free(ctx, f, points * sizeof(float));
    weft__free(ctx, cell_vertex, points * sizeof(uint32_t));
    return result;
}

static void gradient(weft__field_fn *field, const void *user, const float *p, float e, float *g)
{
    for (int a = 0; a < 3; ++a) {
        float q[3] = {p[0], p[1], p[2]};
        q[a] = p[a] + e;
        float fp = field(user, q);
        q[a] = p[a] - e;
        float fm = field(user, q);
        g[a] = (fp - fm) / (2.0f * e);
    }
}

static void project_point(float *p, weft__field_fn *field, const void *user, float h, int iterations)
{
    for (int it = 0; it < iterations; ++it) {
        float v = field(user, p);
        float g[3];
        gradient(field, user, p, 0.05f * h, g);
        float g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if (g2 < 1e-12f) {
            return;
        }
        float step = v / g2;
        /* Never move more than half a cell: far jumps across thin parts would fold the mesh. */
        float len = fabsf(step) * sqrtf(g2);
        if (len > 0.5f * h) {
            step *= 0.5f * h / len;
        }
        for (int a = 0; a < 3; ++a) {
            p[a] -= step * g[a];
        }
        if (fabsf(v) < 1e-6f) {
            return;
        }
    }
}

void weft__project_to_field(weft__mesh *m, weft__field_fn *field, const void *user, float h, int iterations)
{
    for (uint32_t i = 0; i < m->nv; ++i) {
        project_point(m->v + 3 * i, field, user, h, iterations);
    }
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

weft_result weft__adjacency_build(const weft_context *ctx, const weft__mesh *m, weft__adjacency *out)
{
    memset(out, 0, sizeof *out);
    size_t ne = (size_t)m->nt * 6;
    uint64_t *pairs = weft__alloc(ctx, ne * sizeof(uint64_t));
    if (!pairs) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (uint32_t t = 0; t < m->nt; ++t) {
        for (int e = 0; e < 3; ++e) {
            uint64_t a = m->t[3 * t + e], b = m->t[3 * t + (e + 1) % 3];
            pairs[6 * (size_t)t + 2 * (size_t)e + 0] = (a << 32) | b;
            pairs[6 * (size_t)t + 2 * (size_t)e + 1] = (b << 32) | a;
        }
    }
    qsort(pairs, ne, sizeof(uint64_t), cmp_u64);
    size_t unique = 0;
    for (size_t i = 0; i < ne; ++i) {
        if (i == 0 || pairs[i] != pairs[i - 1]) {
            pairs[unique++] = pairs[i];
        }
    }
    out->nv = m->nv;
    out->count = (uint32_t)unique;
    out->offsets = weft__alloc(ctx, ((size_t)m->nv + 1) * sizeof(uint32_t));
    out->neighbours = weft__alloc(ctx, (unique ? unique : 1) * sizeof(uint32_t));
    if (!out->offsets || !out->neighbours) {
        weft__free(ctx, pairs, ne * sizeof(uint64_t));
        weft__adjacency_free(ctx, out);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    for (size_t i = 0; i < unique; ++i) {
        out->offsets[(pairs[i] >> 32) + 1]++;
        out->neighbours[i] = (uint32_t)(pairs[i] & 0xffffffffu);
    }
    for (uint32_t v = 0; v < m->nv; ++v) {
        out->offsets[v + 1] += out->offsets[v];
    }
    weft__free(ctx, pairs, ne * sizeof(uint64_t));
    return WEFT_OK;
}

void weft__adjacency_free(const weft_context *ctx, weft__adjacency *adj)
{
    weft__free(ctx, adj->offsets, ((size_t)adj->nv + 1) * sizeof(uint32_t));
    weft__free(ctx, adj->neighbours, (adj->count ? adj->count : 1) * sizeof(uint32_t));
    memset(adj, 0, sizeof *adj);
}

void weft__relax(weft__mesh *m, const weft__adjacency *adj, weft__field_fn *field, const void *user, float h,
                 int iterations)
{
    weft__relax_free_vertices(m, adj, field, user, h, iterations, NULL);
}

void weft__relax_free_vertices(weft__mesh *m, const weft__adjacency *adj, weft__field_fn *field, const void *user,
                               float h, int iterations, const uint8_t *fixed)
{
    for (int it = 0; it < iterations; ++it) {
        /* In place (Gauss-Seidel order): deterministic and needs no scratch buffer. */
        for (uint32_t i = 0; i < m->nv; ++i) {
            uint32_t b = adj->offsets[i], e = adj->offsets[i + 1];
            if (e == b || (fixed && fixed[i])) {
                continue;
            }
            float c[3] = {0, 0, 0};
            for (uint32_t k = b; k < e; ++k) {
                const float *q = m->v + 3 * adj->neighbours[k];
                c[0] += q[0], c[1] += q[1], c[2] += q[2];
            }
            float *p = m->v + 3 * i;
            float g[3];
            gradient(field, user, p, 0.05f * h, g);
            float gl = sqrtf(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
            float d[3] = {c[0] / (float)(e - b) - p[0], c[1] / (float)(e - b) - p[1], c[2] / (float)(e - b) - p[2]};
            if (gl > 1e-9f) {
                float dn = (d[0] * g[0] + d[1] * g[1] + d[2] * g[2]) / (gl * gl);
                d[0] -= dn * g[0], d[1] -= dn * g[1], d[2] -= dn * g[2];
            }
            p[0] += 0.5f * d[0], p[1] += 0.5f * d[1], p[2] += 0.5f * d[2];
            project_point(p, field, user, h, 2);
        }
    }
}

static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

typedef struct half_edge {
    uint64_t key; /* min << 32 | max */
    uint32_t tri;
    uint8_t forward; /* traversed min -> max */
} half_edge;

static int cmp_half_edge(const void *a, const void *b)
{
    const half_edge *x = a, *y = b;
    if (x->key != y->key) {
        return x->key < y->key ? -1 : 1;
    }
    return x->tri < y->tri ? -1 : x->tri > y->tri;
}

weft_result weft__mesh_topology_of(const weft_context *ctx, const float *v, uint32_t nv, const uint32_t *t,
                                   uint32_t nt, weft__mesh_topology *out)
{
    memset(out, 0, sizeof *out);
    size_t nh = (size_t)nt * 3;
    half_edge *he = weft__alloc(ctx, (nh ? nh : 1) * sizeof(half_edge));
    uint32_t *parent = weft__alloc(ctx, ((size_t)nv + 1) * sizeof(uint32_t));
    /* Per-vertex fan check: incident (triangle-local) neighbour pairs. */
    uint32_t *vt_off = weft__alloc(ctx, ((size_t)nv + 1) * sizeof(uint32_t));
    uint32_t *vt = weft__alloc(ctx, (nh ? nh : 1) * sizeof(uint32_t));
    if (!he || !parent || !vt_off || !vt) {
        weft__free(ctx, he, (nh ? nh : 1) * sizeof(half_edge));
        weft__free(ctx, parent, ((size_t)nv + 1) * sizeof(uint32_t));
        weft__free(ctx, vt_off, ((size_t)nv + 1) * sizeof(uint32_t));
        weft__free(ctx, vt, (nh ? nh : 1) * sizeof(uint32_t));
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    float min_angle = 180.0f;
    for (uint32_t i = 0; i < nv; ++i) {
        parent[i] = i;
    }
    for (uint32_t f = 0; f < nt; ++f) {
        for (int e = 0; e < 3; ++e) {
            uint32_t a = t[3 * f + e], b = t[3 * f + (e + 1) % 3];
            half_edge *h = &he[3 * (size_t)f + (size_t)e];
            h->key = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
            h->tri = f;
            h->forward = a < b;
            uint32_t ra = uf_find(parent, a), rb = uf_find(parent, b);
            if (ra != rb) {
                parent[ra] = rb;
            }
            vt_off[a + 1]++;
        }
        for (int c = 0; c < 3; ++c) {
            const float *p0 = v + 3 * t[3 * f + c], *p1 = v + 3 * t[3 * f + (c + 1) % 3], *p2 = v + 3 * t[3 * f + (c + 2) % 3];
            double u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
            double w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            double nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
            double cosv = nu > 0 && nw > 0 ? (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) / (nu * nw) : 1.0;
            cosv = cosv > 1 ? 1 : cosv < -1 ? -1 : cosv;
            float ang = (float)(acos(cosv) * 180.0 / 3.14159265358979);
            min_angle = ang < min_angle ? ang : min_angle;
        }
    }
    qsort(he, nh, sizeof(half_edge), cmp_half_edge);
    int64_t edges = 0;
    for (size_t i = 0; i < nh;) {
        size_t j = i;
        while (j < nh && he[j].key == he[i].key) {
            j++;
        }
        size_t n = j - i;
        edges++;
        if (n == 1) {
            out->boundary_edges++;
        } else if (n == 2) {
            if (he[i].forward == he[i + 1].forward) {
                out->misoriented_edges++;
            }
        } else {
            out->nonmanifold_edges++;
        }
        i = j;
    }
    uint32_t used = 0;
    for (uint32_t i = 0; i < nv; ++i) {
        if (vt_off[i + 1] > 0) {
            used++;
            if (uf_find(parent, i) == i) {
                out->components++;
            }
        }
        vt_off[i + 1] += vt_off[i];
    }
    /* vt lists, for each vertex, its incident triangles; a fan is manifold when the triangles
     * chained through shared edges form one cycle (interior) or one path (boundary). */
    uint32_t *fill = parent; /* reuse: component info no longer needed */
    for (uint32_t i = 0; i < nv; ++i) {
        fill[i] = vt_off[i];
    }
    for (uint32_t f = 0; f < nt; ++f) {
        for (int e = 0; e < 3; ++e) {
            uint32_t a = t[3 * f + e];
            vt[fill[a]++] = f;
        }
    }
    for (uint32_t i = 0; i < nv; ++i) {
        uint32_t b = vt_off[i], e = vt_off[i + 1], n = e - b;
        if (n == 0) {
            continue;
        }
        /* Count, over the fan, the triangle pairs sharing an edge at i: a single cycle of n
         * triangles has n links, a single path n-1. Fewer means several fans. */
        if (n > 64) {
            out->nonmanifold_vertices++;
            continue;
        }
        uint32_t local[64];
        for (uint32_t x = 0; x < n; ++x) {
            local[x] = x;
        }
        uint32_t links = 0, fans = n;
        for (uint32_t x = b; x < e; ++x) {
            const uint32_t *tx = t + 3 * vt[x];
            for (uint32_t y = x + 1; y < e; ++y) {
                const uint32_t *ty = t + 3 * vt[y];
                int shared = 0;
                for (int p = 0; p < 3; ++p) {
                    for (int q = 0; q < 3; ++q) {
                        shared += tx[p] == ty[q];
                    }
                }
                if (shared >= 2) {
                    links++;
                    uint32_t rx = uf_find(local, x - b), ry = uf_find(local, y - b);
                    if (rx != ry) {
                        local[rx] = ry;
                        fans--;
                    }
                }
            }
        }
        if (fans != 1 || links < n - 1 || links > n) {
            out->nonmanifold_vertices++;
        }
    }
    out->euler = (int64_t)used - edges + (int64_t)nt;
    out->min_angle_deg = nt ? min_angle : 0.0f;
    weft__free(ctx, he, (nh ? nh : 1) * sizeof(half_edge));
    weft__free(ctx, parent, ((size_t)nv + 1) * sizeof(uint32_t));
    weft__free(ctx, vt_off, ((size_t)nv + 1) * sizeof(uint32_t));
    weft__free(ctx, vt, (nh ? nh : 1) * sizeof(uint32_t));
    return WEFT_OK;
}
