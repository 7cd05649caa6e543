/* The avatar render sample, shared by samples/avatar_render and `weft render`. */
#ifndef WEFT_SAMPLE_H
#define WEFT_SAMPLE_H

#include "weft_render.h"

#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Options of the avatar sample; weft_avatar_sample_parse fills them from argv. */
typedef struct weft_avatar_sample_options {
    const char *motion;         /* procedural motion name or "bvh:PATH" (default "walk") */
    const char *garment;        /* tshirt | skirt | dress | none (default "tshirt") */
    const char *resolution;     /* garment resolution 1k | 4k | 16k | 40k (default "4k") */
    const char *method;         /* auto | model | xpbd | lbs | skin (default "auto") */
    const char *model_path;     /* safetensors model for the model method, or NULL */
    const char *out_dir;        /* frames and the contact sheet go here (default "avatar_frames") */
    uint32_t frames;            /* rendered frames at 60 Hz (default 120) */
    uint32_t settle_frames;     /* simulated frames blending from the bind pose into frame 0 (default 30) */
    uint32_t width, height;     /* image size (default 320 x 320) */
    uint32_t sheet_tiles;       /* frames on the contact sheet (default 8) */
    float yaw, pitch;           /* camera direction, degrees (default 25, 8) */
    float speed;                /* procedural motion speed (default 1) */
    bool write_frames;          /* write frame_NNNN.png (default true) */
    bool deterministic;         /* softpipe (reproducible) instead of llvmpipe (faster) (default false) */
    float start;                /* seconds into the motion to start at (default 0) */
} weft_avatar_sample_options;

void weft_avatar_sample_default_options(weft_avatar_sample_options *options);
/* Parses the options above from argv[first..argc). Returns 0, or 2 after printing the usage
 * (unknown option, bad value) to stderr, or 1 for --help (usage printed to stdout). */
int weft_avatar_sample_parse(int argc, char **argv, int first, weft_avatar_sample_options *options);
void weft_avatar_sample_usage(FILE *out, const char *program);
/* Runs the sample; returns a process exit status (0 on success) and prints per-frame timing. */
int weft_avatar_sample_run(const weft_avatar_sample_options *options);

/* Renders the documentation contact sheet: rows = no garment, T-shirt, skirt, dress; columns =
 * bind pose and poses from the procedural motions, garments skinned to the pose. */
int weft_avatar_sample_docs_sheet(const char *path, uint32_t tile_size);

#ifdef __cplusplus
}
#endif

#endif
