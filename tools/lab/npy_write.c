/* Writing .npy arrays (the dataset generator, `weft eval --write-pos`). Reading them lives in
 * runtime/assets (weft_npy_parse), which the core library does not link. */
#include "npy_write.h"

#include <stdio.h>

/* NPY v1.0: magic, header length, a Python dict literal padded to a 64-byte boundary. */
bool weft_npy_write_file(const char *path, const char *descr, const uint64_t *shape, int ndim, const void *data,
                         size_t bytes)
{
    char dims[128] = "";
    size_t len = 0;
    for (int i = 0; i < ndim; ++i) {
        len += (size_t)snprintf(dims + len, sizeof dims - len, "%llu%s", (unsigned long long)shape[i],
                                ndim == 1 ? "," : (i + 1 < ndim ? ", " : ""));
    }
    char header[256];
    int hl = snprintf(header, sizeof header, "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }", descr, dims);
    size_t total = 10 + (size_t)hl + 1;
    size_t pad = (64 - total % 64) % 64;
    FILE *f = fopen(path, "wb");
    if (!f) {
        return false;
    }
    unsigned char pre[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, 0, 0};
    uint16_t hlen = (uint16_t)(hl + pad + 1);
    pre[8] = (unsigned char)(hlen & 0xff);
    pre[9] = (unsigned char)(hlen >> 8);
    bool ok = fwrite(pre, 1, 10, f) == 10 && fwrite(header, 1, (size_t)hl, f) == (size_t)hl;
    for (size_t i = 0; ok && i < pad; ++i) {
        ok = fputc(' ', f) != EOF;
    }
    ok = ok && fputc('\n', f) != EOF && fwrite(data, 1, bytes, f) == bytes;
    return fclose(f) == 0 && ok;
}
