/* BVH import: declared in the public include/weft/motion.h (weft_assets). */
#ifndef WEFT_ASSETS_BVH_H
#define WEFT_ASSETS_BVH_H

#include "weft/motion.h"

#endif
