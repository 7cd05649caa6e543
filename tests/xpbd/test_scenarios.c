/* The scenario generator end to end on small sheets: drop and gripper sequences are written,
 * validated, deterministic for a seed, and the gripper really holds the cloth up. */
#define _POSIX_C_SOURCE 200809L /* mkdir */
#include "test.h"
#include "weft/body.h"
#include "weft/sim.h"

#include <math.h>
#include <stdint.h>
#include <sys/stat.h>

static long file_size(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return -1;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fclose(f);
    return n;
}

static unsigned char *read_all(const char *path, long *n)
{
    *n = file_size(path);
    FILE *f = fopen(path, "rb");
    if (!f || *n <= 0) {
        if (f) {
            fclose(f);
        }
        return NULL;
    }
    unsigned char *b = malloc((size_t)*n + 1); /* NUL-terminated: meta.json is searched as text */
    if (b && fread(b, 1, (size_t)*n, f) != (size_t)*n) {
        free(b);
        b = NULL;
    }
    if (b) {
        b[*n] = 0;
    }
    fclose(f);
    return b;
}

static weft_sim_sequence_result generate_at(weft_context *ctx, weft_sim_scenario sc, uint64_t seed, uint32_t frames,
                                            const char *dir, float motion_speed)
{
    weft_sim_sequence_def d = weft_sim_default_sequence_def();
    d.motion_speed = motion_speed;
    d.scenario = sc;
    d.seed = seed;
    d.frames = frames;
    d.substeps = 20;
    d.max_substeps = 40;
    d.cloth_vertices = 200;
    weft_sim_sequence_result res = {0};
    CHECK_RESULT(weft_sim_generate(ctx, &d, dir, NULL, NULL, &res), WEFT_OK);
    return res;
}

static weft_sim_sequence_result generate(weft_context *ctx, weft_sim_scenario sc, uint64_t seed, uint32_t frames,
                                         const char *dir)
{
    return generate_at(ctx, sc, seed, frames, dir, 1.0f);
}

/* First frame with a pinned vertex in dir/pinned.npy, or -1. */
static long first_pinned_frame(const char *dir, uint32_t vertices)
{
    char path[600];
    snprintf(path, sizeof path, "%s/pinned.npy", dir);
    long n = 0;
    unsigned char *p = read_all(path, &n);
    long first = -1;
    if (p && n > 10) {
        long h = 10 + (p[8] | (p[9] << 8));
        for (long i = h; i < n && first < 0; ++i) {
            first = p[i] ? (i - h) / (long)vertices : -1;
        }
    }
    free(p);
    return first;
}

static void test_drop_deterministic(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char a[512], b[512], pa[600], pb[600];
    snprintf(a, sizeof a, "%s/xpbd_scenarios/drop_a", WEFT_BINARY_DIR);
    snprintf(b, sizeof b, "%s/xpbd_scenarios/drop_b", WEFT_BINARY_DIR);
    weft_sim_sequence_result ra = generate(ctx, WEFT_SIM_SCENARIO_DROP, 11, 40, a);
    weft_sim_sequence_result rb = generate(ctx, WEFT_SIM_SCENARIO_DROP, 11, 40, b);
    CHECK(ra.accepted && rb.accepted);
    CHECK_EQ_INT(ra.ccd_hits + ra.intersection_hits, 0);
    CHECK(ra.vertex_count > 150 && ra.vertex_count < 260);
    snprintf(pa, sizeof pa, "%s/meta.json", a);
    CHECK(file_size(pa) > 100);
    snprintf(pa, sizeof pa, "%s/cloth_pos.npy", a);
    snprintf(pb, sizeof pb, "%s/cloth_pos.npy", b);
    long na = 0, nb = 0;
    unsigned char *da = read_all(pa, &na), *db = read_all(pb, &nb);
    CHECK(da && db && na == nb && na > 40 * 150 * 12);
    CHECK(da && db && na == nb && memcmp(da, db, (size_t)na) == 0);
    free(da);
    free(db);
    weft_context_destroy(ctx);
}

static void test_gripper_lifts(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char dir[512], path[600];
    snprintf(dir, sizeof dir, "%s/xpbd_scenarios/gripper", WEFT_BINARY_DIR);
    weft_sim_sequence_result r = generate(ctx, WEFT_SIM_SCENARIO_GRIPPER, 5, 80, dir);
    CHECK_MSG(r.accepted, "gripper rejected: %u ccd, %u intersection hits at frame %d", r.ccd_hits,
              r.intersection_hits, r.first_hit_frame);
    if (r.accepted) {
        /* Some vertices are pinned in the last frames, and the cloth's highest point rose. */
        snprintf(path, sizeof path, "%s/pinned.npy", dir);
        long n = 0;
        unsigned char *p = read_all(path, &n);
        CHECK(p != NULL);
        long header = p ? (long)(10 + (p[8] | (p[9] << 8))) : 0;
        long pinned_last = 0;
        for (long i = n - r.vertex_count; p && i < n; ++i) {
            pinned_last += p[i];
        }
        CHECK(pinned_last > 0 && header > 10);
        free(p);
        snprintf(path, sizeof path, "%s/cloth_pos.npy", dir);
        unsigned char *c = read_all(path, &n);
        CHECK(c != NULL);
        if (c) {
            long h = 10 + (c[8] | (c[9] << 8));
            const float *x = (const float *)(c + h);
            float top0 = -1e9f, top1 = -1e9f;
            for (uint32_t i = 0; i < r.vertex_count; ++i) {
                top0 = fmaxf(top0, x[3 * i + 1]);
                top1 = fmaxf(top1, x[3 * ((size_t)79 * r.vertex_count + i) + 1]);
            }
            CHECK_MSG(top1 > top0 + 0.05f, "highest point %g -> %g", top0, top1);
            free(c);
        }
    }
    weft_context_destroy(ctx);
}

/* motion_speed 2 plays the same drawn gripper schedule twice as fast: the grasp (first pinned
 * frame) comes about twice as early. */
static void test_gripper_speed(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char d1[512], d2[512];
    snprintf(d1, sizeof d1, "%s/xpbd_scenarios/gripper_x1", WEFT_BINARY_DIR);
    snprintf(d2, sizeof d2, "%s/xpbd_scenarios/gripper_x2", WEFT_BINARY_DIR);
    weft_sim_sequence_result r1 = generate_at(ctx, WEFT_SIM_SCENARIO_GRIPPER, 5, 45, d1, 1.0f);
    weft_sim_sequence_result r2 = generate_at(ctx, WEFT_SIM_SCENARIO_GRIPPER, 5, 45, d2, 2.0f);
    CHECK(r1.accepted && r2.accepted);
    if (r1.accepted && r2.accepted) {
        long f1 = first_pinned_frame(d1, r1.vertex_count), f2 = first_pinned_frame(d2, r2.vertex_count);
        CHECK_MSG(f1 > 0 && f2 > 0 && f2 < f1 && labs(2 * f2 - f1) <= 2, "first pinned frame %ld at x1, %ld at x2",
                  f1, f2);
    }
    weft_context_destroy(ctx);
}

/* The name-hash split: values that earlier manifests recorded, and the 8:1:1 ratio. */
static void test_split(void)
{
    CHECK(strcmp(weft_sim_split_of("gripper_v256_0000"), "train") == 0);
    CHECK(strcmp(weft_sim_split_of("gripper_v256_0012"), "val") == 0);
    CHECK(strcmp(weft_sim_split_of("gripper_v256_0026"), "test") == 0);
    CHECK(strcmp(weft_sim_split_of(NULL), weft_sim_split_of("")) == 0);
    uint32_t n[3] = {0, 0, 0};
    for (uint32_t i = 0; i < 10000; ++i) {
        char name[32];
        snprintf(name, sizeof name, "drop_1k_%04u", i);
        const char *s = weft_sim_split_of(name);
        n[strcmp(s, "train") == 0 ? 0 : strcmp(s, "val") == 0 ? 1 : 2]++;
    }
    CHECK_MSG(n[0] > 7800 && n[0] < 8200 && n[1] > 900 && n[1] < 1100 && n[2] > 900 && n[2] < 1100,
              "split %u / %u / %u", n[0], n[1], n[2]);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    CHECK_MSG(f != NULL, "cannot write %s", path);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

/* A folder's split: meta.json first, then the manifest one folder up, then the name's hash. */
static void test_sequence_split(void)
{
    char root[512], a[600], b[600], c[600], p[700];
    snprintf(root, sizeof root, "%s/xpbd_scenarios", WEFT_BINARY_DIR);
    mkdir(root, 0755);
    snprintf(root, sizeof root, "%s/xpbd_scenarios/split_set", WEFT_BINARY_DIR);
    snprintf(a, sizeof a, "%s/gripper_v256_0000", root); /* hash: train */
    snprintf(b, sizeof b, "%s/gripper_v256_0012", root); /* hash: val */
    snprintf(c, sizeof c, "%s/gripper_v256_0026", root); /* hash: test */
    mkdir(root, 0755), mkdir(a, 0755), mkdir(b, 0755), mkdir(c, 0755);
    snprintf(p, sizeof p, "%s/meta.json", a);
    write_text(p, "{\"scenario\": \"gripper\", \"split\": \"test\"}");
    snprintf(p, sizeof p, "%s/meta.json", b);
    write_text(p, "{\"scenario\": \"gripper\"}");
    snprintf(p, sizeof p, "%s/meta.json", c);
    write_text(p, "{\"scenario\": \"gripper\", \"split\": \"nonsense\"}");
    snprintf(p, sizeof p, "%s/manifest.json", root);
    write_text(p, "{\"sequences\": [{\"name\": \"gripper_v256_0000\", \"split\": \"val\"},"
                  " {\"name\": \"gripper_v256_0012\", \"split\": \"train\"}]}");
    CHECK(strcmp(weft_sim_sequence_split(a), "test") == 0);  /* meta wins over the manifest */
    CHECK(strcmp(weft_sim_sequence_split(b), "train") == 0); /* the manifest over the hash */
    snprintf(p, sizeof p, "%s/", b);
    CHECK(strcmp(weft_sim_sequence_split(p), "train") == 0); /* a trailing slash is the same folder */
    CHECK(strcmp(weft_sim_sequence_split(c), "test") == 0);  /* unknown values fall through */
    snprintf(p, sizeof p, "%s/manifest.json", root);
    write_text(p, "not json");
    CHECK(strcmp(weft_sim_sequence_split(b), "val") == 0); /* unreadable manifest: the hash */
    CHECK(weft_sim_sequence_split(NULL) == NULL && weft_sim_sequence_split("") == NULL);
}

/* A coarse dress (seed found by `weft simgen --scenario garment --count 12 --vertices 256
 * --frames 10 --substeps 10 --max-substeps 20 --arm-spread 0`, garment_v256_0004) whose arms,
 * as drawn, close on it in the pre-roll: rejected at both substep counts, then accepted by the
 * gentle retry (arms held 0.3 rad wider, motion eased in, amplitude x 0.75), and rejected when
 * that retry is off. With the arms held wider from the start (garment_arm_spread, default) it is
 * accepted at once. */
static void test_garment_arm_spread_retry(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char dir[512], path[600];
    snprintf(dir, sizeof dir, "%s/xpbd_scenarios/dress_spread", WEFT_BINARY_DIR);
    weft_sim_sequence_def d = weft_sim_default_sequence_def();
    d.scenario = WEFT_SIM_SCENARIO_GARMENT;
    d.seed = 2996802168190148522ull;
    d.frames = 10;
    d.substeps = 10;
    d.max_substeps = 20;
    d.cloth_vertices = 256;
    d.garment_arm_spread = 0.0f; /* the arms as drawn, as before garment_arm_spread */
    weft_sim_sequence_result r = {0};
    CHECK_RESULT(weft_sim_generate(ctx, &d, dir, NULL, NULL, &r), WEFT_OK);
    CHECK(strstr(r.description, "dress") && strstr(r.description, "gentle retry"));
    CHECK(r.gentle);
    CHECK_MSG(r.accepted && r.attempts == 3 && r.substeps_used == 10, "accepted %d after %u attempts at S = %u",
              r.accepted, r.attempts, r.substeps_used);
    /* The retry's settings, as meta.json records them: arm_spread 0.3, ease-in 0.5 s. */
    snprintf(path, sizeof path, "%s/meta.json", dir);
    long n = 0;
    char *meta = (char *)read_all(path, &n);
    CHECK(meta && strstr(meta, "\"arm_spread\":\t0.3") && strstr(meta, "\"ease_in_s\":\t0.5") &&
          strstr(meta, "\"gentle_retry\":\ttrue"));
    CHECK(meta && !strstr(meta, "first_hit\":\t{")); /* accepted: nothing to locate */
    CHECK_EQ_INT(r.hit.type, WEFT_CCD_TYPE_COUNT);
    free(meta);
    snprintf(dir, sizeof dir, "%s/xpbd_scenarios/dress_no_spread", WEFT_BINARY_DIR);
    d.garment_retry = false;
    CHECK_RESULT(weft_sim_generate(ctx, &d, dir, NULL, NULL, &r), WEFT_OK);
    CHECK_MSG(!r.accepted && r.attempts == 2 && !r.gentle, "accepted %d after %u attempts", r.accepted, r.attempts);
    /* The rejection says where: a hit on the cloth near the avatar, and the joint there. */
    CHECK_MSG(r.hit.type < WEFT_CCD_TYPE_COUNT, "hit type %u", r.hit.type);
    bool joint_known = false;
    for (uint32_t j = 0; j < WEFT_BODY_JOINTS; ++j) {
        joint_known = joint_known || strcmp(r.hit_joint, weft_joint_name(j)) == 0;
    }
    CHECK_MSG(joint_known, "hit joint '%s'", r.hit_joint);
    CHECK(isfinite(r.hit_position[0]) && r.hit_position[1] > 0.0f && r.hit_position[1] < 2.0f);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    meta = (char *)read_all(path, &n);
    CHECK(meta && strstr(meta, "\"arm_spread\":\t0,") && strstr(meta, "\"gentle_retry\":\tfalse"));
    CHECK(meta && strstr(meta, "\"first_hit\":\t{") && strstr(meta, "\"body_joint\":\t\"") &&
          strstr(meta, r.hit_joint));
    free(meta);
    /* With the default garment_arm_spread (0.3) the same dress is accepted in the first round. */
    snprintf(dir, sizeof dir, "%s/xpbd_scenarios/dress_default", WEFT_BINARY_DIR);
    d.garment_arm_spread = weft_sim_default_sequence_def().garment_arm_spread;
    CHECK_RESULT(weft_sim_generate(ctx, &d, dir, NULL, NULL, &r), WEFT_OK);
    CHECK_MSG(r.accepted && r.attempts == 1 && !r.gentle, "accepted %d after %u attempts", r.accepted, r.attempts);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    meta = (char *)read_all(path, &n);
    CHECK(meta && strstr(meta, "\"arm_spread\":\t0.3") && strstr(meta, "\"gentle_retry\":\tfalse"));
    free(meta);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_drop_deterministic), TEST_CASE(test_garment_arm_spread_retry), TEST_CASE(test_gripper_lifts),
          TEST_CASE(test_gripper_speed), TEST_CASE(test_split), TEST_CASE(test_sequence_split))
