/* A host program built against an installed weft and weft_assets: a skirt on weft's avatar
 * driven by a BVH clip (argv[1]), blended in from the bind pose, its waistband held by surface
 * pins, over the floor, as a game would step it. Exits non-zero with weft's message on any
 * failure. */
#include <weft.h>
#include <weft/body.h>
#include <weft/motion.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static int fail(const char *what, weft_result r)
{
    fprintf(stderr, "consumer_motion: %s: %s: %s\n", what, weft_result_string(r), weft_last_error());
    return 1;
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: consumer_motion CLIP.bvh[.gz]\n");
        return 2;
    }
    weft_context_def cdef = weft_default_context_def();
    weft_context *ctx = NULL;
    weft_result r = weft_context_create(&cdef, &ctx);
    if (r != WEFT_OK) {
        return fail("context", r);
    }
    weft_avatar_def adef = weft_default_avatar_def();
    weft_body *body = NULL;
    if ((r = weft_avatar_create(ctx, &adef, &body)) != WEFT_OK) {
        return fail("avatar", r);
    }
    weft_bvh_def bdef = weft_default_bvh_def();
    bdef.rest_joints = weft_body_rest_joints(body);
    weft_bvh_report report;
    bdef.report = &report;
    weft_clip *clip = NULL;
    if ((r = weft_bvh_load_file(ctx, argv[1], &bdef, &clip)) != WEFT_OK) {
        return fail("BVH", r);
    }
    weft_cloth_def cloth_def = weft_default_cloth_def(WEFT_CLOTH_SKIRT);
    cloth_def.resolution = WEFT_CLOTH_RES_1K;
    weft_cloth_mesh *skirt = NULL;
    if ((r = weft_cloth_create(ctx, &cloth_def, body, &skirt)) != WEFT_OK) {
        return fail("skirt", r);
    }
    weft_garment_def gdef = weft_default_garment_def();
    gdef.method = WEFT_METHOD_XPBD_FAST;
    gdef.rest_positions = skirt->positions;
    gdef.vertex_count = skirt->vertex_count;
    gdef.triangles = skirt->triangles;
    gdef.triangle_count = skirt->triangle_count;
    gdef.collider_rest_positions = weft_body_rest_vertices(body);
    gdef.collider_vertex_count = weft_body_vertex_count(body);
    gdef.collider_triangles = weft_body_triangles(body);
    gdef.collider_triangle_count = weft_body_triangle_count(body);
    gdef.ccd.enabled = false;
    gdef.collision.ground = true; /* the avatar stands on y = 0 */
    weft_garment *garment = NULL;
    if ((r = weft_garment_create(ctx, &gdef, &garment)) != WEFT_OK) {
        return fail("garment", r);
    }
    /* the waistband: the top ring, carried by the body */
    const uint32_t band = weft_mesh_top_ring(skirt->positions, skirt->vertex_count, 0.012f, NULL, 0);
    uint32_t *band_idx = malloc(band * sizeof *band_idx);
    float *band_rest = malloc((size_t)band * 3 * sizeof(float)), *targets = malloc((size_t)band * 3 * sizeof(float));
    weft_mesh_top_ring(skirt->positions, skirt->vertex_count, 0.012f, band_idx, band);
    for (uint32_t i = 0; i < band * 3; ++i) {
        band_rest[i] = skirt->positions[3 * (size_t)band_idx[i / 3] + i % 3];
    }
    weft_surface_pins_def pdef = weft_default_surface_pins_def();
    pdef.collider_rest_positions = gdef.collider_rest_positions;
    pdef.collider_vertex_count = gdef.collider_vertex_count;
    pdef.collider_triangles = gdef.collider_triangles;
    pdef.collider_triangle_count = gdef.collider_triangle_count;
    pdef.rest_points = band_rest;
    pdef.vertex_indices = band_idx;
    pdef.count = band;
    weft_surface_pins *pins = NULL;
    if ((r = weft_surface_pins_create(ctx, &pdef, &pins)) != WEFT_OK) {
        return fail("waistband", r);
    }
    float *skin = malloc((size_t)weft_body_vertex_count(body) * 3 * sizeof(float));
    weft_pose bind, first, pose;
    weft_body_bind_pose(body, &bind);
    weft_clip_sample(clip, 0.0, &first);
    const int settle = 10, frames = 20;
    for (int k = 0; k < settle + frames && r == WEFT_OK; ++k) {
        if (k < settle) {
            r = weft_pose_blend(&bind, &first, (k + 1.0) / settle, &pose); /* blend in from the bind pose */
        } else {
            r = weft_clip_sample(clip, (k - settle) / 60.0, &pose);
        }
        r = r != WEFT_OK ? r : weft_body_pose(body, &pose, skin, NULL);
        r = r != WEFT_OK ? r : weft_garment_set_collider(garment, skin);
        r = r != WEFT_OK ? r : weft_surface_pins_targets(pins, skin, targets);
        r = r != WEFT_OK ? r : weft_garment_set_pins(garment, weft_surface_pins_indices(pins), targets, band);
        r = r != WEFT_OK ? r : weft_garment_step(garment);
    }
    if (r != WEFT_OK) {
        return fail("step", r);
    }
    const float *x = weft_garment_positions(garment);
    for (uint32_t i = 0; i < skirt->vertex_count * 3; ++i) {
        if (!isfinite(x[i])) {
            fprintf(stderr, "consumer_motion: non-finite cloth\n");
            return 1;
        }
    }
    printf("consumer_motion: %s clip (%s naming, %u of 24 joints), %u frames at %.0f Hz; %d steps of a skirt with %u "
           "waistband pins\n", argv[1], report.naming, report.mapped, clip->frame_count, (double)clip->fps,
           settle + frames, band);
    weft_surface_pins_destroy(pins);
    free(band_idx);
    free(band_rest);
    free(targets);
    free(skin);
    weft_garment_destroy(garment);
    weft_cloth_destroy(skirt);
    weft_clip_destroy(clip);
    weft_body_destroy(body);
    weft_context_destroy(ctx);
    return 0;
}
