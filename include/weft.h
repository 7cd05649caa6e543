/*
 * weft — learned cloth simulation for game loops.
 *
 * This is the whole core API. Concept headers under weft/ (ccd.h, body.h, sim.h, fnopt.h)
 * add optional pieces; none is needed to step a garment.
 *
 * Conventions
 *   Units      metres, seconds, kilograms. Y is up, gravity is -9.81 m/s^2 along Y.
 *   Layouts    positions are float xyz triplets, tightly packed: p[3*i+0..2] is vertex i.
 *              Triangles are uint32_t index triplets, counter-clockwise seen from the front.
 *   Frames     a step advances one frame of 1/60 s (the rate the models are trained at).
 *   Errors     every fallible call returns weft_result. On failure nothing the caller owns is
 *              changed, and weft_last_error() holds a message naming the offending field.
 *   Memory     all allocation goes through the weft_allocator given at context creation.
 *              Stepping allocates nothing: every buffer is sized when a garment is created.
 *   Threads    objects are not internally locked: use one garment from one thread at a time.
 *              Different garments may be stepped concurrently. Work inside a step is split
 *              through the host's parallel_for hook when one is given.
 *
 * Typical frame:
 *
 *   weft_garment_set_collider(garment, body_vertices_next_frame);
 *   weft_garment_step(garment);
 *   draw(weft_garment_positions(garment));
 */
#ifndef WEFT_H
#define WEFT_H

#include <stddef.h>
#include <stdint.h>
#include <stdbool.h>

#ifdef __cplusplus
extern "C" {
#endif

#define WEFT_VERSION_MAJOR 0
#define WEFT_VERSION_MINOR 1
#define WEFT_VERSION_PATCH 0

#if defined(WEFT_BUILDING_LIBRARY)
#define WEFT_API __attribute__((visibility("default")))
#else
#define WEFT_API
#endif

/* Every position weft takes or makes (rest shapes, colliders, states, pins, step results) is in
 * metres within +-WEFT_MAX_COORDINATE of the origin: float keeps about 1 mm there. Keep the
 * character near the origin (a floating origin) in larger worlds. */
#define WEFT_MAX_COORDINATE 1.0e4f

/* ---------------------------------------------------------------------------------------- */
/* Results                                                                                   */

typedef enum weft_result {
    WEFT_OK = 0,
    WEFT_ERROR_INVALID_ARGUMENT,   /* a NULL pointer, a zero count, an out-of-range enum */
    WEFT_ERROR_OUT_OF_MEMORY,      /* the allocator returned NULL */
    WEFT_ERROR_IO,                 /* a file could not be opened, read or written */
    WEFT_ERROR_NOT_FINITE,         /* NaN, infinity or a coordinate beyond WEFT_MAX_COORDINATE */
    WEFT_ERROR_SIZE_MISMATCH,      /* an array's length disagrees with what was declared */
    WEFT_ERROR_DEGENERATE_MESH,    /* zero-area triangle, out-of-range index, non-manifold edge */
    WEFT_ERROR_TOPOLOGY_MISMATCH,  /* mesh differs from the one the object was created with */
    WEFT_ERROR_NO_MODEL,           /* the method needs a model and none was given or loaded */
    WEFT_ERROR_NO_COLLIDER,        /* a step was asked for before the collider of t+1 was set */
    WEFT_ERROR_UNSUPPORTED,        /* the method, precision or ISA is not available here */
    /* Model files (safetensors). Each names the offending tensor or field in weft_last_error(). */
    WEFT_ERROR_FILE_TRUNCATED,     /* fewer bytes than the header or the offsets need */
    WEFT_ERROR_HEADER_TOO_LARGE,   /* header length over the cap or beyond the file */
    WEFT_ERROR_HEADER_JSON,        /* header is not a JSON object of tensor entries */
    WEFT_ERROR_DUPLICATE_NAME,     /* two tensors (or metadata keys) share a name */
    WEFT_ERROR_UNKNOWN_DTYPE,      /* dtype outside F32, F16, BF16, I8, I32, U8 */
    WEFT_ERROR_BAD_SHAPE,          /* shape not a list of non-negative integers, or too many dims */
    WEFT_ERROR_BAD_OFFSETS,        /* data_offsets malformed, reversed, or outside the data */
    WEFT_ERROR_SIZE_OVERFLOW,      /* shape x dtype size overflows 64 bits */
    WEFT_ERROR_OVERLAP,            /* tensors overlap, leave holes, or the file has trailing bytes */
    WEFT_ERROR_MISSING_TENSOR,     /* a tensor the architecture needs is absent */
    WEFT_ERROR_TENSOR_SHAPE,       /* a tensor has the wrong shape for the configuration */
    WEFT_ERROR_TENSOR_DTYPE,       /* a tensor has the wrong dtype for its role */
    WEFT_ERROR_BAD_METADATA,       /* __metadata__ missing, not strings, or config invalid */
    WEFT_ERROR_FORMAT,             /* any other malformed input file (npz, npy, BVH, glTF, ...) */
    WEFT_ERROR_NOT_CONVERGED,      /* an iterative solve hit its limit; the result is still safe */
    WEFT_ERROR_BUSY,               /* another thread is using the object's shared scratch */
    WEFT_RESULT_COUNT
} weft_result;

/* Short constant description of a result, e.g. "size mismatch". Never NULL. */
WEFT_API const char *weft_result_string(weft_result result);

/* The detailed message of the last failure on the calling thread (empty if none). */
WEFT_API const char *weft_last_error(void);

/* ---------------------------------------------------------------------------------------- */
/* Version and build                                                                          */

/* "MAJOR.MINOR.PATCH". */
WEFT_API const char *weft_version_string(void);

/* One line describing the build and the machine: version, compiler, kernel ISA in use and
 * the CPU features detected, e.g. "weft 0.1.0 gcc-12.2 isa=avx512 (avx2 fma f16c avx512f ...)". */
WEFT_API const char *weft_config_string(void);

/* ---------------------------------------------------------------------------------------- */
/* Host hooks                                                                                 */

/* Memory. alloc returns memory aligned to at least `alignment` (a power of two <= 4096) or NULL.
 * free receives the same size that was allocated. NULL functions mean the C library. */
typedef struct weft_allocator {
    void *(*alloc)(size_t size, size_t alignment, void *user);
    void (*free)(void *ptr, size_t size, void *user);
    void *user;
} weft_allocator;

/* One chunk of a parallel loop: process items [begin, end). */
typedef void weft_task_fn(uint32_t begin, uint32_t end, uint32_t worker, void *task_context);

/* The host's job system: run task over [0, count) in chunks of at least min_chunk items and
 * return when all are done. `worker` must be < max_workers given in weft_context_def. NULL means
 * weft runs the loop serially on the calling thread. */
typedef void weft_parallel_for_fn(weft_task_fn *task, uint32_t count, uint32_t min_chunk,
                                  void *task_context, void *user);

/* ---------------------------------------------------------------------------------------- */
/* Context: allocator, job hook and the CPU kernel table shared by every object made from it. */

typedef enum weft_isa {
    WEFT_ISA_AUTO = 0,   /* the best the CPU supports */
    WEFT_ISA_SCALAR,     /* plain C oracles */
    WEFT_ISA_AVX2,       /* AVX2 + FMA + F16C */
    WEFT_ISA_AVX512,     /* AVX-512 F/BW/VL (+ VNNI when present) */
    WEFT_ISA_NEON,       /* AArch64 Advanced SIMD (+ dot product when present) */
    WEFT_ISA_COUNT
} weft_isa;

typedef struct weft_context weft_context;

typedef struct weft_context_def {
    weft_allocator allocator;
    weft_parallel_for_fn *parallel_for;
    void *parallel_for_user;
    uint32_t max_workers;       /* distinct `worker` values parallel_for may pass; >= 1 */
    /* Kernel level. AUTO honours the WEFT_ISA environment variable (scalar|avx2|avx512|neon),
     * which tests and benchmarks use to force a level. Asking for a level the CPU lacks fails
     * with WEFT_ERROR_UNSUPPORTED. */
    weft_isa isa;
    uint32_t internal_cookie;   /* set by weft_default_context_def(); do not touch */
} weft_context_def;

WEFT_API weft_context_def weft_default_context_def(void);
WEFT_API weft_result weft_context_create(const weft_context_def *def, weft_context **out_context);
/* All models and garments made from the context must be destroyed first. */
WEFT_API void weft_context_destroy(weft_context *context);
/* The kernel level actually in use (never AUTO). */
WEFT_API weft_isa weft_context_isa(const weft_context *context);
WEFT_API const char *weft_isa_name(weft_isa isa);

/* ---------------------------------------------------------------------------------------- */
/* Models: trained weights in a safetensors file, architecture config in its __metadata__.     */

typedef struct weft_model weft_model;

typedef enum weft_precision {
    WEFT_PRECISION_FP32 = 0,
    WEFT_PRECISION_FP16,        /* fp16 weights, fp32 accumulation */
    WEFT_PRECISION_INT8,        /* int8 weights and activations, int32 accumulation; bit-exact across ISAs */
    WEFT_PRECISION_COUNT
} weft_precision;

typedef struct weft_model_info {
    const char *name;           /* metadata "name", or "" */
    const char *architecture;   /* metadata "architecture", e.g. "clothtransformer" or "fnopt" */
    weft_precision precision;   /* the precision the weights are stored in */
    uint32_t tensor_count;
    uint64_t parameter_count;
    uint64_t weight_bytes;
} weft_model_info;

/* Loads and validates a model. The whole file is checked (header, offsets, dtypes, shapes
 * against the config) before anything is used; a failure names the tensor or field. */
WEFT_API weft_result weft_model_load_file(weft_context *context, const char *path, weft_model **out_model);
/* Same, for a given architecture ("clothtransformer", "fnopt"): a file whose metadata
 * "architecture" differs or is missing fails with WEFT_ERROR_BAD_METADATA after reading only
 * its header, however large its tensors. */
WEFT_API weft_result weft_model_load_file_as(weft_context *context, const char *path, const char *architecture,
                                             weft_model **out_model);
/* Same, from memory. The bytes are copied; the caller may free them afterwards. */
WEFT_API weft_result weft_model_load_memory(weft_context *context, const void *bytes, size_t size,
                                            weft_model **out_model);
/* Garments made from the model must be destroyed first. */
WEFT_API void weft_model_destroy(weft_model *model);
WEFT_API weft_model_info weft_model_get_info(const weft_model *model);


/* ---------------------------------------------------------------------------------------- */
/* Garments: one simulated piece of cloth and the collider it responds to.                     */

typedef struct weft_garment weft_garment;

typedef enum weft_method {
    WEFT_METHOD_MODEL = 0,      /* the learned latent transformer (needs a model) */
    WEFT_METHOD_XPBD,           /* classical XPBD solver with `substeps` substeps per frame */
    WEFT_METHOD_LBS,            /* cloth glued to the collider surface (skinning baseline) */
    /* XPBD as a game engine runs it: WEFT_METHOD_XPBD's material, elastic projection and
     * `substeps`, with a game's collision handling in place of the penetration-free bounds. Each
     * substep moves cloth vertices closer than the collider radius to the collider (or inside it,
     * up to 2 cm deep) out along the nearest surface's pseudonormal, with Coulomb friction, and
     * pushes cloth vertices off cloth triangles closer than the self radius, to the side they
     * were on at the substep's start. No proximity bounds, no edge-edge tests: much cheaper, and
     * a collider or a fold that moves more than those radii in a substep can pass through.
     * Fixed substeps only (substeps_max must be 0). docs/REFSIM.md, *The fast XPBD baseline*. */
    WEFT_METHOD_XPBD_FAST,
    /* Positions from the host's own solver (an FNOpt cloth, a game's): the garment runs no method
     * of its own, only the constraint stage on what weft_garment_constrain is given each frame
     * (tethers, strain limit, collision with body parts, CCD), plus cuts. weft_garment_step
     * refuses it. */
    WEFT_METHOD_EXTERNAL,
    WEFT_METHOD_COUNT
} weft_method;

/* Which collider triangles a learned model turns into encoder tokens (WEFT_METHOD_MODEL). Each
 * kept triangle costs a token in the encoder, so on an avatar the crop decides most of a step's
 * cost: a level-of-detail lever. */
typedef enum weft_collider_crop {
    WEFT_COLLIDER_CROP_BOX = 0,     /* as the model was trained: triangles whose box at t+1 overlaps
                                       the garment's box at t grown by the margin */
    WEFT_COLLIDER_CROP_CELLS,       /* finer: triangles within the margin of the tight box of an
                                       occupied cell of a coarse grid (cells >= one margin, at most
                                       16 per axis) over the garment's vertices; a subset of BOX */
    WEFT_COLLIDER_CROP_COUNT
} weft_collider_crop;

/* How a token cap (weft_garment_def.max_collider_tokens) chooses among the triangles the crop
 * keeps when they are more than the cap. */
typedef enum weft_collider_cap {
    WEFT_COLLIDER_CAP_NEAREST = 0,  /* the cap's triangles nearest to the garment (see the def) */
    WEFT_COLLIDER_CAP_SAMPLE,       /* a spatially even sample of the crop: the cap's triangles of
                                       lowest rank in an order fixed at creation (the collider's rest
                                       triangles along a Morton curve, bit-reversed); each kept token
                                       stands for cropped / kept triangles and is weighted so in the
                                       encoder's attention (a key bias of log(cropped / kept)), which
                                       estimates the attention over the whole crop */
    WEFT_COLLIDER_CAP_COUNT
} weft_collider_cap;

/* ---- The constraint stage ------------------------------------------------------------------
 * After the method's step, every garment runs one stage of constraints, in this order: tethers
 * and attachments, strain limit, collision (the push out of the collider), tethers again, the
 * floor (collision.ground), then the optional CCD pass and the tethers' and attachments' last
 * clamp after it. Each
 * constraint has its own small def inside weft_garment_def, off unless set (CCD: on).
 * Cuts (collision.cut_distance) replace the whole step. Body parts (collision.triangle_parts)
 * also filter the collider contacts of both XPBD methods. docs/WEAR.md, docs/CCD.md. */

/* Tethers (every method; game cloth's "max distance"). Each vertex farther than its radius from
 * its skinned position is moved back onto that sphere, after the method's step, once more after
 * the strain limit and the push, and after CCD: no output vertex is farther than its radius. A
 * vertex CCD held beyond its radius (cloth caught where the body overlaps itself) is released onto
 * it uncertified (stats.ccd_released), and the push lets it out of the body the next step.
 * The skinned position is the initial state bound to the collider at creation (the binding
 * WEFT_METHOD_LBS uses) and carried by the collider of t+1; set_state does not rebind. Radius 0
 * glues a vertex (a waistband for a method without pins). Pinned vertices keep their targets.
 * Needs a collider. With WEFT_METHOD_XPBD's bounded contacts the clamp moves cloth past the bounds
 * that keep it out of the collider, and cloth pulled into the body stays there. With
 * collider_projection the solver also holds the max distance inside its substeps, before the
 * bounds that keep the cloth off itself, and the clamp after the step moves only what those bounds
 * held back (the reference on real motion, docs/REFSIM.md). */
typedef struct weft_tether_def {
    float distance;                     /* metres, one radius for every vertex; 0 (default) = off; finite, >= 0 */
    const float *distances;             /* optional vertex_count radii (finite, >= 0) replacing distance */
} weft_tether_def;

/* Long-range attachments (every method; game cloth's "tethers to the pins", LRA). Each vertex
 * stays within (1 + slack) x its rest distance from its anchor: the pinned vertex nearest to it
 * along the rest shape's edges (the shortest edge path, at least the straight distance). The
 * clamp moves a vertex farther than that from its anchor's target back onto the sphere, after
 * the method's step and after CCD; the push between them has the last word over it (a vertex
 * it moves may end up to push_depth + push past its bound, outside the collider rather than
 * pulled into it). A pinned cloth (a cape, a flag, a curtain) then cannot be stretched away from
 * its pins however fast they move, in O(vertices) a step with no iteration.
 * Anchors follow the pins: when weft_garment_set_pins is given a different vertex list they are
 * found again (a shortest-path search over the edges, no allocation; same list, no work).
 * Vertices with no pin in their piece of cloth, and every vertex while nothing is pinned, are
 * left alone. Needs no collider. */
typedef struct weft_attachment_def {
    bool enabled;                       /* default false */
    float slack;                        /* default 0.1; in [0, 10] when enabled */
} weft_attachment_def;

/* Strain limit (every method). Edges longer than (1 + limit) x their rest length are shortened
 * by `iterations` Gauss-Seidel sweeps, each end moving half (pinned vertices and radius-0 tethers
 * stay put): a learned step or a tether clamp moves vertices one by one, and this keeps the cloth
 * from being torn open. With `contact` > 0 a vertex within that distance of the collider at t+1
 * keeps only the part of its correction that does not point into the collider, so a sheet
 * draped over an object is not dragged into it by its hanging part. */
typedef struct weft_strain_limit_def {
    float limit;                        /* 0 (default) = off; in [0, 10] */
    uint32_t iterations;                /* default 8; in [1, 1000] when the limit is on */
    float contact;                      /* metres; 0 (default) = plain limit; in [0, 1]; needs a collider */
} weft_strain_limit_def;

/* Collision with the collider (every method).
 * push: each vertex inside the collider at t+1 by at most push_depth, or in front of it by less
 *   than push, goes to push in front of the nearest collider point (inside told by the angle-
 *   weighted pseudonormal, exact on a closed collider wound outward). Deeper vertices, and those
 *   that came in through the far side, are left alone: past half a limb the nearest surface is
 *   the wrong one. With CCD on, cloth that starts the step inside is let out (CCD skips its
 *   collider contacts that step). Pinned vertices and radius-0 tethers are not moved.
 *   Clearance: a vertex found outside is searched for again only once its own move and the
 *   collider's since then (bounded patch by patch) could have brought it within `push`; until
 *   then it stays outside and is not moved, even where the pseudonormal of a self-intersecting
 *   collider would call it inside (stats.push_searched counts the searches).
 * triangle_parts: a partition of the collider's triangles into parts (e.g. each triangle's
 *   dominant bone, weft_body_triangle_parts in weft/body.h). Each garment vertex then collides
 *   only with the parts it lies against in the initial state (those within part_margin of its
 *   nearest collider point, and the parts meeting those at a collider vertex): where a skinned
 *   body overlaps itself the cloth between is claimed by one part, not trapped. The push, the
 *   contact-aware strain limit, both XPBD methods and CCD all skip the other parts.
 * ground: the plane y = ground_height as a floor, so that a garment that falls off (or a sheet
 *   dropped without a collider) comes to rest on it.
 * cut_distance: a collider vertex that moved farther than this since the last frame (a teleport,
 *   a respawn, a cut in the animation) makes the step a cut: the garment is reset to its skinned
 *   positions on the collider of t+1, at rest, pins at their targets, the method's history
 *   cleared, no method step and no constraint (stats.collider_cut). The binding costs about 128
 *   bytes per garment vertex. */
typedef struct weft_collision_def {
    float push;                         /* metres; 0 (default) = off; in [0, 0.1]; needs a collider */
    float push_depth;                   /* metres; default 0.02; in [0, 0.5] */
    const uint8_t *triangle_parts;      /* collider_triangle_count ids in [0, 31], copied at creation;
                                         * NULL (default) = one part; needs a collider */
    float part_margin;                  /* metres; default 0.03; in [0, 1] */
    float cut_distance;                 /* metres; default 1 (60 m/s at 60 Hz); 0 = off;
                                         * in [0, WEFT_MAX_COORDINATE] */
    bool part_neighbours;               /* a vertex also collides with the parts meeting its own at a
                                         * collider vertex (default true: cloth sliding across a
                                         * joint meets the next part); false: only the parts within
                                         * part_margin (the reference on real motion: torso cloth
                                         * under an arm that sinks into the chest is not squeezed) */
    bool ground;                        /* a floor (default false): vertices below y = ground_height at
                                         * t+1 go onto it and keep their x, z of t (no sliding); it
                                         * needs no collider and has the last word before CCD */
    float ground_height;                /* metres; default 0 (weft's avatar stands on y = 0);
                                         * within +-WEFT_MAX_COORDINATE */
} weft_collision_def;

/* The CCD post-process (the seed's safety net): the cloth's motion x(t) -> x(t+1) against the
 * collider's and itself, hits moved back along their path, `iterations` back-off passes, then a
 * fallback that carries cloth with the collider or holds it; certified intersection-free. Its work
 * is bounded: all passes of a step visit at most 64 triangle pairs per cloth triangle plus 16384;
 * a step that would need more keeps the stages' result, uncertified (stats.ccd_over_budget),
 * rather than hold the garment still while the body moves on. docs/CCD.md. */
typedef struct weft_ccd_def {
    bool enabled;                       /* default true */
    uint32_t iterations;                /* back-off passes; default 16; in [1, 64] when enabled */
} weft_ccd_def;

typedef struct weft_garment_def {
    weft_method method;
    const weft_model *model;            /* WEFT_METHOD_MODEL only */
    weft_precision precision;           /* WEFT_METHOD_MODEL only; the model is converted if needed */

    /* Rest shape (the garment as designed, unstretched). Copied at creation. */
    const float *rest_positions;        /* vertex_count * 3 */
    uint32_t vertex_count;
    const uint32_t *triangles;          /* triangle_count * 3 */
    uint32_t triangle_count;

    /* Collider topology, fixed for the garment's life; positions arrive every frame through
     * weft_garment_set_collider(). collider_rest_positions is the collider at the frame where
     * the garment was placed (used by LBS binding and the initial state). Optional: a garment
     * may have no collider (count 0). */
    const float *collider_rest_positions;
    uint32_t collider_vertex_count;
    const uint32_t *collider_triangles;
    uint32_t collider_triangle_count;

    /* Initial state; NULL means the rest shape, at rest. */
    const float *initial_positions;

    uint32_t substeps;                  /* WEFT_METHOD_XPBD and _FAST: substeps per frame (default 10) */
    /* WEFT_METHOD_XPBD: when above `substeps`, a frame whose collider moves fast near the cloth
     * gets more substeps, up to this many, so that the collider geometry that can reach the cloth
     * moves at most 0.8 gamma / (1 + gamma) of the collider contact radius per substep (0.57 mm by
     * default): the condition under which the solver's bounds keep cloth pushed by the collider
     * outside it (docs/REFSIM.md, *Where the last rejections came from*). Frames that need no more
     * run as with fixed substeps. Ground truth uses it; 0 (default) keeps every frame at
     * `substeps`, a game's fixed budget. At most 4000. */
    uint32_t substeps_max;
    /* WEFT_METHOD_XPBD: how the solver meets the collider. false (default): bounded contacts, so
     * cloth never crosses the collider (the penetration-free reference, exact where the collider
     * does not overlap itself). true: each substep ends with cloth inside the collider (up to 2 cm
     * deep) or nearer than the contact radius moved out along the nearest surface's pseudonormal,
     * among the vertex's body parts (collision.triangle_parts), with Coulomb friction, as
     * WEFT_METHOD_XPBD_FAST does; the max distance (tethers) is also held inside the substeps,
     * before the bounds that keep the cloth off itself. The body cannot be held back, so its
     * projection has the last word in a substep, and the max distance after the step: where the
     * body squeezes cloth against itself (two limbs that overlap), or the bounds held cloth beyond
     * its radius, the cloth is not certified against itself. On a body that overlaps itself (real
     * motion capture) bounded contacts trap the cloth the body has passed, and the reference on
     * real motion projects instead (docs/REFSIM.md, *Real motion*). substeps_max keeps the body's
     * step within the bounds of the cloth it carries. Ignored by the other methods. */
    bool collider_projection;

    /* WEFT_METHOD_MODEL: collider cropping (ignored by other methods, but still validated).
     * collider_crop_margin: metres; 0 (default) means the model's own crop_margin (0.15 m for
     * the shipped models). Must be finite and >= 0. A smaller margin keeps fewer triangles.
     * collider_crop: WEFT_COLLIDER_CROP_BOX (default) or WEFT_COLLIDER_CROP_CELLS.
     * max_collider_tokens: 0 (default) keeps every triangle the crop selects; otherwise at most
     * this many, those whose centroid is nearest to a garment vertex (exact within a quarter of
     * the margin; farther ones rank after, approximately), ties to the lower triangle index (the
     * same set on every kernel ISA); with collider_cap WEFT_COLLIDER_CAP_SAMPLE an even sample of
     * the crop instead, weighted in the attention (weft_collider_cap). Bounds the encoder's cost.
     * collider_cap: WEFT_COLLIDER_CAP_NEAREST (default) or WEFT_COLLIDER_CAP_SAMPLE; the sample
     * keeps a model's accuracy at a far smaller cap (docs/LOD.md, Collider crop). */
    float collider_crop_margin;
    weft_collider_crop collider_crop;
    uint32_t max_collider_tokens;
    weft_collider_cap collider_cap;

    /* The constraint stage, in its order (see above). */
    weft_tether_def tethers;
    weft_attachment_def attachments;
    weft_strain_limit_def strain;
    weft_collision_def collision;
    weft_ccd_def ccd;
    uint32_t internal_cookie;           /* set by weft_default_garment_def(); do not touch */
} weft_garment_def;

typedef struct weft_step_stats {
    uint64_t frame;                     /* frames stepped since creation or the last set_state */
    double step_ms;                     /* wall time of the last step: */
    double method_ms;                   /*   the method's own step (a batched one: its even share) */
    double constraints_ms;              /*   the range check, tethers, strain limit and collision */
    double ccd_ms;                      /*   the CCD pass */
    uint32_t ccd_iterations;            /* CCD post-process passes in the last step */
    uint32_t ccd_vertices_moved;        /* vertices the CCD post-process moved back */
    bool ccd_fallback;                  /* CCD did not converge; unresolved vertices were held */
    uint32_t collider_tokens;           /* collider triangles the last model step turned into tokens */
    uint32_t tether_vertices_clamped;   /* tether clamps in the last step (a vertex clamped in both
                                         * passes counts twice) */
    uint32_t attachment_vertices_clamped; /* vertices the attachments moved after the last method step
                                         * (their clamp after CCD counts in ccd_released) */
    uint32_t strain_limited_edges;      /* edges over the strain limit before limiting, last step */
    uint32_t pushed_vertices;           /* vertices the collider push moved in the last step */
    uint32_t push_searched;             /* vertices the push searched the collider for in the last
                                         * step; the others were kept clear by the collider's motion
                                         * bound (collision.push, *clearance*) */
    uint32_t ccd_let_out;               /* with the push and CCD: vertices that began the step inside
                                         * the collider (within collision.push_depth), whose collider
                                         * contacts CCD skipped so they could leave it */
    uint32_t push_from_far_side;        /* vertices inside that it left to CCD: they came in through
                                         * the collider's far side, so the nearest surface would
                                         * push them through it */
    bool ccd_over_budget;               /* CCD reached its work bound (64 triangle pairs per cloth
                                         * triangle plus 16384, all passes together): the step kept
                                         * the result of the stages before CCD, not certified
                                         * (docs/CCD.md, *Work bound*) */
    bool collider_cut;                  /* the last step was a cut (collision.cut_distance) */
    uint32_t ground_vertices;           /* vertices the floor (collision.ground) held in the last step */
    uint32_t ccd_released;              /* with tethers or attachments and CCD: vertices CCD held
                                         * beyond their radius or attachment limit, released onto it
                                         * after CCD (not certified) */
} weft_step_stats;

WEFT_API weft_garment_def weft_default_garment_def(void);
/* weft_default_garment_def() for this model: method WEFT_METHOD_MODEL, the model, its file's
 * precision, and the settings it was deployed with when its file says so (metadata "deploy", a
 * JSON object with any of "strain_limit", "tether_distance", "push" (metres) and "ccd"; a value
 * outside what weft_garment_def accepts fails the load with WEFT_ERROR_BAD_METADATA). The host
 * still sets the meshes, and the body parts (collision.triangle_parts) when it has them. */
WEFT_API weft_garment_def weft_model_garment_def(const weft_model *model);

/* Validates the meshes (indices in range, no zero-area triangles, finite positions) and sizes
 * every buffer the method needs. */
WEFT_API weft_result weft_garment_create(weft_context *context, const weft_garment_def *def,
                                         weft_garment **out_garment);
WEFT_API void weft_garment_destroy(weft_garment *garment);

/* ---- Shared garment assets (crowds) ---------------------------------------------------------
 * An asset holds what weft_garment_create makes from a def that stepping never changes: the
 * meshes, the skin binding, body-part masks, edge lists and rest lengths, the collider tree's
 * layout, the CCD world, the model's converted weights and constant tokens; and one set of step
 * scratch. An instance made from it holds only its state: positions at t-1, t and t+1, the
 * collider at t and t+1, pins, statistics and the learned model's latent history (the XPBD
 * methods keep their whole solver state per instance). An instance behaves exactly as a garment
 * made by weft_garment_create from the same def, bit for bit, and takes every garment call.
 *
 * Threads: instances of one asset share its scratch, so only one of them at a time may be in
 * weft_garment_step, weft_garment_constrain or weft_garment_skinned_positions; a call that
 * finds another instance of its asset there fails with WEFT_ERROR_BUSY and changes nothing.
 * A host stepping crowds on several threads gives each thread its own asset.
 * weft_garments_step steps an asset's instances one after another (not stacked: they share the
 * scratch a stacked step would need per garment). docs/MODEL_BENCH.md, *Crowds*. */
typedef struct weft_garment_asset weft_garment_asset;
/* Validates def as weft_garment_create does; nothing is made on failure. */
WEFT_API weft_result weft_garment_asset_create(weft_context *context, const weft_garment_def *def,
                                               weft_garment_asset **out_asset);
/* Every instance must be destroyed first. */
WEFT_API void weft_garment_asset_destroy(weft_garment_asset *asset);
/* A new garment in the def's initial state, collider at collider_rest_positions; destroy it with
 * weft_garment_destroy. */
WEFT_API weft_result weft_garment_asset_instance(weft_garment_asset *asset, weft_garment **out_garment);
/* Instances of the asset alive now. */
WEFT_API uint32_t weft_garment_asset_instance_count(const weft_garment_asset *asset);

/* Replaces the state: positions at t and at t-1 (prev may be NULL: zero velocity). Clears the
 * model's frame history. */
WEFT_API weft_result weft_garment_set_state(weft_garment *garment, const float *positions,
                                            const float *prev_positions);

/* Collider vertex positions at the frame being stepped to (t+1), collider_vertex_count * 3. */
WEFT_API weft_result weft_garment_set_collider(weft_garment *garment, const float *collider_positions);

/* Replaces the collider at the current frame t (what the last step moved it to, or
 * collider_rest_positions at creation), collider_vertex_count * 3. With
 * weft_garment_set_state it restarts a garment at any frame of a recorded scene: methods that
 * sweep the collider from t to t+1 (XPBD, CCD) read it. */
WEFT_API weft_result weft_garment_set_collider_current(weft_garment *garment, const float *collider_positions);

/* Pins: vertices that follow given targets this frame (handles, grasps, attachments). XPBD
 * solves with them (the rest of the cloth feels the pull); the learned and LBS methods step
 * first and then set the pinned vertices to their targets. count 0 clears the pins. */
WEFT_API weft_result weft_garment_set_pins(weft_garment *garment, const uint32_t *vertex_indices,
                                           const float *target_positions, uint32_t count);

/* Surface pins: garment vertices carried by the collider's surface, e.g. a skirt's or dress's
 * waistband on the hips, so that a method that holds nothing up (XPBD) keeps the garment on.
 * Each point is bound at creation to its nearest collider triangle at rest (the barycentric foot
 * point and the offset in the triangle's frame, blended over its nearest triangles: the binding
 * LBS and the tethers use); each frame
 * weft_surface_pins_targets gives it on the posed collider, for weft_garment_set_pins:
 *
 *   uint32_t idx[512];
 *   uint32_t n = weft_mesh_top_ring(skirt_rest, skirt_vertices, 0.012f, idx, 512);
 *   ... def.rest_points = the rest positions of those vertices, def.vertex_indices = idx ...
 *   weft_surface_pins_create(ctx, &def, &band);
 *   each frame: weft_surface_pins_targets(band, body_next, targets);
 *               weft_garment_set_pins(garment, weft_surface_pins_indices(band), targets, n);
 *
 * Creation builds a BVH over the collider once; targets allocate nothing. */
typedef struct weft_surface_pins weft_surface_pins;
typedef struct weft_surface_pins_def {
    const float *collider_rest_positions;   /* collider_vertex_count * 3, the pose the points are placed in */
    uint32_t collider_vertex_count;
    const uint32_t *collider_triangles;     /* collider_triangle_count * 3 */
    uint32_t collider_triangle_count;
    const float *rest_points;               /* count * 3: the pinned vertices at rest */
    const uint32_t *vertex_indices;         /* count: which garment vertices they are (copied) */
    uint32_t count;
    uint32_t internal_cookie;
} weft_surface_pins_def;

WEFT_API weft_surface_pins_def weft_default_surface_pins_def(void);
/* Fails naming the problem (missing arrays, a triangle naming a missing vertex, a non-finite
 * point or collider, only degenerate triangles); nothing is made then. */
WEFT_API weft_result weft_surface_pins_create(weft_context *context, const weft_surface_pins_def *def,
                                              weft_surface_pins **out_pins);
WEFT_API void weft_surface_pins_destroy(weft_surface_pins *pins);
/* The targets on the collider posed at `collider_positions` (collider_vertex_count * 3), count * 3.
 * It uses scratch held by the pins object: one thread at a time per object, as for garments. */
WEFT_API weft_result weft_surface_pins_targets(const weft_surface_pins *pins, const float *collider_positions,
                                               float *out_targets);
WEFT_API uint32_t weft_surface_pins_count(const weft_surface_pins *pins);
WEFT_API const uint32_t *weft_surface_pins_indices(const weft_surface_pins *pins);
/* A garment's top ring: the vertices whose rest height (y) is within `band` metres of its highest
 * vertex (a skirt's or dress's waistband; 0.012 for weft's wardrobe garments). Writes up to
 * `capacity` indices (out_indices may be NULL to count) and returns how many there are. */
WEFT_API uint32_t weft_mesh_top_ring(const float *positions, uint32_t vertex_count, float band, uint32_t *out_indices,
                                     uint32_t capacity);

/* Advances one frame. Needs set_collider() for this frame when the garment has a collider.
 * On failure the state is unchanged. */
WEFT_API weft_result weft_garment_step(weft_garment *garment);

/* Steps `count` garments in one call (a crowd: many characters per frame). Each garment gets
 * exactly what weft_garment_step would give it, bit for bit: CCD post-process, NaN check, and
 * its state unchanged when its own step fails. Garments of method MODEL made from the same
 * context, model and precision run their temporal transformer as one stacked GEMM per layer
 * (up to 64 garments per stack), so its weights are read once per stack instead of once per
 * character; other garments and instances of a garment asset (they share its scratch) are
 * stepped one by one.
 *
 * A failing garment does not stop the others: every garment is attempted, the result is the
 * first failure in array order (weft_last_error() names its index), and the garments that
 * succeeded have advanced (their weft_garment_stats().frame went up by one). NULL entries,
 * count 0 or a garment listed twice fail with WEFT_ERROR_INVALID_ARGUMENT before any step.
 * The step_ms of a garment stepped in a group is its even share of the group's forward pass
 * plus its own NaN check and CCD.
 *
 * Memory: the stacked scratch belongs to the first garment of each group (in array order) and
 * is allocated on its first call with that many garments or more, then kept until that garment
 * is destroyed; calls with the same or smaller groups allocate nothing. Why not a separate
 * batch object: the scratch is tied to one model's sizes, and garments are already the unit the
 * host owns per thread, so a crowd needs no extra object to create and keep in step. If that
 * allocation fails, the group is stepped one garment at a time (same results, no error).
 * Threads: the garments of one call must not be used elsewhere during it. */
WEFT_API weft_result weft_garments_step(weft_garment *const *garments, uint32_t count);

/* The step of a WEFT_METHOD_EXTERNAL garment: `next_positions` (vertex_count * 3, the host
 * solver's result for t+1) go through the constraint stage against the collider of t+1 (set
 * first with weft_garment_set_collider when the garment has one) and become the state, exactly
 * as a method's result would; weft_garment_positions then holds the constrained positions. A
 * cut resets to the skinned garment as for any method. Pins (weft_garment_set_pins) are set on
 * the result first. On failure the state is unchanged. Other methods refuse it. */
WEFT_API weft_result weft_garment_constrain(weft_garment *garment, const float *next_positions);

/* Current positions (vertex_count * 3), valid until the next step, set_state or destroy. */
WEFT_API const float *weft_garment_positions(const weft_garment *garment);
WEFT_API uint32_t weft_garment_vertex_count(const weft_garment *garment);
/* Vertices pinned by the last weft_garment_set_pins (0 for NULL). */
WEFT_API uint32_t weft_garment_pin_count(const weft_garment *garment);
/* The garment carried by the skin at the current frame: the initial state as bound to the
 * collider at creation (the binding LBS, the tethers and cuts use), on the collider of the
 * current frame; vertex_count * 3. What a game draws for a character too far away to simulate,
 * and the reference the wear measures call "skinned". WEFT_ERROR_UNSUPPORTED when the garment
 * has no binding (no collider, or neither tethers nor a cut distance). Allocates nothing. */
WEFT_API weft_result weft_garment_skinned_positions(const weft_garment *garment, float *out_positions);
WEFT_API weft_step_stats weft_garment_stats(const weft_garment *garment);

#ifdef __cplusplus
}
#endif

#endif /* WEFT_H */
