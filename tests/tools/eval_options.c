/* `weft eval` options on the committed sample sequence: --sim-mesh with the sequence's own mesh
 * (an identity map) scores exactly as without it, pins included (a copy of the sample with a
 * pinned corner), --tether-cm and --strain-limit run, a tiny
 * --time-limit stops the rollout early and says so, --write-pos writes the rollout, a worn garment
 * reports the wear measures and takes the worn-garment recipe (--recipe worn), and bad values fail
 * with an error exit. argv: weft binary, data folder, output folder. Exits 77 (skipped) without
 * a sample sequence. */
#define _POSIX_C_SOURCE 200809L /* posix_spawn, stat */
#include "test.h"

#include "tool_run.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *g_exe, *g_seq, *g_out;

/* The JSON line eval printed, with its timings (ms_per_frame, ms_p50, ms_p99, ms_max) replaced by
 * '#' (wall time differs per run, in value and in length). */
static bool json_line(const char *path, char *out, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        return false;
    }
    bool found = false;
    char line[2048];
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '{') {
            snprintf(out, cap, "%s", line);
            found = true;
        }
    }
    fclose(f);
    static const char *const timed[] = {"\"ms_per_frame\": ", "\"ms_p50\": ", "\"ms_p99\": ", "\"ms_max\": "};
    for (size_t k = 0; found && k < sizeof timed / sizeof timed[0]; ++k) {
        char *ms = strstr(out, timed[k]);
        char *value = ms ? ms + strlen(timed[k]) : NULL, *end = value ? strchr(value, ',') : NULL;
        if (end) {
            *value = '#';
            memmove(value + 1, end, strlen(end) + 1);
        }
    }
    return found;
}

static double json_number(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\": ", key);
    const char *p = strstr(json, k);
    return p ? strtod(p + strlen(k), NULL) : NAN;
}

static void sim_mesh_identity(void)
{
    char a[1200], b[1200], ja[2048], jb[2048];
    snprintf(a, sizeof a, "%s/eval_plain.txt", g_out);
    snprintf(b, sizeof b, "%s/eval_map.txt", g_out);
    const char *plain[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "6", "--json", NULL};
    const char *mapped[] = {g_exe,  "eval",   "--seq", g_seq,        "--method", "xpbd:5", "--frames",
                            "6",    "--json", "--sim-mesh", g_seq, NULL};
    CHECK_EQ_INT(tool_run(plain, a), 0);
    CHECK_EQ_INT(tool_run(mapped, b), 0);
    CHECK(json_line(a, ja, sizeof ja));
    CHECK(json_line(b, jb, sizeof jb));
    double mve = json_number(ja, "mve_cm");
    CHECK_MSG(isfinite(mve) && mve >= 0.0, "MVE '%s'", ja);
    CHECK_EQ_INT((int)json_number(ja, "frames"), 6);
    /* rest positions map onto themselves exactly, so the whole run is the same */
    CHECK_MSG(strcmp(ja, jb) == 0, "identity map changed the result:\n%s%s", ja, jb);
}

/* A copy of the sample (links to its arrays) whose first `pinned` vertices are pinned in every
 * frame: pinned.npy [T, N] uint8. */
static bool pinned_copy(const char *dir, uint32_t frames, uint32_t vertices, uint32_t pinned)
{
    static const char *const files[] = {"cloth_pos.npy", "collider_faces.npy", "collider_pos.npy", "faces.npy",
                                        "meta.json",     "rest_pos.npy",       "stats.npy"};
    mkdir(dir, 0777);
    char src[1200], dst[1200];
    for (size_t i = 0; i < sizeof files / sizeof files[0]; ++i) {
        snprintf(src, sizeof src, "%s/%s", g_seq, files[i]);
        snprintf(dst, sizeof dst, "%s/%s", dir, files[i]);
        unlink(dst);
        if (symlink(src, dst) != 0) {
            return false;
        }
    }
    snprintf(dst, sizeof dst, "%s/pinned.npy", dir);
    FILE *f = fopen(dst, "wb");
    if (!f) {
        return false;
    }
    char header[128];
    int n = snprintf(header, sizeof header, "{'descr': '|u1', 'fortran_order': False, 'shape': (%u, %u), }", frames,
                     vertices);
    while ((n + 10 + 1) % 64 != 0) { /* magic, version and length take 10 bytes; pad so the data is aligned */
        header[n++] = ' ';
    }
    header[n++] = '\n';
    const unsigned char pre[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (unsigned char)(n & 0xff), (unsigned char)(n >> 8)};
    bool ok = fwrite(pre, 1, sizeof pre, f) == sizeof pre && fwrite(header, 1, (size_t)n, f) == (size_t)n;
    for (uint32_t t = 0; ok && t < frames; ++t) {
        for (uint32_t v = 0; ok && v < vertices; ++v) {
            ok = fputc(v < pinned ? 1 : 0, f) != EOF;
        }
    }
    return fclose(f) == 0 && ok;
}

/* Pins reach a --sim-mesh: with the identity map the pinned run scores exactly as without the
 * map, and differently from the unpinned sample (so the pins were applied on both paths). */
static void sim_mesh_keeps_pins(void)
{
    char dir[1100], a[1200], b[1200], c[1200], ja[2048], jb[2048], jc[2048];
    snprintf(dir, sizeof dir, "%s/pinned_seq", g_out);
    CHECK(pinned_copy(dir, 60, 941, 40));
    snprintf(a, sizeof a, "%s/eval_pins_plain.txt", g_out);
    snprintf(b, sizeof b, "%s/eval_pins_map.txt", g_out);
    snprintf(c, sizeof c, "%s/eval_no_pins.txt", g_out);
    const char *plain[] = {g_exe, "eval", "--seq", dir, "--method", "xpbd:5", "--frames", "8", "--pins", "all", "--json", NULL};
    const char *mapped[] = {g_exe,  "eval", "--seq", dir,    "--method", "xpbd:5",     "--frames", "8",
                            "--pins", "all", "--json", "--sim-mesh", dir,    NULL};
    const char *unpinned[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "8", "--pins", "all", "--json", NULL};
    CHECK_EQ_INT(tool_run(plain, a), 0);
    CHECK_EQ_INT(tool_run(mapped, b), 0);
    CHECK_EQ_INT(tool_run(unpinned, c), 0);
    CHECK(json_line(a, ja, sizeof ja));
    CHECK(json_line(b, jb, sizeof jb));
    CHECK(json_line(c, jc, sizeof jc));
    CHECK_MSG(strcmp(ja, jb) == 0, "identity map changed the pinned result:\n%s%s", ja, jb);
    CHECK_MSG(json_number(ja, "mve_cm") != json_number(jc, "mve_cm"), "pins changed nothing:\n%s%s", ja, jc);
}

static void tethers_and_bad_values(void)
{
    char o[1200], j[2048];
    snprintf(o, sizeof o, "%s/eval_tether.txt", g_out);
    const char *tied[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "6", "--tether-cm", "2",
                          "--json", NULL};
    CHECK_EQ_INT(tool_run(tied, o), 0);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(isfinite(json_number(j, "mve_cm")) && isfinite(json_number(j, "ccd_passes")), "%s", j);
    const char *negative[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--tether-cm", "-1", "--json", NULL};
    CHECK_EQ_INT(tool_run(negative, o), 2); /* out of the option's range: refused before anything is scored */
    const char *garbage[] = {g_exe, "eval", "--seq", g_seq, "--tether-cm", "3cm", NULL};
    CHECK_EQ_INT(tool_run(garbage, o), 2);
    const char *missing[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--sim-mesh", g_out, "--json", NULL};
    CHECK_EQ_INT(tool_run(missing, o), 1); /* no rest_pos.npy there */
    /* --frames is a whole number in range, or the command refuses it before scoring anything */
    static const char *const bad_frames[] = {"-1", "0", "abc", "2x", "3.7", "99999999999999999999", " 5", "+5", ""};
    for (size_t k = 0; k < sizeof bad_frames / sizeof bad_frames[0]; ++k) {
        const char *frames[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", bad_frames[k], "--json", NULL};
        CHECK_MSG(tool_run(frames, o) == 2, "--frames '%s' was accepted", bad_frames[k]);
    }
}

static void strain_and_time_limits(void)
{
    char o[1200], j[2048];
    snprintf(o, sizeof o, "%s/eval_strain.txt", g_out);
    const char *limited[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:5", "--frames", "6", "--strain-limit",
                             "10", "--json", NULL};
    CHECK_EQ_INT(tool_run(limited, o), 0);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(isfinite(json_number(j, "mve_cm")) && json_number(j, "overstretched_pct") >= 0.0 &&
                  json_number(j, "gt_max_edge_strain") >= 0.0 && strstr(j, "\"time_limited\": false"),
              "%s", j);
    /* 1 ms of stepping: XPBD on the sample takes longer than that per frame, so the rollout stops
     * after its first frame or two and reports it. */
    snprintf(o, sizeof o, "%s/eval_time.txt", g_out);
    const char *timed[] = {g_exe, "eval", "--seq", g_seq, "--method", "xpbd:40", "--time-limit", "0.001", "--json", NULL};
    CHECK_EQ_INT(tool_run(timed, o), 0);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(strstr(j, "\"time_limited\": true") && json_number(j, "frames") >= 1 && json_number(j, "frames") < 10,
              "%s", j);
    const char *bad_strain[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--strain-limit", "-5", "--json", NULL};
    CHECK_EQ_INT(tool_run(bad_strain, o), 2); /* out of the option's range: refused before anything is scored */
    const char *bad_time[] = {g_exe, "eval", "--seq", g_seq, "--time-limit", "0", NULL};
    CHECK_EQ_INT(tool_run(bad_time, o), 2);
    const char *junk_time[] = {g_exe, "eval", "--seq", g_seq, "--time-limit", "5s", NULL};
    CHECK_EQ_INT(tool_run(junk_time, o), 2);
    const char *bad_pins[] = {g_exe, "eval", "--seq", g_seq, "--pins", "some", NULL};
    CHECK_EQ_INT(tool_run(bad_pins, o), 2);
    const char *all_pins[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", "2", "--pins", "all", NULL};
    CHECK_EQ_INT(tool_run(all_pins, o), 0);
}

/* Payload bytes of an .npy file (file size minus its header); -1 when unreadable. */
static long npy_payload(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return -1;
    }
    unsigned char pre[10];
    long size = -1;
    if (fread(pre, 1, 10, f) == 10 && memcmp(pre, "\x93NUMPY\x01", 7) == 0 && fseek(f, 0, SEEK_END) == 0) {
        size = ftell(f) - 10 - (long)(pre[8] | pre[9] << 8);
    }
    fclose(f);
    return size;
}

/* --write-pos: the two start frames plus one array row per scored frame, float32 [T, V, 3]. */
static void write_pos(void)
{
    char dir[1100], path[1300], rest[1300], o[1100], j[2048];
    snprintf(dir, sizeof dir, "%s/rollouts", g_out);
    snprintf(path, sizeof path, "%s/sample_seq.npy", dir);
    snprintf(rest, sizeof rest, "%s/rest_pos.npy", g_seq);
    snprintf(o, sizeof o, "%s/eval_write.txt", g_out);
    remove(path);
    const char *argv[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--ccd", "off", "--frames", "6",
                          "--write-pos", dir, "--json", NULL};
    CHECK_EQ_INT(tool_run(argv, o), 0);
    CHECK(json_line(o, j, sizeof j));
    long frames = (long)json_number(j, "frames"), vertex_bytes = npy_payload(rest) / 3; /* rest is [V, 3] f32 */
    CHECK_EQ_INT((int)frames, 6);
    CHECK_MSG(vertex_bytes > 0 && npy_payload(path) == (frames + 2) * vertex_bytes * 3,
              "%s holds %ld bytes, expected %ld", path, npy_payload(path), (frames + 2) * vertex_bytes * 3);
    const char *unwritable[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", "2", "--write-pos",
                                "/proc/weft-cannot-write-here", NULL};
    CHECK_EQ_INT(tool_run(unwritable, o), 1);
}

/* The golden model with its out_scale raised to 1e9 (same header length, so the offsets hold):
 * its first step puts the cloth beyond WEFT_MAX_COORDINATE. Returns false when it cannot. */
static bool write_exploding_model(const char *path)
{
    FILE *f = fopen(WEFT_SOURCE_DIR "/tests/model/data/golden_model.safetensors", "rb");
    if (!f) {
        return false;
    }
    fseek(f, 0, SEEK_END);
    const long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *bytes = malloc((size_t)size + 1);
    bool ok = bytes && fread(bytes, 1, (size_t)size, f) == (size_t)size;
    fclose(f);
    char *key = NULL;
    if (ok) {
        bytes[size] = '\0';
        uint64_t n = 0;
        memcpy(&n, bytes, 8);
        const char save = bytes[8 + n];
        bytes[8 + n] = '\0'; /* search the header only */
        key = strstr(bytes + 8, "out_scale\\\": ");
        bytes[8 + n] = save;
    }
    if (key) {
        char *v = key + strlen("out_scale\\\": "), *end = v;
        while ((*end >= '0' && *end <= '9') || *end == '.' || *end == 'e' || *end == '-' || *end == '+') {
            ++end;
        }
        ok = end - v >= 3;
        if (ok) {
            memset(v, ' ', (size_t)(end - v));
            memcpy(v, "1e9", 3);
        }
    }
    ok = ok && key;
    FILE *o = ok ? fopen(path, "wb") : NULL;
    ok = o && fwrite(bytes, 1, (size_t)size, o) == (size_t)size;
    if (o) {
        fclose(o);
    }
    free(bytes);
    return ok;
}

/* A rollout that fails is never a score: exit 1, MVE null, "failed": true. A model of another
 * architecture is refused from its header. */
static void failed_rollout_is_not_scored(void)
{
    char model[1100], o[1100], e[1100], j[2048], text[4096];
    snprintf(model, sizeof model, "%s/exploding.safetensors", g_out);
    snprintf(o, sizeof o, "%s/eval_failed.txt", g_out);
    snprintf(e, sizeof e, "%s/eval_failed.err", g_out);
    CHECK(write_exploding_model(model));
    const char *argv[] = {g_exe, "eval", "--seq", g_seq, "--model", model, "--frames", "5", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(argv, o, e), 1);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(strstr(j, "\"mve_cm\": null") && strstr(j, "\"failed\": true"), "%s", j);
    tool_slurp(e, text, sizeof text);
    CHECK_MSG(strstr(text, "it is not scored") != NULL, "%s", text);
    const char *fnopt[] = {g_exe, "eval", "--seq", g_seq, "--model",
                           WEFT_SOURCE_DIR "/tools/fnopt/models/fnopt_32.safetensors", "--frames", "5", NULL};
    CHECK_EQ_INT(tool_run_err(fnopt, o, e), 1);
    tool_slurp(e, text, sizeof text);
    CHECK_MSG(strstr(text, "architecture 'fnopt', not 'clothtransformer'") != NULL, "%s", text);
}

/* A worn garment made here by simgen on a library clip (the T-shirt, 12 frames), once: its folder
 * into seq; false when simgen failed. */
static bool worn_sequence(char *seq, size_t cap)
{
    char dir[1100], o[1100], e[1100], clip[1100], meta[1400];
    snprintf(dir, sizeof dir, "%s/worn", g_out);
    snprintf(seq, cap, "%s/mocap_walk_cmu07_01_v300_00000", dir);
    snprintf(meta, sizeof meta, "%s/meta.json", seq);
    struct stat st;
    if (stat(meta, &st) == 0) {
        return true;
    }
    snprintf(o, sizeof o, "%s/simgen_worn.txt", g_out);
    snprintf(e, sizeof e, "%s/simgen_worn.err", g_out);
    snprintf(clip, sizeof clip, "%s/samples/mocap/clips/walk_cmu07_01.bvh.gz", WEFT_SOURCE_DIR);
    const char *gen[] = {g_exe, "simgen", "--out", dir, "--bvh", clip, "--vertices", "300", "--frames", "12",
                         "--limit", "1", "--no-validate", NULL};
    return tool_run_err(gen, o, e) == 0;
}

/* Wear measures: the worn garment reports them, with step-time percentiles; the drop sample
 * reports "wear": null. */
static void wear_measures(void)
{
    char o[1100], e[1100], j[4096], seq[1300];
    snprintf(o, sizeof o, "%s/eval_wear.txt", g_out);
    snprintf(e, sizeof e, "%s/eval_wear.err", g_out);
    CHECK(worn_sequence(seq, sizeof seq));
    const char *lbs[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(lbs, o, e), 0);
    tool_slurp(o, j, sizeof j); /* the raw line: its timings are read below */
    CHECK_MSG(strstr(j, "\"wear\": {\"sequences\": 1, \"garments_lost\": 0") != NULL, "%s", j);
    const double inside = json_number(j, "inside_body_mean"), p50 = json_number(j, "ms_p50"),
                 p99 = json_number(j, "ms_p99"), mx = json_number(j, "ms_max");
    CHECK_MSG(inside >= 0.0 && inside <= 1.0, "%s", j);
    CHECK_MSG(p50 > 0.0 && p50 <= p99 && p99 <= mx, "%s", j);
    const char *text_run[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", NULL};
    CHECK_EQ_INT(tool_run_err(text_run, o, e), 0);
    char text[8192];
    tool_slurp(o, text, sizeof text);
    CHECK_MSG(strstr(text, "garment kept") && strstr(text, "worn: 0 of 1 garments lost"), "%s", text);
    const char *drop[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", "5", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(drop, o, e), 0);
    CHECK(json_line(o, j, sizeof j));
    CHECK_MSG(strstr(j, "\"wear\": null") != NULL, "%s", j);
}

/* --recipe worn: on the worn garment, LBS scores exactly as with the recipe's settings passed one
 * by one (max distance 8 cm for a T-shirt, 0.5 cm push from 6 cm deep, CCD off), the learned model
 * sees at most the recipe's 1024 sampled collider tokens (more without it); on the drop sample,
 * which is not worn, it changes nothing; an option it sets, or another recipe, is refused. */
static void worn_recipe(void)
{
    char o[1100], e[1100], seq[1300], ja[4096], jb[4096], model[1200];
    snprintf(o, sizeof o, "%s/eval_recipe.txt", g_out);
    snprintf(e, sizeof e, "%s/eval_recipe.err", g_out);
    CHECK(worn_sequence(seq, sizeof seq));
    const char *recipe[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--recipe", "worn", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(recipe, o, e), 0);
    CHECK(json_line(o, ja, sizeof ja));
    const char *spelled[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--ccd", "off", "--tether-cm", "8",
                             "--push-cm", "0.5", "--push-depth-cm", "6", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(spelled, o, e), 0);
    CHECK(json_line(o, jb, sizeof jb));
    CHECK_MSG(strcmp(ja, jb) == 0, "recipe: %s\nspelled out: %s", ja, jb);
    const char *none[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--recipe", "none", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(none, o, e), 0);
    CHECK(json_line(o, jb, sizeof jb));
    CHECK_MSG(strcmp(ja, jb) != 0, "the recipe changed nothing: %s", ja);

    snprintf(model, sizeof model, "%s/tools/train/models/garment.int8.safetensors", WEFT_SOURCE_DIR);
    const char *learned[] = {g_exe, "eval", "--seq", seq, "--method", "model", "--model", model, "--precision", "int8",
                             "--frames", "4", "--recipe", "worn", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(learned, o, e), 0);
    CHECK(json_line(o, ja, sizeof ja));
    const char *whole[] = {g_exe, "eval", "--seq", seq, "--method", "model", "--model", model, "--precision", "int8",
                           "--frames", "4", "--ccd", "off", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(whole, o, e), 0);
    CHECK(json_line(o, jb, sizeof jb));
    const double tokens = json_number(ja, "collider_tokens"), all = json_number(jb, "collider_tokens");
    CHECK_MSG(tokens > 0.0 && tokens <= 1024.0 && all > tokens, "tokens %g with the recipe, %g without", tokens, all);

    const char *drop_recipe[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", "5", "--recipe", "worn",
                                 "--json", NULL};
    CHECK_EQ_INT(tool_run_err(drop_recipe, o, e), 0);
    CHECK(json_line(o, ja, sizeof ja));
    const char *drop[] = {g_exe, "eval", "--seq", g_seq, "--method", "lbs", "--frames", "5", "--json", NULL};
    CHECK_EQ_INT(tool_run_err(drop, o, e), 0);
    CHECK(json_line(o, jb, sizeof jb));
    CHECK_MSG(strcmp(ja, jb) == 0, "recipe on a drop: %s\nplain: %s", ja, jb);

    const char *both[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--recipe", "worn", "--push-cm", "1", NULL};
    CHECK_EQ_INT(tool_run_err(both, o, e), 2);
    const char *unknown[] = {g_exe, "eval", "--seq", seq, "--method", "lbs", "--recipe", "game", NULL};
    CHECK_EQ_INT(tool_run_err(unknown, o, e), 2);
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s WEFT DATA OUT\n", argv[0]);
        return 1;
    }
    g_exe = argv[1];
    g_out = argv[3];
    static char seq[1024];
    snprintf(seq, sizeof seq, "%s/sample_seq", argv[2]);
    g_seq = seq;
    char meta[1100];
    struct stat st;
    snprintf(meta, sizeof meta, "%s/meta.json", seq);
    if (stat(meta, &st) != 0) {
        printf("no sample sequence at %s: skipped\n", meta);
        return 77;
    }
    mkdir(g_out, 0777);
    static const test_case_ cases[] = {TEST_CASE(sim_mesh_identity), TEST_CASE(sim_mesh_keeps_pins),
                                       TEST_CASE(tethers_and_bad_values),
                                       TEST_CASE(strain_and_time_limits), TEST_CASE(write_pos),
                                       TEST_CASE(failed_rollout_is_not_scored), TEST_CASE(wear_measures),
                                       TEST_CASE(worn_recipe)};
    return test_run_(cases, sizeof cases / sizeof cases[0], 1, argv);
}
