/* The committed sample sequence (tests/data/sample_seq, written by `weft simgen`): the NPY
 * files parse with consistent shapes, and the independent validator finds no penetration
 * between any two consecutive frames. */
#include "test.h"
#include "weft/sim.h"

#include <stdint.h>

typedef struct npy {
    char descr[8];
    uint64_t shape[3];
    int ndim;
    void *data;
    size_t bytes;
} npy;

/* Minimal NPY v1 reader for the files simgen writes. */
static int npy_load(const char *name, npy *out)
{
    char path[512];
    snprintf(path, sizeof path, "%s/tests/data/sample_seq/%s", WEFT_SOURCE_DIR, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        return 0;
    }
    unsigned char pre[10];
    int ok = fread(pre, 1, 10, f) == 10 && pre[0] == 0x93 && memcmp(pre + 1, "NUMPY", 5) == 0 && pre[6] == 1;
    size_t hl = ok ? (size_t)pre[8] | ((size_t)pre[9] << 8) : 0;
    char header[512] = {0};
    ok = ok && hl < sizeof header && fread(header, 1, hl, f) == hl;
    const char *d = ok ? strstr(header, "'descr': '") : NULL;
    const char *s = ok ? strstr(header, "'shape': (") : NULL;
    ok = ok && d && s;
    if (ok) {
        sscanf(d + 10, "%7[^']", out->descr);
        out->ndim = 0;
        const char *p = s + 10;
        while (*p && *p != ')' && out->ndim < 3) {
            char *end;
            unsigned long long v = strtoull(p, &end, 10);
            if (end == p) {
                break;
            }
            out->shape[out->ndim++] = v;
            p = end;
            while (*p == ',' || *p == ' ') {
                ++p;
            }
        }
        size_t elem = strcmp(out->descr, "|u1") == 0 ? 1 : 4, count = 1;
        for (int i = 0; i < out->ndim; ++i) {
            count *= out->shape[i];
        }
        out->bytes = count * elem;
        out->data = malloc(out->bytes ? out->bytes : 1);
        ok = out->data && fread(out->data, 1, out->bytes, f) == out->bytes && fgetc(f) == EOF;
    }
    fclose(f);
    return ok;
}

static void test_sample_sequence(void)
{
    npy cloth = {0}, rest = {0}, faces = {0}, coll = {0}, cfaces = {0}, pinned = {0}, stats = {0};
    CHECK(npy_load("cloth_pos.npy", &cloth));
    CHECK(npy_load("rest_pos.npy", &rest));
    CHECK(npy_load("faces.npy", &faces));
    CHECK(npy_load("collider_pos.npy", &coll));
    CHECK(npy_load("collider_faces.npy", &cfaces));
    CHECK(npy_load("pinned.npy", &pinned));
    CHECK(npy_load("stats.npy", &stats));
    if (test_failures_) {
        return;
    }
    uint32_t T = (uint32_t)cloth.shape[0], nv = (uint32_t)cloth.shape[1], nc = (uint32_t)coll.shape[1];
    CHECK_EQ_INT(cloth.ndim, 3);
    CHECK(strcmp(cloth.descr, "<f4") == 0 && strcmp(faces.descr, "<i4") == 0);
    CHECK_EQ_INT(rest.shape[0], nv);
    CHECK_EQ_INT(coll.shape[0], T);
    CHECK_EQ_INT(pinned.shape[0], T);
    CHECK_EQ_INT(pinned.shape[1], nv);
    CHECK_EQ_INT(stats.shape[0], T);
    CHECK(T >= 60 && nv > 500);
    weft_context_def cd = weft_default_context_def();
    weft_context *ctx = NULL;
    CHECK_RESULT(weft_context_create(&cd, &ctx), WEFT_OK);
    weft_sim_validator *v = NULL;
    CHECK_RESULT(weft_sim_validator_create(ctx, faces.data, (uint32_t)faces.shape[0], nv, cfaces.data,
                                           (uint32_t)cfaces.shape[0], nc, &v),
                 WEFT_OK);
    const float *x = cloth.data, *c = coll.data;
    uint32_t hits = 0;
    for (uint32_t f = 1; f < T && v; ++f) {
        weft_sim_validation res;
        CHECK_RESULT(weft_sim_validator_check(v, x + (size_t)(f - 1) * nv * 3, x + (size_t)f * nv * 3,
                                              c + (size_t)(f - 1) * nc * 3, c + (size_t)f * nc * 3, &res),
                     WEFT_OK);
        hits += res.ccd_hits + res.intersection_hits;
    }
    CHECK_EQ_INT(hits, 0);
    /* The stored statistics agree: zero validator hits and a sane strain. */
    const float *st = stats.data;
    for (uint32_t f = 1; f < T; ++f) {
        CHECK(st[f * stats.shape[1] + 10] == 0.0f && st[f * stats.shape[1] + 11] == 0.0f);
        CHECK(st[f * stats.shape[1] + 8] < 0.2f);
    }
    weft_sim_validator_destroy(v);
    weft_context_destroy(ctx);
    free(cloth.data), free(rest.data), free(faces.data), free(coll.data), free(cfaces.data), free(pinned.data),
        free(stats.data);
}

TEST_MAIN(TEST_CASE(test_sample_sequence))
