/* Skinned glTF/FBX import and the glTF writer: declared in the public include/weft/motion.h
 * (weft_assets); what follows is internal. */
#ifndef WEFT_ASSETS_GLTF_H
#define WEFT_ASSETS_GLTF_H

#include "weft/motion.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Tests and fuzzers: the child's wall-clock limit (seconds > 0; default 300), and strict mode,
 * in which a child that fails after assimp returned (in weft's own conversion code) aborts the
 * caller, so a fuzzer reports it as the defect it is. */
void weft__skinned_import_limits(double seconds, bool strict);

#ifdef __cplusplus
}
#endif

#endif
