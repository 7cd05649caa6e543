/*
 * Checks a skinned-mesh file before assimp 5.2 reads it (weft_assets, internal).
 *
 * assimp's glTF and FBX readers crash, rather than fail, on some malformed or merely unusual
 * files. weft_skinned_load_file refuses those input classes first, with WEFT_ERROR_FORMAT and a
 * message:
 *   glTF (JSON text, or the JSON chunk of a .glb)
 *     - JSON that cJSON cannot parse (so nothing below slips into assimp's own parser),
 *     - a skin without inverseBindMatrices, or whose accessor is not a float MAT4 with a matrix
 *       per joint (optional in glTF 2.0, but assimp dereferences it: upstream issue 3465).
 *   FBX (binary, or ASCII text when the name ends in .fbx or the first bytes mention FBX)
 *     - a cycle in the object connections, a self-connection included (assimp's node
 *       conversion recurses along them until the stack overflows),
 *     - scopes nested deeper than 64 levels (assimp's parser recurses per level),
 *     - (ASCII) a skin cluster index beyond every mesh's control points, or negative (assimp's
 *       converter asserts and aborts).
 *   Anything else: a file that is neither glTF 2.0 (JSON text, or a glb of version 2 whose
 *     header length is the file's size and whose first chunk is JSON) nor FBX (binary, or ASCII
 *     opening with its ';' comment or its first record) is refused, so
 *     assimp never tries its other readers (one kept busy for minutes by 55 bytes of noise).
 * Structure the checks do not understand inside glTF and FBX is left to assimp.
 */
#ifndef WEFT_ASSETS_ASSIMP_CHECK_H
#define WEFT_ASSETS_ASSIMP_CHECK_H

#include "weft.h"

/* WEFT_OK, or WEFT_ERROR_FORMAT / _IO / _OUT_OF_MEMORY with a message naming path. */
weft_result weft__assimp_check_file(const char *path);

#endif
