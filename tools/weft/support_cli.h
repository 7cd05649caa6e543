/* Numeric command-line values, parsed whole: the entire string is the number (no sign unless the
 * range allows negatives, no spaces, no trailing text, no overflow, nothing but finite numbers)
 * and it lies in [lo, hi]. On failure each prints "<tool>: <option> wants <what> in [lo, hi],
 * got '<value>'" to stderr and returns false, leaving *out unchanged. Commands exit with status 2
 * (a usage error) when one fails, before doing any work. */
#ifndef WEFT_SUPPORT_CLI_H
#define WEFT_SUPPORT_CLI_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

bool cli_u32(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out);
bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out);
bool cli_float(const char *tool, const char *option, const char *value, float lo, float hi, float *out);
bool cli_double(const char *tool, const char *option, const char *value, double lo, double hi, double *out);

/* "5,10,20": one to cap comma-separated whole numbers, each in [lo, hi] (no empty items). Writes
 * out[0 .. *count) only on success. */
bool cli_u32_list(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out,
                  size_t cap, size_t *count);

/* "1000,8,0.5": exactly n comma-separated numbers, each in [lo, hi]. Writes out[0 .. n) only on
 * success. */
bool cli_floats(const char *tool, const char *option, const char *value, float lo, float hi, float *out, size_t n);

#endif
