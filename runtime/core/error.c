#include "core/core.h"

#include <stdio.h>

static _Thread_local char g_last_error[512];

static const char *const g_result_strings[WEFT_RESULT_COUNT] = {
    [WEFT_OK] = "ok",
    [WEFT_ERROR_INVALID_ARGUMENT] = "invalid argument",
    [WEFT_ERROR_OUT_OF_MEMORY] = "out of memory",
    [WEFT_ERROR_IO] = "i/o error",
    [WEFT_ERROR_NOT_FINITE] = "non-finite value",
    [WEFT_ERROR_SIZE_MISMATCH] = "size mismatch",
    [WEFT_ERROR_DEGENERATE_MESH] = "degenerate mesh",
    [WEFT_ERROR_TOPOLOGY_MISMATCH] = "topology mismatch",
    [WEFT_ERROR_NO_MODEL] = "no model",
    [WEFT_ERROR_NO_COLLIDER] = "collider not set for this frame",
    [WEFT_ERROR_UNSUPPORTED] = "unsupported",
    [WEFT_ERROR_FILE_TRUNCATED] = "file truncated",
    [WEFT_ERROR_HEADER_TOO_LARGE] = "header too large",
    [WEFT_ERROR_HEADER_JSON] = "malformed header JSON",
    [WEFT_ERROR_DUPLICATE_NAME] = "duplicate name",
    [WEFT_ERROR_UNKNOWN_DTYPE] = "unknown dtype",
    [WEFT_ERROR_BAD_SHAPE] = "bad shape",
    [WEFT_ERROR_BAD_OFFSETS] = "bad data offsets",
    [WEFT_ERROR_SIZE_OVERFLOW] = "size overflow",
    [WEFT_ERROR_OVERLAP] = "overlapping or non-contiguous tensors",
    [WEFT_ERROR_MISSING_TENSOR] = "missing tensor",
    [WEFT_ERROR_TENSOR_SHAPE] = "tensor shape mismatch",
    [WEFT_ERROR_TENSOR_DTYPE] = "tensor dtype mismatch",
    [WEFT_ERROR_BAD_METADATA] = "bad metadata",
    [WEFT_ERROR_FORMAT] = "malformed file",
    [WEFT_ERROR_NOT_CONVERGED] = "not converged",
    [WEFT_ERROR_BUSY] = "busy",
};

const char *weft_result_string(weft_result result)
{
    if ((unsigned)result >= WEFT_RESULT_COUNT || !g_result_strings[result]) {
        return "unknown result";
    }
    return g_result_strings[result];
}

const char *weft_last_error(void) { return g_last_error; }

void weft__clear_error(void) { g_last_error[0] = '\0'; }

weft_result weft__fail(weft_result result, const char *fmt, ...)
{
    va_list args;
    va_start(args, fmt);
    vsnprintf(g_last_error, sizeof g_last_error, fmt, args);
    va_end(args);
    return result;
}
