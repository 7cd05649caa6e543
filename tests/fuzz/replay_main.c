/* Runs the libFuzzer target without libFuzzer, so every ctest run (and every sanitizer build)
 * exercises it: each corpus file as is, then deterministic mutations of it: bit flips,
 * truncations, byte insertions and deletions, length-field rewrites, and edits of the header
 * JSON with the length field kept consistent, half of them number substitutions that keep the
 * JSON valid (so they reach the shape, offset and layout validators past the parser).
 *
 *   test_fuzz_safetensors_replay CORPUS_DIR [MUTATIONS_PER_FILE] */
#define _POSIX_C_SOURCE 200809L /* opendir, readdir */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

typedef struct rng {
    uint64_t s;
} rng;

static uint32_t next(rng *r)
{
    r->s ^= r->s << 13;
    r->s ^= r->s >> 7;
    r->s ^= r->s << 17;
    return (uint32_t)(r->s >> 11);
}

static uint32_t below(rng *r, size_t n) { return n ? (uint32_t)(next(r) % n) : 0; }

static const uint8_t g_interesting[] = {'{', '}', '[', ']', '"', ',', ':', '0', '9', '-', '.',
                                        'e', '\\', ' ', 0x00, 0xff, 0x80, 0xc3, 'u', 'F'};
static const char *const g_tokens[] = {
    "18446744073709551616", "9007199254740993", "9007199254740992", "-1", "-0", "1e308", "1e999", "0", "4.5",
    "1099511627776", "[]", "{}", "null", "true", "\"F32\"", "\"BF16\"", "\"I64\"", "\"__metadata__\"",
    "\"dtype\"", "\"shape\"", "\"data_offsets\"", "\\u0000", "\\ud800", "[[[[[[[[[[[[[[[[[[",
};

/* One edit of buf[0..*len) in place; cap is the buffer's capacity. */
static void mutate_bytes(rng *r, uint8_t *buf, size_t *len, size_t cap)
{
    size_t n = *len;
    switch (below(r, 6)) {
    case 0: /* bit flip */
        if (n) {
            buf[below(r, n)] ^= (uint8_t)(1u << below(r, 8));
        }
        break;
    case 1: /* truncate */
        *len = below(r, n + 1);
        break;
    case 2: /* insert a byte */
        if (n < cap) {
            size_t at = below(r, n + 1);
            memmove(buf + at + 1, buf + at, n - at);
            buf[at] = (next(r) & 1) ? g_interesting[below(r, sizeof g_interesting)] : (uint8_t)next(r);
            *len = n + 1;
        }
        break;
    case 3: /* delete a range */
        if (n) {
            size_t at = below(r, n), k = 1 + below(r, n - at < 8 ? n - at : 8);
            memmove(buf + at, buf + at + k, n - at - k);
            *len = n - k;
        }
        break;
    case 4: /* overwrite a byte */
        if (n) {
            buf[below(r, n)] = g_interesting[below(r, sizeof g_interesting)];
        }
        break;
    default: { /* splice in a token */
        const char *tok = g_tokens[below(r, sizeof g_tokens / sizeof g_tokens[0])];
        size_t k = strlen(tok), at = below(r, n + 1), drop = below(r, n - at < 4 ? n - at + 1 : 5);
        if (n - drop + k <= cap) {
            memmove(buf + at + k, buf + at + drop, n - at - drop);
            memcpy(buf + at, tok, k);
            *len = n - drop + k;
        }
        break;
    }
    }
}

/* Replaces one run of digits (a dimension, an offset, a config value) with another number, so
 * the edit keeps the JSON valid and lands in the shape/offset/layout validators. */
static void mutate_number(rng *r, uint8_t *buf, size_t *len, size_t cap)
{
    static const char *const numbers[] = {"0", "1", "2", "3", "4", "7", "8", "9", "16", "255", "256", "65536",
                                          "4294967296", "9007199254740991", "9007199254740992",
                                          "18446744073709551615", "1099511627776", "2.5", "-1", "1e3"};
    size_t n = *len, runs = 0;
    for (size_t i = 0; i < n; ++i) {
        runs += (buf[i] >= '0' && buf[i] <= '9') && (i == 0 || buf[i - 1] < '0' || buf[i - 1] > '9');
    }
    if (runs == 0) {
        return;
    }
    size_t pick = below(r, runs), at = 0, seen = 0;
    for (size_t i = 0; i < n; ++i) {
        if ((buf[i] >= '0' && buf[i] <= '9') && (i == 0 || buf[i - 1] < '0' || buf[i - 1] > '9') && seen++ == pick) {
            at = i;
            break;
        }
    }
    size_t end = at;
    while (end < n && buf[end] >= '0' && buf[end] <= '9') {
        end++;
    }
    char tmp[32];
    if (next(r) & 1) {
        snprintf(tmp, sizeof tmp, "%s", numbers[below(r, sizeof numbers / sizeof numbers[0])]);
    } else { /* nudge the value by a little */
        unsigned long long v = 0;
        for (size_t i = at; i < end && i < at + 18; ++i) {
            v = v * 10 + (unsigned long long)(buf[i] - '0');
        }
        static const long long deltas[] = {-8, -4, -2, -1, 1, 2, 4, 8};
        snprintf(tmp, sizeof tmp, "%llu", v + (unsigned long long)deltas[below(r, 8)]);
    }
    size_t k = strlen(tmp);
    if (n - (end - at) + k <= cap) {
        memmove(buf + at + k, buf + end, n - end);
        memcpy(buf + at, tmp, k);
        *len = n - (end - at) + k;
    }
}

static uint64_t read_u64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; --i) {
        v = (v << 8) | p[i];
    }
    return v;
}

static void write_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

/* Builds one mutant of `src` into `dst` (capacity cap) and returns its length. */
static size_t make_mutant(rng *r, const uint8_t *src, size_t size, uint8_t *dst, size_t cap)
{
    size_t len = size;
    memcpy(dst, src, size);
    uint64_t n = size >= 8 ? read_u64(src) : UINT64_MAX;
    uint32_t edits = 1 + below(r, 3);
    if (n <= size - 8 && (next(r) & 1)) {
        /* Edit the header text only and fix up the length field. */
        size_t hlen = (size_t)n, data_len = size - 8 - (size_t)n;
        uint8_t *header = dst + 8;
        size_t header_cap = cap - 8 - data_len;
        for (uint32_t e = 0; e < edits; ++e) {
            if (next(r) & 1) {
                mutate_number(r, header, &hlen, header_cap);
            } else {
                mutate_bytes(r, header, &hlen, header_cap);
            }
        }
        memcpy(dst + 8 + hlen, src + 8 + n, data_len);
        write_u64(dst, hlen);
        return 8 + hlen + data_len;
    }
    if (len >= 8 && below(r, 4) == 0) {
        static const int64_t deltas[] = {-8, -1, 1, 8};
        uint64_t v = below(r, 3) == 0 ? (uint64_t)next(r) << below(r, 40) : n + (uint64_t)deltas[below(r, 4)];
        write_u64(dst, v);
        return len;
    }
    for (uint32_t e = 0; e < edits; ++e) {
        mutate_bytes(r, dst, &len, cap);
    }
    return len;
}

static int cmp_names(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s CORPUS_DIR [MUTATIONS_PER_FILE]\n", argv[0]);
        return 2;
    }
    long mutations = argc > 2 ? strtol(argv[2], NULL, 10) : 400;
    DIR *dir = opendir(argv[1]);
    if (!dir) {
        fprintf(stderr, "cannot open corpus directory %s\n", argv[1]);
        return 1;
    }
    char *names[1024];
    size_t count = 0;
    for (struct dirent *e; (e = readdir(dir)) != NULL && count < 1024;) {
        if (e->d_name[0] != '.') {
            names[count] = malloc(strlen(e->d_name) + 1);
            if (!names[count]) {
                closedir(dir);
                return 1;
            }
            strcpy(names[count++], e->d_name);
        }
    }
    closedir(dir);
    qsort(names, count, sizeof *names, cmp_names);

    long runs = 0;
    int status = count ? 0 : 1;
    const char *trace = getenv("WEFT_REPLAY_TRACE");
    for (size_t i = 0; i < count; ++i) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", argv[1], names[i]);
        FILE *f = fopen(path, "rb");
        uint8_t *src = NULL, *dst = NULL;
        size_t size = 0;
        if (f && fseek(f, 0, SEEK_END) == 0) {
            long end = ftell(f);
            size = end > 0 ? (size_t)end : 0;
            rewind(f);
            src = malloc(size + 1);
            dst = malloc(2 * size + 256);
            if (src && dst && fread(src, 1, size, f) != size) {
                free(src);
                src = NULL;
            }
        }
        if (f) {
            fclose(f);
        }
        if (!src || !dst) {
            fprintf(stderr, "cannot read %s\n", path);
            status = 1;
        } else {
            LLVMFuzzerTestOneInput(src, size);
            runs++;
            rng r = {0x9E3779B97F4A7C15ull ^ (uint64_t)(i + 1) * 0xBF58476D1CE4E5B9ull};
            for (long k = 0; k < mutations; ++k) {
                size_t len = make_mutant(&r, src, size, dst, 2 * size + 256);
                if (trace) { /* WEFT_REPLAY_TRACE=DIR: each mutant written before it runs */
                    char out[4200];
                    snprintf(out, sizeof out, "%s/last_input", trace);
                    FILE *t = fopen(out, "wb");
                    if (t) {
                        fwrite(dst, 1, len, t);
                        fclose(t);
                    }
                    fprintf(stderr, "%s mutant %ld\n", names[i], k);
                }
                LLVMFuzzerTestOneInput(dst, len);
                runs++;
            }
        }
        free(src);
        free(dst);
        free(names[i]);
    }
    printf("%zu corpus files, %ld inputs replayed\n", count, runs);
    return status;
}
