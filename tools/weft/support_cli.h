/* Numeric command-line values, parsed whole: the entire string is the number (no sign unless the
 * range allows negatives, no spaces, no trailing text, no overflow) and it lies in [lo, hi].
 * On failure each prints "<tool>: <option> wants <what> in [lo, hi], got '<value>'" to stderr
 * and returns false, leaving *out unchanged. */
#ifndef WEFT_SUPPORT_CLI_H
#define WEFT_SUPPORT_CLI_H

#include <stdbool.h>
#include <stdint.h>

bool cli_u32(const char *tool, const char *option, const char *value, uint32_t lo, uint32_t hi, uint32_t *out);
bool cli_u64(const char *tool, const char *option, const char *value, uint64_t lo, uint64_t hi, uint64_t *out);
bool cli_float(const char *tool, const char *option, const char *value, float lo, float hi, float *out);

#endif
