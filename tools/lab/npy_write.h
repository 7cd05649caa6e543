/* Writing one .npy file (NumPy format 1.0). */
#ifndef WEFT_IO_NPY_WRITE_H
#define WEFT_IO_NPY_WRITE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* descr as numpy spells it ("<f4", "<i4", "|u1"), C order, `bytes` of data. False when the
 * file cannot be written completely. */
bool weft_npy_write_file(const char *path, const char *descr, const uint64_t *shape, int ndim, const void *data,
                         size_t bytes);

#endif
