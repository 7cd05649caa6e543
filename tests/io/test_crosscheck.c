/* Cross-check against an independent implementation (tests/io/make_safetensors.py, numpy):
 *   argv[1]  a file the Python side wrote; every value is checked against the shared formulas
 *   argv[2]  where weft's writer puts the same tensors, for the Python side to verify */
#include "io/safetensors.h"
#include "model/model.h"
#include "test.h"

static const char *g_in_path, *g_out_path;

static float half_to_float(uint16_t h)
{
    int exp = (h >> 10) & 31, mant = h & 1023;
    float v = exp == 0 ? ldexpf((float)mant, -24) : ldexpf((float)(mant | 1024), exp - 25);
    return (h & 0x8000) ? -v : v;
}

static float bf16_to_float(uint16_t b)
{
    uint32_t bits = (uint32_t)b << 16;
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static const weft_tensor *expect_tensor(const weft_model *m, const char *name, weft_dtype dtype, uint32_t rank,
                                        const uint64_t *dims)
{
    const weft_tensor *t = NULL;
    CHECK_RESULT(weft__model_require(m, name, dtype, rank, dims, &t), WEFT_OK);
    return t;
}

static void test_python_file(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, g_in_path, &m), WEFT_OK);
    if (!m) {
        weft_context_destroy(ctx);
        return;
    }
    weft_model_info info = weft_model_get_info(m);
    CHECK(strcmp(info.name, "py-crosscheck") == 0);
    CHECK(strcmp(info.architecture, "none") == 0);
    CHECK(m->arch == NULL);
    CHECK_EQ_INT(info.tensor_count, 8);
    CHECK_EQ_INT(info.parameter_count, 15 + 8 + 7 + 12 + 5 + 9 + 1);

    const weft_tensor *t = expect_tensor(m, "w.f32", WEFT_DTYPE_F32, 2, (const uint64_t[]){3, 5});
    for (int i = 0; t && i < 15; ++i) {
        CHECK(((const float *)t->data)[i] == (float)i * 0.25f - 1.0f);
    }
    t = expect_tensor(m, "w.f16", WEFT_DTYPE_F16, 2, (const uint64_t[]){4, 2});
    for (int i = 0; t && i < 8; ++i) {
        CHECK(half_to_float(((const uint16_t *)t->data)[i]) == ((float)i - 3.0f) * 0.5f);
    }
    t = expect_tensor(m, "w.bf16", WEFT_DTYPE_BF16, 1, (const uint64_t[]){7});
    for (int i = 0; t && i < 7; ++i) {
        CHECK(bf16_to_float(((const uint16_t *)t->data)[i]) == (float)i * 2.0f - 5.0f);
    }
    t = expect_tensor(m, "q.i8", WEFT_DTYPE_I8, 3, (const uint64_t[]){2, 3, 2});
    for (int i = 0; t && i < 12; ++i) {
        CHECK(((const int8_t *)t->data)[i] == i - 6);
    }
    t = expect_tensor(m, "idx.i32", WEFT_DTYPE_I32, 1, (const uint64_t[]){5});
    for (int i = 0; t && i < 5; ++i) {
        CHECK(((const int32_t *)t->data)[i] == i * 100000 - 7);
    }
    t = expect_tensor(m, "mask.u8", WEFT_DTYPE_U8, 1, (const uint64_t[]){9});
    for (int i = 0; t && i < 9; ++i) {
        CHECK(((const uint8_t *)t->data)[i] == (uint8_t)(i * 29 % 256));
    }
    t = expect_tensor(m, "scalar", WEFT_DTYPE_F32, 0, NULL);
    CHECK(t && *(const float *)t->data == 3.5f);
    t = expect_tensor(m, "empty", WEFT_DTYPE_F32, 2, (const uint64_t[]){0, 4});
    CHECK(t && t->count == 0);

    int64_t latents = 0;
    double ratio = 0;
    const char *tag = NULL;
    const double *dims = NULL;
    uint32_t ndims = 0;
    bool flag = false;
    CHECK_RESULT(weft__model_config_int(m, "latent_count", &latents), WEFT_OK);
    CHECK_RESULT(weft__model_config_number(m, "ratio", &ratio), WEFT_OK);
    CHECK_RESULT(weft__model_config_string(m, "tag", &tag), WEFT_OK);
    CHECK_RESULT(weft__model_config_array(m, "dims", &dims, &ndims), WEFT_OK);
    CHECK_RESULT(weft__model_config_bool(m, "flag", &flag), WEFT_OK);
    CHECK(latents == 16 && ratio == 0.5 && tag && strcmp(tag, "x") == 0 && flag);
    CHECK(ndims == 3 && dims && dims[0] == 1 && dims[1] == 2 && dims[2] == 3);

    /* Write the same content with weft's writer for the Python side to verify. */
    weft_st_tensor_in out[8];
    for (uint32_t i = 0; i < m->tensor_count && i < 8; ++i) {
        const weft_tensor *s = &m->tensors[i];
        out[i] = (weft_st_tensor_in){s->name, s->dtype, s->rank, s->shape, s->data};
    }
    weft_st_meta meta[] = {
        {"name", "py-crosscheck"},
        {"architecture", "none"},
        {"config", "{\"latent_count\":16,\"ratio\":0.5,\"tag\":\"x\",\"dims\":[1,2,3],\"flag\":true}"},
    };
    CHECK_RESULT(weft__st_write_file(ctx, g_out_path, out, m->tensor_count, meta, 3), WEFT_OK);
    weft_model_destroy(m);
    weft_context_destroy(ctx);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s PYTHON_FILE OUTPUT_FILE\n", argv[0]);
        return 2;
    }
    g_in_path = argv[1];
    g_out_path = argv[2];
    static const test_case_ cases[] = {TEST_CASE(test_python_file)};
    return test_run_(cases, 1, 1, argv);
}
