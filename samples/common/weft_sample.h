/* The avatar render sample, shared by samples/avatar_render and `weft render`. */
#ifndef WEFT_SAMPLE_H
#define WEFT_SAMPLE_H

#include "weft_render.h"
#include "weft/wear.h"

#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Options of the avatar sample; weft_avatar_sample_parse fills them from argv. */
typedef struct weft_avatar_sample_options {
    const char *motion;         /* procedural motion name or "bvh:PATH" (default "walk") */
    bool motion_given;          /* --motion was on the command line */
    const char *joint_map;      /* with a bvh:PATH motion: a joint map file (weft_bvh_read_joint_map);
                                   NULL (default): the naming tables */
    const char *avatar;         /* "gltf:PATH": the user's skinned character (character.h), played by its
                                   own animation; NULL (default): weft's avatar */
    const char *avatar_joint_map; /* with avatar and a mocap:/bvh: motion: the character's joint for each
                                   SMPL joint (weft_bvh_read_joint_map's format); the motion then plays
                                   on the character (weft_sample_character_set_clip) */
    const char *garment;        /* tshirt | skirt | dress | none | obj:PATH (a garment fitted to the
                                   avatar's bind pose) (default "tshirt"; with `avatar`, "none") */
    bool garment_given;         /* --garment was on the command line */
    const char *resolution;     /* garment resolution 1k | 4k | 16k | 40k (default "4k") */
    const char *sim_resolution; /* simulate this resolution of the garment and draw `resolution` from it
                                   through a weft_mesh_map; NULL (default): simulate what is drawn */
    const char *method;         /* auto | model | xpbd | lbs | skin (default "auto") */
    const char *model_path;     /* safetensors model for the model method; NULL (default): the shipped
                                   garment model for `precision`, tools/train/models/garment[.fp16|.int8].safetensors */
    weft_precision precision;   /* the model's arithmetic (default int8) */
    float tether_cm;            /* tether radius in cm (weft_garment_def.tethers.distance); < 0 (default):
                                   the worn-garment recipe's max distance, weft_sample_worn_tether_cm
                                   (none for the reference XPBD); 0: none */
    float strain_pct;           /* strain limit in % (weft_garment_def.strain.limit); < 0 (default): 10 %
                                   for the learned model, none for XPBD; 0: none */
    float push_cm;              /* collider push in cm (weft_garment_def.collision.push); < 0 (default):
                                   0.5, none for the reference XPBD; 0: off */
    float push_depth_cm;        /* deepest cloth the push moves out, cm (collision.push_depth); < 0
                                   (default): WEFT_WORN_PUSH_DEPTH_CM */
    int64_t collider_tokens;    /* the learned model's sampled collider tokens
                                   (weft_garment_def.max_collider_tokens); < 0 (default):
                                   WEFT_WORN_COLLIDER_TOKENS; 0: the whole crop */
    int body_parts;             /* the body collision by parts (weft_garment_def.collision.triangle_parts from
                                   weft_body_triangle_parts): 1 on, 0 off, < 0 (default) auto, as
                                   weft_sample_parts_on decides */
    bool ccd;                   /* the CCD post-process (weft_garment_def.ccd) (default false) */
    const char *export_dir;     /* --export DIR: garment.obj + garment.pc2, body.obj + body.pc2 over the
                                   rendered frames (samples/common/pc2.h); NULL (default): none */
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
    uint32_t crowd;             /* --crowd N: N avatars at mixed levels of detail (crowd.c); 0 = off (default) */
    const char *lod_table;      /* --lod-table: the measured LOD table for --crowd (default
                                 * samples/data/lod_garment.csv, else samples/data/lod.csv) */
    float crowd_mve;            /* --crowd-mve: the front row's accuracy target in cm; 0 = the best level's */
    float crowd_budget;         /* --crowd-budget: per-character ms budget for --crowd; 0 = none */
    bool cape;                  /* add the cape (cape.c) (default false) */
    uint32_t cape_xpbd_substeps; /* --cape-method xpbd-fast:S: the cape by fast XPBD; 0 = FNOpt (default) */
    const char *cape_model;     /* its FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors) */
    weft_precision cape_precision; /* its FNO arithmetic (default fp32) */
} weft_avatar_sample_options;

void weft_avatar_sample_default_options(weft_avatar_sample_options *options);
/* The mocap library's folder: $WEFT_MOCAP_DIR when set, else samples/mocap of the source tree
 * the build was configured from; NULL when neither is known. */
const char *weft_sample_mocap_dir(void);
/* The file behind a motion spec: "bvh:PATH" gives PATH; "mocap:NAME" gives the library clip
 * NAME (samples/mocap/clips/NAME.bvh.gz, or under $WEFT_MOCAP_DIR/clips when that is set).
 * Fails with WEFT_ERROR_INVALID_ARGUMENT naming the spec when it is neither or too long, and
 * with WEFT_ERROR_IO when a library clip does not exist. */
weft_result weft_sample_motion_path(const char *spec, char *out_path, size_t size);
/* The sample's command-line options, one table from which both the parsing (getopt_long) and the
 * help are made; `weft render` merges it with its own options. */
typedef struct weft_sample_option {
    const char *name;           /* the long name without "--" */
    const char *value;          /* the value's name in the help ("N", "on|off"); NULL: a flag */
    int id;                     /* what weft_avatar_sample_apply takes; 1 .. WEFT_AVATAR_SAMPLE_OPTION_ID_END - 1 */
    const char *help;           /* its help, lines separated by '\n' (at most 72 columns); NULL: not listed */
} weft_sample_option;
/* The ids of the sample's options are below this (and below ':', '?' and 'h', getopt's own
 * returns); a caller merging the table with its own options numbers those from here up. */
#define WEFT_AVATAR_SAMPLE_OPTION_ID_END 50
/* Ends with an entry whose name is NULL. */
extern const weft_sample_option weft_avatar_sample_option_table[];
/* Sets the option `id` of the table with its value (NULL for a flag). False when the value is
 * not one the option takes (the caller reports "bad value 'V' for --NAME"). */
bool weft_avatar_sample_apply(int id, const char *value, weft_avatar_sample_options *options);
/* Parses argv[1..argc) into options with getopt_long (--name value, --name=value, unambiguous
 * prefixes). Returns 0; 1 for -h/--help (nothing printed: the caller prints the usage); 2 after
 * printing one line naming `program` and the option to stderr (unknown option, missing or bad
 * value, a positional argument). */
int weft_avatar_sample_parse(const char *program, int argc, char **argv, weft_avatar_sample_options *options);
/* The help: "usage: PROGRAM [options]", a line about the sample, the options of the table. */
void weft_avatar_sample_usage(FILE *out, const char *program);
/* Runs the sample; returns a process exit status (0 on success) and prints per-frame timing. */
int weft_avatar_sample_run(const weft_avatar_sample_options *options);

#if WEFT_RENDER_HAVE_SAMPLE
#include "weft/body.h"
/* The sample's garment: loads the model (o->model_path, else the shipped garment model for
 * o->precision; a missing default file falls back to XPBD with a note) and creates the garment
 * with the first method that works (o->method "auto": model, xpbd, lbs), tethered as o->tether_cm
 * says. WEFT_OK with *out_garment NULL means only rigid skinning is left (o->method "skin", or
 * auto with nothing available); an error means the requested method or model failed (printed).
 * `label` receives e.g. "model int8". The caller destroys the garment, then the model. */
weft_result weft_avatar_sample_garment_create(const weft_avatar_sample_options *o, weft_context *ctx,
                                              const weft_body *body, const weft_cloth_mesh *cloth,
                                              weft_model **out_model, weft_garment **out_garment, char *label,
                                              size_t label_cap);
/* A motion by the render sample's --motion spelling: a procedural NAME (at `speed`),
 * mocap:CLIP of the library, bvh:PATH (plain or .gz) or gltf:PATH (a skinned glTF/FBX with SMPL
 * joint names), retargeted to `body`. verbose prints the BVH mapping report. */
typedef struct weft_sample_motion {
    bool procedural;
    weft_motion_def def;
    weft_clip *clip;
} weft_sample_motion;
weft_result weft_sample_motion_load(weft_context *ctx, const weft_body *body, const char *spec, float speed,
                                   bool verbose, weft_sample_motion *out);
/* The same with a joint map file for a bvh:PATH motion (NULL: the naming tables). */
weft_result weft_sample_motion_load_mapped(weft_context *ctx, const weft_body *body, const char *spec,
                                          const char *joint_map, float speed, bool verbose, weft_sample_motion *out);
weft_result weft_sample_motion_pose(const weft_sample_motion *m, double t, weft_pose *out);
void weft_sample_motion_free(weft_sample_motion *m);

/* The collider a worn garment is made on: rest positions (the bind pose), triangles, and body
 * parts (triangle_count ids, NULL: one part). */
typedef struct weft_sample_collider {
    const float *rest_positions;
    uint32_t vertex_count;
    const uint32_t *triangles;
    uint32_t triangle_count;
    const uint8_t *triangle_parts;
} weft_sample_collider;
/* weft_avatar_sample_garment_create on any collider and garment mesh (a user's character and OBJ);
 * `kind` picks the recipe's max distance (weft_sample_worn_tether_cm; WEFT_CLOTH_COUNT: the user's
 * own garment, the T-shirt's). */
weft_result weft_avatar_sample_garment_create_on(const weft_avatar_sample_options *o, weft_context *ctx,
                                                 const weft_sample_collider *collider, weft_cloth_kind kind,
                                                 const float *positions,
                                                 uint32_t vertex_count, const uint32_t *triangles,
                                                 uint32_t triangle_count, weft_model **out_model,
                                                 weft_garment **out_garment, char *label, size_t label_cap);

/* weft_default_garment_def() with `method`, the given cloth mesh as rest shape and the body (bind
 * pose) as collider. */
weft_garment_def weft_sample_body_garment_def(const weft_body *body, weft_method method, const float *positions,
                                              uint32_t vertex_count, const uint32_t *triangles, uint32_t triangle_count);
/* The worn-garment recipe (docs/WEAR.md) for `method`: the cloth mesh on the body as collider,
 * body parts from weft_body_triangle_parts written into `parts` (weft_body_triangle_count(body)
 * bytes, kept by the caller until the garment is created; NULL: no parts) and used where
 * weft_sample_parts_on(-1, false) says (CCD is off: none), the floor y = 0
 * (collision.ground), no CCD, a max distance of weft_sample_worn_tether_cm(cloth->kind), a 0.5 cm
 * push from up to 6 cm deep, and for the learned model a 10 % strain limit and at most
 * WEFT_WORN_COLLIDER_TOKENS collider tokens, an even sample of its crop (WEFT_COLLIDER_CAP_SAMPLE;
 * docs/LOD.md, Collider crop); the constants are weft/wear.h's. The reference XPBD
 * (WEFT_METHOD_XPBD) runs as simgen runs it on real motion: the same recipe with its collider
 * projected each substep (collider_projection). Callers override fields after it (the sample's
 * options). Fails only when the parts cannot be made. */
weft_result weft_sample_worn_def(const weft_body *body, const weft_cloth_mesh *cloth, weft_method method, uint8_t *parts,
                                 weft_garment_def *out);
/* The recipe's settings alone on `d`, for a garment of `kind` stepped by `method`: the floor
 * y = 0, no CCD, the max distance, the push and, for the learned model, the strain limit and the
 * sampled collider tokens; for the reference XPBD its projection and no push. The collider, the mesh,
 * the body parts and the substeps are the caller's (weft_sample_worn_def sets them; `weft eval
 * --recipe worn` scores simgen sequences with this on their own collider). */
void weft_sample_worn_recipe(weft_garment_def *d, weft_cloth_kind kind, weft_method method);
/* The recipe's max distance for a garment kind, in cm: WEFT_WORN_TETHER_SKIRT_CM for skirts and
 * WEFT_WORN_TETHER_DRESS_CM for dresses, whose hems swing wide of the skinned hem (held closer, a
 * hem a thigh kicks up through is held inside it; the dress's longer hem, let farther, leaves the
 * body), WEFT_WORN_TETHER_CM otherwise (docs/WEAR.md, The max distance). */
float weft_sample_worn_tether_cm(weft_cloth_kind kind);
/* Whether a worn garment collides by body parts: `mode` 1 on, 0 off; < 0 (auto) wherever CCD runs,
 * where the parts keep CCD from trapping cloth between two overlapping body parts; with CCD off the
 * push (and the reference's projection) moves cloth to the nearest body surface, and the whole body
 * keeps less cloth inside it (docs/WEAR.md, Body parts and the push). Every method alike. */
bool weft_sample_parts_on(int mode, bool ccd);
/* Sets def->substeps to `substeps` (0 keeps the def's). The reference XPBD runs as `weft simgen`
 * runs it: frames whose body moves fast near the cloth get up to WEFT_REFERENCE_SUBSTEP_FACTOR
 * times the substeps (substeps_max; docs/REFSIM.md, Fast colliders), or a walking body outruns its
 * contacts and passes through the cloth. Every other method keeps fixed substeps. */
#define WEFT_REFERENCE_SUBSTEP_FACTOR 8u
void weft_sample_set_substeps(weft_garment_def *def, uint32_t substeps);
/* The waistband of a skirt or dress for the reference XPBD, which runs without the max distance
 * that holds the band for the other methods: the garment's top ring (weft_mesh_top_ring, 1.2 cm)
 * as surface pins on the body's bind pose, as weft simgen pins it. *out is NULL for a T-shirt.
 * Each frame before the step, weft_sample_waistband_pin sets the pins on the collider of t+1
 * (scratch: 3 floats a band vertex, weft_surface_pins_count). */
weft_result weft_sample_waistband_create(weft_context *ctx, const weft_body *body, const weft_cloth_mesh *cloth,
                                         weft_surface_pins **out);
weft_result weft_sample_waistband_pin(const weft_surface_pins *band, weft_garment *garment, const float *collider_next,
                                      float *scratch);
/* The sample's settle pose for simulated frame k of `settle` (k < settle): the bind pose blended
 * into the motion's first pose by a smoothstep of (k + 1) / settle, per-joint slerp. */
void weft_avatar_sample_settle_pose(const weft_pose *bind, const weft_pose *first, uint32_t k, uint32_t settle,
                                    weft_pose *out);
#endif

/* Renders the documentation contact sheet: rows = no garment, T-shirt, skirt, dress; columns =
 * bind pose and poses from the procedural motions, garments skinned to the pose. */
int weft_avatar_sample_docs_sheet(const char *path, uint32_t tile_size);

/* Crowd mode (crowd.c): N avatars in a grid, each garment at the level the measured LOD table
 * picks for its distance; prints total and per-level cloth ms/frame, writes OUT/crowd.png. */
int weft_avatar_sample_crowd(const weft_avatar_sample_options *options);
/* Its options (--crowd, --lod-table, --crowd-mve, --crowd-budget; listed in
 * weft_avatar_sample_option_table): parses the value of `name` ("--crowd"), false on a bad value
 * (weft_avatar_sample_apply calls it). */
bool weft_avatar_sample_crowd_option(const char *name, const char *value, weft_avatar_sample_options *options);

#if WEFT_RENDER_HAVE_SAMPLE
#include "weft/body.h"

/* The cape (cape.c): an across x down grid cloth whose top row is pinned on a curve behind the
 * shoulders and neck of `body` (bind pose), the pins skinned with the body every step. Stepped
 * by FNOpt (weft/fnopt.h, the learned optimizer at K = 10) with body collision through weft's
 * constraint stage, or, for comparison on the same cloth, as a fast-XPBD garment over the same
 * grid with the same pins and body collision. */
typedef struct weft_sample_cape weft_sample_cape;

typedef struct weft_sample_cape_def {
    const char *model_path;     /* FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors) */
    weft_precision precision;   /* the FNO's arithmetic (default fp32) */
    uint32_t across, down;      /* grid, 10..256 each (default 32 x 40) */
    uint32_t xpbd_substeps;     /* 0 (default): FNOpt; S > 0: fast XPBD with S substeps instead */
} weft_sample_cape_def;

weft_sample_cape_def weft_sample_default_cape_def(void);
weft_result weft_sample_cape_create(weft_context *context, const weft_body *body, const weft_sample_cape_def *def,
                                    weft_sample_cape **out_cape);
/* One 1/60 s step with the pins at `pose`; with `body_vertices` (the body posed at `pose`) the
 * cape collides with the body (cape.c). The XPBD cape needs body_vertices (its solver collides
 * as it steps). On failure the cape keeps its previous state. */
weft_result weft_sample_cape_step(weft_sample_cape *cape, const weft_body *body, const weft_pose *pose,
                                  const float *body_vertices);
/* Cape vertices the last step's body collision moved. */
uint32_t weft_sample_cape_pushed(const weft_sample_cape *cape);
const float *weft_sample_cape_positions(const weft_sample_cape *cape); /* world metres */
uint32_t weft_sample_cape_vertex_count(const weft_sample_cape *cape);
const uint32_t *weft_sample_cape_triangles(const weft_sample_cape *cape, uint32_t *count);
float weft_sample_cape_units_per_metre(const weft_sample_cape *cape);
uint32_t weft_sample_cape_failed_steps(const weft_sample_cape *cape);
void weft_sample_cape_destroy(weft_sample_cape *cape);
#endif

/* ---------------------------------------------------------------------------------------- */
/* Sequence contact sheets (seqview.c, `weft render --seq DIR --sheet OUT.png`)              */

/* Renders chosen frames of a `weft simgen` sequence folder (meta.json, cloth_pos.npy [T,N,3],
 * faces.npy [F,3], collider_pos.npy [T,M,3] + collider_faces.npy [G,3], see weft/sim.h) into
 * one PNG: one tile per frame stamped with its frame number, cloth two-sided blue/orange, the
 * collider grey (skin-coloured for the garment scenario's avatar), one fixed camera framed on
 * the union bounding box of the chosen frames. Upward-facing collider triangles lying on the
 * collider's lowest plane (the scenarios' 6 m floor quad) are drawn as the renderer's checker
 * ground instead, so the framing follows the cloth and the objects. Rendering uses softpipe,
 * so the same folder and options give the same bytes. A caption strip carries meta.json's
 * description and validator verdict (validated, unvalidated or rejected). Every array is
 * validated (dtype, rank, shapes agreeing, indices in range, finite positions) before anything
 * is drawn; on failure nothing is written. */
#define WEFT_SEQ_SHEET_MAX_FRAMES 32u

typedef struct weft_seq_sheet_options {
    const char *seq_dir;        /* the sequence folder */
    const char *out_path;       /* the PNG to write */
    uint32_t frames[WEFT_SEQ_SHEET_MAX_FRAMES];
    uint32_t frame_count;       /* 0: five frames at 0, T/4, T/2, 3T/4 and T-1 (default) */
    uint32_t tile;              /* tile width in pixels, 64..1024 (default 240) */
    uint32_t tile_height;       /* 64..1024; 0: square, or 4:3 portrait for garments (default 0) */
    uint32_t columns;           /* tiles per row; 0: all in one row up to 6 (default 0) */
    float yaw, pitch;           /* camera direction in degrees, |pitch| <= 85; NaN: per scenario */
    bool caption;               /* the caption strip (default true) */
} weft_seq_sheet_options;

typedef struct weft_seq_sheet_info {
    uint32_t width, height;     /* of the written sheet */
    uint32_t tile_width, tile_height;
    uint32_t sequence_frames;   /* T */
    uint32_t cloth_vertices, cloth_triangles, collider_vertices, collider_triangles;
    uint32_t ground_triangles;  /* collider triangles drawn as the checker ground */
    uint32_t frames[WEFT_SEQ_SHEET_MAX_FRAMES];
    uint32_t frame_count;       /* the frames drawn, in tile order */
    int accepted;               /* meta.json "accepted": 1 true, 0 false, -1 absent */
    int validated;              /* meta.json "validator"."run": 1 true, 0 false (--no-validate), -1 absent */
    uint32_t validator_hits;    /* meta.json validator ccd_hits + intersection_hits */
    char scenario[32];          /* meta.json "scenario", or "" */
    char description[160];      /* meta.json "description", or "" */
} weft_seq_sheet_info;

void weft_seq_sheet_default_options(weft_seq_sheet_options *options);
/* Parses a comma-separated frame list ("0,60,120") into options->frames. INVALID_ARGUMENT on
 * an empty item, a non-number, a value over 2^31 or more than WEFT_SEQ_SHEET_MAX_FRAMES items;
 * options are unchanged on failure. Frames are checked against the sequence when rendering. */
weft_result weft_seq_sheet_parse_frames(const char *text, weft_seq_sheet_options *options);
/* Reads, renders and writes the sheet. out_info (optional) describes what was drawn. */
weft_result weft_seq_sheet_render(const weft_seq_sheet_options *options, weft_seq_sheet_info *out_info);

#ifdef __cplusplus
}
#endif

#endif
