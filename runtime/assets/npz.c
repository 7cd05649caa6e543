/* .npz reader: the zip through minizip over an in-memory stream, each .npy header parsed
 * strictly (magic, version 1-3, the three-key dict, shape against the payload size). */
#include "npz.h"

#include "core/core.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unzip.h>

#define NPZ_MAX_FILE_BYTES ((uint64_t)4 << 30)  /* archives above 4 GiB are refused */
#define NPZ_MAX_ENTRY_BYTES ((uint64_t)2 << 30) /* one array above 2 GiB is refused */
#define NPZ_MAX_ENTRIES 4096u

typedef struct npz_entry {
    weft_npy_array array;
    uint8_t *buffer; /* the whole .npy image */
    size_t buffer_size;
} npz_entry;

struct weft_npz {
    weft_context *context;
    uint32_t count;
    npz_entry *entries;
    uint32_t capacity;
};

/* ---------------------------------------------------------------------------------------- */
/* .npy header                                                                                */

typedef struct cursor {
    const char *p, *end;
} cursor;

static void skip_ws(cursor *c)
{
    while (c->p < c->end && (*c->p == ' ' || *c->p == '\t')) {
        c->p++;
    }
}

static bool take(cursor *c, char ch)
{
    skip_ws(c);
    if (c->p < c->end && *c->p == ch) {
        c->p++;
        return true;
    }
    return false;
}

/* A quoted Python string without escapes (npy keys and dtype strings never have any). */
static bool parse_string(cursor *c, char *out, size_t cap)
{
    skip_ws(c);
    if (c->p >= c->end || (*c->p != '\'' && *c->p != '"')) {
        return false;
    }
    char q = *c->p++;
    size_t n = 0;
    while (c->p < c->end && *c->p != q) {
        if (*c->p == '\\' || n + 1 >= cap) {
            return false;
        }
        out[n++] = *c->p++;
    }
    if (c->p >= c->end) {
        return false;
    }
    c->p++;
    out[n] = '\0';
    return true;
}

static bool parse_u64(cursor *c, uint64_t *out)
{
    skip_ws(c);
    if (c->p >= c->end || *c->p < '0' || *c->p > '9') {
        return false;
    }
    uint64_t v = 0;
    while (c->p < c->end && *c->p >= '0' && *c->p <= '9') {
        if (!weft__mul_u64(v, 10, &v) || !weft__add_u64(v, (uint64_t)(*c->p - '0'), &v)) {
            return false;
        }
        c->p++;
    }
    /* Python 2 era writers append L to longs. */
    if (c->p < c->end && *c->p == 'L') {
        c->p++;
    }
    *out = v;
    return true;
}

static bool parse_dtype(const char *descr, weft_npy_dtype *dtype, uint32_t *size)
{
    static const struct {
        const char *code;
        weft_npy_dtype dtype;
        uint32_t size;
    } table[] = {{"f4", WEFT_NPY_F4, 4}, {"f8", WEFT_NPY_F8, 8}, {"i1", WEFT_NPY_I1, 1}, {"u1", WEFT_NPY_U1, 1},
                 {"i2", WEFT_NPY_I2, 2}, {"u2", WEFT_NPY_U2, 2}, {"i4", WEFT_NPY_I4, 4}, {"u4", WEFT_NPY_U4, 4},
                 {"i8", WEFT_NPY_I8, 8}, {"u8", WEFT_NPY_U8, 8}, {"b1", WEFT_NPY_B1, 1}};
    size_t len = strlen(descr);
    if (len < 3) {
        return false;
    }
    char order = descr[0];
    for (size_t i = 0; i < sizeof table / sizeof table[0]; ++i) {
        if (strcmp(descr + 1, table[i].code) == 0) {
            bool single = table[i].size == 1;
            /* '|' is "not applicable" for one-byte types; '<' little-endian; '=' native (we
             * only build for little-endian machines). Big-endian data is reported as such. */
            if (order == '<' || order == '=' || (single && order == '|')) {
                *dtype = table[i].dtype;
                *size = table[i].size;
                return true;
            }
            if (order == '>' && single) {
                *dtype = table[i].dtype;
                *size = table[i].size;
                return true;
            }
            *dtype = WEFT_NPY_UNSUPPORTED;
            *size = table[i].size;
            return true;
        }
    }
    /* Strings, objects, complex, datetimes: well-formed, just not numeric for us. */
    if (order == '<' || order == '>' || order == '|' || order == '=') {
        *dtype = WEFT_NPY_UNSUPPORTED;
        *size = 0;
        return true;
    }
    return false;
}

weft_result weft_npy_parse(const void *bytes, size_t size, const char *name, weft_npy_array *out)
{
    const uint8_t *b = bytes;
    if (!name) {
        name = "?";
    }
    if (!b || size < 10) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': %zu bytes, too short for a header", name, size);
    }
    if (memcmp(b, "\x93NUMPY", 6) != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': bad magic (not a .npy array)", name);
    }
    uint8_t major = b[6], minor = b[7];
    if (major < 1 || major > 3 || minor != 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': unsupported format version %u.%u", name, major, minor);
    }
    size_t prefix = major == 1 ? 10 : 12;
    if (size < prefix) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': truncated header length", name);
    }
    uint64_t header_len = major == 1 ? (uint64_t)(b[8] | (b[9] << 8))
                                     : (uint64_t)b[8] | ((uint64_t)b[9] << 8) | ((uint64_t)b[10] << 16) |
                                           ((uint64_t)b[11] << 24);
    if (header_len == 0 || header_len > size - prefix || header_len > (1u << 20)) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': header length %llu beyond the %zu-byte entry", name,
                          (unsigned long long)header_len, size);
    }
    const char *h = (const char *)b + prefix;
    if (h[header_len - 1] != '\n') {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': header does not end with a newline", name);
    }
    for (uint64_t i = 0; i < header_len; ++i) {
        unsigned char ch = (unsigned char)h[i];
        if (ch == 0 || (ch >= 0x80 && major < 3)) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': header has a non-ASCII byte at %llu", name,
                              (unsigned long long)i);
        }
    }
    weft_npy_array a;
    memset(&a, 0, sizeof a);
    snprintf(a.name, sizeof a.name, "%s", name);
    cursor c = {h, h + header_len - 1};
    bool have_descr = false, have_order = false, have_shape = false;
    if (!take(&c, '{')) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': header is not a dict", name);
    }
    for (;;) {
        if (take(&c, '}')) {
            break;
        }
        char key[32];
        if (!parse_string(&c, key, sizeof key) || !take(&c, ':')) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': malformed header key", name);
        }
        if (strcmp(key, "descr") == 0 && !have_descr) {
            if (!parse_string(&c, a.descr, sizeof a.descr) || !parse_dtype(a.descr, &a.dtype, &a.item_size)) {
                return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': malformed descr", name);
            }
            have_descr = true;
        } else if (strcmp(key, "fortran_order") == 0 && !have_order) {
            skip_ws(&c);
            if ((size_t)(c.end - c.p) >= 4 && memcmp(c.p, "True", 4) == 0) {
                a.fortran_order = true;
                c.p += 4;
            } else if ((size_t)(c.end - c.p) >= 5 && memcmp(c.p, "False", 5) == 0) {
                a.fortran_order = false;
                c.p += 5;
            } else {
                return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': fortran_order is not True or False", name);
            }
            have_order = true;
        } else if (strcmp(key, "shape") == 0 && !have_shape) {
            if (!take(&c, '(')) {
                return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': shape is not a tuple", name);
            }
            bool need_comma = false;
            for (;;) {
                if (take(&c, ')')) {
                    break;
                }
                if (need_comma && !take(&c, ',')) {
                    return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': malformed shape tuple", name);
                }
                if (take(&c, ')')) {
                    break;
                }
                if (a.ndim >= WEFT_NPY_MAX_DIMS) {
                    return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': more than %d dimensions", name, WEFT_NPY_MAX_DIMS);
                }
                if (!parse_u64(&c, &a.shape[a.ndim])) {
                    return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': shape entry is not a non-negative integer", name);
                }
                a.ndim++;
                need_comma = true;
            }
            /* Python writes a one-element tuple as (n,); (n) is an int, not a tuple. */
            have_shape = true;
        } else {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': unexpected or repeated header key '%s'", name, key);
        }
        if (take(&c, '}')) {
            break;
        }
        if (!take(&c, ',')) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': expected ',' or '}' in header", name);
        }
    }
    skip_ws(&c);
    if (c.p != c.end) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': trailing characters after the header dict", name);
    }
    if (!have_descr || !have_order || !have_shape) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': header lacks %s", name,
                          !have_descr ? "descr" : !have_order ? "fortran_order" : "shape");
    }
    uint64_t count = 1;
    for (uint32_t d = 0; d < a.ndim; ++d) {
        if (!weft__mul_u64(count, a.shape[d], &count)) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': shape overflows 64 bits", name);
        }
    }
    a.count = count;
    uint64_t payload = size - prefix - header_len;
    if (a.item_size != 0) {
        uint64_t need;
        if (!weft__mul_u64(count, a.item_size, &need)) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': shape x item size overflows", name);
        }
        if (need != payload) {
            return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': shape needs %llu data bytes, the entry has %llu", name,
                              (unsigned long long)need, (unsigned long long)payload);
        }
    }
    a.data = b + prefix + header_len;
    *out = a;
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Conversions                                                                                */

/* Storage index of the element at C-order index i. */
static uint64_t storage_index(const weft_npy_array *a, uint64_t i)
{
    if (!a->fortran_order || a->ndim < 2) {
        return i;
    }
    /* Decompose i in C order (last index fastest), recompose in Fortran order. */
    uint64_t idx[WEFT_NPY_MAX_DIMS];
    for (int d = (int)a->ndim - 1; d >= 0; --d) {
        idx[d] = i % a->shape[d];
        i /= a->shape[d];
    }
    uint64_t s = 0;
    for (int d = (int)a->ndim - 1; d >= 0; --d) {
        s = s * a->shape[d] + idx[d];
    }
    return s;
}

static double element(const weft_npy_array *a, uint64_t s)
{
    const uint8_t *p = a->data + s * a->item_size;
    switch (a->dtype) {
    case WEFT_NPY_F4: { float v; memcpy(&v, p, 4); return v; }
    case WEFT_NPY_F8: { double v; memcpy(&v, p, 8); return v; }
    case WEFT_NPY_I1: return (int8_t)p[0];
    case WEFT_NPY_U1: return p[0];
    case WEFT_NPY_B1: return p[0] != 0;
    case WEFT_NPY_I2: { int16_t v; memcpy(&v, p, 2); return v; }
    case WEFT_NPY_U2: { uint16_t v; memcpy(&v, p, 2); return v; }
    case WEFT_NPY_I4: { int32_t v; memcpy(&v, p, 4); return v; }
    case WEFT_NPY_U4: { uint32_t v; memcpy(&v, p, 4); return v; }
    case WEFT_NPY_I8: { int64_t v; memcpy(&v, p, 8); return (double)v; }
    case WEFT_NPY_U8: { uint64_t v; memcpy(&v, p, 8); return (double)v; }
    case WEFT_NPY_UNSUPPORTED:
    default: return NAN;
    }
}

weft_result weft_npy_to_f32(const weft_npy_array *a, float *out, uint64_t count)
{
    if (!a || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_npy_to_f32: NULL argument");
    }
    if (a->dtype == WEFT_NPY_UNSUPPORTED) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': dtype '%s' is not numeric little-endian", a->name, a->descr);
    }
    if (count != a->count) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "npy '%s': %llu elements, expected %llu", a->name,
                          (unsigned long long)a->count, (unsigned long long)count);
    }
    for (uint64_t i = 0; i < count; ++i) {
        double v = element(a, storage_index(a, i));
        if (!isfinite(v) || fabs(v) > 3.0e38) {
            return weft__fail(WEFT_ERROR_NOT_FINITE, "npy '%s': element %llu is not a finite float", a->name,
                              (unsigned long long)i);
        }
        out[i] = (float)v;
    }
    return WEFT_OK;
}

weft_result weft_npy_to_i64(const weft_npy_array *a, int64_t *out, uint64_t count)
{
    if (!a || !out) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_npy_to_i64: NULL argument");
    }
    if (a->dtype == WEFT_NPY_UNSUPPORTED) {
        return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': dtype '%s' is not numeric little-endian", a->name, a->descr);
    }
    if (count != a->count) {
        return weft__fail(WEFT_ERROR_SIZE_MISMATCH, "npy '%s': %llu elements, expected %llu", a->name,
                          (unsigned long long)a->count, (unsigned long long)count);
    }
    for (uint64_t i = 0; i < count; ++i) {
        uint64_t s = storage_index(a, i);
        int64_t v;
        if (a->dtype == WEFT_NPY_I8) {
            memcpy(&v, a->data + s * 8, 8);
        } else if (a->dtype == WEFT_NPY_U8) {
            uint64_t u;
            memcpy(&u, a->data + s * 8, 8);
            /* kintree_table roots are stored as 2^32-1 or 2^64-1; anything past INT64_MAX is -1. */
            v = u > (uint64_t)INT64_MAX ? -1 : (int64_t)u;
        } else {
            double d = element(a, s);
            if (!isfinite(d) || d != floor(d) || fabs(d) > 9.0e15) {
                return weft__fail(WEFT_ERROR_FORMAT, "npy '%s': element %llu is not an integer", a->name,
                                  (unsigned long long)i);
            }
            v = (int64_t)d;
        }
        out[i] = v;
    }
    return WEFT_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Zip over memory                                                                            */

typedef struct mem_stream {
    const uint8_t *data;
    uint64_t size, pos;
} mem_stream;

static voidpf ZCALLBACK mem_open(voidpf opaque, const void *filename, int mode)
{
    (void)filename;
    if ((mode & ZLIB_FILEFUNC_MODE_READWRITEFILTER) != ZLIB_FILEFUNC_MODE_READ) {
        return NULL;
    }
    mem_stream *s = opaque;
    s->pos = 0;
    return s;
}

static uLong ZCALLBACK mem_read(voidpf opaque, voidpf stream, void *buf, uLong size)
{
    mem_stream *s = stream;
    uint64_t left = s->size - s->pos;
    uint64_t n = size < left ? size : left;
    memcpy(buf, s->data + s->pos, (size_t)n);
    s->pos += n;
    return (uLong)n;
}

static uLong ZCALLBACK mem_write(voidpf opaque, voidpf stream, const void *buf, uLong size)
{
    return 0;
}

static ZPOS64_T ZCALLBACK mem_tell(voidpf opaque, voidpf stream)
{
    return ((mem_stream *)stream)->pos;
}

static long ZCALLBACK mem_seek(voidpf opaque, voidpf stream, ZPOS64_T offset, int origin)
{
    mem_stream *s = stream;
    uint64_t base;
    switch (origin) {
    case ZLIB_FILEFUNC_SEEK_SET: base = 0; break;
    case ZLIB_FILEFUNC_SEEK_CUR: base = s->pos; break;
    case ZLIB_FILEFUNC_SEEK_END: base = s->size; break;
    default: return -1;
    }
    uint64_t target;
    if (!weft__add_u64(base, offset, &target) || target > s->size) {
        return -1;
    }
    s->pos = target;
    return 0;
}

static int ZCALLBACK mem_close(voidpf opaque, voidpf stream) { return 0; }
static int ZCALLBACK mem_error(voidpf opaque, voidpf stream) { return 0; }

void weft_npz_destroy(weft_npz *npz)
{
    if (!npz) {
        return;
    }
    for (uint32_t i = 0; i < npz->count; ++i) {
        weft__free(npz->context, npz->entries[i].buffer, npz->entries[i].buffer_size);
    }
    weft__free(npz->context, npz->entries, (size_t)npz->capacity * sizeof(npz_entry));
    weft__free(npz->context, npz, sizeof *npz);
}

static weft_result read_entries(weft_npz *npz, unzFile zip, uint64_t archive_size)
{
    unz_global_info64 gi;
    if (unzGetGlobalInfo64(zip, &gi) != UNZ_OK) {
        return weft__fail(WEFT_ERROR_FORMAT, "npz: unreadable zip directory");
    }
    if (gi.number_entry == 0) {
        return weft__fail(WEFT_ERROR_FORMAT, "npz: the archive has no entries");
    }
    if (gi.number_entry > NPZ_MAX_ENTRIES) {
        return weft__fail(WEFT_ERROR_FORMAT, "npz: %llu entries, more than %u", (unsigned long long)gi.number_entry,
                          NPZ_MAX_ENTRIES);
    }
    npz->capacity = (uint32_t)gi.number_entry;
    npz->entries = weft__alloc(npz->context, (size_t)npz->capacity * sizeof(npz_entry));
    if (!npz->entries) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    int rc = unzGoToFirstFile(zip);
    for (uint32_t e = 0; e < npz->capacity; ++e) {
        if (rc != UNZ_OK) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: zip directory entry %u unreadable", e);
        }
        unz_file_info64 info;
        char fname[256];
        if (unzGetCurrentFileInfo64(zip, &info, fname, sizeof fname, NULL, 0, NULL, 0) != UNZ_OK) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: zip entry %u header unreadable", e);
        }
        if (info.size_filename >= sizeof fname) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: zip entry %u name too long", e);
        }
        size_t len = strlen(fname);
        if (len < 5 || strcmp(fname + len - 4, ".npy") != 0 || len - 4 >= sizeof npz->entries[0].array.name) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: entry '%s' is not a .npy array", fname);
        }
        fname[len - 4] = '\0';
        for (uint32_t k = 0; k < npz->count; ++k) {
            if (strcmp(npz->entries[k].array.name, fname) == 0) {
                return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' appears twice", fname);
            }
        }
        if (info.uncompressed_size > NPZ_MAX_ENTRY_BYTES || info.uncompressed_size < 10) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' has an implausible size of %llu bytes", fname,
                              (unsigned long long)info.uncompressed_size);
        }
        /* Sizes come from the (untrusted) directory: stored entries must match exactly, and
         * deflate cannot expand more than ~1032:1, so a larger claim is a forged header (and
         * would make us allocate gigabytes for a tiny file). */
        if (info.compressed_size > archive_size) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' claims %llu compressed bytes in a %llu-byte archive", fname,
                              (unsigned long long)info.compressed_size, (unsigned long long)archive_size);
        }
        if (info.compression_method == 0 ? info.uncompressed_size != info.compressed_size
                                         : info.compression_method != Z_DEFLATED ||
                                               info.uncompressed_size > info.compressed_size * 1040u + 1024u) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s': method %lu, %llu bytes from %llu compressed is not a valid entry",
                              fname, (unsigned long)info.compression_method, (unsigned long long)info.uncompressed_size,
                              (unsigned long long)info.compressed_size);
        }
        size_t n = (size_t)info.uncompressed_size;
        uint8_t *buf = weft__alloc(npz->context, n);
        if (!buf) {
            return WEFT_ERROR_OUT_OF_MEMORY;
        }
        npz_entry *entry = &npz->entries[npz->count++];
        entry->buffer = buf;
        entry->buffer_size = n;
        if (unzOpenCurrentFile(zip) != UNZ_OK) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' cannot be opened (unsupported compression?)", fname);
        }
        size_t got = 0;
        while (got < n) {
            size_t chunk = n - got > (1u << 30) ? (1u << 30) : n - got;
            int r = unzReadCurrentFile(zip, buf + got, (unsigned)chunk);
            if (r <= 0) {
                unzCloseCurrentFile(zip);
                return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' truncated or corrupt after %zu of %zu bytes", fname,
                                  got, n);
            }
            got += (size_t)r;
        }
        uint8_t extra;
        int tail = unzReadCurrentFile(zip, &extra, 1);
        int close_rc = unzCloseCurrentFile(zip);
        if (tail != 0 || close_rc != UNZ_OK) {
            return weft__fail(WEFT_ERROR_FORMAT, "npz: array '%s' fails its CRC or size check", fname);
        }
        weft_result r = weft_npy_parse(buf, n, fname, &entry->array);
        if (r != WEFT_OK) {
            return r;
        }
        rc = unzGoToNextFile(zip);
    }
    return WEFT_OK;
}

weft_result weft_npz_read_memory(weft_context *context, const void *bytes, size_t size, weft_npz **out_npz)
{
    if (!context || !bytes || !out_npz) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_npz_read_memory: NULL argument");
    }
    if (size < 22) {
        return weft__fail(WEFT_ERROR_FORMAT, "npz: %zu bytes, too short for a zip archive", size);
    }
    if ((uint64_t)size > NPZ_MAX_FILE_BYTES) {
        return weft__fail(WEFT_ERROR_FORMAT, "npz: %zu bytes, larger than the 4 GiB limit", size);
    }
    weft_npz *npz = weft__alloc(context, sizeof *npz);
    if (!npz) {
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    npz->context = context;
    mem_stream stream = {bytes, size, 0};
    zlib_filefunc64_def funcs = {mem_open, mem_read, mem_write, mem_tell, mem_seek, mem_close, mem_error, &stream};
    unzFile zip = unzOpen2_64("npz", &funcs);
    if (!zip) {
        weft_npz_destroy(npz);
        return weft__fail(WEFT_ERROR_FORMAT, "npz: not a zip archive (no readable central directory)");
    }
    weft_result r = read_entries(npz, zip, size);
    unzClose(zip);
    if (r != WEFT_OK) {
        weft_npz_destroy(npz);
        return r;
    }
    *out_npz = npz;
    return WEFT_OK;
}

weft_result weft_npz_read_file(weft_context *context, const char *path, weft_npz **out_npz)
{
    if (!context || !path || !out_npz) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "weft_npz_read_file: NULL argument");
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        return weft__fail(WEFT_ERROR_IO, "npz: cannot open '%s'", path);
    }
    long size = -1;
    if (fseek(f, 0, SEEK_END) == 0) {
        size = ftell(f);
    }
    if (size < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return weft__fail(WEFT_ERROR_IO, "npz: cannot size '%s'", path);
    }
    if ((uint64_t)size > NPZ_MAX_FILE_BYTES) {
        fclose(f);
        return weft__fail(WEFT_ERROR_FORMAT, "npz: '%s' is larger than the 4 GiB limit", path);
    }
    size_t n = (size_t)size;
    uint8_t *bytes = weft__alloc(context, n);
    if (!bytes) {
        fclose(f);
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    size_t got = fread(bytes, 1, n, f);
    fclose(f);
    weft_result r;
    if (got != n) {
        r = weft__fail(WEFT_ERROR_IO, "npz: short read on '%s'", path);
    } else {
        r = weft_npz_read_memory(context, bytes, n, out_npz);
    }
    weft__free(context, bytes, n);
    return r;
}

uint32_t weft_npz_count(const weft_npz *npz) { return npz ? npz->count : 0; }

const weft_npy_array *weft_npz_array(const weft_npz *npz, uint32_t index)
{
    return npz && index < npz->count ? &npz->entries[index].array : NULL;
}

const weft_npy_array *weft_npz_find(const weft_npz *npz, const char *name)
{
    if (!npz || !name) {
        return NULL;
    }
    for (uint32_t i = 0; i < npz->count; ++i) {
        if (strcmp(npz->entries[i].array.name, name) == 0) {
            return &npz->entries[i].array;
        }
    }
    return NULL;
}
