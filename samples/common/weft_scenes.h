/* Scenes shared by the golden-image tests, `weft render --update-goldens` and the samples:
 * procedural meshes and the fixed golden scenes, each written once. */
#ifndef WEFT_SCENES_H
#define WEFT_SCENES_H

#include "weft_render.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A malloc'd triangle mesh. */
typedef struct weft_render_mesh {
    float *positions;       /* vertex_count * 3 */
    uint32_t *triangles;    /* triangle_count * 3, counter-clockwise from outside */
    uint32_t vertex_count, triangle_count;
} weft_render_mesh;

void weft_render_mesh_free(weft_render_mesh *mesh);
/* Closed UV sphere with single-vertex poles. */
weft_result weft_render_make_sphere(const float center[3], float radius, uint32_t rings, uint32_t segments,
                                    weft_render_mesh *out_mesh);
/* An n x n grid sheet of edge `size` draped over the sphere (center, radius) in closed form:
 * it hugs the cap, then hangs with eight folds. Front (+Y side) faces up and out. */
weft_result weft_render_make_draped_sheet(const float center[3], float radius, float size, uint32_t n,
                                          weft_render_mesh *out_mesh);

/* ---------------------------------------------------------------------------------------- */
/* Golden scenes                                                                              */

/* Golden images are this size and compared with this tolerance: a pixel differs when any RGB
 * channel is off by more than WEFT_GOLDEN_CHANNEL_TOLERANCE counts, and a scene fails when more
 * than WEFT_GOLDEN_MAX_FRACTION of its pixels differ. */
#define WEFT_GOLDEN_SIZE 256u
#define WEFT_GOLDEN_CHANNEL_TOLERANCE 8u
#define WEFT_GOLDEN_MAX_FRACTION 0.005

uint32_t weft_golden_scene_count(void);
/* File stem of scene i ("sheet_sphere", "avatar_rest", ...), NULL when out of range. */
const char *weft_golden_scene_name(uint32_t scene);
/* One line saying what the scene shows. */
const char *weft_golden_scene_description(uint32_t scene);
/* Builds scene i into the renderer (its meshes are replaced), frames and renders it. */
weft_result weft_golden_scene_render(uint32_t scene, weft_context *context, weft_renderer *renderer);

typedef struct weft_golden_outcome {
    weft_image_diff diff;
    bool passed;            /* within tolerance (or just written with update) */
    bool updated;           /* the golden was (re)written */
    char golden_path[512];
    char diff_path[512];    /* written on failure: reference greyed, differing pixels red */
    char actual_path[512];  /* written on failure: what was rendered */
} weft_golden_outcome;

/* Renders scene i and compares it with golden_dir/<name>.png; with update, writes the golden
 * instead. On a mismatch writes <name>.actual.png and <name>.diff.png into out_dir. A missing
 * golden is an IO error (run with update to create it). */
weft_result weft_golden_check(uint32_t scene, weft_context *context, const char *golden_dir, const char *out_dir,
                              bool update, weft_golden_outcome *out);

#ifdef __cplusplus
}
#endif

#endif
