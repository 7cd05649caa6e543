/* Internal mesh helpers for procedural bodies and garments: growable triangle meshes,
 * surface nets over an implicit function, vertex adjacency, smoothing and checks. */
#ifndef WEFT_BODY_MESH_H
#define WEFT_BODY_MESH_H

#include "core/core.h"

typedef struct weft__mesh {
    const weft_context *ctx;
    float *v;          /* 3 per vertex */
    uint32_t nv, cap_v;
    uint32_t *t;       /* 3 per triangle */
    uint32_t nt, cap_t;
} weft__mesh;

/* Implicit function: negative inside. */
typedef float weft__field_fn(const void *user, const float *p);

void weft__mesh_init(weft__mesh *m, const weft_context *ctx);
void weft__mesh_free(weft__mesh *m);
bool weft__mesh_reserve(weft__mesh *m, uint32_t vertices, uint32_t triangles);
uint32_t weft__mesh_add_vertex(weft__mesh *m, float x, float y, float z); /* UINT32_MAX on OOM */
bool weft__mesh_add_triangle(weft__mesh *m, uint32_t a, uint32_t b, uint32_t c);

/* Surface nets of {field = 0} on a grid of spacing h over [lo, hi] (which must enclose the
 * surface). Quads are split along their shorter diagonal; triangles face outward (towards
 * positive field). */
weft_result weft__surface_nets(weft__mesh *out, weft__field_fn *field, const void *user, const float lo[3],
                               const float hi[3], float h);

/* Moves every vertex onto {field = 0} by Newton steps along the numerical gradient. */
void weft__project_to_field(weft__mesh *m, weft__field_fn *field, const void *user, float h, int iterations);

/* Vertex adjacency in CSR form (neighbours through edges, each once). */
typedef struct weft__adjacency {
    uint32_t *offsets; /* nv + 1 */
    uint32_t *neighbours;
    uint32_t nv, count;
} weft__adjacency;

weft_result weft__adjacency_build(const weft_context *ctx, const weft__mesh *m, weft__adjacency *out);
void weft__adjacency_free(const weft_context *ctx, weft__adjacency *adj);

/* Tangential relaxation: each vertex moves towards its neighbours' centroid, the move's
 * normal component removed, then is projected back to the field. */
void weft__relax(weft__mesh *m, const weft__adjacency *adj, weft__field_fn *field, const void *user, float h,
                 int iterations);
/* Same, leaving the vertices with fixed[i] != 0 in place (fixed may be NULL). */
void weft__relax_free_vertices(weft__mesh *m, const weft__adjacency *adj, weft__field_fn *field, const void *user,
                               float h, int iterations, const uint8_t *fixed);

/* Topology report of a triangle mesh. */
typedef struct weft__mesh_topology {
    uint32_t boundary_edges;     /* edges with one triangle */
    uint32_t nonmanifold_edges;  /* edges with three or more */
    uint32_t misoriented_edges;  /* interior edges both triangles traverse the same way */
    uint32_t nonmanifold_vertices; /* vertices whose triangle fan is not one disc / half disc */
    uint32_t components;
    int64_t euler;               /* V - E + F */
    float min_angle_deg;
} weft__mesh_topology;

weft_result weft__mesh_topology_of(const weft_context *ctx, const float *v, uint32_t nv, const uint32_t *t,
                                   uint32_t nt, weft__mesh_topology *out);

#endif
