/* The avatar render sample: the default avatar performs a motion wearing a garment; the cloth
 * is stepped through the public garment API with the best method this build has (the learned
 * model when a model file is given, else XPBD, else LBS). Only when no method can be created
 * is the garment skinned rigidly with the body, and the output says so. Frames are written as
 * PNGs with a contact sheet, and every frame's timing is printed. */
#define _POSIX_C_SOURCE 200809L

#include "weft_sample.h"
#include "weft_scenes.h"
#include "weft/wear.h"
#include "pc2.h"
#include "character.h"
#include "core/core.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if WEFT_RENDER_HAVE_SAMPLE
#include "weft/body.h"
#include "weft/lod.h"
#if WEFT_RENDER_HAVE_ASSETS
#include "bvh.h"
#include "gltf.h"
#endif
#endif

void weft_avatar_sample_default_options(weft_avatar_sample_options *o)
{
    memset(o, 0, sizeof *o);
    o->motion = "walk";
    o->garment = "tshirt";
    o->resolution = "4k";
    o->method = "auto";
    o->precision = WEFT_PRECISION_INT8;
    o->tether_cm = -1.0f;
    o->strain_pct = -1.0f;
    o->body_parts = -1;
    o->ccd = false;
    o->push_cm = -1.0f;
    o->push_depth_cm = -1.0f;
    o->collider_tokens = -1;
    o->out_dir = "avatar_frames";
    o->frames = 120;
    o->settle_frames = 30;
    o->width = 320;
    o->height = 320;
    o->sheet_tiles = 8;
    o->yaw = 25.0f;
    o->pitch = 8.0f;
    o->speed = 1.0f;
    o->write_frames = true;
    o->cape_model = "tools/fnopt/models/fnopt_32.safetensors";
}

/* ---- Options ---------------------------------------------------------------------------------
 * One table, read by getopt_long (here and, merged with its own options, by `weft render`), from
 * which the help is printed. */

enum {
    OPT_MOTION = 1, OPT_JOINT_MAP, OPT_AVATAR, OPT_AVATAR_JOINT_MAP, OPT_GARMENT, OPT_RESOLUTION,
    OPT_SIM_RESOLUTION, OPT_METHOD, OPT_MODEL, OPT_PRECISION, OPT_TETHER_CM, OPT_STRAIN_LIMIT, OPT_PUSH_CM,
    OPT_PUSH_DEPTH_CM,
    OPT_COLLIDER_TOKENS,
    OPT_BODY_PARTS, OPT_CCD, OPT_EXPORT, OPT_FRAMES, OPT_SETTLE, OPT_OUT, OPT_SIZE, OPT_SHEET, OPT_YAW, OPT_PITCH,
    OPT_SPEED, OPT_START, OPT_DETERMINISTIC, OPT_NO_FRAMES, OPT_CAPE, OPT_CAPE_MODEL, OPT_CAPE_PRECISION, OPT_CAPE_METHOD,
    OPT_CROWD, OPT_LOD_TABLE, OPT_CROWD_MVE, OPT_CROWD_BUDGET,
    OPT_COUNT
};
_Static_assert(OPT_COUNT <= WEFT_AVATAR_SAMPLE_OPTION_ID_END, "the sample's option ids are below the bound");

const weft_sample_option weft_avatar_sample_option_table[] = {
    {"motion", "NAME|mocap:CLIP|bvh:PATH|gltf:PATH", OPT_MOTION,
     "idle walk run jump dance arm_raise flip, a clip of the CMU library by\n"
     "name (samples/mocap/clips.csv, e.g. mocap:walk_cmu07_01), a BVH file\n"
     "(plain or .gz), or a skinned glTF/FBX with SMPL joint names\n"
     "(default walk)"},
    {"joint-map", "FILE", OPT_JOINT_MAP,
     "with bvh:PATH, the file's joint for each SMPL joint, one 'smpl_joint\n"
     "source_joint' a line, for skeletons no naming table knows\n"
     "(docs/RENDER.md)"},
    {"avatar", "gltf:PATH", OPT_AVATAR,
     "your own skinned character (glTF/FBX, any joint names, metres, Y up)\n"
     "as the collider, played by its own animation (--start, --frames), or\n"
     "by a mocap:/bvh: --motion with --avatar-joint-map; garments then come\n"
     "from --garment obj:PATH (docs/RENDER.md, Your own character)"},
    {"avatar-joint-map", "FILE", OPT_AVATAR_JOINT_MAP,
     "with --avatar and a mocap:/bvh: --motion: the character's joint for\n"
     "each SMPL joint, one 'smpl_joint character_joint' a line (the\n"
     "--joint-map format)"},
    {"garment", "KIND", OPT_GARMENT,
     "tshirt | skirt | dress | none | obj:PATH, an OBJ garment fitted to the\n"
     "avatar's bind pose (default tshirt; with --avatar, none)"},
    {"resolution", "RES", OPT_RESOLUTION, "garment mesh 1k | 4k | 16k | 40k (default 4k)"},
    {"sim-resolution", "RES", OPT_SIM_RESOLUTION,
     "simulate this mesh of the garment and draw --resolution from it\n"
     "(a mesh map; default: 1k for the learned model (auto, model), else the\n"
     "drawn mesh; --sim-resolution 4k simulates a 4k garment directly)"},
    {"method", "M", OPT_METHOD,
     "auto | model | xpbd[:S] | xpbd-fast[:S] | lbs | skin (default auto:\n"
     "the learned model, else xpbd, lbs); S substeps, 1..1000 (default 10);\n"
     "xpbd is the reference as weft simgen runs it (frames of a fast body\n"
     "get up to 8 S substeps), xpbd-fast XPBD as a game runs it, fixed S\n"
     "(docs/REFSIM.md)"},
    {"model", "FILE", OPT_MODEL,
     "safetensors model for the model method (default: the shipped garment\n"
     "model for --precision,\n"
     "tools/train/models/garment[.fp16|.int8].safetensors)"},
    {"precision", "P", OPT_PRECISION, "fp32 | fp16 | int8: the model's arithmetic (default int8)"},
    {"tether-cm", "X", OPT_TETHER_CM,
     "tether every garment vertex within X cm of its skinned position,\n"
     "0..1000 (default 8, skirts 16, dresses 12, off for xpbd; 0: off)"},
    {"strain-limit", "PCT", OPT_STRAIN_LIMIT,
     "shorten garment edges stretched over PCT % after each step, 0..1000\n"
     "(0: off; default 10 for the learned model, off for xpbd)"},
    {"push-cm", "X", OPT_PUSH_CM,
     "push garment cloth inside the body (up to --push-depth-cm) or nearer than\n"
     "X cm to X cm in front of it, 0..10 (default 0.5, off for xpbd; 0: off;\n"
     "docs/CCD.md, Collider push)"},
    {"push-depth-cm", "X", OPT_PUSH_DEPTH_CM, "the deepest cloth the push moves out, 0..50 (default 6)"},
    {"collider-tokens", "N", OPT_COLLIDER_TOKENS,
     "the learned model sees at most N collider triangles, an even sample of\n"
     "its crop weighted in its attention, 0..1000000 (default 1024; 0: the\n"
     "whole crop; docs/LOD.md, The sample cap)"},
    {"body-parts", "auto|on|off", OPT_BODY_PARTS,
     "garment vertices collide only with the body parts they lie against at\n"
     "rest (each triangle's dominant bone; docs/CCD.md, Body parts); default\n"
     "auto: on where CCD runs"},
    {"ccd", "on|off", OPT_CCD,
     "the CCD post-process after each step (default off: its cost is\n"
     "unbounded where the body overlaps itself; docs/CCD.md, Body parts)"},
    {"export", "DIR", OPT_EXPORT,
     "write garment.obj + garment.pc2 and body.obj + body.pc2 (point caches\n"
     "of the rendered frames, for Blender, Maya, 3ds Max; docs/RENDER.md,\n"
     "Export)"},
    {"frames", "N", OPT_FRAMES, "frames to render at 60 Hz, 1..100000 (default 120)"},
    {"settle", "N", OPT_SETTLE,
     "simulated frames blending from the bind pose into the motion,\n"
     "0..10000 (default 30)"},
    {"out", "DIR", OPT_OUT,
     "output folder for frame_NNNN.png and contact_sheet.png\n"
     "(default avatar_frames)"},
    {"size", "WxH", OPT_SIZE, "image size, each 16..4096 (default 320x320)"},
    {"sheet", "N", OPT_SHEET, "frames on the contact sheet, 1..64 (default 8)"},
    {"yaw", "DEG", OPT_YAW, "camera direction about the vertical, -360..360 (default 25)"},
    {"pitch", "DEG", OPT_PITCH, "camera elevation, -80..80 (default 8)"},
    {"speed", "S", OPT_SPEED, "procedural motion speed, 0.05..8 (default 1)"},
    {"start", "SECONDS", OPT_START, "start this far into the motion, 0..100000 (default 0)"},
    {"deterministic", NULL, OPT_DETERMINISTIC,
     "render with softpipe (reproducible bytes, slower) instead of llvmpipe"},
    {"no-frames", NULL, OPT_NO_FRAMES, "write only the contact sheet"},
    {"cape", NULL, OPT_CAPE,
     "add a 32x40 cape pinned behind the shoulders, stepped by FNOpt with\n"
     "body collision through the constraint stage"},
    {"cape-method", "M", OPT_CAPE_METHOD,
     "fnopt | xpbd-fast:S: step the cape by FNOpt (default) or, on the same\n"
     "grid, pins and collision, by fast XPBD with S substeps (1..200)"},
    {"cape-model", "FILE", OPT_CAPE_MODEL,
     "its FNOpt weights (default tools/fnopt/models/fnopt_32.safetensors)"},
    {"cape-precision", "P", OPT_CAPE_PRECISION, "fp32 | fp16 | int8: its FNO arithmetic (default fp32)"},
    {"crowd", "N", OPT_CROWD,
     "crowd mode: N (1..256) avatars in a grid, garments at mixed levels of\n"
     "detail picked from the LOD table by depth; writes OUT/crowd.png (no\n"
     "frames)"},
    {"lod-table", "FILE", OPT_LOD_TABLE,
     "the measured LOD table for --crowd (default\n"
     "samples/data/lod_garment.csv, else samples/data/lod.csv; paths from\n"
     "the source root)"},
    {"crowd-mve", "CM", OPT_CROWD_MVE,
     "accuracy target of the front row (default: the best usable level's\n"
     "MVE); it grows by 100% per metre of depth"},
    {"crowd-budget", "MS", OPT_CROWD_BUDGET, "per-character ms/frame budget for the pick (default none)"},
    {NULL, NULL, 0, NULL},
};

/* Prints text with every line after the first indented by `indent` spaces. */
static void print_indented(FILE *out, const char *text, int indent)
{
    for (const char *t = text; *t;) {
        const size_t len = strcspn(t, "\n");
        fprintf(out, "%.*s\n", (int)len, t);
        t += len + (t[len] == '\n');
        if (*t) {
            fprintf(out, "%*s", indent, "");
        }
    }
}

/* The table's option lines, at column 28 as the weft CLI's help. */
static void options_help(FILE *out)
{
    enum { column = 28 };
    for (const weft_sample_option *o = weft_avatar_sample_option_table; o->name; ++o) {
        if (!o->help) {
            continue;
        }
        char head[128];
        const int w = snprintf(head, sizeof head, "  --%s%s%s", o->name, o->value ? " " : "", o->value ? o->value : "");
        if (w + 2 > column) {
            fprintf(out, "%s\n%*s", head, column, "");
        } else {
            fprintf(out, "%-*s", column, head);
        }
        print_indented(out, o->help, column);
    }
}

void weft_avatar_sample_usage(FILE *out, const char *program)
{
    fprintf(out, "usage: %s [options]\n\n"
                 "The avatar performs a motion wearing a garment, rendered off-screen: PNG frames and a\n"
                 "contact sheet in --out, per-frame timing on stdout.\n\noptions:\n",
            program);
    options_help(out);
    fprintf(out, "  %-26s%s\n", "-h, --help", "this help");
}

static bool parse_precision(const char *s, weft_precision *out)
{
    static const char *const names[WEFT_PRECISION_COUNT] = {"fp32", "fp16", "int8"};
    for (int p = 0; p < WEFT_PRECISION_COUNT; ++p) {
        if (strcmp(s, names[p]) == 0) {
            *out = (weft_precision)p;
            return true;
        }
    }
    return false;
}

static bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out);

/* --method: auto | model | lbs | skin | xpbd[:S] | xpbd-fast[:S] (S substeps, 1..1000; 0 when not
 * given: the default 10). */
static bool split_method(const char *v, char base[16], uint32_t *substeps)
{
    const char *colon = strchr(v, ':');
    const size_t n = colon ? (size_t)(colon - v) : strlen(v);
    if (n >= 16) {
        return false;
    }
    memcpy(base, v, n);
    base[n] = '\0';
    *substeps = 0;
    const bool xpbd = !strcmp(base, "xpbd") || !strcmp(base, "xpbd-fast");
    if (colon) {
        return xpbd && parse_u32(colon + 1, 1, 1000, substeps);
    }
    return xpbd || !strcmp(base, "auto") || !strcmp(base, "model") || !strcmp(base, "lbs") || !strcmp(base, "skin");
}

static bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    if (!s || *s < '0' || *s > '9') { /* strtoul alone takes " 5", "+5" and "-1" */
        return false;
    }
    char *end = NULL;
    errno = 0;
    unsigned long v = strtoul(s, &end, 10);
    if (errno || !end || *end || end == s || v < lo || v > hi) {
        return false;
    }
    *out = (uint32_t)v;
    return true;
}

static bool parse_float(const char *s, float lo, float hi, float *out)
{
    if (!s || !((*s >= '0' && *s <= '9') || *s == '-' || *s == '.')) {
        return false;
    }
    char *end = NULL;
    float v = strtof(s, &end);
    if (!end || *end || end == s || !(v >= lo && v <= hi)) {
        return false;
    }
    *out = v;
    return true;
}

bool weft_avatar_sample_apply(int id, const char *v, weft_avatar_sample_options *o)
{
    switch (id) {
    case OPT_NO_FRAMES:
        o->write_frames = false;
        return true;
    case OPT_DETERMINISTIC:
        o->deterministic = true;
        return true;
    case OPT_CAPE:
        o->cape = true;
        return true;
    default:
        break;
    }
    if (!v) {
        return false;
    }
    switch (id) {
    case OPT_CROWD:
        return weft_avatar_sample_crowd_option("--crowd", v, o);
    case OPT_LOD_TABLE:
        return weft_avatar_sample_crowd_option("--lod-table", v, o);
    case OPT_CROWD_MVE:
        return weft_avatar_sample_crowd_option("--crowd-mve", v, o);
    case OPT_CROWD_BUDGET:
        return weft_avatar_sample_crowd_option("--crowd-budget", v, o);
    case OPT_MOTION:
        o->motion = v;
        o->motion_given = true;
        return true;
    case OPT_JOINT_MAP:
        o->joint_map = v;
        return true;
    case OPT_AVATAR_JOINT_MAP:
        o->avatar_joint_map = v;
        return true;
    case OPT_AVATAR:
        o->avatar = v;
        return strncmp(v, "gltf:", 5) == 0 && v[5] != '\0';
    case OPT_GARMENT:
        o->garment = v;
        o->garment_given = true;
        return true;
    case OPT_RESOLUTION:
        o->resolution = v;
        return true;
    case OPT_SIM_RESOLUTION:
        o->sim_resolution = v;
        return true;
    case OPT_METHOD: {
        o->method = v;
        char base[16];
        uint32_t substeps = 0;
        return split_method(v, base, &substeps);
    }
    case OPT_MODEL:
        o->model_path = v;
        return true;
    case OPT_PRECISION:
        return parse_precision(v, &o->precision);
    case OPT_TETHER_CM:
        return parse_float(v, 0.0f, 1000.0f, &o->tether_cm);
    case OPT_STRAIN_LIMIT:
        return parse_float(v, 0.0f, 1000.0f, &o->strain_pct);
    case OPT_PUSH_CM:
        return parse_float(v, 0.0f, 10.0f, &o->push_cm);
    case OPT_PUSH_DEPTH_CM:
        return parse_float(v, 0.0f, 50.0f, &o->push_depth_cm);
    case OPT_COLLIDER_TOKENS: {
        uint32_t n = 0;
        if (!parse_u32(v, 0, 1000000, &n)) {
            return false;
        }
        o->collider_tokens = n;
        return true;
    }
    case OPT_EXPORT:
        o->export_dir = v;
        return true;
    case OPT_BODY_PARTS:
        if (strcmp(v, "auto") == 0) {
            o->body_parts = -1;
            return true;
        }
        if (strcmp(v, "on") != 0 && strcmp(v, "off") != 0) {
            return false;
        }
        o->body_parts = strcmp(v, "on") == 0;
        return true;
    case OPT_CCD:
        if (strcmp(v, "on") != 0 && strcmp(v, "off") != 0) {
            return false;
        }
        o->ccd = strcmp(v, "on") == 0;
        return true;
    case OPT_FRAMES:
        return parse_u32(v, 1, 100000, &o->frames);
    case OPT_SETTLE:
        return parse_u32(v, 0, 10000, &o->settle_frames);
    case OPT_OUT:
        o->out_dir = v;
        return true;
    case OPT_SIZE: {
        unsigned w = 0, h = 0;
        char tail = 0;
        if (sscanf(v, "%ux%u%c", &w, &h, &tail) != 2 || w < 16 || h < 16 || w > 4096 || h > 4096) {
            return false;
        }
        o->width = w;
        o->height = h;
        return true;
    }
    case OPT_SHEET:
        return parse_u32(v, 1, 64, &o->sheet_tiles);
    case OPT_YAW:
        return parse_float(v, -360.0f, 360.0f, &o->yaw);
    case OPT_PITCH:
        return parse_float(v, -80.0f, 80.0f, &o->pitch);
    case OPT_START:
        return parse_float(v, 0.0f, 100000.0f, &o->start);
    case OPT_SPEED:
        return parse_float(v, 0.05f, 8.0f, &o->speed);
    case OPT_CAPE_MODEL:
        o->cape_model = v;
        return true;
    case OPT_CAPE_PRECISION:
        return parse_precision(v, &o->cape_precision);
    case OPT_CAPE_METHOD:
        if (!strcmp(v, "fnopt")) {
            o->cape_xpbd_substeps = 0;
            return true;
        }
        return !strncmp(v, "xpbd-fast:", 10) && parse_u32(v + 10, 1, 200, &o->cape_xpbd_substeps);
    default:
        return false;
    }
}

/* "--name" of an option id, for messages. */
static const char *option_name(int id, char *buf, size_t cap)
{
    for (const weft_sample_option *o = weft_avatar_sample_option_table; o->name; ++o) {
        if (o->id == id) {
            snprintf(buf, cap, "--%s", o->name);
            return buf;
        }
    }
    snprintf(buf, cap, "?");
    return buf;
}

int weft_avatar_sample_parse(const char *program, int argc, char **argv, weft_avatar_sample_options *o)
{
    enum { max_options = OPT_COUNT + 1 };
    struct option table[max_options + 1];
    int n = 0;
    for (const weft_sample_option *e = weft_avatar_sample_option_table; e->name && n < max_options - 1; ++e, ++n) {
        table[n] = (struct option){e->name, e->value ? required_argument : no_argument, NULL, e->id};
    }
    table[n++] = (struct option){"help", no_argument, NULL, 'h'};
    table[n] = (struct option){NULL, 0, NULL, 0};
    /* getopt keeps its position in globals: start over (0 also resets GNU getopt's permutation). */
#ifdef __GLIBC__
    optind = 0;
#else
    optind = 1;
#endif
    opterr = 0;
    char name[96];
    for (;;) {
        const int before = optind;
        const int c = getopt_long(argc, argv, ":h", table, NULL);
        if (c == -1) {
            break;
        }
        if (c == 'h') {
            return 1;
        }
        const int at = optind - 1 >= 1 ? optind - 1 : before;
        const char *arg = at < argc ? argv[at] : "";
        if (c == ':') {
            fprintf(stderr, "%s: %s needs a value (%s --help lists the options)\n", program,
                    optopt > 0 ? option_name(optopt, name, sizeof name) : arg, program);
            return 2;
        }
        if (c == '?') {
            const bool is_long = strncmp(arg, "--", 2) == 0;
            if (optopt > 0 && is_long) {
                fprintf(stderr, "%s: %s takes no value (%s --help lists the options)\n", program,
                        option_name(optopt, name, sizeof name), program);
            } else if (optopt == 0 && is_long) {
                const size_t len = strcspn(arg + 2, "=");
                int matches = 0;
                for (int k = 0; table[k].name; ++k) {
                    matches += strncmp(table[k].name, arg + 2, len) == 0;
                }
                fprintf(stderr, "%s: %s option '%.*s' (%s --help lists the options)\n", program,
                        matches > 1 ? "ambiguous" : "unknown", (int)(len + 2), arg, program);
            } else {
                fprintf(stderr, "%s: unknown option '%s' (%s --help lists the options)\n", program, arg, program);
            }
            return 2;
        }
        if (!weft_avatar_sample_apply(c, optarg, o)) {
            fprintf(stderr, "%s: bad value '%s' for %s\n", program, optarg ? optarg : "",
                    option_name(c, name, sizeof name));
            return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "%s: unexpected argument '%s' (%s --help lists the options)\n", program, argv[optind],
                program);
        return 2;
    }
    return 0;
}

/* mkdir -p */
static bool make_dirs(const char *path)
{
    char buf[1024];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) {
        return false;
    }
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; ++i) {
        if (buf[i] == '/' || buf[i] == '\0') {
            char c = buf[i];
            buf[i] = '\0';
            if (mkdir(buf, 0755) != 0 && errno != EEXIST) {
                return false;
            }
            buf[i] = c;
        }
    }
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

#if WEFT_RENDER_HAVE_SAMPLE

/* ---------------------------------------------------------------------------------------- */

weft_result weft_sample_motion_pose(const weft_sample_motion *m, double t, weft_pose *out)
{
    return m->procedural ? weft_motion_sample(&m->def, t, out) : weft_clip_sample(m->clip, t, out);
}

void weft_sample_motion_free(weft_sample_motion *m)
{
    weft_clip_destroy(m->clip);
    m->clip = NULL;
}

typedef struct sample_state {
    weft_context *ctx;
    weft_body *body;
    weft_cloth_mesh *cloth;
    weft_cloth_mesh *sim_cloth;         /* --sim-resolution: the simulated mesh (cloth is drawn) */
    weft_mesh_map *sim_map;             /* sim_cloth -> cloth */
    const char *sim_resolution;         /* the simulated mesh's name (1k, 4k, ...) when sim_map is made */
    weft_model *model;
    weft_garment *garment;
    weft_renderer *renderer;
    weft_sample_motion motion;
    float *body_verts, *cloth_verts;
    float *skinned_verts;               /* the drawn garment skinned to the body (wear measures) */
    double *cloth_ms;                   /* per rendered frame */
    weft_wear *wear;
    weft_pc2_writer pc2_cloth, pc2_body;
    uint8_t *tiles;
    weft_sample_cape *cape;
    weft_sample_character *character;   /* --avatar gltf:PATH */
    float *obj_positions;               /* --garment obj:PATH */
    uint32_t *obj_triangles;
    uint32_t obj_vertices, obj_triangle_count;
    float *obj_weights;                 /* the OBJ garment's 24 skinning weights on weft's avatar */
    uint32_t cape_mesh;
    double cape_ms;
    uint64_t cape_pushed;       /* cape vertices its body collision moved, all steps */
    uint32_t cape_push_steps;   /* steps where it moved any */
    weft_surface_pins *band;    /* the reference XPBD's waistband (skirts, dresses), else NULL */
    float *band_targets;
} sample_state;

static void sample_free(sample_state *s)
{
    weft_sample_cape_destroy(s->cape);
    weft_sample_character_destroy(s->character);
    free(s->obj_positions);
    free(s->obj_triangles);
    free(s->obj_weights);
    weft_garment_destroy(s->garment);
    weft_surface_pins_destroy(s->band);
    free(s->band_targets);
    weft_model_destroy(s->model);
    weft_cloth_destroy(s->cloth);
    weft_mesh_map_destroy(s->sim_map);
    weft_cloth_destroy(s->sim_cloth);
    if (s->motion.clip) {
        weft_sample_motion_free(&s->motion);
    }
    weft_body_destroy(s->body);
    weft_renderer_destroy(s->renderer);
    free(s->body_verts);
    free(s->cloth_verts);
    free(s->skinned_verts);
    free(s->cloth_ms);
    weft_wear_destroy(s->wear);
    weft_pc2_close(&s->pc2_cloth);
    weft_pc2_close(&s->pc2_body);
    free(s->tiles);
    if (s->ctx) {
        weft_context_destroy(s->ctx);
    }
}

static int fail_msg(sample_state *s, const char *what)
{
    fprintf(stderr, "avatar_render: %s: %s\n", what, weft_last_error());
    sample_free(s);
    return 1;
}

const char *weft_sample_mocap_dir(void)
{
    const char *dir = getenv("WEFT_MOCAP_DIR");
#ifdef WEFT_MOCAP_DIR
    if (!dir || !dir[0]) {
        dir = WEFT_MOCAP_DIR;
    }
#endif
    return dir && dir[0] ? dir : NULL;
}

weft_result weft_sample_motion_path(const char *spec, char *out_path, size_t size)
{
    int n = -1;
    if (spec && strncmp(spec, "bvh:", 4) == 0 && spec[4]) {
        n = snprintf(out_path, size, "%s", spec + 4);
    } else if (spec && strncmp(spec, "mocap:", 6) == 0 && spec[6]) {
        const char *name = spec + 6;
        if (strchr(name, '/') || strstr(name, "..")) {
            return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion '%s': a library clip name has no '/' or '..'", spec);
        }
        const char *dir = weft_sample_mocap_dir();
        if (!dir) {
            return weft__fail(WEFT_ERROR_UNSUPPORTED, "motion '%s': set WEFT_MOCAP_DIR to the mocap library", spec);
        }
        n = snprintf(out_path, size, "%s/clips/%s.bvh.gz", dir, name);
        if (n > 0 && (size_t)n < size && access(out_path, R_OK) != 0) {
            return weft__fail(WEFT_ERROR_IO, "motion '%s': no library clip %s (clips are listed in %s/clips.csv)", spec,
                              out_path, dir);
        }
    } else {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion '%s' is neither bvh:PATH nor mocap:NAME", spec ? spec : "");
    }
    if (n <= 0 || (size_t)n >= size) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "motion '%s': path too long", spec);
    }
    return WEFT_OK;
}

weft_result weft_sample_motion_load(weft_context *ctx, const weft_body *body, const char *spec, float speed,
                                   bool verbose, weft_sample_motion *out)
{
    return weft_sample_motion_load_mapped(ctx, body, spec, NULL, speed, verbose, out);
}

weft_result weft_sample_motion_load_mapped(weft_context *ctx, const weft_body *body, const char *spec,
                                          const char *joint_map, float speed, bool verbose, weft_sample_motion *out)
{
    memset(out, 0, sizeof *out);
    if (joint_map && strncmp(spec, "bvh:", 4) != 0) {
        return weft__fail(WEFT_ERROR_INVALID_ARGUMENT, "a joint map goes with a bvh:PATH motion, not '%s'", spec);
    }
    if (strncmp(spec, "bvh:", 4) == 0 || strncmp(spec, "mocap:", 6) == 0) {
#if WEFT_RENDER_HAVE_ASSETS
        weft_bvh_def def = weft_default_bvh_def();
        def.rest_joints = weft_body_rest_joints(body);
        char path[1024];
        weft_bvh_report rep;
        def.report = &rep;
        weft_bvh_joint_map map;
        weft_result r = joint_map ? weft_bvh_read_joint_map(joint_map, &map) : WEFT_OK;
        def.joint_map = joint_map ? map.entries : NULL;
        r = r != WEFT_OK ? r : weft_sample_motion_path(spec, path, sizeof path);
        r = r != WEFT_OK ? r : weft_bvh_load_file(ctx, path, &def, &out->clip);
        if (r == WEFT_OK && verbose) {
            printf("motion %s: %s joint names, %u of 24 SMPL joints driven by the clip\n", spec, rep.naming, rep.mapped);
        }
        return r;
#else
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "this build has no weft_assets (BVH import)");
#endif
    }
    if (strncmp(spec, "gltf:", 5) == 0) {
#if WEFT_RENDER_HAVE_ASSETS
        /* a skinned glTF/FBX whose 24 joints carry SMPL names, e.g. one weft_gltf_write_body wrote */
        weft_skinned_asset *asset = NULL;
        weft_result r = weft_skinned_load_file(ctx, spec + 5, 60.0f, &asset);
        if (r == WEFT_OK) {
            r = weft_skinned_to_clip(ctx, asset, &out->clip);
            weft_skinned_asset_destroy(asset);
        }
        return r;
#else
        return weft__fail(WEFT_ERROR_UNSUPPORTED, "this build has no weft_assets (glTF import)");
#endif
    }
    weft_motion m;
    weft_result res = weft_motion_from_name(spec, &m);
    if (res != WEFT_OK) {
        return res;
    }
    out->procedural = true;
    out->def = weft_default_motion_def(m);
    out->def.speed = speed;
    return WEFT_OK;
}

/* The camera box: the bind-pose bounds (arms out, head, feet) following the pelvis over the
 * floor, so the framing is steady while the avatar moves. */
static void camera_box(const weft_body *body, const weft_pose *pose, float lo[3], float hi[3])
{
    const float *v = weft_body_rest_vertices(body);
    uint32_t n = weft_body_vertex_count(body);
    float a[3] = {INFINITY, INFINITY, INFINITY}, b[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            a[k] = fminf(a[k], v[3 * i + k]);
            b[k] = fmaxf(b[k], v[3 * i + k]);
        }
    }
    lo[0] = a[0] + pose->translation[0];
    hi[0] = b[0] + pose->translation[0];
    lo[1] = 0.0f;
    hi[1] = b[1] + fmaxf(0.0f, pose->translation[1]) + 0.1f; /* a jump's airborne frames stay in view */
    lo[2] = a[2] + pose->translation[2];
    hi[2] = b[2] + pose->translation[2];
}

/* The optional FNOpt cape (--cape): built on the bind-pose body, drawn as a second cloth mesh. */
static int cape_setup(const weft_avatar_sample_options *o, sample_state *s)
{
    if (!o->cape) {
        return 0;
    }
    weft_sample_cape_def cd = weft_sample_default_cape_def();
    cd.model_path = o->cape_model;
    cd.precision = o->cape_precision;
    cd.xpbd_substeps = o->cape_xpbd_substeps;
    weft_result r = weft_sample_cape_create(s->ctx, s->body, &cd, &s->cape);
    if (r != WEFT_OK) {
        fprintf(stderr, "avatar_render: cape with '%s': %s: %s\n", o->cape_model, weft_result_string(r),
                weft_last_error());
        return 1;
    }
    uint32_t tc = 0;
    const uint32_t *tris = weft_sample_cape_triangles(s->cape, &tc);
    if (weft_renderer_add_mesh(s->renderer, weft_sample_cape_positions(s->cape), weft_sample_cape_vertex_count(s->cape),
                               tris, tc, WEFT_RENDER_CLOTH, &s->cape_mesh) != WEFT_OK) {
        fprintf(stderr, "avatar_render: adding the cape mesh: %s\n", weft_last_error());
        return 1;
    }
    const float lc = weft_sample_cape_units_per_metre(s->cape);
    if (cd.xpbd_substeps) {
        printf("cape: %ux%u grid (%.2f x %.2f m) by fast XPBD, %u substeps; body collision 1 cm\n", cd.across,
               cd.down, (double)((cd.across - 1) / lc), (double)((cd.down - 1) / lc), cd.xpbd_substeps);
        return 0;
    }
    printf("cape: %ux%u FNOpt grid (%.2f x %.2f m), %s FNO, one step per frame; body collision through the "
           "constraint stage (1 cm push)\n", cd.across, cd.down,
           (double)((cd.across - 1) / lc), (double)((cd.down - 1) / lc),
           o->cape_precision == WEFT_PRECISION_FP16 ? "fp16" : (o->cape_precision == WEFT_PRECISION_INT8 ? "int8" : "fp32"));
    return 0;
}

/* One cape step with the pins at `pose`; a non-finite step keeps the previous state. */
static int cape_frame(sample_state *s, const weft_pose *pose, uint32_t k)
{
    if (!s->cape) {
        return 0;
    }
    double t0 = weft__now_ms();
    weft_result r = weft_sample_cape_step(s->cape, s->body, pose, s->body_verts);
    s->cape_ms += weft__now_ms() - t0;
    s->cape_pushed += weft_sample_cape_pushed(s->cape);
    s->cape_push_steps += weft_sample_cape_pushed(s->cape) > 0;
    if (r == WEFT_ERROR_NOT_FINITE) {
        printf("cape: step %u was not finite; the cape kept its previous state\n", k);
    } else if (r != WEFT_OK) {
        fprintf(stderr, "avatar_render: cape step %u: %s\n", k, weft_last_error());
        return 1;
    }
    return 0;
}

/* The shipped garment model for a precision (run from the repository root): the garment
 * specialist, whose decayed skinned prior keeps the cloth on its wearer without tethers
 * (docs/MODEL.md, *The decayed skinned prior*). */
static const char *shipped_model(weft_precision precision)
{
    static const char *const shipped[] = {"tools/train/models/garment.safetensors",
                                          "tools/train/models/garment.fp16.safetensors",
                                          "tools/train/models/garment.int8.safetensors"};
    return shipped[precision < WEFT_PRECISION_COUNT ? precision : WEFT_PRECISION_FP32];
}

weft_garment_def weft_sample_body_garment_def(const weft_body *body, weft_method method, const float *positions,
                                              uint32_t vertex_count, const uint32_t *triangles, uint32_t triangle_count)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.rest_positions = positions;
    d.vertex_count = vertex_count;
    d.triangles = triangles;
    d.triangle_count = triangle_count;
    d.collider_rest_positions = weft_body_rest_vertices(body);
    d.collider_vertex_count = weft_body_vertex_count(body);
    d.collider_triangles = weft_body_triangles(body);
    d.collider_triangle_count = weft_body_triangle_count(body);
    return d;
}

bool weft_sample_parts_on(int mode, bool ccd)
{
    return mode >= 0 ? mode != 0 : ccd;
}

float weft_sample_worn_tether_cm(weft_cloth_kind kind)
{
    return kind == WEFT_CLOTH_SKIRT ? WEFT_WORN_TETHER_SKIRT_CM
                                    : (kind == WEFT_CLOTH_DRESS ? WEFT_WORN_TETHER_DRESS_CM : WEFT_WORN_TETHER_CM);
}

/* The worn-garment recipe on any collider (weft_sample_worn_def's fields); kind WEFT_CLOTH_COUNT:
 * a garment of the user's (an OBJ). */
static weft_garment_def worn_def_on(const weft_sample_collider *col, weft_cloth_kind kind, const float *positions,
                                    uint32_t vertex_count, const uint32_t *triangles, uint32_t triangle_count,
                                    weft_method method)
{
    weft_garment_def d = weft_default_garment_def();
    d.method = method;
    d.rest_positions = positions;
    d.vertex_count = vertex_count;
    d.triangles = triangles;
    d.triangle_count = triangle_count;
    d.collider_rest_positions = col->rest_positions;
    d.collider_vertex_count = col->vertex_count;
    d.collider_triangles = col->triangles;
    d.collider_triangle_count = col->triangle_count;
    d.collision.triangle_parts = weft_sample_parts_on(-1, false) ? col->triangle_parts : NULL;
    weft_sample_worn_recipe(&d, kind, method);
    weft_sample_set_substeps(&d, 0);
    return d;
}

void weft_sample_worn_recipe(weft_garment_def *d, weft_cloth_kind kind, weft_method method)
{
    d->collision.ground = true; /* the floor the sample draws, y = 0 */
    d->collision.ground_height = 0.0f;
    d->ccd.enabled = false;
    d->tethers.distance = weft_sample_worn_tether_cm(kind) / 100.0f;
    d->collision.push = WEFT_WORN_PUSH_CM / 100.0f;
    d->collision.push_depth = WEFT_WORN_PUSH_DEPTH_CM / 100.0f;
    d->strain.limit = method == WEFT_METHOD_MODEL ? WEFT_WORN_STRAIN_PCT / 100.0f : 0.0f;
    if (method == WEFT_METHOD_MODEL) {
        d->max_collider_tokens = WEFT_WORN_COLLIDER_TOKENS;
        d->collider_cap = WEFT_COLLIDER_CAP_SAMPLE;
    }
    if (method == WEFT_METHOD_XPBD) {
        /* The reference runs as weft simgen runs it on real motion (docs/REFSIM.md, Real motion):
         * its cloth-cloth bounds, the collider projected and the max distance held each substep, no
         * push after the step (it would move cloth past the bounds). */
        d->collider_projection = true;
        d->collision.push = 0.0f;
    }
}

weft_result weft_sample_waistband_create(weft_context *ctx, const weft_body *body, const weft_cloth_mesh *cloth,
                                         weft_surface_pins **out)
{
    *out = NULL;
    if (cloth->kind != WEFT_CLOTH_SKIRT && cloth->kind != WEFT_CLOTH_DRESS) {
        return WEFT_OK;
    }
    const uint32_t n = weft_mesh_top_ring(cloth->positions, cloth->vertex_count, 0.012f, NULL, 0);
    uint32_t *idx = malloc((n ? n : 1) * sizeof *idx);
    float *rest = malloc((n ? n : 1) * 3 * sizeof *rest);
    weft_result r = idx && rest ? WEFT_OK : weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "waistband: out of memory");
    if (r == WEFT_OK) {
        weft_mesh_top_ring(cloth->positions, cloth->vertex_count, 0.012f, idx, n);
        for (uint32_t k = 0; k < n; ++k) {
            memcpy(rest + 3 * (size_t)k, cloth->positions + 3 * (size_t)idx[k], 3 * sizeof(float));
        }
        weft_surface_pins_def d = weft_default_surface_pins_def();
        d.collider_rest_positions = weft_body_rest_vertices(body);
        d.collider_vertex_count = weft_body_vertex_count(body);
        d.collider_triangles = weft_body_triangles(body);
        d.collider_triangle_count = weft_body_triangle_count(body);
        d.rest_points = rest;
        d.vertex_indices = idx;
        d.count = n;
        r = weft_surface_pins_create(ctx, &d, out);
    }
    free(idx);
    free(rest);
    return r;
}

weft_result weft_sample_waistband_pin(const weft_surface_pins *band, weft_garment *garment, const float *collider_next,
                                      float *scratch)
{
    if (!band) {
        return WEFT_OK;
    }
    weft_result r = weft_surface_pins_targets(band, collider_next, scratch);
    return r != WEFT_OK ? r
                        : weft_garment_set_pins(garment, weft_surface_pins_indices(band), scratch,
                                                weft_surface_pins_count(band));
}

void weft_sample_set_substeps(weft_garment_def *def, uint32_t substeps)
{
    def->substeps = substeps ? substeps : def->substeps;
    def->substeps_max = def->method == WEFT_METHOD_XPBD ? WEFT_REFERENCE_SUBSTEP_FACTOR * def->substeps : 0;
}

weft_result weft_sample_worn_def(const weft_body *body, const weft_cloth_mesh *cloth, weft_method method, uint8_t *parts,
                                 weft_garment_def *out)
{
    if (parts) {
        weft_result r = weft_body_triangle_parts(body, parts, weft_body_triangle_count(body));
        if (r != WEFT_OK) {
            return r;
        }
    }
    const weft_sample_collider col = {weft_body_rest_vertices(body), weft_body_vertex_count(body),
                                      weft_body_triangles(body), weft_body_triangle_count(body), parts};
    *out = worn_def_on(&col, cloth->kind, cloth->positions, cloth->vertex_count, cloth->triangles,
                       cloth->triangle_count, method);
    return WEFT_OK;
}

weft_result weft_avatar_sample_garment_create(const weft_avatar_sample_options *o, weft_context *ctx,
                                              const weft_body *body, const weft_cloth_mesh *cloth,
                                              weft_model **out_model, weft_garment **out_garment, char *label,
                                              size_t label_cap)
{
    uint8_t *parts = o->body_parts != 0 ? malloc(weft_body_triangle_count(body)) : NULL;
    if (o->body_parts != 0 && !parts) {
        *out_model = NULL;
        *out_garment = NULL;
        return WEFT_ERROR_OUT_OF_MEMORY;
    }
    weft_result r = parts ? weft_body_triangle_parts(body, parts, weft_body_triangle_count(body)) : WEFT_OK;
    const weft_sample_collider col = {weft_body_rest_vertices(body), weft_body_vertex_count(body),
                                      weft_body_triangles(body), weft_body_triangle_count(body), parts};
    if (r == WEFT_OK) {
        r = weft_avatar_sample_garment_create_on(o, ctx, &col, cloth->kind, cloth->positions, cloth->vertex_count,
                                                 cloth->triangles, cloth->triangle_count, out_model, out_garment,
                                                 label, label_cap);
    } else {
        *out_model = NULL;
        *out_garment = NULL;
    }
    free(parts); /* the garment copied them */
    return r;
}

weft_result weft_avatar_sample_garment_create_on(const weft_avatar_sample_options *o, weft_context *ctx,
                                                 const weft_sample_collider *collider, weft_cloth_kind kind,
                                                 const float *positions,
                                                 uint32_t vertex_count, const uint32_t *triangles,
                                                 uint32_t triangle_count, weft_model **out_model,
                                                 weft_garment **out_garment, char *label, size_t label_cap)
{
    *out_model = NULL;
    *out_garment = NULL;
    snprintf(label, label_cap, "skin");
    if (strcmp(o->method, "skin") == 0) {
        return WEFT_OK;
    }
    /* The shipped garment model unless --model names another; a missing default file (the sample
     * run away from the repository) falls back to XPBD with a note, a named file must load. */
    const char *model_path = o->model_path ? o->model_path : shipped_model(o->precision);
    bool want_auto = strcmp(o->method, "auto") == 0;
    if (want_auto || strcmp(o->method, "model") == 0) {
        weft_result r = weft_model_load_file_as(ctx, model_path, "clothtransformer", out_model);
        if (r != WEFT_OK && (o->model_path || !want_auto)) {
            fprintf(stderr, "avatar_render: loading the model %s: %s: %s\n", model_path, weft_result_string(r),
                    weft_last_error());
            return r;
        }
        if (r != WEFT_OK) {
            printf("NOTE: the shipped model %s did not load (%s); run from the repository root for the learned "
                   "model. Trying XPBD.\n",
                   model_path, weft_last_error());
        }
    }
    /* The best method first; each failure is reported, never hidden. */
    static const struct {
        const char *name;
        weft_method method;
    } order[] = {{"model", WEFT_METHOD_MODEL},
                 {"xpbd", WEFT_METHOD_XPBD},
                 {"xpbd-fast", WEFT_METHOD_XPBD_FAST},
                 {"lbs", WEFT_METHOD_LBS}};
    char base[16];
    uint32_t substeps = 0;
    if (!split_method(o->method, base, &substeps)) {
        fprintf(stderr, "avatar_render: unknown method '%s'\n", o->method);
        return WEFT_ERROR_INVALID_ARGUMENT;
    }
    for (size_t m = 0; m < sizeof order / sizeof order[0] && !*out_garment; ++m) {
        if (want_auto ? (order[m].method == WEFT_METHOD_MODEL && !*out_model) : strcmp(base, order[m].name) != 0) {
            continue;
        }
        weft_garment_def gdef =
            worn_def_on(collider, kind, positions, vertex_count, triangles, triangle_count, order[m].method);
        gdef.model = *out_model;
        gdef.precision = o->precision;
        if (*out_model && order[m].method == WEFT_METHOD_MODEL) {
            /* the strain limit the model file was deployed with (metadata "deploy"), else the recipe's */
            const float deployed = weft_model_garment_def(*out_model).strain.limit;
            gdef.strain.limit = deployed != weft_default_garment_def().strain.limit ? deployed : gdef.strain.limit;
        }
        weft_sample_set_substeps(&gdef, substeps);
        /* The options override the worn-garment recipe: --tether-cm (8; skirts 16, dresses 12;
         * 0 turns it off),
         * --strain-limit (10 % for the learned model), --push-cm (0.5), --ccd; the reference
         * XPBD's recipe has none of the three. */
        float tether_cm = o->tether_cm >= 0.0f ? o->tether_cm : gdef.tethers.distance * 100.0f;
        gdef.tethers.distance = tether_cm / 100.0f;
        float strain_pct = o->strain_pct >= 0.0f ? o->strain_pct : gdef.strain.limit * 100.0f;
        gdef.strain.limit = strain_pct / 100.0f;
        const float push_cm = o->push_cm >= 0.0f ? o->push_cm : gdef.collision.push * 100.0f;
        gdef.collision.push = push_cm / 100.0f;
        if (o->push_depth_cm >= 0.0f) {
            gdef.collision.push_depth = o->push_depth_cm / 100.0f;
        }
        if (o->collider_tokens >= 0) {
            gdef.max_collider_tokens = (uint32_t)o->collider_tokens;
        }
        gdef.ccd.enabled = o->ccd;
        gdef.collision.triangle_parts =
            weft_sample_parts_on(o->body_parts, o->ccd) ? collider->triangle_parts : NULL;
        weft_result r = weft_garment_create(ctx, &gdef, out_garment);
        if (r != WEFT_OK) {
            fprintf(stderr, "avatar_render: method %s unavailable: %s\n", order[m].name, weft_last_error());
            continue;
        }
        static const char *const prec[] = {"fp32", "fp16", "int8"};
        if (order[m].method == WEFT_METHOD_MODEL) {
            snprintf(label, label_cap, "model %s", prec[o->precision]);
        } else if (substeps) {
            snprintf(label, label_cap, "%s:%u", order[m].name, substeps);
        } else {
            snprintf(label, label_cap, "%s", order[m].name);
        }
        if (tether_cm > 0.0f) {
            printf("tethers: every garment vertex within %.1f cm of its skinned position\n", (double)tether_cm);
            if (order[m].method == WEFT_METHOD_XPBD) {
                printf("NOTE: the clamp after the reference XPBD's step moves cloth past the bounds that keep it out of\n"
                       "the body; where the skinned garment lies inside the body or across a limb (real motion), the\n"
                       "cloth is pulled in and stays (docs/STABILITY_MOCAP.md, The reference XPBD on real motion)\n");
            }
        }
        if (push_cm > 0.0f) {
            printf("collider push: garment cloth inside the body goes %.1f cm in front of it before CCD\n",
                   (double)push_cm);
        }
        if (strain_pct > 0.0f) {
            printf("strain limit: garment edges at most %.0f %% over their rest length before CCD\n", (double)strain_pct);
        }
    }
    if (!*out_garment && !want_auto) {
        fprintf(stderr, "avatar_render: the requested method '%s' could not be created\n", o->method);
        weft_model_destroy(*out_model);
        *out_model = NULL;
        return WEFT_ERROR_UNSUPPORTED;
    }
    return WEFT_OK;
}

void weft_avatar_sample_settle_pose(const weft_pose *bind, const weft_pose *first, uint32_t k, uint32_t settle,
                                    weft_pose *out)
{
    double u = (double)(k + 1) / (double)settle;
    if (weft_pose_blend(bind, first, u * u * (3.0 - 2.0 * u), out) != WEFT_OK) {
        *out = *first; /* a non-finite pose: the clip's own frame, which the step then refuses */
    }
}

/* An OBJ garment on weft's avatar: each vertex takes the skinning weights of the nearest body
 * vertex (24 per vertex, as weft_body_skin_points reads them). Refuses a garment whose median
 * distance to the avatar is over 10 cm (not fitted to it). */
static weft_result bind_obj_to_avatar(const weft_body *body, const float *garment, uint32_t n, float **out_weights)
{
    const uint32_t nb = weft_body_vertex_count(body);
    const float *rest = weft_body_rest_vertices(body), *bw = weft_body_weights(body);
    float *w = malloc((size_t)n * WEFT_BODY_JOINTS * sizeof(float));
    uint32_t far = 0;
    if (!w) {
        return weft__fail(WEFT_ERROR_OUT_OF_MEMORY, "garment: out of memory");
    }
    for (uint32_t i = 0; i < n; ++i) {
        const float *p = garment + 3 * (size_t)i;
        double best = INFINITY;
        const uint32_t nearest = weft_sample_nearest_point(rest, nb, p, &best);
        far += best > 0.01; /* 10 cm */
        memcpy(w + (size_t)i * WEFT_BODY_JOINTS, bw + (size_t)nearest * WEFT_BODY_JOINTS, WEFT_BODY_JOINTS * sizeof(float));
    }
    if (far > n / 2) {
        free(w);
        return weft__fail(WEFT_ERROR_FORMAT, "garment: %u of its %u vertices are over 10 cm from the avatar: it is not "
                          "fitted to the avatar's bind pose", far, n);
    }
    *out_weights = w;
    return WEFT_OK;
}

/* The drawn garment carried by the skin: the wardrobe garment's weights, the OBJ's nearest-vertex
 * weights on weft's avatar, or the character's binding. */
static weft_result skin_garment(const sample_state *s, const weft_pose *pose, const float *rest, uint32_t n, float *out)
{
    if (s->character) {
        return weft_sample_character_skin_garment(s->character, out);
    }
    return weft_body_skin_points(s->body, pose, rest, s->obj_weights ? s->obj_weights : s->cloth->weights, n, out);
}

/* The camera box for a character: its bind-pose bounds moved with the centroid over the floor. */
static void camera_box_points(const float *rest, const float *posed, uint32_t n, float lo[3], float hi[3])
{
    double a[3] = {INFINITY, INFINITY, INFINITY}, b[3] = {-INFINITY, -INFINITY, -INFINITY}, shift[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            a[k] = fmin(a[k], rest[3 * (size_t)i + (size_t)k]);
            b[k] = fmax(b[k], rest[3 * (size_t)i + (size_t)k]);
            shift[k] += (double)posed[3 * (size_t)i + (size_t)k] - rest[3 * (size_t)i + (size_t)k];
        }
    }
    lo[0] = (float)(a[0] + shift[0] / n), hi[0] = (float)(b[0] + shift[0] / n);
    lo[1] = 0.0f, hi[1] = (float)(b[1] + fmax(0.0, shift[1] / n)) + 0.1f; /* airborne frames stay in view */
    lo[2] = (float)(a[2] + shift[2] / n), hi[2] = (float)(b[2] + shift[2] / n);
}

int weft_avatar_sample_run(const weft_avatar_sample_options *o)
{
    if (o->crowd > 0) {
        return weft_avatar_sample_crowd(o); /* crowd.c */
    }
    sample_state s;
    memset(&s, 0, sizeof s);
    weft_context_def cdef = weft_default_context_def();
    if (weft_context_create(&cdef, &s.ctx) != WEFT_OK) {
        return fail_msg(&s, "weft_context_create");
    }
    weft_avatar_def adef = weft_default_avatar_def();
    if (weft_avatar_create(s.ctx, &adef, &s.body) != WEFT_OK) {
        return fail_msg(&s, "weft_avatar_create");
    }
    if (o->avatar_joint_map && !(o->avatar && o->motion_given)) {
        fprintf(stderr, "avatar_render: --avatar-joint-map goes with --avatar and a mocap:/bvh: --motion\n");
        sample_free(&s);
        return 2;
    }
    if (o->avatar) {
        const bool clip_motion =
            o->motion_given && (strncmp(o->motion, "mocap:", 6) == 0 || strncmp(o->motion, "bvh:", 4) == 0);
        if ((o->motion_given && !(clip_motion && o->avatar_joint_map)) || o->cape || o->sim_resolution || o->crowd) {
            fprintf(stderr, "avatar_render: with --avatar the character plays its own animation, or a mocap:/bvh: "
                            "--motion with --avatar-joint-map; no --cape, --sim-resolution or --crowd\n");
            sample_free(&s);
            return 2;
        }
        if (weft_sample_character_load(s.ctx, o->avatar + 5, &s.character) != WEFT_OK) {
            fprintf(stderr, "avatar_render: --avatar %s: %s\n", o->avatar, weft_last_error());
            sample_free(&s);
            return 2;
        }
        if (clip_motion) {
            /* the clip retargeted onto weft's avatar (SMPL), then onto the character's skeleton */
            weft_bvh_joint_map map;
            weft_result r = weft_bvh_read_joint_map(o->avatar_joint_map, &map);
            r = r != WEFT_OK ? r
                             : weft_sample_motion_load_mapped(s.ctx, s.body, o->motion, o->joint_map, o->speed, true,
                                                              &s.motion);
            r = r != WEFT_OK ? r : weft_sample_character_set_clip(s.character, s.body, s.motion.clip, map.entries);
            if (r == WEFT_OK) {
                printf("motion %s retargeted onto the character through %s: %u frames (%.2f s)\n", o->motion,
                       o->avatar_joint_map, weft_sample_character_frame_count(s.character),
                       weft_sample_character_duration(s.character));
            }
            if (r != WEFT_OK) {
                fprintf(stderr, "avatar_render: --motion %s on --avatar %s: %s\n", o->motion, o->avatar,
                        weft_last_error());
                sample_free(&s);
                return 2;
            }
        }
        uint32_t parts = 0;
        weft_sample_character_parts(s.character, &parts);
        printf("character %s: %u vertices, %u joints, %u body parts, %u frames of animation (%.2f s)\n", o->avatar + 5,
               weft_sample_character_vertex_count(s.character), weft_sample_character_joint_count(s.character), parts,
               weft_sample_character_frame_count(s.character), weft_sample_character_duration(s.character));
    } else if (weft_sample_motion_load_mapped(s.ctx, s.body, o->motion, o->joint_map, o->speed, true, &s.motion) !=
               WEFT_OK) {
        fprintf(stderr, "avatar_render: motion '%s': %s\n", o->motion, weft_last_error());
        sample_free(&s);
        return 2;
    }
    /* the collider: weft's avatar, or the user's character */
    const uint32_t nv = s.character ? weft_sample_character_vertex_count(s.character) : weft_body_vertex_count(s.body);
    const float *body_rest = s.character ? weft_sample_character_bind_vertices(s.character) : weft_body_rest_vertices(s.body);
    const uint32_t *body_tris = s.character ? weft_sample_character_triangles(s.character) : weft_body_triangles(s.body);
    const uint32_t body_ntri =
        s.character ? weft_sample_character_triangle_count(s.character) : weft_body_triangle_count(s.body);
    s.body_verts = malloc((size_t)nv * 3 * sizeof(float));
    if (!s.body_verts) {
        return fail_msg(&s, "out of memory");
    }

    /* a character wears nothing unless given an OBJ: weft's garments fit weft's avatar */
    bool dressed = strcmp(o->garment, "none") != 0 && (!s.character || o->garment_given);
    const bool obj_garment = strncmp(o->garment, "obj:", 4) == 0;
    const char *method_used = "none";
    char method_label[32];
    bool simulated = false;
    /* the drawn garment mesh: a wardrobe garment, or the user's OBJ */
    const float *gm_rest = NULL;
    const uint32_t *gm_tris = NULL;
    uint32_t gm_nv = 0, gm_nt = 0;
    if (s.character && dressed && !obj_garment) {
        fprintf(stderr, "avatar_render: weft's garments are fitted to weft's avatar; dress your character with "
                        "--garment obj:PATH (a garment fitted to its bind pose) or none\n");
        sample_free(&s);
        return 2;
    }
    if (obj_garment) {
        if (o->sim_resolution) {
            fprintf(stderr, "avatar_render: --sim-resolution needs one of weft's garments, not an OBJ\n");
            sample_free(&s);
            return 2;
        }
        weft_result r = weft_obj_read(o->garment + 4, &s.obj_positions, &s.obj_vertices, &s.obj_triangles,
                                      &s.obj_triangle_count);
        if (r == WEFT_OK && s.character) {
            r = weft_sample_character_bind(s.character, s.obj_positions, s.obj_vertices);
        } else if (r == WEFT_OK) {
            r = bind_obj_to_avatar(s.body, s.obj_positions, s.obj_vertices, &s.obj_weights);
        }
        if (r != WEFT_OK) {
            fprintf(stderr, "avatar_render: --garment %s: %s\n", o->garment, weft_last_error());
            sample_free(&s);
            return 2;
        }
        gm_rest = s.obj_positions, gm_tris = s.obj_triangles, gm_nv = s.obj_vertices, gm_nt = s.obj_triangle_count;
        s.cloth_verts = malloc((size_t)gm_nv * 3 * sizeof(float));
        if (!s.cloth_verts) {
            return fail_msg(&s, "out of memory");
        }
        const weft_sample_collider col = {body_rest, nv, body_tris, body_ntri, NULL};
        weft_sample_collider with_parts = col;
        uint8_t *avatar_parts = NULL;
        if (s.character) {
            with_parts.triangle_parts = weft_sample_character_parts(s.character, NULL);
        } else if ((avatar_parts = malloc(body_ntri)) == NULL ||
                   weft_body_triangle_parts(s.body, avatar_parts, body_ntri) != WEFT_OK) {
            free(avatar_parts);
            return fail_msg(&s, "body parts");
        } else {
            with_parts.triangle_parts = avatar_parts;
        }
        weft_result gr = weft_avatar_sample_garment_create_on(o, s.ctx, &with_parts, WEFT_CLOTH_COUNT, gm_rest, gm_nv,
                                                              gm_tris, gm_nt, &s.model, &s.garment, method_label,
                                                              sizeof method_label);
        free(avatar_parts);
        if (gr != WEFT_OK) {
            sample_free(&s);
            return 1;
        }
        simulated = s.garment != NULL;
        method_used = simulated ? method_label : "skin";
    } else if (dressed) {
        weft_cloth_kind kind;
        weft_cloth_resolution res;
        if (weft_cloth_kind_from_name(o->garment, &kind) != WEFT_OK || kind >= WEFT_CLOTH_SHEET) {
            fprintf(stderr, "avatar_render: --garment must be tshirt, skirt, dress or none\n");
            sample_free(&s);
            return 2;
        }
        if (weft_cloth_resolution_from_name(o->resolution, &res) != WEFT_OK) {
            fprintf(stderr, "avatar_render: --resolution must be 1k, 4k, 16k or 40k\n");
            sample_free(&s);
            return 2;
        }
        weft_cloth_def cdef2 = weft_default_cloth_def(kind);
        cdef2.resolution = res;
        if (weft_cloth_create(s.ctx, &cdef2, s.body, &s.cloth) != WEFT_OK) {
            return fail_msg(&s, "weft_cloth_create");
        }
        s.cloth_verts = malloc((size_t)s.cloth->vertex_count * 3 * sizeof(float));
        if (!s.cloth_verts) {
            return fail_msg(&s, "out of memory");
        }
        const weft_cloth_mesh *simulated_mesh = s.cloth;
        /* The learned model (auto, model) simulates the 1k mesh and draws a finer one through the
         * mesh map unless --sim-resolution names the mesh: the model learned at 1k, and 1k carried
         * to 4k costs about half the 4k step at an error no worse (docs/RESOLUTION.md). */
        const bool learned = strcmp(o->method, "auto") == 0 || strcmp(o->method, "model") == 0;
        const char *sim_resolution =
            o->sim_resolution ? o->sim_resolution : (learned && res != WEFT_CLOTH_RES_1K ? "1k" : NULL);
        if (sim_resolution && strcmp(sim_resolution, o->resolution) != 0) {
            weft_cloth_resolution sres;
            if (weft_cloth_resolution_from_name(sim_resolution, &sres) != WEFT_OK) {
                fprintf(stderr, "avatar_render: --sim-resolution must be 1k, 4k, 16k or 40k\n");
                sample_free(&s);
                return 2;
            }
            weft_cloth_def sdef = weft_default_cloth_def(kind);
            sdef.resolution = sres;
            if (weft_cloth_create(s.ctx, &sdef, s.body, &s.sim_cloth) != WEFT_OK) {
                return fail_msg(&s, "weft_cloth_create (--sim-resolution)");
            }
            /* Both meshes are the same garment on the bind pose: the drawn one follows the simulated. */
            weft_mesh_map_def md = weft_default_mesh_map_def();
            md.from_rest_positions = s.sim_cloth->positions;
            md.from_vertex_count = s.sim_cloth->vertex_count;
            md.from_triangles = s.sim_cloth->triangles;
            md.from_triangle_count = s.sim_cloth->triangle_count;
            md.to_rest_positions = s.cloth->positions;
            md.to_vertex_count = s.cloth->vertex_count;
            s.sim_resolution = sim_resolution;
            if (weft_mesh_map_create(s.ctx, &md, &s.sim_map) != WEFT_OK) {
                return fail_msg(&s, "weft_mesh_map_create");
            }
            simulated_mesh = s.sim_cloth;
        }
        weft_result gr = weft_avatar_sample_garment_create(o, s.ctx, s.body, simulated_mesh, &s.model, &s.garment,
                                                           method_label, sizeof method_label);
        if (gr != WEFT_OK) {
            sample_free(&s);
            return 1;
        }
        if (s.garment) {
            method_used = method_label;
            simulated = true;
        }
        /* the reference XPBD ("xpbd", "xpbd:S") runs without the max distance: its waistband */
        if (s.garment && strncmp(method_label, "xpbd", 4) == 0 && strncmp(method_label, "xpbd-fast", 9) != 0) {
            if (weft_sample_waistband_create(s.ctx, s.body, simulated_mesh, &s.band) != WEFT_OK ||
                !(s.band_targets = malloc(((size_t)weft_surface_pins_count(s.band) + 1) * 3 * sizeof(float)))) {
                return fail_msg(&s, "the waistband");
            }
        }
        if (!simulated) {
            method_used = "skin";
        }
        gm_rest = s.cloth->positions, gm_tris = s.cloth->triangles;
        gm_nv = s.cloth->vertex_count, gm_nt = s.cloth->triangle_count;
    }
    if (dressed && !simulated) {
        printf("NOTE: the garment is skinned rigidly with the body (linear blend skinning of its rest mesh); "
               "no cloth is simulated in this run.\n");
    }

    weft_render_def rdef = weft_default_render_def();
    rdef.width = o->width;
    rdef.height = o->height;
    rdef.deterministic = o->deterministic;
    if (weft_renderer_create(&rdef, &s.renderer) != WEFT_OK) {
        return fail_msg(&s, "weft_renderer_create");
    }
    uint32_t body_mesh = 0, cloth_mesh = 0;
    if (weft_renderer_add_mesh(s.renderer, body_rest, nv, body_tris, body_ntri, WEFT_RENDER_SKIN, &body_mesh) != WEFT_OK) {
        return fail_msg(&s, "adding the body mesh");
    }
    if (dressed && weft_renderer_add_mesh(s.renderer, gm_rest, gm_nv, gm_tris, gm_nt, WEFT_RENDER_CLOTH, &cloth_mesh) !=
                       WEFT_OK) {
        return fail_msg(&s, "adding the garment mesh");
    }
    weft_renderer_set_ground(s.renderer, true, 0.0f);
    if (cape_setup(o, &s) != 0) {
        sample_free(&s);
        return 1;
    }
    if (!make_dirs(o->out_dir)) {
        fprintf(stderr, "avatar_render: cannot create the output folder '%s': %s\n", o->out_dir, strerror(errno));
        sample_free(&s);
        return 1;
    }
    s.cloth_ms = calloc(o->frames, sizeof(double));
    if (!s.cloth_ms) {
        return fail_msg(&s, "out of memory for the frame times");
    }
    if (dressed && simulated) {
        s.skinned_verts = malloc((size_t)gm_nv * 3 * sizeof(float));
        if (!s.skinned_verts || weft_wear_create(body_tris, body_ntri, nv, gm_nv, &s.wear) != WEFT_OK) {
            return fail_msg(&s, "setting up the wear measures");
        }
    }
    if (o->export_dir) {
        char p[1200];
        if (!make_dirs(o->export_dir)) {
            fprintf(stderr, "avatar_render: cannot create the export folder '%s'\n", o->export_dir);
            sample_free(&s);
            return 1;
        }
        snprintf(p, sizeof p, "%s/body.obj", o->export_dir);
        weft_result er = weft_obj_write(p, body_rest, nv, body_tris, body_ntri);
        snprintf(p, sizeof p, "%s/body.pc2", o->export_dir);
        er = er != WEFT_OK ? er : weft_pc2_open(&s.pc2_body, p, nv, 0.0f);
        if (er == WEFT_OK && dressed) {
            snprintf(p, sizeof p, "%s/garment.obj", o->export_dir);
            er = weft_obj_write(p, gm_rest, gm_nv, gm_tris, gm_nt);
            snprintf(p, sizeof p, "%s/garment.pc2", o->export_dir);
            er = er != WEFT_OK ? er : weft_pc2_open(&s.pc2_cloth, p, gm_nv, 0.0f);
        }
        if (er != WEFT_OK) {
            return fail_msg(&s, "export");
        }
    }
    /* skirts and dresses swing farther from the skinned garment than a T-shirt's cloth does */
    const float off_distance = o->garment && (!strcmp(o->garment, "skirt") || !strcmp(o->garment, "dress")) ? 0.25f : 0.10f;
    weft_wear_summary wear = {0};
    uint32_t tiles = o->sheet_tiles < o->frames ? o->sheet_tiles : o->frames;
    size_t image_bytes = (size_t)o->width * o->height * 4;
    s.tiles = malloc(image_bytes * tiles);
    if (!s.tiles) {
        return fail_msg(&s, "out of memory for the contact sheet");
    }

    const char *motion_name = s.character && !s.motion.clip ? "its own animation" : o->motion;
    printf("avatar %u vertices; garment %s (%u vertices); motion %s; cloth method %s; %u frames at 60 Hz, %ux%u\n", nv,
           dressed ? o->garment : "none", gm_nv, motion_name, method_used, o->frames, o->width, o->height);
    if (s.sim_map && simulated) {
        printf("simulated at %s (%u vertices), drawn at %s through a mesh map\n", s.sim_resolution,
               s.sim_cloth->vertex_count, o->resolution);
    }
    weft_pose bind, first, pose;
    weft_body_bind_pose(s.body, &bind);
    pose = bind;
    if (!s.character && weft_sample_motion_pose(&s.motion, o->start, &first) != WEFT_OK) {
        return fail_msg(&s, "sampling the motion");
    }
    uint32_t settle = simulated || o->cape ? o->settle_frames : 0;
    double sums[4] = {0, 0, 0, 0};
    double push_searched = 0.0, push_moved = 0.0; /* sums over the simulated frames (stats) */
    uint32_t push_frames = 0;
    char path[1200];
    uint32_t tile_next = 0;
    char labels[64][48];
    for (uint32_t k = 0; k < settle + o->frames; ++k) {
        double t0 = weft__now_ms();
        if (s.character) {
            /* the character's own animation, blended from its bind pose while settling */
            const double u = k < settle ? (double)(k + 1) / (double)settle : 1.0;
            const double t = o->start + (k < settle ? 0.0 : (double)(k - settle) / 60.0);
            if (weft_sample_character_pose(s.character, t, u * u * (3.0 - 2.0 * u), s.body_verts) != WEFT_OK) {
                return fail_msg(&s, "posing the character");
            }
        } else {
            if (k < settle) {
                weft_avatar_sample_settle_pose(&bind, &first, k, settle, &pose);
            } else if (weft_sample_motion_pose(&s.motion, o->start + (double)(k - settle) / 60.0, &pose) != WEFT_OK) {
                return fail_msg(&s, "sampling the motion");
            }
            if (weft_body_pose(s.body, &pose, s.body_verts, NULL) != WEFT_OK) {
                return fail_msg(&s, "posing the body");
            }
        }
        double t1 = weft__now_ms();
        const float *cloth = NULL;
        if (dressed && simulated) {
            if (weft_garment_set_collider(s.garment, s.body_verts) != WEFT_OK ||
                weft_sample_waistband_pin(s.band, s.garment, s.body_verts, s.band_targets) != WEFT_OK ||
                weft_garment_step(s.garment) != WEFT_OK) {
                char what[64];
                snprintf(what, sizeof what, "cloth step at frame %u", k);
                return fail_msg(&s, what);
            }
            cloth = weft_garment_positions(s.garment);
            if (s.sim_map) {
                if (weft_mesh_map_apply(s.sim_map, cloth, s.cloth_verts) != WEFT_OK) {
                    return fail_msg(&s, "mapping the simulated garment onto the drawn one");
                }
                cloth = s.cloth_verts;
            }
        } else if (dressed) {
            if (skin_garment(&s, &pose, gm_rest, gm_nv, s.cloth_verts) != WEFT_OK) {
                return fail_msg(&s, "skinning the garment");
            }
            cloth = s.cloth_verts;
        }
        if (cape_frame(&s, &pose, k) != 0) {
            sample_free(&s);
            return 1;
        }
        double t2 = weft__now_ms();
        if (k < settle) {
            continue;
        }
        uint32_t frame = k - settle;
        if (weft_renderer_update_mesh(s.renderer, body_mesh, s.body_verts) != WEFT_OK ||
            (cloth && weft_renderer_update_mesh(s.renderer, cloth_mesh, cloth) != WEFT_OK)) {
            return fail_msg(&s, "updating the render meshes");
        }
        if (s.cape && weft_renderer_update_mesh(s.renderer, s.cape_mesh, weft_sample_cape_positions(s.cape)) != WEFT_OK) {
            return fail_msg(&s, "updating the cape mesh");
        }
        float lo[3], hi[3];
        if (s.character) {
            camera_box_points(body_rest, s.body_verts, nv, lo, hi);
        } else {
            camera_box(s.body, &pose, lo, hi);
        }
        if (weft_renderer_frame_box(s.renderer, lo, hi, o->yaw, o->pitch) != WEFT_OK ||
            weft_renderer_render(s.renderer) != WEFT_OK) {
            return fail_msg(&s, "rendering");
        }
        double t3 = weft__now_ms();
        if (o->write_frames) {
            snprintf(path, sizeof path, "%s/frame_%04u.png", o->out_dir, frame);
            if (weft_render_write_png(path, weft_renderer_pixels(s.renderer), o->width, o->height) != WEFT_OK) {
                return fail_msg(&s, "writing a frame");
            }
        }
        double t4 = weft__now_ms();
        /* tiles evenly spaced over the clip, first and last frames included */
        if (tile_next < tiles && (tiles == 1 ? frame == 0 : frame == (uint64_t)tile_next * (o->frames - 1) / (tiles - 1))) {
            memcpy(s.tiles + image_bytes * tile_next, weft_renderer_pixels(s.renderer), image_bytes);
            const char *spec = s.character ? o->avatar : o->motion;
            const char *motion_label = strchr(spec, ':') ? strrchr(spec, '/') : NULL;
            snprintf(labels[tile_next], sizeof labels[tile_next], "%s %s t=%.2fs",
                     motion_label ? motion_label + 1 : strchr(spec, ':') ? strchr(spec, ':') + 1 : spec, method_used,
                     o->start + frame / 60.0);
            tile_next++;
        }
        sums[0] += t1 - t0;
        sums[1] += t2 - t1;
        sums[2] += t3 - t2;
        sums[3] += t4 - t3;
        if ((s.pc2_body.f && weft_pc2_write(&s.pc2_body, s.body_verts) != WEFT_OK) ||
            (s.pc2_cloth.f && cloth && weft_pc2_write(&s.pc2_cloth, cloth) != WEFT_OK)) {
            return fail_msg(&s, "export");
        }
        s.cloth_ms[frame] = t2 - t1;
        weft_wear_frame wf = {0};
        if (s.wear) {
            if (skin_garment(&s, &pose, gm_rest, gm_nv, s.skinned_verts) != WEFT_OK ||
                weft_wear_measure(s.wear, s.body_verts, cloth, s.skinned_verts, off_distance, &wf) != WEFT_OK) {
                return fail_msg(&s, "measuring the wear");
            }
            weft_wear_summary_add(&wear, &wf);
        }
        printf("frame %4u  pose %6.2f ms  cloth(%s) %7.2f ms  render %7.2f ms  png %6.2f ms", frame, t1 - t0,
               method_used, t2 - t1, t3 - t2, t4 - t3);
        if (s.wear) {
            printf("  off_body %5.1f %%  inside_body %5.1f %%  body_self_overlap %4.1f %%", 100.0 * wf.off_body,
                   100.0 * wf.inside_body, 100.0 * wf.body_self_overlap);
        }
        if (dressed && simulated) {
            const weft_step_stats st = weft_garment_stats(s.garment);
            push_searched += st.push_searched;
            push_moved += st.pushed_vertices;
            push_frames++;
            printf("%s%s", st.collider_cut ? "  cut (body jumped; garment reset to the skinned one)" : "",
                   st.ccd_over_budget ? "  ccd over budget (uncertified)" : "");
        }
        printf("\n");
    }
    const uint8_t *tile_ptrs[64];
    const char *label_ptrs[64];
    for (uint32_t i = 0; i < tile_next; ++i) {
        tile_ptrs[i] = s.tiles + image_bytes * i;
        label_ptrs[i] = labels[i];
    }
    uint8_t *sheet = NULL;
    uint32_t sw = 0, sh = 0;
    if (weft_render_contact_sheet(tile_ptrs, label_ptrs, tile_next, o->width, o->height, tile_next > 4 ? 4 : tile_next,
                                  &sheet, &sw, &sh) != WEFT_OK) {
        return fail_msg(&s, "building the contact sheet");
    }
    snprintf(path, sizeof path, "%s/contact_sheet.png", o->out_dir);
    weft_result wr = weft_render_write_png(path, sheet, sw, sh);
    weft_render_free_image(sheet);
    if (wr != WEFT_OK) {
        return fail_msg(&s, "writing the contact sheet");
    }
    double n = o->frames;
    printf("mean per frame: pose %.2f ms, cloth(%s) %.2f ms, render %.2f ms, png %.2f ms\n", sums[0] / n, method_used,
           sums[1] / n, sums[2] / n, sums[3] / n);
    if (push_frames > 0 && s.garment) {
        const uint32_t sim_nv = weft_garment_vertex_count(s.garment);
        printf("push: searched %.1f %% of the simulated garment's %u vertices a frame, moved %.1f (mean over %u "
               "frames; docs/CCD.md, Clearance)\n",
               100.0 * push_searched / ((double)push_frames * sim_nv), sim_nv, push_moved / push_frames, push_frames);
    }
    if (s.wear) {
        printf("wear: garment %s (%u of %u frames over 1 %% of vertices farther than %.0f cm from the skinned "
               "garment; worst %.1f %%); inside_body mean %.1f %%, max %.1f %% (%.1f %% where the body is clear); "
               "body_self_overlap mean %.1f %%, max %.1f %%\n",
               wear.frames_off ? "LOST" : "kept", wear.frames_off, wear.frames, 100.0 * off_distance,
               100.0 * wear.off_body_max, 100.0 * wear.inside_mean, 100.0 * wear.inside_max,
               100.0 * wear.inside_clear_max, 100.0 * wear.overlap_mean, 100.0 * wear.overlap_max);
        const double p50 = weft_wear_percentile(s.cloth_ms, o->frames, 50.0);
        const double p99 = weft_wear_percentile(s.cloth_ms, o->frames, 99.0);
        const double pmax = weft_wear_percentile(s.cloth_ms, o->frames, 100.0);
        printf("cloth ms per frame: p50 %.2f, p99 %.2f, max %.2f (max / p50 %.1f)\n", p50, p99, pmax,
               p50 > 0.0 ? pmax / p50 : 0.0);
    }
    if (s.cape) {
        printf("cape (%s): %.2f ms per step over %u steps (included in the cloth column), %u non-finite steps; "
               "body collision moved cape vertices in %u steps (%llu vertex moves)\n",
               o->cape_xpbd_substeps ? "fast XPBD" : "FNOpt", s.cape_ms / (settle + o->frames), settle + o->frames,
               weft_sample_cape_failed_steps(s.cape),
               s.cape_push_steps, (unsigned long long)s.cape_pushed);
    }
    if (o->export_dir) {
        const uint32_t samples = s.pc2_body.samples;
        if (weft_pc2_close(&s.pc2_body) != WEFT_OK || weft_pc2_close(&s.pc2_cloth) != WEFT_OK) {
            return fail_msg(&s, "export");
        }
        printf("exported %u frames to %s (body.obj + body.pc2%s)\n", samples, o->export_dir,
               dressed ? ", garment.obj + garment.pc2" : "");
    }
    printf("wrote %s%s\n", o->write_frames ? "frames and " : "", path);
    sample_free(&s);
    return 0;
}

int weft_avatar_sample_docs_sheet(const char *path, uint32_t tile)
{
    if (!path || tile < 64 || tile > 1024) {
        fprintf(stderr, "docs sheet: a path and a tile size in 64..1024 are required\n");
        return 2;
    }
    static const int garments[] = {-1, WEFT_CLOTH_TSHIRT, WEFT_CLOTH_SKIRT, WEFT_CLOTH_DRESS};
    static const struct {
        const char *label;
        int motion; /* -1: bind pose */
        double phase; /* fraction of the motion's period */
    } poses[] = {{"bind pose", -1, 0.0},
                 {"walk", WEFT_MOTION_WALK, 0.25},
                 {"run", WEFT_MOTION_RUN, 0.3},
                 {"arm raise", WEFT_MOTION_ARM_RAISE, 0.5},
                 {"dance", WEFT_MOTION_DANCE, 0.35}};
    enum { ROWS = 4, COLS = 5 };
    sample_state s;
    memset(&s, 0, sizeof s);
    weft_context_def cdef = weft_default_context_def();
    weft_avatar_def adef = weft_default_avatar_def();
    weft_render_def rdef = weft_default_render_def();
    rdef.width = rdef.height = tile;
    if (weft_context_create(&cdef, &s.ctx) != WEFT_OK || weft_avatar_create(s.ctx, &adef, &s.body) != WEFT_OK ||
        weft_renderer_create(&rdef, &s.renderer) != WEFT_OK) {
        return fail_msg(&s, "docs sheet setup");
    }
    uint32_t nv = weft_body_vertex_count(s.body);
    size_t image_bytes = (size_t)tile * tile * 4;
    s.body_verts = malloc((size_t)nv * 3 * sizeof(float));
    s.tiles = malloc(image_bytes * ROWS * COLS);
    if (!s.body_verts || !s.tiles) {
        return fail_msg(&s, "out of memory");
    }
    char labels[ROWS * COLS][48];
    const uint8_t *tile_ptrs[ROWS * COLS];
    const char *label_ptrs[ROWS * COLS];
    for (int row = 0; row < ROWS; ++row) {
        weft_cloth_destroy(s.cloth);
        s.cloth = NULL;
        free(s.cloth_verts);
        s.cloth_verts = NULL;
        if (garments[row] >= 0) {
            weft_cloth_def cd = weft_default_cloth_def((weft_cloth_kind)garments[row]);
            cd.resolution = WEFT_CLOTH_RES_4K;
            if (weft_cloth_create(s.ctx, &cd, s.body, &s.cloth) != WEFT_OK) {
                return fail_msg(&s, "weft_cloth_create");
            }
            s.cloth_verts = malloc((size_t)s.cloth->vertex_count * 3 * sizeof(float));
            if (!s.cloth_verts) {
                return fail_msg(&s, "out of memory");
            }
        }
        for (int col = 0; col < COLS; ++col) {
            weft_pose pose;
            if (poses[col].motion < 0) {
                weft_body_bind_pose(s.body, &pose);
            } else {
                weft_motion_def md = weft_default_motion_def((weft_motion)poses[col].motion);
                if (weft_motion_sample(&md, poses[col].phase * weft_motion_period(&md), &pose) != WEFT_OK) {
                    return fail_msg(&s, "weft_motion_sample");
                }
            }
            weft_renderer_clear_meshes(s.renderer);
            if (weft_body_pose(s.body, &pose, s.body_verts, NULL) != WEFT_OK ||
                weft_renderer_add_mesh(s.renderer, s.body_verts, nv, weft_body_triangles(s.body),
                                       weft_body_triangle_count(s.body), WEFT_RENDER_SKIN, NULL) != WEFT_OK) {
                return fail_msg(&s, "posing the body");
            }
            if (s.cloth) {
                if (weft_body_skin_points(s.body, &pose, s.cloth->positions, s.cloth->weights, s.cloth->vertex_count,
                                          s.cloth_verts) != WEFT_OK ||
                    weft_renderer_add_mesh(s.renderer, s.cloth_verts, s.cloth->vertex_count, s.cloth->triangles,
                                           s.cloth->triangle_count, WEFT_RENDER_CLOTH, NULL) != WEFT_OK) {
                    return fail_msg(&s, "skinning the garment");
                }
            }
            float lo[3], hi[3];
            camera_box(s.body, &pose, lo, hi);
            weft_renderer_set_ground(s.renderer, true, 0.0f);
            if (weft_renderer_frame_box(s.renderer, lo, hi, 25.0f, 8.0f) != WEFT_OK ||
                weft_renderer_render(s.renderer) != WEFT_OK) {
                return fail_msg(&s, "rendering");
            }
            int i = row * COLS + col;
            memcpy(s.tiles + image_bytes * (size_t)i, weft_renderer_pixels(s.renderer), image_bytes);
            snprintf(labels[i], sizeof labels[i], "%s, %s", garments[row] >= 0 ? weft_cloth_kind_name((weft_cloth_kind)garments[row]) : "no garment",
                     poses[col].label);
            tile_ptrs[i] = s.tiles + image_bytes * (size_t)i;
            label_ptrs[i] = labels[i];
        }
    }
    uint8_t *sheet = NULL;
    uint32_t sw = 0, sh = 0;
    if (weft_render_contact_sheet(tile_ptrs, label_ptrs, ROWS * COLS, tile, tile, COLS, &sheet, &sw, &sh) != WEFT_OK) {
        return fail_msg(&s, "building the sheet");
    }
    weft_result wr = weft_render_write_png(path, sheet, sw, sh);
    weft_render_free_image(sheet);
    if (wr != WEFT_OK) {
        return fail_msg(&s, "writing the sheet");
    }
    printf("wrote %s (%ux%u): rows no garment, tshirt, skirt, dress; garments skinned to each pose\n", path, sw, sh);
    sample_free(&s);
    return 0;
}

#else

int weft_avatar_sample_run(const weft_avatar_sample_options *o)
{
    (void)o;
    (void)make_dirs;
    fprintf(stderr, "avatar_render: this build has no body/wardrobe/motion runtime (include/weft/body.h)\n");
    return 1;
}

int weft_avatar_sample_docs_sheet(const char *path, uint32_t tile_size)
{
    (void)path;
    (void)tile_size;
    fprintf(stderr, "docs sheet: this build has no body/wardrobe/motion runtime\n");
    return 1;
}

#endif
