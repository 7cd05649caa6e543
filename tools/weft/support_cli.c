/* Whole-string numeric option values (support_cli.h). */
#include "support_cli.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static bool digits_first(const char *v) { return v && v[0] >= '0' && v[0] <= '9'; }

/* A real number may start with a digit, or with '-' or '.' followed by something (strtod alone
 * skips spaces and takes "+5", "inf" and "nan"). */
static bool real_first(const char *v)
{
    return v && (digits_first(v) || ((v[0] == '-' || v[0] == '.') && v[1]));
}

/* The silent parsers: true with *out set, or false. */
static bool parse_whole(const char *v, uint64_t lo, uint64_t hi, uint64_t *out)
{
    if (!digits_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const unsigned long long n = strtoull(v, &end, 10);
    if (!end || *end || errno == ERANGE || n < lo || n > hi) {
        return false;
    }
    *out = (uint64_t)n;
    return true;
}

static bool parse_double(const char *v, double lo, double hi, double *out)
{
    if (!real_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const double x = strtod(v, &end);
    if (!end || *end || errno == ERANGE || !isfinite(x) || x < lo || x > hi) {
        return false;
    }
    *out = x;
    return true;
}

static bool parse_float(const char *v, float lo, float hi, float *out)
{
    if (!real_first(v)) {
        return false;
    }
    char *end = NULL;
    errno = 0;
    const float x = strtof(v, &end);
    if (!end || *end || errno == ERANGE || !isfinite(x) || x < lo || x > hi) {
        return false;
    }
    *out = x;
    return true;
}

/* The next item of a comma-separated list into buf (cap bytes); false when it is too long. *p
 * moves past the item and its comma; *last tells whether it was the final item. */
static bool next_item(const char **p, char *buf, size_t cap, bool *last)
{
    const size_t len = strcspn(*p, ",");
    if (len >= cap) {
        return false;
    }
    memcpy(buf, *p, len);
    buf[len] = '\0';
    *last = (*p)[len] == '\0';
    *p += len + !*last;
    return true;
}

bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out)
{
    if (!parse_whole(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a whole number in [%llu, %llu], got '%s'\n", tool, option, (unsigned long long)lo,
                (unsigned long long)hi, value ? value : "");
        return false;
    }
    return true;
}

bool cli_u32(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out)
{
    uint64_t n = 0;
    if (!cli_u64(tool, option, value, lo, hi, &n)) {
        return false;
    }
    *out = (uint32_t)n;
    return true;
}

bool cli_float(const char *tool, const char *option, const char *value, float lo, float hi, float *out)
{
    if (!parse_float(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a number in [%g, %g], got '%s'\n", tool, option, (double)lo, (double)hi,
                value ? value : "");
        return false;
    }
    return true;
}

bool cli_double(const char *tool, const char *option, const char *value, double lo, double hi, double *out)
{
    if (!parse_double(value, lo, hi, out)) {
        fprintf(stderr, "%s: %s wants a number in [%g, %g], got '%s'\n", tool, option, lo, hi, value ? value : "");
        return false;
    }
    return true;
}

bool cli_u32_list(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out,
                  size_t cap, size_t *count)
{
    uint32_t got[64];
    size_t n = 0;
    bool ok = value && *value && cap > 0 && cap <= sizeof got / sizeof got[0];
    for (const char *p = value; ok;) {
        char item[32];
        bool last = false;
        uint64_t x = 0;
        ok = n < cap && next_item(&p, item, sizeof item, &last) && parse_whole(item, lo, hi, &x);
        if (ok) {
            got[n++] = (uint32_t)x;
        }
        if (last) {
            break;
        }
    }
    if (!ok) {
        fprintf(stderr, "%s: %s wants 1 to %zu comma-separated whole numbers in [%lu, %lu], got '%s'\n", tool, option,
                cap, (unsigned long)lo, (unsigned long)hi, value ? value : "");
        return false;
    }
    memcpy(out, got, n * sizeof got[0]);
    *count = n;
    return true;
}

bool cli_floats(const char *tool, const char *option, const char *value, float lo, float hi, float *out, size_t n)
{
    float got[16];
    size_t k = 0;
    bool ok = value && n > 0 && n <= sizeof got / sizeof got[0];
    for (const char *p = value; ok;) {
        char item[64];
        bool last = false;
        ok = k < n && next_item(&p, item, sizeof item, &last) && parse_float(item, lo, hi, &got[k]);
        k += ok;
        if (last) {
            break;
        }
    }
    if (!ok || k != n) {
        fprintf(stderr, "%s: %s wants %zu comma-separated numbers in [%g, %g], got '%s'\n", tool, option, n, (double)lo,
                (double)hi, value ? value : "");
        return false;
    }
    memcpy(out, got, n * sizeof got[0]);
    return true;
}
