#define _POSIX_C_SOURCE 200809L /* mkdtemp */
/* Calibration, per-layer decisions, SmoothQuant and the end-to-end check, on the shipped game
 * model and the committed sample sequence (tests/data/sample_seq); bad calibration input writes
 * nothing. */
#include "test.h"
#include "quant.h"
#include "io/safetensors.h"
#include "model/model.h"
#include "assets/npz.h"

#include <sys/stat.h>

#include <unistd.h>

#define SAMPLE WEFT_SOURCE_DIR "/tests/data/sample_seq"
#define GAME WEFT_SOURCE_DIR "/tools/train/models/game.safetensors"

/* The tests calibrate and validate on the first SHORT_T frames of the sample sequence (a copy
 * in a temporary folder): rollouts to the end of the full sequence would dominate the run time
 * under the sanitizers without testing anything more. */
#define SHORT_T 10u

static weft_context *g_ctx;
static void *g_model;
static size_t g_model_size;
static char g_tmp[] = "/tmp/weft-qshort-XXXXXX";
static char g_short[64];

static void *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *b = malloc(n > 0 ? (size_t)n : 1);
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return b;
}

static bool make_short_sample(void);
static void remove_sample(const char *dir);

static void cleanup(void)
{
    if (g_short[0]) {
        remove_sample(g_short);
        rmdir(g_tmp);
    }
    free(g_model);
    weft_context_destroy(g_ctx);
}

static bool setup(void)
{
    static bool ok;
    if (!g_ctx) {
        weft_context_def def = weft_default_context_def();
        CHECK_RESULT(weft_context_create(&def, &g_ctx), WEFT_OK);
        g_model = slurp(GAME, &g_model_size);
        CHECK_MSG(g_model != NULL, "cannot read %s", GAME);
        atexit(cleanup);
        ok = g_ctx && g_model && make_short_sample();
        CHECK_MSG(ok, "cannot make a short copy of %s", SAMPLE);
    }
    return ok;
}

/* A minimal .npy (v1.0, little-endian float32 or int64, C order). */
static bool write_npy(const char *path, const char *descr, const uint64_t *shape, int ndim, const void *data,
                      size_t bytes)
{
    char dict[256];
    int n = snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': (", descr);
    for (int i = 0; i < ndim; ++i) {
        n += snprintf(dict + n, sizeof dict - (size_t)n, "%llu,%s", (unsigned long long)shape[i],
                      i + 1 < ndim ? " " : "");
    }
    n += snprintf(dict + n, sizeof dict - (size_t)n, "), }");
    size_t total = 10 + (size_t)n + 1;
    size_t pad = (64 - total % 64) % 64;
    uint16_t hlen = (uint16_t)((size_t)n + pad + 1);
    FILE *f = fopen(path, "wb");
    if (!f) {
        return false;
    }
    fwrite("\x93NUMPY\x01\x00", 1, 8, f);
    unsigned char hl[2] = {(unsigned char)(hlen & 0xff), (unsigned char)(hlen >> 8)};
    fwrite(hl, 1, 2, f);
    fwrite(dict, 1, (size_t)n, f);
    for (size_t i = 0; i < pad; ++i) {
        fputc(' ', f);
    }
    fputc('\n', f);
    fwrite(data, 1, bytes, f);
    return fclose(f) == 0;
}

static void copy_file(const char *from, const char *to)
{
    size_t n = 0;
    void *b = slurp(from, &n);
    FILE *f = b ? fopen(to, "wb") : NULL;
    CHECK_MSG(f != NULL, "copy %s -> %s", from, to);
    if (f) {
        fwrite(b, 1, n, f);
        fclose(f);
    }
    free(b);
}

static const char *const k_seq_files[] = {"meta.json", "rest_pos.npy", "faces.npy", "cloth_pos.npy",
                                           "collider_pos.npy", "collider_faces.npy"};

/* dir: a copy of the sample sequence. */
static void copy_sample(const char *dir)
{
    CHECK(mkdir(dir, 0700) == 0);
    for (size_t i = 0; i < sizeof k_seq_files / sizeof *k_seq_files; ++i) {
        char a[512], b[512];
        snprintf(a, sizeof a, "%s/%s", g_short, k_seq_files[i]);
        snprintf(b, sizeof b, "%s/%s", dir, k_seq_files[i]);
        copy_file(a, b);
    }
}

static void remove_sample(const char *dir)
{
    for (size_t i = 0; i < sizeof k_seq_files / sizeof *k_seq_files; ++i) {
        char b[512];
        snprintf(b, sizeof b, "%s/%s", dir, k_seq_files[i]);
        remove(b);
    }
    rmdir(dir);
}

/* dir/name.npy as floats (or uint32 indices), with its shape. */
static void *load_npy(const char *dir, const char *name, bool index, uint64_t shape[3])
{
    char p[512];
    snprintf(p, sizeof p, "%s/%s.npy", dir, name);
    size_t sz = 0;
    void *b = slurp(p, &sz);
    weft_npy_array a;
    void *out = NULL;
    if (b && weft_npy_parse(b, sz, name, &a) == WEFT_OK && a.ndim <= 3) {
        for (uint32_t i = 0; i < a.ndim; ++i) {
            shape[i] = a.shape[i];
        }
        if (index) {
            int64_t *t = malloc(a.count * sizeof(int64_t));
            uint32_t *u = malloc(a.count * sizeof(uint32_t));
            if (t && u && weft_npy_to_i64(&a, t, a.count) == WEFT_OK) {
                for (uint64_t i = 0; i < a.count; ++i) {
                    u[i] = (uint32_t)t[i];
                }
                out = u;
                u = NULL;
            }
            free(t);
            free(u);
        } else {
            float *f = malloc(a.count * sizeof(float));
            if (f && weft_npy_to_f32(&a, f, a.count) == WEFT_OK) {
                out = f;
            } else {
                free(f);
            }
        }
    }
    free(b);
    return out;
}

/* Pins for rollout(): [T, V] bytes, non-zero = that vertex follows the sequence in that frame. */
static const uint8_t *g_pins;

/* The rollout MVE (cm) the way a game runs the file: the weft_garment API only, started from the
 * first two frames, CCD off, with g_pins set each frame as `weft eval --pins all` sets them.
 * Optionally the positions after every frame (frames * V * 3). */
static double rollout(const void *bytes, size_t size, weft_precision prec, uint32_t frames, float *trace)
{
    uint64_t sr[3] = {0}, sf[3] = {0}, sp[3] = {0}, sc[3] = {0}, scf[3] = {0};
    float *rest = load_npy(g_short, "rest_pos", false, sr), *pos = load_npy(g_short, "cloth_pos", false, sp);
    float *cpos = load_npy(g_short, "collider_pos", false, sc);
    uint32_t *faces = load_npy(g_short, "faces", true, sf), *cfaces = load_npy(g_short, "collider_faces", true, scf);
    weft_model *m = NULL;
    double mve = -1;
    const uint32_t V = (uint32_t)sr[0], Vc = (uint32_t)sc[1], T = (uint32_t)sp[0];
    if (rest && pos && cpos && faces && cfaces && weft_model_load_memory(g_ctx, bytes, size, &m) == WEFT_OK) {
        weft_garment_def gd = weft_default_garment_def();
        gd.method = WEFT_METHOD_MODEL;
        gd.model = m;
        gd.precision = prec;
        gd.ccd.enabled = false;
        gd.rest_positions = rest;
        gd.vertex_count = V;
        gd.triangles = faces;
        gd.triangle_count = (uint32_t)sf[0];
        gd.collider_rest_positions = cpos + (size_t)Vc * 3;
        gd.collider_vertex_count = Vc;
        gd.collider_triangles = cfaces;
        gd.collider_triangle_count = (uint32_t)scf[0];
        gd.initial_positions = pos + (size_t)V * 3;
        weft_garment *g = NULL;
        if (weft_garment_create(g_ctx, &gd, &g) == WEFT_OK &&
            weft_garment_set_state(g, pos + (size_t)V * 3, pos) == WEFT_OK) {
            double err = 0;
            uint32_t done = 0;
            for (uint32_t t = 1; t + 1 < T && done < frames; ++t) {
                if (weft_garment_set_collider(g, cpos + (size_t)(t + 1) * Vc * 3) != WEFT_OK) {
                    break;
                }
                uint32_t idx[8], n = 0;
                float to[8 * 3];
                for (uint32_t v = 0; g_pins && v < V && n < 8; ++v) {
                    if (g_pins[(size_t)(t + 1) * V + v]) {
                        idx[n] = v;
                        memcpy(to + 3 * n, pos + ((size_t)(t + 1) * V + v) * 3, 3 * sizeof(float));
                        n++;
                    }
                }
                if (weft_garment_set_pins(g, idx, to, n) != WEFT_OK || weft_garment_step(g) != WEFT_OK) {
                    break;
                }
                const float *x = weft_garment_positions(g), *gt = pos + (size_t)(t + 1) * V * 3;
                if (trace) {
                    memcpy(trace + (size_t)done * V * 3, x, (size_t)V * 3 * sizeof(float));
                }
                for (uint32_t i = 0; i < V; ++i) {
                    double dx = (double)x[3 * i] - gt[3 * i], dy = (double)x[3 * i + 1] - gt[3 * i + 1],
                           dz = (double)x[3 * i + 2] - gt[3 * i + 2];
                    err += sqrt(dx * dx + dy * dy + dz * dz);
                }
                done++;
            }
            mve = done == frames ? err / ((double)done * V) * 100.0 : -1;
        }
        weft_garment_destroy(g);
    }
    weft_model_destroy(m);
    free(rest);
    free(pos);
    free(cpos);
    free(faces);
    free(cfaces);
    return mve;
}

static uint32_t sample_vertices(void)
{
    uint64_t s[3] = {0};
    float *r = load_npy(SAMPLE, "rest_pos", false, s);
    free(r);
    return (uint32_t)s[0];
}

static bool make_short_sample(void)
{
    if (!mkdtemp(g_tmp)) {
        return false;
    }
    snprintf(g_short, sizeof g_short, "%s/sample", g_tmp);
    if (mkdir(g_short, 0700) != 0) {
        return false;
    }
    static const char *const copied[4] = {"meta.json", "rest_pos.npy", "faces.npy", "collider_faces.npy"};
    for (int i = 0; i < 4; ++i) {
        char a[512], b[512];
        snprintf(a, sizeof a, "%s/%s", SAMPLE, copied[i]);
        snprintf(b, sizeof b, "%s/%s", g_short, copied[i]);
        copy_file(a, b);
    }
    bool ok = true;
    static const char *const cut[2] = {"cloth_pos", "collider_pos"};
    for (int i = 0; i < 2 && ok; ++i) {
        uint64_t shape[3] = {0};
        float *a = load_npy(SAMPLE, cut[i], false, shape);
        char b[512];
        snprintf(b, sizeof b, "%s/%s.npy", g_short, cut[i]);
        ok = a && shape[0] >= SHORT_T;
        shape[0] = SHORT_T;
        ok = ok && write_npy(b, "<f4", shape, 3, a, (size_t)SHORT_T * shape[1] * 3 * sizeof(float));
        free(a);
    }
    return ok;
}

static const char *const k_calib[] = {g_short, NULL};

/* Calibrated int8: every layer measured, decisions follow the rule and reach the file, and the
 * end-to-end figures match a rollout of the written file through the public API. */
static void test_calibrated_int8(void)
{
    if (!setup()) {
        return;
    }
    weft_quant_def def = weft_default_quant_def();
    def.calib = k_calib;
    def.calib_frames = 4;
    def.val = g_short;
    def.val_frames = 8;
    void *out = NULL;
    size_t out_size = 0;
    weft_quant_report rep;
    weft_result r = weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, &rep);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    CHECK_EQ_INT(rep.calib_sequences, 1);
    CHECK_EQ_INT(rep.calib_frames, 4);
    weft_model *src = NULL, *m = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, g_model, g_model_size, &src), WEFT_OK);
    CHECK_RESULT(weft_model_load_memory(g_ctx, out, out_size, &m), WEFT_OK);
    uint32_t layers = 0, int8 = 0;
    for (uint32_t i = 0; src && i < src->tensor_count; ++i) {
        const weft_tensor *t = &src->tensors[i];
        size_t n = strlen(t->name);
        layers += t->rank == 2 && n > 7 && strcmp(t->name + n - 7, ".weight") == 0;
    }
    CHECK_EQ_INT(rep.layer_count, layers);
    for (uint32_t i = 0; i < rep.layer_count && m; ++i) {
        const weft_quant_layer_report *L = &rep.layers[i];
        const bool tiny = L->out < 16 || L->in < 16;
        CHECK_MSG(L->rows > 0, "%s never observed", L->name);
        CHECK_MSG(L->absmax > 0 && L->p999 > 0 && L->p999 <= L->absmax, "%s: absmax %g p999 %g", L->name, L->absmax,
                  L->p999);
        float cmax = 0;
        for (uint32_t k = 0; L->channel_absmax && k < L->in; ++k) {
            cmax = fmaxf(cmax, L->channel_absmax[k]);
        }
        CHECK_MSG((double)cmax == L->absmax, "%s: channel max %g vs tensor %g", L->name, (double)cmax, L->absmax);
        CHECK(strcmp(L->smooth, "off") == 0);
        char key[200];
        snprintf(key, sizeof key, "quant.layer.%s", L->name);
        const char *stored = weft__model_metadata(m, key);
        CHECK_MSG(stored && strcmp(stored, L->decision) == 0, "%s: metadata '%s', report '%s'", key,
                  stored ? stored : "(none)", L->decision);
        if (tiny) {
            CHECK_MSG(strcmp(L->decision, "fp32:tiny") == 0 && L->act_error < 0, "%s: %s", L->name, L->decision);
            continue;
        }
        CHECK_MSG(L->act_error > 0 && L->act_error < 0.5 && L->act_error == L->act_error_plain, "%s: act error %g",
                  L->name, L->act_error);
        CHECK_MSG(L->weight_error > 0 && L->weight_error < 0.02, "%s: weight error %g", L->name, L->weight_error);
        char wname[200];
        snprintf(wname, sizeof wname, "%s.weight.q8", L->name);
        if (L->act_error > def.max_layer_error) {
            CHECK_MSG(strncmp(L->decision, "fp32:error=", 11) == 0, "%s: %s", L->name, L->decision);
            CHECK(weft__model_find(m, wname) == NULL);
        } else {
            CHECK_MSG(strcmp(L->decision, "int8") == 0, "%s: %s", L->name, L->decision);
            CHECK(weft__model_find(m, wname) != NULL);
            int8++;
        }
    }
    CHECK(int8 > 0);
    const char *qm = m ? weft__model_metadata(m, "quantization") : NULL;
    CHECK(qm && strstr(qm, "\"calibration\"") && strstr(qm, "\"frames\":4"));
    /* end to end: the report's figures are those of the written file run as a game would */
    CHECK(rep.e2e.measured);
    CHECK_EQ_INT(rep.e2e.frames, 8);
    double fp = rollout(g_model, g_model_size, WEFT_PRECISION_FP32, 8, NULL);
    double q = rollout(out, out_size, WEFT_PRECISION_INT8, 8, NULL);
    CHECK_NEAR(rep.e2e.mve_fp32_cm, fp, 1e-9);
    CHECK_NEAR(rep.e2e.mve_quant_cm, q, 1e-9);
    CHECK_NEAR(rep.e2e.ratio, q / fp, 1e-12);
    CHECK_MSG(rep.e2e.ratio > 0.9 && rep.e2e.ratio < 1.1, "int8 / fp32 MVE %g", rep.e2e.ratio);
    weft_model_destroy(m);
    weft_model_destroy(src);
    weft_quant_report_free(&rep);
    weft_quant_buffer_free(g_ctx, out, out_size);
}

/* A sequence's pinned.npy reaches calibration and the error report: the report's fp32 rollout is
 * the one with those vertices pinned every frame (`weft eval --pins all`), not the free one; pins
 * of the wrong shape are refused, naming the file. */
static void test_pins(void)
{
    if (!setup()) {
        return;
    }
    char dir[] = "/tmp/weft-qpin-XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char seq[300], path[400];
    snprintf(seq, sizeof seq, "%s/seq", dir);
    copy_sample(seq);
    const uint32_t V = sample_vertices();
    uint8_t *mask = calloc((size_t)SHORT_T * (V + 1), 1);
    for (uint32_t t = 2; mask && t < SHORT_T; ++t) {
        for (uint32_t v = 0; v < 5; ++v) {
            mask[(size_t)t * V + v * 7] = 1; /* five vertices held from frame 2 on */
        }
    }
    snprintf(path, sizeof path, "%s/pinned.npy", seq);
    uint64_t shape[2] = {SHORT_T, V};
    CHECK(mask && write_npy(path, "|u1", shape, 2, mask, (size_t)SHORT_T * V));
    const char *calib[2] = {seq, NULL};
    weft_quant_def def = weft_default_quant_def();
    def.calib = calib;
    def.calib_frames = 4;
    def.val = seq;
    def.val_frames = 8;
    void *out = NULL;
    size_t out_size = 0;
    weft_quant_report rep;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, &rep), WEFT_OK);
    if (out) {
        g_pins = mask;
        const double pinned = rollout(g_model, g_model_size, WEFT_PRECISION_FP32, 8, NULL),
                     pinned_q = rollout(out, out_size, WEFT_PRECISION_INT8, 8, NULL);
        g_pins = NULL;
        const double free_fp = rollout(g_model, g_model_size, WEFT_PRECISION_FP32, 8, NULL);
        CHECK(rep.e2e.measured);
        CHECK_NEAR(rep.e2e.mve_fp32_cm, pinned, 1e-9);
        CHECK_NEAR(rep.e2e.mve_quant_cm, pinned_q, 1e-9);
        CHECK_MSG(fabs(pinned - free_fp) > 1e-4, "pins change nothing: %g cm pinned, %g free", pinned, free_fp);
        weft_quant_report_free(&rep);
        weft_quant_buffer_free(g_ctx, out, out_size);
    }
    /* one vertex too many per frame: refused, nothing written */
    shape[1] = V + 1;
    CHECK(mask && write_npy(path, "|u1", shape, 2, mask, (size_t)SHORT_T * (V + 1)));
    out = NULL;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, &rep),
                 WEFT_ERROR_SIZE_MISMATCH);
    CHECK_MSG(strstr(weft_last_error(), "pinned.npy") != NULL, "message: %s", weft_last_error());
    CHECK(out == NULL);
    remove(path);
    remove_sample(seq);
    rmdir(dir);
    free(mask);
}

/* A threshold below every measured error keeps every eligible layer in fp32, with its reason. */
static void test_error_threshold(void)
{
    if (!setup()) {
        return;
    }
    weft_quant_def def = weft_default_quant_def();
    def.calib = k_calib;
    def.calib_frames = 2;
    def.max_layer_error = 1e-9;
    def.format = WEFT_QUANT_FP16;
    void *out = NULL;
    size_t out_size = 0;
    weft_quant_report rep;
    weft_result r = weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, &rep);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    CHECK_EQ_INT(rep.quantized_count, 0);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, out, out_size, &m), WEFT_OK);
    for (uint32_t i = 0; i < rep.layer_count && m; ++i) {
        const weft_quant_layer_report *L = &rep.layers[i];
        if (L->out < 16 || L->in < 16) {
            continue;
        }
        /* fp16 weights with fp32 activations: small but measurable error */
        CHECK_MSG(L->act_error > 0 && L->act_error < 1e-2, "%s: fp16 act error %g", L->name, L->act_error);
        char want[48], wname[200];
        snprintf(want, sizeof want, "fp32:error=%.3g", L->act_error);
        CHECK_MSG(strcmp(L->decision, want) == 0, "%s: %s vs %s", L->name, L->decision, want);
        snprintf(wname, sizeof wname, "%s.weight", L->name);
        const weft_tensor *t = weft__model_find(m, wname);
        CHECK(t && t->dtype == WEFT_DTYPE_F32);
    }
    weft_model_destroy(m);
    /* The runtime honours the decisions: with every layer kept in fp32, the fp16 path computes
     * what the fp32 path computes, bit for bit. */
    const uint32_t V = sample_vertices(), frames = 4;
    float *a = malloc((size_t)frames * V * 3 * sizeof(float)), *b = malloc((size_t)frames * V * 3 * sizeof(float));
    if (a && b) {
        double m32 = rollout(g_model, g_model_size, WEFT_PRECISION_FP32, frames, a);
        double m16 = rollout(out, out_size, WEFT_PRECISION_FP16, frames, b);
        CHECK(m32 >= 0 && m16 >= 0);
        CHECK_MSG(memcmp(a, b, (size_t)frames * V * 3 * sizeof(float)) == 0, "fp16 rollout of the all-fp32 file "
                  "differs from fp32 (MVE %g vs %g cm)", m16, m32);
    }
    free(a);
    free(b);
    weft_quant_report_free(&rep);
    weft_quant_buffer_free(g_ctx, out, out_size);
}

/* SmoothQuant: the migrated fp32 model computes the same rollout; only LayerNorm-fed layers and
 * their norms change; the quantiser keeps a migration only where it lowers the error. */
static void test_smoothquant(void)
{
    if (!setup()) {
        return;
    }
    weft_quant_def def = weft_default_quant_def();
    def.calib = k_calib;
    def.calib_frames = 3;
    def.smoothquant_alpha = 0.5f;
    void *sm = NULL;
    size_t sm_size = 0;
    weft_result r = weft_quant_smooth_memory(g_ctx, &def, g_model, g_model_size, &sm, &sm_size);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    weft_model *a = NULL, *b = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, g_model, g_model_size, &a), WEFT_OK);
    CHECK_RESULT(weft_model_load_memory(g_ctx, sm, sm_size, &b), WEFT_OK);
    if (a && b) {
        const char *info = weft__model_metadata(b, "smoothquant");
        CHECK(info && strstr(info, "\"tmp.0.ln1\"") && !strstr(info, "dec_ln"));
        /* a migrated norm and layer differ; a layer fed by GELU is untouched */
        const weft_tensor *g0 = weft__model_find(a, "tmp.0.ln1.weight"), *g1 = weft__model_find(b, "tmp.0.ln1.weight");
        const weft_tensor *q0 = weft__model_find(a, "tmp.0.q.weight"), *q1 = weft__model_find(b, "tmp.0.q.weight");
        const weft_tensor *f0 = weft__model_find(a, "enc_cloth.fc2.weight"),
                          *f1 = weft__model_find(b, "enc_cloth.fc2.weight");
        CHECK(g0 && g1 && memcmp(g0->data, g1->data, g0->bytes) != 0);
        CHECK(q0 && q1 && memcmp(q0->data, q1->data, q0->bytes) != 0);
        CHECK(f0 && f1 && memcmp(f0->data, f1->data, f0->bytes) == 0);
        /* per channel: g' w' = g w (the product the layer sees) up to rounding */
        if (g0 && g1 && q0 && q1) {
            const float *ga = g0->data, *gb = g1->data, *wa = q0->data, *wb = q1->data;
            const uint32_t K = (uint32_t)q0->shape[1];
            double worst = 0;
            for (uint32_t j = 0; j < K; ++j) {
                double pa = (double)ga[j] * wa[j], pb = (double)gb[j] * wb[j];
                worst = fmax(worst, fabs(pa - pb) / fmax(fabs(pa), 1e-12));
            }
            CHECK_MSG(worst < 1e-6, "g*w changed by %g relative", worst);
        }
    }
    weft_model_destroy(a);
    weft_model_destroy(b);
    /* the same function: fp32 rollouts of both files agree to fp32 rounding */
    const uint32_t V = sample_vertices(), frames = SHORT_T - 2;
    float *ta = malloc((size_t)frames * V * 3 * sizeof(float)), *tb = malloc((size_t)frames * V * 3 * sizeof(float));
    if (ta && tb) {
        double ma = rollout(g_model, g_model_size, WEFT_PRECISION_FP32, frames, ta);
        double mb = rollout(sm, sm_size, WEFT_PRECISION_FP32, frames, tb);
        CHECK(ma > 0 && mb > 0);
        double worst = 0;
        for (size_t i = 0; i < (size_t)frames * V * 3; ++i) {
            worst = fmax(worst, fabs((double)ta[i] - tb[i]));
        }
        CHECK_MSG(worst < 1e-5, "migrated fp32 model moves a vertex by %g m within %u frames", worst, frames);
    }
    free(ta);
    free(tb);
    weft_quant_buffer_free(g_ctx, sm, sm_size);

    /* through the quantiser: every layer says what happened to it */
    void *out = NULL;
    size_t out_size = 0;
    weft_quant_report rep;
    r = weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, &rep);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    uint32_t applied = 0;
    for (uint32_t i = 0; i < rep.layer_count; ++i) {
        const weft_quant_layer_report *L = &rep.layers[i];
        if (strncmp(L->smooth, "applied", 7) == 0) {
            applied++;
            CHECK_MSG(L->act_error >= 0 && L->act_error_plain >= 0, "%s", L->name);
        } else if (strncmp(L->smooth, "reverted", 8) == 0) {
            CHECK_MSG(L->act_error == L->act_error_plain, "%s: reverted but %g vs %g", L->name, L->act_error,
                      L->act_error_plain);
        } else {
            CHECK_MSG(strncmp(L->smooth, "skipped: ", 9) == 0, "%s: '%s'", L->name, L->smooth);
            CHECK(L->act_error == L->act_error_plain);
        }
        if (strcmp(L->name, "enc_cloth.fc2") == 0) {
            CHECK(strcmp(L->smooth, "skipped: the input is not a LayerNorm output") == 0);
        }
        if (strcmp(L->name, "tmp.0.q") == 0 || strcmp(L->name, "tmp.1.up") == 0) {
            CHECK_MSG(strncmp(L->smooth, "applied", 7) == 0 || strncmp(L->smooth, "reverted", 8) == 0, "%s: %s",
                      L->name, L->smooth);
        }
        if (strcmp(L->name, "dec_head") == 0) {
            CHECK_MSG(strstr(L->smooth, "stays fp32") != NULL, "dec_head: %s", L->smooth);
        }
    }
    const char *qm = NULL;
    weft_model *qmod = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, out, out_size, &qmod), WEFT_OK);
    qm = qmod ? weft__model_metadata(qmod, "quantization") : NULL;
    CHECK(qm && strstr(qm, "\"smoothquant_alpha\":0.5"));
    /* the file lists exactly the norms whose layers report "applied" */
    CHECK(qm && (applied > 0) == (strstr(qm, "\"smoothed_norms\":[]") == NULL));
    weft_model_destroy(qmod);
    weft_quant_report_free(&rep);
    weft_quant_buffer_free(g_ctx, out, out_size);
}

/* Missing or malformed calibration data, bad options: a clear error and nothing written. */
static void test_bad_calibration(void)
{
    if (!setup()) {
        return;
    }
    char dir[] = "/tmp/weft-qcal-XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char seq[300], out_path[300], in_path[300], path[400];
    snprintf(seq, sizeof seq, "%s/seq", dir);
    snprintf(out_path, sizeof out_path, "%s/out.safetensors", dir);
    snprintf(in_path, sizeof in_path, "%s/in.safetensors", dir);
    FILE *f = fopen(in_path, "wb");
    CHECK(f != NULL);
    if (f) {
        fwrite(g_model, 1, g_model_size, f);
        fclose(f);
    }
    const char *calib[2] = {seq, NULL};
    weft_quant_def def = weft_default_quant_def();
    def.calib = calib;
    def.calib_frames = 2;
    void *out = NULL;
    size_t out_size = 0;

    /* missing folder */
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_IO);
    CHECK(strstr(weft_last_error(), "does not exist") != NULL);
    CHECK(access(out_path, F_OK) != 0);

    /* a folder without sequences */
    CHECK(mkdir(seq, 0700) == 0);
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "no sequences") != NULL);
    rmdir(seq);

    /* malformed meta.json */
    copy_sample(seq);
    snprintf(path, sizeof path, "%s/meta.json", seq);
    f = fopen(path, "wb");
    if (f) {
        fputs("{\"frames\": 60", f);
        fclose(f);
    }
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "meta.json") != NULL);
    CHECK(access(out_path, F_OK) != 0);
    copy_file(SAMPLE "/meta.json", path);

    /* NaN in the positions */
    const uint32_t V = sample_vertices();
    uint64_t shape[3] = {4, V, 3};
    float *pos = calloc((size_t)4 * V * 3, sizeof(float));
    if (pos) {
        pos[7] = NAN;
        snprintf(path, sizeof path, "%s/cloth_pos.npy", seq);
        CHECK(write_npy(path, "<f4", shape, 3, pos, (size_t)4 * V * 3 * sizeof(float)));
        CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                     WEFT_ERROR_NOT_FINITE);
        CHECK(out == NULL);
        /* wrong vertex count */
        pos[7] = 0.0f;
        shape[1] = V - 1;
        CHECK(write_npy(path, "<f4", shape, 3, pos, (size_t)4 * (V - 1) * 3 * sizeof(float)));
        CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                     WEFT_ERROR_SIZE_MISMATCH);
        /* wrong layout */
        uint64_t flat[2] = {4, (uint64_t)V * 3};
        CHECK(write_npy(path, "<f4", flat, 2, pos, (size_t)4 * V * 3 * sizeof(float)));
        CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                     WEFT_ERROR_FORMAT);
        CHECK(out == NULL);
    }
    free(pos);
    char good[512];
    snprintf(good, sizeof good, "%s/cloth_pos.npy", g_short);
    copy_file(good, path);

    /* a face index out of range */
    uint64_t fshape[2] = {1, 3};
    int64_t bad_face[3] = {0, 1, 1000000};
    snprintf(path, sizeof path, "%s/faces.npy", seq);
    CHECK(write_npy(path, "<i8", fshape, 2, bad_face, sizeof bad_face));
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "faces.npy") != NULL);
    copy_file(SAMPLE "/faces.npy", path);

    /* a split list naming a missing sequence; then a good one */
    char list[300];
    snprintf(list, sizeof list, "%s/split.txt", dir);
    f = fopen(list, "wb");
    if (f) {
        fputs("# calibration\nseq\nno_such_sequence\n", f);
        fclose(f);
    }
    const char *by_list[2] = {list, NULL};
    def.calib = by_list;
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_IO);
    CHECK(strstr(weft_last_error(), "no_such_sequence") != NULL);
    CHECK(access(out_path, F_OK) != 0);
    f = fopen(list, "wb");
    if (f) {
        fputs("seq  # the copy\n", f);
        fclose(f);
    }
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_OK);
    CHECK(access(out_path, F_OK) == 0);
    remove(out_path);

    /* a missing validation sequence fails before anything is written */
    def.val = "/nonexistent/weft-val";
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_IO);
    CHECK(access(out_path, F_OK) != 0);
    def.val = NULL;

    /* bad options */
    def.smoothquant_alpha = 1.5f;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    def.smoothquant_alpha = NAN;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    def.smoothquant_alpha = -1.0f;
    def.max_layer_error = 0.0;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    def.max_layer_error = WEFT_QUANT_DEFAULT_MAX_LAYER_ERROR;
    def.calib_split = "holdout";
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, g_model, g_model_size, &out, &out_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    def.calib_split = NULL;
    weft_quant_def nocal = weft_default_quant_def();
    nocal.smoothquant_alpha = 0.5f;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &nocal, g_model, g_model_size, &out, &out_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(out == NULL);

    /* calibration of a model that is not a clothtransformer */
    static const float w[16 * 16] = {0};
    static const uint64_t s2[2] = {16, 16};
    weft_st_tensor_in t[1] = {{"lin.weight", WEFT_DTYPE_F32, 2, s2, w}};
    weft_st_meta meta[1] = {{"name", "generic"}};
    void *gen = NULL;
    size_t gen_size = 0;
    CHECK_RESULT(weft__st_write_memory(g_ctx, t, 1, meta, 1, &gen, &gen_size), WEFT_OK);
    def.calib = calib;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, gen, gen_size, &out, &out_size, NULL), WEFT_ERROR_UNSUPPORTED);
    CHECK(out == NULL);
    weft_quant_buffer_free(g_ctx, gen, gen_size);

    remove(list);
    remove(in_path);
    remove_sample(seq);
    rmdir(dir);
}

/* The game model with one layer weight dropped, or with an infinity in it: the loader's error,
 * before any calibration runs, and no output. */
static void test_bad_model(void)
{
    if (!setup()) {
        return;
    }
    weft_st_header h;
    const uint8_t *data = NULL;
    weft_result r = weft__st_parse_memory(g_ctx, g_model, g_model_size, &h, &data);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    weft_st_tensor_in *t = calloc(h.entry_count, sizeof *t);
    float *inf_copy = NULL;
    uint32_t victim = UINT32_MAX;
    for (uint32_t i = 0; t && i < h.entry_count; ++i) {
        const weft_st_entry *e = &h.entries[i];
        t[i] = (weft_st_tensor_in){e->name, e->dtype, e->rank, e->shape, data + e->begin};
        if (strcmp(e->name, "tmp.0.q.weight") == 0) {
            victim = i;
            inf_copy = malloc(e->end - e->begin);
            if (inf_copy) {
                memcpy(inf_copy, data + e->begin, e->end - e->begin);
                inf_copy[5] = INFINITY;
            }
        }
    }
    CHECK(t && victim != UINT32_MAX && inf_copy);
    weft_quant_def def = weft_default_quant_def();
    def.calib = k_calib;
    def.calib_frames = 2;
    if (t && victim != UINT32_MAX && inf_copy) {
        void *bad = NULL, *out = NULL;
        size_t bad_size = 0, out_size = 0;
        /* missing: the last entry takes the victim's place */
        weft_st_tensor_in keep = t[victim];
        t[victim] = t[h.entry_count - 1];
        CHECK_RESULT(weft__st_write_memory(g_ctx, t, h.entry_count - 1, h.meta, h.meta_count, &bad, &bad_size),
                     WEFT_OK);
        CHECK_RESULT(weft_quantize_memory(g_ctx, &def, bad, bad_size, &out, &out_size, NULL),
                     WEFT_ERROR_MISSING_TENSOR);
        CHECK(strstr(weft_last_error(), "tmp.0.q") != NULL);
        CHECK(out == NULL);
        weft_quant_buffer_free(g_ctx, bad, bad_size);
        t[h.entry_count - 1] = t[victim];
        t[victim] = keep;
        /* not finite */
        t[victim].data = inf_copy;
        CHECK_RESULT(weft__st_write_memory(g_ctx, t, h.entry_count, h.meta, h.meta_count, &bad, &bad_size), WEFT_OK);
        CHECK_RESULT(weft_quantize_memory(g_ctx, &def, bad, bad_size, &out, &out_size, NULL), WEFT_ERROR_NOT_FINITE);
        CHECK(strstr(weft_last_error(), "tmp.0.q.weight") != NULL);
        CHECK(out == NULL);
        weft_quant_buffer_free(g_ctx, bad, bad_size);
    }
    free(inf_copy);
    free(t);
    weft__st_header_free(g_ctx, &h);
}

TEST_MAIN(TEST_CASE(test_calibrated_int8), TEST_CASE(test_pins), TEST_CASE(test_error_threshold), TEST_CASE(test_smoothquant),
          TEST_CASE(test_bad_calibration), TEST_CASE(test_bad_model))
