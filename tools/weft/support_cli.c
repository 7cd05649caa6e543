/* Whole-string numeric option values (support_cli.h). */
#include "support_cli.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static bool digits_first(const char *v) { return v && v[0] >= '0' && v[0] <= '9'; }

bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out)
{
    char *end = NULL;
    errno = 0;
    unsigned long long n = digits_first(value) ? strtoull(value, &end, 10) : 0;
    if (!digits_first(value) || !end || *end || errno == ERANGE || n < lo || n > hi) {
        fprintf(stderr, "%s: %s wants a whole number in [%llu, %llu], got '%s'\n", tool, option, (unsigned long long)lo,
                (unsigned long long)hi, value ? value : "");
        return false;
    }
    *out = (uint64_t)n;
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
    char *end = NULL;
    errno = 0;
    const bool starts = value && (digits_first(value) || ((value[0] == '-' || value[0] == '.') && value[1]));
    float x = starts ? strtof(value, &end) : NAN;
    if (!starts || !end || *end || errno == ERANGE || !isfinite(x) || x < lo || x > hi) {
        fprintf(stderr, "%s: %s wants a number in [%g, %g], got '%s'\n", tool, option, (double)lo, (double)hi,
                value ? value : "");
        return false;
    }
    *out = x;
    return true;
}
