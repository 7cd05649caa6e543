/* A user's own character (samples/common/character.c): weft's avatar exported as a skinned glTF
 * with every joint renamed (no SMPL name left) and a walk, loaded back as a character. Its own
 * animation must pose it where weft's avatar stands in the same frames, a garment fitted to it
 * must bind and skin like the wardrobe's, and garments not fitted to it are refused by name.
 * Also writes the files the render-sample test runs on (tests/character_*.gltf/.obj). */
#include "test.h"
#include "character.h"
#include "pc2.h"
#include "gltf.h"
#include "weft/body.h"
#include "weft/motion.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHAR_GLTF WEFT_BINARY_DIR "/tests/character_renamed.gltf"
#define CHAR_OBJ WEFT_BINARY_DIR "/tests/character_tshirt.obj"

static weft_context *g_ctx;
static weft_body *g_body;
static weft_clip *g_clip;

static char *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    if (buf) {
        buf[n] = '\0';
        *size = (size_t)n;
    }
    return buf;
}

/* weft's avatar and a 2 s walk as glTF, each joint's name replaced by "rig:Bone_NN". */
static void test_write_character(void)
{
    weft_avatar_def adef = weft_default_avatar_def();
    CHECK_RESULT(weft_avatar_create(g_ctx, &adef, &g_body), WEFT_OK);
    weft_motion_def mdef = weft_default_motion_def(WEFT_MOTION_WALK);
    CHECK_RESULT(weft_clip_from_motion(g_ctx, &mdef, 2.0, 60.0f, &g_clip), WEFT_OK);
    if (!g_body || !g_clip) {
        return;
    }
    const char *plain = WEFT_BINARY_DIR "/tests/character_plain.gltf";
    CHECK_RESULT(weft_gltf_write_body(plain, g_body, g_clip), WEFT_OK);
    size_t size = 0;
    char *text = read_all(plain, &size);
    CHECK(text != NULL);
    if (!text) {
        return;
    }
    char *out = malloc(size * 2 + 1024);
    strcpy(out, text);
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        char from[64], to[64];
        snprintf(from, sizeof from, "\"%s\"", weft_joint_name(j));
        snprintf(to, sizeof to, "\"rig:Bone_%02u\"", j);
        char *hit = strstr(out, from);
        CHECK_MSG(hit != NULL, "joint name %s not in the glTF", from);
        if (hit) {
            memmove(hit + strlen(to), hit + strlen(from), strlen(hit + strlen(from)) + 1);
            memcpy(hit, to, strlen(to));
        }
    }
    /* the binary buffer keeps its name: point at the plain file's */
    FILE *f = fopen(CHAR_GLTF, "wb");
    CHECK(f != NULL);
    if (f) {
        fputs(out, f);
        fclose(f);
    }
    size_t bin_size = 0;
    char *bin = read_all(WEFT_BINARY_DIR "/tests/character_plain.bin", &bin_size);
    f = fopen(WEFT_BINARY_DIR "/tests/character_renamed.bin", "wb");
    CHECK(bin && f);
    if (bin && f) {
        fwrite(bin, 1, bin_size, f);
    }
    if (f) {
        fclose(f);
    }
    free(bin);
    free(text);
    free(out);
    /* the renamed file names its own .bin only when the uri followed the file name */
    size_t check_size = 0;
    char *check = read_all(CHAR_GLTF, &check_size);
    CHECK(check && strstr(check, "pelvis") == NULL && strstr(check, "rig:Bone_23") != NULL);
    if (check && strstr(check, "character_plain.bin")) {
        /* uri kept: the plain .bin next to it serves both */
    }
    free(check);
}

static void test_pose_matches_avatar(void)
{
    weft_sample_character *c = NULL;
    CHECK_RESULT(weft_sample_character_load(g_ctx, CHAR_GLTF, &c), WEFT_OK);
    if (!c || !g_body) {
        weft_sample_character_destroy(c);
        return;
    }
    const uint32_t nv = weft_sample_character_vertex_count(c);
    CHECK_EQ_INT(nv, weft_body_vertex_count(g_body));
    CHECK_EQ_INT(weft_sample_character_joint_count(c), WEFT_BODY_JOINTS);
    CHECK_EQ_INT(weft_sample_character_frame_count(c), g_clip->frame_count);
    uint32_t parts = 0;
    const uint8_t *ids = weft_sample_character_parts(c, &parts);
    CHECK(parts >= 16 && parts <= 24);
    for (uint32_t t = 0; t < weft_sample_character_triangle_count(c); ++t) {
        CHECK(ids[t] < parts);
    }
    float *a = malloc((size_t)nv * 3 * sizeof(float)), *b = malloc((size_t)nv * 3 * sizeof(float));
    /* u = 0 is the bind pose as stored */
    CHECK_RESULT(weft_sample_character_pose(c, 0.7, 0.0, a), WEFT_OK);
    double worst = 0.0;
    for (size_t i = 0; i < (size_t)nv * 3; ++i) {
        worst = fmax(worst, fabs((double)a[i] - weft_sample_character_bind_vertices(c)[i]));
    }
    CHECK_MSG(worst < 1e-5, "bind pose moved by %.2e m", worst);
    /* frames of the walk against weft's avatar posed by the same clip (the glTF keeps four
     * weights a vertex, the avatar has up to 24: differences of millimetres) */
    double worst_frame = 0.0;
    for (uint32_t f = 0; f < g_clip->frame_count; f += 17) {
        weft_pose pose;
        CHECK_RESULT(weft_clip_sample(g_clip, f / 60.0, &pose), WEFT_OK);
        CHECK_RESULT(weft_body_pose(g_body, &pose, b, NULL), WEFT_OK);
        CHECK_RESULT(weft_sample_character_pose(c, f / 60.0, 1.0, a), WEFT_OK);
        for (size_t i = 0; i < (size_t)nv; ++i) {
            const double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
            worst_frame = fmax(worst_frame, sqrt(dx * dx + dy * dy + dz * dz));
        }
    }
    printf("  renamed-joint character vs weft's avatar over the walk: worst vertex %.2f mm\n", 1000.0 * worst_frame);
    CHECK_MSG(worst_frame < 0.01, "worst vertex %.4f m", worst_frame);
    /* halfway blend stays finite and between */
    CHECK_RESULT(weft_sample_character_pose(c, 1.0, 0.5, a), WEFT_OK);
    bool finite = true;
    for (size_t i = 0; i < (size_t)nv * 3; ++i) {
        finite &= isfinite(a[i]) != 0;
    }
    CHECK(finite);
    CHECK_RESULT(weft_sample_character_pose(c, NAN, 1.0, a), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_sample_character_pose(c, 0.0, 1.5, a), WEFT_ERROR_INVALID_ARGUMENT);
    free(a);
    free(b);
    weft_sample_character_destroy(c);
}

static void test_garment_binding(void)
{
    weft_sample_character *c = NULL;
    CHECK_RESULT(weft_sample_character_load(g_ctx, CHAR_GLTF, &c), WEFT_OK);
    weft_cloth_def cd = weft_default_cloth_def(WEFT_CLOTH_TSHIRT);
    cd.resolution = WEFT_CLOTH_RES_1K;
    weft_cloth_mesh *cloth = NULL;
    CHECK_RESULT(weft_cloth_create(g_ctx, &cd, g_body, &cloth), WEFT_OK);
    if (!c || !cloth) {
        weft_sample_character_destroy(c);
        weft_cloth_destroy(cloth);
        return;
    }
    const uint32_t n = cloth->vertex_count;
    CHECK_RESULT(weft_obj_write(CHAR_OBJ, cloth->positions, n, cloth->triangles, cloth->triangle_count), WEFT_OK);
    float *rest = NULL;
    uint32_t *tris = NULL, rn = 0, rt = 0;
    CHECK_RESULT(weft_obj_read(CHAR_OBJ, &rest, &rn, &tris, &rt), WEFT_OK);
    CHECK(rn == n && rt == cloth->triangle_count);
    CHECK_RESULT(weft_sample_character_bind(c, rest, rn), WEFT_OK);
    /* carried by the skin: close to the wardrobe's own skinning of the same garment */
    float *x = malloc((size_t)n * 3 * sizeof(float)), *y = malloc((size_t)n * 3 * sizeof(float));
    float *body = malloc((size_t)weft_sample_character_vertex_count(c) * 3 * sizeof(float));
    weft_pose pose;
    CHECK_RESULT(weft_clip_sample(g_clip, 1.0, &pose), WEFT_OK);
    CHECK_RESULT(weft_sample_character_pose(c, 1.0, 1.0, body), WEFT_OK);
    CHECK_RESULT(weft_sample_character_skin_garment(c, x), WEFT_OK);
    CHECK_RESULT(weft_body_skin_points(g_body, &pose, cloth->positions, cloth->weights, n, y), WEFT_OK);
    double mean = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const double dx = x[3 * i] - y[3 * i], dy = x[3 * i + 1] - y[3 * i + 1], dz = x[3 * i + 2] - y[3 * i + 2];
        mean += sqrt(dx * dx + dy * dy + dz * dz) / n;
    }
    printf("  T-shirt skinned by the character vs the wardrobe's weights: mean %.2f mm\n", 1000.0 * mean);
    CHECK_MSG(mean < 0.01, "mean %.4f m", mean);
    /* not on this character: 1 m to the side */
    float *moved = malloc((size_t)n * 3 * sizeof(float));
    for (uint32_t i = 0; i < n * 3; ++i) {
        moved[i] = rest[i] + (i % 3 == 0 ? 1.0f : 0.0f);
    }
    CHECK_RESULT(weft_sample_character_bind(c, moved, n), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "not fitted") != NULL);
    /* inside it: shrunk to 60 % about the torso's centre */
    double centre[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            centre[k] += rest[3 * i + (uint32_t)k] / n;
        }
    }
    for (uint32_t i = 0; i < n * 3; ++i) {
        moved[i] = (float)(centre[i % 3] + 0.6 * (rest[i] - centre[i % 3]));
    }
    CHECK_RESULT(weft_sample_character_bind(c, moved, n), WEFT_ERROR_FORMAT);
    CHECK_MSG(strstr(weft_last_error(), "inside the character") != NULL, "%s", weft_last_error());
    /* the refused bindings left the first in place */
    CHECK_RESULT(weft_sample_character_skin_garment(c, y), WEFT_OK);
    CHECK(memcmp(x, y, (size_t)n * 3 * sizeof(float)) == 0);
    free(moved);
    free(x);
    free(y);
    free(body);
    free(rest);
    free(tris);
    weft_cloth_destroy(cloth);
    weft_sample_character_destroy(c);
}

static void test_bad_files(void)
{
    weft_sample_character *c = NULL;
    CHECK_RESULT(weft_sample_character_load(g_ctx, WEFT_BINARY_DIR "/tests/no_such_character.gltf", &c), WEFT_ERROR_IO);
    CHECK(c == NULL);
    /* OBJ errors name the line */
    const char *bad = WEFT_BINARY_DIR "/tests/character_bad.obj";
    static const char *const cases[][2] = {
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "line 4"},
        {"v 0 0 0\nv 1 0 x\n", "line 2"},
        {"v 0 0 0\nv 1 0 0\nf 1 2\n", "at least three"},
        {"v 0 0 1e38\n", "beyond"},
        {"# nothing\n", "no vertices"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        FILE *f = fopen(bad, "wb");
        fputs(cases[i][0], f);
        fclose(f);
        float *p = (float *)(uintptr_t)0x10;
        uint32_t *t = NULL, nv = 7, nt = 7;
        weft_result r = weft_obj_read(bad, &p, &nv, &t, &nt);
        CHECK_MSG(r != WEFT_OK && strstr(weft_last_error(), cases[i][1]) != NULL, "case %zu: %s", i, weft_last_error());
        CHECK(p == (float *)(uintptr_t)0x10 && nv == 7 && nt == 7);
    }
    /* quads and negative indices */
    FILE *f = fopen(bad, "wb");
    fputs("o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf -4/1 -3/1 -2/1 -1/1\n", f);
    fclose(f);
    float *p = NULL;
    uint32_t *t = NULL, nv = 0, nt = 0;
    CHECK_RESULT(weft_obj_read(bad, &p, &nv, &t, &nt), WEFT_OK);
    CHECK(nv == 4 && nt == 2 && t && t[0] == 0 && t[1] == 1 && t[2] == 2 && t[5] == 3);
    free(p);
    free(t);
}

/* A library clip (BVH, CMU names) retargeted onto weft's avatar, then through a joint map onto the
 * renamed character: since the character is weft's avatar under other names, it must stand where
 * the avatar stands in every frame. Maps missing required joints or naming no joint fail by name. */
static void test_library_clip_on_character(void)
{
    weft_sample_character *c = NULL;
    CHECK_RESULT(weft_sample_character_load(g_ctx, CHAR_GLTF, &c), WEFT_OK);
    if (!c || !g_body) {
        weft_sample_character_destroy(c);
        return;
    }
    weft_bvh_def bd = weft_default_bvh_def();
    bd.rest_joints = weft_body_rest_joints(g_body);
    weft_clip *clip = NULL;
    CHECK_RESULT(weft_bvh_load_file(g_ctx, WEFT_SOURCE_DIR "/samples/mocap/clips/walk_cmu07_01.bvh.gz", &bd, &clip),
                 WEFT_OK);
    char names[WEFT_BODY_JOINTS][16];
    const char *map[WEFT_BODY_JOINTS];
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        snprintf(names[j], sizeof names[j], "Bone_%02u", j); /* the file says rig:Bone_NN */
        map[j] = names[j];
    }
    const uint32_t nv = weft_sample_character_vertex_count(c);
    float *a = malloc((size_t)nv * 3 * sizeof(float)), *b = malloc((size_t)nv * 3 * sizeof(float));
    if (clip && a && b) {
        CHECK_RESULT(weft_sample_character_set_clip(c, g_body, clip, map), WEFT_OK);
        CHECK_EQ_INT(weft_sample_character_frame_count(c), clip->frame_count);
        double worst = 0.0;
        for (uint32_t f = 0; f < clip->frame_count; f += 23) {
            weft_pose pose;
            CHECK_RESULT(weft_clip_sample(clip, f / (double)clip->fps, &pose), WEFT_OK);
            CHECK_RESULT(weft_body_pose(g_body, &pose, b, NULL), WEFT_OK);
            CHECK_RESULT(weft_sample_character_pose(c, f / (double)clip->fps, 1.0, a), WEFT_OK);
            for (size_t i = 0; i < (size_t)nv; ++i) {
                const double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
                worst = fmax(worst, sqrt(dx * dx + dy * dy + dz * dz));
            }
        }
        printf("  library walk retargeted onto the renamed character vs weft's avatar: worst vertex %.2f mm\n",
               1000.0 * worst);
        CHECK_MSG(worst < 0.01, "worst vertex %.4f m", worst);
        /* bad maps leave the retargeted clip in place */
        map[18] = NULL;
        CHECK_RESULT(weft_sample_character_set_clip(c, g_body, clip, map), WEFT_ERROR_FORMAT);
        CHECK(strstr(weft_last_error(), "left_elbow") != NULL);
        map[18] = "LeftForeArm";
        CHECK_RESULT(weft_sample_character_set_clip(c, g_body, clip, map), WEFT_ERROR_FORMAT);
        CHECK(strstr(weft_last_error(), "'LeftForeArm'") != NULL);
        CHECK_EQ_INT(weft_sample_character_frame_count(c), clip->frame_count);
    }
    free(a);
    free(b);
    weft_clip_destroy(clip);
    weft_sample_character_destroy(c);
}

static void setup(void)
{
    weft_context_def cdef = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cdef, &g_ctx), WEFT_OK);
}

static void teardown(void)
{
    weft_clip_destroy(g_clip);
    weft_body_destroy(g_body);
    weft_context_destroy(g_ctx);
}

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_write_character), TEST_CASE(test_pose_matches_avatar),
          TEST_CASE(test_garment_binding), TEST_CASE(test_library_clip_on_character), TEST_CASE(test_bad_files),
          TEST_CASE(teardown))
