/* Checkpointed sequences (weft_sim_sequence_def.checkpoint_frames): a run stopped at every
 * checkpoint by its time limit and continued call after call writes the same arrays, byte for
 * byte, as the same def run in one go; a corrupt or foreign checkpoint is ignored; the file is
 * gone once the sequence is finished. */
#define _POSIX_C_SOURCE 200809L
#include "test.h"
#include "weft/sim.h"

#include <math.h>
#include <stdint.h>

static unsigned char *read_all(const char *path, long *n)
{
    *n = -1;
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    unsigned char *b = NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (*n = ftell(f)) > 0 && fseek(f, 0, SEEK_SET) == 0 &&
        (b = malloc((size_t)*n)) && fread(b, 1, (size_t)*n, f) != (size_t)*n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    return b;
}

static bool same_file(const char *a_dir, const char *b_dir, const char *name)
{
    char pa[700], pb[700];
    snprintf(pa, sizeof pa, "%s/%s", a_dir, name);
    snprintf(pb, sizeof pb, "%s/%s", b_dir, name);
    long na = 0, nb = 0;
    unsigned char *a = read_all(pa, &na), *b = read_all(pb, &nb);
    const bool same = a && b && na == nb && memcmp(a, b, (size_t)na) == 0;
    free(a);
    free(b);
    return same;
}

static bool exists(const char *dir, const char *name)
{
    char p[700];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    FILE *f = fopen(p, "rb");
    if (f) {
        fclose(f);
    }
    return f != NULL;
}

static weft_sim_sequence_def small_def(weft_sim_scenario scenario)
{
    weft_sim_sequence_def d = weft_sim_default_sequence_def();
    d.scenario = scenario;
    d.seed = 7;
    d.frames = 60;
    d.substeps = 20;
    d.max_substeps = 40;
    d.cloth_vertices = 400;
    d.checkpoint_frames = 4;
    return d;
}

static void remove_sequence(const char *dir)
{
    static const char *const files[] = {"meta.json",      "cloth_pos.npy",    "rest_pos.npy", "faces.npy",
                                        "collider_pos.npy", "collider_faces.npy", "pinned.npy", "stats.npy",
                                        "checkpoint.bin"};
    char p[700];
    for (size_t k = 0; k < sizeof files / sizeof files[0]; ++k) {
        snprintf(p, sizeof p, "%s/%s", dir, files[k]);
        remove(p);
    }
}

static void check_same_sequence(const char *a, const char *b)
{
    static const char *const arrays[] = {"cloth_pos.npy", "collider_pos.npy", "pinned.npy", "rest_pos.npy",
                                         "faces.npy"};
    for (size_t k = 0; k < sizeof arrays / sizeof arrays[0]; ++k) {
        CHECK_MSG(same_file(a, b, arrays[k]), "%s differs between %s and %s", arrays[k], a, b);
    }
}

/* One uninterrupted run of d against one stopped at every checkpoint (every call after the first
 * goes on from the checkpoint the one before left), `calls` calls in all. */
static void interrupted_matches(weft_sim_sequence_def d, const char *tag, uint32_t calls_expected)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char a[512], b[512];
    snprintf(a, sizeof a, "%s/xpbd_checkpoint/%s_whole", WEFT_BINARY_DIR, tag);
    snprintf(b, sizeof b, "%s/xpbd_checkpoint/%s_parts", WEFT_BINARY_DIR, tag);
    remove_sequence(a);
    remove_sequence(b);
    weft_sim_sequence_result whole = {0};
    CHECK_RESULT(weft_sim_generate(ctx, &d, a, NULL, NULL, &whole), WEFT_OK);
    CHECK(whole.finished && whole.accepted && whole.resumed_frame == 0);
    CHECK(!exists(a, "checkpoint.bin"));

    /* A time limit of a nanosecond stops each call at its first checkpoint. */
    d.time_limit_s = 1e-9;
    weft_sim_sequence_result part = {0};
    uint32_t calls = 0, last_frame = 0;
    do {
        CHECK_RESULT(weft_sim_generate(ctx, &d, b, NULL, NULL, &part), WEFT_OK);
        ++calls;
        if (calls > 1) {
            CHECK_MSG(part.resumed_frame == last_frame + d.checkpoint_frames, "call %u resumed at %u after %u", calls,
                      part.resumed_frame, last_frame);
        }
        last_frame = part.resumed_frame;
        CHECK(part.finished || exists(b, "checkpoint.bin"));
        CHECK(part.finished || !exists(b, "meta.json"));
    } while (!part.finished && calls < 2 * calls_expected);
    CHECK_EQ_INT(calls, calls_expected);
    CHECK(part.accepted && part.attempts == whole.attempts && part.substeps_used == whole.substeps_used);
    CHECK(!exists(b, "checkpoint.bin"));
    check_same_sequence(a, b);
    weft_context_destroy(ctx);
}

/* frames 1..59 with checkpoints after 4, 8, ..., 56: 14 stops, then the call that finishes */
static void test_drop_interrupted(void) { interrupted_matches(small_def(WEFT_SIM_SCENARIO_DROP), "drop", 15); }

static void test_gripper_interrupted(void) { interrupted_matches(small_def(WEFT_SIM_SCENARIO_GRIPPER), "gripper", 15); }

/* Real motion: the squeeze zone the reference holds a dress to its bounds in, and the
 * validator's exempt and tangle state, are rebuilt from the checkpoint's frame (without the
 * squeeze zone's rebuild this case differs). Frames 1..119 (a 90-frame pre-roll, then 30) with
 * checkpoints after 8, 16, ..., 112: 14 stops, then the call that finishes. */
static void test_mocap_interrupted(void)
{
    weft_sim_sequence_def d = weft_sim_default_sequence_def();
    d.scenario = WEFT_SIM_SCENARIO_GARMENT;
    d.motion_path = WEFT_SOURCE_DIR "/samples/mocap/clips/crouch_cmu01_05.bvh.gz";
    d.motion_start_s = 1.0f;
    d.seed = 9; /* a dress the crouch squeezes at a checkpoint's frame */
    d.frames = 30;
    d.substeps = d.max_substeps = 10;
    d.cloth_vertices = 256;
    d.checkpoint_frames = 8;
    interrupted_matches(d, "mocap", 15);
}

/* A checkpoint truncated, overwritten with garbage or made by another def is not trusted: the
 * run starts over and still writes the right sequence. */
static void test_bad_checkpoint_ignored(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    char ref[512], dir[512], ck[700];
    snprintf(ref, sizeof ref, "%s/xpbd_checkpoint/drop_whole", WEFT_BINARY_DIR);
    snprintf(dir, sizeof dir, "%s/xpbd_checkpoint/drop_bad", WEFT_BINARY_DIR);
    snprintf(ck, sizeof ck, "%s/checkpoint.bin", dir);
    weft_sim_sequence_def d = small_def(WEFT_SIM_SCENARIO_DROP);
    if (!exists(ref, "meta.json")) {
        weft_sim_sequence_result whole = {0};
        CHECK_RESULT(weft_sim_generate(ctx, &d, ref, NULL, NULL, &whole), WEFT_OK);
    }
    for (int mode = 0; mode < 3; ++mode) {
        remove_sequence(dir);
        /* leave a real checkpoint after frame 4 (of another seed in mode 2) */
        weft_sim_sequence_def first = d;
        first.time_limit_s = 1e-9;
        first.seed = mode == 2 ? 8 : d.seed;
        weft_sim_sequence_result res = {0};
        CHECK_RESULT(weft_sim_generate(ctx, &first, dir, NULL, NULL, &res), WEFT_OK);
        CHECK(!res.finished);
        long n = 0;
        unsigned char *bytes = read_all(ck, &n);
        CHECK(bytes && n > 64);
        if (bytes && mode < 2) {
            FILE *f = fopen(ck, "wb");
            CHECK(f != NULL);
            if (f) {
                if (mode == 0) {
                    fwrite(bytes, 1, (size_t)n / 2, f); /* truncated */
                } else {
                    bytes[n / 2] ^= 0x5a; /* one byte flipped in the middle of the data */
                    fwrite(bytes, 1, (size_t)n, f);
                }
                fclose(f);
            }
        }
        free(bytes);
        CHECK_RESULT(weft_sim_generate(ctx, &d, dir, NULL, NULL, &res), WEFT_OK);
        CHECK_MSG(res.finished && res.resumed_frame == 0, "mode %d: resumed at %u", mode, res.resumed_frame);
        check_same_sequence(ref, dir);
    }
    weft_context_destroy(ctx);
}

static void test_bad_settings(void)
{
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    weft_sim_sequence_result res = {0};
    weft_sim_sequence_def d = small_def(WEFT_SIM_SCENARIO_DROP);
    d.checkpoint_frames = 0;
    d.time_limit_s = 10.0; /* a limit needs checkpoints to stop at */
    CHECK_RESULT(weft_sim_generate(ctx, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    d = small_def(WEFT_SIM_SCENARIO_DROP);
    d.time_limit_s = -1.0;
    CHECK_RESULT(weft_sim_generate(ctx, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    d.time_limit_s = NAN;
    CHECK_RESULT(weft_sim_generate(ctx, &d, "/tmp/never", NULL, NULL, &res), WEFT_ERROR_INVALID_ARGUMENT);
    weft_context_destroy(ctx);
}

TEST_MAIN(TEST_CASE(test_drop_interrupted), TEST_CASE(test_gripper_interrupted), TEST_CASE(test_mocap_interrupted),
          TEST_CASE(test_bad_checkpoint_ignored),
          TEST_CASE(test_bad_settings))
