/*
 * weft/lod.h — level of detail: model no more than a scene needs.
 *
 * A level is one way of stepping a garment: the method (learned model, XPBD, LBS), the model and
 * its precision and collider crop, the XPBD substeps, CCD post-processing on or off, and the
 * garment resolution.
 * `weft bench lod` runs every candidate level over a held-out split and writes the measured
 * table (ms per frame and mean vertex error) as CSV; the runtime loads that CSV, picks the
 * cheapest level that meets a per-frame budget and an accuracy target, and switches a live
 * garment between levels without a visible pop.
 *
 * Typical use:
 *
 *   weft_lod_table *table;
 *   weft_lod_table_load_file(ctx, "samples/data/lod.csv", &table);
 *   uint32_t level;
 *   weft_lod_pick_result fit = weft_lod_pick(table, 0.5, 1.0, &level);   // 0.5 ms, 1 cm
 *   ... weft_lod_garment_create(ctx, &def_with_level, &lg) ...
 *   per frame: weft_lod_garment_set_collider(lg, body); weft_lod_garment_step(lg);
 *   when the character walks away: weft_lod_garment_switch(lg, cheaper_level);
 *
 * The CSV (one header line, then one line per level; lines starting with '#' are comments):
 *
 *   level,method,model,precision,substeps,ccd,resolution,ms_per_frame,mve_cm,max_edge_strain,sequences,frames
 *   xpbd-5,xpbd,-,-,5,on,1,0.8123,1.42,0.031,3,357
 *
 *   level            unique name, [A-Za-z0-9_.:+-], at most 47 characters
 *   method           model | xpbd | lbs
 *   model            the model's metadata "name" (e.g. "game") for method model, "-" otherwise
 *   precision        fp32 | fp16 | int8 for method model, "-" otherwise
 *   substeps         1..1000 for method xpbd, "-" otherwise
 *   ccd              on | off
 *   resolution       in (0, 1]: the simulated mesh's vertex count over the drawn mesh's. 1 simulates
 *                    the garment's own mesh; 0.25 simulates a mesh of the same garment with about a
 *                    quarter of its vertices (weft_lod_garment_def.sim_meshes) and draws the garment
 *                    through a mesh map
 *   ms_per_frame     measured mean step time, finite and > 0
 *   mve_cm           measured mean vertex error, finite and >= 0
 *   max_edge_strain  measured max |edge length / rest - 1|, finite and >= 0 (information only)
 *   sequences        sequences measured (>= 1)
 *   frames           frames measured (>= 1)
 *
 * Optional columns (the collider crop of a model level: weft_garment_def's collider_crop_margin,
 * collider_crop and max_collider_tokens; "-" for other methods, and what an absent column means):
 *
 *   crop_cm              crop margin in cm, in (0, 10000]; "-": the model's own (15 cm for the
 *                        shipped models)
 *   collider_crop        box | cells; "-": box (the rule the models were trained with)
 *   max_collider_tokens  cap on kept collider triangles, >= 1; "-": no cap
 *
 *   (a row of a table with all three, from `weft bench lod --crops model,5:cells,model@3000`)
 *   game-int8-noccd-cells5,model,game,int8,-,off,1,4.02397,6.39549,1.53334,3,180,5,cells,-
 *
 * Optional columns for every method (weft_garment_def's tethers.distance and strain.limit):
 *
 *   tether_cm            tether radius in cm, in (0, 100000]; "-": no tethers
 *   strain_limit_pct     strain limit in %, in (0, 1000]; "-": none
 *   strain_contact_cm    contact-aware strain limit distance in cm, in (0, 100], only with a
 *                        strain limit (weft_garment_def.strain.contact); "-": plain limit
 *   push_cm              collider push thickness in cm, in (0, 10] (weft_garment_def.collision.push,
 *                        with the default depth); "-": no push
 *
 * Columns may come in any order; unknown columns are an error (a misspelt name would otherwise
 * silently drop a measurement). Tables written before the crop columns existed load unchanged.
 */
#ifndef WEFT_LOD_H
#define WEFT_LOD_H

#include "weft.h"

#ifdef __cplusplus
extern "C" {
#endif

#define WEFT_LOD_MAX_LEVELS 256u
#define WEFT_LOD_NAME_CAP 48u

/* One measured level (a row of the table). */
typedef struct weft_lod_level {
    char name[WEFT_LOD_NAME_CAP];
    weft_method method;
    char model[WEFT_LOD_NAME_CAP];      /* model metadata name; "" unless method is MODEL */
    weft_precision precision;           /* MODEL only (FP32 otherwise) */
    uint32_t substeps;                  /* XPBD only (0 otherwise) */
    bool ccd;
    double resolution;                  /* (0, 1]; 1: the garment's own mesh (see the CSV above) */
    /* MODEL only: the collider crop (weft_garment_def.collider_crop_*). */
    double crop_cm;                     /* 0: the model's own margin */
    weft_collider_crop collider_crop;   /* BOX unless the table says cells */
    uint32_t max_collider_tokens;       /* 0: no cap */
    double tether_cm;                   /* 0: no tethers (weft_garment_def.tethers.distance, in cm) */
    double strain_limit_pct;            /* 0: none (weft_garment_def.strain.limit, in %) */
    double strain_contact_cm;           /* 0: plain limit (weft_garment_def.strain.contact, in cm) */
    double push_cm;                     /* 0: no push (weft_garment_def.collision.push, in cm) */
    double ms_per_frame;
    double mve_cm;
    double max_edge_strain;
    uint32_t sequences, frames;
} weft_lod_level;

typedef struct weft_lod_table weft_lod_table;

/* Parses and validates a table. A malformed file fails with WEFT_ERROR_FORMAT and a message
 * naming the line and column; nothing is returned then. */
WEFT_API weft_result weft_lod_table_load_file(weft_context *context, const char *path, weft_lod_table **out_table);
/* Same, from text in memory (need not be NUL-terminated). */
WEFT_API weft_result weft_lod_table_load_memory(weft_context *context, const char *text, size_t size,
                                                weft_lod_table **out_table);
WEFT_API void weft_lod_table_destroy(weft_lod_table *table);
WEFT_API uint32_t weft_lod_table_count(const weft_lod_table *table);
/* Level i in file order, or NULL when i is out of range. */
WEFT_API const weft_lod_level *weft_lod_table_level(const weft_lod_table *table, uint32_t index);
/* Index of the level called name; WEFT_ERROR_INVALID_ARGUMENT when there is none. */
WEFT_API weft_result weft_lod_table_find(const weft_lod_table *table, const char *name, uint32_t *out_index);

/* ---------------------------------------------------------------------------------------- */
/* Picking a level                                                                            */

typedef enum weft_lod_pick_result {
    WEFT_LOD_PICK_OK = 0,           /* the cheapest level within the budget and the accuracy target */
    WEFT_LOD_PICK_ACCURACY_MISSED,  /* no level within budget meets the target: the most accurate
                                       level within budget was chosen */
    WEFT_LOD_PICK_OVER_BUDGET,      /* no level fits the budget: the cheapest level was chosen */
    WEFT_LOD_PICK_INVALID           /* NULL table or output, empty table, budget or target not a
                                       positive number; *out_level is untouched and
                                       weft_last_error() says why */
} weft_lod_pick_result;

/* Chooses a level for one garment from the measured table. Ties on cost go to the more accurate
 * level, ties on accuracy to the cheaper one, then to the earlier row. */
WEFT_API weft_lod_pick_result weft_lod_pick(const weft_lod_table *table, double budget_ms, double max_mve_cm,
                                            uint32_t *out_level);
/* The same over the levels with usable[i] != 0 (e.g. those whose model is loaded); usable may be
 * NULL (all levels). No usable level at all is WEFT_LOD_PICK_INVALID. */
WEFT_API weft_lod_pick_result weft_lod_pick_among(const weft_lod_table *table, const uint8_t *usable,
                                                  double budget_ms, double max_mve_cm, uint32_t *out_level);
WEFT_API const char *weft_lod_pick_result_string(weft_lod_pick_result result);

/* ---------------------------------------------------------------------------------------- */
/* A garment that can change level while it runs                                             */

typedef struct weft_lod_garment weft_lod_garment;

/* A coarser mesh of the same garment in the same rest pose (e.g. the wardrobe's 1k T-shirt for the
 * 4k one), simulated by the levels whose resolution is below 1. */
typedef struct weft_lod_mesh {
    const float *rest_positions;        /* vertex_count * 3 */
    uint32_t vertex_count;
    const uint32_t *triangles;          /* triangle_count * 3 */
    uint32_t triangle_count;
} weft_lod_mesh;

#define WEFT_LOD_MAX_SIM_MESHES 8u

/* The table and the models are referenced, not copied: both must outlive the garment. */
typedef struct weft_lod_garment_def {
    const weft_lod_table *table;
    uint32_t level;                     /* starting level (index into the table) */

    /* Loaded models the table's model levels refer to, matched by metadata name. When several
     * share a name, the one stored at the level's precision is preferred (no conversion at
     * switch time); otherwise the garment converts. A model level without its model fails at
     * creation or switch with WEFT_ERROR_NO_MODEL. */
    const weft_model *const *models;
    uint32_t model_count;

    /* The garment, as in weft_garment_def (copied). */
    const float *rest_positions;
    uint32_t vertex_count;
    const uint32_t *triangles;
    uint32_t triangle_count;
    const float *collider_rest_positions;
    uint32_t collider_vertex_count;
    const uint32_t *collider_triangles;
    uint32_t collider_triangle_count;
    const float *initial_positions;     /* NULL: the rest shape */

    /* Past frames kept to warm a learned model's latent history at a switch. 0 means the
     * longest history of any model level in the table that has its model in `models`. */
    uint32_t history_frames;

    /* Resolution levels (resolution < 1). Each level simulates the given mesh whose vertex count
     * over vertex_count is nearest its resolution (within a factor of 1.5, else the level fails
     * with WEFT_ERROR_UNSUPPORTED), and the garment is drawn through a mesh map: positions and
     * vertex_count stay those of the garment's own mesh at every level. Copied at creation; the
     * maps both ways are made here. At most WEFT_LOD_MAX_SIM_MESHES. Pins name the drawn mesh's
     * vertices at every level; at a resolution level each pinned vertex pins its nearest vertex of
     * the simulated mesh (rest space), and a simulated vertex whose nearest drawn vertex is pinned
     * is pinned too, at the drawn target plus the rest-space offset between the two (exact for a
     * pinned patch that translates; a pin target is then off by that offset's rotation).
     * resolution_blend_frames: a switch onto a coarser mesh cannot show the finer mesh's detail;
     * the difference is faded out over this many frames instead of popping (default 8; 0: none). */
    const weft_lod_mesh *sim_meshes;
    uint32_t sim_mesh_count;
    uint32_t resolution_blend_frames;
    uint32_t internal_cookie;           /* set by weft_default_lod_garment_def(); do not touch */
} weft_lod_garment_def;

WEFT_API weft_lod_garment_def weft_default_lod_garment_def(void);

/* Creates the garment at def->level. Every buffer, including the past-frame ring used to warm a
 * model at a switch, is sized here. */
WEFT_API weft_result weft_lod_garment_create(weft_context *context, const weft_lod_garment_def *def,
                                             weft_lod_garment **out_garment);
WEFT_API void weft_lod_garment_destroy(weft_lod_garment *garment);

/* Collider at t+1, as weft_garment_set_collider. The first call of each frame also records the
 * current state (positions and collider at t) into the past-frame ring; no allocation. */
WEFT_API weft_result weft_lod_garment_set_collider(weft_lod_garment *garment, const float *collider_positions);
/* As weft_garment_set_pins, with indices of the drawn mesh at every level (see sim_meshes for a
 * resolution level); the pins are carried over at a switch. No allocation. */
WEFT_API weft_result weft_lod_garment_set_pins(weft_lod_garment *garment, const uint32_t *vertex_indices,
                                               const float *target_positions, uint32_t count);
/* As weft_garment_step. */
WEFT_API weft_result weft_lod_garment_step(weft_lod_garment *garment);
/* As weft_garment_set_state (a teleport): also forgets the recorded past frames, so a later
 * switch to a model level starts its latent window from the new state. */
WEFT_API weft_result weft_lod_garment_set_state(weft_lod_garment *garment, const float *positions,
                                                const float *prev_positions);

/* Switches to another level of the table. A new garment of that level is created; it takes the
 * positions at t and t-1 (so the velocity carries over), the collider at t (and at t+1 when it
 * was already set this frame) and the pins; a learned model's latent history is rebuilt from the
 * recorded past frames, so its first step sees the same window as if it had run all along.
 * LBS, tethers and a model with the skinned prior bind to the current pose instead of the rest
 * pose. This allocates (a switch is not a per-frame operation). On failure (no model, no sim mesh
 * for the level's resolution, out of memory) the garment stays at its current level, unchanged.
 * Switching to the current level is a no-op. */
WEFT_API weft_result weft_lod_garment_switch(weft_lod_garment *garment, uint32_t level);

WEFT_API uint32_t weft_lod_garment_level(const weft_lod_garment *garment);
WEFT_API const float *weft_lod_garment_positions(const weft_lod_garment *garment);
WEFT_API uint32_t weft_lod_garment_vertex_count(const weft_lod_garment *garment);
/* The garment of the current level, e.g. to step many at once with weft_garments_step, or to
 * read its stats. Valid until the next switch or destroy. Step it only after
 * weft_lod_garment_set_collider so that the past-frame ring stays complete, and change its state
 * through weft_lod_garment_set_state, not weft_garment_set_state. At a resolution level it is the
 * coarse garment (its own vertex count): call weft_lod_garment_sync after each such step. */
WEFT_API weft_garment *weft_lod_garment_current(weft_lod_garment *garment);
/* After stepping weft_lod_garment_current yourself: maps the new state onto the drawn mesh at a
 * resolution level (no-op at resolution 1, or when it was not stepped since the last call).
 * weft_lod_garment_step does this itself. */
WEFT_API weft_result weft_lod_garment_sync(weft_lod_garment *garment);

/* ---------------------------------------------------------------------------------------- */
/* Mesh maps: one garment at two resolutions (the resolution lever of level of detail).        */
/*                                                                                              */
/* Simulate a coarse mesh of the garment (fewer encoder tokens, constraints and CCD work) and   */
/* render a fine one from it: each `to` vertex is bound at creation to its nearest `from`       */
/* triangles in rest space (closest-point barycentrics plus an offset in the triangle's frame,  */
/* blended over up to 4 nearby triangles by inverse distance: the binding of WEFT_METHOD_LBS),   */
/* so it follows the coarse surface's stretch, bend and rigid motion. A map the other way       */
/* (from = fine, to = coarse) samples a fine state onto the coarse mesh, e.g. to start it.      */
/* Both meshes must be the same garment in the same rest pose (e.g. the wardrobe's 1k and 4k     */
/* T-shirt on one body). docs/LOD.md measures the accuracy and cost of simulating at 1k for a    */
/* 4k garment.                                                                                  */

typedef struct weft_mesh_map weft_mesh_map;

typedef struct weft_mesh_map_def {
    const float *from_rest_positions;   /* from_vertex_count * 3: the mesh that is simulated */
    uint32_t from_vertex_count;
    const uint32_t *from_triangles;     /* from_triangle_count * 3 */
    uint32_t from_triangle_count;
    const float *to_rest_positions;     /* to_vertex_count * 3: the points that follow it */
    uint32_t to_vertex_count;
    uint32_t internal_cookie;           /* set by weft_default_mesh_map_def(); do not touch */
} weft_mesh_map_def;

WEFT_API weft_mesh_map_def weft_default_mesh_map_def(void);
/* Validates both inputs as weft_garment_create does (indices, finite values, zero-area triangles)
 * and binds every `to` vertex. Allocates only here. */
WEFT_API weft_result weft_mesh_map_create(weft_context *context, const weft_mesh_map_def *def,
                                          weft_mesh_map **out_map);
WEFT_API void weft_mesh_map_destroy(weft_mesh_map *map);
/* to_positions (to_vertex_count * 3) from from_positions (from_vertex_count * 3); no allocation
 * (the map owns a scratch buffer: one thread at a time per map). NaN/inf input or a frame where
 * every triangle bound to a vertex has collapsed fails and leaves to_positions untouched. */
WEFT_API weft_result weft_mesh_map_apply(weft_mesh_map *map, const float *from_positions, float *to_positions);
WEFT_API uint32_t weft_mesh_map_from_vertex_count(const weft_mesh_map *map);
WEFT_API uint32_t weft_mesh_map_to_vertex_count(const weft_mesh_map *map);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_LOD_H */
