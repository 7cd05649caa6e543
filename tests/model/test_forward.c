/* C forward pass of the ClothTransformer against PyTorch golden tensors
 * (tools/train/export.py --golden), the three residual priors against each other (the skinned one
 * against the LBS method, also after a LOD switch), plus the method's bad-input behaviour. */
#include "test.h"
#include <pthread.h>
#include "quant.h"
#include "weft.h"
#include "weft/lod.h"

#include <stdbool.h>
#include <stdint.h>

#define DATA WEFT_SOURCE_DIR "/tests/model/data/"

/* ---- minimal .npy reader (little-endian <f4 / <u4, C order) ---------------------------- */

typedef struct npy {
    void *data;
    size_t count;
    uint32_t rank;
    size_t shape[4];
} npy;

/* dir/name.npy (dir ends with '/'), its element type `descr` ("<f4", "<u4", "<i4"). */
static int npy_load_in(const char *dir, const char *name, const char *descr, npy *out)
{
    char path[512];
    snprintf(path, sizeof path, "%s%s.npy", dir, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return 0;
    }
    unsigned char pre[10];
    int ok = fread(pre, 1, 10, f) == 10 && memcmp(pre, "\x93NUMPY", 6) == 0 && pre[6] == 1;
    size_t hlen = ok ? (size_t)pre[8] | (size_t)pre[9] << 8 : 0;
    char header[1024] = {0};
    ok = ok && hlen < sizeof header && fread(header, 1, hlen, f) == hlen;
    ok = ok && strstr(header, descr) && strstr(header, "'fortran_order': False");
    const char *sh = ok ? strstr(header, "'shape': (") : NULL;
    *out = (npy){0};
    out->count = 1;
    if (sh) {
        sh += 10;
        while (*sh && *sh != ')' && out->rank < 4) {
            char *end;
            size_t v = (size_t)strtoull(sh, &end, 10);
            if (end == sh) {
                break;
            }
            out->shape[out->rank++] = v;
            out->count *= v;
            sh = end;
            while (*sh == ',' || *sh == ' ') {
                sh++;
            }
        }
    }
    ok = ok && sh && out->rank > 0;
    const size_t item = strstr(descr, "u1") ? 1 : 4; /* pin masks are bytes, the rest 4-byte */
    if (ok) {
        out->data = malloc(out->count * item + 1);
        ok = out->data && fread(out->data, item, out->count, f) == out->count;
    }
    fclose(f);
    if (!ok) {
        fprintf(stderr, "malformed %s\n", path);
        free(out->data);
        out->data = NULL;
    }
    return ok;
}

static void *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *p = malloc((size_t)n + 1);
    if (p && fread(p, 1, (size_t)n, f) != (size_t)n) {
        free(p);
        p = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return p;
}

/* ---- fixture --------------------------------------------------------------------------- */

typedef struct golden {
    npy rest, faces, cfaces, gt, cpos, tf_frames, tf_pred, rollout, pinned; /* pinned: data NULL without pins */
    uint32_t V, F, Vc, Fc;
} golden;

/* Where a golden's arrays are: the sequence's (rest, faces, collider faces, cloth and collider
 * positions) in seq_dir under their names and index type, the PyTorch predictions (tf_frames,
 * tf_pred, rollout, and the teacher_forced_parity_of ones) in pred_dir. */
typedef struct golden_layout {
    const char *seq_dir, *pred_dir;
    const char *rest, *faces, *cfaces, *gt, *cpos, *index_descr;
    const char *pinned; /* [T, V] u1 pin masks in seq_dir, or NULL */
} golden_layout;

/* tests/model/data: everything written by export.py --golden (of tests/data/sample_seq). */
static const golden_layout golden_flat = {DATA, DATA, "rest", "faces", "cfaces", "gt_pos", "c_pos", "<u4", NULL};

/* tests/model/data/garment_seq (tools/train/cut_seq.py): a garment on a moving body, in the simgen
 * layout, with the predictions of export.py --golden-preds-only in golden/ (see
 * skinned_teacher_forced_parity). */
#define GARMENT_SEQ DATA "garment_seq/"
static const golden_layout golden_garment_seq = {GARMENT_SEQ, GARMENT_SEQ "golden/", "rest_pos", "faces",
                                                 "collider_faces", "cloth_pos", "collider_pos", "<i4", NULL};

/* tests/data/sample_seq (a 60-frame drop in the simgen layout), with the shipped drop model's
 * predictions in tests/model/data/drop_golden (see shipped_drop_parity). */
static const golden_layout golden_drop_seq = {WEFT_SOURCE_DIR "/tests/data/sample_seq/", DATA "drop_golden/",
                                              "rest_pos", "faces", "collider_faces", "cloth_pos", "collider_pos",
                                              "<i4", NULL};

/* tests/model/data/garment_seq again, with the shipped garment specialist's predictions in
 * tests/model/data/garment_golden (see shipped_garment_parity). */
static const golden_layout golden_garment_specialist = {GARMENT_SEQ, DATA "garment_golden/", "rest_pos", "faces",
                                                        "collider_faces", "cloth_pos", "collider_pos", "<i4", NULL};

/* tests/model/data/gripper_seq (cut_seq.py --start: a grasped sheet being lifted, with its pin
 * masks), with the shipped gripper specialist's predictions in gripper_seq/golden (see
 * shipped_gripper_parity). */
static const golden_layout golden_gripper_seq = {DATA "gripper_seq/", DATA "gripper_seq/golden/", "rest_pos", "faces",
                                                 "collider_faces", "cloth_pos", "collider_pos", "<i4", "pinned"};

static void golden_free(golden *g)
{
    npy *all[] = {&g->rest,      &g->faces,   &g->cfaces,  &g->gt,    &g->cpos,
                  &g->tf_frames, &g->tf_pred, &g->rollout, &g->pinned};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; ++i) {
        free(all[i]->data);
    }
}

static int golden_load_from(golden *g, const golden_layout *l)
{
    *g = (golden){0};
    int ok = npy_load_in(l->seq_dir, l->rest, "<f4", &g->rest) &&
             npy_load_in(l->seq_dir, l->faces, l->index_descr, &g->faces) &&
             npy_load_in(l->seq_dir, l->cfaces, l->index_descr, &g->cfaces) &&
             npy_load_in(l->seq_dir, l->gt, "<f4", &g->gt) && npy_load_in(l->seq_dir, l->cpos, "<f4", &g->cpos) &&
             npy_load_in(l->pred_dir, "tf_frames", "<u4", &g->tf_frames) &&
             npy_load_in(l->pred_dir, "tf_pred", "<f4", &g->tf_pred) &&
             npy_load_in(l->pred_dir, "rollout", "<f4", &g->rollout) &&
             (!l->pinned || npy_load_in(l->seq_dir, l->pinned, "|u1", &g->pinned));
    /* shapes: V x 3 rest, [T, V, 3] cloth, [T, Vc, 3] collider; frames t-1 .. t+1 of each
     * teacher-forced t and frames 0 .. R+1 of the rollout are in the sequence */
    ok = ok && g->rest.rank == 2 && g->rest.shape[1] == 3 && g->faces.rank == 2 && g->faces.shape[1] == 3 &&
         g->cfaces.rank == 2 && g->cfaces.shape[1] == 3 && g->gt.rank == 3 && g->gt.shape[1] == g->rest.shape[0] &&
         g->cpos.rank == 3 && g->cpos.shape[0] == g->gt.shape[0] && g->rollout.rank == 3 &&
         g->rollout.shape[1] == g->rest.shape[0] && g->rollout.shape[0] + 2 <= g->gt.shape[0] &&
         g->tf_frames.rank == 1 && g->tf_pred.rank == 3 && g->tf_pred.shape[0] == g->tf_frames.shape[0] &&
         g->tf_pred.shape[1] == g->rest.shape[0] &&
         (!l->pinned || (g->pinned.rank == 2 && g->pinned.shape[0] == g->gt.shape[0] &&
                         g->pinned.shape[1] == g->rest.shape[0]));
    for (size_t i = 0; ok && i < g->tf_frames.count; ++i) {
        const uint32_t t = ((const uint32_t *)g->tf_frames.data)[i];
        ok = t >= 1 && t + 1 < g->gt.shape[0];
    }
    if (ok) {
        g->V = (uint32_t)g->rest.shape[0];
        g->F = (uint32_t)g->faces.shape[0];
        g->Vc = (uint32_t)g->cpos.shape[1];
        g->Fc = (uint32_t)g->cfaces.shape[0];
    } else {
        fprintf(stderr, "golden arrays in %s and %s: missing, or their shapes disagree\n", l->seq_dir, l->pred_dir);
        golden_free(g);
    }
    return ok;
}

static int golden_load(golden *g) { return golden_load_from(g, &golden_flat); }

static const float *frame(const npy *a, size_t t)
{
    size_t per = a->count / a->shape[0];
    return (const float *)a->data + t * per;
}

/* Counting allocator: a step must not allocate. */
static size_t g_allocs;
static void *count_alloc(size_t size, size_t alignment, void *user)
{
    (void)user;
    g_allocs++;
    return aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}
static void count_free(void *p, size_t size, void *user)
{
    (void)size;
    (void)user;
    free(p);
}

static weft_context *make_ctx(void)
{
    weft_context_def cd = weft_default_context_def();
    cd.allocator.alloc = count_alloc;
    cd.allocator.free = count_free;
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    return ctx;
}

/* The pins of frame t (the golden's mask, targets its ground truth), as `weft eval --pins all`
 * sets them before the step to t; nothing without pin masks. */
static void set_frame_pins(weft_garment *gar, const golden *g, size_t t)
{
    if (!g->pinned.data) {
        return;
    }
    const uint8_t *mask = (const uint8_t *)g->pinned.data + t * g->V;
    uint32_t *idx = malloc(g->V * sizeof(uint32_t));
    float *to = malloc((size_t)g->V * 3 * sizeof(float));
    uint32_t n = 0;
    for (uint32_t v = 0; idx && to && v < g->V; ++v) {
        if (mask[v]) {
            idx[n] = v;
            memcpy(to + 3 * (size_t)n, frame(&g->gt, t) + 3 * (size_t)v, 3 * sizeof(float));
            n++;
        }
    }
    CHECK_RESULT(weft_garment_set_pins(gar, idx, to, n), WEFT_OK);
    free(idx);
    free(to);
}

static weft_garment_def garment_def(const golden *g, const weft_model *m, size_t t)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = WEFT_METHOD_MODEL;
    d.model = m;
    d.ccd.enabled = false;
    d.rest_positions = g->rest.data;
    d.vertex_count = g->V;
    d.triangles = g->faces.data;
    d.triangle_count = g->F;
    d.collider_rest_positions = frame(&g->cpos, t);
    d.collider_vertex_count = g->Vc;
    d.collider_triangles = g->cfaces.data;
    d.collider_triangle_count = g->Fc;
    d.initial_positions = frame(&g->gt, t);
    return d;
}

/* max |a - b| relative to max |b| (the parity measure) and to the frame's largest motion. */
static void compare(const float *c, const float *p, const float *x_t, size_t n, double *rel, double *rel_motion)
{
    double e = 0, mag = 0, mot = 0;
    for (size_t i = 0; i < n; ++i) {
        e = fmax(e, fabs((double)c[i] - p[i]));
        mag = fmax(mag, fabs((double)p[i]));
        mot = fmax(mot, fabs((double)p[i] - x_t[i]));
    }
    *rel = e / fmax(mag, 1e-12);
    *rel_motion = e / fmax(mot, 1e-12);
}

/* ---- cases ----------------------------------------------------------------------------- */

/* One step from ground-truth frames (t, t-1) per golden frame, against PyTorch's prediction
 * `pred_name` (in the layout's pred_dir) of the model in `model_file`. One garment made as
 * `weft eval` makes it (X_1 and the collider at frame 1: the binding of the skinned prior, which
 * weft_garment_set_state keeps) is set to each ground-truth frame t in turn and stepped to t + 1,
 * so its collider at t is the sequence's; set_state restarts the latent history, as Python's
 * teacher-forced steps start from an empty one. */
static void teacher_forced_parity_of(const golden_layout *l, const char *model_file, const char *pred_name)
{
    golden g;
    npy pred;
    if (!golden_load_from(&g, l)) {
        CHECK(!"golden tensors missing");
        return;
    }
    if (!npy_load_in(l->pred_dir, pred_name, "<f4", &pred)) {
        CHECK(!"golden prediction missing");
        golden_free(&g);
        return;
    }
    const size_t n_tf = g.tf_frames.shape[0];
    const uint32_t *tf = g.tf_frames.data;
    CHECK(pred.rank == 3 && pred.shape[0] == n_tf && pred.shape[1] == g.V);
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, model_file, &m), WEFT_OK);
    weft_garment *gar = NULL;
    weft_garment_def d = garment_def(&g, m, 1);
    if (m) {
        CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    }
    uint32_t last = 0;
    for (size_t i = 0; i < n_tf; ++i) {
        last = tf[i] > last ? tf[i] : last;
    }
    double worst = 0, worst_motion = 0;
    size_t compared = 0;
    for (uint32_t t = 1; gar && t <= last; ++t) {
        CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, t), frame(&g.gt, t - 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, t + 1)), WEFT_OK);
        set_frame_pins(gar, &g, t + 1);
        weft_result r = weft_garment_step(gar);
        CHECK_RESULT(r, WEFT_OK);
        if (r != WEFT_OK) {
            break;
        }
        for (size_t i = 0; i < n_tf; ++i) {
            if (tf[i] != t) {
                continue;
            }
            double rel, relm;
            compare(weft_garment_positions(gar), frame(&pred, i), frame(&g.gt, t), (size_t)g.V * 3, &rel, &relm);
            CHECK_MSG(rel <= 1e-4, "frame %u: relative error %.3g > 1e-4", t, rel);
            CHECK_MSG(relm <= 1e-3, "frame %u: error %.3g of the frame's motion > 1e-3", t, relm);
            worst = fmax(worst, rel);
            worst_motion = fmax(worst_motion, relm);
            compared++;
        }
    }
    CHECK_EQ_INT(compared, n_tf);
    printf("teacher-forced %s (%s): %zu frames, max relative error %.3g (%.3g of the per-frame motion)\n",
           pred_name, strrchr(model_file, '/') + 1, compared, worst, worst_motion);
    weft_garment_destroy(gar);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(pred.data);
    golden_free(&g);
}

static void teacher_forced_parity(void)
{
    teacher_forced_parity_of(&golden_flat, DATA "golden_model.safetensors", "tf_pred");
}

/* The shipped game model (the skinned prior, K = 32) on the garment sequence; game_tf_pred.npy is
 * tf_pred.npy of `export.py --ckpt tools/train/models/game.ckpt.pt --golden DIR --golden-seq
 * tests/model/data/garment_seq --tf-frames 1,2,5,10 --rollout 14 --golden-preds-only`. */
static void shipped_game_parity(void)
{
    teacher_forced_parity_of(&golden_garment_seq, WEFT_SOURCE_DIR "/tools/train/models/game.safetensors",
                             "game_tf_pred");
}

/* The autoregressive rollout from ground-truth frames (0, 1) with its latent history, against
 * PyTorch's (rollout.npy: frame i + 2 at i), the garment made as teacher_forced_parity_of's. The
 * first frames are also held to the teacher-forced bound relative to the frame's motion: on a
 * slow garment the relative bound alone would pass a skinned prior bound on the wrong frame (its
 * S_{t+1} - S_t off by a fraction of a millimetre). */
static void rollout_parity_of(const golden_layout *l, const char *model_file)
{
    golden g;
    if (!golden_load_from(&g, l)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, model_file, &m), WEFT_OK);
    weft_garment *gar = NULL;
    weft_garment_def d = garment_def(&g, m, 1);
    if (m) {
        CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    }
    if (!gar) {
        weft_model_destroy(m);
        weft_context_destroy(ctx);
        golden_free(&g);
        return;
    }
    CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, 1), frame(&g.gt, 0)), WEFT_OK);
    size_t allocs_before = g_allocs;
    size_t R = g.rollout.shape[0];
    double worst = 0, first5 = 0, first5_motion = 0;
    float *prev = malloc((size_t)g.V * 3 * sizeof(float));
    for (size_t i = 0; i < R; ++i) {
        memcpy(prev, weft_garment_positions(gar), (size_t)g.V * 3 * sizeof(float));
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, i + 2)), WEFT_OK);
        set_frame_pins(gar, &g, i + 2);
        weft_result r = weft_garment_step(gar);
        CHECK_RESULT(r, WEFT_OK);
        if (r != WEFT_OK) {
            break;
        }
        double rel, relm;
        compare(weft_garment_positions(gar), frame(&g.rollout, i), prev, (size_t)g.V * 3, &rel, &relm);
        worst = fmax(worst, rel);
        if (i < 5) {
            first5 = fmax(first5, rel);
            first5_motion = fmax(first5_motion, relm);
        }
    }
    CHECK_EQ_INT(g_allocs, allocs_before);
    /* Per-frame parity for the first frames; the documented rollout tolerance (docs/MODEL.md)
     * for all of them, since float rounding differences compound through the feedback. */
    CHECK_MSG(first5 <= 1e-4, "first 5 rollout frames: relative error %.3g > 1e-4", first5);
    CHECK_MSG(first5_motion <= 1e-3, "first 5 rollout frames: error %.3g of the frame's motion > 1e-3", first5_motion);
    CHECK_MSG(worst <= 1e-3, "%zu-frame rollout: relative error %.3g > 1e-3", R, worst);
    printf("rollout (%s): %zu frames, max relative error %.3g (first 5: %.3g, %.3g of the per-frame motion)\n",
           strrchr(model_file, '/') + 1, R, worst, first5, first5_motion);
    free(prev);
    weft_garment_destroy(gar);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    golden_free(&g);
}

static void rollout_parity(void) { rollout_parity_of(&golden_flat, DATA "golden_model.safetensors"); }

/* The shipped drop specialist (the ballistic prior, K = 16) on the sample drop, teacher-forced and
 * rolled out; drop_golden/ is `export.py --ckpt tools/train/models/drop.ckpt.pt --golden
 * tests/model/data/drop_golden --golden-seq tests/data/sample_seq --tf-frames 1,2,5,10 --rollout 14
 * --golden-preds-only`. */
static void shipped_drop_parity(void)
{
    teacher_forced_parity_of(&golden_drop_seq, WEFT_SOURCE_DIR "/tools/train/models/drop.safetensors", "tf_pred");
    rollout_parity_of(&golden_drop_seq, WEFT_SOURCE_DIR "/tools/train/models/drop.safetensors");
}

/* The shipped garment specialist (the skinned prior with prior_decay 0.9, K = 16) on the garment
 * sequence, teacher-forced and rolled out (the rollout leaves S, so the decay acts);
 * garment_golden/ is `export.py --ckpt tools/train/models/garment.ckpt.pt --golden
 * tests/model/data/garment_golden --golden-seq tests/model/data/garment_seq --tf-frames 1,2,5,10
 * --rollout 14 --golden-preds-only`. */
static void shipped_garment_parity(void)
{
    teacher_forced_parity_of(&golden_garment_specialist, WEFT_SOURCE_DIR "/tools/train/models/garment.safetensors",
                             "tf_pred");
    rollout_parity_of(&golden_garment_specialist, WEFT_SOURCE_DIR "/tools/train/models/garment.safetensors");
}

/* The skinned prior's S_t is the previous step's S_{t+1} while the collider at t is bitwise what
 * it was evaluated from. Three garment-specialist garments end at the same state and collider at
 * t, then step to the same t+1: A stepped the sequence itself (its S_{t+1} is reused), B stepped
 * the sequence shifted 5 cm and is then given the collider at t (its kept S_{t+1} is stale and must
 * not be reused), C never stepped and is given it too (nothing kept). All three equal bit for bit,
 * at every precision, and so does D, which stepped the sequence and had its collider at t
 * rewritten with the same values (kept S_{t+1} still valid). */
static void skinned_prior_reuse(void)
{
    golden g;
    if (!golden_load_from(&g, &golden_garment_specialist)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, WEFT_SOURCE_DIR "/tools/train/models/garment.safetensors", &m), WEFT_OK);
    const size_t n = (size_t)g.V * 3, nc = (size_t)g.Vc * 3;
    const size_t t = g.cpos.shape[0] > 6 ? 5 : g.cpos.shape[0] - 2; /* the frame the three meet at */
    float *shifted = malloc(nc * sizeof(float));
    for (int prec = 0; m && prec < 3; ++prec) {
        weft_garment *gar[4] = {NULL};
        for (int k = 0; k < 4; ++k) {
            weft_garment_def d = garment_def(&g, m, 1);
            d.precision = (weft_precision)prec;
            CHECK_RESULT(weft_garment_create(ctx, &d, &gar[k]), WEFT_OK);
        }
        if (!gar[0] || !gar[1] || !gar[2] || !gar[3]) {
            for (int k = 0; k < 4; ++k) {
                weft_garment_destroy(gar[k]);
            }
            continue;
        }
        for (size_t f = 2; f <= t; ++f) { /* A and D on the sequence, B on it shifted 5 cm in x */
            for (size_t i = 0; i < nc; ++i) {
                shifted[i] = frame(&g.cpos, f)[i] + (i % 3 == 0 ? 0.05f : 0.0f);
            }
            CHECK_RESULT(weft_garment_set_collider(gar[0], frame(&g.cpos, f)), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(gar[3], frame(&g.cpos, f)), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(gar[1], shifted), WEFT_OK);
            for (int k = 0; k < 4; ++k) {
                if (k != 2) {
                    CHECK_RESULT(weft_garment_step(gar[k]), WEFT_OK);
                }
            }
        }
        for (int k = 1; k < 4; ++k) {
            CHECK_RESULT(weft_garment_set_collider_current(gar[k], frame(&g.cpos, t)), WEFT_OK);
        }
        for (int k = 0; k < 4; ++k) {
            CHECK_RESULT(weft_garment_set_state(gar[k], frame(&g.gt, t), frame(&g.gt, t - 1)), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(gar[k], frame(&g.cpos, t + 1)), WEFT_OK);
            CHECK_RESULT(weft_garment_step(gar[k]), WEFT_OK);
        }
        const float *xa = weft_garment_positions(gar[0]);
        for (int k = 1; k < 4; ++k) {
            CHECK_MSG(memcmp(xa, weft_garment_positions(gar[k]), n * sizeof(float)) == 0,
                      "precision %d: garment %d differs from the one that stepped the sequence", prec, k);
        }
        /* not vacuous: B's own S_{t+1} of the shifted collider would have moved every vertex */
        double moved = 0;
        for (size_t i = 0; i < n; ++i) {
            moved = fmax(moved, fabs((double)xa[i] - frame(&g.gt, t)[i]));
        }
        CHECK(moved > 0.0);
        for (int k = 0; k < 4; ++k) {
            weft_garment_destroy(gar[k]);
        }
    }
    free(shifted);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The shipped gripper specialist (the grasp prior, K = 16) on a grasped sheet being lifted,
 * teacher-forced and rolled out with the sequence's pins set every frame as `weft eval --pins all`
 * sets them (the prior moves the sheet with them); gripper_seq/ is `cut_seq.py --seq
 * data/refsim/gripper_1k_0003 --start 60 --frames 16 --out tests/model/data/gripper_seq`, its
 * golden/ `export.py --ckpt tools/train/models/gripper.ckpt.pt --golden
 * tests/model/data/gripper_seq/golden --golden-seq tests/model/data/gripper_seq --tf-frames
 * 1,2,5,10 --rollout 14 --golden-preds-only`. */
static void shipped_gripper_parity(void)
{
    teacher_forced_parity_of(&golden_gripper_seq, WEFT_SOURCE_DIR "/tools/train/models/gripper.safetensors", "tf_pred");
    rollout_parity_of(&golden_gripper_seq, WEFT_SOURCE_DIR "/tools/train/models/gripper.safetensors");
}

/* The skinned prior X_t + S_{t+1} - S_t + out_scale d against PyTorch, on a garment whose collider
 * moves (tests/model/data/garment_seq). Python's S is that sequence's skin_pos.npy, the LBS method's
 * rollout from `weft eval` (bound on X_1 and the collider at frame 1); the runtime binds the
 * garment at creation, so the parity garments are made on frame 1 exactly so (garment_def(.., 1))
 * and this also checks the runtime's S against the LBS method's (the garment bound on frame 2 instead
 * is off by 2% of the motion at t = 2, twenty times the bound; the relative bound alone would miss
 * it on this slow garment). Regenerating the files: the
 * sequence and its S track as tools/train/cut_seq.py's docstring says; the model (CPU, 300 steps)
 *
 *   /usr/bin/python3 tools/train/train.py --data data/refsim --skin data/skin --preset golden \
 *       --config '{"prior":"skinned"}' --steps 300 --eval-every 0 --out data/runs/golden_skin
 *
 * and the model file and goldens (golden/: tf_frames, tf_pred, rollout only; the rest is the
 * sequence's own arrays):
 *
 *   /usr/bin/python3 tools/train/export.py --ckpt data/runs/golden_skin/ckpt.pt \
 *       --out tests/model/data/garment_seq/golden_skin.safetensors --name golden_skin \
 *       --golden tests/model/data/garment_seq/golden --golden-seq tests/model/data/garment_seq \
 *       --tf-frames 1,2,5,10 --rollout 14 --golden-preds-only
 */
static void skinned_teacher_forced_parity(void)
{
    teacher_forced_parity_of(&golden_garment_seq, GARMENT_SEQ "golden_skin.safetensors", "tf_pred");
}

static void skinned_rollout_parity(void)
{
    rollout_parity_of(&golden_garment_seq, GARMENT_SEQ "golden_skin.safetensors");
}

/* The model file, with `from` replaced by `to` in its header (the length is fixed up). */
static void *patched_model(const char *from, const char *to, size_t *size)
{
    size_t n = 0;
    unsigned char *src = read_file(DATA "golden_model.safetensors", &n);
    if (!src || n < 8) {
        free(src);
        return NULL;
    }
    uint64_t hlen = 0;
    for (int i = 7; i >= 0; --i) {
        hlen = hlen << 8 | src[i];
    }
    char *hdr = malloc(hlen + 1);
    memcpy(hdr, src + 8, hlen);
    hdr[hlen] = '\0';
    char *at = strstr(hdr, from);
    if (!at) {
        free(hdr);
        free(src);
        return NULL;
    }
    size_t lf = strlen(from), lt = strlen(to);
    uint64_t nh = hlen - lf + lt;
    unsigned char *out = malloc(n - hlen + nh);
    for (int i = 0; i < 8; ++i) {
        out[i] = (unsigned char)(nh >> (8 * i));
    }
    size_t pre = (size_t)(at - hdr);
    memcpy(out + 8, hdr, pre);
    memcpy(out + 8 + pre, to, lt);
    memcpy(out + 8 + pre + lt, at + lf, hlen - pre - lf);
    memcpy(out + 8 + nh, src + 8 + hlen, n - 8 - hlen);
    *size = n - hlen + nh;
    free(hdr);
    free(src);
    return out;
}

/* Load must succeed; garment creation must then fail with `expected` (or the load itself may
 * already reject the file with `expected`). */
static void expect_create_fails(const char *from, const char *to, bool with_collider, weft_result expected)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    size_t size = 0;
    void *bytes = patched_model(from, to, &size);
    CHECK_MSG(bytes != NULL, "could not patch '%s'", from);
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    weft_result r = bytes ? weft_model_load_memory(ctx, bytes, size, &m) : WEFT_ERROR_IO;
    if (r == WEFT_OK) {
        weft_garment_def d = garment_def(&g, m, 1);
        if (!with_collider) {
            d.collider_vertex_count = 0;
            d.collider_rest_positions = NULL;
            d.collider_triangles = NULL;
            d.collider_triangle_count = 0;
        }
        weft_garment *gar = NULL;
        r = weft_garment_create(ctx, &d, &gar);
        CHECK(gar == NULL);
        weft_garment_destroy(gar);
    }
    CHECK_MSG(r == expected, "patch '%s' -> '%s': got %s (%s), expected %s", from, to, weft_result_string(r),
              weft_last_error(), weft_result_string(expected));
    CHECK(strlen(weft_last_error()) > 0);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(bytes);
    golden_free(&g);
}

static void bad_model_files(void)
{
    expect_create_fails("\"dec_head.bias\"", "\"dec_head.bixs\"", true, WEFT_ERROR_MISSING_TENSOR);
    expect_create_fails("\\\"dec_skip\\\"", "\\\"vertex_count\\\": 7, \\\"dec_skip\\\"", true,
                        WEFT_ERROR_TOPOLOGY_MISMATCH);
    expect_create_fails("\\\"dec_skip\\\"", "\\\"requires_collider\\\": true, \\\"dec_skip\\\"", false,
                        WEFT_ERROR_NO_COLLIDER);
    expect_create_fails("\\\"prior\\\": \\\"", "\\\"prior\\\": \\\"x", true, WEFT_ERROR_BAD_METADATA);
    expect_create_fails("\\\"D\\\": ", "\\\"D\\\": 1", true, WEFT_ERROR_TENSOR_SHAPE);
}

/* The golden model's prior entries, last in its config: the ballistic prior without gravity,
 * X_t + (X_t - X_{t-1}) (the inertial prior), as they appear escaped in the metadata string. */
#define GOLDEN_PRIOR "\\\"prior\\\": \\\"ballistic\\\", \\\"prior_beta\\\": 1.0, \\\"gravity_step\\\": 0.0"
/* The same without the carried velocity: X_t. */
#define GOLDEN_PRIOR_STILL "\\\"prior\\\": \\\"ballistic\\\", \\\"prior_beta\\\": 0.0, \\\"gravity_step\\\": 0.0"

/* The golden model with its prior entries replaced by `to` (a JSON fragment as it appears escaped
 * in the metadata string); NULL on failure. */
static weft_model *model_patched(weft_context *ctx, const char *to, weft_result *result)
{
    size_t size = 0;
    void *bytes = patched_model(GOLDEN_PRIOR, to, &size);
    CHECK_MSG(bytes != NULL, "could not patch the prior to '%s'", to);
    weft_model *m = NULL;
    *result = bytes ? weft_model_load_memory(ctx, bytes, size, &m) : WEFT_ERROR_IO;
    free(bytes);
    return m;
}

static weft_model *model_with_prior(weft_context *ctx, const char *prior, weft_result *result)
{
    char to[64];
    snprintf(to, sizeof to, "\\\"prior\\\": \\\"%s\\\"", prior);
    return model_patched(ctx, to, result);
}

/* max over i of |(a_i - b_i) - (c_i - d_i)| */
static double diff_of_diffs(const float *a, const float *b, const float *c, const float *d, size_t n)
{
    double e = 0;
    for (size_t i = 0; i < n; ++i) {
        e = fmax(e, fabs(((double)a[i] - b[i]) - ((double)c[i] - d[i])));
    }
    return e;
}

/* S_1 .. S_{frames}: an LBS garment bound like the model garments (frame 1 positions and
 * collider) and stepped with each frame's collider gives S_k = the binding on the collider at k. */
static bool lbs_track(const golden *g, weft_context *ctx, uint32_t frames, float *S)
{
    weft_garment_def d = garment_def(g, NULL, 1);
    d.method = WEFT_METHOD_LBS;
    weft_garment *gl = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gl), WEFT_OK);
    const size_t n = (size_t)g->V * 3;
    const bool made = gl != NULL;
    for (uint32_t k = 1; gl && k <= frames; ++k) {
        CHECK_RESULT(weft_garment_set_collider(gl, frame(&g->cpos, k)), WEFT_OK);
        CHECK_RESULT(weft_garment_step(gl), WEFT_OK);
        memcpy(S + (k - 1) * n, weft_garment_positions(gl), n * sizeof(float));
    }
    weft_garment_destroy(gl);
    return made;
}

/* The priors on the same network output: six garments (ballistic without gravity, at beta 1:
 * "inertial", and at beta 0: "previous"; skinned, ballistic at its defaults, skinned with
 * prior_decay 0.5, grasp with prior_beta 0.5) set to the same state every frame of the skinned
 * model's rollout step to
 *   x(previous) - x(inertial) = X_{t-1} - X_t,   x(skinned) - x(previous) = S_{t+1} - S_t,
 *   x(ballistic) - x(previous) = X_t - X_{t-1} - g dt^2 Y   (the default beta 1, g dt^2 9.81/3600 m),
 *   x(decayed) - x(previous) = S_{t+1} + 0.5 (X_t - S_t) - X_t and
 *   x(grasp) - x(previous) = Y - X_t with Y = X_t + 0.5 (X_t - X_{t-1}), on a frame with pins (three,
 *   every other frame) each Y_v farther from the targets' centroid c than |rest_v - rest_c| (rest_c
 *   the pinned vertices' rest centroid) pulled back to that distance along Y_v - c (unpinned
 *   vertices; the pinned ones sit at their targets), and with attach_output (the seventh garment)
 *   the same attachment applied to Y plus the network's displacement, x(previous) - X_t,
 * S from the LBS method, at every precision. (weft_garment_set_state restarts the latent history
 * each frame, the same in all six.) */
enum { PRIOR_MODELS = 7, GRASP_PINS = 3 };

static void prior_differences(const golden *g, weft_context *ctx, weft_model *const models[PRIOR_MODELS],
                              const float *S, uint32_t T)
{
    const size_t n = (size_t)g->V * 3;
    float *X = malloc(n * sizeof(float)), *Xp = malloc(n * sizeof(float));
    double worst_prev = 0, worst_skin = 0, worst_ball = 0, worst_decay = 0, skin_motion = 0, offset = 0;
    double worst_grasp = 0, held_motion = 0;
    size_t attached = 0;
    const float *rest = g->rest.data;
    const uint32_t pin_idx[GRASP_PINS] = {0, g->V / 2, g->V - 1};
    for (int prec = 0; prec < 3; ++prec) {
        weft_garment *gar[PRIOR_MODELS] = {NULL};
        bool all = true;
        for (int k = 0; k < PRIOR_MODELS; ++k) {
            weft_garment_def d = garment_def(g, models[k], 1);
            d.precision = (weft_precision)prec;
            CHECK_RESULT(weft_garment_create(ctx, &d, &gar[k]), WEFT_OK);
            all = all && gar[k];
        }
        if (!all) {
            for (int k = 0; k < PRIOR_MODELS; ++k) {
                weft_garment_destroy(gar[k]);
            }
            continue;
        }
        memcpy(X, frame(&g->gt, 1), n * sizeof(float));
        memcpy(Xp, frame(&g->gt, 0), n * sizeof(float));
        for (uint32_t t = 1; t <= T; ++t) {
            /* the grasp garment's hand: three vertices pulled along a frame-dependent step */
            float pin_to[GRASP_PINS * 3];
            double hand[3] = {0, 0, 0}, hand_rest[3] = {0, 0, 0};
            const uint32_t pins = t % 2 == 0 ? GRASP_PINS : 0;
            for (uint32_t k = 0; k < pins; ++k) {
                for (int j = 0; j < 3; ++j) {
                    const float move = 0.004f * (float)t * (float)(j + 1) - 0.01f * (float)k;
                    pin_to[3 * k + j] = X[3 * (size_t)pin_idx[k] + j] + move;
                    hand[j] += pin_to[3 * k + j] / (double)pins;
                    hand_rest[j] += rest[3 * (size_t)pin_idx[k] + j] / (double)pins;
                }
            }
            CHECK_RESULT(weft_garment_set_pins(gar[5], pin_idx, pin_to, pins), WEFT_OK);
            CHECK_RESULT(weft_garment_set_pins(gar[6], pin_idx, pin_to, pins), WEFT_OK);
            for (int k = 0; k < PRIOR_MODELS; ++k) {
                CHECK_RESULT(weft_garment_set_state(gar[k], X, Xp), WEFT_OK);
                CHECK_RESULT(weft_garment_set_collider(gar[k], frame(&g->cpos, t + 1)), WEFT_OK);
                CHECK_RESULT(weft_garment_step(gar[k]), WEFT_OK);
            }
            const float *xi = weft_garment_positions(gar[0]), *xp = weft_garment_positions(gar[1]),
                        *xs = weft_garment_positions(gar[2]);
            const float *s_cur = S + (t - 1) * n, *s_next = S + t * n;
            const double e_prev = diff_of_diffs(xp, xi, Xp, X, n), e_skin = diff_of_diffs(xs, xp, s_next, s_cur, n);
            CHECK_MSG(e_prev <= 1e-5, "precision %d frame %u: previous - inertial off by %.3g m", prec, t, e_prev);
            CHECK_MSG(e_skin <= 1e-5, "precision %d frame %u: skinned - previous off by %.3g m", prec, t, e_skin);
            const float *xb = weft_garment_positions(gar[3]);
            double e_ball = 0;
            for (size_t i = 0; i < n; ++i) {
                const double want = ((double)X[i] - Xp[i]) - (i % 3 == 1 ? 9.81 / 3600.0 : 0.0);
                e_ball = fmax(e_ball, fabs(((double)xb[i] - xp[i]) - want));
            }
            CHECK_MSG(e_ball <= 1e-5, "precision %d frame %u: ballistic - previous off by %.3g m", prec, t, e_ball);
            const float *xd = weft_garment_positions(gar[4]);
            double e_decay = 0;
            for (size_t i = 0; i < n; ++i) {
                const double want = (double)s_next[i] + 0.5 * ((double)X[i] - s_cur[i]) - X[i];
                e_decay = fmax(e_decay, fabs(((double)xd[i] - xp[i]) - want));
                offset = fmax(offset, fabs((double)X[i] - s_cur[i]));
            }
            CHECK_MSG(e_decay <= 1e-5, "precision %d frame %u: decayed skinned - previous off by %.3g m", prec, t,
                      e_decay);
            worst_decay = fmax(worst_decay, e_decay);
            double e_grasp = 0;
            for (int out = 0; out < 2; ++out) { /* the prior attached; the output attached */
                const float *xg = weft_garment_positions(gar[5 + out]);
                for (uint32_t v = 0; v < g->V; ++v) {
                    if (pins && (v == pin_idx[0] || v == pin_idx[1] || v == pin_idx[2])) {
                        continue; /* pinned: at their targets after the step */
                    }
                    double y[3], d[3], len = 0, reach = 0;
                    for (int j = 0; j < 3; ++j) {
                        const size_t i = 3 * (size_t)v + j;
                        y[j] = X[i] + 0.5 * ((double)X[i] - Xp[i]) + (out ? (double)xp[i] - X[i] : 0.0);
                        d[j] = y[j] - hand[j];
                        len += d[j] * d[j];
                        reach += (rest[i] - hand_rest[j]) * (rest[i] - hand_rest[j]);
                    }
                    len = sqrt(len);
                    reach = sqrt(reach);
                    if (pins && len > reach) {
                        attached++;
                        for (int j = 0; j < 3; ++j) {
                            y[j] = hand[j] + d[j] * (reach / len);
                        }
                    }
                    for (int j = 0; j < 3; ++j) {
                        const size_t i = 3 * (size_t)v + j;
                        /* x(previous) - X_t is the network's displacement, which the first adds
                         * after the attachment and the second before it */
                        const double want = out ? y[j] : y[j] + ((double)xp[i] - X[i]);
                        e_grasp = fmax(e_grasp, fabs((double)xg[i] - want));
                        held_motion = fmax(held_motion, fabs(y[j] - X[i]));
                    }
                }
            }
            for (uint32_t k = 0; k < pins; ++k) {
                for (int out = 0; out < 2; ++out) {
                    CHECK(memcmp(weft_garment_positions(gar[5 + out]) + 3 * (size_t)pin_idx[k], pin_to + 3 * k,
                                 3 * sizeof(float)) == 0);
                }
            }
            CHECK_MSG(e_grasp <= 1e-5, "precision %d frame %u (%u pins): grasp - previous off by %.3g m", prec, t, pins,
                      e_grasp);
            worst_grasp = fmax(worst_grasp, e_grasp);
            worst_prev = fmax(worst_prev, e_prev);
            worst_skin = fmax(worst_skin, e_skin);
            worst_ball = fmax(worst_ball, e_ball);
            for (size_t i = 0; i < n; ++i) {
                skin_motion = fmax(skin_motion, fabs((double)s_next[i] - s_cur[i]));
            }
            memcpy(Xp, X, n * sizeof(float));
            memcpy(X, xs, n * sizeof(float));
        }
        for (int k = 0; k < PRIOR_MODELS; ++k) {
            weft_garment_destroy(gar[k]);
        }
    }
    /* not vacuous: the collider moves the skinned prior away from the previous one, and the
     * rollout leaves S, so the decay has an offset to act on */
    CHECK_MSG(skin_motion > 1e-3, "S moves at most %.3g m per frame", skin_motion);
    CHECK_MSG(offset > 1e-3, "X_t stays within %.3g m of S_t", offset);
    CHECK_MSG(held_motion > 1e-2, "the grasp prior's steps stay within %.3g m", held_motion);
    CHECK_MSG(attached > 100, "the attachment pulled back only %zu vertex-frames", attached);
    printf("priors over %u frames x 3 precisions: previous - inertial off by %.3g m, skinned - previous off by "
           "%.3g m (S moves up to %.3g m per frame), ballistic - previous off by %.3g m, decayed skinned - "
           "previous off by %.3g m (X_t - S_t up to %.3g m), grasp - previous off by %.3g m (steps up to %.3g m, %zu vertex-frames pulled back)\n",
           T, worst_prev, worst_skin, skin_motion, worst_ball, worst_decay, offset, worst_grasp, held_motion, attached);
    free(X);
    free(Xp);
}

/* A skinned rollout with its latent history: stepped alone it equals two twins stepped as one
 * batch (weft_garments_step), bit for bit; a collider whose triangles collapsed fails the step
 * with DEGENERATE_MESH and leaves the garment as it was (the next step matches the twins'); no
 * step allocates. */
static void skinned_rollout(const golden *g, weft_context *ctx, const weft_model *m, uint32_t T)
{
    const size_t n = (size_t)g->V * 3, nc = (size_t)g->Vc * 3;
    weft_garment *alone = NULL, *twins[2] = {NULL, NULL};
    weft_garment_def d = garment_def(g, m, 1);
    CHECK_RESULT(weft_garment_create(ctx, &d, &alone), WEFT_OK);
    CHECK_RESULT(weft_garment_create(ctx, &d, &twins[0]), WEFT_OK);
    CHECK_RESULT(weft_garment_create(ctx, &d, &twins[1]), WEFT_OK);
    float *before = malloc(n * sizeof(float)), *collapsed = calloc(nc, sizeof(float));
    size_t allocs_before = g_allocs;
    for (uint32_t t = 1; alone && twins[0] && twins[1] && t <= T; ++t) {
        if (t == 2) {
            allocs_before = g_allocs; /* the batch's stacked scratch is made on its first step */
        }
        if (t == 3) {
            memcpy(before, weft_garment_positions(alone), n * sizeof(float));
            CHECK_RESULT(weft_garment_set_collider(alone, collapsed), WEFT_OK);
            CHECK_RESULT(weft_garment_step(alone), WEFT_ERROR_DEGENERATE_MESH);
            CHECK(strstr(weft_last_error(), "skinned prior") != NULL);
            CHECK(memcmp(before, weft_garment_positions(alone), n * sizeof(float)) == 0);
        }
        CHECK_RESULT(weft_garment_set_collider(alone, frame(&g->cpos, t + 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(twins[0], frame(&g->cpos, t + 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(twins[1], frame(&g->cpos, t + 1)), WEFT_OK);
        CHECK_RESULT(weft_garment_step(alone), WEFT_OK);
        CHECK_RESULT(weft_garments_step(twins, 2), WEFT_OK);
        for (int k = 0; k < 2; ++k) {
            CHECK_MSG(memcmp(weft_garment_positions(alone), weft_garment_positions(twins[k]), n * sizeof(float)) == 0,
                      "frame %u: batched twin %d differs from the garment stepped alone", t, k);
        }
    }
    CHECK_EQ_INT(g_allocs, allocs_before);
    free(before);
    free(collapsed);
    weft_garment_destroy(alone);
    weft_garment_destroy(twins[0]);
    weft_garment_destroy(twins[1]);
}

/* The priors "skinned" (X_t + S_{t+1} - S_t), "ballistic" and "grasp" against one another on the
 * same weights, the skinned one's collider requirement, the optional keys' ranges and an unknown
 * prior name. */
static void priors(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    const char *const patches[PRIOR_MODELS] = {
        GOLDEN_PRIOR,
        GOLDEN_PRIOR_STILL,
        "\\\"prior\\\": \\\"skinned\\\"",
        "\\\"prior\\\": \\\"ballistic\\\"",
        "\\\"prior_decay\\\": 0.5, \\\"prior\\\": \\\"skinned\\\"",
        "\\\"prior_beta\\\": 0.5, \\\"prior\\\": \\\"grasp\\\"",
        "\\\"attach_output\\\": true, \\\"prior_beta\\\": 0.5, \\\"prior\\\": \\\"grasp\\\""};
    weft_model *models[PRIOR_MODELS] = {NULL};
    bool loaded = true;
    for (int k = 0; k < PRIOR_MODELS; ++k) {
        weft_result r;
        models[k] = model_patched(ctx, patches[k], &r);
        CHECK_RESULT(r, WEFT_OK);
        loaded = loaded && models[k];
    }
    const uint32_t T = 12;
    const size_t n = (size_t)g.V * 3;
    float *S = malloc((T + 1) * n * sizeof(float));
    if (loaded && lbs_track(&g, ctx, T + 1, S)) {
        prior_differences(&g, ctx, models, S, T);
        skinned_rollout(&g, ctx, models[2], T);
    }
    /* an unknown prior is refused at load, naming the known ones */
    weft_result r;
    weft_model *bad = model_with_prior(ctx, "skinny", &r);
    CHECK(bad == NULL);
    CHECK_RESULT(r, WEFT_ERROR_BAD_METADATA);
    CHECK_MSG(strstr(weft_last_error(), "'skinned', 'ballistic' or 'grasp'") != NULL,
              "message: %s",
              weft_last_error());
    free(S);
    for (int k = 0; k < PRIOR_MODELS; ++k) {
        weft_model_destroy(models[k]);
    }
    weft_context_destroy(ctx);
    golden_free(&g);
    /* the skinned prior follows the collider: a garment without one is refused, nothing held */
    expect_create_fails(GOLDEN_PRIOR, "\\\"prior\\\": \\\"skinned\\\"", false, WEFT_ERROR_NO_COLLIDER);
    /* the ballistic prior's optional terms are range-checked at load */
    expect_create_fails(GOLDEN_PRIOR, "\\\"prior\\\": \\\"ballistic\\\", \\\"prior_beta\\\": 1.5", true,
                        WEFT_ERROR_BAD_METADATA);
    expect_create_fails(GOLDEN_PRIOR, "\\\"prior\\\": \\\"ballistic\\\", \\\"gravity_step\\\": -1", true,
                        WEFT_ERROR_BAD_METADATA);
    /* a key given twice is refused, not read either way */
    expect_create_fails(GOLDEN_PRIOR, GOLDEN_PRIOR ", \\\"prior_beta\\\": 0.5", true, WEFT_ERROR_DUPLICATE_NAME);
    /* and so is the skinned prior's decay */
    expect_create_fails("\\\"prior\\\": \\\"", "\\\"prior_decay\\\": 1.5, \\\"prior\\\": \\\"", true,
                        WEFT_ERROR_BAD_METADATA);
}

/* The golden collider (which only translates) also turning about the vertical axis through its
 * centroid, 0.03 rad per frame: a binding made against another pose then gives another
 * S_{t+1} - S_t. Frames 0 .. frames-1 into out. */
static void turning_collider(const golden *g, uint32_t frames, float *out)
{
    for (uint32_t k = 0; k < frames; ++k) {
        const float *c = frame(&g->cpos, k);
        double m[3] = {0, 0, 0};
        for (uint32_t i = 0; i < g->Vc; ++i) {
            for (int d = 0; d < 3; ++d) {
                m[d] += c[3 * i + d] / g->Vc;
            }
        }
        const double a = 0.03 * k, ca = cos(a), sa = sin(a);
        float *o = out + (size_t)k * g->Vc * 3;
        for (uint32_t i = 0; i < g->Vc; ++i) {
            const double x = c[3 * i] - m[0], z = c[3 * i + 2] - m[2];
            o[3 * i] = (float)(m[0] + ca * x + sa * z);
            o[3 * i + 1] = c[3 * i + 1];
            o[3 * i + 2] = (float)(m[2] - sa * x + ca * z);
        }
    }
}

/* A LOD garment on the golden garment and collider track `C`, starting at an LBS level, with
 * `model` for its model level; NULL when it could not be made. */
static weft_lod_garment *lod_on_golden(const golden *g, const float *C, weft_context *ctx, const weft_lod_table *table,
                                       const weft_model *const *model)
{
    weft_lod_garment_def d = weft_default_lod_garment_def();
    d.table = table;
    CHECK_RESULT(weft_lod_table_find(table, "lbs", &d.level), WEFT_OK);
    d.models = model;
    d.model_count = 1;
    d.rest_positions = g->rest.data;
    d.vertex_count = g->V;
    d.triangles = g->faces.data;
    d.triangle_count = g->F;
    d.collider_rest_positions = C + (size_t)g->Vc * 3;
    d.collider_vertex_count = g->Vc;
    d.collider_triangles = g->cfaces.data;
    d.collider_triangle_count = g->Fc;
    d.initial_positions = frame(&g->gt, 1);
    weft_lod_garment *lg = NULL;
    CHECK_RESULT(weft_lod_garment_create(ctx, &d, &lg), WEFT_OK);
    if (lg) {
        CHECK_RESULT(weft_lod_garment_set_state(lg, frame(&g->gt, 1), frame(&g->gt, 0)), WEFT_OK);
    }
    return lg;
}

/* A level switch onto a skinned-prior model level binds the garment to the collider as it is at
 * the switch, as LBS levels do (a binding against the rest pose would follow the wrong part of
 * the collider). Two LOD garments run LBS on a turning collider up to frame `at` and switch to
 * the same model level, one with the ballistic prior at beta 0 and no gravity (X_t), one with
 * "skinned"; both rebuild the same
 * latent window, so their first steps differ by S_{t+1} - S_t of an LBS garment bound at the
 * switch. */
static void skinned_lod_switch(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    static const char table_text[] =
        "level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames\n"
        "lbs,lbs,-,-,-,off,1,0.1,4.0,0.01,1,1\n"
        "golden,model,golden,fp32,-,off,1,1.0,1.0,0.03,1,1\n";
    weft_context *ctx = make_ctx();
    weft_lod_table *table = NULL;
    CHECK_RESULT(weft_lod_table_load_memory(ctx, table_text, strlen(table_text), &table), WEFT_OK);
    weft_result r;
    weft_model *models[2] = {model_patched(ctx, GOLDEN_PRIOR_STILL, &r), model_with_prior(ctx, "skinned", &r)};
    const uint32_t at = 20;
    const size_t n = (size_t)g.V * 3, nc = (size_t)g.Vc * 3;
    float *C = malloc((at + 2) * nc * sizeof(float));
    turning_collider(&g, at + 2, C);
    weft_lod_garment *lg[2] = {NULL, NULL};
    for (int k = 0; table && models[0] && models[1] && k < 2; ++k) {
        lg[k] = lod_on_golden(&g, C, ctx, table, (const weft_model *const *)&models[k]);
    }
    for (uint32_t t = 1; lg[0] && lg[1] && t < at; ++t) {
        for (int k = 0; k < 2; ++k) {
            CHECK_RESULT(weft_lod_garment_set_collider(lg[k], C + (t + 1) * nc), WEFT_OK);
            CHECK_RESULT(weft_lod_garment_step(lg[k]), WEFT_OK);
        }
    }
    uint32_t model_level = 0;
    weft_garment *gl = NULL;
    float *X = malloc(n * sizeof(float)), *S = malloc(2 * n * sizeof(float));
    if (lg[0] && lg[1] && table && weft_lod_table_find(table, "golden", &model_level) == WEFT_OK) {
        memcpy(X, weft_lod_garment_positions(lg[0]), n * sizeof(float));
        CHECK(memcmp(X, weft_lod_garment_positions(lg[1]), n * sizeof(float)) == 0);
        /* S bound as the switch binds: the positions and the collider of frame `at` */
        weft_garment_def d = garment_def(&g, NULL, at);
        d.method = WEFT_METHOD_LBS;
        d.initial_positions = X;
        d.collider_rest_positions = C + at * nc;
        CHECK_RESULT(weft_garment_create(ctx, &d, &gl), WEFT_OK);
        for (uint32_t k = 0; gl && k < 2; ++k) {
            CHECK_RESULT(weft_garment_set_collider(gl, C + (at + k) * nc), WEFT_OK);
            CHECK_RESULT(weft_garment_step(gl), WEFT_OK);
            memcpy(S + k * n, weft_garment_positions(gl), n * sizeof(float));
        }
        for (int k = 0; k < 2; ++k) {
            CHECK_RESULT(weft_lod_garment_switch(lg[k], model_level), WEFT_OK);
            CHECK_RESULT(weft_lod_garment_set_collider(lg[k], C + (at + 1) * nc), WEFT_OK);
            CHECK_RESULT(weft_lod_garment_step(lg[k]), WEFT_OK);
        }
    }
    if (gl) {
        const double e = diff_of_diffs(weft_lod_garment_positions(lg[1]), weft_lod_garment_positions(lg[0]), S + n, S,
                                       n);
        CHECK_MSG(e <= 1e-5, "after the switch, skinned - previous is off S_{t+1} - S_t by %.3g m", e);
        printf("switch onto a skinned-prior level at frame %u: skinned - previous matches the LBS binding made at "
               "the switch to %.3g m\n",
               at, e);
    }
    weft_garment_destroy(gl);
    free(C);
    free(X);
    free(S);
    for (int k = 0; k < 2; ++k) {
        weft_lod_garment_destroy(lg[k]);
        weft_model_destroy(models[k]);
    }
    weft_lod_table_destroy(table);
    weft_context_destroy(ctx);
    golden_free(&g);
}

static void bad_state_and_collider(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    weft_garment_def d = garment_def(&g, m, 1);
    weft_garment *gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (!gar) {
        weft_model_destroy(m);
        weft_context_destroy(ctx);
        golden_free(&g);
        return;
    }
    size_t n = (size_t)g.V * 3;
    float *before = malloc(n * sizeof(float));
    memcpy(before, weft_garment_positions(gar), n * sizeof(float));
    /* step without the collider of t+1 */
    CHECK_RESULT(weft_garment_step(gar), WEFT_ERROR_NO_COLLIDER);
    /* NaN state is refused and leaves the state as it was */
    float *bad = malloc(n * sizeof(float));
    memcpy(bad, frame(&g.gt, 2), n * sizeof(float));
    bad[7] = NAN;
    CHECK_RESULT(weft_garment_set_state(gar, bad, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(memcmp(before, weft_garment_positions(gar), n * sizeof(float)) == 0);
    /* NaN collider */
    float *badc = malloc((size_t)g.Vc * 3 * sizeof(float));
    memcpy(badc, frame(&g.cpos, 2), (size_t)g.Vc * 3 * sizeof(float));
    badc[0] = INFINITY;
    CHECK_RESULT(weft_garment_set_collider(gar, badc), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_garment_step(gar), WEFT_ERROR_NO_COLLIDER);
    CHECK(memcmp(before, weft_garment_positions(gar), n * sizeof(float)) == 0);
    /* a pin is honoured after the learned step: vertex 0 lands exactly on its target */
    uint32_t idx = 0;
    const float target[3] = {before[0] + 0.01f, before[1] + 0.02f, before[2] - 0.01f};
    CHECK_RESULT(weft_garment_set_pins(gar, &idx, target, 1), WEFT_OK);
    CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, 2)), WEFT_OK);
    CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
    CHECK(memcmp(weft_garment_positions(gar), target, sizeof target) == 0);
    CHECK_RESULT(weft_garment_set_pins(gar, NULL, NULL, 0), WEFT_OK);
    weft_garment_destroy(gar);

    /* out-of-range precision */
    d.precision = WEFT_PRECISION_COUNT;
    gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(gar == NULL);

    /* no model */
    d = garment_def(&g, NULL, 1);
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_ERROR_NO_MODEL);

    /* garment without a collider runs on cloth tokens alone */
    d = garment_def(&g, m, 1);
    d.collider_vertex_count = 0;
    d.collider_rest_positions = NULL;
    d.collider_triangles = NULL;
    d.collider_triangle_count = 0;
    gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (gar) {
        CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, 2)), WEFT_ERROR_NO_COLLIDER);
    }
    weft_garment_destroy(gar);
    free(before);
    free(bad);
    free(badc);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The shipped models bind (every tensor and config key checked) and step the golden garment. */
static void shipped_models_step(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    static const char *const files[] = {WEFT_SOURCE_DIR "/tools/train/models/game.safetensors",
                                        WEFT_SOURCE_DIR "/tools/train/models/game_k16.safetensors",
                                        WEFT_SOURCE_DIR "/tools/train/models/drop.safetensors",
                                        WEFT_SOURCE_DIR "/tools/train/models/garment.safetensors",
                                        WEFT_SOURCE_DIR "/tools/train/models/gripper.safetensors"};
    weft_context *ctx = make_ctx();
    for (size_t f = 0; f < sizeof files / sizeof files[0]; ++f) {
        weft_model *m = NULL;
        CHECK_RESULT(weft_model_load_file(ctx, files[f], &m), WEFT_OK);
        weft_garment *gar = NULL;
        weft_garment_def d = garment_def(&g, m, 1);
        if (m) {
            CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
        }
        if (gar) {
            CHECK_RESULT(weft_garment_set_state(gar, frame(&g.gt, 1), frame(&g.gt, 0)), WEFT_OK);
            for (size_t t = 1; t < 6; ++t) {
                CHECK_RESULT(weft_garment_set_collider(gar, frame(&g.cpos, t + 1)), WEFT_OK);
                CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
            }
            const float *x = weft_garment_positions(gar);
            int finite = 1;
            for (size_t i = 0; i < (size_t)g.V * 3; ++i) {
                finite &= isfinite(x[i]) != 0;
            }
            CHECK(finite);
        }
        weft_garment_destroy(gar);
        weft_model_destroy(m);
    }
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* Rolls the golden garment out for T frames from ground-truth frames (0, 1) at a precision and
 * copies each frame's positions into out (T x V x 3). False if the garment could not be made. */
static bool rollout_into(const golden *g, weft_context *ctx, const weft_model *m, weft_precision prec, uint32_t T,
                         float *out)
{
    weft_garment_def d = garment_def(g, m, 1);
    d.precision = prec;
    weft_garment *gar = NULL;
    CHECK_RESULT(weft_garment_create(ctx, &d, &gar), WEFT_OK);
    if (!gar) {
        return false;
    }
    const size_t n = (size_t)g->V * 3;
    CHECK_RESULT(weft_garment_set_state(gar, frame(&g->gt, 1), frame(&g->gt, 0)), WEFT_OK);
    for (uint32_t t = 0; t < T; ++t) {
        CHECK_RESULT(weft_garment_set_collider(gar, frame(&g->cpos, 2 + t)), WEFT_OK);
        CHECK_RESULT(weft_garment_step(gar), WEFT_OK);
        memcpy(out + t * n, weft_garment_positions(gar), n * sizeof(float));
    }
    weft_garment_destroy(gar);
    return true;
}

/* fp16 and int8 against fp32 on the teacher-forced frames and a 20-frame rollout, and the int8
 * path bit-identical on every ISA level this CPU runs (scalar oracle included). */
static void reduced_precision(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    static const weft_isa isas[] = {WEFT_ISA_SCALAR, WEFT_ISA_AVX2, WEFT_ISA_AVX512, WEFT_ISA_NEON};
    weft_context *ctxs[4] = {NULL};
    weft_model *models[4] = {NULL};
    uint32_t nctx = 0;
    for (int i = 0; i < 4; ++i) {
        weft_context_def cd = weft_default_context_def();
        cd.isa = isas[i];
        if (weft_context_create(&cd, &ctxs[nctx]) != WEFT_OK) {
            continue;
        }
        CHECK_RESULT(weft_model_load_file(ctxs[nctx], DATA "golden_model.safetensors", &models[nctx]), WEFT_OK);
        if (!models[nctx]) {
            weft_context_destroy(ctxs[nctx]);
            continue;
        }
        nctx++;
    }
    CHECK(nctx >= 1);
    const size_t n = (size_t)g.V * 3;
    const uint32_t T = 20;
    float *ref = malloc(n * sizeof(float) * T), *out = malloc(n * sizeof(float) * T);
    double worst[3] = {0, 0, 0};
    for (int prec = 0; prec < 3 && nctx > 0; ++prec) {
        for (uint32_t c = 0; c < nctx; ++c) {
            if (!rollout_into(&g, ctxs[c], models[c], (weft_precision)prec, T, c == 0 ? ref : out)) {
                continue;
            }
            if (c > 0 && prec == WEFT_PRECISION_INT8) {
                CHECK_MSG(memcmp(ref, out, n * T * sizeof(float)) == 0, "int8 rollout differs on isa %s",
                          weft_isa_name(weft_context_isa(ctxs[c])));
            }
        }
        /* accuracy against the PyTorch fp32 rollout (rollout.npy: frames 2..) */
        for (uint32_t t = 0; t < T && t < g.rollout.shape[0]; ++t) {
            double rel, relm;
            compare(ref + t * n, frame(&g.rollout, t), frame(&g.gt, 1), n, &rel, &relm);
            worst[prec] = fmax(worst[prec], rel);
        }
    }
    printf("20-frame rollout vs PyTorch fp32, max relative error: fp32 %.3g, fp16 %.3g, int8 %.3g (%u ISA levels "
           "bit-identical at int8)\n",
           worst[0], worst[1], worst[2], nctx);
    CHECK(worst[0] <= 1e-3);
    CHECK(worst[1] <= 2e-3);
    CHECK(worst[2] <= 2.5e-2);
    free(ref);
    free(out);
    for (uint32_t c = 0; c < nctx; ++c) {
        weft_model_destroy(models[c]);
        weft_context_destroy(ctxs[c]);
    }
    golden_free(&g);
}

/* Files written by `weft quantize` run exactly like the fp32 file at the same precision: the
 * runtime quantises with the same function, so int8 (and fp16) rollouts are bit-identical. */
static void quantized_files(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    weft_context *ctx = make_ctx();
    size_t size = 0;
    void *bytes = read_file(DATA "golden_model.safetensors", &size);
    CHECK(bytes != NULL);
    weft_model *fp32 = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &fp32), WEFT_OK);
    const size_t n = (size_t)g.V * 3;
    float *a = malloc(n * sizeof(float) * 10), *b = malloc(n * sizeof(float) * 10);
    for (int fmt = 0; fmt < 2 && bytes && fp32; ++fmt) {
        weft_quant_def qd = weft_default_quant_def();
        qd.format = fmt == 0 ? WEFT_QUANT_INT8 : WEFT_QUANT_FP16;
        void *qbytes = NULL;
        size_t qsize = 0;
        CHECK_RESULT(weft_quantize_memory(ctx, &qd, bytes, size, &qbytes, &qsize, NULL), WEFT_OK);
        weft_model *qm = NULL;
        CHECK_RESULT(weft_model_load_memory(ctx, qbytes, qsize, &qm), WEFT_OK);
        if (!qm) {
            weft_quant_buffer_free(ctx, qbytes, qsize);
            continue;
        }
        CHECK(weft_model_get_info(qm).precision == (fmt == 0 ? WEFT_PRECISION_INT8 : WEFT_PRECISION_FP16));
        /* every precision runs from the quantised file; the matching one equals the fp32 file's */
        for (int prec = 0; prec < 3; ++prec) {
            rollout_into(&g, ctx, fp32, (weft_precision)prec, 10, a);
            rollout_into(&g, ctx, qm, (weft_precision)prec, 10, b);
            bool matching = (fmt == 0 && prec == WEFT_PRECISION_INT8) || (fmt == 1 && prec == WEFT_PRECISION_FP16);
            if (matching) {
                CHECK_MSG(memcmp(a, b, n * 10 * sizeof(float)) == 0, "%s file at its own precision differs from "
                          "the fp32 file", fmt == 0 ? "int8" : "fp16");
            } else {
                double rel, relm;
                compare(b + 9 * n, a + 9 * n, frame(&g.gt, 1), n, &rel, &relm);
                CHECK_MSG(rel < 3e-2, "%s file at precision %d: relative difference %.3g", fmt == 0 ? "int8" : "fp16",
                          prec, rel);
            }
        }
        weft_model_destroy(qm);
        weft_quant_buffer_free(ctx, qbytes, qsize);
    }
    free(a);
    free(b);
    free(bytes);
    weft_model_destroy(fp32);
    weft_context_destroy(ctx);
    golden_free(&g);
}

/* The host's job hook: chunks run on two threads (in reverse order on the second), and the
 * result is bit-identical to the serial run at every precision. */
typedef struct hook_job {
    weft_task_fn *task;
    void *ctx;
    uint32_t count, chunk;
    int calls;
} hook_job;

static void *hook_thread(void *arg)
{
    hook_job *j = arg;
    uint32_t nchunks = (j->count + j->chunk - 1) / j->chunk;
    for (uint32_t c = nchunks; c-- > nchunks / 2;) { /* upper half, last chunk first */
        uint32_t b = c * j->chunk, e = b + j->chunk < j->count ? b + j->chunk : j->count;
        j->task(b, e, 1, j->ctx);
    }
    return NULL;
}

static int g_hook_calls;

static void two_thread_parallel_for(weft_task_fn *task, uint32_t count, uint32_t min_chunk, void *task_context,
                                    void *user)
{
    (void)user;
    g_hook_calls++;
    hook_job job = {task, task_context, count, min_chunk, 0};
    pthread_t th;
    bool threaded = pthread_create(&th, NULL, hook_thread, &job) == 0;
    uint32_t nchunks = (count + min_chunk - 1) / min_chunk;
    for (uint32_t c = 0; c < nchunks / 2; ++c) {
        uint32_t b = c * min_chunk, e = b + min_chunk < count ? b + min_chunk : count;
        task(b, e, 0, task_context);
    }
    if (threaded) {
        pthread_join(th, NULL);
    } else {
        hook_thread(&job);
    }
}

static void parallel_for_hook(void)
{
    golden g;
    if (!golden_load(&g)) {
        CHECK(!"golden tensors missing");
        return;
    }
    const size_t n = (size_t)g.V * 3;
    float *serial = malloc(n * sizeof(float) * 5), *hooked = malloc(n * sizeof(float) * 5);
    for (int prec = 0; prec < 3; ++prec) {
        for (int use_hook = 0; use_hook < 2; ++use_hook) {
            weft_context_def cd = weft_default_context_def();
            if (use_hook) {
                cd.parallel_for = two_thread_parallel_for;
                cd.max_workers = 2;
            }
            weft_context *ctx = NULL;
            CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
            weft_model *m = NULL;
            CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
            int calls_before = g_hook_calls;
            if (m) {
                rollout_into(&g, ctx, m, (weft_precision)prec, 5, use_hook ? hooked : serial);
            }
            if (use_hook) {
                CHECK_MSG(g_hook_calls > calls_before, "the hook was never called");
                CHECK_MSG(memcmp(serial, hooked, n * 5 * sizeof(float)) == 0,
                          "precision %d: parallel_for changes the result", prec);
            }
            weft_model_destroy(m);
            weft_context_destroy(ctx);
        }
    }
    free(serial);
    free(hooked);
    golden_free(&g);
}

TEST_MAIN(TEST_CASE(teacher_forced_parity), TEST_CASE(shipped_game_parity), TEST_CASE(shipped_models_step),
          TEST_CASE(rollout_parity), TEST_CASE(shipped_drop_parity), TEST_CASE(shipped_garment_parity), TEST_CASE(shipped_gripper_parity),
          TEST_CASE(skinned_prior_reuse),
          TEST_CASE(skinned_teacher_forced_parity), TEST_CASE(skinned_rollout_parity),
          TEST_CASE(bad_model_files), TEST_CASE(priors), TEST_CASE(skinned_lod_switch),
          TEST_CASE(bad_state_and_collider), TEST_CASE(reduced_precision),
          TEST_CASE(quantized_files), TEST_CASE(parallel_for_hook))
