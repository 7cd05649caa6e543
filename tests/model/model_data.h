/* Shared by the model tests: the golden arrays exported by tools/train/export.py into
 * tests/model/data/ (NPY v1.0, 4-byte elements, C order). */
#ifndef WEFT_TEST_MODEL_DATA_H
#define WEFT_TEST_MODEL_DATA_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DATA WEFT_SOURCE_DIR "/tests/model/data/"

/* DATA/name.npy: its elements (malloc'd, NULL when missing or malformed), their count, and the
 * first dimension. */
static void *load_npy(const char *name, size_t *count, size_t *rows)
{
    char path[512];
    snprintf(path, sizeof path, "%s%s.npy", DATA, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        return NULL;
    }
    unsigned char pre[10];
    char header[1024] = {0};
    void *data = NULL;
    size_t hlen = 0;
    if (fread(pre, 1, 10, f) == 10 && memcmp(pre, "\x93NUMPY", 6) == 0 && pre[6] == 1) {
        hlen = (size_t)pre[8] | (size_t)pre[9] << 8;
    }
    if (hlen > 0 && hlen < sizeof header && fread(header, 1, hlen, f) == hlen) {
        const char *sh = strstr(header, "'shape': (");
        size_t n = 1, first = 0;
        for (const char *p = sh ? sh + 10 : NULL; p && *p && *p != ')';) {
            char *end;
            size_t v = (size_t)strtoull(p, &end, 10);
            if (end == p) {
                break;
            }
            first = first ? first : v;
            n *= v;
            p = end;
            while (*p == ',' || *p == ' ') {
                p++;
            }
        }
        data = sh ? malloc(n * 4) : NULL;
        if (data && fread(data, 4, n, f) != n) {
            free(data);
            data = NULL;
        }
        *count = n;
        *rows = first;
    }
    fclose(f);
    return data;
}

#endif
