/* Point caches for DCC tools: a mesh's rest shape as OBJ plus its per-frame positions as PC2
 * (the point-cache format Blender, Maya and 3ds Max read). The render sample's --export writes
 * one pair for the garment and one for the body (docs/RENDER.md, *Export*).
 *
 * PC2 layout (little-endian): char[12] "POINTCACHE2\0", int32 version (1), int32 point count,
 * float start frame, float sample rate (frames per sample, 1), int32 sample count, then
 * sample count x point count x 3 float32 positions. */
#ifndef WEFT_SAMPLE_PC2_H
#define WEFT_SAMPLE_PC2_H

#include "weft.h"

#include <stdio.h>

typedef struct weft_pc2_writer {
    FILE *f;
    uint32_t points, samples;
} weft_pc2_writer;

/* Creates path (truncating) and writes a header for `points` points starting at start_frame. */
weft_result weft_pc2_open(weft_pc2_writer *w, const char *path, uint32_t points, float start_frame);
/* Appends one sample (points * 3 floats; rejected when not finite). */
weft_result weft_pc2_write(weft_pc2_writer *w, const float *positions);
/* Writes the sample count into the header and closes the file. */
weft_result weft_pc2_close(weft_pc2_writer *w);

/* Reads a whole PC2 file: *out_positions (malloc'd, samples * points * 3; the caller frees).
 * Fails with WEFT_ERROR_FORMAT on a bad signature or version, counts that disagree with the
 * file's size, or non-finite values. */
weft_result weft_pc2_read(const char *path, float **out_positions, uint32_t *out_points, uint32_t *out_samples,
                          float *out_start_frame);

/* Writes an OBJ of the mesh (v lines, then 1-based f lines). */
weft_result weft_obj_write(const char *path, const float *positions, uint32_t vertex_count, const uint32_t *triangles,
                           uint32_t triangle_count);

/* Reads an OBJ's vertices ("v x y z") and faces ("f a b c ...", with optional /vt/vn parts and
 * negative, relative indices; polygons become triangle fans); other statements are ignored.
 * *out_positions (vertex_count * 3) and *out_triangles (triangle_count * 3) are malloc'd; the
 * caller frees them. Fails naming the file and line: WEFT_ERROR_IO (cannot open or read),
 * WEFT_ERROR_FORMAT (a bad number, an index naming no earlier vertex, a face of fewer than 3
 * corners, no vertices or faces, NUL bytes, lines over 4 KB, over 1 GiB, 2^24 vertices or 2^26
 * triangles), WEFT_ERROR_NOT_FINITE (a coordinate beyond +-WEFT_MAX_COORDINATE). Nothing is
 * returned on failure. */
weft_result weft_obj_read(const char *path, float **out_positions, uint32_t *out_vertex_count, uint32_t **out_triangles,
                          uint32_t *out_triangle_count);
#endif
