/* safetensors reader and writer: round trips through memory and files, and a handcrafted
 * corruption matrix where every broken file must fail with its own result, a message naming
 * the tensor or field, and the caller's out-pointer untouched. */
#include "io/safetensors.h"
#include "model/model.h"
#include "test.h"

#include <stdint.h>

static weft_context *make_context(void)
{
    weft_context_def def = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    return ctx;
}

/* A file image: u64 LE header length, the header text, then data_len data bytes. */
typedef struct image {
    uint8_t bytes[4096];
    size_t size;
} image;

static void make_image(image *im, const char *header, size_t data_len)
{
    size_t n = strlen(header);
    if (8 + n + data_len > sizeof im->bytes) {
        fprintf(stderr, "test image too large\n");
        abort();
    }
    for (int i = 0; i < 8; ++i) {
        im->bytes[i] = (uint8_t)((uint64_t)n >> (8 * i));
    }
    memcpy(im->bytes + 8, header, n);
    memset(im->bytes + 8 + n, 0, data_len); /* zeros are finite in every dtype */
    im->size = 8 + n + data_len;
}

static const char *temp_path(const char *leaf)
{
    static char path[512];
    snprintf(path, sizeof path, "%s/tests/%s", WEFT_BINARY_DIR, leaf);
    return path;
}

static void write_bytes(const char *path, const void *bytes, size_t size)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (f) {
        CHECK(fwrite(bytes, 1, size, f) == size);
        fclose(f);
    }
}

typedef struct bad_case {
    const char *label;
    const char *header;
    size_t data_len;
    weft_result expect;
    const char *needle; /* must appear in weft_last_error() */
} bad_case;

static const bad_case g_bad_cases[] = {
    /* header text */
    {"not json", "{not json}", 0, WEFT_ERROR_HEADER_JSON, "not valid JSON"},
    {"not an object", "[1, 2, 3]", 0, WEFT_ERROR_HEADER_JSON, "'{'"},
    {"leading space", " {}", 0, WEFT_ERROR_HEADER_JSON, "'{'"},
    {"junk after json", "{}xx", 0, WEFT_ERROR_HEADER_JSON, "after the header"},
    {"unterminated", "{\"w\":{\"dtype\":\"F32\"", 0, WEFT_ERROR_HEADER_JSON, "JSON"},
    {"invalid utf8", "{\"w\xff\":{}}", 0, WEFT_ERROR_HEADER_JSON, "UTF-8"},
    {"overlong utf8", "{\"w\xc0\xaf\":{}}", 0, WEFT_ERROR_HEADER_JSON, "UTF-8"},
    {"escaped nul", "{\"w\\u0000x\":{\"dtype\":\"U8\",\"shape\":[],\"data_offsets\":[0,1]}}", 1,
     WEFT_ERROR_HEADER_JSON, "NUL"},
    {"deep nesting", "{\"w\":[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]}", 0, WEFT_ERROR_HEADER_JSON, "deeper"},
    /* entries */
    {"entry not object", "{\"w\":[1]}", 0, WEFT_ERROR_HEADER_JSON, "'w'"},
    {"entry is string", "{\"w\":\"F32\"}", 0, WEFT_ERROR_HEADER_JSON, "'w'"},
    {"empty name", "{\"\":{\"dtype\":\"U8\",\"shape\":[1],\"data_offsets\":[0,1]}}", 1, WEFT_ERROR_HEADER_JSON,
     "empty name"},
    {"unknown field", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4],\"x\":1}}", 4,
     WEFT_ERROR_HEADER_JSON, "'x'"},
    {"missing dtype", "{\"w\":{\"shape\":[1],\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_UNKNOWN_DTYPE, "'w'"},
    {"missing shape", "{\"w\":{\"dtype\":\"F32\",\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_BAD_SHAPE, "'w'"},
    {"missing offsets", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1]}}", 4, WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"unknown dtype", "{\"w\":{\"dtype\":\"F64\",\"shape\":[1],\"data_offsets\":[0,8]}}", 8,
     WEFT_ERROR_UNKNOWN_DTYPE, "'F64'"},
    {"dtype not string", "{\"w\":{\"dtype\":4,\"shape\":[1],\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_UNKNOWN_DTYPE,
     "'w'"},
    {"lowercase dtype", "{\"w\":{\"dtype\":\"f32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 4,
     WEFT_ERROR_UNKNOWN_DTYPE, "'w'"},
    {"duplicate field", "{\"w\":{\"dtype\":\"F32\",\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 4,
     WEFT_ERROR_DUPLICATE_NAME, "'dtype'"},
    /* shapes */
    {"negative dim", "{\"w\":{\"dtype\":\"F32\",\"shape\":[-1],\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_BAD_SHAPE,
     "'w'"},
    {"negative zero dim", "{\"w\":{\"dtype\":\"F32\",\"shape\":[-0],\"data_offsets\":[0,0]}}", 0,
     WEFT_ERROR_BAD_SHAPE, "'w'"},
    {"float dim", "{\"w\":{\"dtype\":\"F32\",\"shape\":[3.5],\"data_offsets\":[0,12]}}", 12, WEFT_ERROR_BAD_SHAPE,
     "'w'"},
    {"huge dim", "{\"w\":{\"dtype\":\"U8\",\"shape\":[9007199254740993],\"data_offsets\":[0,1]}}", 1,
     WEFT_ERROR_BAD_SHAPE, "'w'"},
    {"exponent dim", "{\"w\":{\"dtype\":\"U8\",\"shape\":[1e300],\"data_offsets\":[0,1]}}", 1, WEFT_ERROR_BAD_SHAPE,
     "'w'"},
    {"string dim", "{\"w\":{\"dtype\":\"U8\",\"shape\":[\"4\"],\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_BAD_SHAPE,
     "'w'"},
    {"shape not list", "{\"w\":{\"dtype\":\"U8\",\"shape\":4,\"data_offsets\":[0,4]}}", 4, WEFT_ERROR_BAD_SHAPE,
     "'w'"},
    {"rank 9", "{\"w\":{\"dtype\":\"U8\",\"shape\":[1,1,1,1,1,1,1,1,1],\"data_offsets\":[0,1]}}", 1,
     WEFT_ERROR_BAD_SHAPE, "'w'"},
    {"count overflow", "{\"w\":{\"dtype\":\"U8\",\"shape\":[1099511627776,1099511627776],\"data_offsets\":[0,1]}}",
     1, WEFT_ERROR_SIZE_OVERFLOW, "'w'"},
    {"bytes overflow", "{\"w\":{\"dtype\":\"F32\",\"shape\":[2147483648,2147483648],\"data_offsets\":[0,1]}}", 1,
     WEFT_ERROR_SIZE_OVERFLOW, "'w'"},
    {"size mismatch", "{\"w\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,4]}}", 4,
     WEFT_ERROR_SIZE_MISMATCH, "'w'"},
    /* offsets and layout */
    {"offsets reversed", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,0]}}", 4,
     WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"offsets one value", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4]}}", 4,
     WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"offsets three values", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4,8]}}", 4,
     WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"offsets negative", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[-4,0]}}", 4,
     WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"offsets float", "{\"w\":{\"dtype\":\"U8\",\"shape\":[1],\"data_offsets\":[0.5,1.5]}}", 2,
     WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"offsets outside",
     "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]},"
     "\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[100,104]}}",
     8, WEFT_ERROR_BAD_OFFSETS, "'w'"},
    {"data truncated", "{\"w\":{\"dtype\":\"F32\",\"shape\":[4],\"data_offsets\":[0,16]}}", 12,
     WEFT_ERROR_FILE_TRUNCATED, "'w'"},
    {"overlap",
     "{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]},"
     "\"w\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[4,12]}}",
     12, WEFT_ERROR_OVERLAP, "'w'"},
    {"same range",
     "{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]},"
     "\"w\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]}}",
     8, WEFT_ERROR_OVERLAP, "'w'"},
    {"hole",
     "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]},"
     "\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[8,12]}}",
     12, WEFT_ERROR_OVERLAP, "'w'"},
    {"hole at start", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}", 8, WEFT_ERROR_OVERLAP,
     "'w'"},
    {"trailing bytes", "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 8, WEFT_ERROR_OVERLAP,
     "'w'"},
    {"trailing bytes no tensors", "{}", 3, WEFT_ERROR_OVERLAP, "trailing"},
    /* names and metadata */
    {"duplicate name",
     "{\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]},"
     "\"w\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}",
     8, WEFT_ERROR_DUPLICATE_NAME, "'w'"},
    {"duplicate metadata key", "{\"__metadata__\":{\"k\":\"a\",\"k\":\"b\"}}", 0, WEFT_ERROR_DUPLICATE_NAME, "'k'"},
    {"two metadata objects", "{\"__metadata__\":{},\"__metadata__\":{}}", 0, WEFT_ERROR_DUPLICATE_NAME,
     "__metadata__"},
    {"metadata value number", "{\"__metadata__\":{\"k\":1}}", 0, WEFT_ERROR_BAD_METADATA, "'k'"},
    {"metadata value object", "{\"__metadata__\":{\"k\":{\"x\":\"y\"}}}", 0, WEFT_ERROR_BAD_METADATA, "'k'"},
    {"metadata not object", "{\"__metadata__\":\"x\"}", 0, WEFT_ERROR_BAD_METADATA, "__metadata__"},
    /* model-level rules (runtime/model) */
    {"config not json", "{\"__metadata__\":{\"config\":\"{oops\"}}", 0, WEFT_ERROR_BAD_METADATA, "config"},
    {"config nested object", "{\"__metadata__\":{\"config\":\"{\\\"a\\\":{\\\"b\\\":1}}\"}}", 0,
     WEFT_ERROR_BAD_METADATA, "'a'"},
    {"config duplicate key", "{\"__metadata__\":{\"config\":\"{\\\"a\\\":1,\\\"a\\\":2}\"}}", 0,
     WEFT_ERROR_DUPLICATE_NAME, "'a'"},
    {"known architecture without config", "{\"__metadata__\":{\"architecture\":\"clothtransformer\"}}", 0,
     WEFT_ERROR_BAD_METADATA, "clothtransformer"},
    {"q8 without scale", "{\"w.q8\":{\"dtype\":\"I8\",\"shape\":[2],\"data_offsets\":[0,2]}}", 2,
     WEFT_ERROR_MISSING_TENSOR, "'w.scale'"},
    {"q8 wrong dtype", "{\"w.q8\":{\"dtype\":\"U8\",\"shape\":[2],\"data_offsets\":[0,2]}}", 2,
     WEFT_ERROR_TENSOR_DTYPE, "'w.q8'"},
    {"scale wrong shape",
     "{\"w.q8\":{\"dtype\":\"I8\",\"shape\":[2,2],\"data_offsets\":[0,4]},"
     "\"w.scale\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}",
     8, WEFT_ERROR_TENSOR_SHAPE, "'w.scale'"},
    {"scale wrong dtype", "{\"w.scale\":{\"dtype\":\"F16\",\"shape\":[2],\"data_offsets\":[0,4]}}", 4,
     WEFT_ERROR_TENSOR_DTYPE, "'w.scale'"},
};

static void check_bad_image(weft_context *ctx, const char *label, const uint8_t *bytes, size_t size,
                            weft_result expect, const char *needle)
{
    weft_model *sentinel = (weft_model *)(uintptr_t)0x1234;
    weft_model *m = sentinel;
    weft_result r = weft_model_load_memory(ctx, bytes, size, &m);
    CHECK_MSG(r == expect, "[%s] memory: got %s (%s), expected %s", label, weft_result_string(r), weft_last_error(),
              weft_result_string(expect));
    CHECK_MSG(m == sentinel, "[%s] out pointer changed on failure", label);
    CHECK_MSG(strstr(weft_last_error(), needle) != NULL, "[%s] message '%s' lacks '%s'", label, weft_last_error(),
              needle);

    const char *path = temp_path("io_safetensors_case.safetensors");
    write_bytes(path, bytes, size);
    m = sentinel;
    r = weft_model_load_file(ctx, path, &m);
    CHECK_MSG(r == expect, "[%s] file: got %s (%s), expected %s", label, weft_result_string(r), weft_last_error(),
              weft_result_string(expect));
    CHECK_MSG(m == sentinel, "[%s] out pointer changed on failure (file)", label);
    remove(path);
}

static void test_corruption_matrix(void)
{
    weft_context *ctx = make_context();
    image im;
    for (size_t i = 0; i < sizeof g_bad_cases / sizeof g_bad_cases[0]; ++i) {
        const bad_case *c = &g_bad_cases[i];
        make_image(&im, c->header, c->data_len);
        check_bad_image(ctx, c->label, im.bytes, im.size, c->expect, c->needle);
    }
    weft_context_destroy(ctx);
}

/* Files broken before the JSON: length field truncated, too large, beyond the file. */
static void test_length_field(void)
{
    weft_context *ctx = make_context();
    uint8_t b[64] = {0};
    check_bad_image(ctx, "empty file", b, 0, WEFT_ERROR_FILE_TRUNCATED, "8-byte");
    check_bad_image(ctx, "3-byte file", b, 3, WEFT_ERROR_FILE_TRUNCATED, "8-byte");
    check_bad_image(ctx, "7-byte file", b, 7, WEFT_ERROR_FILE_TRUNCATED, "8-byte");
    check_bad_image(ctx, "zero header", b, 8, WEFT_ERROR_HEADER_JSON, "'{'");

    uint64_t n = 100000001u; /* one over the cap */
    for (int i = 0; i < 8; ++i) {
        b[i] = (uint8_t)(n >> (8 * i));
    }
    check_bad_image(ctx, "header over cap", b, sizeof b, WEFT_ERROR_HEADER_TOO_LARGE, "cap");
    memset(b, 0xff, 8);
    check_bad_image(ctx, "header length 2^64-1", b, sizeof b, WEFT_ERROR_HEADER_TOO_LARGE, "cap");
    memset(b, 0, 8);
    b[0] = 57; /* 57 > 64 - 8 */
    check_bad_image(ctx, "header beyond file", b, sizeof b, WEFT_ERROR_HEADER_TOO_LARGE, "exceeds the 56 bytes");

    weft_model *m = (weft_model *)(uintptr_t)0x1234;
    CHECK_RESULT(weft_model_load_file(ctx, "/nonexistent/weft/model.safetensors", &m), WEFT_ERROR_IO);
    CHECK(strstr(weft_last_error(), "/nonexistent/weft/model.safetensors") != NULL);
    CHECK(m == (weft_model *)(uintptr_t)0x1234);
    CHECK_RESULT(weft_model_load_file(ctx, WEFT_BINARY_DIR, &m), WEFT_ERROR_IO); /* a directory */
    CHECK_RESULT(weft_model_load_file(ctx, NULL, &m), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_model_load_memory(ctx, NULL, 10, &m), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_model_load_memory(NULL, b, sizeof b, &m), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(weft_model_load_memory(ctx, b, sizeof b, NULL), WEFT_ERROR_INVALID_ARGUMENT);
    CHECK(m == (weft_model *)(uintptr_t)0x1234);
    weft_context_destroy(ctx);
}

/* Every readable dtype, rank 0, empty tensors, padding and an empty header load. */
static void test_accepted_variants(void)
{
    static const char *const ok_headers[] = {
        "{}",
        "{}      ",
        "{ }\n\t\r ",
        "{\"w\":{\"dtype\":\"BF16\",\"shape\":[2,2],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"F16\",\"shape\":[4],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"I8\",\"shape\":[8],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"U8\",\"shape\":[2,2,2],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"I32\",\"shape\":[2],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"F32\",\"shape\":[1,1,1,1,1,1,1,2],\"data_offsets\":[0,8]}}",
        "{\"w\":{\"dtype\":\"F32\",\"shape\":[2.0],\"data_offsets\":[0,8]}}",
        ("{\"s\":{\"dtype\":\"F32\",\"shape\":[],\"data_offsets\":[0,4]},"
         "\"e\":{\"dtype\":\"F32\",\"shape\":[0,3],\"data_offsets\":[4,4]},"
         "\"t\":{\"dtype\":\"U8\",\"shape\":[4],\"data_offsets\":[4,8]}}"),
        ("{\"__metadata__\":{\"name\":\"n\",\"k\":\"\\u00e9\\\"\"},"
         "\"w\":{\"data_offsets\":[0,8],\"shape\":[2],\"dtype\":\"F32\"}}"),
        "{\"w\\u00e9\\n\":{\"dtype\":\"U8\",\"shape\":[8],\"data_offsets\":[0,8]}}",
    };
    weft_context *ctx = make_context();
    image im;
    for (size_t i = 0; i < sizeof ok_headers / sizeof ok_headers[0]; ++i) {
        size_t data = i < 3 ? 0 : 8;
        make_image(&im, ok_headers[i], data);
        weft_model *m = NULL;
        weft_result r = weft_model_load_memory(ctx, im.bytes, im.size, &m);
        CHECK_MSG(r == WEFT_OK, "header %zu rejected: %s (%s)", i, weft_result_string(r), weft_last_error());
        if (m) {
            weft_model_info info = weft_model_get_info(m);
            CHECK(info.weight_bytes == data);
            for (uint32_t t = 0; t < m->tensor_count; ++t) {
                CHECK(((uintptr_t)m->tensors[t].data & 63) == 0);
            }
            weft_model_destroy(m);
        }
    }
    /* Rank 0 counts one element, an empty tensor none, and names are unescaped. */
    make_image(&im, ok_headers[10], 8);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_OK);
    if (m) {
        CHECK(weft__model_find(m, "s")->count == 1);
        CHECK(weft__model_find(m, "s")->rank == 0);
        CHECK(weft__model_find(m, "e")->count == 0);
        CHECK(weft__model_find(m, "e")->data != NULL);
        CHECK(weft_model_get_info(m).parameter_count == 5);
        weft_model_destroy(m);
    }
    make_image(&im, ok_headers[12], 8);
    CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_OK);
    if (m) {
        CHECK(weft__model_find(m, "w\xc3\xa9\n") != NULL);
        weft_model_destroy(m);
    }
    weft_context_destroy(ctx);
}

/* Non-finite floats are rejected at load, naming the tensor and the element. */
static void test_non_finite(void)
{
    weft_context *ctx = make_context();
    image im;
    struct {
        const char *header;
        size_t at;
        uint8_t b0, b1;
    } cases[] = {
        {"{\"w\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]}}", 4, 0x7f, 0x80}, /* +inf */
        {"{\"w\":{\"dtype\":\"F16\",\"shape\":[4],\"data_offsets\":[0,8]}}", 2, 0x7e, 0x00}, /* NaN */
        {"{\"w\":{\"dtype\":\"BF16\",\"shape\":[4],\"data_offsets\":[0,8]}}", 6, 0xff, 0x80}, /* -inf */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        make_image(&im, cases[i].header, 8);
        size_t data = im.size - 8;
        size_t elem = (i == 0) ? 4 : 2;
        /* little-endian: the high byte (sign+exponent) comes last */
        im.bytes[data + cases[i].at + elem - 1] = cases[i].b0;
        im.bytes[data + cases[i].at + elem - 2] = cases[i].b1;
        weft_model *m = NULL;
        CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_ERROR_NOT_FINITE);
        CHECK(strstr(weft_last_error(), "'w'") != NULL);
        CHECK(m == NULL);
    }
    /* I8 -128 in a quantised tensor, negative scale. */
    make_image(&im,
               "{\"w.q8\":{\"dtype\":\"I8\",\"shape\":[1,4],\"data_offsets\":[0,4]},"
               "\"w.scale\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}",
               8);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_OK);
    weft_model_destroy(m);
    m = NULL;
    size_t data = im.size - 8;
    im.bytes[data + 2] = 0x80;
    CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "'w.q8'") != NULL);
    im.bytes[data + 2] = 0x81; /* -127 is fine */
    im.bytes[data + 7] = 0xbf; /* scale -0.5 */
    CHECK_RESULT(weft_model_load_memory(ctx, im.bytes, im.size, &m), WEFT_ERROR_FORMAT);
    CHECK(strstr(weft_last_error(), "'w.scale'") != NULL);
    CHECK(m == NULL);
    weft_context_destroy(ctx);
}

/* ---------------------------------------------------------------------------------------- */
/* Writer                                                                                     */

typedef struct sample {
    float f32[15];
    uint16_t f16[8];
    uint16_t bf16[7];
    int8_t i8[12];
    int32_t i32[5];
    uint8_t u8[9];
    float scalar;
    uint64_t s_f32[2], s_f16[2], s_bf16[1], s_i8[3], s_i32[1], s_u8[1], s_empty[2];
    weft_st_tensor_in t[8];
    weft_st_meta meta[3];
} sample;

static void make_sample(sample *s)
{
    memset(s, 0, sizeof *s);
    for (int i = 0; i < 15; ++i) s->f32[i] = (float)i * 0.25f - 1.0f;
    for (int i = 0; i < 8; ++i) s->f16[i] = (uint16_t)(0x3c00 + i); /* around 1.0 */
    for (int i = 0; i < 7; ++i) s->bf16[i] = (uint16_t)(0x4000 + 16 * i);
    for (int i = 0; i < 12; ++i) s->i8[i] = (int8_t)(i - 6);
    for (int i = 0; i < 5; ++i) s->i32[i] = i * 100000 - 7;
    for (int i = 0; i < 9; ++i) s->u8[i] = (uint8_t)(i * 29);
    s->scalar = 3.5f;
    uint64_t f32s[] = {3, 5}, f16s[] = {4, 2}, bf16s[] = {7}, i8s[] = {2, 3, 2}, i32s[] = {5}, u8s[] = {9},
             es[] = {0, 4};
    memcpy(s->s_f32, f32s, sizeof f32s);
    memcpy(s->s_f16, f16s, sizeof f16s);
    memcpy(s->s_bf16, bf16s, sizeof bf16s);
    memcpy(s->s_i8, i8s, sizeof i8s);
    memcpy(s->s_i32, i32s, sizeof i32s);
    memcpy(s->s_u8, u8s, sizeof u8s);
    memcpy(s->s_empty, es, sizeof es);
    s->t[0] = (weft_st_tensor_in){"w.f32", WEFT_DTYPE_F32, 2, s->s_f32, s->f32};
    s->t[1] = (weft_st_tensor_in){"w.f16", WEFT_DTYPE_F16, 2, s->s_f16, s->f16};
    s->t[2] = (weft_st_tensor_in){"w.bf16", WEFT_DTYPE_BF16, 1, s->s_bf16, s->bf16};
    s->t[3] = (weft_st_tensor_in){"q.i8", WEFT_DTYPE_I8, 3, s->s_i8, s->i8};
    s->t[4] = (weft_st_tensor_in){"idx.i32", WEFT_DTYPE_I32, 1, s->s_i32, s->i32};
    s->t[5] = (weft_st_tensor_in){"mask.u8", WEFT_DTYPE_U8, 1, s->s_u8, s->u8};
    s->t[6] = (weft_st_tensor_in){"scalar", WEFT_DTYPE_F32, 0, NULL, &s->scalar};
    s->t[7] = (weft_st_tensor_in){"empty", WEFT_DTYPE_F32, 2, s->s_empty, NULL};
    s->meta[0] = (weft_st_meta){"name", "round \"trip\"\n"};
    s->meta[1] = (weft_st_meta){"architecture", "generic"};
    s->meta[2] = (weft_st_meta){"config", "{\"latent_count\": 16, \"ratio\": 0.5, \"flag\": true, \"dims\": [1, 2, 3]}"};
}

static void check_sample_model(const sample *s, const weft_model *m)
{
    weft_model_info info = weft_model_get_info(m);
    CHECK(strcmp(info.name, "round \"trip\"\n") == 0);
    CHECK(strcmp(info.architecture, "generic") == 0);
    CHECK_EQ_INT(info.tensor_count, 8);
    CHECK_EQ_INT(info.parameter_count, 15 + 8 + 7 + 12 + 5 + 9 + 1);
    CHECK_EQ_INT(info.weight_bytes, 60 + 16 + 14 + 12 + 20 + 9 + 4);
    CHECK_EQ_INT(info.precision, WEFT_PRECISION_INT8); /* an I8 tensor is present */
    for (int i = 0; i < 8; ++i) {
        const weft_st_tensor_in *in = &s->t[i];
        const weft_tensor *t = weft__model_find(m, in->name);
        CHECK_MSG(t != NULL, "tensor %s missing", in->name);
        if (!t) {
            continue;
        }
        CHECK(t->dtype == in->dtype);
        CHECK(t->rank == in->rank);
        for (uint32_t d = 0; d < in->rank; ++d) {
            CHECK(t->shape[d] == in->shape[d]);
        }
        CHECK(((uintptr_t)t->data & 63) == 0);
        CHECK(t->bytes == 0 || memcmp(t->data, in->data, (size_t)t->bytes) == 0);
    }
    int64_t latents = 0;
    CHECK_RESULT(weft__model_config_int(m, "latent_count", &latents), WEFT_OK);
    CHECK_EQ_INT(latents, 16);
}

static void test_writer_round_trip(void)
{
    weft_context *ctx = make_context();
    sample s;
    make_sample(&s);
    void *bytes = NULL;
    size_t size = 0;
    CHECK_RESULT(weft__st_write_memory(ctx, s.t, 8, s.meta, 3, &bytes, &size), WEFT_OK);
    if (!bytes) {
        weft_context_destroy(ctx);
        return;
    }
    /* Layout: header padded so the data starts 8-aligned; tensors by descending element size,
     * each aligned to its element size; the data section is exactly covered. */
    weft_st_header h;
    const uint8_t *data = NULL;
    CHECK_RESULT(weft__st_parse_memory(ctx, bytes, size, &h, &data), WEFT_OK);
    CHECK(((size_t)(data - (const uint8_t *)bytes) & 7) == 0);
    uint8_t *pad = (uint8_t *)data - 1;
    CHECK(*pad == ' ' || *pad == '}');
    size_t prev_size = 8;
    uint64_t end = 0;
    for (uint32_t i = 0; i < h.entry_count; ++i) {
        size_t es = weft__dtype_size(h.entries[i].dtype);
        CHECK(es <= prev_size);
        CHECK(h.entries[i].begin % es == 0);
        CHECK(h.entries[i].begin == end);
        end = h.entries[i].end;
        prev_size = es;
    }
    CHECK(end == h.data_size);
    CHECK_EQ_INT(h.meta_count, 3);
    weft__st_header_free(ctx, &h);

    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &m), WEFT_OK);
    if (m) {
        check_sample_model(&s, m);
        weft_model_destroy(m);
    }

    /* File round trip gives the same bytes, and writing is deterministic. */
    const char *path = temp_path("io_safetensors_roundtrip.safetensors");
    CHECK_RESULT(weft__st_write_file(ctx, path, s.t, 8, s.meta, 3), WEFT_OK);
    FILE *f = fopen(path, "rb");
    CHECK(f != NULL);
    if (f) {
        uint8_t *again = malloc(size + 1);
        CHECK(fread(again, 1, size + 1, f) == size);
        CHECK(memcmp(again, bytes, size) == 0);
        free(again);
        fclose(f);
    }
    m = NULL;
    CHECK_RESULT(weft_model_load_file(ctx, path, &m), WEFT_OK);
    if (m) {
        check_sample_model(&s, m);
        weft_model_destroy(m);
    }
    remove(path);
    weft__free(ctx, bytes, size);

    /* No tensors, no metadata: the smallest valid file. */
    CHECK_RESULT(weft__st_write_memory(ctx, NULL, 0, NULL, 0, &bytes, &size), WEFT_OK);
    CHECK_EQ_INT(size, 16); /* 8 + "{}" padded to 8 */
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &m), WEFT_OK);
    CHECK_EQ_INT(weft_model_get_info(m).tensor_count, 0);
    weft_model_destroy(m);
    weft__free(ctx, bytes, size);
    weft_context_destroy(ctx);
}

static void test_writer_rejects(void)
{
    weft_context *ctx = make_context();
    sample s;
    make_sample(&s);
    void *bytes = (void *)(uintptr_t)0x99;
    size_t size = 77;

    weft_st_tensor_in t[2] = {s.t[0], s.t[0]};
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_DUPLICATE_NAME);
    CHECK(strstr(weft_last_error(), "'w.f32'") != NULL);
    t[1].name = "__metadata__";
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_INVALID_ARGUMENT);
    t[1].name = "bad\xff";
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_INVALID_ARGUMENT);
    t[1] = s.t[0];
    t[1].name = "other";
    t[1].rank = 9;
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_BAD_SHAPE);
    t[1].rank = 2;
    t[1].data = NULL;
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_INVALID_ARGUMENT);
    t[1].data = s.f32;
    t[1].dtype = WEFT_DTYPE_COUNT;
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_UNKNOWN_DTYPE);
    t[1].dtype = WEFT_DTYPE_F32;
    uint64_t huge[2] = {1ull << 40, 1ull << 40};
    t[1].shape = huge;
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2, NULL, 0, &bytes, &size), WEFT_ERROR_SIZE_OVERFLOW);
    weft_st_meta meta[2] = {{"k", "a"}, {"k", "b"}};
    CHECK_RESULT(weft__st_write_memory(ctx, s.t, 1, meta, 2, &bytes, &size), WEFT_ERROR_DUPLICATE_NAME);
    meta[1].key = NULL;
    CHECK_RESULT(weft__st_write_memory(ctx, s.t, 1, meta, 2, &bytes, &size), WEFT_ERROR_BAD_METADATA);
    CHECK(bytes == (void *)(uintptr_t)0x99 && size == 77);
    CHECK_RESULT(weft__st_write_file(ctx, "/nonexistent/dir/x.safetensors", s.t, 1, NULL, 0), WEFT_ERROR_IO);
    weft_context_destroy(ctx);
}

/* Thousands of tensors (sorting, duplicate detection and lookups at scale), quantised pairs
 * among them, and names far longer than any fixed buffer. */
static void test_many_tensors(void)
{
    enum { PAIRS = 3000, LONG = 600 };
    weft_context *ctx = make_context();
    static char names[2 * PAIRS + 2][LONG + 16];
    static weft_st_tensor_in t[2 * PAIRS + 2];
    static const int8_t q[2] = {-127, 127};
    static const float scale[2] = {0.5f, 2.0f};
    static const uint64_t shape_q[2] = {2, 1}, shape_s[1] = {2};
    for (int i = 0; i < PAIRS; ++i) {
        /* Reverse order, so the writer and reader both have to sort. */
        snprintf(names[2 * i], sizeof names[0], "layer%05d.w.q8", PAIRS - i);
        snprintf(names[2 * i + 1], sizeof names[0], "layer%05d.w.scale", PAIRS - i);
        t[2 * i] = (weft_st_tensor_in){names[2 * i], WEFT_DTYPE_I8, 2, shape_q, q};
        t[2 * i + 1] = (weft_st_tensor_in){names[2 * i + 1], WEFT_DTYPE_F32, 1, shape_s, scale};
    }
    memset(names[2 * PAIRS], 'n', LONG);
    memcpy(names[2 * PAIRS] + LONG, ".q8", 4);
    memset(names[2 * PAIRS + 1], 'n', LONG);
    memcpy(names[2 * PAIRS + 1] + LONG, ".scale", 7);
    t[2 * PAIRS] = (weft_st_tensor_in){names[2 * PAIRS], WEFT_DTYPE_I8, 2, shape_q, q};
    t[2 * PAIRS + 1] = (weft_st_tensor_in){names[2 * PAIRS + 1], WEFT_DTYPE_F32, 1, shape_s, scale};

    void *bytes = NULL;
    size_t size = 0;
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2 * PAIRS + 2, NULL, 0, &bytes, &size), WEFT_OK);
    weft_model *m = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &m), WEFT_OK);
    if (m) {
        CHECK_EQ_INT(weft_model_get_info(m).tensor_count, 2 * PAIRS + 2);
        CHECK_EQ_INT(weft_model_get_info(m).precision, WEFT_PRECISION_INT8);
        for (int i = 0; i < 2 * PAIRS + 2; ++i) {
            const weft_tensor *x = weft__model_find(m, names[i]);
            CHECK_MSG(x && strcmp(x->name, names[i]) == 0, "tensor %d not found", i);
        }
        weft_model_destroy(m);
    }
    weft__free(ctx, bytes, size);

    /* Drop one scale: the loader names the quantised tensor (the message is cut at the error
     * buffer's 512 bytes, the name is not). */
    CHECK_RESULT(weft__st_write_memory(ctx, t, 2 * PAIRS + 1, NULL, 0, &bytes, &size), WEFT_OK);
    m = NULL;
    CHECK_RESULT(weft_model_load_memory(ctx, bytes, size, &m), WEFT_ERROR_MISSING_TENSOR);
    CHECK(strncmp(weft_last_error(), "model: quantised tensor 'nnnnnnnn", 33) == 0);
    CHECK(m == NULL);
    weft__free(ctx, bytes, size);
    weft_context_destroy(ctx);
}

/* ---------------------------------------------------------------------------------------- */
/* Allocation failures at every point of a load leave nothing behind.                          */

typedef struct counting_allocator {
    long live_blocks;
    long long live_bytes; /* frees must pass the size that was allocated */
    long fail_after;      /* -1: never */
} counting_allocator;

static void *count_alloc(size_t size, size_t alignment, void *user)
{
    counting_allocator *a = user;
    if (a->fail_after == 0) {
        return NULL;
    }
    if (a->fail_after > 0) {
        a->fail_after--;
    }
    void *p = aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
    if (p) {
        a->live_blocks++;
        a->live_bytes += (long long)size;
    }
    return p;
}

static void count_free(void *ptr, size_t size, void *user)
{
    counting_allocator *a = user;
    a->live_blocks--;
    a->live_bytes -= (long long)size;
    free(ptr);
}

static void test_allocation_failures(void)
{
    sample s;
    make_sample(&s);
    counting_allocator a = {0, 0, -1};
    weft_context_def def = weft_default_context_def();
    def.allocator = (weft_allocator){count_alloc, count_free, &a};
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&def, &ctx), WEFT_OK);
    void *bytes = NULL;
    size_t size = 0;
    CHECK_RESULT(weft__st_write_memory(ctx, s.t, 8, s.meta, 3, &bytes, &size), WEFT_OK);
    const char *path = temp_path("io_safetensors_alloc.safetensors");
    write_bytes(path, bytes, size);
    long base = a.live_blocks;
    long long base_bytes = a.live_bytes;
    bool loaded_mem = false, loaded_file = false;
    for (long n = 0; n < 64 && !(loaded_mem && loaded_file); ++n) {
        weft_model *m = NULL;
        a.fail_after = n;
        weft_result r = weft_model_load_memory(ctx, bytes, size, &m);
        a.fail_after = -1;
        CHECK_MSG(r == WEFT_OK || r == WEFT_ERROR_OUT_OF_MEMORY, "fail_after %ld: %s", n, weft_result_string(r));
        if (r == WEFT_OK) {
            loaded_mem = true;
            weft_model_destroy(m);
        } else {
            CHECK(m == NULL);
        }
        CHECK_MSG(a.live_blocks == base && a.live_bytes == base_bytes, "fail_after %ld leaks %ld blocks", n,
                  a.live_blocks - base);

        a.fail_after = n;
        r = weft_model_load_file(ctx, path, &m);
        a.fail_after = -1;
        CHECK(r == WEFT_OK || r == WEFT_ERROR_OUT_OF_MEMORY);
        if (r == WEFT_OK) {
            loaded_file = true;
            weft_model_destroy(m);
        }
        CHECK_MSG(a.live_blocks == base && a.live_bytes == base_bytes, "file, fail_after %ld leaks %ld blocks", n,
                  a.live_blocks - base);
    }
    CHECK(loaded_mem && loaded_file);
    remove(path);
    weft__free(ctx, bytes, size);
    weft_context_destroy(ctx);
    CHECK_EQ_INT(a.live_blocks, 0);
    CHECK_EQ_INT(a.live_bytes, 0);
}

TEST_MAIN(TEST_CASE(test_corruption_matrix), TEST_CASE(test_length_field), TEST_CASE(test_accepted_variants),
          TEST_CASE(test_non_finite), TEST_CASE(test_writer_round_trip), TEST_CASE(test_writer_rejects),
          TEST_CASE(test_many_tensors), TEST_CASE(test_allocation_failures))
