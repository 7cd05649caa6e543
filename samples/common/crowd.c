/* Crowd mode of the avatar sample (`avatar_render --crowd N`): N avatars in a grid, each wearing
 * a garment stepped at its own level of detail. Levels come from the measured LOD table
 * (samples/data/lod_garment.csv, else samples/data/lod.csv; `weft bench lod`): every character
 * asks weft_lod_pick for the cheapest level whose measured error meets an accuracy target that
 * loosens with its depth from the camera, so the front row gets the most accurate level and the
 * back rows cheaper ones (levels with CCD only). The garments of one level are stepped together
 * by weft_garments_step. Prints the total and per-level cloth ms per frame and writes one PNG
 * (garments coloured by level, with a legend). */
#define _POSIX_C_SOURCE 200809L

#include "weft_sample.h"
#include "core/core.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#if WEFT_RENDER_HAVE_SAMPLE
#include "weft/body.h"
#include "weft/lod.h"

#define CROWD_MAX_MODELS 16
#define CROWD_SPACING_X 1.1f            /* metres between characters in a row */
#define CROWD_SPACING_Z 1.4f            /* metres between rows */

typedef struct crowd {
    weft_context *ctx;
    weft_body *body;
    weft_cloth_mesh *cloth;
    /* The same garment at the wardrobe's coarser resolutions: the sim meshes of resolution levels
     * (lod.csv resolution < 1), placed per character in coarse_rest. */
    weft_cloth_mesh *coarse[WEFT_CLOTH_RES_COUNT];
    float *coarse_rest[WEFT_CLOTH_RES_COUNT];
    uint32_t coarse_count;
    weft_lod_table *table;
    weft_model *models[CROWD_MAX_MODELS];
    uint32_t model_count;
    uint8_t *usable;
    weft_renderer *renderer;
    weft_lod_garment **garments;
    uint32_t *level;                    /* per character */
    uint32_t *by_level;                 /* characters ordered by level (groups for batched steps) */
    weft_garment **current;             /* scratch for one weft_garments_step call */
    float *offset;                      /* per character x, z */
    float *verts, *placed, *rest;
    uint32_t *body_mesh, *cloth_mesh;
    double *level_ms;                   /* per level, summed over frames */
    uint32_t *level_count;              /* characters per level */
    uint32_t n;
} crowd;

static void crowd_free(crowd *c)
{
    for (uint32_t i = 0; c->garments && i < c->n; ++i) {
        weft_lod_garment_destroy(c->garments[i]);
    }
    for (uint32_t i = 0; i < c->model_count; ++i) {
        weft_model_destroy(c->models[i]);
    }
    weft_lod_table_destroy(c->table);
    weft_cloth_destroy(c->cloth);
    for (uint32_t k = 0; k < c->coarse_count; ++k) {
        weft_cloth_destroy(c->coarse[k]);
        free(c->coarse_rest[k]);
    }
    weft_body_destroy(c->body);
    weft_renderer_destroy(c->renderer);
    free(c->garments);
    free(c->level);
    free(c->by_level);
    free(c->current);
    free(c->offset);
    free(c->verts);
    free(c->placed);
    free(c->rest);
    free(c->body_mesh);
    free(c->cloth_mesh);
    free(c->level_ms);
    free(c->level_count);
    free(c->usable);
    if (c->ctx) {
        weft_context_destroy(c->ctx);
    }
}

static int crowd_fail(crowd *c, const char *what)
{
    fprintf(stderr, "avatar_render --crowd: %s: %s\n", what, weft_last_error());
    crowd_free(c);
    return 1;
}

static bool file_exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

/* Loads the model files the table's model levels name, from the folder of --model (or
 * tools/train/models): NAME.PRECISION.safetensors when present, else NAME.safetensors, NAME being
 * the model's name or the same with '-' as '_'. A level whose model cannot be loaded is not usable
 * (and said so). */
static void load_models(crowd *c, const weft_avatar_sample_options *o)
{
    char dir[1024] = "tools/train/models";
    if (o->model_path) {
        snprintf(dir, sizeof dir, "%s", o->model_path);
        char *slash = strrchr(dir, '/');
        if (slash) {
            *slash = '\0';
        } else {
            snprintf(dir, sizeof dir, ".");
        }
    }
    static const char *const prec_names[] = {"fp32", "fp16", "int8"};
    for (uint32_t i = 0; i < weft_lod_table_count(c->table); ++i) {
        const weft_lod_level *l = weft_lod_table_level(c->table, i);
        /* Levels without CCD are left out: the table's MVE does not see the body poking through
         * a garment, which is what those levels show on an avatar. */
        if (!l->ccd) {
            continue;
        }
        if (l->method != WEFT_METHOD_MODEL) {
            c->usable[i] = 1;
            continue;
        }
        /* Files are named by the training run's stem (game_k16), the table by the model's
         * metadata name (game-k16): try the name as it is, then with '-' as '_'. */
        char stems[2][WEFT_LOD_NAME_CAP], path[1400] = "";
        snprintf(stems[0], sizeof stems[0], "%s", l->model);
        snprintf(stems[1], sizeof stems[1], "%s", l->model);
        for (char *ch = stems[1]; *ch; ++ch) {
            *ch = *ch == '-' ? '_' : *ch;
        }
        for (int k = 1; k >= 0; --k) { /* stems[0] last, so its path is the one reported on failure */
            char prec_path[1400], base_path[1400];
            snprintf(prec_path, sizeof prec_path, "%s/%s.%s.safetensors", dir, stems[k], prec_names[l->precision]);
            snprintf(base_path, sizeof base_path, "%s/%s.safetensors", dir, stems[k]);
            const char *pick = l->precision != WEFT_PRECISION_FP32 && file_exists(prec_path) ? prec_path : base_path;
            if (k == 0 || file_exists(pick)) {
                snprintf(path, sizeof path, "%s", pick);
                break;
            }
        }
        /* Already loaded (same name at the wanted stored precision, or the fp32 base)? */
        bool have = false;
        for (uint32_t m = 0; m < c->model_count && !have; ++m) {
            weft_model_info info = weft_model_get_info(c->models[m]);
            have = strcmp(info.name, l->model) == 0 &&
                   (info.precision == l->precision || (info.precision == WEFT_PRECISION_FP32 && !strstr(path, ".fp16.") &&
                                                       !strstr(path, ".int8.")));
        }
        if (!have && c->model_count < CROWD_MAX_MODELS) {
            if (weft_model_load_file(c->ctx, path, &c->models[c->model_count]) == WEFT_OK) {
                c->model_count++;
                have = true;
            } else {
                fprintf(stderr, "avatar_render --crowd: level %s not usable: %s\n", l->name, weft_last_error());
            }
        }
        c->usable[i] = have;
    }
}

/* mkdir -p */
static bool make_path(const char *path)
{
    char buf[1024];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) {
        errno = ENAMETOOLONG;
        return false;
    }
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; ++i) {
        if (buf[i] == '/' || buf[i] == '\0') {
            char saved = buf[i];
            buf[i] = '\0';
            if (mkdir(buf, 0755) != 0 && errno != EEXIST) {
                return false;
            }
            buf[i] = saved;
        }
    }
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static bool load_table(crowd *c, const weft_avatar_sample_options *o)
{
    /* Default: the worn-garment table (tethered and strain-limited levels, measured on garments),
     * else the table over every scenario. */
    struct stat st;
    const char *path = o->lod_table                                           ? o->lod_table
                       : stat("samples/data/lod_garment.csv", &st) == 0 ? "samples/data/lod_garment.csv"
                                                                             : "samples/data/lod.csv";
    if (weft_lod_table_load_file(c->ctx, path, &c->table) != WEFT_OK) {
        fprintf(stderr, "avatar_render --crowd: the LOD table: %s\n  (run from the source root, or pass --lod-table; "
                        "`weft bench lod` writes samples/data/lod.csv and samples/data/lod_garment.csv)\n",
                weft_last_error());
        return false;
    }
    printf("LOD table: %s\n", path);
    return true;
}

/* Distinct colours for up to 8 levels, then they repeat. */
static void level_color(uint32_t k, float rgb[3])
{
    static const float pal[8][3] = {{0.85f, 0.20f, 0.20f}, {0.95f, 0.60f, 0.10f}, {0.90f, 0.85f, 0.20f},
                                    {0.25f, 0.70f, 0.30f}, {0.20f, 0.55f, 0.85f}, {0.55f, 0.35f, 0.80f},
                                    {0.85f, 0.45f, 0.70f}, {0.50f, 0.50f, 0.50f}};
    memcpy(rgb, pal[k % 8], sizeof pal[0]);
}

int weft_avatar_sample_crowd(const weft_avatar_sample_options *o)
{
    crowd c;
    memset(&c, 0, sizeof c);
    const uint32_t n = o->crowd;
    c.n = n;
    weft_motion motion;
    if (weft_motion_from_name(o->motion, &motion) != WEFT_OK) {
        fprintf(stderr, "avatar_render --crowd: --motion must be a procedural motion (walk, run, ...): %s\n",
                weft_last_error());
        return 2;
    }
    weft_cloth_kind kind;
    weft_cloth_resolution res;
    if (weft_cloth_kind_from_name(o->garment, &kind) != WEFT_OK || kind >= WEFT_CLOTH_SHEET) {
        fprintf(stderr, "avatar_render --crowd: --garment must be tshirt, skirt or dress\n");
        return 2;
    }
    if (weft_cloth_resolution_from_name(o->resolution, &res) != WEFT_OK) {
        fprintf(stderr, "avatar_render --crowd: --resolution must be 1k, 4k, 16k or 40k\n");
        return 2;
    }
    weft_context_def cdef = weft_default_context_def();
    weft_avatar_def adef = weft_default_avatar_def();
    weft_cloth_def cldef = weft_default_cloth_def(kind);
    cldef.resolution = res;
    if (weft_context_create(&cdef, &c.ctx) != WEFT_OK || weft_avatar_create(c.ctx, &adef, &c.body) != WEFT_OK ||
        weft_cloth_create(c.ctx, &cldef, c.body, &c.cloth) != WEFT_OK) {
        return crowd_fail(&c, "setting up the avatar and garment");
    }
    for (int r = WEFT_CLOTH_RES_1K; r < (int)res; ++r) {
        weft_cloth_def coarse_def = cldef;
        coarse_def.resolution = (weft_cloth_resolution)r;
        weft_cloth_mesh **m = &c.coarse[c.coarse_count];
        if (weft_cloth_create(c.ctx, &coarse_def, c.body, m) != WEFT_OK ||
            !(c.coarse_rest[c.coarse_count] = malloc((size_t)(*m)->vertex_count * 3 * sizeof(float)))) {
            weft_cloth_destroy(*m);
            return crowd_fail(&c, "making the garment's coarser meshes");
        }
        c.coarse_count++;
    }
    if (!load_table(&c, o)) {
        crowd_free(&c);
        return 1;
    }
    const uint32_t levels = weft_lod_table_count(c.table);
    const uint32_t nb = weft_body_vertex_count(c.body), nv = c.cloth->vertex_count;
    c.usable = calloc(levels, 1);
    weft_lod_mesh sim[WEFT_CLOTH_RES_COUNT];
    for (uint32_t k = 0; k < c.coarse_count; ++k) {
        sim[k] = (weft_lod_mesh){c.coarse_rest[k], c.coarse[k]->vertex_count, c.coarse[k]->triangles,
                                 c.coarse[k]->triangle_count};
    }
    c.garments = calloc(n, sizeof *c.garments);
    c.level = calloc(n, sizeof *c.level);
    c.by_level = calloc(n, sizeof *c.by_level);
    c.current = calloc(n, sizeof *c.current);
    c.offset = calloc((size_t)n * 2, sizeof *c.offset);
    c.verts = malloc((size_t)nb * 3 * sizeof(float));
    c.placed = malloc((size_t)nb * 3 * sizeof(float));
    c.rest = malloc((size_t)nv * 3 * sizeof(float));
    c.body_mesh = calloc(n, sizeof *c.body_mesh);
    c.cloth_mesh = calloc(n, sizeof *c.cloth_mesh);
    c.level_ms = calloc(levels, sizeof *c.level_ms);
    c.level_count = calloc(levels, sizeof *c.level_count);
    if (!c.usable || !c.garments || !c.level || !c.by_level || !c.current || !c.offset || !c.verts || !c.placed ||
        !c.rest || !c.body_mesh || !c.cloth_mesh || !c.level_ms || !c.level_count) {
        fprintf(stderr, "avatar_render --crowd: out of memory\n");
        crowd_free(&c);
        return 1;
    }
    load_models(&c, o);
    /* A resolution level needs a coarser mesh near its share of the drawn vertices (the rule of
     * weft_lod_garment_def.sim_meshes: within a factor of 1.5). */
    for (uint32_t l = 0; l < levels; ++l) {
        const weft_lod_level *lv = weft_lod_table_level(c.table, l);
        bool mesh = lv->resolution >= 1.0;
        for (uint32_t k = 0; k < c.coarse_count && !mesh; ++k) {
            double share = (double)c.coarse[k]->vertex_count / nv;
            mesh = share <= 1.5 * lv->resolution && share >= lv->resolution / 1.5;
        }
        if (c.usable[l] && !mesh) {
            printf("level %s not usable: no %s mesh near %.0f vertices for resolution %g\n", lv->name, o->garment,
                   lv->resolution * nv, lv->resolution);
            c.usable[l] = 0;
        }
    }

    /* Grid: columns along X, rows going away from the camera (-Z), centred on the origin. */
    const uint32_t cols = (uint32_t)ceil(sqrt((double)n));
    const uint32_t rows = (n + cols - 1) / cols;
    float *depth = malloc(n * sizeof(float));
    if (!depth) {
        fprintf(stderr, "avatar_render --crowd: out of memory\n");
        crowd_free(&c);
        return 1;
    }
    const float deg = 3.14159265f / 180.0f;
    const float eye_dir[3] = {sinf(o->yaw * deg) * cosf(o->pitch * deg), sinf(o->pitch * deg),
                              cosf(o->yaw * deg) * cosf(o->pitch * deg)};
    float depth_min = INFINITY;
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t r = i / cols, k = i % cols;
        c.offset[2 * i] = ((float)k - 0.5f * (float)(cols - 1)) * CROWD_SPACING_X;
        c.offset[2 * i + 1] = -((float)r - 0.5f * (float)(rows - 1)) * CROWD_SPACING_Z;
        /* Depth along the viewing direction (the camera sits along eye_dir from the centre). */
        depth[i] = -(c.offset[2 * i] * eye_dir[0] + c.offset[2 * i + 1] * eye_dir[2]);
        depth_min = fminf(depth_min, depth[i]);
    }
    /* Accuracy target: --crowd-mve at the front, growing linearly with depth (an error of a fixed
     * size covers fewer pixels further away): target = mve * (1 + extra depth / 1 m). */
    double best_mve = INFINITY;
    for (uint32_t l = 0; l < levels; ++l) {
        const weft_lod_level *lv = weft_lod_table_level(c.table, l);
        if (c.usable[l] && lv->mve_cm < best_mve) {
            best_mve = lv->mve_cm;
        }
    }
    const double front_mve = o->crowd_mve > 0.0f ? o->crowd_mve : best_mve;
    const double budget = o->crowd_budget > 0.0f ? o->crowd_budget : INFINITY;
    for (uint32_t i = 0; i < n; ++i) {
        double target = front_mve * (1.0 + (depth[i] - depth_min));
        weft_lod_pick_result pr = weft_lod_pick_among(c.table, c.usable, budget, target, &c.level[i]);
        if (pr == WEFT_LOD_PICK_INVALID) {
            free(depth);
            return crowd_fail(&c, "picking a level");
        }
        c.level_count[c.level[i]]++;
    }
    free(depth);
    for (uint32_t l = 0, k = 0; l < levels; ++l) {
        for (uint32_t i = 0; i < n; ++i) {
            if (c.level[i] == l) {
                c.by_level[k++] = i;
            }
        }
    }

    /* Garments on the bind pose at each character's place; the renderer gets every mesh. */
    weft_render_def rdef = weft_default_render_def();
    rdef.width = o->width;
    rdef.height = o->height;
    rdef.deterministic = o->deterministic;
    if (weft_renderer_create(&rdef, &c.renderer) != WEFT_OK) {
        return crowd_fail(&c, "weft_renderer_create");
    }
    const float *br = weft_body_rest_vertices(c.body);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; ++i) {
        const float dx = c.offset[2 * i], dz = c.offset[2 * i + 1];
        for (uint32_t v = 0; v < nb; ++v) {
            c.placed[3 * v] = br[3 * v] + dx;
            c.placed[3 * v + 1] = br[3 * v + 1];
            c.placed[3 * v + 2] = br[3 * v + 2] + dz;
            for (int k = 0; k < 3; ++k) {
                lo[k] = fminf(lo[k], c.placed[3 * v + k]);
                hi[k] = fmaxf(hi[k], c.placed[3 * v + k]);
            }
        }
        for (uint32_t v = 0; v < nv; ++v) {
            c.rest[3 * v] = c.cloth->positions[3 * v] + dx;
            c.rest[3 * v + 1] = c.cloth->positions[3 * v + 1];
            c.rest[3 * v + 2] = c.cloth->positions[3 * v + 2] + dz;
        }
        for (uint32_t k = 0; k < c.coarse_count; ++k) {
            for (uint32_t v = 0; v < c.coarse[k]->vertex_count; ++v) {
                c.coarse_rest[k][3 * v] = c.coarse[k]->positions[3 * v] + dx;
                c.coarse_rest[k][3 * v + 1] = c.coarse[k]->positions[3 * v + 1];
                c.coarse_rest[k][3 * v + 2] = c.coarse[k]->positions[3 * v + 2] + dz;
            }
        }
        weft_lod_garment_def d = weft_default_lod_garment_def();
        d.table = c.table;
        d.level = c.level[i];
        d.models = (const weft_model *const *)c.models;
        d.model_count = c.model_count;
        d.rest_positions = c.rest;
        d.vertex_count = nv;
        d.triangles = c.cloth->triangles;
        d.triangle_count = c.cloth->triangle_count;
        d.collider_rest_positions = c.placed;
        d.collider_vertex_count = nb;
        d.collider_triangles = weft_body_triangles(c.body);
        d.collider_triangle_count = weft_body_triangle_count(c.body);
        d.sim_meshes = sim;
        d.sim_mesh_count = c.coarse_count;
        if (weft_lod_garment_create(c.ctx, &d, &c.garments[i]) != WEFT_OK) {
            return crowd_fail(&c, "creating a garment");
        }
        float col[3];
        level_color(c.level[i], col);
        if (weft_renderer_add_mesh(c.renderer, c.placed, nb, weft_body_triangles(c.body), weft_body_triangle_count(c.body),
                                   WEFT_RENDER_SKIN, &c.body_mesh[i]) != WEFT_OK ||
            weft_renderer_add_mesh(c.renderer, c.rest, nv, c.cloth->triangles, c.cloth->triangle_count,
                                   WEFT_RENDER_CLOTH, &c.cloth_mesh[i]) != WEFT_OK ||
            weft_renderer_set_mesh_colors(c.renderer, c.cloth_mesh[i], col, NULL) != WEFT_OK) {
            return crowd_fail(&c, "adding meshes");
        }
    }
    weft_renderer_set_ground(c.renderer, true, 0.0f);
    lo[1] = 0.0f;
    hi[1] += 0.1f;
    if (weft_renderer_frame_box(c.renderer, lo, hi, o->yaw, o->pitch) != WEFT_OK) {
        return crowd_fail(&c, "framing the crowd");
    }

    /* --settle frames blend from the bind pose (where the garments were made) into the motion. */
    const uint32_t blend = o->settle_frames;
    printf("crowd of %u avatars (%u x %u grid), garment %s %s (%u vertices), motion %s, %u frames after %u blend-in "
           "frames\n",
           n, cols, rows, o->garment, o->resolution, nv, o->motion, o->frames, blend);
    printf("accuracy target %.3f cm at the front row, +100%% per metre of depth; budget %s\n", front_mve,
           isfinite(budget) ? "per character as given" : "none");
    for (uint32_t l = 0; l < levels; ++l) {
        if (c.level_count[l]) {
            const weft_lod_level *lv = weft_lod_table_level(c.table, l);
            printf("  level %-20s %3u characters  (table: %.3f ms/frame, MVE %.3f cm)\n", lv->name, c.level_count[l],
                   lv->ms_per_frame, lv->mve_cm);
        }
    }

    weft_motion_def md = weft_default_motion_def(motion);
    md.speed = o->speed;
    weft_pose bind;
    weft_body_bind_pose(c.body, &bind);
    double total_ms = 0;
    for (uint32_t f = 0; f < blend + o->frames; ++f) {
        double frame_ms = 0;
        for (uint32_t i = 0; i < n; ++i) {
            weft_pose pose;
            /* Each character starts at its own phase so the crowd does not march in step. */
            if (weft_motion_sample(&md, o->start + 0.37 * i + (f >= blend ? (f - blend) / 60.0 : 0.0),
                                   &pose) != WEFT_OK) {
                return crowd_fail(&c, "sampling the motion");
            }
            if (f < blend) {
                float u = (float)(f + 1) / (float)blend;
                u = u * u * (3.0f - 2.0f * u);
                for (int j = 0; j < WEFT_POSE_ROTATION_FLOATS; ++j) {
                    pose.rotations[j] = bind.rotations[j] + u * (pose.rotations[j] - bind.rotations[j]);
                }
                for (int k = 0; k < 3; ++k) {
                    pose.translation[k] = bind.translation[k] + u * (pose.translation[k] - bind.translation[k]);
                }
            }
            pose.translation[0] = c.offset[2 * i];
            pose.translation[2] = c.offset[2 * i + 1];
            if (weft_body_pose(c.body, &pose, c.verts, NULL) != WEFT_OK ||
                weft_renderer_update_mesh(c.renderer, c.body_mesh[i], c.verts) != WEFT_OK ||
                weft_lod_garment_set_collider(c.garments[i], c.verts) != WEFT_OK) {
                return crowd_fail(&c, "posing a character");
            }
        }
        /* One weft_garments_step call per level: characters sharing a model level run its
         * temporal transformer as one stacked GEMM. set_collider above recorded each garment's
         * frame, so stepping the current garments directly keeps the LOD state complete. */
        for (uint32_t l = 0, first = 0; l < levels; first += c.level_count[l], ++l) {
            if (!c.level_count[l]) {
                continue;
            }
            for (uint32_t k = 0; k < c.level_count[l]; ++k) {
                c.current[k] = weft_lod_garment_current(c.garments[c.by_level[first + k]]);
            }
            double t0 = weft__now_ms();
            if (weft_garments_step(c.current, c.level_count[l]) != WEFT_OK) {
                char what[96];
                snprintf(what, sizeof what, "cloth step of level %s at frame %u", weft_lod_table_level(c.table, l)->name,
                         f);
                return crowd_fail(&c, what);
            }
            /* Resolution levels draw the garment through a mesh map: part of their step. */
            for (uint32_t k = 0; k < c.level_count[l]; ++k) {
                if (weft_lod_garment_sync(c.garments[c.by_level[first + k]]) != WEFT_OK) {
                    return crowd_fail(&c, "mapping a garment onto its drawn mesh");
                }
            }
            double ms = weft__now_ms() - t0;
            frame_ms += ms;
            if (f >= blend) {
                c.level_ms[l] += ms;
            }
        }
        for (uint32_t i = 0; i < n; ++i) {
            if (weft_renderer_update_mesh(c.renderer, c.cloth_mesh[i], weft_lod_garment_positions(c.garments[i])) !=
                WEFT_OK) {
                return crowd_fail(&c, "updating a garment mesh");
            }
        }
        if (f >= blend) {
            total_ms += frame_ms;
            printf("frame %4u  cloth total %9.2f ms  (%u characters)\n", f - blend, frame_ms, n);
        }
    }
    const double frames = o->frames;
    printf("mean cloth ms/frame: total %.2f ms for %u characters (%.2f ms per character)\n", total_ms / frames, n,
           total_ms / frames / n);
    for (uint32_t l = 0; l < levels; ++l) {
        if (c.level_count[l]) {
            printf("  level %-20s %3u characters  %9.2f ms/frame  (%.2f ms per character)\n",
                   weft_lod_table_level(c.table, l)->name, c.level_count[l], c.level_ms[l] / frames,
                   c.level_ms[l] / frames / c.level_count[l]);
        }
    }

    /* One picture of the last frame with a legend of the levels' colours. */
    if (weft_renderer_render(c.renderer) != WEFT_OK) {
        return crowd_fail(&c, "rendering");
    }
    size_t bytes = (size_t)o->width * o->height * 4;
    uint8_t *img = malloc(bytes);
    if (!img) {
        fprintf(stderr, "avatar_render --crowd: out of memory\n");
        crowd_free(&c);
        return 1;
    }
    memcpy(img, weft_renderer_pixels(c.renderer), bytes);
    int y = 4;
    for (uint32_t l = 0; l < levels; ++l) {
        if (!c.level_count[l]) {
            continue;
        }
        float col[3];
        level_color(l, col);
        for (int yy = y; yy < y + 8 && yy < (int)o->height; ++yy) {
            for (int xx = 4; xx < 12 && xx < (int)o->width; ++xx) {
                uint8_t *p = img + ((size_t)yy * o->width + (size_t)xx) * 4;
                p[0] = (uint8_t)(col[0] * 255.0f);
                p[1] = (uint8_t)(col[1] * 255.0f);
                p[2] = (uint8_t)(col[2] * 255.0f);
                p[3] = 255;
            }
        }
        char label[96];
        snprintf(label, sizeof label, "%s x%u", weft_lod_table_level(c.table, l)->name, c.level_count[l]);
        weft_render_draw_text(img, o->width, o->height, 16, y, 1, label);
        y += 12;
    }
    char path[1200];
    snprintf(path, sizeof path, "%s/crowd.png", o->out_dir);
    if (!make_path(o->out_dir)) {
        fprintf(stderr, "avatar_render --crowd: cannot create the output folder '%s': %s\n", o->out_dir,
                strerror(errno));
        free(img);
        crowd_free(&c);
        return 1;
    }
    weft_result wr = weft_render_write_png(path, img, o->width, o->height);
    free(img);
    if (wr != WEFT_OK) {
        return crowd_fail(&c, "writing the PNG");
    }
    printf("wrote %s\n", path);
    crowd_free(&c);
    return 0;
}

#else

int weft_avatar_sample_crowd(const weft_avatar_sample_options *o)
{
    (void)o;
    fprintf(stderr, "avatar_render --crowd: this build has no body/wardrobe/motion runtime (include/weft/body.h)\n");
    return 1;
}

#endif

/* ---------------------------------------------------------------------------------------- */
/* Options (available in every build so that the parser and the usage text do not change).   */

bool weft_avatar_sample_crowd_option(const char *name, const char *value, weft_avatar_sample_options *o)
{
    char *end = NULL;
    if (strcmp(name, "--lod-table") == 0) {
        o->lod_table = value;
        return value[0] != '\0';
    }
    if (strcmp(name, "--crowd") == 0) {
        errno = 0;
        unsigned long v = strtoul(value, &end, 10);
        if (errno || end == value || *end || v < 1 || v > 256) {
            return false;
        }
        o->crowd = (uint32_t)v;
        return true;
    }
    float f = strtof(value, &end);
    if (end == value || *end || !(f > 0.0f) || !(f < 1e6f)) {
        return false;
    }
    *(strcmp(name, "--crowd-mve") == 0 ? &o->crowd_mve : &o->crowd_budget) = f;
    return true;
}
