/* The golden scenes. Every input is fixed (procedural meshes, a hand-set pose, garment rest
 * meshes, the shipped int8 model), so a scene's pixels change only when the renderer, the
 * avatar, the wardrobe or the default cloth path of the render sample do. */
#define _POSIX_C_SOURCE 200809L

#include "weft_scenes.h"
#include "core/core.h"
#if WEFT_RENDER_HAVE_AVATAR
#include "weft/body.h"
#endif
#if WEFT_RENDER_HAVE_AVATAR && WEFT_RENDER_HAVE_ASSETS
#include "bvh.h"
#define WEFT_RENDER_CMU_CLIP "/usr/share/assimp/models/BVH/01_01.bvh"
#endif

#if WEFT_RENDER_HAVE_SAMPLE
#include "weft_sample.h"
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef weft_result scene_fn(weft_context *ctx, weft_renderer *r);

typedef struct golden_scene {
    const char *name;
    const char *description;
    scene_fn *build;
} golden_scene;

static weft_result add_and_free(weft_renderer *r, weft_render_mesh *m, weft_render_material material)
{
    weft_result res = weft_renderer_add_mesh(r, m->positions, m->vertex_count, m->triangles, m->triangle_count, material, NULL);
    weft_render_mesh_free(m);
    return res;
}

static weft_result scene_sheet_sphere(weft_context *ctx, weft_renderer *r)
{
    (void)ctx;
    const float center[3] = {0.0f, 0.55f, 0.0f};
    weft_render_mesh sphere, sheet;
    weft_result res = weft_render_make_sphere(center, 0.3f, 32, 48, &sphere);
    if (res != WEFT_OK) {
        return res;
    }
    res = add_and_free(r, &sphere, WEFT_RENDER_RIGID);
    if (res != WEFT_OK) {
        return res;
    }
    res = weft_render_make_draped_sheet(center, 0.3f, 1.2f, 64, &sheet);
    if (res != WEFT_OK) {
        return res;
    }
    res = add_and_free(r, &sheet, WEFT_RENDER_CLOTH);
    if (res != WEFT_OK) {
        return res;
    }
    weft_renderer_set_ground(r, true, 0.0f);
    /* low pitch, so the orange underside shows where a corner hangs towards the camera */
    return weft_renderer_frame_scene(r, 30.0f, 12.0f);
}

#if WEFT_RENDER_HAVE_AVATAR
/* A fixed, recognisable pose set by hand (not a motion clip, so tuning the procedural clips
 * does not move the golden): reaching forward with the left arm, right arm down with the
 * forearm bent forward, mid-stride. Zero rotations are the T-pose. */
static void golden_pose(weft_pose *pose)
{
    memset(pose, 0, sizeof *pose);
    float *rot = pose->rotations;
    rot[3 * WEFT_JOINT_LEFT_SHOULDER + 1] = -1.1f;   /* about Y: arm swings forward */
    rot[3 * WEFT_JOINT_LEFT_SHOULDER + 2] = -0.25f;  /* about Z: slightly below horizontal */
    rot[3 * WEFT_JOINT_LEFT_ELBOW + 1] = -0.35f;
    rot[3 * WEFT_JOINT_RIGHT_SHOULDER + 2] = 1.2f;   /* arm down beside the body */
    rot[3 * WEFT_JOINT_RIGHT_ELBOW + 1] = 1.1f;      /* forearm bent forward */
    rot[3 * WEFT_JOINT_LEFT_HIP + 0] = -0.5f;        /* thigh forward */
    rot[3 * WEFT_JOINT_LEFT_KNEE + 0] = 0.6f;
    rot[3 * WEFT_JOINT_RIGHT_HIP + 0] = 0.3f;        /* thigh back */
    rot[3 * WEFT_JOINT_RIGHT_KNEE + 0] = 0.25f;
    rot[3 * WEFT_JOINT_SPINE2 + 1] = 0.15f;
    rot[3 * WEFT_JOINT_HEAD + 1] = -0.3f;
}

typedef struct avatar_parts {
    weft_body *body;
#if WEFT_RENDER_HAVE_WARDROBE
    weft_cloth_mesh *cloth;
#endif
    float *verts;
    float *cloth_verts;
} avatar_parts;

static void avatar_parts_free(avatar_parts *a)
{
    free(a->verts);
    free(a->cloth_verts);
#if WEFT_RENDER_HAVE_WARDROBE
    weft_cloth_destroy(a->cloth);
#endif
    weft_body_destroy(a->body);
    memset(a, 0, sizeof *a);
}

/* The default avatar, optionally posed and dressed; meshes are added to the renderer. A given
 * pose (fixed_pose) wins over the hand-set golden pose. */
static weft_result avatar_scene_pose(weft_context *ctx, weft_renderer *r, bool posed, const weft_pose *fixed_pose,
                                     int cloth_kind, float yaw, float pitch)
{
    avatar_parts a = {0};
    weft_avatar_def adef = weft_default_avatar_def();
    weft_result res = weft_avatar_create(ctx, &adef, &a.body);
    if (res != WEFT_OK) {
        return res;
    }
    uint32_t nv = weft_body_vertex_count(a.body);
    a.verts = malloc((size_t)nv * 3 * sizeof(float));
    if (!a.verts) {
        avatar_parts_free(&a);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "golden scene: out of memory");
    }
    weft_pose pose;
    if (fixed_pose) {
        pose = *fixed_pose;
    } else if (posed) {
        golden_pose(&pose);
    } else {
        weft_body_bind_pose(a.body, &pose);
    }
    res = weft_body_pose(a.body, &pose, a.verts, NULL);
    if (res == WEFT_OK) {
        res = weft_renderer_add_mesh(r, a.verts, nv, weft_body_triangles(a.body), weft_body_triangle_count(a.body),
                                     WEFT_RENDER_SKIN, NULL);
    }
#if WEFT_RENDER_HAVE_WARDROBE
    if (res == WEFT_OK && cloth_kind >= 0) {
        weft_cloth_def cdef = weft_default_cloth_def((weft_cloth_kind)cloth_kind);
        cdef.resolution = WEFT_CLOTH_RES_4K;
        res = weft_cloth_create(ctx, &cdef, a.body, &a.cloth);
        if (res == WEFT_OK) {
            const float *cp = a.cloth->positions;
            if (posed) {
                a.cloth_verts = malloc((size_t)a.cloth->vertex_count * 3 * sizeof(float));
                if (!a.cloth_verts) {
                    res = weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "golden scene: out of memory");
                } else {
                    res = weft_body_skin_points(a.body, &pose, a.cloth->positions, a.cloth->weights,
                                                a.cloth->vertex_count, a.cloth_verts);
                    cp = a.cloth_verts;
                }
            }
            if (res == WEFT_OK) {
                res = weft_renderer_add_mesh(r, cp, a.cloth->vertex_count, a.cloth->triangles, a.cloth->triangle_count,
                                             WEFT_RENDER_CLOTH, NULL);
            }
        }
    }
#else
    if (cloth_kind >= 0) {
        res = weft__fail(WEFT_ERROR_UNSUPPORTED, "golden scene: this build has no wardrobe");
    }
#endif
    avatar_parts_free(&a);
    if (res != WEFT_OK) {
        return res;
    }
    weft_renderer_set_ground(r, true, 0.0f);
    return weft_renderer_frame_scene(r, yaw, pitch);
}

static weft_result avatar_scene(weft_context *ctx, weft_renderer *r, bool posed, int cloth_kind, float yaw, float pitch)
{
    return avatar_scene_pose(ctx, r, posed, NULL, cloth_kind, yaw, pitch);
}

static weft_result scene_avatar_rest(weft_context *ctx, weft_renderer *r) { return avatar_scene(ctx, r, false, -1, 25.0f, 6.0f); }
static weft_result scene_avatar_posed(weft_context *ctx, weft_renderer *r) { return avatar_scene(ctx, r, true, -1, 35.0f, 8.0f); }
#if WEFT_RENDER_HAVE_WARDROBE
static weft_result scene_avatar_tshirt(weft_context *ctx, weft_renderer *r)
{
    return avatar_scene(ctx, r, false, WEFT_CLOTH_TSHIRT, -20.0f, 8.0f);
}
static weft_result scene_avatar_dress_posed(weft_context *ctx, weft_renderer *r)
{
    return avatar_scene(ctx, r, true, WEFT_CLOTH_DRESS, 35.0f, 8.0f);
}
#endif
#endif

#if WEFT_RENDER_HAVE_AVATAR && WEFT_RENDER_HAVE_ASSETS
/* A frame of CMU motion capture retargeted onto the avatar (01_01 at 4.5 s: mid-stride), so the
 * BVH import and retargeting are covered by an image as well as by numbers. */
static weft_result scene_avatar_cmu(weft_context *ctx, weft_renderer *r)
{
    weft_avatar_def adef = weft_default_avatar_def();
    weft_body *body = NULL;
    weft_result res = weft_avatar_create(ctx, &adef, &body);
    if (res != WEFT_OK) {
        return res;
    }
    weft_bvh_def bdef = weft_default_bvh_def();
    bdef.rest_joints = weft_body_rest_joints(body);
    bdef.first_frame = 540; /* 4.5 s at the clip's 120 Hz */
    bdef.max_frames = 1;
    weft_clip *clip = NULL;
    res = weft_bvh_load_file(ctx, WEFT_RENDER_CMU_CLIP, &bdef, &clip);
    weft_body_destroy(body);
    if (res != WEFT_OK) {
        return res;
    }
    weft_pose pose;
    res = weft_clip_sample(clip, 0.0, &pose);
    weft_clip_destroy(clip);
    if (res != WEFT_OK) {
        return res;
    }
    return avatar_scene_pose(ctx, r, true, &pose, -1, 30.0f, 8.0f);
}
#endif


#if WEFT_RENDER_HAVE_SAMPLE
/* The render sample's worn cloth, short: the avatar blends from its bind pose into the motion at
 * `start` seconds (20 frames) and moves `frames` frames wearing the 1k T-shirt stepped by `method`
 * (the sample's --method) with the worn-garment recipe (body parts, 8 cm max distance, 0.5 cm
 * push, no CCD; for the model the shipped int8 garment model and a 10 % strain limit). The model
 * is required here: a missing file fails the scene instead of falling back to XPBD. The int8
 * forward is bit-exact on every ISA, so the scene runs on this machine's best kernels (its own
 * context) for speed and draws the same pixels everywhere; LBS and the fast XPBD are scalar
 * double-precision code. clip NULL: the procedural walk. */
static weft_result worn_scene(weft_renderer *r, const char *method, const char *clip_path, double start,
                              uint32_t frames, float yaw)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_result cr = weft_context_create(&cd, &ctx);
    if (cr != WEFT_OK) {
        return cr;
    }
    weft_avatar_sample_options o;
    weft_avatar_sample_default_options(&o);
    o.method = method;
    o.model_path = WEFT_RENDER_MODEL_INT8;
    avatar_parts a = {0};
    weft_model *model = NULL;
    weft_garment *garment = NULL;
    weft_clip *clip = NULL;
    weft_avatar_def adef = weft_default_avatar_def();
    weft_result res = weft_avatar_create(ctx, &adef, &a.body);
    const uint32_t nv = res == WEFT_OK ? weft_body_vertex_count(a.body) : 0;
    if (res == WEFT_OK) {
        weft_cloth_def cdef = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
        cdef.resolution = WEFT_CLOTH_RES_1K;
        res = weft_cloth_create(ctx, &cdef, a.body, &a.cloth);
    }
    if (res == WEFT_OK) {
        a.verts = malloc((size_t)nv * 3 * sizeof(float));
        res = a.verts ? weft_avatar_sample_garment_create(&o, ctx, a.body, a.cloth, &model, &garment, (char[32]){0}, 32)
                      : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "golden scene: out of memory");
    }
#if WEFT_RENDER_HAVE_ASSETS
    if (res == WEFT_OK && clip_path) {
        weft_bvh_def bdef = weft_default_bvh_def();
        bdef.rest_joints = weft_body_rest_joints(a.body);
        res = weft_bvh_load_file(ctx, clip_path, &bdef, &clip);
    }
#else
    if (res == WEFT_OK && clip_path) {
        res = weft__fail(WEFT_ERROR_UNSUPPORTED, "golden scene: this build has no BVH import");
    }
#endif
    weft_motion_def md = weft_default_motion_def(WEFT_MOTION_WALK);
    weft_pose bind, first, pose;
    if (res == WEFT_OK) {
        weft_body_bind_pose(a.body, &bind);
        res = clip ? weft_clip_sample(clip, start, &first) : weft_motion_sample(&md, start, &first);
    }
    const uint32_t settle = 20;
    for (uint32_t k = 0; res == WEFT_OK && k < settle + frames; ++k) {
        if (k < settle) {
            weft_avatar_sample_settle_pose(&bind, &first, k, settle, &pose);
        } else {
            const double t = start + (double)(k - settle + 1) / 60.0;
            res = clip ? weft_clip_sample(clip, t, &pose) : weft_motion_sample(&md, t, &pose);
        }
        if (res == WEFT_OK) {
            res = weft_body_pose(a.body, &pose, a.verts, NULL);
        }
        if (res == WEFT_OK) {
            res = weft_garment_set_collider(garment, a.verts);
        }
        if (res == WEFT_OK) {
            res = weft_garment_step(garment);
        }
    }
    if (res == WEFT_OK) {
        res = weft_renderer_add_mesh(r, a.verts, nv, weft_body_triangles(a.body), weft_body_triangle_count(a.body),
                                     WEFT_RENDER_SKIN, NULL);
    }
    if (res == WEFT_OK) {
        res = weft_renderer_add_mesh(r, weft_garment_positions(garment), a.cloth->vertex_count, a.cloth->triangles,
                                     a.cloth->triangle_count, WEFT_RENDER_CLOTH, NULL);
    }
    if (clip) {
        weft_clip_destroy(clip);
    }
    weft_garment_destroy(garment);
    weft_model_destroy(model);
    avatar_parts_free(&a);
    weft_context_destroy(ctx);
    if (res != WEFT_OK) {
        return res;
    }
    weft_renderer_set_ground(r, true, 0.0f);
    return weft_renderer_frame_scene(r, yaw, 8.0f);
}

static weft_result scene_avatar_model_int8(weft_context *scalar_ctx, weft_renderer *r)
{
    (void)scalar_ctx;
    return worn_scene(r, "model", NULL, 0.0, 20, 25.0f);
}

#if WEFT_RENDER_HAVE_ASSETS
/* Real motion capture where the body overlaps itself: Debian's CMU 01_01 from 1 s through the
 * crouch (the forearms sink into the chest) to 2.5 s, where the T-shirt used to be torn off. */
static weft_result scene_avatar_cmu_worn(weft_context *scalar_ctx, weft_renderer *r)
{
    (void)scalar_ctx;
    return worn_scene(r, "model", WEFT_RENDER_CMU_CLIP, 1.0, 90, 25.0f);
}

/* The same crouch with LBS and with the fast XPBD at 10 substeps: every method keeps the shirt on. */
static weft_result scene_avatar_cmu_worn_lbs(weft_context *scalar_ctx, weft_renderer *r)
{
    (void)scalar_ctx;
    return worn_scene(r, "lbs", WEFT_RENDER_CMU_CLIP, 1.0, 90, 25.0f);
}

static weft_result scene_avatar_cmu_worn_xpbd_fast(weft_context *scalar_ctx, weft_renderer *r)
{
    (void)scalar_ctx;
    return worn_scene(r, "xpbd-fast:10", WEFT_RENDER_CMU_CLIP, 1.0, 90, 25.0f);
}
#endif
#endif

static const golden_scene k_scenes[] = {
    {"sheet_sphere", "a 64x64 cloth sheet draped in closed form over a sphere", scene_sheet_sphere},
#if WEFT_RENDER_HAVE_AVATAR
    {"avatar_rest", "the default avatar in its bind (A) pose", scene_avatar_rest},
    {"avatar_posed", "the default avatar in a fixed hand-set pose", scene_avatar_posed},
#endif
#if WEFT_RENDER_HAVE_AVATAR && WEFT_RENDER_HAVE_ASSETS
    {"avatar_cmu", "CMU 01_01.bvh at 4.5 s retargeted onto the avatar", scene_avatar_cmu},
#endif
#if WEFT_RENDER_HAVE_WARDROBE
    {"avatar_tshirt", "the avatar in its bind pose wearing the 4k T-shirt rest mesh", scene_avatar_tshirt},
    {"avatar_dress_posed", "the posed avatar with the 4k dress skinned to the pose", scene_avatar_dress_posed},
#endif
#if WEFT_RENDER_HAVE_SAMPLE
    {"avatar_model_int8", "the render sample's default: a 1k T-shirt stepped by the int8 garment model, worn-garment recipe",
     scene_avatar_model_int8},
#if WEFT_RENDER_HAVE_ASSETS
    {"avatar_cmu_worn", "the same T-shirt through CMU 01_01's crouch (1 s to 2.5 s): the body overlaps itself, the shirt stays on",
     scene_avatar_cmu_worn},
    {"avatar_cmu_worn_lbs", "the crouch of avatar_cmu_worn with LBS and the recipe", scene_avatar_cmu_worn_lbs},
    {"avatar_cmu_worn_xpbd_fast", "the crouch of avatar_cmu_worn with the fast XPBD at 10 substeps and the recipe",
     scene_avatar_cmu_worn_xpbd_fast},
#endif
#endif
};

uint32_t weft_golden_scene_count(void) { return (uint32_t)(sizeof k_scenes / sizeof k_scenes[0]); }

const char *weft_golden_scene_name(uint32_t scene)
{
    return scene < weft_golden_scene_count() ? k_scenes[scene].name : NULL;
}

const char *weft_golden_scene_description(uint32_t scene)
{
    return scene < weft_golden_scene_count() ? k_scenes[scene].description : NULL;
}

weft_result weft_golden_scene_render(uint32_t scene, weft_context *context, weft_renderer *renderer)
{
    if (!renderer || scene >= weft_golden_scene_count()) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_golden_scene_render: renderer required and scene %u < %u",
                          scene, weft_golden_scene_count());
    }
    weft_renderer_clear_meshes(renderer);
    weft_result res = k_scenes[scene].build(context, renderer);
    if (res != WEFT_OK) {
        return res;
    }
    return weft_renderer_render(renderer);
}

weft_result weft_golden_check(uint32_t scene, weft_context *context, const char *golden_dir, const char *out_dir,
                              bool update, weft_golden_outcome *out)
{
    if (!golden_dir || !out || scene >= weft_golden_scene_count()) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_golden_check: golden_dir, out and a valid scene are required");
    }
    weft_golden_outcome o;
    memset(&o, 0, sizeof o);
    const char *name = k_scenes[scene].name;
    snprintf(o.golden_path, sizeof o.golden_path, "%s/%s.png", golden_dir, name);
    weft_render_def def = weft_default_render_def();
    def.width = def.height = WEFT_GOLDEN_SIZE;
    weft_renderer *r = NULL;
    weft_result res = weft_renderer_create(&def, &r);
    if (res != WEFT_OK) {
        return res;
    }
    res = weft_golden_scene_render(scene, context, r);
    if (res != WEFT_OK) {
        weft_renderer_destroy(r);
        return res;
    }
    const uint8_t *pixels = weft_renderer_pixels(r);
    if (update) {
        res = weft_render_write_png(o.golden_path, pixels, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_SIZE);
        weft_renderer_destroy(r);
        if (res == WEFT_OK) {
            o.passed = o.updated = true;
            *out = o;
        }
        return res;
    }
    uint8_t *golden = NULL;
    uint32_t gw = 0, gh = 0;
    res = weft_render_read_png(o.golden_path, &golden, &gw, &gh);
    if (res != WEFT_OK) {
        weft_renderer_destroy(r);
        return res;
    }
    if (gw != WEFT_GOLDEN_SIZE || gh != WEFT_GOLDEN_SIZE) {
        weft_render_free_image(golden);
        weft_renderer_destroy(r);
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "weft_golden_check: '%s' is %ux%u, expected %ux%u", o.golden_path, gw,
                          gh, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_SIZE);
    }
    uint8_t *diff = malloc((size_t)WEFT_GOLDEN_SIZE * WEFT_GOLDEN_SIZE * 4);
    if (!diff) {
        weft_render_free_image(golden);
        weft_renderer_destroy(r);
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "weft_golden_check: out of memory");
    }
    res = weft_render_compare(golden, pixels, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_CHANNEL_TOLERANCE, &o.diff, diff);
    o.passed = res == WEFT_OK && o.diff.fraction_over <= WEFT_GOLDEN_MAX_FRACTION;
    if (res == WEFT_OK && !o.passed && out_dir) {
        snprintf(o.diff_path, sizeof o.diff_path, "%s/%s.diff.png", out_dir, name);
        snprintf(o.actual_path, sizeof o.actual_path, "%s/%s.actual.png", out_dir, name);
        res = weft_render_write_png(o.diff_path, diff, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_SIZE);
        if (res == WEFT_OK) {
            res = weft_render_write_png(o.actual_path, pixels, WEFT_GOLDEN_SIZE, WEFT_GOLDEN_SIZE);
        }
    }
    free(diff);
    weft_render_free_image(golden);
    weft_renderer_destroy(r);
    if (res == WEFT_OK) {
        *out = o;
    }
    return res;
}
