/* Internal layout of the LOD table and the level-switching garment (include/weft/lod.h). */
#ifndef WEFT_LOD_INTERNAL_H
#define WEFT_LOD_INTERNAL_H

#include "core/core.h"
#include "weft/lod.h"

struct weft_lod_table {
    const weft_context *ctx;
    weft_lod_level *levels;
    uint32_t count;
};

#endif
