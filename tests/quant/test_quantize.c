#define _POSIX_C_SOURCE 200809L /* mkdtemp */
/* The offline quantiser: per-tensor decisions, dequantisation error bounds, metadata, the
 * report, and bad input (NaN, wrong dtype, already quantised, paths) writing nothing. */
#include "test.h"
#include "quant.h"
#include "io/safetensors.h"
#include "kernels/qkernels.h"
#include "model/model.h"

#include <unistd.h>

static weft_context *g_ctx;

static float g_fc1[32 * 24], g_bias[32], g_embed[8 * 3], g_queries[16 * 32];

/* A small fp32 model: one eligible weight, a bias, a tiny layer and a config-kept tensor. */
static void make_model(void **bytes, size_t *size, weft_dtype fc1_dtype, const void *fc1_data, bool quantized_meta)
{
    test_rng rng = {5};
    for (size_t i = 0; i < 32 * 24; ++i) {
        g_fc1[i] = test_rng_float(&rng, -0.3f, 0.3f);
    }
    for (size_t i = 0; i < 32; ++i) {
        g_bias[i] = test_rng_float(&rng, -0.1f, 0.1f);
    }
    for (size_t i = 0; i < 8 * 3; ++i) {
        g_embed[i] = test_rng_float(&rng, -1.0f, 1.0f);
    }
    for (size_t i = 0; i < 16 * 32; ++i) {
        g_queries[i] = test_rng_float(&rng, -1.0f, 1.0f);
    }
    static const uint64_t s_fc1[2] = {32, 24}, s_bias[1] = {32}, s_embed[2] = {8, 3}, s_q[2] = {16, 32};
    weft_st_tensor_in t[4] = {
        {"enc.fc1.weight", fc1_dtype, 2, s_fc1, fc1_data ? fc1_data : g_fc1},
        {"enc.fc1.bias", WEFT_DTYPE_F32, 1, s_bias, g_bias},
        {"embed.weight", WEFT_DTYPE_F32, 2, s_embed, g_embed},
        {"queries", WEFT_DTYPE_F32, 2, s_q, g_queries},
    };
    weft_st_meta meta[4] = {
        {"name", "quant-test"},
        {"config", "{\"width\": 32}"},
        {"keep_fp32", "other,queries"},
        {"quantization", "{}"},
    };
    weft_result r = weft__st_write_memory(g_ctx, t, 4, meta, quantized_meta ? 4 : 3, bytes, size);
    CHECK_RESULT(r, WEFT_OK);
}

static void setup(void)
{
    if (!g_ctx) {
        weft_context_def def = weft_default_context_def();
        weft_context_create(&def, &g_ctx);
    }
}

static void test_int8(void)
{
    setup();
    void *in;
    size_t in_size;
    make_model(&in, &in_size, WEFT_DTYPE_F32, NULL, false);
    weft_quant_def def = weft_default_quant_def();
    void *out;
    size_t out_size;
    weft_quant_report rep;
    weft_result r = weft_quantize_memory(g_ctx, &def, in, in_size, &out, &out_size, &rep);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    CHECK_EQ_INT(rep.tensor_count, 4);
    CHECK_EQ_INT(rep.quantized_count, 1);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, out, out_size, &m), WEFT_OK);
    if (m) {
        const weft_tensor *q, *s, *b, *e, *qq;
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.fc1.weight.q8", WEFT_DTYPE_I8, &q, 32, 24), WEFT_OK);
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.fc1.weight.scale", WEFT_DTYPE_F32, &s, 32), WEFT_OK);
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.fc1.bias", WEFT_DTYPE_F32, &b, 32), WEFT_OK);
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "embed.weight", WEFT_DTYPE_F32, &e, 8, 3), WEFT_OK);
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "queries", WEFT_DTYPE_F32, &qq, 16, 32), WEFT_OK);
        CHECK(weft__model_find(m, "enc.fc1.weight") == NULL);
        if (q && s) {
            const int8_t *qd = q->data;
            const float *sd = s->data;
            int bad = 0;
            for (int n = 0; n < 32; ++n) {
                for (int k = 0; k < 24; ++k) {
                    float d = (float)qd[n * 24 + k] * sd[n];
                    bad += fabsf(d - g_fc1[n * 24 + k]) > 0.5001f * sd[n];
                }
            }
            CHECK_EQ_INT(bad, 0);
        }
        if (b) {
            CHECK(memcmp(b->data, g_bias, sizeof g_bias) == 0); /* kept bit-for-bit */
        }
        CHECK(strcmp(weft__model_metadata(m, "precision"), "int8") == 0);
        CHECK(strcmp(weft__model_metadata(m, "name"), "quant-test") == 0);
        const char *qm = weft__model_metadata(m, "quantization");
        CHECK(qm && strstr(qm, "\"enc.fc1.weight\":\"int8-per-channel-symmetric\""));
        CHECK(qm && strstr(qm, "\"queries\":\"fp32 (kept by request)\""));
        CHECK(qm && strstr(qm, "\"embed.weight\":\"fp32 (small: 8x3)\""));
        CHECK(qm && strstr(qm, "\"enc.fc1.bias\":\"fp32 (rank 1)\""));
        weft_model_destroy(m);
    }
    for (uint32_t i = 0; i < rep.tensor_count; ++i) {
        if (strcmp(rep.tensors[i].name, "enc.fc1.weight") == 0) {
            CHECK(rep.tensors[i].rel_error > 0.0 && rep.tensors[i].rel_error < 0.01);
        } else {
            CHECK(rep.tensors[i].error_max == 0.0);
        }
    }
    /* Quantising the output again is refused. */
    void *again = NULL;
    size_t again_size = 0;
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, out, out_size, &again, &again_size, NULL),
                 WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(again == NULL);
    CHECK(strstr(weft_last_error(), "already quantised") != NULL);
    weft_quant_report_free(&rep);
    weft_quant_buffer_free(g_ctx, out, out_size);
    weft_quant_buffer_free(g_ctx, in, in_size);
}

static void test_fp16(void)
{
    setup();
    void *in;
    size_t in_size;
    make_model(&in, &in_size, WEFT_DTYPE_F32, NULL, false);
    weft_quant_def def = weft_default_quant_def();
    def.format = WEFT_QUANT_FP16;
    void *out;
    size_t out_size;
    weft_result r = weft_quantize_memory(g_ctx, &def, in, in_size, &out, &out_size, NULL);
    CHECK_RESULT(r, WEFT_OK);
    if (r != WEFT_OK) {
        return;
    }
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(g_ctx, out, out_size, &m), WEFT_OK);
    if (m) {
        const weft_tensor *h;
        CHECK_RESULT(WEFT_MODEL_REQUIRE(m, "enc.fc1.weight", WEFT_DTYPE_F16, &h, 32, 24), WEFT_OK);
        if (h) {
            const uint16_t *hd = h->data;
            int bad = 0;
            for (int i = 0; i < 32 * 24; ++i) {
                float d = weft_f16_to_f32(hd[i]);
                bad += fabsf(d - g_fc1[i]) > fabsf(g_fc1[i]) * (1.0f / 2048.0f) + 3e-8f;
            }
            CHECK_EQ_INT(bad, 0);
        }
        CHECK(strcmp(weft__model_metadata(m, "precision"), "fp16") == 0);
        weft_model_info info = weft_model_get_info(m);
        CHECK(info.precision == WEFT_PRECISION_FP16);
        weft_model_destroy(m);
    }
    CHECK(out_size < in_size);
    weft_quant_buffer_free(g_ctx, out, out_size);
    weft_quant_buffer_free(g_ctx, in, in_size);
}

static void test_bad_input_writes_nothing(void)
{
    setup();
    weft_quant_def def = weft_default_quant_def();
    void *in, *out = NULL;
    size_t in_size, out_size = 0;
    /* NaN weight */
    float nan_fc1[32 * 24];
    memcpy(nan_fc1, g_fc1, sizeof nan_fc1);
    nan_fc1[100] = NAN;
    make_model(&in, &in_size, WEFT_DTYPE_F32, nan_fc1, false);
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, in, in_size, &out, &out_size, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(strstr(weft_last_error(), "enc.fc1.weight") != NULL);
    CHECK(out == NULL);

    /* files: NaN input -> no output file */
    char dir[] = "/tmp/weft-quant-XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char in_path[256], out_path[256];
    snprintf(in_path, sizeof in_path, "%s/in.safetensors", dir);
    snprintf(out_path, sizeof out_path, "%s/out.safetensors", dir);
    FILE *f = fopen(in_path, "wb");
    fwrite(in, 1, in_size, f);
    fclose(f);
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_ERROR_NOT_FINITE);
    CHECK(access(out_path, F_OK) != 0);
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, in_path, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    weft_quant_buffer_free(g_ctx, in, in_size);

    /* already-quantised metadata */
    make_model(&in, &in_size, WEFT_DTYPE_F32, NULL, true);
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, in, in_size, &out, &out_size, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    weft_quant_buffer_free(g_ctx, in, in_size);

    /* an F16 tensor in the input */
    uint16_t half[32 * 24];
    for (int i = 0; i < 32 * 24; ++i) {
        half[i] = weft_f32_to_f16(g_fc1[i]);
    }
    make_model(&in, &in_size, WEFT_DTYPE_F16, half, false);
    CHECK_RESULT(weft_quantize_memory(g_ctx, &def, in, in_size, &out, &out_size, NULL), WEFT_ERROR_TENSOR_DTYPE);
    weft_quant_buffer_free(g_ctx, in, in_size);

    /* a valid file quantises through the file API; missing input fails with IO */
    make_model(&in, &in_size, WEFT_DTYPE_F32, NULL, false);
    f = fopen(in_path, "wb");
    fwrite(in, 1, in_size, f);
    fclose(f);
    weft_quant_buffer_free(g_ctx, in, in_size);
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, in_path, out_path, NULL), WEFT_OK);
    CHECK(access(out_path, F_OK) == 0);
    char missing[300];
    snprintf(missing, sizeof missing, "%s/missing.safetensors", dir);
    CHECK_RESULT(weft_quantize_file(g_ctx, &def, missing, out_path, NULL), WEFT_ERROR_IO);
    remove(in_path);
    remove(out_path);
    rmdir(dir);
    /* a def not made by the default function */
    weft_quant_def raw = {0};
    CHECK_RESULT(weft_quantize_file(g_ctx, &raw, in_path, out_path, NULL), WEFT_ERROR_INVALID_ARGUMENT);
}

TEST_MAIN(TEST_CASE(test_int8), TEST_CASE(test_fp16), TEST_CASE(test_bad_input_writes_nothing))
