/* The model object's internal API used by forward passes: tensor lookup, dtype/shape
 * requirements, metadata and config accessors, the architecture table, and the public info. */
#include "io/safetensors.h"
#include "model/model.h"
#include "test.h"
#include <math.h>
#include <stdio.h>
#include <string.h>

static weft_context *g_ctx;

/* Builds a model in memory with weft's writer. */
static weft_model *load(const weft_st_tensor_in *t, uint32_t n, const weft_st_meta *meta, uint32_t meta_count,
                        weft_result expect)
{
    void *bytes = NULL;
    size_t size = 0;
    CHECK_RESULT(weft__st_write_memory(g_ctx, t, n, meta, meta_count, &bytes, &size), WEFT_OK);
    weft_model *m = NULL;
    if (bytes) {
        CHECK_RESULT(weft_model_load_memory(g_ctx, bytes, size, &m), expect);
        weft__free(g_ctx, bytes, size);
    }
    return m;
}

static float g_enc_w[16 * 8], g_enc_b[16], g_scale[4] = {0.5f, 0.25f, 1.0f, 0.0f};
static int8_t g_q8[4 * 16];
static uint16_t g_h[4] = {0x3c00, 0x4000, 0xbc00, 0};
static const uint64_t g_enc_w_shape[] = {16, 8}, g_enc_b_shape[] = {16}, g_q8_shape[] = {4, 16},
                      g_scale_shape[] = {4}, g_h_shape[] = {2, 2};

static const weft_st_tensor_in g_tensors[] = {
    {"enc.w", WEFT_DTYPE_F32, 2, g_enc_w_shape, g_enc_w},
    {"enc.b", WEFT_DTYPE_F32, 1, g_enc_b_shape, g_enc_b},
    {"dec.w.q8", WEFT_DTYPE_I8, 2, g_q8_shape, g_q8},
    {"dec.w.scale", WEFT_DTYPE_F32, 1, g_scale_shape, g_scale},
    {"h", WEFT_DTYPE_F16, 2, g_h_shape, g_h},
};

static const weft_st_meta g_meta[] = {
    {"name", "lookup test"},
    {"architecture", "lookup-test"}, /* not in the table: a generic weights file */
    {"config", "{\"latent_count\": 16, \"width\": 8, \"heads\": 2.5, \"act\": \"gelu\", \"use_ccd\": false, "
               "\"modes\": [4, 4.5], \"neg\": -3, \"big\": 1e20, \"empty\": []}"},
};

static void test_find_and_require(void)
{
    weft_model *m = load(g_tensors, 5, g_meta, 3, WEFT_OK);
    if (!m) {
        return;
    }
    CHECK(weft__model_find(m, "enc.w") != NULL);
    CHECK(weft__model_find(m, "enc") == NULL);
    CHECK(weft__model_find(m, "") == NULL);
    CHECK(weft__model_find(m, NULL) == NULL);
    CHECK(weft__model_find(NULL, "enc.w") == NULL);
    const weft_tensor *t = weft__model_find(m, "enc.b");
    CHECK(t && t->rank == 1 && t->shape[0] == 16 && t->count == 16 && t->bytes == 64);

    const weft_tensor *sentinel = (const weft_tensor *)(uintptr_t)0x40;
    const weft_tensor *out = sentinel;
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, &out, 16, 8), WEFT_OK);
    CHECK(out == weft__model_find(m, "enc.w"));
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, NULL, WEFT_DIM_ANY, 8), WEFT_OK);

    out = sentinel;
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.x", WEFT_DTYPE_F32, &out, 16, 8), WEFT_ERROR_MISSING_TENSOR);
    CHECK(strstr(weft_last_error(), "'enc.x'") != NULL);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F16, &out, 16, 8), WEFT_ERROR_TENSOR_DTYPE);
    CHECK(strstr(weft_last_error(), "'enc.w' is F32, expected F16") != NULL);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, &out, 16, 9), WEFT_ERROR_TENSOR_SHAPE);
    CHECK(strstr(weft_last_error(), "'enc.w' has shape [16, 8], expected [16, 9]") != NULL);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, &out, 16), WEFT_ERROR_TENSOR_SHAPE);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, &out, 16, 8, 1), WEFT_ERROR_TENSOR_SHAPE);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.b", WEFT_DTYPE_F32, &out, WEFT_DIM_ANY, WEFT_DIM_ANY),
                 WEFT_ERROR_TENSOR_SHAPE);
    CHECK(strstr(weft_last_error(), "expected [*, *]") != NULL);
    CHECK_RESULT(weft__model_require(m, "enc.b", WEFT_DTYPE_F32, 0, NULL, &out), WEFT_ERROR_TENSOR_SHAPE);
    CHECK_RESULT(weft__model_require(m, "enc.b", WEFT_DTYPE_F32, 9, g_enc_w_shape, &out), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft__model_require(NULL, "enc.b", WEFT_DTYPE_F32, 1, g_enc_b_shape, &out),
                 WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(out == sentinel);

    /* Shapes checked against the config, the way a forward pass validates at load. */
    uint32_t latents = 0, width = 0;
    CHECK_RESULT(weft__model_config_u32(m, "latent_count", 1, 4096, &latents), WEFT_OK);
    CHECK_RESULT(weft__model_config_u32(m, "width", 1, 4096, &width), WEFT_OK);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.w", WEFT_DTYPE_F32, NULL, latents, width), WEFT_OK);
    CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "dec.w.q8", WEFT_DTYPE_I8, NULL, 4, latents), WEFT_OK);
    weft_model_destroy(m);
}

static void test_config_and_metadata(void)
{
    weft_model *m = load(g_tensors, 5, g_meta, 3, WEFT_OK);
    if (!m) {
        return;
    }
    CHECK(strcmp(weft__model_metadata(m, "name"), "lookup test") == 0);
    CHECK(weft__model_metadata(m, "missing") == NULL);
    CHECK(weft__model_metadata(NULL, "name") == NULL);

    int64_t i = 0;
    double d = 0;
    uint32_t u = 7;
    bool b = true;
    const char *s = NULL;
    const double *arr = NULL;
    uint32_t n = 99;
    CHECK_RESULT(weft__model_config_int(m, "latent_count", &i), WEFT_OK);
    CHECK_EQ_INT(i, 16);
    CHECK_RESULT(weft__model_config_int(m, "neg", &i), WEFT_OK);
    CHECK_EQ_INT(i, -3);
    CHECK_RESULT(weft__model_config_number(m, "heads", &d), WEFT_OK);
    CHECK(d == 2.5);
    CHECK_RESULT(weft__model_config_bool(m, "use_ccd", &b), WEFT_OK);
    CHECK(!b);
    CHECK_RESULT(weft__model_config_string(m, "act", &s), WEFT_OK);
    CHECK(s && strcmp(s, "gelu") == 0);
    CHECK_RESULT(weft__model_config_array(m, "modes", &arr, &n), WEFT_OK);
    CHECK(n == 2 && arr && arr[0] == 4.0 && arr[1] == 4.5);
    CHECK_RESULT(weft__model_config_array(m, "empty", &arr, &n), WEFT_OK);
    CHECK_EQ_INT(n, 0);
    CHECK(weft__model_config_find(m, "width") && weft__model_config_find(m, "width")->kind == WEFT_CONFIG_NUMBER);

    /* Failures name the key and leave outputs alone. */
    i = 123;
    CHECK_RESULT(weft__model_config_int(m, "heads", &i), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "'heads'") != NULL);
    CHECK_RESULT(weft__model_config_int(m, "big", &i), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_int(m, "missing_key", &i), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "'missing_key' is missing") != NULL);
    CHECK_RESULT(weft__model_config_int(m, "act", &i), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "'act' is not a number") != NULL);
    CHECK_EQ_INT(i, 123);
    CHECK_RESULT(weft__model_config_u32(m, "neg", 0, 10, &u), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_u32(m, "latent_count", 17, 20, &u), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "outside [17, 20]") != NULL);
    CHECK_EQ_INT(u, 7);
    CHECK_RESULT(weft__model_config_bool(m, "width", &b), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_string(m, "width", &s), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_array(m, "width", &arr, &n), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_number(m, "modes", &d), WEFT_ERROR_BAD_METADATA);
    CHECK_RESULT(weft__model_config_int(m, NULL, &i), WEFT_ERROR_INVALID_ARGUMENT);
    weft_model_destroy(m);

    /* No config at all: every lookup fails cleanly. */
    weft_st_meta plain[] = {{"architecture", "something-else"}};
    m = load(g_tensors, 2, plain, 1, WEFT_OK);
    if (m) {
        CHECK(m->arch == NULL);
        CHECK_RESULT(weft__model_config_int(m, "latent_count", &i), WEFT_ERROR_BAD_METADATA);
        CHECK(weft__model_config_find(m, "latent_count") == NULL);
        weft_model_destroy(m);
    }
}

static void test_config_rejects(void)
{
    static const struct {
        const char *config;
        weft_result expect;
        const char *needle;
    } cases[] = {
        {"[1, 2]", WEFT_ERROR_BAD_METADATA, "'{'"},
        {"{\"a\": 1", WEFT_ERROR_BAD_METADATA, "not valid JSON"},
        {"{\"a\": 1} x", WEFT_ERROR_BAD_METADATA, "not valid JSON"},
        {"{\"a\": null}", WEFT_ERROR_BAD_METADATA, "'a'"},
        {"{\"a\": {\"b\": 1}}", WEFT_ERROR_BAD_METADATA, "'a'"},
        {"{\"a\": [1, \"x\"]}", WEFT_ERROR_BAD_METADATA, "'a'"},
        {"{\"a\": [[1]]}", WEFT_ERROR_BAD_METADATA, "'a'"},
        {"{\"a\": 1e999}", WEFT_ERROR_BAD_METADATA, "'a'"},
        {"{\"a\": 1, \"a\": 1}", WEFT_ERROR_DUPLICATE_NAME, "'a'"},
        {"{\"a\": [[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]}", WEFT_ERROR_BAD_METADATA, "deeper"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        weft_st_meta meta[] = {{"architecture", "lookup-test"}, {"config", cases[i].config}};
        weft_model *m = load(g_tensors, 1, meta, 2, cases[i].expect);
        CHECK_MSG(m == NULL, "config %zu loaded", i);
        CHECK_MSG(strstr(weft_last_error(), cases[i].needle) != NULL, "config %zu: '%s' lacks '%s'", i,
                  weft_last_error(), cases[i].needle);
        weft_model_destroy(m);
    }
    weft_st_meta ok[] = {{"config", "{}"}};
    weft_model *m = load(g_tensors, 1, ok, 1, WEFT_OK);
    CHECK(m && m->arch == NULL && m->config_count == 0);
    weft_model_destroy(m);
}

static void test_info_and_architectures(void)
{
    weft_model *m = load(g_tensors, 5, g_meta, 3, WEFT_OK);
    if (m) {
        weft_model_info info = weft_model_get_info(m);
        CHECK(strcmp(info.name, "lookup test") == 0);
        CHECK(strcmp(info.architecture, "lookup-test") == 0);
        CHECK_EQ_INT(info.precision, WEFT_PRECISION_INT8);
        CHECK_EQ_INT(info.tensor_count, 5);
        CHECK_EQ_INT(info.parameter_count, 128 + 16 + 64 + 4 + 4);
        CHECK_EQ_INT(info.weight_bytes, 512 + 64 + 64 + 16 + 8);
        CHECK(m->arch == NULL);
        weft_model_destroy(m);
    }
    /* F16 without I8 is FP16; F32 only is FP32; no metadata gives empty strings. */
    weft_st_tensor_in half[] = {g_tensors[0], g_tensors[4]};
    m = load(half, 2, NULL, 0, WEFT_OK);
    if (m) {
        weft_model_info info = weft_model_get_info(m);
        CHECK_EQ_INT(info.precision, WEFT_PRECISION_FP16);
        CHECK(strcmp(info.name, "") == 0 && strcmp(info.architecture, "") == 0);
        CHECK(m->arch == NULL);
        weft_model_destroy(m);
    }
    m = load(g_tensors, 2, NULL, 0, WEFT_OK);
    if (m) {
        CHECK_EQ_INT(weft_model_get_info(m).precision, WEFT_PRECISION_FP32);
        weft_model_destroy(m);
    }
    weft_model_info none = weft_model_get_info(NULL);
    CHECK(none.name && none.architecture && none.tensor_count == 0);
    weft_model_destroy(NULL);
    CHECK(weft__architecture_find("clothtransformer") != NULL);
    CHECK(weft__architecture_find("fnopt") != NULL);
    CHECK(weft__architecture_find("ClothTransformer") == NULL);
    CHECK(weft__architecture_find("lookup-test") == NULL);
    /* A known architecture is validated at load: without its config it is refused. */
    weft_st_meta ct[] = {{"architecture", "clothtransformer"}};
    m = load(g_tensors, 2, ct, 1, WEFT_ERROR_BAD_METADATA);
    CHECK(m == NULL);
    CHECK(strstr(weft_last_error(), "clothtransformer") != NULL);
    CHECK(weft__architecture_find(NULL) == NULL);
}

static void setup(void)
{
    weft_context_def def = weft_default_context_def();
    CHECK_RESULT(weft_context_create(&def, &g_ctx), WEFT_OK);
    for (int i = 0; i < 16 * 8; ++i) g_enc_w[i] = (float)i / 128.0f;
    for (int i = 0; i < 16; ++i) g_enc_b[i] = (float)i;
    for (int i = 0; i < 64; ++i) g_q8[i] = (int8_t)((i * 37) % 255 - 127);
}

static void teardown(void) { weft_context_destroy(g_ctx); }

/* weft_model_load_file_as refuses another architecture from the header alone: a file whose
 * tensor holds NaN (which a full load reports) is refused for its architecture instead. */
static void test_load_as_reads_the_header_only(void)
{
    static float nan_w[4] = {0.0f, 1.0f, 0.0f, 0.0f};
    nan_w[2] = NAN;
    static const uint64_t shape[] = {4};
    const weft_st_tensor_in t[] = {{"w", WEFT_DTYPE_F32, 1, shape, nan_w}};
    const weft_st_meta other[] = {{"architecture", "fnopt"}};
    const char *path = WEFT_BINARY_DIR "/tests/load_as.safetensors";
    CHECK_RESULT(weft__st_write_file(g_ctx, path, t, 1, other, 1), WEFT_OK);
    weft_model *m = (weft_model *)(uintptr_t)0x40;
    CHECK_RESULT(weft_model_load_file_as(g_ctx, path, "clothtransformer", &m), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "architecture 'fnopt', not 'clothtransformer' (no tensor was read)") != NULL);
    CHECK(m == (weft_model *)(uintptr_t)0x40);
    CHECK_RESULT(weft_model_load_file(g_ctx, path, &m), WEFT_ERROR_NOT_FINITE); /* a full load reads it */
    CHECK_RESULT(weft_model_load_file_as(g_ctx, path, "fnopt", &m), WEFT_ERROR_NOT_FINITE);
    CHECK_RESULT(weft_model_load_file_as(g_ctx, path, NULL, &m), WEFT_ERROR_INVALID_ARGUMENT);
    /* no architecture at all */
    CHECK_RESULT(weft__st_write_file(g_ctx, path, t, 1, NULL, 0), WEFT_OK);
    CHECK_RESULT(weft_model_load_file_as(g_ctx, path, "clothtransformer", &m), WEFT_ERROR_BAD_METADATA);
    CHECK(strstr(weft_last_error(), "'(none)'") != NULL);
    remove(path);
}

/* Metadata "deploy": the settings a model runs with, in weft_model_garment_def; the shipped
 * garment model carries the worn-garment recipe; bad values fail the load by name. */
static void test_deployed_settings(void)
{
    weft_st_meta meta[] = {{"architecture", "lookup-test"},
                           {"deploy", "{\"strain_limit\": 0.1, \"tether_distance\": 0.08, \"push\": 0.005, \"ccd\": false}"}};
    weft_model *m = load(g_tensors, 1, meta, 2, WEFT_OK);
    if (m) {
        const weft_garment_def d = weft_model_garment_def(m);
        CHECK(d.method == WEFT_METHOD_MODEL && d.model == m && d.precision == weft_model_get_info(m).precision);
        CHECK(d.strain.limit == 0.1f && d.tethers.distance == 0.08f && d.collision.push == 0.005f && !d.ccd.enabled);
        weft_model_destroy(m);
    }
    /* only some keys: the rest stay weft_default_garment_def's */
    weft_st_meta some[] = {{"deploy", "{\"push\": 0.01}"}};
    m = load(g_tensors, 1, some, 1, WEFT_OK);
    if (m) {
        const weft_garment_def d = weft_model_garment_def(m), base = weft_default_garment_def();
        CHECK(d.collision.push == 0.01f && d.strain.limit == base.strain.limit && d.ccd.enabled == base.ccd.enabled);
        weft_model_destroy(m);
    }
    static const struct {
        const char *deploy, *needle;
    } bad[] = {{"{\"strain_limit\": 11}", "strain_limit"}, {"{\"push\": -1}", "push"},
               {"{\"ccd\": 1}", "ccd"},                     {"{\"tethers\": 0.1}", "unknown key 'tethers'"},
               {"[1]", "not a JSON object"},                  {"{\"push\": \"0.1\"}", "push"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        weft_st_meta b[] = {{"deploy", bad[i].deploy}};
        m = load(g_tensors, 1, b, 1, WEFT_ERROR_BAD_METADATA);
        CHECK_MSG(m == NULL && strstr(weft_last_error(), bad[i].needle) != NULL, "deploy %zu: %s", i, weft_last_error());
        weft_model_destroy(m);
    }
    const weft_garment_def none = weft_model_garment_def(NULL), base = weft_default_garment_def();
    CHECK(none.method == base.method && none.model == NULL);
    /* the shipped worn-garment model, each precision */
    static const char *const files[] = {"garment.safetensors", "garment.fp16.safetensors", "garment.int8.safetensors"};
    for (size_t i = 0; i < 3; ++i) {
        char path[1024];
        snprintf(path, sizeof path, "%s/tools/train/models/%s", WEFT_SOURCE_DIR, files[i]);
        weft_model *g = NULL;
        CHECK_RESULT(weft_model_load_file(g_ctx, path, &g), WEFT_OK);
        if (g) {
            const weft_garment_def d = weft_model_garment_def(g);
            CHECK_MSG(d.strain.limit == 0.1f && d.tethers.distance == 0.08f && d.collision.push == 0.005f &&
                          !d.ccd.enabled && d.precision == (weft_precision)i,
                      "%s: strain %g tethers %g push %g ccd %d precision %d", files[i], (double)d.strain.limit,
                      (double)d.tethers.distance, (double)d.collision.push, d.ccd.enabled, (int)d.precision);
            weft_model_destroy(g);
        }
    }
}

TEST_MAIN(TEST_CASE(setup), TEST_CASE(test_find_and_require), TEST_CASE(test_config_and_metadata),
          TEST_CASE(test_config_rejects), TEST_CASE(test_info_and_architectures),
          TEST_CASE(test_load_as_reads_the_header_only), TEST_CASE(test_deployed_settings), TEST_CASE(teardown))
