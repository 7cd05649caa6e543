/* The calibration observer (weft__ct_set_observer): every linear layer is seen exactly once per
 * step with the right shapes, the output it reports is the layer's own (no residual), and
 * installing it changes nothing in the step's result. */
#include "model/model.h"
#include "model/transformer.h"
#include "model_data.h"
#include "test.h"
#include "weft.h"

#define MAX_SEEN 128

typedef struct seen {
    char name[WEFT_CT_NAME_MAX];
    uint32_t rows, in_cols, out_cols, calls;
} seen;

typedef struct watch {
    const weft_model *model;
    seen layers[MAX_SEEN];
    uint32_t count;
    uint32_t total_calls;
    double worst_rel;           /* own output against a double-precision recomputation */
    char worst_name[WEFT_CT_NAME_MAX];
    float head[4096 * 3];       /* last dec_head output */
    uint32_t head_rows;
} watch;

static void on_layer(const char *name, const float *in, uint32_t rows, uint32_t in_cols, const float *out,
                     uint32_t out_cols, void *user)
{
    watch *w = user;
    w->total_calls++;
    seen *s = NULL;
    for (uint32_t i = 0; i < w->count; ++i) {
        if (strcmp(w->layers[i].name, name) == 0) {
            s = &w->layers[i];
        }
    }
    if (!s && w->count < MAX_SEEN) {
        s = &w->layers[w->count++];
        snprintf(s->name, sizeof s->name, "%s", name);
    }
    if (!s) {
        return;
    }
    s->rows = rows;
    s->in_cols = in_cols;
    s->out_cols = out_cols;
    s->calls++;
    if (strcmp(name, "dec_head") == 0 && (size_t)rows * out_cols <= sizeof w->head / sizeof w->head[0]) {
        memcpy(w->head, out, (size_t)rows * out_cols * sizeof(float));
        w->head_rows = rows;
    }
    /* Layers without an activation (all but the MLPs' fc1): out must be in W^T + b exactly as
     * the layer computes it, with no residual folded in. */
    size_t len = strlen(name);
    if (len >= 3 && strcmp(name + len - 3, "fc1") == 0) {
        return;
    }
    char wname[96], bname[96];
    snprintf(wname, sizeof wname, "%s.weight", name);
    snprintf(bname, sizeof bname, "%s.bias", name);
    const weft_tensor *W = weft__model_find(w->model, wname), *B = weft__model_find(w->model, bname);
    CHECK_MSG(W && B, "layer '%s' has no weight/bias tensor", name);
    if (!W || !B || W->shape[0] != out_cols || W->shape[1] != in_cols) {
        CHECK_MSG(W && W->shape[0] == out_cols && W->shape[1] == in_cols, "layer '%s' shape", name);
        return;
    }
    const float *wd = W->data, *bd = B->data;
    double err = 0, mag = 1e-6;
    for (uint32_t r = 0; r < rows; ++r) {
        for (uint32_t o = 0; o < out_cols; ++o) {
            double acc = bd[o];
            for (uint32_t k = 0; k < in_cols; ++k) {
                acc += (double)in[(size_t)r * in_cols + k] * wd[(size_t)o * in_cols + k];
            }
            err = fmax(err, fabs(acc - out[(size_t)r * out_cols + o]));
            mag = fmax(mag, fabs(acc));
        }
    }
    if (err / mag > w->worst_rel) {
        w->worst_rel = err / mag;
        snprintf(w->worst_name, sizeof w->worst_name, "%s", name);
    }
}

static uint32_t expect_rows(const char *name, uint32_t N, uint32_t K, uint32_t hk, uint32_t L, bool *known)
{
    *known = true;
    char last[32];
    snprintf(last, sizeof last, "tmp.%u.", L - 1);
    if (strncmp(name, "enc_cloth", 9) == 0 || strncmp(name, "enc_gnn", 7) == 0 || strncmp(name, "dec_gnn", 7) == 0 ||
        strncmp(name, "dec_rest", 8) == 0 || strcmp(name, "dec_head") == 0 || strncmp(name, "dec_xattn.q", 11) == 0 ||
        strncmp(name, "dec_xattn.o", 11) == 0 || strncmp(name, "dec_xattn.ff", 12) == 0) {
        return N;
    }
    if (strcmp(name, "dec_xattn.k") == 0 || strcmp(name, "dec_xattn.v") == 0) {
        return K;
    }
    if (strncmp(name, "enc_xattn.", 10) == 0 && strcmp(name, "enc_xattn.k") && strcmp(name, "enc_xattn.v")) {
        return K;
    }
    if (strncmp(name, "tmp.", 4) == 0) {
        const char *lin = strrchr(name, '.') + 1;
        if (strcmp(lin, "k") == 0 || strcmp(lin, "v") == 0) {
            return hk;
        }
        return strncmp(name, last, strlen(last)) == 0 ? K : hk;
    }
    *known = false; /* enc_coll and enc_xattn.k/v: the cropped collider token count varies */
    return 0;
}

static void every_linear_once_per_step(void)
{
    size_t nrest, V, nfaces, F, ncpos, T, ngt, T2, ncf, Fc;
    float *rest = load_npy("rest", &nrest, &V), *cpos = load_npy("c_pos", &ncpos, &T),
          *gt = load_npy("gt_pos", &ngt, &T2);
    uint32_t *faces = load_npy("faces", &nfaces, &F), *cfaces = load_npy("cfaces", &ncf, &Fc);
    CHECK(rest && cpos && gt && faces && cfaces);
    weft_context *ctx = NULL;
    weft_model *m = NULL;
    weft_garment *a = NULL, *b = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    if (ctx) {
        CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    }
    const uint32_t Vc = (uint32_t)(ncpos / T / 3);
    weft_garment_def d = weft_default_garment_def();
    d.model = m;
    d.ccd.enabled = false;
    d.rest_positions = rest;
    d.vertex_count = (uint32_t)V;
    d.triangles = faces;
    d.triangle_count = (uint32_t)F;
    d.collider_rest_positions = cpos;
    d.collider_vertex_count = Vc;
    d.collider_triangles = cfaces;
    d.collider_triangle_count = (uint32_t)Fc;
    d.initial_positions = gt + (size_t)V * 3;
    weft_ct_config c = {0};
    if (m) {
        CHECK_RESULT(weft__ct_bind(m, &c, NULL), WEFT_OK);
        CHECK_RESULT(weft_garment_create(ctx, &d, &a), WEFT_OK);
        CHECK_RESULT(weft_garment_create(ctx, &d, &b), WEFT_OK);
    }
    static watch w;
    memset(&w, 0, sizeof w);
    w.model = m;
    if (a && b) {
        CHECK_RESULT(weft__ct_set_observer(a, on_layer, &w), WEFT_OK);
        const size_t n = V * 3;
        CHECK_RESULT(weft_garment_set_state(a, gt + n, gt), WEFT_OK);
        CHECK_RESULT(weft_garment_set_state(b, gt + n, gt), WEFT_OK);
        const uint32_t steps = 4;
        for (uint32_t t = 0; t < steps; ++t) {
            CHECK_RESULT(weft_garment_set_collider(a, cpos + (size_t)(2 + t) * Vc * 3), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(b, cpos + (size_t)(2 + t) * Vc * 3), WEFT_OK);
            CHECK_RESULT(weft_garment_step(a), WEFT_OK);
            CHECK_RESULT(weft_garment_step(b), WEFT_OK);
            CHECK_MSG(memcmp(weft_garment_positions(a), weft_garment_positions(b), n * sizeof(float)) == 0,
                      "step %u: the observed garment differs from the unobserved one", t);
        }
        /* 41 layers in the golden config: 3 MLPs, 2 x 2 GNN MLPs, 2 cross blocks of 6, L x 7, head. */
        const uint32_t expected_layers = 6 + 4 * c.gnn_layers + 12 + 7 * c.L + 1;
        CHECK_EQ_INT(w.count, expected_layers);
        CHECK_EQ_INT(w.total_calls, expected_layers * steps);
        const uint32_t hk = c.history * c.K;
        for (uint32_t i = 0; i < w.count; ++i) {
            const seen *s = &w.layers[i];
            CHECK_MSG(s->calls == steps, "layer '%s' seen %u times in %u steps", s->name, s->calls, steps);
            bool known;
            uint32_t rows = expect_rows(s->name, (uint32_t)V, c.K, hk, c.L, &known);
            if (known) {
                CHECK_MSG(s->rows == rows, "layer '%s': %u rows, expected %u", s->name, s->rows, rows);
            } else {
                CHECK_MSG(s->rows >= 1 && s->rows <= V + Fc, "layer '%s': %u rows", s->name, s->rows);
            }
            const weft_tensor *W = NULL;
            char wname[96];
            snprintf(wname, sizeof wname, "%s.weight", s->name);
            W = weft__model_find(m, wname);
            CHECK_MSG(W && W->shape[0] == s->out_cols && W->shape[1] == s->in_cols, "layer '%s' widths", s->name);
        }
        printf("observer: %u layers x %u steps; own outputs within %.3g (relative, worst '%s') of a double "
               "recomputation\n",
               w.count, steps, w.worst_rel, w.worst_name);
        CHECK_MSG(w.worst_rel < 1e-4, "layer '%s': observed output off by %.3g", w.worst_name, w.worst_rel);
        CHECK_EQ_INT(w.head_rows, V);

        /* Removing the observer stops the calls. */
        CHECK_RESULT(weft__ct_set_observer(a, NULL, NULL), WEFT_OK);
        const uint32_t before = w.total_calls;
        CHECK_RESULT(weft_garment_set_collider(a, cpos + (size_t)(2 + steps) * Vc * 3), WEFT_OK);
        CHECK_RESULT(weft_garment_step(a), WEFT_OK);
        CHECK_EQ_INT(w.total_calls, before);
    }
    /* Other methods are refused. */
    weft_garment *x = NULL;
    weft_garment_def dx = d;
    dx.method = WEFT_METHOD_LBS;
    dx.model = NULL;
    if (ctx && weft_garment_create(ctx, &dx, &x) == WEFT_OK) {
        CHECK_RESULT(weft__ct_set_observer(x, on_layer, &w), WEFT_ERROR_INVALID_ARGUMENT);
        weft_garment_destroy(x);
    }
    CHECK_RESULT(weft__ct_set_observer(NULL, on_layer, &w), WEFT_ERROR_INVALID_ARGUMENT);
    weft_garment_destroy(a);
    weft_garment_destroy(b);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(rest);
    free(cpos);
    free(gt);
    free(faces);
    free(cfaces);
}

/* At int8 the observer also sees every layer once, and the step is unchanged. */
static void int8_observed_unchanged(void)
{
    size_t nrest, V, nfaces, F, ncpos, T, ngt, T2, ncf, Fc;
    float *rest = load_npy("rest", &nrest, &V), *cpos = load_npy("c_pos", &ncpos, &T),
          *gt = load_npy("gt_pos", &ngt, &T2);
    uint32_t *faces = load_npy("faces", &nfaces, &F), *cfaces = load_npy("cfaces", &ncf, &Fc);
    CHECK(rest && cpos && gt && faces && cfaces);
    weft_context *ctx = NULL;
    weft_model *m = NULL;
    weft_garment *a = NULL, *b = NULL;
    weft_context_def cd = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    if (ctx) {
        CHECK_RESULT(weft_model_load_file(ctx, DATA "golden_model.safetensors", &m), WEFT_OK);
    }
    const uint32_t Vc = (uint32_t)(ncpos / T / 3);
    weft_garment_def d = weft_default_garment_def();
    d.model = m;
    d.precision = WEFT_PRECISION_INT8;
    d.rest_positions = rest;
    d.vertex_count = (uint32_t)V;
    d.triangles = faces;
    d.triangle_count = (uint32_t)F;
    d.collider_rest_positions = cpos;
    d.collider_vertex_count = Vc;
    d.collider_triangles = cfaces;
    d.collider_triangle_count = (uint32_t)Fc;
    d.initial_positions = gt;
    if (m) {
        CHECK_RESULT(weft_garment_create(ctx, &d, &a), WEFT_OK);
        CHECK_RESULT(weft_garment_create(ctx, &d, &b), WEFT_OK);
    }
    static watch w;
    memset(&w, 0, sizeof w);
    w.model = m;
    if (a && b) {
        CHECK_RESULT(weft__ct_set_observer(b, on_layer, &w), WEFT_OK);
        for (uint32_t t = 0; t < 3; ++t) {
            CHECK_RESULT(weft_garment_set_collider(a, cpos + (size_t)(1 + t) * Vc * 3), WEFT_OK);
            CHECK_RESULT(weft_garment_set_collider(b, cpos + (size_t)(1 + t) * Vc * 3), WEFT_OK);
            CHECK_RESULT(weft_garment_step(a), WEFT_OK);
            CHECK_RESULT(weft_garment_step(b), WEFT_OK);
            CHECK(memcmp(weft_garment_positions(a), weft_garment_positions(b), V * 3 * sizeof(float)) == 0);
        }
        for (uint32_t i = 0; i < w.count; ++i) {
            CHECK_MSG(w.layers[i].calls == 3, "int8: layer '%s' seen %u times", w.layers[i].name, w.layers[i].calls);
        }
        CHECK(w.count > 0);
    }
    weft_garment_destroy(a);
    weft_garment_destroy(b);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
    free(rest);
    free(cpos);
    free(gt);
    free(faces);
    free(cfaces);
}

TEST_MAIN(TEST_CASE(every_linear_once_per_step), TEST_CASE(int8_observed_unchanged))
