/*
 * weft_render — off-screen renderer for the samples, the `weft render` command and the
 * golden-image tests.
 *
 * It draws triangle meshes with OpenGL through OSMesa (software rasterisation, no window, no
 * GPU), lights them with a key, a fill and an ambient term, shades cloth two-sided (front and
 * back faces in clearly different colours, so self-intersections and inside-out folds show), puts
 * a checker ground plane with a planar contact shadow under the scene, frames a bounding box from
 * a yaw/pitch direction and returns RGBA8 pixels, top row first.
 *
 *   weft_render_def def = weft_default_render_def();
 *   def.width = 256; def.height = 256;
 *   weft_renderer *r;
 *   weft_renderer_create(&def, &r);
 *   uint32_t body;
 *   weft_renderer_add_mesh(r, positions, nv, triangles, nt, WEFT_RENDER_SKIN, &body);
 *   weft_renderer_frame_scene(r, 20.0f, 10.0f);
 *   weft_renderer_render(r);
 *   weft_render_write_png("out.png", weft_renderer_pixels(r), 256, 256);
 *   weft_renderer_destroy(r);
 *
 * Determinism: with def.deterministic (the default) the renderer selects Mesa's softpipe
 * rasteriser with its C vertex path (GALLIUM_DRIVER=softpipe, DRAW_USE_LLVM=0) before OSMesa
 * starts, so the same scene gives the same bytes on every x86 CPU (llvmpipe's JIT output depends
 * on the host's vector ISA and thread count). Mesa picks its driver once per process: the first
 * renderer created decides for all later ones.
 *
 * Memory: meshes are copied when added; updating positions, framing and rendering allocate
 * nothing. Errors follow weft's rules: a weft_result, a message in weft_last_error(), and the
 * renderer left unchanged on failure.
 */
#ifndef WEFT_RENDER_H
#define WEFT_RENDER_H

#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum weft_render_material {
    WEFT_RENDER_SKIN = 0,   /* matte mannequin */
    WEFT_RENDER_CLOTH,      /* two-sided: blue front, orange back */
    WEFT_RENDER_GROUND,     /* a user ground mesh: flat light grey */
    WEFT_RENDER_RIGID,      /* colliders and props: cool grey, slightly glossy */
    WEFT_RENDER_MATERIAL_COUNT
} weft_render_material;

typedef struct weft_render_def {
    uint32_t width, height;     /* output image size in pixels, 16..4096 */
    uint32_t supersample;       /* 1..4: render at supersample x size and box-filter down (default 2) */
    bool deterministic;         /* force Mesa's softpipe (default true), see above */
    bool ground;                /* draw the checker ground plane (default true) */
    bool shadows;               /* planar contact shadows on the ground (default true) */
    float background[3];        /* clear colour, linear 0..1 */
    uint32_t internal_cookie;   /* set by weft_default_render_def(); do not touch */
} weft_render_def;

typedef struct weft_renderer weft_renderer;

weft_render_def weft_default_render_def(void);
weft_result weft_renderer_create(const weft_render_def *def, weft_renderer **out_renderer);
void weft_renderer_destroy(weft_renderer *renderer);

/* Copies a mesh (positions vertex_count*3, CCW triangles) and computes its vertex normals.
 * Fails on NaN/inf positions, out-of-range indices or empty meshes. */
weft_result weft_renderer_add_mesh(weft_renderer *renderer, const float *positions, uint32_t vertex_count,
                                   const uint32_t *triangles, uint32_t triangle_count,
                                   weft_render_material material, uint32_t *out_mesh);
/* New positions for a mesh (same vertex count); normals are recomputed. Allocates nothing. */
weft_result weft_renderer_update_mesh(weft_renderer *renderer, uint32_t mesh, const float *positions);
weft_result weft_renderer_set_mesh_visible(weft_renderer *renderer, uint32_t mesh, bool visible);
/* Overrides a mesh's colours (0..1 RGB). back may be NULL to use front for both sides. */
weft_result weft_renderer_set_mesh_colors(weft_renderer *renderer, uint32_t mesh, const float front[3],
                                          const float back[3]);
/* Removes every mesh. */
void weft_renderer_clear_meshes(weft_renderer *renderer);
uint32_t weft_renderer_mesh_count(const weft_renderer *renderer);

/* Axis-aligned bounds of the visible meshes. Fails when there is none. */
weft_result weft_renderer_scene_bounds(const weft_renderer *renderer, float out_min[3], float out_max[3]);

/* Camera that looks at the box centre from direction (yaw, pitch) in degrees — yaw 0 looks at
 * the avatar's face (from +Z), positive yaw orbits towards +X, positive pitch looks down — at
 * the distance where all eight box corners fit with a small margin. The ground plane, when on,
 * is placed at the box's minimum Y unless weft_renderer_set_ground() fixed it. */
weft_result weft_renderer_frame_box(weft_renderer *renderer, const float box_min[3], const float box_max[3],
                                    float yaw_deg, float pitch_deg);
/* Frames weft_renderer_scene_bounds(). */
weft_result weft_renderer_frame_scene(weft_renderer *renderer, float yaw_deg, float pitch_deg);
/* Fixes the ground height (metres along Y); NaN returns to "box minimum". */
void weft_renderer_set_ground(weft_renderer *renderer, bool enabled, float height);

/* Draws the scene into the pixel buffer. Needs a camera (a frame_* call). */
weft_result weft_renderer_render(weft_renderer *renderer);
/* RGBA8, width*height*4 bytes, top row first; valid until the next render or destroy. */
const uint8_t *weft_renderer_pixels(const weft_renderer *renderer);
uint32_t weft_renderer_width(const weft_renderer *renderer);
uint32_t weft_renderer_height(const weft_renderer *renderer);

/* ---------------------------------------------------------------------------------------- */
/* Images (RGBA8, top row first).                                                            */

weft_result weft_render_write_png(const char *path, const uint8_t *rgba, uint32_t width, uint32_t height);
/* Reads a PNG into a malloc'd RGBA8 buffer (free with weft_render_free_image). */
weft_result weft_render_read_png(const char *path, uint8_t **out_rgba, uint32_t *out_width, uint32_t *out_height);
void weft_render_free_image(uint8_t *rgba);

/* Image comparison for golden tests: a pixel "differs" when any RGB channel differs by more than
 * channel_tolerance counts. Returns the number of such pixels and the largest channel
 * difference; diff_rgba (optional, width*height*4) receives a visualisation: the reference
 * dimmed to grey with differing pixels in red. */
typedef struct weft_image_diff {
    uint64_t pixels_over;
    uint32_t max_channel_diff;
    double fraction_over;       /* pixels_over / (width*height) */
} weft_image_diff;
weft_result weft_render_compare(const uint8_t *reference, const uint8_t *actual, uint32_t width, uint32_t height,
                                uint32_t channel_tolerance, weft_image_diff *out_diff, uint8_t *diff_rgba);

/* Tiles count images of tile_width x tile_height into a sheet with `columns` columns and a
 * 2-pixel gutter, each with an optional label (ASCII, drawn in the tile's top-left corner;
 * labels may be NULL or contain NULLs). The sheet is malloc'd: free with weft_render_free_image. */
weft_result weft_render_contact_sheet(const uint8_t *const *images, const char *const *labels, uint32_t count,
                                      uint32_t tile_width, uint32_t tile_height, uint32_t columns,
                                      uint8_t **out_rgba, uint32_t *out_width, uint32_t *out_height);
/* Draws ASCII text into an RGBA8 image at (x, y) with an integer pixel scale and a dark
 * backing box so it reads on any background. Clipped to the image. */
void weft_render_draw_text(uint8_t *rgba, uint32_t width, uint32_t height, int x, int y, int scale, const char *text);

#ifdef __cplusplus
}
#endif

#endif
