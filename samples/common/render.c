/* OSMesa renderer: fixed-function GL with per-vertex normals, which every Mesa software driver
 * implements identically and which needs no shader compilation at start-up. */
#define _POSIX_C_SOURCE 200809L

#include "weft_render.h"
#include "core/core.h"

#include <GL/gl.h>
#include <GL/osmesa.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define RENDER_MAX_SIZE 4096u
#define RENDER_FOV_Y_DEG 30.0f    /* a mild telephoto: less perspective distortion on bodies */
#define RENDER_FRAME_MARGIN 1.08f /* framed box corners keep ~4% of the image free at each edge */

typedef struct render_mesh {
    float *positions;   /* vertex_count * 3 */
    float *normals;     /* vertex_count * 3 */
    uint32_t *triangles;
    uint32_t vertex_count, triangle_count;
    weft_render_material material;
    float front[3], back[3];
    bool visible;
} render_mesh;

struct weft_renderer {
    weft_render_def def;
    OSMesaContext gl;
    uint32_t fb_width, fb_height;   /* supersampled framebuffer */
    uint8_t *framebuffer;           /* fb_width * fb_height * 4, written by GL */
    uint8_t *pixels;                /* width * height * 4, the box-filtered result */

    render_mesh *meshes;
    uint32_t mesh_count, mesh_capacity;

    bool has_camera;
    float eye[3], center[3], right[3], up[3], forward[3];
    float distance, radius;
    bool ground_enabled, ground_fixed;
    float ground_height;            /* fixed height, or the framed box's minimum Y */
};

static const float k_material_colors[WEFT_RENDER_MATERIAL_COUNT][2][3] = {
    [WEFT_RENDER_SKIN] = {{0.80f, 0.72f, 0.64f}, {0.80f, 0.72f, 0.64f}},
    [WEFT_RENDER_CLOTH] = {{0.22f, 0.42f, 0.78f}, {0.92f, 0.52f, 0.16f}},
    [WEFT_RENDER_GROUND] = {{0.78f, 0.78f, 0.76f}, {0.78f, 0.78f, 0.76f}},
    [WEFT_RENDER_RIGID] = {{0.56f, 0.60f, 0.64f}, {0.56f, 0.60f, 0.64f}},
};

weft_render_def weft_default_render_def(void)
{
    weft_render_def def = {0};
    def.width = 256;
    def.height = 256;
    def.supersample = 2;
    def.deterministic = true;
    def.ground = true;
    def.shadows = true;
    def.background[0] = 0.93f;
    def.background[1] = 0.94f;
    def.background[2] = 0.96f;
    def.internal_cookie = WEFT_DEF_COOKIE;
    return def;
}

weft_result weft_renderer_create(const weft_render_def *def, weft_renderer **out_renderer)
{
    if (!def || !out_renderer) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_create: def and out_renderer are required");
    }
    if (def->internal_cookie != WEFT_DEF_COOKIE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT,
                          "weft_renderer_create: def was not initialised with weft_default_render_def()");
    }
    if (def->width < 16 || def->height < 16 || def->width > RENDER_MAX_SIZE || def->height > RENDER_MAX_SIZE) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_create: size %ux%u outside 16..%u", def->width,
                          def->height, RENDER_MAX_SIZE);
    }
    if (def->supersample < 1 || def->supersample > 4) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_create: supersample %u outside 1..4",
                          def->supersample);
    }
    if (!weft__all_finite(def->background, 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_renderer_create: background colour is not finite");
    }
    /* Mesa reads these when OSMesa creates its screen (once per process). softpipe rasterises
     * in plain C, and DRAW_USE_LLVM=0 keeps its vertex stage off the LLVM JIT too, so no code
     * generated for the host's vector ISA touches the image; the llvmpipe settings pin the JIT
     * for processes where another component already chose llvmpipe. */
    if (def->deterministic) {
        setenv("GALLIUM_DRIVER", "softpipe", 1);
        setenv("DRAW_USE_LLVM", "0", 1);
        setenv("LP_NATIVE_VECTOR_WIDTH", "128", 1);
        setenv("LP_NUM_THREADS", "0", 1);
    }

    weft_renderer *r = calloc(1, sizeof *r);
    if (!r) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_renderer_create: out of memory");
    }
    r->def = *def;
    r->fb_width = def->width * def->supersample;
    r->fb_height = def->height * def->supersample;
    r->framebuffer = malloc((size_t)r->fb_width * r->fb_height * 4);
    r->pixels = malloc((size_t)def->width * def->height * 4);
    if (!r->framebuffer || !r->pixels) {
        free(r->framebuffer);
        free(r->pixels);
        free(r);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_renderer_create: out of memory for %ux%u pixels",
                          def->width, def->height);
    }
    memset(r->pixels, 0, (size_t)def->width * def->height * 4);
    static const int attribs[] = {OSMESA_FORMAT,       OSMESA_RGBA, OSMESA_DEPTH_BITS, 24, OSMESA_STENCIL_BITS, 8,
                                  OSMESA_PROFILE, OSMESA_COMPAT_PROFILE, 0};
    r->gl = OSMesaCreateContextAttribs(attribs, NULL);
    if (!r->gl) {
        free(r->framebuffer);
        free(r->pixels);
        free(r);
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_renderer_create: OSMesa could not create a GL context");
    }
    if (!OSMesaMakeCurrent(r->gl, r->framebuffer, GL_UNSIGNED_BYTE, (GLsizei)r->fb_width, (GLsizei)r->fb_height)) {
        uint32_t fw = r->fb_width, fh = r->fb_height;
        OSMesaDestroyContext(r->gl);
        free(r->framebuffer);
        free(r->pixels);
        free(r);
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_renderer_create: OSMesaMakeCurrent failed for %ux%u", fw, fh);
    }
    OSMesaPixelStore(OSMESA_Y_UP, 0); /* row 0 is the top row, as PNG expects */
    r->ground_enabled = def->ground;
    *out_renderer = r;
    return WEFT_OK;
}

static void free_mesh(render_mesh *m)
{
    free(m->positions);
    free(m->normals);
    free(m->triangles);
    memset(m, 0, sizeof *m);
}

void weft_renderer_clear_meshes(weft_renderer *r)
{
    if (!r) {
        return;
    }
    for (uint32_t i = 0; i < r->mesh_count; ++i) {
        free_mesh(&r->meshes[i]);
    }
    r->mesh_count = 0;
}

void weft_renderer_destroy(weft_renderer *r)
{
    if (!r) {
        return;
    }
    weft_renderer_clear_meshes(r);
    free(r->meshes);
    if (OSMesaGetCurrentContext() == r->gl) {
        OSMesaMakeCurrent(NULL, NULL, 0, 0, 0);
    }
    OSMesaDestroyContext(r->gl);
    free(r->framebuffer);
    free(r->pixels);
    free(r);
}

uint32_t weft_renderer_mesh_count(const weft_renderer *r) { return r ? r->mesh_count : 0; }
const uint8_t *weft_renderer_pixels(const weft_renderer *r) { return r ? r->pixels : NULL; }
uint32_t weft_renderer_width(const weft_renderer *r) { return r ? r->def.width : 0; }
uint32_t weft_renderer_height(const weft_renderer *r) { return r ? r->def.height : 0; }

/* Area-weighted vertex normals: the cross product's length is twice the triangle area, so
 * summing unnormalised face normals weights big faces more, which avoids slivers dominating. */
static void compute_normals(render_mesh *m)
{
    memset(m->normals, 0, (size_t)m->vertex_count * 3 * sizeof(float));
    for (uint32_t t = 0; t < m->triangle_count; ++t) {
        const uint32_t *tri = m->triangles + 3 * (size_t)t;
        const float *a = m->positions + 3 * (size_t)tri[0];
        const float *b = m->positions + 3 * (size_t)tri[1];
        const float *c = m->positions + 3 * (size_t)tri[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; ++k) {
            float *dst = m->normals + 3 * (size_t)tri[k];
            dst[0] += n[0];
            dst[1] += n[1];
            dst[2] += n[2];
        }
    }
    for (uint32_t v = 0; v < m->vertex_count; ++v) {
        float *n = m->normals + 3 * (size_t)v;
        float len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 1e-20f) {
            n[0] /= len;
            n[1] /= len;
            n[2] /= len;
        } else {
            /* isolated or fully degenerate vertex: any unit vector keeps GL lighting finite */
            n[0] = 0.0f;
            n[1] = 1.0f;
            n[2] = 0.0f;
        }
    }
}

weft_result weft_renderer_add_mesh(weft_renderer *r, const float *positions, uint32_t vertex_count,
                                   const uint32_t *triangles, uint32_t triangle_count,
                                   weft_render_material material, uint32_t *out_mesh)
{
    if (!r || !positions || !triangles) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_add_mesh: renderer, positions and triangles are required");
    }
    if (vertex_count == 0 || triangle_count == 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_add_mesh: empty mesh (%u vertices, %u triangles)",
                          vertex_count, triangle_count);
    }
    if ((unsigned)material >= WEFT_RENDER_MATERIAL_COUNT) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_add_mesh: material %d out of range", (int)material);
    }
    if (triangle_count > UINT32_MAX / 3 || vertex_count > UINT32_MAX / 3) {
        return weft__fail(WEFT_ERROR_SIZE_OVERFLOW, "weft_renderer_add_mesh: mesh too large");
    }
    if (!weft__all_finite(positions, (size_t)vertex_count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_renderer_add_mesh: positions contain NaN or infinity");
    }
    for (size_t i = 0; i < (size_t)triangle_count * 3; ++i) {
        if (triangles[i] >= vertex_count) {
            return weft__fail(WEFT_ERROR_DEGENERATE_MESH, "weft_renderer_add_mesh: triangle %zu index %u >= vertex count %u",
                              i / 3, triangles[i], vertex_count);
        }
    }
    if (r->mesh_count == r->mesh_capacity) {
        uint32_t cap = r->mesh_capacity ? r->mesh_capacity * 2 : 8;
        render_mesh *grown = realloc(r->meshes, cap * sizeof *grown);
        if (!grown) {
            return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_renderer_add_mesh: out of memory");
        }
        r->meshes = grown;
        r->mesh_capacity = cap;
    }
    render_mesh m = {0};
    m.vertex_count = vertex_count;
    m.triangle_count = triangle_count;
    m.material = material;
    m.visible = true;
    memcpy(m.front, k_material_colors[material][0], sizeof m.front);
    memcpy(m.back, k_material_colors[material][1], sizeof m.back);
    m.positions = malloc((size_t)vertex_count * 3 * sizeof(float));
    m.normals = malloc((size_t)vertex_count * 3 * sizeof(float));
    m.triangles = malloc((size_t)triangle_count * 3 * sizeof(uint32_t));
    if (!m.positions || !m.normals || !m.triangles) {
        free_mesh(&m);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_renderer_add_mesh: out of memory for %u vertices", vertex_count);
    }
    memcpy(m.positions, positions, (size_t)vertex_count * 3 * sizeof(float));
    memcpy(m.triangles, triangles, (size_t)triangle_count * 3 * sizeof(uint32_t));
    compute_normals(&m);
    r->meshes[r->mesh_count] = m;
    if (out_mesh) {
        *out_mesh = r->mesh_count;
    }
    r->mesh_count++;
    return WEFT_OK;
}

static weft_result check_mesh_id(const weft_renderer *r, uint32_t mesh, const char *fn)
{
    if (!r) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: renderer is NULL", fn);
    }
    if (mesh >= r->mesh_count) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "%s: mesh %u does not exist (%u meshes)", fn, mesh, r->mesh_count);
    }
    return WEFT_OK;
}

weft_result weft_renderer_update_mesh(weft_renderer *r, uint32_t mesh, const float *positions)
{
    weft_result res = check_mesh_id(r, mesh, "weft_renderer_update_mesh");
    if (res != WEFT_OK) {
        return res;
    }
    if (!positions) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_update_mesh: positions is NULL");
    }
    render_mesh *m = &r->meshes[mesh];
    if (!weft__all_finite(positions, (size_t)m->vertex_count * 3)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_renderer_update_mesh: mesh %u positions contain NaN or infinity", mesh);
    }
    memcpy(m->positions, positions, (size_t)m->vertex_count * 3 * sizeof(float));
    compute_normals(m);
    return WEFT_OK;
}

weft_result weft_renderer_set_mesh_visible(weft_renderer *r, uint32_t mesh, bool visible)
{
    weft_result res = check_mesh_id(r, mesh, "weft_renderer_set_mesh_visible");
    if (res != WEFT_OK) {
        return res;
    }
    r->meshes[mesh].visible = visible;
    return WEFT_OK;
}

weft_result weft_renderer_set_mesh_colors(weft_renderer *r, uint32_t mesh, const float front[3], const float back[3])
{
    weft_result res = check_mesh_id(r, mesh, "weft_renderer_set_mesh_colors");
    if (res != WEFT_OK) {
        return res;
    }
    if (!front) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_set_mesh_colors: front is NULL");
    }
    if (!back) {
        back = front;
    }
    for (int k = 0; k < 3; ++k) {
        if (!(front[k] >= 0.0f && front[k] <= 1.0f && back[k] >= 0.0f && back[k] <= 1.0f)) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_set_mesh_colors: colours must be in 0..1");
        }
    }
    memcpy(r->meshes[mesh].front, front, 3 * sizeof(float));
    memcpy(r->meshes[mesh].back, back, 3 * sizeof(float));
    return WEFT_OK;
}

weft_result weft_renderer_scene_bounds(const weft_renderer *r, float out_min[3], float out_max[3])
{
    if (!r || !out_min || !out_max) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_scene_bounds: arguments are required");
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    bool any = false;
    for (uint32_t i = 0; i < r->mesh_count; ++i) {
        const render_mesh *m = &r->meshes[i];
        if (!m->visible) {
            continue;
        }
        any = true;
        for (uint32_t v = 0; v < m->vertex_count; ++v) {
            for (int k = 0; k < 3; ++k) {
                float x = m->positions[3 * (size_t)v + (size_t)k];
                lo[k] = x < lo[k] ? x : lo[k];
                hi[k] = x > hi[k] ? x : hi[k];
            }
        }
    }
    if (!any) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_scene_bounds: no visible mesh");
    }
    memcpy(out_min, lo, sizeof lo);
    memcpy(out_max, hi, sizeof hi);
    return WEFT_OK;
}

static float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void normalize3(float *v)
{
    float len = sqrtf(dot3(v, v));
    v[0] /= len;
    v[1] /= len;
    v[2] /= len;
}

void weft_renderer_set_ground(weft_renderer *r, bool enabled, float height)
{
    if (!r) {
        return;
    }
    r->ground_enabled = enabled;
    r->ground_fixed = isfinite(height);
    if (r->ground_fixed) {
        r->ground_height = height;
    }
}

weft_result weft_renderer_frame_box(weft_renderer *r, const float box_min[3], const float box_max[3], float yaw_deg,
                                    float pitch_deg)
{
    if (!r || !box_min || !box_max) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_frame_box: renderer and box are required");
    }
    if (!weft__all_finite(box_min, 3) || !weft__all_finite(box_max, 3) || !isfinite(yaw_deg) || !isfinite(pitch_deg)) {
        return weft__fail(WEFT_ERROR_NOT_FINITE, "weft_renderer_frame_box: box or angles are not finite");
    }
    for (int k = 0; k < 3; ++k) {
        if (box_min[k] > box_max[k]) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_frame_box: box_min[%d] > box_max[%d]", k, k);
        }
    }
    if (pitch_deg > 85.0f || pitch_deg < -85.0f) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_frame_box: pitch %.1f outside -85..85 degrees",
                          (double)pitch_deg);
    }
    const float deg = 3.14159265358979f / 180.0f;
    float yaw = yaw_deg * deg, pitch = pitch_deg * deg;
    float dir[3] = {sinf(yaw) * cosf(pitch), sinf(pitch), cosf(yaw) * cosf(pitch)}; /* centre -> eye */
    float center[3], half[3];
    for (int k = 0; k < 3; ++k) {
        center[k] = 0.5f * (box_min[k] + box_max[k]);
        half[k] = 0.5f * (box_max[k] - box_min[k]);
    }
    float forward[3] = {-dir[0], -dir[1], -dir[2]};
    float world_up[3] = {0.0f, 1.0f, 0.0f};
    float right[3] = {forward[1] * world_up[2] - forward[2] * world_up[1], forward[2] * world_up[0] - forward[0] * world_up[2],
                      forward[0] * world_up[1] - forward[1] * world_up[0]};
    normalize3(right);
    float up[3] = {right[1] * forward[2] - right[2] * forward[1], right[2] * forward[0] - right[0] * forward[2],
                   right[0] * forward[1] - right[1] * forward[0]};
    float tan_y = tanf(0.5f * RENDER_FOV_Y_DEG * deg);
    float tan_x = tan_y * (float)r->def.width / (float)r->def.height;
    /* A corner at view offsets (x, y) and depth offset z towards the camera fits when the
     * camera distance D satisfies |x| <= (D - z) tan_x and |y| <= (D - z) tan_y. */
    float distance = 0.0f;
    float radius = sqrtf(dot3(half, half));
    for (int c = 0; c < 8; ++c) {
        float v[3] = {(c & 1) ? half[0] : -half[0], (c & 2) ? half[1] : -half[1], (c & 4) ? half[2] : -half[2]};
        float x = fabsf(dot3(v, right)), y = fabsf(dot3(v, up)), z = dot3(v, dir);
        float need = fmaxf(z + x / tan_x, z + y / tan_y);
        distance = fmaxf(distance, need);
    }
    if (radius < 1e-4f) {
        radius = 1e-4f; /* a point: keep the projection well defined */
    }
    distance = fmaxf(distance * RENDER_FRAME_MARGIN, 2.0f * radius);
    for (int k = 0; k < 3; ++k) {
        r->center[k] = center[k];
        r->eye[k] = center[k] + dir[k] * distance;
        r->forward[k] = forward[k];
        r->right[k] = right[k];
        r->up[k] = up[k];
    }
    r->distance = distance;
    r->radius = radius;
    if (!r->ground_fixed) {
        r->ground_height = box_min[1];
    }
    r->has_camera = true;
    return WEFT_OK;
}

weft_result weft_renderer_frame_scene(weft_renderer *r, float yaw_deg, float pitch_deg)
{
    float lo[3], hi[3];
    weft_result res = weft_renderer_scene_bounds(r, lo, hi);
    if (res != WEFT_OK) {
        return res;
    }
    return weft_renderer_frame_box(r, lo, hi, yaw_deg, pitch_deg);
}

/* Eye-space lights, so every view direction gets the same studio look: a warm key from the
 * upper left, a cool fill from the right and a rim light from behind. */
static void setup_lights(void)
{
    static const float global_ambient[4] = {0.22f, 0.22f, 0.24f, 1.0f};
    static const float key_pos[4] = {-0.45f, 0.75f, 0.55f, 0.0f};
    static const float key_diffuse[4] = {0.78f, 0.76f, 0.72f, 1.0f};
    static const float key_specular[4] = {0.5f, 0.5f, 0.5f, 1.0f};
    static const float fill_pos[4] = {0.7f, 0.15f, 0.45f, 0.0f};
    static const float fill_diffuse[4] = {0.28f, 0.30f, 0.34f, 1.0f};
    static const float rim_pos[4] = {0.1f, 0.5f, -0.9f, 0.0f};
    static const float rim_diffuse[4] = {0.22f, 0.22f, 0.22f, 1.0f};
    static const float black[4] = {0.0f, 0.0f, 0.0f, 1.0f};

    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, global_ambient);
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
    glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, GL_FALSE);
    glLightfv(GL_LIGHT0, GL_POSITION, key_pos);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, key_diffuse);
    glLightfv(GL_LIGHT0, GL_SPECULAR, key_specular);
    glLightfv(GL_LIGHT0, GL_AMBIENT, black);
    glLightfv(GL_LIGHT1, GL_POSITION, fill_pos);
    glLightfv(GL_LIGHT1, GL_DIFFUSE, fill_diffuse);
    glLightfv(GL_LIGHT1, GL_SPECULAR, black);
    glLightfv(GL_LIGHT1, GL_AMBIENT, black);
    glLightfv(GL_LIGHT2, GL_POSITION, rim_pos);
    glLightfv(GL_LIGHT2, GL_DIFFUSE, rim_diffuse);
    glLightfv(GL_LIGHT2, GL_SPECULAR, black);
    glLightfv(GL_LIGHT2, GL_AMBIENT, black);
    glEnable(GL_LIGHT0);
    glEnable(GL_LIGHT1);
    glEnable(GL_LIGHT2);
}

static void load_view(const weft_renderer *r)
{
    /* column-major look-at: rows of the rotation are right, up, -forward */
    float m[16] = {r->right[0], r->up[0], -r->forward[0], 0.0f, r->right[1], r->up[1], -r->forward[1], 0.0f,
                   r->right[2], r->up[2], -r->forward[2], 0.0f, 0.0f,        0.0f,    0.0f,           1.0f};
    m[12] = -dot3(r->right, r->eye);
    m[13] = -dot3(r->up, r->eye);
    m[14] = dot3(r->forward, r->eye);
    glMatrixMode(GL_MODELVIEW);
    glLoadMatrixf(m);
}

static void set_material(const render_mesh *m)
{
    float spec = 0.08f, shininess = 24.0f;
    if (m->material == WEFT_RENDER_SKIN) {
        spec = 0.12f;
        shininess = 18.0f;
    } else if (m->material == WEFT_RENDER_RIGID) {
        spec = 0.35f;
        shininess = 48.0f;
    } else if (m->material == WEFT_RENDER_CLOTH) {
        spec = 0.04f; /* woven fabric: almost no highlight */
        shininess = 8.0f;
    }
    float front[4] = {m->front[0], m->front[1], m->front[2], 1.0f};
    float back[4] = {m->back[0], m->back[1], m->back[2], 1.0f};
    float specular[4] = {spec, spec, spec, 1.0f};
    glMaterialfv(GL_FRONT, GL_AMBIENT_AND_DIFFUSE, front);
    glMaterialfv(GL_BACK, GL_AMBIENT_AND_DIFFUSE, back);
    glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, specular);
    glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, shininess);
}

static float ground_tile_size(float radius)
{
    /* 25 cm tiles for human-sized scenes; coarser for large ones so the grid stays readable */
    float tile = 0.25f;
    while (tile * 12.0f < radius) {
        tile *= 2.0f;
    }
    return tile;
}

static void draw_ground(const weft_renderer *r)
{
    float tile = ground_tile_size(r->radius);
    int n = (int)ceilf(fmaxf(6.0f * r->radius, 3.0f) / tile);
    float cx = floorf(r->center[0] / tile) * tile, cz = floorf(r->center[2] / tile) * tile;
    float y = r->ground_height;
    const float *bg = r->def.background;
    float fog_color[4] = {bg[0], bg[1], bg[2], 1.0f};
    glEnable(GL_FOG);
    glFogi(GL_FOG_MODE, GL_LINEAR);
    glFogfv(GL_FOG_COLOR, fog_color);
    glFogf(GL_FOG_START, r->distance + r->radius);
    glFogf(GL_FOG_END, r->distance + 5.0f * r->radius + 2.0f);
    glEnable(GL_COLOR_MATERIAL);
    glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
    static const float no_spec[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, no_spec);
    glNormal3f(0.0f, 1.0f, 0.0f);
    glBegin(GL_QUADS);
    for (int i = -n; i < n; ++i) {
        for (int j = -n; j < n; ++j) {
            float x0 = cx + (float)i * tile, z0 = cz + (float)j * tile;
            if (((i + j) & 1) == 0) {
                glColor3f(0.80f, 0.80f, 0.78f);
            } else {
                glColor3f(0.71f, 0.72f, 0.71f);
            }
            glVertex3f(x0, y, z0);
            glVertex3f(x0, y, z0 + tile);
            glVertex3f(x0 + tile, y, z0 + tile);
            glVertex3f(x0 + tile, y, z0);
        }
    }
    glEnd();
    glDisable(GL_COLOR_MATERIAL);
    glDisable(GL_FOG);
}

/* Flattens meshes onto the ground along a near-vertical light; the stencil makes every ground
 * pixel darken at most once, so overlapping triangles do not stack. */
static void draw_shadows(const weft_renderer *r)
{
    const float light[3] = {0.25f, 1.0f, 0.35f};
    float g = r->ground_height;
    float ax = light[0] / light[1], az = light[2] / light[1];
    /* x' = x - ax (y - g), y' = g, z' = z - az (y - g); column-major */
    float m[16] = {1.0f, 0.0f, 0.0f, 0.0f, -ax, 0.0f, -az, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, ax * g, g, az * g, 1.0f};
    glDisable(GL_LIGHTING);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glEnable(GL_STENCIL_TEST);
    glStencilFunc(GL_EQUAL, 1, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_INCR);
    glColor4f(0.05f, 0.05f, 0.08f, 0.28f);
    glPushMatrix();
    glMultMatrixf(m);
    for (uint32_t i = 0; i < r->mesh_count; ++i) {
        const render_mesh *mesh = &r->meshes[i];
        if (!mesh->visible || mesh->material == WEFT_RENDER_GROUND) {
            continue;
        }
        glVertexPointer(3, GL_FLOAT, 0, mesh->positions);
        glDrawElements(GL_TRIANGLES, (GLsizei)(mesh->triangle_count * 3), GL_UNSIGNED_INT, mesh->triangles);
    }
    glPopMatrix();
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_BLEND);
    glEnable(GL_DEPTH_TEST);
    glEnable(GL_LIGHTING);
}

static void downsample(weft_renderer *r)
{
    uint32_t s = r->def.supersample, w = r->def.width, h = r->def.height;
    uint32_t n = s * s;
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            uint32_t acc[3] = {0, 0, 0};
            for (uint32_t sy = 0; sy < s; ++sy) {
                const uint8_t *row = r->framebuffer + ((size_t)(y * s + sy) * r->fb_width + (size_t)x * s) * 4;
                for (uint32_t sx = 0; sx < s; ++sx) {
                    acc[0] += row[4 * sx + 0];
                    acc[1] += row[4 * sx + 1];
                    acc[2] += row[4 * sx + 2];
                }
            }
            uint8_t *dst = r->pixels + ((size_t)y * w + x) * 4;
            dst[0] = (uint8_t)((acc[0] + n / 2) / n);
            dst[1] = (uint8_t)((acc[1] + n / 2) / n);
            dst[2] = (uint8_t)((acc[2] + n / 2) / n);
            dst[3] = 255;
        }
    }
}

weft_result weft_renderer_render(weft_renderer *r)
{
    if (!r) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_render: renderer is NULL");
    }
    if (!r->has_camera) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_renderer_render: no camera; call weft_renderer_frame_box or _frame_scene first");
    }
    if (OSMesaGetCurrentContext() != r->gl &&
        !OSMesaMakeCurrent(r->gl, r->framebuffer, GL_UNSIGNED_BYTE, (GLsizei)r->fb_width, (GLsizei)r->fb_height)) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_renderer_render: OSMesaMakeCurrent failed");
    }
    OSMesaPixelStore(OSMESA_Y_UP, 0);
    const float *bg = r->def.background;
    glViewport(0, 0, (GLsizei)r->fb_width, (GLsizei)r->fb_height);
    glClearColor(bg[0], bg[1], bg[2], 1.0f);
    glClearStencil(0);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);

    float near_plane = fmaxf(r->distance - 2.0f * r->radius, 0.02f * r->distance);
    float far_plane = r->distance + 12.0f * r->radius + 8.0f;
    float tan_y = tanf(0.5f * RENDER_FOV_Y_DEG * 3.14159265358979f / 180.0f);
    float top = near_plane * tan_y, right = top * (float)r->def.width / (float)r->def.height;
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    glFrustum(-right, right, -top, top, near_plane, far_plane);

    setup_lights();
    load_view(r);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glShadeModel(GL_SMOOTH);
    glEnable(GL_NORMALIZE);
    glEnable(GL_LIGHTING);
    glEnableClientState(GL_VERTEX_ARRAY);

    if (r->ground_enabled) {
        glEnable(GL_STENCIL_TEST);
        glStencilFunc(GL_ALWAYS, 1, 0xff);
        glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
        draw_ground(r);
        glDisable(GL_STENCIL_TEST);
        if (r->def.shadows) {
            draw_shadows(r);
        }
    }

    glEnableClientState(GL_NORMAL_ARRAY);
    for (uint32_t i = 0; i < r->mesh_count; ++i) {
        const render_mesh *m = &r->meshes[i];
        if (!m->visible) {
            continue;
        }
        set_material(m);
        glVertexPointer(3, GL_FLOAT, 0, m->positions);
        glNormalPointer(GL_FLOAT, 0, m->normals);
        glDrawElements(GL_TRIANGLES, (GLsizei)(m->triangle_count * 3), GL_UNSIGNED_INT, m->triangles);
    }
    glDisableClientState(GL_NORMAL_ARRAY);
    glDisableClientState(GL_VERTEX_ARRAY);
    glFinish();
    GLenum err = glGetError();
    if (err != GL_NO_ERROR) {
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "weft_renderer_render: GL error 0x%04x", (unsigned)err);
    }
    downsample(r);
    return WEFT_OK;
}
